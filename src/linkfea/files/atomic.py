"""File output shared by linkfea and vjm: one file at a time.

Atomic writes: to a temporary name beside the target, then a rename, so a
failed write leaves neither a partial file nor the temporary behind and a
command that stops on an error writes nothing.  Temporaries are named
``.linkfea-tmp.<pid>.<random>.<name>``, so that a later run recognises the
ones a killed process left behind (:func:`stale_temporary`) and removes them.
Sets of files written together, ownership and the checks before any work are
in :mod:`linkfea.files.outputs`.  :func:`plain` turns numpy values into plain Python
for JSON and YAML.
"""
from __future__ import annotations

import errno
import hashlib
import os
import re
import stat
import tempfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ..runtime.errors import LinkFeaError

#: prefix of every temporary file the tools write beside a target
TMP_PREFIX = ".linkfea-tmp."
#: the whole name of such a temporary: prefix, the writing process's pid, mkstemp's random part, the target
_TMP_NAME = re.compile(r"^\.linkfea-tmp\.(?P<pid>[0-9]{1,10})\.[a-z0-9_]{8}\.(?P<target>.+)$")
#: first lines of the single-file outputs written outside a manifest (see :func:`seal`)
SIMULATED_CSV_MARK = "# simulated by vjm simulate"
COMMANDS_CSV_MARK = "# commands by vjm compensate"
SINGLE_FILE_MARKS = (SIMULATED_CSV_MARK, COMMANDS_CSV_MARK)
_SEAL = re.compile(r"; sha256 (?P<h>[0-9a-f]{64})$")


def umask() -> int:
    """The process's umask, read without changing it where the system allows."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    m = os.umask(0o022)
    os.umask(m)
    return m


def temp_beside(path) -> Path:
    """A new empty temporary file in the folder of ``path``, named after it (same suffix), with the
    permissions a new file gets under the user's umask (mkstemp alone makes 0600)."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f"{TMP_PREFIX}{os.getpid()}.", suffix=f".{path.name}")
    os.close(fd)
    os.chmod(tmp, 0o666 & ~umask())
    return Path(tmp)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def is_temporary(name: str) -> bool:
    """Is ``name`` shaped as the tools' temporaries are (:func:`temp_beside`: prefix, pid, mkstemp's random
    part, the target's name)?  A user's ``.linkfea-tmp.notes.txt`` is not."""
    return _TMP_NAME.match(name) is not None


def temporary_target(name: str) -> str | None:
    """The output a temporary stands for (``.linkfea-tmp.<pid>.<random>.r.vtu`` -> ``r.vtu``), None for another name."""
    m = _TMP_NAME.match(name)
    return m["target"] if m else None


def stale_temporary(name: str) -> bool:
    """Is ``name`` a temporary of this tool whose process is gone (killed before it could clean up)?
    Only a name of the tools' pattern with the pid of a process that no longer runs: a file the user
    named with the prefix is theirs and never removed."""
    m = _TMP_NAME.match(name)
    return m is not None and int(m["pid"]) != os.getpid() and not _alive(int(m["pid"]))


def seal(text: str) -> str:
    """``text`` with the sha256 of its content appended to its first line, if that line is the mark of a
    single-file output (:data:`SINGLE_FILE_MARKS`): such a file is the tool's own only while its bytes are
    those it wrote (:func:`sealed`); one the user edited is theirs."""
    if not text.startswith(SINGLE_FILE_MARKS):
        return text
    first, nl, rest = text.partition("\n")
    digest = hashlib.sha256((first + nl + rest).encode("utf-8")).hexdigest()
    return f"{first}; sha256 {digest}{nl}{rest}"


def sealed(data: bytes, mark: str) -> bool:
    """Are ``data`` a file that starts with ``mark`` and whose bytes are still those :func:`seal` recorded?"""
    if not data.startswith(mark.encode()):
        return False
    first, nl, rest = data.partition(b"\n")
    m = _SEAL.search(first.decode("utf-8", "replace"))
    if m is None:
        return False
    return hashlib.sha256(first[:m.start()] + nl + rest).hexdigest() == m["h"]


