"""docs/examples/*.py run as they are (from a scratch folder), and what they print is checked.

Each example is a short script in notebook style (``# %%`` cells); the README points to them,
so an API change that breaks them fails here.
"""
import json
import runpy
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from linkfea.beam.closed_form import cantilever_compliance, rect_section
from linkfea.mechanics.materials import get_material

EXAMPLES = Path(__file__).resolve().parents[1] / "docs" / "examples"


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    """One scratch folder for all examples: the mesh cache (.cache/meshes) is shared between them."""
    return tmp_path_factory.mktemp("examples")


def _run(name, workdir, monkeypatch):
    monkeypatch.chdir(workdir)
    monkeypatch.setenv("LINKFEA_CACHE_DIR", str(workdir / ".cache" / "meshes"))
    return runpy.run_path(str(EXAMPLES / f"{name}.py"), run_name="__main__")


def _png(path):
    with Image.open(path) as im:
        return im.size


def test_all_examples_are_tested():
    assert sorted(p.stem for p in EXAMPLES.glob("*.py")) == sorted(
        ["beam_vs_fea", "cad_to_compliance", "diagnose", "machine_map_from_fea", "serial_robot"])


def test_cad_to_compliance(workdir, monkeypatch):
    ns = _run("cad_to_compliance", workdir, monkeypatch)
    C = ns["C"]
    assert np.allclose(C, C.T, rtol=0, atol=1e-12 * np.abs(C).max())
    # a 100 x 20 x 10 mm steel cantilever: Timoshenko with Cowper's kappa, Saint-Venant torsion
    steel = get_material("steel")
    ref = cantilever_compliance(100.0, rect_section(20.0, 10.0, steel.nu), steel.E, steel.nu)
    assert np.all(np.abs(np.diag(C) / np.diag(ref) - 1.0) < 0.08)
    w, h = _png(workdir / ns["png"])
    assert w > 100 and h > 100
    assert np.array_equal(ns["same"].compliance, C)  # saved and loaded back exactly


def test_beam_vs_fea(workdir, monkeypatch):
    ns = _run("beam_vs_fea", workdir, monkeypatch)
    out = workdir / ns["OUT"]
    rec = json.loads((out / "compare.json").read_text())
    assert np.array_equal(np.array(rec["fea"]["compliance"]), ns["C_fea"])
    assert [m["n"] for m in rec["beams"]] == [1, 4]
    Cf = np.array(rec["fea"]["compliance"])
    assert np.all(np.linalg.eigvalsh(0.5 * (Cf + Cf.T)) > 0)
    for m in rec["beams"]:  # the stated error definition, recomputed from the saved matrices
        Cb = np.array(m["compliance_timoshenko"])
        assert np.allclose(m["timoshenko"]["diagonal_error"], np.diag(Cb) / np.diag(Cf) - 1.0, rtol=1e-9)
    assert (out / "compare.md").stat().st_size > 0 and min(_png(out / "compare.png")) > 100


def test_machine_map_from_fea(workdir, monkeypatch):
    ns = _run("machine_map_from_fea", workdir, monkeypatch)
    model, smap, foot = ns["model"], ns["smap"], ns["foot"]
    # the machine uses exactly the FEA foot, through the saved JSON
    assert np.allclose(model.foot.compliance, foot.compliance, rtol=1e-12, atol=0)
    # the batched map equals pose-by-pose stiffness
    for i in (0, len(smap.points) // 2, len(smap.points) - 1):
        assert smap.k_tran[i] == pytest.approx(model.stiffness(smap.points[i]).k_tran, rel=1e-9)
    out = workdir / ns["OUT"] / "map"
    assert {p.name for p in out.iterdir()} >= {"map.npz", "k_tran.png", "k_rot.png"}
    assert np.nanmax(smap.k_tran) / np.nanmin(smap.k_tran) > 10  # so its picture is on a log scale


def test_diagnose(workdir, monkeypatch):
    ns = _run("diagnose", workdir, monkeypatch)
    dg = ns["dg"]
    assert dg.verdict == "explained" and dg.named == ["gravity"]
    lo, hi = dg.report["final_params"]["gravity"]["weight"]["ci95"]
    assert lo < 15.0 < hi  # the hidden weight
    out = workdir / ns["OUT"]
    assert (out / "report.html").stat().st_size > 0 and (out / "model_updated.yaml").exists()


def test_serial_robot(workdir, monkeypatch):
    ns = _run("serial_robot", workdir, monkeypatch)
    robot, jmap, q0 = ns["robot"], ns["jmap"], ns["q0"]
    i, j = 4, 9
    q = q0.copy()
    q[1], q[2] = jmap.a[i], jmap.b[j]
    assert jmap.sag[i, j] == pytest.approx(robot.self_weight(q), rel=1e-9, abs=1e-12)
    assert np.all(np.isfinite(jmap.sag)) and np.max(np.abs(jmap.sag[..., 2])) > 0.1  # mm: a visible sag
    assert all(_png(workdir / ns["OUT"] / f"{k}.png")[0] > 100 for k in ("sag", "k_tran"))
    assert np.all(ns["ik"].reached)
