"""The user's files: nothing deleted or overwritten that the tools did not write, output paths checked
before any work, folders at the user's umask, no stray temporaries, output sets all old or all new.

The SIGKILL runs of whole commands are in test_faults.py; here each rule is checked on its own, fast.
"""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from linkfea.cli import app as linkfea_app
from linkfea.files.outputs import MANIFEST, OutputSet, check_folder, read_manifest, recover, sha256
from linkfea.result.fileset import check_companion, companion_mismatch
from linkfea.runtime.errors import LinkFeaError
from vjm.cli import app as vjm_app

PUU = "data/orthoglide/puu.yaml"
ROOT = Path(__file__).resolve().parents[1]


def _error(r) -> str:
    """The one `error:` line of a refused command (exit status 2)."""
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.exit_code == 2 and len(lines) == 1 and lines[0].startswith("error: "), (r.exit_code, r.output)
    return lines[0]


def _tree(folder: Path) -> dict:
    """Every file under ``folder`` with its bytes (and the folders, as None)."""
    return {str(p.relative_to(folder)): (p.read_bytes() if p.is_file() else None) for p in folder.rglob("*")}


@pytest.fixture
def no_work(monkeypatch):
    """Any FEA, mesh or model loading fails the test: the output paths must be checked first."""
    import importlib

    def mod(name):  # the package re-exports functions under some module names
        return importlib.import_module(name)

    def started(*args, **kwargs):
        raise AssertionError("work started before the output path was checked")

    # modules that bind these functions by name at import: imported first, so that they keep the real ones
    for name in ("vjm.discrepancy.workflow", "vjm.discrepancy.simulate", "vjm.sweep.combine", "vjm.maps.compute"):
        mod(name)

    for name, attr in [("linkfea.pipeline", "compute"), ("linkfea.beam.compare", "fea_compliance"),
                       ("linkfea.sweep", "make_sweep"), ("vjm.modelio.read", "load_model"),
                       ("vjm.discrepancy.simulate", "load_model")]:
        monkeypatch.setattr(mod(name), attr, started)


# --------------------------------------------------------------------------- 1. data loss
def test_diagnose_into_the_users_folder_deletes_nothing(tmp_path, no_work):
    """`vjm diagnose puu m.csv --out .` removed m.csv and everything else: now one line naming a file
    of the user's and --force, before any work, and every file is as it was."""
    (tmp_path / "measurements.csv").write_text("x,y,z\n1,2,3\n")
    (tmp_path / "notes").mkdir()
    (tmp_path / "notes" / "a.txt").write_text("mine")
    before = _tree(tmp_path)
    r = CliRunner().invoke(vjm_app, ["diagnose", PUU, str(tmp_path / "measurements.csv"), "--out", str(tmp_path)])
    line = _error(r)
    assert ("measurements.csv" in line or "notes" in line) and "--force" in line
    assert _tree(tmp_path) == before


def test_force_never_overwrites_a_file_of_other_origin(tmp_path, no_work):
    (tmp_path / "report.html").write_text("my own report")
    r = CliRunner().invoke(vjm_app, ["diagnose", PUU, "m.csv", "--out", str(tmp_path), "--force"])
    assert "report.html" in _error(r)
    assert (tmp_path / "report.html").read_text() == "my own report"
    assert sorted(os.listdir(tmp_path)) == ["report.html"]


@pytest.mark.parametrize("cmd", [
    ["linkfea", "compare", "bar"],
    ["linkfea", "sweep", "bar", "--param", "width=10,20"],
    ["vjm", "map", PUU],
    ["vjm", "sweep", PUU, "--leg", "leg.json"],
    ["vjm", "diagnose", PUU, "m.csv"],
])
def test_every_folder_command_refuses_a_folder_of_other_origin_before_work(cmd, tmp_path, no_work):
    out = tmp_path / "d"
    out.mkdir()
    (out / "mine.txt").write_text("keep")
    app = linkfea_app if cmd[0] == "linkfea" else vjm_app
    r = CliRunner().invoke(app, [*cmd[1:], "--out", str(out)])
    line = _error(r)
    assert "mine.txt" in line and "--force" in line
    assert sorted(os.listdir(out)) == ["mine.txt"] and (out / "mine.txt").read_text() == "keep"


