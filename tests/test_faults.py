"""Fault injection: whole commands SIGKILLed inside their write path (``LINKFEA_FAULT=<point>``,
see linkfea.files.outputs.FAULT_POINTS), then checked: every output set is the old one or the new one,
a rerun succeeds, and no temporary is left after it.

Which run wrote a file is read from the file itself, independently of the tool's own records:
the bar's length from the mesh's extent in the .vtu, the data file's name in the report, and
bytes compared with the set before the kill.  Coarsest meshes: each command runs in seconds.
"""
import json
import os
import shlex
import signal
import subprocess
from pathlib import Path

import bad_inputs
import freshrun
import pytest

import linkfea
from linkfea.files.outputs import MANIFEST, read_manifest, recover, sha256
from linkfea.runtime.errors import LinkFeaError

ROOT = Path(__file__).resolve().parents[1]
PUU = str(ROOT / "data" / "orthoglide" / "puu.yaml")
#: killed before the journal is written: the old set; after: the new one
POINTS = [("members-written", "old"), ("journal-written", "new"), ("renamed-one", "new")]


@pytest.fixture(scope="module")
def env(tmp_path_factory):
    e = dict(os.environ)
    e["LINKFEA_CACHE_DIR"] = str(tmp_path_factory.mktemp("meshes"))
    e.pop("LINKFEA_FAULT", None)
    return e


def run(tool, args, env, fault=None, cwd=None):
    """Run ``tool args`` in a process of its own (tests/freshrun.py: forked from one that has imported the
    packages, in its own process group); what is left of the group afterwards (the workers of a killed sweep)
    is killed."""
    e = dict(env, **({"LINKFEA_FAULT": fault} if fault else {}))
    res = freshrun.command([tool, *args], cwd or os.getcwd(), e)
    return res.returncode, res.stderr


def in_process(tool, args, env, monkeypatch, cwd):
    """A run that is not killed, in this process (as the bad-input table runs its cases): the state before a
    kill and the rerun after it need no process of their own; the killed runs do."""
    monkeypatch.setenv("LINKFEA_CACHE_DIR", env["LINKFEA_CACHE_DIR"])
    res = bad_inputs.run(bad_inputs.Case("", shlex.join([tool, *map(str, args)]), ""), cwd)
    return res.status, res.stderr


def no_temporaries(folder: Path):
    left = [p.name for p in folder.rglob("*") if p.name.startswith((".linkfea-tmp", ".linkfea-journal", ".tmp_", ".old_"))]
    assert not left, left


# --------------------------------------------------------------------------- linkfea compute
def _bar_length(vtu: Path) -> float:
    import pyvista as pv

    return float(pv.read(vtu).points[:, 0].max())


def test_compute_killed_while_writing_json_vtu_png(tmp_path, env, monkeypatch):
    """Lengths 200 and 150 mm alternate; after each kill the JSON, the mesh in the VTU and the PNG
    are all of one run (the PNG and JSON bytes are the old ones exactly when the run is the old one)."""
    out = tmp_path / "r.json"

    def compute(length, fault=None):
        args = ["compute", "bar", "--mesh-size", "60", "--param", f"length={length}", "--out", str(out), "-q"]
        return run("linkfea", args, env, fault) if fault else in_process("linkfea", args, env, monkeypatch, tmp_path)

    assert compute(200)[0] == 0
    length = 200
    for point, which in POINTS:
        old = {p.name: p.read_bytes() for p in tmp_path.iterdir() if not p.name.startswith(".")}
        new = 350 - length
        rc, err = compute(new, point)
        assert rc == -signal.SIGKILL, err
        if which == "old":  # nothing renamed yet: the files on disk are the old set, byte for byte
            assert all((tmp_path / n).read_bytes() == b for n, b in old.items())
        res = linkfea.load(out)  # the reader completes a committed write first
        want = length if which == "old" else new
        assert res.params["length"] == want
        assert abs(_bar_length(tmp_path / "r.vtu") - want) < 20  # the mesh is the JSON's own (lengths 50 apart)
        assert ((tmp_path / "r.png").read_bytes() == old["r.png"]) == (which == "old")
        assert json.loads(out.read_text())["files"]["png"]["sha256"] == sha256(tmp_path / "r.png")
        length = want
    # a .vtu of another run beside the JSON is detected, not shown as this result's mesh
    (tmp_path / "r.vtu").write_bytes(old["r.vtu"])
    with pytest.raises(LinkFeaError, match="r.vtu"):
        linkfea.load(out).to_pyvista()
    # a rerun (without pictures) succeeds, leaves no temporary, and removes the earlier result's own
    # .png, which would not match the new JSON; the .vtu whose bytes the JSON does not record is not
    # the tool's to remove and stays as it is
    rc, err = in_process("linkfea", ["compute", "bar", "--mesh-size", "60", "--no-picture", "--out", str(out), "-q"], env,
                         monkeypatch, tmp_path)
    assert rc == 0, err
    assert sorted(os.listdir(tmp_path)) == ["r.json", "r.vtu"] and (tmp_path / "r.vtu").read_bytes() == old["r.vtu"]


