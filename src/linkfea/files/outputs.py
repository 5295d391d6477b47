"""The user's files: ownership of output files, complete output sets, checks before any work.

Every command of linkfea and vjm that writes goes through this module.

**Ownership.**  A folder a command writes into holds a small manifest,
``.linkfea-outputs.json``, listing the files each command (a *set*, such as
``vjm diagnose``) wrote there, with their sha256 and a run id.  A file not in
it, or whose bytes are no longer those recorded (the user edited it), is of
other origin: it is never overwritten and never deleted.  A single result file
in the user's own folder (``linkfea compute --out r.json``, ``vjm simulate
--out d.csv``) gets no manifest; there the tool recognises its own files by
their content (a ``linkfea.result.linkresult`` JSON, and the ``.vtu``/``.png`` beside it
whose sha256 the JSON records; a CSV whose first line says vjm simulate or vjm
compensate wrote it and records the sha256 of its content, :func:`~linkfea.files.atomic.seal`).
A symbolic link is never the tool's own: an output path that is one is
refused; nor is an input of the command (:func:`refuse_inputs`).  A set that rewrites
a file of another set in the folder replaces that set whole (:func:`_superseded`).

**Complete sets.**  Members are written to temporaries beside their targets
(:func:`linkfea.files.atomic.temp_beside`) and flushed to disk; then a journal
``.linkfea-journal.<set>.<run>.json`` listing the renames (and the tool's own files
the new set no longer has) is written atomically; the renames follow and the
journal is removed.  Killed before the journal exists: the old set is
untouched, and the next run removes the stray temporaries.  Killed after: the
next run into the folder, or the next read of the result, rolls the journal
forward (:func:`recover`), so the set is the new one, complete.

**Fault injection.**  ``LINKFEA_FAULT=<point>[:<n>]`` SIGKILLs the process the
``n``-th time (default the first) it reaches ``point`` (:data:`FAULT_POINTS`).
"""
from __future__ import annotations

import json
import os
import signal
import stat
import time
import uuid
from pathlib import Path
from typing import Callable, Iterable

from ..runtime.errors import LinkFeaError
from .atomic import (
    COMMANDS_CSV_MARK,
    SIMULATED_CSV_MARK,
    SINGLE_FILE_MARKS,
    fsync_dir,
    fsync_file,
    is_temporary,
    refuse_link,
    sealed,
    stale_temporary,
    temp_beside,
    temporary_target,
    write_error,
)
from .atomic import file_sha256 as sha256

MANIFEST = ".linkfea-outputs.json"
MANIFEST_SCHEMA = "linkfea.outputs/1"
JOURNAL_PREFIX = ".linkfea-journal."
JOURNAL_SCHEMA = "linkfea.journal/1"
#: where ``LINKFEA_FAULT`` can kill a process: every member written to its temporary; the journal
#: written; the first member renamed into place; all renamed (journal not yet removed); one sweep
#: design's result written
FAULT_POINTS = ("members-written", "journal-written", "renamed-one", "renamed-all", "design-written")
_hits: dict[str, int] = {}
#: what marks the files written outside a manifest (see :func:`recognised`)
RESULT_SCHEMA_PREFIX = "linkfea.result/"
RECOGNISE_MAX_BYTES = 50_000_000


def fault(point: str) -> None:
    """SIGKILL this process here if ``LINKFEA_FAULT`` names ``point`` (test hook; see FAULT_POINTS)."""
    spec = os.environ.get("LINKFEA_FAULT")
    if not spec:
        return
    name, _, nth = spec.partition(":")
    if name != point:
        return
    _hits[point] = _hits.get(point, 0) + 1
    if _hits[point] >= (int(nth) if nth.isdigit() else 1):
        os.kill(os.getpid(), signal.SIGKILL)


def _internal(name: str) -> bool:
    """Names of the machinery itself (manifest, journals, temporaries): never a user's file."""
    return name == MANIFEST or name.startswith(JOURNAL_PREFIX) or is_temporary(name)