# --------------------------------------------------------------------------- 5. checks before work
@pytest.mark.parametrize("case", ["existing_text", "folder", "under_a_file", "unwritable", "foreign_vtu"])
def test_compute_out_is_checked_before_the_fea(case, tmp_path, no_work):
    """An --out that cannot be or must not be written is refused before meshing (no_work fails any FEA)."""
    out = {"existing_text": tmp_path / "existing_file.txt", "folder": tmp_path / "d",
           "under_a_file": tmp_path / "f.txt" / "r.json", "unwritable": Path("/proc/linkfea-no/r.json"),
           "foreign_vtu": tmp_path / "r.json"}[case]
    if case == "existing_text":
        out.write_text("not a result")
    if case == "folder":
        out.mkdir()
    if case == "under_a_file":
        (tmp_path / "f.txt").write_text("a file")
    if case == "foreign_vtu":
        (tmp_path / "r.vtu").write_text("someone's mesh")
    before = _tree(tmp_path)
    r = CliRunner().invoke(linkfea_app, ["compute", "bar", "--out", str(out)])
    _error(r)
    assert _tree(tmp_path) == before


def test_simulate_never_overwrites_measured_data_but_replaces_its_own(tmp_path):
    measured = tmp_path / "measured.csv"
    measured.write_text("x,y,z,Fx,Fy,Fz,Mx,My,Mz,dx,dy,dz\n")
    r = CliRunner().invoke(vjm_app, ["simulate", PUU, "--poses", "grid:2", "--out", str(measured)])
    assert "measured.csv" in _error(r)
    assert measured.read_text() == "x,y,z,Fx,Fy,Fz,Mx,My,Mz,dx,dy,dz\n"
    own = tmp_path / "sim.csv"
    for seed in ("1", "2"):
        r = CliRunner().invoke(vjm_app, ["simulate", PUU, "--poses", "grid:2", "--seed", seed, "--out", str(own)])
        assert r.exit_code == 0, r.output
    assert sorted(os.listdir(tmp_path)) == ["measured.csv", "sim.csv"]


# --------------------------------------------------------------------------- report folders
@pytest.fixture(scope="module")
def diagnosis(tmp_path_factory):
    """A diagnosis of clean data from the independent true machine of tests/truth.py."""
    import truth as tr

    from vjm.discrepancy.workflow import diagnose

    d = tmp_path_factory.mktemp("truth")
    given, machine = tr.hide()
    P, W = tr.design(6, 6, seed=0)
    data = tr.measure(machine, P, W, seed=0).write(d / "measured.csv")
    return diagnose(tr.write_model(given, d / "model.yaml"), data, effects=["gravity"])


def test_report_folder_gets_the_users_umask_and_no_temporaries(tmp_path, diagnosis):
    from vjm.discrepancy.diagnosis import write_diagnosis

    old = os.umask(0o027)
    try:
        write_diagnosis(diagnosis, tmp_path / "rep")
    finally:
        os.umask(old)
    rep = tmp_path / "rep"
    assert rep.stat().st_mode & 0o777 == 0o750
    assert all(p.stat().st_mode & 0o777 == 0o640 for p in rep.iterdir())
    assert sorted(os.listdir(tmp_path)) == ["rep"]


def test_rerun_replaces_its_own_report_and_nothing_else(tmp_path, diagnosis):
    from vjm.discrepancy.diagnosis import write_diagnosis

    rep = tmp_path / "rep"
    rep.mkdir()
    (rep / "notes.txt").write_text("mine")
    with pytest.raises(LinkFeaError, match="notes.txt"):
        write_diagnosis(diagnosis, rep)
    write_diagnosis(diagnosis, rep, force=True)
    first = json.loads((rep / "report.json").read_text())
    stale = rep / f".linkfea-tmp.{2**31 - 2}.x1y2z3w4.report.json"  # a dead process's temporary
    stale.write_text("{")
    write_diagnosis(diagnosis, rep, force=True)
    assert json.loads((rep / "report.json").read_text()) == first
    assert (rep / "notes.txt").read_text() == "mine"
    assert sorted(os.listdir(rep)) == sorted([MANIFEST, "notes.txt", "report.json", "report.html", "before_after.png",
                                              "residuals_per_posture.png", "model_updated.yaml"])


