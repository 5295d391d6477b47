"""`linkfea compute` end to end on a coarse bar, and its failure modes."""
import json
import os
import shlex
import subprocess
import sys

import numpy as np
import pytest
from bad_inputs import Case, run
from typer.testing import CliRunner

from linkfea.cli import app
from linkfea.result.schema import read_result, write_json_atomic
from linkfea.runtime.errors import LinkFeaError

KEYS = {"compliance", "stiffness", "units", "frame", "mesh", "diagnostics", "timing", "versions",
        "name", "params", "material", "mode"}


@pytest.fixture(scope="module")
def env(tmp_path_factory):
    e = dict(os.environ)
    e["LINKFEA_CACHE_DIR"] = str(tmp_path_factory.mktemp("meshes"))
    return e


@pytest.fixture(scope="module")
def run_ok(tmp_path_factory, env):
    out = tmp_path_factory.mktemp("cli") / "res" / "bar.json"
    runner = CliRunner()
    r = runner.invoke(app, ["compute", "bar", "--param", "length=120", "--mesh-size", "6", "--out", str(out)],
                      env={"LINKFEA_CACHE_DIR": env["LINKFEA_CACHE_DIR"]})
    assert r.exit_code == 0, r.output
    return out, r.output


def test_cli_writes_json_vtu_png(run_ok):
    out, text = run_ok
    doc = json.loads(out.read_text())
    assert KEYS <= set(doc)
    assert {"n_nodes", "n_tets", "n_dofs", "edge_length", "quality"} <= set(doc["mesh"])
    import gmsh

    assert doc["mesh"]["mesher"] == "gmsh" and doc["mesh"]["mesher_version"] == gmsh.__version__
    assert doc["versions"]["gmsh"] == gmsh.__version__
    assert {"symmetry_error", "fit_residual", "min_eigenvalue", "error_estimate"} <= set(doc["diagnostics"])
    assert doc["diagnostics"]["error_estimate"] is None
    assert {"cad", "mesh", "assemble", "factor", "solve", "fit"} <= set(doc["timing"])
    assert doc["params"]["length"] == 120.0 and doc["mode"] == "rigid"
    C, K = np.array(doc["compliance"]), np.array(doc["stiffness"])
    np.testing.assert_allclose(C, C.T, rtol=0, atol=1e-12 * np.abs(C).max())
    assert np.all(np.linalg.eigvalsh(C) > 0)
    np.testing.assert_allclose(C @ K, np.eye(6), atol=1e-8)
    np.testing.assert_allclose(doc["frame"]["origin"], [120.0, 0.0, 0.0])
    png = out.with_suffix(".png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 5000
    import meshio

    vtu = meshio.read(out.with_suffix(".vtu"))
    assert "u_Fy" in vtu.point_data and vtu.point_data["u_Fy"].shape == (len(vtu.points), 3)
    assert "compliance" in text and "stiffness" in text


def test_read_result_validates(run_ok, tmp_path):
    out, _ = run_ok
    doc = read_result(out)
    assert doc["compliance"].shape == (6, 6)
    np.testing.assert_allclose(doc["frame_obj"].origin, [120.0, 0.0, 0.0])
    raw = json.loads(out.read_text())
    bad = dict(raw, compliance=(np.array(raw["compliance"]) + np.triu(np.ones((6, 6)), 1) * 1e-3).tolist())
    write_json_atomic(tmp_path / "asym.json", bad)
    with pytest.raises(LinkFeaError, match="symmetric"):
        read_result(tmp_path / "asym.json")
    neg = dict(raw, compliance=(-np.eye(6)).tolist())
    write_json_atomic(tmp_path / "neg.json", neg)
    with pytest.raises(LinkFeaError, match="positive definite"):
        read_result(tmp_path / "neg.json")
    with pytest.raises(LinkFeaError, match="not found"):
        read_result(tmp_path / "nothing.json")
    (tmp_path / "short.json").write_text(json.dumps({"compliance": [[1.0]]}))
    with pytest.raises(LinkFeaError, match="missing"):
        read_result(tmp_path / "short.json")


@pytest.mark.parametrize("args", [
    ["bar", "--param", "length=0"],
    ["bar", "--param", "width=nan"],
    ["bar", "--material", "unobtainium"],
    ["bar", "--param", "colour=red"],
    ["bar", "--tip", "plane:x=99"],
    ["bar", "--base", "plane:x=200", "--tip", "plane:x=200"],
    ["bar", "--mode", "elastic"],
    ["bar", "--mesher", "netgen"],
    ["missing.step", "--base", "plane:x=0", "--tip", "plane:x=1"],
])
def test_bad_input_gives_one_error_line_and_no_file(args, env, tmp_path, monkeypatch):
    """In process, as the bad-input table runs its cases (``main`` returns the exit status); the status of a
    real ``linkfea`` process is test_surface.py's test_open_stl_is_one_error_line_and_no_file (three refused surfaces) and
    test_ctrl_c_during_meshing_stops_at_once's."""
    monkeypatch.setenv("LINKFEA_CACHE_DIR", env["LINKFEA_CACHE_DIR"])
    res = run(Case("", shlex.join(["linkfea", "compute", *args, "--out", "o/r.json"]), ""), tmp_path)
    assert res.status == 2, res.stderr
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), res.stderr
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())


