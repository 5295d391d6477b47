"""A robot whose arm rides on a telescopic lifting column whose top tilts under the arm's weight, more as it
extends (pinocchio's truth, tests/truth_serial.py: :func:`column_robot_poses`, no vjm code), diagnosed on a
model without the tilt.  A carriage's tilt on its guide (``guide_tilt``, turning about the moving carriage)
does not express a stage turning about its guide's top: fitted without its physical domain it goes negative
by more than two standard deviations and passes its tests; within the domain it is listed as standing in for
something else, with the value it wanted, and nothing named is negative.  With the whole library the
column's own effect (``column_tilt``) is named, alone, and its compliance recovered."""
import numpy as np
import pytest

truth = pytest.importorskip("truth_serial")

from vjm.calibration import engine  # noqa: E402
from vjm.calibration.poses import read_poses  # noqa: E402
from vjm.calibration.serial import rotation_matrix  # noqa: E402
from vjm.effects import absolute  # noqa: E402
from vjm.modelio.read import load_model  # noqa: E402

EFFECTS = ("geometry", "compliance", "guide_tilt")
#: the effects whose parameters are >= 0 (their declared domain's lower bound)
NONNEGATIVE = ("compliance", "lateral", "backlash", "bending", "payload", "guide_tilt", "column_tilt")
#: the hidden tilt's compliance c(z) = a + b z, rad/(N m) with z in m (column_robot_poses' default)
TILT = (2e-6, 2e-5)


@pytest.fixture(scope="module")
def column(tmp_path_factory):
    d = tmp_path_factory.mktemp("column")
    (d / "column.urdf").write_text(truth.column_robot_urdf(False))
    (d / "hidden.urdf").write_text(truth.column_robot_urdf(True))
    (d / "column.yaml").write_text("urdf: column.urdf\n")   # rigid joints, as the truth's
    q, p = truth.column_robot_poses(str(d / "hidden.urdf"), 400, tilt=TILT, R=rotation_matrix([0.1, -0.2, 0.5]),
                                    t=[1500, -300, 100], marker=(10, 5, -3), sigma=0.01, seed=3)
    np.savetxt(d / "poses.csv", np.column_stack([q, p]), delimiter=",", comments="", fmt="%.10f",
               header=",".join(truth.COLUMN_JOINTS) + ",tool.x,tool.y,tool.z")
    model = load_model(d / "column.yaml")
    return model, read_poses(d / "poses.csv", None, model.q_names).with_group("g")


def _negative(cal) -> dict:
    """The named parameters of the effects >= 0 whose value is below zero, {name: (value, std)}."""
    return {k: (v, cal.std[k]) for k, v in cal.robot_values().items()
            if absolute.owner(k)[0].name in NONNEGATIVE and v < 0}


def test_the_column_pulls_a_named_parameter_negative_without_its_domain(column, monkeypatch):
    model, data = column
    monkeypatch.setattr(absolute, "domain", lambda names, *a, **k: (np.full(len(names), -np.inf),
                                                                    np.full(len(names), np.inf),
                                                                    np.zeros(len(names), dtype=bool)))
    cal = engine.calibrate(model, data, "tool", effects=EFFECTS, folds=5)
    neg = _negative(cal)
    assert "compliance" in [s.name for s in cal.stages if s.kept]
    assert any(k.endswith(".compliance") and v < -2 * s for k, (v, s) in neg.items()), neg


def test_within_the_domain_nothing_named_is_negative(column):
    model, data = column
    cal = engine.calibrate(model, data, "tool", effects=EFFECTS, folds=5)
    assert not _negative(cal)


def test_the_whole_library_names_the_column_alone_and_recovers_it(column):
    """The default candidates (every effect that applies): the column's tilt about its guide's top is named,
    nothing else (the model's geometry is exact), nothing named is negative, and the compliance at the
    travel's ends (a + b z at z = 0 and 0.8 m, rad/(N mm)) is recovered within 4 standard deviations or 1 %
    (the truth turns about x, then y, by a fixed point: a second-order difference that 400 poses resolve), the
    residual that of the noise (0.01 mm per axis)."""
    model, data = column
    cal = engine.calibrate(model, data, "tool", effects=absolute.applicable(model, "absolute", data), folds=5)
    named = [s.name for s in cal.stages[1:] if s.kept]
    assert named == ["column_tilt"], [(s.name, s.kept, s.note) for s in cal.stages]
    assert not _negative(cal)
    a, b = TILT
    for end, z in (("lower", 0.0), ("upper", 0.8)):
        k = f"lift.column_tilt_{end}"
        true = (a + b * z) / 1000.0
        assert abs(cal.values[k] - true) < max(4 * cal.std[k], 0.01 * true), (k, cal.values[k], cal.std[k])
    assert [s for s in cal.stages if s.kept][-1].rms < 1.2 * 0.01 * np.sqrt(3)


def test_vjm_diagnose_names_the_column(column, tmp_path):
    """``vjm diagnose`` with its defaults on the column's data names the column's tilt, nothing else, and says
    what it sags at the poses."""
    import json

    from vjm.cli import main

    model, data = column
    folder = model.path.rsplit("/", 1)[0]
    assert main(["diagnose", model.path, f"{folder}/poses.csv", "--out", str(tmp_path / "o")]) == 0
    rep = json.loads((tmp_path / "o" / "report.json").read_text())
    assert rep["named_effects"] == ["column_tilt"], rep["named_effects"]
    assert "column_tilt" in (tmp_path / "o" / "summary.txt").read_text()