# --------------------------------------------------------------------------- sets
def test_a_rerun_removes_only_its_own_files_that_it_no_longer_writes(tmp_path):
    with OutputSet(tmp_path, "a") as s:
        for n in ("x.txt", "y.txt"):
            Path(s.path(n)).write_text(f"a {n}")
    with OutputSet(tmp_path, "b") as s:
        Path(s.path("z.txt")).write_text("b")
    (tmp_path / "user.txt").write_text("user")
    with OutputSet(tmp_path, "a") as s:
        Path(s.path("x.txt")).write_text("a again")
    assert sorted(os.listdir(tmp_path)) == [MANIFEST, "user.txt", "x.txt", "z.txt"]
    man = read_manifest(tmp_path)["sets"]
    assert man["a"]["files"] == {"x.txt": sha256(tmp_path / "x.txt")} and "z.txt" in man["b"]["files"]


def test_a_failing_writer_leaves_the_old_set_and_no_temporary(tmp_path):
    with OutputSet(tmp_path, "a") as s:
        Path(s.path("x.txt")).write_text("old")
    with pytest.raises(RuntimeError):
        with OutputSet(tmp_path, "a") as s:
            Path(s.path("x.txt")).write_text("new")
            raise RuntimeError("the picture failed")
    assert sorted(os.listdir(tmp_path)) == [MANIFEST, "x.txt"] and (tmp_path / "x.txt").read_text() == "old"


WRITER = """
import sys
from pathlib import Path
from linkfea.files.outputs import OutputSet
with OutputSet(sys.argv[1], "t") as s:
    for n in ("a.txt", "b.txt", "c.txt"):
        Path(s.path(n)).write_text(sys.argv[2])
"""


@pytest.mark.parametrize("point,new", [("members-written", False), ("journal-written", True),
                                       ("renamed-one", True), ("renamed-all", True)])
def test_sigkill_at_each_point_leaves_the_old_set_or_the_new_one(point, new, tmp_path):
    """Killed before the journal: the old set, untouched on disk; after it: the new set, complete once
    the next run (or reader) has looked at the folder.  No temporary survives that next run."""
    subprocess.run([sys.executable, "-c", WRITER, str(tmp_path), "old"], check=True)
    p = subprocess.run([sys.executable, "-c", WRITER, str(tmp_path), "new"], env={**os.environ, "LINKFEA_FAULT": point})
    assert p.returncode == -9
    if not new:
        assert all((tmp_path / n).read_text() == "old" for n in ("a.txt", "b.txt", "c.txt"))
    recover(tmp_path)
    want = "new" if new else "old"
    assert [(tmp_path / n).read_text() for n in ("a.txt", "b.txt", "c.txt")] == [want] * 3
    assert sorted(os.listdir(tmp_path)) == [MANIFEST, "a.txt", "b.txt", "c.txt"]
    files = read_manifest(tmp_path)["sets"]["t"]["files"]
    assert files == {n: sha256(tmp_path / n) for n in ("a.txt", "b.txt", "c.txt")}


def test_check_folder_rolls_a_killed_commit_forward(tmp_path):
    subprocess.run([sys.executable, "-c", WRITER, str(tmp_path), "old"], check=True)
    p = subprocess.run([sys.executable, "-c", WRITER, str(tmp_path), "new"],
                       env={**os.environ, "LINKFEA_FAULT": "renamed-one"})
    assert p.returncode == -9
    check_folder(tmp_path, ["a.txt"])
    assert {(tmp_path / n).read_text() for n in ("a.txt", "b.txt", "c.txt")} == {"new"}


def test_a_result_json_refuses_a_vtu_that_is_not_its_own(tmp_path):
    (tmp_path / "r.vtu").write_bytes(b"mesh one")
    doc = {"schema": "linkfea.result/1", "files": {"vtu": {"name": "r.vtu", "sha256": sha256(tmp_path / "r.vtu")}}}
    (tmp_path / "r.json").write_text(json.dumps(doc))
    assert companion_mismatch(tmp_path / "r.json") is None
    (tmp_path / "r.vtu").write_bytes(b"mesh two")
    assert "sha256" in companion_mismatch(tmp_path / "r.json")
    with pytest.raises(LinkFeaError, match="r.vtu"):
        check_companion(tmp_path / "r.json")


