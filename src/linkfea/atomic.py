"""File output shared by linkfea and vjm.

Atomic writes: to a temporary name beside the target, then a rename, so a
failed write leaves neither a partial file nor the temporary behind and a
command that stops on an error writes nothing.  :func:`plain` turns numpy
values into plain Python for JSON and YAML.
"""
from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from .errors import LinkFeaError


@contextmanager
def atomic_path(path, suffix: str | None = None):
    """Yield a temporary path beside ``path``; rename it onto ``path`` on success.

    The parent folder is created if needed.  A path that cannot be written
    raises :class:`~linkfea.errors.LinkFeaError` naming it.  ``suffix`` (default: the target's)
    keeps writers that choose a format from the file name (matplotlib, VTK) happy.

    Examples
    --------
    >>> import json, tempfile, os
    >>> target = os.path.join(tempfile.mkdtemp(), "r.json")
    >>> with atomic_path(target) as tmp:
    ...     _ = Path(tmp).write_text(json.dumps({"a": 1}))
    >>> json.loads(Path(target).read_text())
    {'a': 1}
    """
    path = Path(path).absolute()
    tmp = None
    try:
        if path.is_dir():
            raise IsADirectoryError(21, "is a folder", str(path))
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.",
                                   suffix=path.suffix if suffix is None else suffix)
        os.close(fd)
        os.chmod(tmp, 0o644)  # mkstemp makes 0600; results are meant to be shared
        yield tmp
        os.replace(tmp, path)
    except OSError as exc:
        raise LinkFeaError(f"cannot write {path}: {exc.strerror or exc}") from None
    finally:
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)


def write_text(path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8", newline="") as fh:
        fh.write(text)


def write_bytes(path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        Path(tmp).write_bytes(data)


def plain(x):
    """numpy arrays and scalars (nested in dicts, lists, tuples) as plain Python.

    Non-finite floats become ``None``: JSON has no NaN or infinity.

    >>> plain({"a": np.arange(2), "b": np.float64("nan"), 3: (np.int64(1), np.bool_(True))})
    {'a': [0, 1], 'b': None, '3': [1, True]}
    """
    if isinstance(x, dict):
        return {str(k): plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return plain(x.tolist())
    if isinstance(x, np.bool_):
        return bool(x)
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, (float, np.floating)):
        v = float(x)
        return v if np.isfinite(v) else None
    return x
