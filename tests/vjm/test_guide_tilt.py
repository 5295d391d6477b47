"""A prismatic guide's tilt (``guide_tilt``, vjm.calibration.flex) against pinocchio's truth (tests/truth_serial.py):
an arm on a vertical column whose carriage tilts under the moment it carries, the compliance growing with the
extension (two passive revolute joints at the carriage, deflected by ``c(q) g`` in the equilibrium).  The
calibration names the guide, recovers its compliance at both ends of the travel, and the held-out error drops
to the noise; a telescope whose stages are one drive (mimic joints) is one candidate."""
import warnings

import numpy as np
import pytest

truth = pytest.importorskip("truth_serial")

import vjm  # noqa: E402
from vjm.calibration.engine import _problem, calibrate, position_errors  # noqa: E402
from vjm.calibration.poses import AbsolutePoses  # noqa: E402
from vjm.calibration.serial import full_layout, jacobian, jacobian_fast, rotation_matrix  # noqa: E402
from vjm.effects.absolute import POSES  # noqa: E402

SIGMA = 0.01   # mm
LOWER, UPPER = 2e-9, 6e-9   # rad/(N mm): the carriage's tilt compliance retracted (0 mm) and extended (800 mm)
TRAVEL = 800.0   # mm
BASE = dict(offsets={"j2": 2e-3, "j3": -1.5e-3}, compliance={"j2": 4e-6, "j3": 8e-6},   # rad/(N m)
            R=rotation_matrix([0.2, -0.1, 1.0]), t=np.array([1500.0, -800.0, 200.0]),
            marker=np.array([10.0, -20.0, -30.0]), sigma=SIGMA)


def _c(row, lower=LOWER, upper=UPPER):
    """The truth's tilt compliance (2, 2) rad/(N m) at the commanded column extension (mm): a + b q."""
    s = row["column"] / TRAVEL
    return np.eye(2) * 1000.0 * (lower * (1 - s) + upper * s)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("guide")
    out = {}
    for tilt in (False, True):
        for stages in (1, 2):
            p = d / f"guide{int(tilt)}{stages}.urdf"
            p.write_text(truth.guide_robot_urdf(tilt, stages))
            out[tilt, stages] = str(p)
    return out


def _model(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return vjm.load_model(path)


def _data(model, urdf, hidden, n, seed, stages=1):
    rng = np.random.default_rng(seed)
    q = np.column_stack([rng.uniform(0.0, TRAVEL, n), rng.uniform(-np.pi, np.pi, n), rng.uniform(-1.2, 1.2, n),
                         rng.uniform(-2.2, 2.2, n), rng.uniform(-np.pi, np.pi, n)])
    names = list(model.q_names)
    qt = q
    if stages == 2:   # the truth's second stage: pinocchio drives the mimic as a joint of its own
        names = ["column", "column2", *names[1:]]
        qt = np.column_stack([q[:, 0], q])
    pts = truth.measure(urdf, "tool", names, qt, hidden, rng)
    return AbsolutePoses(tuple(model.q_names), q, {"tool": pts}, group=np.full(n, "A", dtype=object))


def _hidden(stages=1):
    groups = {("tilt_x", "tilt_y"): _c}
    if stages == 2:
        groups[("tilt2_x", "tilt2_y")] = _c
    return truth.Hidden(**BASE, passive=groups)


def test_a_tilting_guide_is_named_and_its_compliance_recovered(files):
    model = _model(files[False, 1])
    data = _data(model, files[True, 1], _hidden(), 150, 1)
    cal = calibrate(model, data, "tool", effects=("geometry", "compliance", "guide_tilt"))
    assert [s.name for s in cal.stages if s.kept][-1] == "guide_tilt"
    for end, value in (("lower", LOWER), ("upper", UPPER)):
        name = f"column.guide_tilt_{end}"
        assert abs(cal.values[name] - value) < 4 * cal.std[name] and cal.std[name] < 0.2 * value, name
    # a + b q: a the retracted end's, b the growth per mm of extension
    b = (cal.values["column.guide_tilt_upper"] - cal.values["column.guide_tilt_lower"]) / TRAVEL
    assert abs(b - (UPPER - LOWER) / TRAVEL) < 0.25 * (UPPER - LOWER) / TRAVEL
    held = _data(model, files[True, 1], _hidden(), 100, 2)
    without = calibrate(model, data, "tool", effects=("geometry", "compliance"))
    e, e0 = np.mean(position_errors(cal, held)), np.mean(position_errors(without, held))
    assert e < 2 * SIGMA < e0, (e, e0)


def test_a_telescope_is_one_candidate_and_is_recovered(files):
    model = _model(files[False, 2])
    lay = full_layout(model, "tool", ("A",), ("guide_tilt",))
    assert [n for n, k in zip(lay.names, lay.kinds) if k == "guide_tilt"] == ["column.guide_tilt_lower",
                                                                               "column.guide_tilt_upper"]
    data = _data(model, files[True, 2], _hidden(2), 150, 3, stages=2)
    cal = calibrate(model, data, "tool", effects=("geometry", "compliance", "guide_tilt"))
    for end, value in (("lower", LOWER), ("upper", UPPER)):
        name = f"column.guide_tilt_{end}"
        assert abs(cal.values[name] - value) < 4 * cal.std[name] and cal.std[name] < 0.2 * value, name


def test_a_rigid_guide_names_no_tilt_and_the_domain_is_declared(files):
    model = _model(files[False, 1])
    data = _data(model, files[False, 1], truth.Hidden(**BASE), 150, 4)
    cal = calibrate(model, data, "tool", effects=("geometry", "compliance", "guide_tilt"))
    assert "guide_tilt" not in [s.name for s in cal.stages if s.kept]
    # the compliance is >= 0 over the whole travel exactly when both ends are: a box the fit can keep to
    assert [p.lower for p in POSES["guide_tilt"].patterns] == [0.0, 0.0]
    # a revolute joint's bearing is the lateral effect's, a prismatic joint's carriage the guide's
    lat = full_layout(model, "tool", ("A",), ("lateral",))
    assert "column.lateral" not in lat.names and "j2.lateral" in lat.names


@pytest.mark.parametrize("tilt", ["guide_tilt", "column_tilt"])
def test_guide_jacobian_matches_central_differences(files, tilt):
    """The tilt's columns (about the carriage, or about the guide's exit) against central differences."""
    model = _model(files[False, 2])
    d = _data(model, files[False, 2], truth.Hidden(**BASE), 30, 5, stages=2)
    prob = _problem(model, d, "tool", {"A": (np.eye(3), np.zeros(3))}, BASE["marker"], flex=True)
    lay = full_layout(model, "tool", prob.groups, (tilt, "lateral"))
    assert f"column.{tilt}_upper" in lay.names
    x = np.random.default_rng(6).normal(size=lay.size) * 1e-2
    for i, kind in enumerate(lay.kinds):
        x[i] = 0.0 if kind in ("compliance", "backlash") else x[i]
        x[i] = {tilt: 4e-9, "lateral": 3e-9}.get(kind, x[i])
    J1, J2 = jacobian(prob, lay, x), jacobian_fast(prob, lay, x)
    scale = np.linalg.norm(J1, axis=0) / np.sqrt(len(J1)) + 1e-3
    err = np.max(np.abs(J1 - J2) / scale, axis=0)
    assert np.max(err) < 1e-5, [(lay.names[i], err[i]) for i in np.argsort(err)[-4:]]