def test_results_written_outside_a_manifest_are_recognised_as_the_tools_own(tmp_path):
    """A folder holding `linkfea compute` and `vjm simulate` outputs takes a report without --force;
    a JSON of another schema beside them is of other origin, and so is a .vtu or .png whose bytes the
    result JSON does not record."""
    (tmp_path / "foot.vtu").write_text("mesh")
    (tmp_path / "foot.png").write_text("picture")
    files = {k: {"name": f"foot.{k}", "sha256": sha256(tmp_path / f"foot.{k}")} for k in ("vtu", "png")}
    (tmp_path / "foot.json").write_text(json.dumps({"schema": "linkfea.result/1", "files": files}))
    from linkfea.files.atomic import write_text

    write_text(tmp_path / "m.csv", "# simulated by vjm simulate from puu.yaml\nx,y,z\n")  # sealed by its writer
    check_folder(tmp_path, ["report.json"])
    (tmp_path / "foot.png").write_text("my own picture")
    with pytest.raises(LinkFeaError, match="foot.png"):
        check_folder(tmp_path, ["report.json"])
    (tmp_path / "foot.png").write_text("picture")
    (tmp_path / "other.json").write_text(json.dumps({"schema": "someone/1"}))
    with pytest.raises(LinkFeaError, match="other.json"):
        check_folder(tmp_path, ["report.json"])


# --------------------------------------------------------------------------- bytes decide, not names
def test_a_file_of_the_set_edited_since_is_the_users_and_never_removed(tmp_path):
    """A rerun removes the files of its previous run that it no longer writes, but only while their bytes are
    the ones recorded: an edited one is the user's now (kept, and refused as a target)."""
    with OutputSet(tmp_path, "a") as s:
        for n in ("x.txt", "y.txt"):
            Path(s.path(n)).write_text(f"a {n}")
    (tmp_path / "y.txt").write_text("a y.txt, with my notes")
    with pytest.raises(LinkFeaError, match="y.txt was changed since linkfea or vjm wrote it"):
        check_folder(tmp_path, ["x.txt", "y.txt"], force=True)
    with OutputSet(tmp_path, "a") as s:
        Path(s.path("x.txt")).write_text("a again")
    assert (tmp_path / "y.txt").read_text() == "a y.txt, with my notes"
    with pytest.raises(LinkFeaError, match="y.txt is there and was not written by linkfea or vjm"):
        check_folder(tmp_path, ["x.txt", "y.txt"], force=True)


def test_a_rerun_without_pictures_keeps_a_picture_the_json_does_not_record(tmp_path):
    """`linkfea compute --no-picture` removes the .vtu/.png of the earlier result only if their bytes are the
    ones that result recorded: a picture the user put there instead stays."""
    from linkfea.files.outputs import own_companions

    (tmp_path / "r.vtu").write_text("the tool's mesh")
    (tmp_path / "r.png").write_text("the user's picture")
    doc = {"schema": "linkfea.result/1", "files": {k: {"name": f"r.{k}", "sha256": sha256(tmp_path / "r.vtu")}
                                                   for k in ("vtu", "png")}}
    (tmp_path / "r.json").write_text(json.dumps(doc))
    assert own_companions(tmp_path / "r.json") == {"r.vtu"}


# --------------------------------------------------------------------------- model files
def _saves(diagnosis):
    import vjm

    m = vjm.load_model(PUU)
    return {"Model.save": m.save, "vjm.save_model": lambda p: vjm.save_model(m, p),
            "Diagnosis.updated_model.save": diagnosis.updated_model.save}


@pytest.mark.parametrize("how", ["Model.save", "vjm.save_model", "Diagnosis.updated_model.save"])
def test_saving_a_model_never_replaces_a_file_vjm_did_not_write(how, tmp_path, diagnosis):
    """A user's analysis.py is not turned into YAML; a model file vjm wrote is replaced; once edited, it is
    the user's and refused; a dangling link is refused, not replaced.  Nothing else is left in the folder."""
    import vjm

    save = _saves(diagnosis)[how]
    mine = tmp_path / "analysis.py"
    mine.write_text("import vjm\n")
    with pytest.raises(ValueError, match="analysis.py exists and is not a model file vjm wrote"):
        save(mine)
    assert mine.read_text() == "import vjm\n"
    own = tmp_path / "m.yaml"
    save(own)
    save(own)  # its own file: replaced
    assert vjm.load_model(own).name == vjm.load_model(PUU).name
    with open(own, "a", encoding="utf-8") as fh:
        fh.write("# calibrated on Monday\n")
    edited = own.read_bytes()
    with pytest.raises(ValueError, match="changed since"):
        save(own)
    assert own.read_bytes() == edited
    (tmp_path / "link.yaml").symlink_to("elsewhere/m.yaml")
    with pytest.raises(ValueError, match="symbolic link to elsewhere/m.yaml, which does not exist"):
        save(tmp_path / "link.yaml")
    assert sorted(os.listdir(tmp_path)) == ["analysis.py", "link.yaml", "m.yaml"]