def test_broken_step_via_cli(env, tmp_path, monkeypatch):
    """An open shell written as STEP: one ``error:`` line naming the missing closed solid, exit 2, nothing
    written (in process, as the cases above)."""
    import cadquery as cq

    box = cq.Workplane().box(100, 10, 10, centered=(False, True, True)).val()
    shell = cq.Shell.makeShell([f for f in box.Faces() if f.Center().x < 99.0])
    step = tmp_path / "open.step"
    cq.exporters.export(cq.Workplane().add(shell), str(step))
    monkeypatch.setenv("LINKFEA_CACHE_DIR", env["LINKFEA_CACHE_DIR"])
    (tmp_path / "run").mkdir()
    res = run(Case("", shlex.join(["linkfea", "compute", str(step), "--base", "plane:x=0", "--tip", "plane:x=100",
                                   "--out", "o/r.json"]), ""), tmp_path / "run")
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.status == 2 and len(lines) == 1 and lines[0].startswith("error: ") and "closed solid" in lines[0], \
        res.stderr
    assert res.changed == [] and not (tmp_path / "run" / "o").exists()


def _children(pid: int) -> list[int]:
    try:
        with open(f"/proc/{pid}/task/{pid}/children") as fh:
            return [int(x) for x in fh.read().split()]
    except OSError:
        return []


@pytest.mark.skipif(not os.path.exists(f"/proc/{os.getpid()}/task/{os.getpid()}/children"), reason="needs Linux /proc")
def test_ctrl_c_during_meshing_stops_at_once(env, tmp_path):
    """SIGINT while gmsh meshes (a 1 mm bar: 20 s of meshing) ends the command within seconds: status 130,
    one ``error:`` line, nothing written, and no mesher left running (it ran in a child process)."""
    import signal
    import time

    e = dict(env, LINKFEA_MEMORY="100")  # the estimate must let this mesh through on any machine
    p = subprocess.Popen([sys.executable, "-m", "linkfea", "compute", "bar", "--mesh-size", "1", "--out",
                          str(tmp_path / "r.json")], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=e,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))  # even if we ignore it
    try:
        t0 = time.monotonic()
        while not _children(p.pid) and p.poll() is None and time.monotonic() - t0 < 120:
            time.sleep(0.05)
        mesher = _children(p.pid)
        assert mesher, "the mesher did not start in a child process"
        time.sleep(1.0)
        p.send_signal(signal.SIGINT)
        out, err = p.communicate(timeout=10)
    finally:
        p.kill()
        p.wait()
    assert p.returncode == 130, err
    assert err.strip().splitlines() == ["error: interrupted (Ctrl-C)"], err
    assert list(tmp_path.iterdir()) == []
    assert not os.path.exists(f"/proc/{mesher[0]}") or open(f"/proc/{mesher[0]}/stat").read().split()[2] == "Z"


def test_traceback_shows_the_scripts_own_frames(tmp_path, monkeypatch, capsys):
    """A failing link script: one ``error:`` line naming the script, line and exception (exit 2); with
    ``--traceback`` the script's own frames come before it, and no frame of linkfea."""
    from linkfea.cli import main

    (tmp_path / "s.py").write_text("PARAMS = {}\n\n\ndef helper():\n    raise ValueError('no such bore')\n\n\n"
                                   "def build(**p):\n    return helper()\n")
    monkeypatch.chdir(tmp_path)
    assert main(["compute", "s.py", "--out", "r.json"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "s.py, line 5: ValueError: no such bore" in err[0]
    assert main(["compute", "s.py", "--out", "r.json", "--traceback"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0] == "Traceback (most recent call last):" and err[-1].startswith("error: ")
    frames = [ln for ln in err if ln.lstrip().startswith("File ")]
    assert [f.split(", in ")[-1] for f in frames] == ["build", "helper"] and all("s.py" in f for f in frames)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.py"]  # no r.json, no __pycache__


def test_the_mesher_child_returns_its_result_and_raises_its_errors():
    """``run_in_child`` runs in another process (its pid differs) where Ctrl-C can reach the caller, and gives
    back the value or the exception (type and message) of the function."""
    from linkfea.runtime.child import interruptible_here, run_in_child

    if not interruptible_here():
        pytest.skip("SIGINT is not Python's here (a worker thread or an ignored signal)")
    assert run_in_child(os.getpid) != os.getpid()
    assert run_in_child(np.arange, 3).tolist() == [0, 1, 2]

    def fails():
        raise LinkFeaError("the mesher said no")

    with pytest.raises(LinkFeaError, match="the mesher said no"):
        run_in_child(fails)