# --------------------------------------------------------------------------- vjm diagnose
def test_diagnose_killed_while_writing_the_report(tmp_path, env, monkeypatch):
    """Two data files alternate; after each kill report.json, report.html and the figures are of one
    run, and the user's own file in the folder (written with --force) is untouched."""
    for k in (1, 2):
        rc, err = in_process("vjm", ["simulate", PUU, "--poses", "grid:2", "--seed", str(k), "--out", f"m{k}.csv"], env,
                             monkeypatch, tmp_path)
        assert rc == 0, err
    rep = tmp_path / "rep"
    rep.mkdir()
    (rep / "notes.txt").write_text("mine")

    def diagnose(k, fault=None):
        args = ["diagnose", PUU, f"m{k}.csv", "--effect", "gravity", "--out", "rep", "--force"]
        return run("vjm", args, env, fault, cwd=tmp_path) if fault else in_process("vjm", args, env, monkeypatch,
                                                                                    tmp_path)

    assert diagnose(1)[0] == 0
    data = 1
    for point, which in POINTS:
        old = {n: (rep / n).read_bytes() for n in ("report.json", "before_after.png", "residuals_per_posture.png")}
        new = 3 - data
        rc, err = diagnose(new, point)
        assert rc == -signal.SIGKILL, err
        if which == "old":
            assert all((rep / n).read_bytes() == b for n, b in old.items())
        recover(rep)  # what the next run does first
        want = data if which == "old" else new
        doc = json.loads((rep / "report.json").read_text())
        assert doc["data"].endswith(f"m{want}.csv")
        assert f"m{want}.csv" in (rep / "report.html").read_text()
        assert ((rep / "residuals_per_posture.png").read_bytes() == old["residuals_per_posture.png"]) == (which == "old")
        assert (rep / "notes.txt").read_text() == "mine"
        data = want
    assert diagnose(3 - data)[0] == 0
    no_temporaries(tmp_path)
    assert sorted(os.listdir(rep)) == sorted([MANIFEST, "notes.txt", "report.json", "report.html", "before_after.png",
                                              "residuals_per_posture.png", "model_updated.yaml"])


# --------------------------------------------------------------------------- linkfea sweep
def test_sweep_killed_after_a_design_and_while_writing_the_table(tmp_path, env):
    out = tmp_path / "sw"

    def sweep(fault=None, plot="dx_Fx"):
        return run("linkfea", ["sweep", "bar", "--param", "width=20,25", "--mesh-size", "60", "--workers", "1",
                               "--plot", plot, "--out", str(out), "-q"], env, fault)

    rc, err = sweep("design-written")
    assert rc == -signal.SIGKILL, err
    done = list((out / "results").glob("*.json"))
    assert len(done) == 1 and json.loads(done[0].read_text())["sweep"]["status"] == "ok"
    assert not any(out.glob("sweep.*"))  # no table yet: the old (empty) set
    rc, err = sweep()
    assert rc == 0, err
    table = json.loads((out / "sweep.json").read_text())
    assert table["counts"] == {"ok": 2, "failed": 0, "not_run": 0}
    old_png = (out / "sweep.png").read_bytes()
    rc, err = sweep("renamed-one", plot="dy_Fy")  # nothing to compute: straight to the table
    assert rc == -signal.SIGKILL, err
    recover(out)
    files = read_manifest(out)["sets"]["linkfea sweep"]["files"]
    assert files == {n: sha256(out / n) for n in ("sweep.parquet", "sweep.csv", "sweep.json", "sweep.png")}
    assert (out / "sweep.png").read_bytes() != old_png  # the new plot, with the rest of its set
    assert sweep()[0] == 0
    no_temporaries(out)
    assert sorted(os.listdir(out)) == [MANIFEST, "results", "sweep.csv", "sweep.json", "sweep.parquet", "sweep.png"]


# --------------------------------------------------------------------------- a full disk
def test_compute_on_a_full_disk_is_one_line_naming_the_device_and_leaves_nothing(tmp_path, env):
    """On a 16 KB tmpfs the .vtu (26 KB) does not fit: VTK's writer used to die with SIGSEGV (exit 139), leaving its
    temporary to keep the disk full.  Now: one error line naming the device, exit 2, the folder empty."""
    if os.geteuid() != 0:
        pytest.skip("mounting a small tmpfs needs root")
    mnt = tmp_path / "full"
    mnt.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=16k", "tmpfs", str(mnt)], capture_output=True).returncode:
        pytest.skip("cannot mount a tmpfs here")
    try:
        rc, err = run("linkfea", ["compute", "bar", "--mesh-size", "60", "--out", str(mnt / "r.json"), "-q"], env)
        lines = err.strip().splitlines()
        assert rc == 2 and len(lines) == 1 and lines[0].startswith("error: "), (rc, err)
        assert f"no space left on device tmpfs (mounted at {mnt})" in lines[0], lines[0]
        assert os.listdir(mnt) == []
    finally:
        subprocess.run(["umount", str(mnt)], check=False)