def test_the_report_model_file_is_recognised_as_vjms_own(tmp_path, diagnosis):
    """model_updated.yaml of a report carries the checksum line, so `updated_model.save` may replace it."""
    from vjm.discrepancy.diagnosis import write_diagnosis
    from vjm.modelio.write import own_model_file

    write_diagnosis(diagnosis, tmp_path / "rep")
    assert own_model_file(tmp_path / "rep" / "model_updated.yaml")
    text = (tmp_path / "rep" / "model_updated.yaml").read_text()
    (tmp_path / "copy.yaml").write_text(text.replace("name:", "name: x", 1))
    assert not own_model_file(tmp_path / "copy.yaml")


# --------------------------------------------------------------------------- input files, full disks
def test_input_files_are_read_only_when_regular_and_bounded(tmp_path):
    from linkfea.files.atomic import read_user_file

    (tmp_path / "m.csv").write_text("x,y,z\n" * 100)
    assert len(read_user_file(tmp_path / "m.csv", "measurement file")) == 600
    with pytest.raises(LinkFeaError, match="larger than"):
        read_user_file(tmp_path / "m.csv", "measurement file", limit=500)
    os.mkfifo(tmp_path / "fifo.csv")  # a pipe nobody writes to must not block the read
    with pytest.raises(LinkFeaError, match="not a regular file"):
        read_user_file(tmp_path / "fifo.csv", "measurement file")
    with pytest.raises(LinkFeaError, match="it is a folder"):
        read_user_file(tmp_path, "measurement file")


def test_a_full_disk_while_writing_a_set_is_one_line_naming_the_device_and_leaves_nothing(tmp_path):
    import errno

    with pytest.raises(LinkFeaError) as err:
        with OutputSet(tmp_path / "out", "a") as s:
            Path(s.path("x.txt")).write_text("x")
            tmp = s.path("r.vtu")
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), tmp)
    line = str(err.value)
    assert "\n" not in line and "no space left on" in line and "mounted at /" in line
    assert line.startswith(f"cannot write {tmp_path / 'out' / 'r.vtu'}:"), line
    assert not (tmp_path / "out").exists()  # nothing was written: not even the folder the set made


def test_the_vtu_writer_reports_a_full_disk_instead_of_crashing(tmp_path):
    """VTK's own file writer dies with SIGSEGV on a full disk: the mesh is written by Python, which raises.
    (/dev/full fails every write with ENOSPC; the writer follows the link as it would a temporary file.)"""
    import errno
    from types import SimpleNamespace

    from linkfea.result.post import write_vtu

    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [.5, 0, 0], [.5, .5, 0], [0, .5, 0], [0, 0, .5],
                    [.5, 0, .5], [0, .5, .5]], float)
    sol = SimpleNamespace(points=pts, cells=np.arange(10)[None, :], displacements=[np.ones((10, 3))] * 6)
    res = SimpleNamespace(name="t", solution=sol, mesh=SimpleNamespace(block=np.zeros(1, np.int8)))
    write_vtu(tmp_path / "ok.vtu", res)
    import pyvista as pv

    assert np.allclose(pv.read(tmp_path / "ok.vtu").point_data["u_Mz"], 1.0)
    if not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full here")
    (tmp_path / "full.vtu").symlink_to("/dev/full")
    with pytest.raises(OSError) as err:
        write_vtu(tmp_path / "full.vtu", res)
    assert err.value.errno == errno.ENOSPC and err.value.filename == str(tmp_path / "full.vtu")


def test_a_full_disk_at_the_journal_leaves_the_old_set_and_no_temporary(tmp_path, monkeypatch):
    """The members fit but the journal does not: the old set stays, and neither the members' temporaries nor
    the new manifest's or journal's are left to keep the disk full."""
    import errno

    with OutputSet(tmp_path, "a") as s:
        Path(s.path("x.txt")).write_text("old")
    before = _tree(tmp_path)
    real = json.dump

    def dump(doc, fh, **kw):
        if "renames" in doc:
            fh.write("{")
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real(doc, fh, **kw)

    monkeypatch.setattr(json, "dump", dump)
    with pytest.raises(LinkFeaError, match="no space left on"):
        with OutputSet(tmp_path, "a") as s:
            Path(s.path("x.txt")).write_text("new")
    assert _tree(tmp_path) == before