def fsync_file(path) -> None:
    """Flush a written file's data to disk (a rename after it then never exposes an empty file)."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def fsync_dir(path) -> None:
    """Flush a folder's entries (renames, new and removed names) to disk."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_DIRECTORY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


@contextmanager
def atomic_path(path, suffix: str | None = None):
    """Yield a temporary path beside ``path``; rename it onto ``path`` on success.

    The parent folder is created if needed.  A path that cannot be written
    raises :class:`~linkfea.runtime.errors.LinkFeaError` naming it.  ``suffix`` (default: the target's)
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
        refuse_link(path, "")
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = str(temp_beside(path if suffix is None else path.with_suffix(suffix)))
        yield tmp
        fsync_file(tmp)
        os.replace(tmp, path)
    except OSError as exc:
        raise LinkFeaError(write_error(path, exc)) from None
    finally:
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)


def _mount_of(path: Path) -> tuple[str, str]:
    """The mount point holding ``path`` and the device mounted there (its name in /proc/self/mounts)."""
    p = path.absolute()
    while not p.exists():
        p = p.parent
    try:
        dev = p.stat().st_dev
        while p.parent != p and p.parent.stat().st_dev == dev:
            p = p.parent
    except OSError:
        pass
    device = ""
    try:
        with open("/proc/self/mounts", encoding="utf-8", errors="replace") as fh:
            for line in fh:
                f = line.split()
                if len(f) > 2 and f[1].replace("\\040", " ") == str(p):
                    device = f[0]  # the last mount at a point is the one in effect
    except OSError:
        pass
    return str(p), device


def write_error(path, exc: OSError) -> str:
    """The one line for a write of ``path`` that failed with ``exc``: a full disk (or quota) names the device."""
    path = Path(path)
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        mount, device = _mount_of(path)
        on = f"device {device} (mounted at {mount})" if device else f"the device mounted at {mount}"
        what = "no space left" if exc.errno == errno.ENOSPC else "disk quota exceeded"
        return f"cannot write {path}: {what} on {on}; nothing was written: free some space or choose another place"
    return f"cannot write {path}: {exc.strerror or exc}"


def refuse_link(path, option: str = "--out") -> None:
    """Refuse a symbolic link at an output path: the tools neither replace a link nor write through it."""
    p = Path(path)
    if p.is_symlink():
        target = os.readlink(p)
        state = "" if p.exists() else ", which does not exist"
        raise LinkFeaError(f"{option + ' ' if option else ''}{p} is a symbolic link to {target}{state}: linkfea and vjm neither replace a "
                           f"link nor write through one; give the real path or remove the link")


#: largest input file read whole (measurement and pose CSVs): far above any measured data set
READ_MAX_BYTES = 200_000_000


def read_user_file(path, what: str, limit: int = READ_MAX_BYTES, error: type[Exception] = LinkFeaError) -> bytes:
    """The bytes of input file ``path``: only a regular file (not a device, pipe or folder, even through a
    link: a link to /dev/zero would fill the memory) of at most ``limit`` bytes; else ``error`` naming it."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))  # a FIFO must not block the open
    except OSError as exc:
        raise error(f"cannot read {what} {path}: {exc.strerror or exc}") from None
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode):
        os.close(fd)
        kind = "a folder" if stat.S_ISDIR(st.st_mode) else "not a regular file (a device, pipe or socket)"
        raise error(f"cannot read {what} {path}: it is {kind}")
    with os.fdopen(fd, "rb") as fh:
        try:
            data = fh.read(limit + 1) if st.st_size <= limit else b""
        except OSError as exc:
            raise error(f"cannot read {what} {path}: {exc.strerror or exc}") from None
        if st.st_size > limit or len(data) > limit:
            raise error(f"{what} {path} is larger than {limit / 1e6:.0f} MB, more than any such file should be: "
                        f"is it the right file?")
        return data


def file_sha256(path) -> str:
    """SHA-256 of a file's bytes (hex): the identity of an output set's members and of a result's source."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def write_text(path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically; a single-file output (its first line a mark of
    :data:`SINGLE_FILE_MARKS`) sealed with its sha256 (:func:`seal`)."""
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8", newline="") as fh:
        fh.write(seal(text))


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