# --------------------------------------------------------------------------- manifest
def read_manifest(folder) -> dict:
    """The manifest of ``folder`` (an empty one if there is none or it is unreadable)."""
    try:
        doc = json.loads((Path(folder) / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {"schema": MANIFEST_SCHEMA, "sets": {}}
    if not isinstance(doc, dict) or not isinstance(doc.get("sets"), dict):
        return {"schema": MANIFEST_SCHEMA, "sets": {}}
    return doc


def unchanged(path, digest) -> bool:
    """Are the bytes at ``path`` still those the tool wrote (sha256 ``digest``)?  A link never is."""
    p = Path(path)
    try:
        return isinstance(digest, str) and not p.is_symlink() and p.is_file() and sha256(p) == digest
    except OSError:
        return False


def _recorded(folder: Path) -> dict[str, set]:
    """Every name the manifest of ``folder`` records, with the sha256 each set recorded for it (None: a
    sub-folder claimed by name)."""
    out: dict[str, set] = {}
    for s in read_manifest(folder)["sets"].values():
        for n, digest in (s.get("files") or {}).items():
            out.setdefault(n, set()).add(digest if isinstance(digest, str) else None)
    return out


def _as_recorded(path: Path, digests: set) -> bool:
    return None in digests or any(unchanged(path, d) for d in digests)


def owned(folder) -> set[str]:
    """Top-level names in ``folder`` that the tools wrote: in its manifest with the bytes recorded there
    (sub-folders such as ``results`` by their name), or recognised by content (:func:`recognised`)."""
    folder = Path(folder)
    names = {n.split("/", 1)[0] for n, d in _recorded(folder).items() if _as_recorded(folder / n, d)}
    return names | recognised(folder)


def changed(folder) -> set[str]:
    """Files the manifest of ``folder`` records whose bytes changed since (edited by the user: theirs now)."""
    folder = Path(folder)
    return {n for n, d in _recorded(folder).items() if (folder / n).exists() and not _as_recorded(folder / n, d)}


def _regular(path) -> bool:
    """A regular file, not a link (a link to /dev/zero must not be read), of bounded size."""
    try:
        st = os.lstat(path)
    except OSError:
        return False
    return stat.S_ISREG(st.st_mode) and st.st_size <= RECOGNISE_MAX_BYTES


def _doc(path) -> dict:
    try:
        if not _regular(path):
            return {}
        with open(path, encoding="utf-8") as fh:
            doc = json.load(fh)
    except (OSError, ValueError, UnicodeDecodeError):
        return {}
    return doc if isinstance(doc, dict) else {}


def _schema(path) -> str:
    return str(_doc(path).get("schema", ""))


def own_companions(path, doc: dict | None = None) -> set[str]:
    """Names of the files beside result JSON ``path`` (its document ``doc``, if read already) that are its
    own: recorded under ``files`` with the sha256 of their present bytes.  A ``.vtu`` or ``.png`` the
    JSON does not record, or whose bytes differ, is someone else's."""
    files = (_doc(path) if doc is None else doc).get("files")
    out = set()
    for rec in (files.values() if isinstance(files, dict) else ()):
        name = rec.get("name") if isinstance(rec, dict) else None
        if isinstance(name, str) and _plain_name(name) and unchanged(Path(path).with_name(name), rec.get("sha256")):
            out.add(name)
    return out


def is_result_json(path) -> bool:
    """Is ``path`` a link result JSON written by linkfea (schema ``linkfea.result/...``)?"""
    return _schema(path).startswith(RESULT_SCHEMA_PREFIX)


def is_simulated_csv(path, mark: str = SIMULATED_CSV_MARK) -> bool:
    """Was ``path`` written by vjm simulate (or by the command whose ``mark`` it is), and are its bytes still
    those written?  Its first line says so and records the sha256 of the content (:func:`~linkfea.files.atomic.seal`):
    a file the user edited, or wrote with that first line, is theirs."""
    try:
        if not _regular(path):
            return False
        with open(path, "rb") as fh:
            if fh.read(len(mark)) != mark.encode():
                return False
            fh.seek(0)
            return sealed(fh.read(), mark)
    except OSError:
        return False


def _marked(path) -> bool:
    """Does ``path`` start as a single-file output of the tools does (whatever its bytes after)?"""
    try:
        if not _regular(path):  # never open a pipe
            return False
        with open(path, "rb") as fh:
            head = fh.read(max(map(len, SINGLE_FILE_MARKS)))
    except OSError:
        return False
    return head.startswith(tuple(m.encode() for m in SINGLE_FILE_MARKS))


def is_commands_csv(path) -> bool:
    """Was ``path`` written by vjm compensate, unedited since (see :func:`is_simulated_csv`)?"""
    return is_simulated_csv(path, COMMANDS_CSV_MARK)


def recognised(folder) -> set[str]:
    """Files in ``folder`` that the tools wrote outside any manifest, known by their content: link
    results (``linkfea compute``, ``LinkResult.save``) with the companions whose sha256 they record
    (:func:`own_companions`) and CSVs of ``vjm simulate`` and ``vjm compensate``."""
    folder = Path(folder)
    names = set()
    for e in os.listdir(folder):
        p = folder / e
        doc = _doc(p) if e.endswith(".json") else {}
        schema = str(doc.get("schema", ""))
        if schema.startswith(RESULT_SCHEMA_PREFIX):
            names |= {e} | own_companions(p, doc)
        elif e.endswith(".csv") and (is_simulated_csv(p) or is_commands_csv(p)):
            names.add(e)
    return names


# --------------------------------------------------------------------------- recovery
def _roll_forward(folder: Path, journal: Path) -> None:
    try:
        doc = json.loads(journal.read_text(encoding="utf-8"))
        renames, remove = [(str(t), str(n)) for t, n in doc["renames"]], [str(n) for n in doc["remove"]]
    except (OSError, ValueError, KeyError, TypeError):
        journal.unlink(missing_ok=True)  # written atomically, so never partial; unreadable: nothing to do
        return
    # names in the folder itself, temporaries of the tool: a planted journal cannot reach elsewhere
    plain = [n for _, n in renames] + remove
    if any(not _plain_name(n) for n in plain) or any(not is_temporary(t) or not _plain_name(t)
                                                      for t, _ in renames):
        journal.unlink(missing_ok=True)
        return
    for tmp, name in renames:
        if (folder / tmp).exists():
            os.replace(folder / tmp, folder / name)
    for name in remove:
        (folder / name).unlink(missing_ok=True)
    fsync_dir(folder)
    journal.unlink(missing_ok=True)
    fsync_dir(folder)


def _target(path: Path) -> Path:
    """The output a temporary stands for (``.linkfea-tmp.<pid>.<random>.r.vtu`` -> ``r.vtu``)."""
    target = temporary_target(path.name)
    return path if target is None else path.with_name(target)


def _plain_name(name: str) -> bool:
    return bool(name) and "/" not in name and "\\" not in name and name not in (".", "..")


def file_set_name(path) -> str:
    """The name of the set anchored on main file ``path`` (a result JSON with its companions, a CSV)."""
    return f"file-{Path(path).name}"


def roll_forward_file(path) -> None:
    """Complete a killed, committed write of the set anchored on ``path`` (what a reader does first)."""
    roll_forward(Path(path).absolute().parent, file_set_name(path))


def journal_path(folder, set_name: str, run: str) -> Path:
    """The journal of one commit (named by its run, so that two runs never share one)."""
    return Path(folder) / f"{JOURNAL_PREFIX}{_slug(set_name)}.{run}.json"


def roll_forward(folder, set_name: str) -> None:
    """Complete the committed write of set ``set_name`` in ``folder`` if a killed run left its journal
    (what a reader does before reading; best effort)."""
    try:
        for j in sorted(Path(folder).glob(f"{JOURNAL_PREFIX}{_slug(set_name)}.*.json")):
            _roll_forward(Path(folder), j)
    except OSError:
        pass


def recover(folder) -> None:
    """Finish what a killed run left in ``folder``: roll its journals forward, remove its stale
    temporaries (also in the tool's sub-folders).  Best effort: a folder that cannot be written
    is left as it is."""
    folder = Path(folder)
    if not folder.is_dir():
        return
    try:
        for j in sorted(folder.glob(JOURNAL_PREFIX + "*")):
            _roll_forward(folder, j)
        subs = [folder / n for n in owned(folder) if (folder / n).is_dir()]
        for d in [folder, *subs]:
            for entry in os.listdir(d):
                if stale_temporary(entry):
                    (d / entry).unlink(missing_ok=True)
    except OSError:
        pass


# --------------------------------------------------------------------------- checks before any work
def check_writable(folder, option: str = "--out") -> None:
    """Refuse a place where nothing can be written: the nearest existing ancestor of ``folder``
    must be a folder in which a file can be created (a probe file is made and removed)."""
    p = Path(folder).absolute()
    a = p
    while not a.exists():
        a = a.parent
    if not a.is_dir():
        raise LinkFeaError(f"{option} {p}: {a} is a file, not a folder")
    try:
        probe = temp_beside(a / "probe")
        probe.unlink()
    except OSError as exc:
        raise LinkFeaError(f"{option} {p}: cannot write in {a}: {exc.strerror or exc}") from None


def refuse_inputs(out, names: Iterable[str] | None, inputs: Iterable, option: str = "--out") -> None:
    """Refuse an output that would replace a file the command reads: a member ``out/name`` of ``names``
    (None: every file the manifest of folder ``out`` records, which a new set may replace or remove), or
    ``out`` itself when ``names`` is empty (a single file), that is one of ``inputs`` (None entries skipped),
    also under another name (a link, a second path).  Called before any work."""
    out = Path(out)
    if names is None:
        names = list(_recorded(out)) if out.is_dir() else []
    targets = [out / n for n in names] or [out]
    for src in (Path(i) for i in inputs if i is not None):
        for t in targets:
            try:
                same = t.exists() and src.exists() and os.path.samefile(t, src)
            except OSError:
                same = False
            if same:
                raise LinkFeaError(f"{option} {out}: writing {t.name} would replace {src}, which this command reads: "
                                   f"choose another {'folder' if t != out else 'name'} or copy the input elsewhere")


def check_folder(out, names: Iterable[str], force: bool = False, option: str = "--out", inputs: Iterable = ()) -> Path:
    """Check an output folder before any work; raise LinkFeaError (one line) if it will not do.

    Refused: a file where the folder should be; a place that cannot be written; a folder
    holding files the tools did not write (unless ``force``); and, even with ``force``,
    a folder where one of ``names`` (the files the command will write) is such a file.
    A killed earlier run's journal is rolled forward and its temporaries removed first.  ``inputs``:
    the files the command reads, none of which the set may replace (:func:`refuse_inputs`).
    """
    out = Path(out)
    names = list(names)
    refuse_inputs(out, names, inputs, option)
    if out.is_symlink() and not out.exists():
        refuse_link(out, option)
    if out.exists() and not out.is_dir():
        raise LinkFeaError(f"{option} {out} exists and is not a directory: this command writes a folder")
    check_writable(out, option)
    if not out.is_dir():
        return out
    recover(out)
    own = owned(out)
    foreign = sorted(e for e in os.listdir(out) if e not in own and not _internal(e))
    clash = sorted({n.split("/", 1)[0] for n in names} & set(foreign))
    if clash and clash[0] in changed(out):
        raise LinkFeaError(f"{option} {out}: {clash[0]} was changed since linkfea or vjm wrote it (its sha256 is not "
                           f"the one recorded), so it is yours now and never overwritten, not even with --force: "
                           f"choose another folder or move it")
    if clash:
        raise LinkFeaError(f"{option} {out}: {clash[0]} is there and was not written by linkfea or vjm; it is never "
                           f"overwritten, not even with --force: choose another folder or move it")
    if foreign and not force:
        raise LinkFeaError(f"{option} {out} holds {foreign[0]}, which linkfea or vjm did not write: choose a new or "
                           f"empty folder, or pass --force to write beside such files (never touching them)")
    return out


def check_file(path, owner: Callable[[Path], bool], what: str, companions: Iterable = (),
               option: str = "--out", own_companions: Callable[[Path], set[str]] | None = None,
               inputs: Iterable = ()) -> Path:
    """Check an output file (and its companions, written with it) before any work.

    Refused: a symbolic link (dangling or not); a folder where the file should be; a place that
    cannot be written; an existing file that ``owner`` does not recognise as the tool's own
    ``what``; an existing companion that is not among ``own_companions(path)`` (the names whose
    bytes the file records), or beside a file that is not the tool's; a file the command reads (``inputs``).
    """
    path = Path(path)
    refuse_inputs(path, (), inputs, option)
    for p in (path, *map(Path, companions)):
        refuse_link(p, option)
        if p.is_dir():
            raise LinkFeaError(f"{option} {path}: {p} is a folder, not a file")
    check_writable(path.parent, option)
    recover(path.parent)
    ours = path.is_file() and owner(path)
    if path.exists() and not ours and _marked(path):
        raise LinkFeaError(f"{option} {path} was changed since linkfea or vjm wrote it (its sha256 is not the one its "
                           f"first line records), so it is yours now and never overwritten: choose another name or "
                           f"move it")
    if path.exists() and not ours:
        raise LinkFeaError(f"{option} {path} exists and is not {what}; it is never overwritten: "
                           f"choose another name or move it")
    mine = own_companions(path) if ours and own_companions is not None else set()
    for c in map(Path, companions):
        if c.exists() and ours and c.name not in mine and own_companions is not None:
            raise LinkFeaError(f"{option} {path}: {c} exists and {path.name} does not record its bytes (your file, or "
                               f"changed since linkfea wrote it); it is never overwritten: choose another name or move it")
        if c.exists() and not ours:
            raise LinkFeaError(f"{option} {path}: {c} exists and is not part of {what}; it is never "
                               f"overwritten: choose another name or move it")
    return path


# --------------------------------------------------------------------------- writing a set
class OutputSet:
    """Files written together into one folder: after :meth:`commit`, all of them are the new ones;
    before it (or if the process dies before the journal is written), all are the old ones.

    ``with OutputSet(folder, "vjm map") as s: write(s.path("map.npz")); ...`` commits at the end
    of the block and removes the temporaries if the block raises.  ``manifest=True`` (folders the
    tools own) records the set in the folder's manifest and removes the set's files of the
    previous run that this one no longer writes; ``remove`` names further own files to remove.
    """

    def __init__(self, folder, name: str, manifest: bool = True, remove: Iterable[str] = ()):
        self.folder = Path(folder)
        self.name = name
        self.manifest = manifest
        self.remove = list(remove)
        self.run = uuid.uuid4().hex
        self.tmps: dict[str, Path] = {}
        self.made: list[Path] = []  # folders this set created, removed again if the write fails and they stay empty

    def __enter__(self) -> "OutputSet":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.commit()
            return
        self.abort()
        if isinstance(exc, OSError):  # a writer that failed (a full disk): one line, no temporary left
            where = exc.filename if isinstance(exc.filename, str) else self.folder
            raise LinkFeaError(write_error(_target(Path(where)), exc)) from None

    def path(self, name: str) -> str:
        """A temporary path for member ``name`` (same suffix, so matplotlib and VTK pick the format)."""
        try:
            if not self.made and not self.folder.exists():
                self.made = [p for p in (self.folder, *self.folder.parents) if not p.exists()]
            self.folder.mkdir(parents=True, exist_ok=True)
            tmp = temp_beside(self.folder / name)
        except OSError as exc:
            raise LinkFeaError(write_error(self.folder / name, exc)) from None
        self.tmps[name] = tmp
        return str(tmp)

    def abort(self) -> None:
        """Remove this run's temporaries, and the folders it created if they are empty again (a full disk:
        "nothing was written" leaves nothing, not even an empty folder)."""
        for tmp in self.tmps.values():
            tmp.unlink(missing_ok=True)
        self.tmps.clear()
        for d in self.made:  # innermost first
            try:
                d.rmdir()
            except OSError:
                break
        self.made = []

    def digests(self) -> dict[str, str]:
        """sha256 of each member written so far (to record in a member that names its companions)."""
        return {n: sha256(t) for n, t in self.tmps.items()}

    def commit(self) -> list[Path]:
        """Flush the members, write the journal, rename them into place; the final paths."""
        try:
            return self._commit()
        except OSError as exc:
            self.abort()
            raise LinkFeaError(write_error(self.folder, exc)) from None

    def _commit(self) -> list[Path]:
        for tmp in self.tmps.values():
            fsync_file(tmp)
        fault("members-written")
        renames = [(t.name, n) for n, t in self.tmps.items()]
        remove = list(self.remove)
        journal = journal_path(self.folder, self.name, self.run)
        manifest_tmp = None
        try:
            if self.manifest:
                man = read_manifest(self.folder)
                before = (man["sets"].get(self.name) or {}).get("files") or {}
                remove += _superseded(self.folder, man, self.name, set(self.tmps))
                others = {n for k, s in man["sets"].items() if k != self.name for n in (s.get("files") or {})}
                # only files whose bytes are still those recorded: one the user edited is theirs now
                remove += sorted(n for n in set(before) - set(self.tmps) - others
                                 if not n.endswith("/") and unchanged(self.folder / n, before[n]))
                man["sets"][self.name] = {"files": self.digests(), "run": self.run,
                                          "written": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
                manifest_tmp = _write_temp(self.folder / MANIFEST, man)
                renames.append((manifest_tmp.name, MANIFEST))
            jt = _write_temp(journal, {"schema": JOURNAL_SCHEMA, "set": self.name, "run": self.run,
                                       "renames": renames, "remove": remove})
            os.replace(jt, journal)
        except OSError:  # before the commit point (a full disk): nothing of this run may stay
            if manifest_tmp is not None:
                manifest_tmp.unlink(missing_ok=True)
            raise
        fsync_dir(self.folder)
        fault("journal-written")
        for k, (tname, name) in enumerate(renames):
            try:
                os.replace(self.folder / tname, self.folder / name)
            except FileNotFoundError:
                # a concurrent run into this folder found the journal and finished these renames
                # (what the journal is for): the member is in place, the set complete
                if not (self.folder / name).exists():
                    raise
            if k == 0:
                fault("renamed-one")
        for name in remove:
            (self.folder / name).unlink(missing_ok=True)
        fsync_dir(self.folder)
        fault("renamed-all")
        journal.unlink(missing_ok=True)  # gone if a concurrent run finished the renames
        fsync_dir(self.folder)
        done = [self.folder / n for n in self.tmps]
        self.tmps, self.made = {}, []
        return done


def _superseded(folder: Path, man: dict, name: str, members: set) -> list[str]:
    """The files to remove of the other sets in manifest ``man`` that set ``name`` (writing ``members``)
    replaces: a set that rewrites one file of another set (``vjm calibrate`` into a ``vjm diagnose``
    folder: report.json) replaces that set whole, so that no file of the old run (its report.html) is
    left beside the new set as if it were of it.  Those sets leave ``man``; of their files only the ones
    still as recorded go (an edited one is the user's) and none that a remaining set also records."""
    gone = [k for k, s in man["sets"].items() if k != name and members & set(s.get("files") or {})]
    old = {n: d for k in gone for n, d in (man["sets"].pop(k).get("files") or {}).items()}
    keep = members | {n for s in man["sets"].values() for n in (s.get("files") or {})}
    return sorted(n for n, d in old.items() if n not in keep and _plain_name(n) and isinstance(d, str)
                  and unchanged(folder / n, d))


def claim(folder, names: Iterable[str], set_name: str) -> None:
    """Record ``names`` (e.g. a sub-folder ``results/``) as written by ``set_name`` in the manifest
    of ``folder`` before they are made, so that a run killed half way still owns them."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    man = read_manifest(folder)
    s = man["sets"].setdefault(set_name, {"files": {}})
    files = s.setdefault("files", {})
    if all(n in files for n in names):
        return
    files.update({n: None for n in names if n not in files})
    tmp = _write_temp(folder / MANIFEST, man)
    os.replace(tmp, folder / MANIFEST)
    fsync_dir(folder)


def _write_temp(target: Path, doc: dict) -> Path:
    tmp = temp_beside(target)
    try:
        with open(tmp, "w", encoding="utf-8") as fh:
            json.dump(doc, fh, indent=1)
            fh.flush()
            os.fsync(fh.fileno())
    except OSError:
        tmp.unlink(missing_ok=True)
        raise
    return tmp


def _slug(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "-" for c in name)
