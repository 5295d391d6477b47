"""Atomic file output: write to a temporary name beside the target, then rename.

A failed write leaves neither a partial file nor the temporary behind, so a
command that stops on an error writes nothing.  linkfea and vjm both use it.
"""
from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def atomic_path(path, suffix: str | None = None):
    """Yield a temporary path beside ``path``; rename it onto ``path`` on success.

    The parent folder is created if needed.  ``suffix`` (default: the target's)
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
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.",
                               suffix=path.suffix if suffix is None else suffix)
    os.close(fd)
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def write_text(path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8", newline="") as fh:
        fh.write(text)


def write_bytes(path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        Path(tmp).write_bytes(data)
