"""vjm's shipped data: the model files (``data/orthoglide/*.yaml``) and the seed's Table 1.

In the source tree they are in ``data/``; an installed wheel carries them as ``vjm/_data``
(see :mod:`linkfea.runtime.resources`).  :func:`data_file` lets every command take the README's
paths (``data/orthoglide/puu.yaml``) or short names (``puu``) from any folder.
"""
from __future__ import annotations

import os
import warnings
from pathlib import Path

from linkfea.runtime.resources import shipped_dir

from .errors import VjmError, VjmWarning


def data_dir() -> Path:
    """Folder of the bundled model files and ``seed_table1.csv``."""
    return shipped_dir("vjm", "_data", "data")


def seed_table() -> Path:
    """The seed paper's Table 1 (``seed_table1.csv``)."""
    return data_dir() / "seed_table1.csv"


def data_file(path, suffixes=(".yaml", ".csv")) -> Path:
    """``path`` if it exists, else the bundled file it names.

    A bare name (no folder, no suffix) is first looked up in the current folder with one of
    ``suffixes``, in their order: a **local file wins** over a bundled one of the same name
    (with a :class:`~vjm.errors.VjmWarning` naming both when both exist and differ).
    A relative path that does not exist is looked up in :func:`data_dir`, as given
    (``orthoglide/puu.yaml``), without a leading ``data/`` (``data/orthoglide/puu.yaml``), or
    as a bare name with one of ``suffixes`` (``puu`` -> ``orthoglide/puu.yaml``).  A name that
    matches nothing is returned unchanged, for the caller's "not found" message; a bare name
    that matches several bundled files is an error.
    """
    p = Path(os.fspath(path))
    if p.exists() or p.is_absolute():
        return p
    root = data_dir()
    if len(p.parts) == 1 and not p.suffix:
        local = [q for q in (Path(p.name + s) for s in suffixes) if q.is_file()]
        if local:  # a local file wins over a bundled one of the same name
            bundled = [b for b in _bundled_hits(root, [local[0].name]) if b.read_bytes() != local[0].read_bytes()]
            if bundled:
                warnings.warn(f"{path!s}: using {local[0].resolve()} from this folder, not the bundled "
                              f"{bundled[0].relative_to(root)} (a local file takes precedence over a bundled name)",
                              VjmWarning, stacklevel=2)
            return local[0]
    parts = p.parts[1:] if p.parts and p.parts[0] == "data" else p.parts
    for cand in (root / p, root.joinpath(*parts) if parts else None):
        if cand is not None and cand.is_file():
            return cand
    if len(p.parts) == 1 and root.is_dir():
        names = [p.name] if p.suffix else [p.name + s for s in suffixes]
        hits = _bundled_hits(root, names)
        if len(hits) == 1:
            return hits[0]
        if len(hits) > 1:
            rel = ", ".join(str(h.relative_to(root)) for h in hits)
            raise VjmError(f"{path!s} names several bundled files ({rel}); give the path")
    return p


def _bundled_hits(root: Path, names) -> list[Path]:
    return sorted(q for n in names for q in root.rglob(n) if q.is_file()) if root.is_dir() else []
