"""A data kind added in this module alone: a CSV of per-pose translational stiffness in its own layout
(``pose;k`` with the pose ``x|y|z``), registered, and then handled end to end by ``vjm.diagnose`` and
``vjm diagnose`` with no other edit.  The truth: the observations are the model's own k_tran at the poses,
so the diagnosis must find no discrepancy (and nominal residuals at round-off); the built-in readers cannot
read the file at all."""
from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

import vjm
from vjm.cli import app
from vjm.discrepancy import kinds
from vjm.discrepancy.data import StiffnessObs
from vjm.discrepancy.simulate import grid_poses
from vjm.discrepancy.stages.kinds import StiffnessKind
from vjm.errors import VjmError


class ScalarStiffness(kinds.Kind):
    """``pose;k``: the pose ``x|y|z`` (mm), its translational stiffness k_tran (mm/N)."""

    name = "toy_scalar_stiffness"
    stages = StiffnessKind()

    def sniff(self, data, model, columns=None) -> bool:
        return kinds.header(data) == {"pose;k"}

    def read(self, path, model, columns=None):
        rows = [line.split(";") for line in open(path).read().splitlines()[1:] if line]
        P = np.array([[float(v) for v in p.split("|")] for p, _ in rows])
        k = np.array([float(v) for _, v in rows])
        return StiffnessObs(P, np.zeros(len(k), dtype=int), k, None, None, str(path), {})


@pytest.fixture
def toy_kind():
    kind = kinds.register(ScalarStiffness())
    yield kind
    kinds.unregister(kind.name)


@pytest.fixture
def data_file(tmp_path):
    model = vjm.load_model("puu")
    P = grid_poses(model, 3)
    k = [model.stiffness(p).k_tran for p in P]
    path = tmp_path / "k.csv"
    path.write_text("pose;k\n" + "".join(f"{x:.17g}|{y:.17g}|{z:.17g};{v:.17g}\n" for (x, y, z), v in zip(P[:, :3], k)))
    return path


def test_without_the_kind_no_reader_takes_the_file(data_file):
    with pytest.raises(VjmError):
        vjm.diagnose("puu", data_file)


def test_a_registered_kind_is_diagnosed_by_vjm_diagnose(toy_kind, data_file):
    assert kinds.find(data_file, vjm.load_model("puu")) is toy_kind
    dg = vjm.diagnose("puu", data_file, effects=["clearance"])
    assert isinstance(dg, vjm.Diagnosis) and dg.kind == toy_kind.name
    assert dg.verdict == "no_discrepancy" and dg.named == []
    assert dg.report["rms_nominal"] < 1e-6   # ln(predicted / observed) of the model's own values: round-off


def test_a_registered_kind_is_diagnosed_by_the_command(toy_kind, data_file, tmp_path):
    out = tmp_path / "rep"
    r = CliRunner().invoke(app, ["diagnose", "puu", str(data_file), "--out", str(out), "--effect", "clearance"])
    assert r.exit_code == 0, r.output
    rep = json.loads((out / "report.json").read_text())
    assert rep["verdict"] == "no_discrepancy" and rep["n_observations"] == len(data_file.read_text().splitlines()) - 1
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == sorted(
        n for n in toy_kind.files if n != "next_measurements.csv")


def test_unregistering_restores_the_registry(toy_kind):
    names = [k.name for k in kinds.KINDS]
    kinds.unregister(toy_kind.name)
    assert [k.name for k in kinds.KINDS] == [n for n in names if n != toy_kind.name]
    kinds.register(toy_kind)   # the fixture removes it again
    with pytest.raises(VjmError):
        kinds.register(ScalarStiffness())


def test_a_bundled_data_name_is_recognised_from_another_folder(tmp_path, monkeypatch):
    """``vjm diagnose puu seed_table1.csv`` run elsewhere: the bundled file's header decides its kind (stiffness
    observations: k_tran/k_rot columns and no wrench), as its reader resolves the name, not the fallback of deflections."""
    import vjm
    from vjm.discrepancy import kinds
    from vjm.resources import seed_table

    monkeypatch.chdir(tmp_path)
    head = next(x for x in seed_table().read_text().splitlines() if not x.startswith("#")).split(",")
    assert any(h.startswith("k_tran") for h in head) and "Fx" not in head   # wide stiffness columns, no wrench
    assert kinds.find("seed_table1.csv", vjm.load_model("puu")).name == "stiffness"
