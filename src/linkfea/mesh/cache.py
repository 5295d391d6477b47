"""The mesh cache: one raw mesh (points, tets) per key, shared by concurrent runs, safe to damage.

pytetwild is not deterministic from run to run, so a key must stand for exactly one mesh:

* **One mesh per key, also for concurrent runs.** The run that finds no entry takes an
  exclusive lock on ``KEY.npz.lock`` (``fcntl.flock``), checks again, meshes and writes the entry;
  the others block on the lock and then read what it wrote.  The kernel drops a flock when its
  holder dies, so a killed run never leaves a lock that blocks the next one.  (The tool runs on
  Linux; flock on a network file system depends on its locking support.)
* **Entries appear whole.** An entry is written to a temporary name and renamed
  (:func:`linkfea.files.atomic.atomic_path`), so a reader sees a complete file or none.
* **A damaged entry is a miss.** An entry that cannot be read (truncated, not a zip, wrong
  arrays) gets one warning, is meshed again and replaced atomically; never a traceback.

Lock files are empty and stay in the cache folder (removing one while another run waits on it
would let a third run take a second lock on a new file).

**Where.** ``$LINKFEA_CACHE_DIR`` if set (and not empty), else ``meshes`` in the platform's cache folder
for linkfea (``platformdirs``: ``~/.cache/linkfea/meshes`` on Linux, under ``$XDG_CACHE_HOME`` if set), so
runs from any folder share one cache and none litters the folder it runs in.
"""
from __future__ import annotations

import fcntl
import os
import warnings
import zipfile
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

from ..files.atomic import atomic_path
from ..runtime.errors import LinkFeaError, LinkFeaWarning

Mesh = tuple[np.ndarray, np.ndarray]

#: the environment variable that names the cache folder (a sweep's local workers get the client's)
CACHE_ENV = "LINKFEA_CACHE_DIR"


def cache_dir_default() -> Path:
    """The mesh cache folder when none is given: ``$LINKFEA_CACHE_DIR``, else the platform's cache folder."""
    chosen = os.environ.get(CACHE_ENV)
    if chosen:
        return Path(chosen)
    from platformdirs import user_cache_path

    return user_cache_path("linkfea", appauthor=False) / "meshes"


class DamagedEntry(Exception):
    """A cache entry that exists but cannot be read as a mesh (the reason is the message)."""


def entry_path(cache_dir, key: str) -> Path:
    return Path(cache_dir) / f"{key}.npz"


def read_entry(path: Path) -> Mesh | None:
    """The cached (points, tets), or None if there is no entry.

    Raises :class:`DamagedEntry` for a file that is there but is no complete mesh.
    """
    try:
        with np.load(path, allow_pickle=False) as z:
            points, tets = np.asarray(z["points"]), np.asarray(z["tets"])
    except FileNotFoundError:
        return None
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
        raise DamagedEntry(f"{type(exc).__name__}: {' '.join(str(exc).split())}") from None
    ok = (points.ndim == 2 and points.shape[1] == 3 and points.dtype.kind == "f"
          and tets.ndim == 2 and tets.shape[1] == 4 and tets.dtype.kind in "iu" and np.isfinite(points).all()
          and (len(tets) == 0 or (int(tets.min()) >= 0 and int(tets.max()) < len(points))))
    if not ok:
        raise DamagedEntry(f"arrays of shape {points.shape} and {tets.shape} are no tetrahedral mesh")
    return points, tets.astype(np.int64, copy=False)


def write_entry(path: Path, points: np.ndarray, tets: np.ndarray) -> None:
    """Write an entry atomically (a reader sees the old file, the new one or none)."""
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez(fh, points=points, tets=tets)


@contextmanager
def key_lock(path: Path, on_wait: Callable[[], None] | None = None) -> Iterator[None]:
    """Hold an exclusive lock on ``path`` (created if needed); ``on_wait`` is called if another holds it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise LinkFeaError(f"cannot use the mesh cache {path.parent}: {exc.strerror or exc}") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            if on_wait is not None:
                on_wait()
            fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # closing the last descriptor releases the lock


def cached_mesh(cache_dir, key: str, make: Callable[[], Mesh], progress: Callable[[str], None]) -> Mesh:
    """The mesh of ``key``: from the cache, else made by ``make()`` (once, under the key's lock) and stored."""
    path = entry_path(cache_dir, key)
    try:
        hit = read_entry(path)  # the common case needs no lock: entries only ever appear whole
    except DamagedEntry:
        hit = None
    if hit is not None:
        progress("mesh from cache")
        return hit
    with key_lock(path.with_name(path.name + ".lock"),
                  on_wait=lambda: progress("waiting for another run meshing the same part")):
        try:
            hit = read_entry(path)
        except DamagedEntry as exc:
            warnings.warn(f"mesh cache entry {path} is damaged ({exc}); meshing again and replacing it",
                          LinkFeaWarning, stacklevel=2)
            hit = None
        if hit is not None:
            progress("mesh from cache")
            return hit
        points, tets = make()
        write_entry(path, points, tets)
    return points, tets
