"""Truth cases of the absolute-pose calibration beyond geometry and compliance (pinocchio's truth,
tests/truth_serial.py): a backlash flipping with the sign of a joint's gravity torque."""
import os
import warnings

import numpy as np
import pytest

truth = pytest.importorskip("truth_serial")

import vjm  # noqa: E402
from vjm.calibration.engine import calibrate, position_errors  # noqa: E402
from vjm.calibration.poses import AbsolutePoses  # noqa: E402
from vjm.calibration.serial import rotation_matrix  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
URDF = os.path.join(ROOT, "data", "robots", "ur10", "ur10.urdf")
RIGID = os.path.join(ROOT, "tests", "ur10_rigid.yaml")
SIGMA = 0.01
BASE = dict(R=rotation_matrix([0.3, -0.2, 2.0]), t=np.array([2000.0, -1500.0, 300.0]),
            marker=np.array([10.0, -20.0, 110.0]), sigma=SIGMA)
EFFECTS = ("geometry", "compliance", "backlash", "payload")


@pytest.fixture(scope="module")
def model():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return vjm.load_model(RIGID)   # the model pinocchio's truth simulates: the URDF, rigid


def _q(model, n, seed, away=3.0):
    """n configurations whose elbow gravity torque is at least ``away`` N m from 0 (pinocchio's), so that
    the side a clearance is taken up on is not decided by noise."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(-np.pi, np.pi, (3 * n, 6))
    q[:, 1] = rng.uniform(-np.pi, 0.0, 3 * n)
    g = truth.gravity_torques(URDF, model.q_names, q)
    return q[np.abs(g[:, 2]) > away][:n]


def _data(model, hidden, q, seed):
    pts = truth.measure(URDF, "tool0", model.q_names, q, hidden, np.random.default_rng(seed))
    return AbsolutePoses(tuple(model.q_names), q, {"tool0": pts}, group=np.full(len(q), "A", dtype=object))


def test_backlash_flipping_with_the_gravity_torque_is_named(model):
    b = 4e-4   # rad: 0.25 mm at the wrist, 25 times the noise
    hidden = truth.Hidden(offsets={"elbow_joint": 1e-3}, backlash={"elbow_joint": b}, **BASE)
    q = _q(model, 300, 1)
    data = _data(model, hidden, q, 2)
    g = truth.gravity_torques(URDF, model.q_names, q)[:, 2]
    assert 0.2 < np.mean(g > 0) < 0.8   # both sides of the clearance in the data: the test has teeth
    cal = calibrate(model, data, "tool0", effects=EFFECTS)
    kept = [s.name for s in cal.stages if s.kept]
    assert "backlash" in kept and "payload" not in kept
    v, s = cal.values["elbow_joint.backlash"], cal.std["elbow_joint.backlash"]
    assert s < 0.1 * b and abs(v - b) < 4 * s
    # a compliance the F test may keep on the way absorbs nothing once the backlash is in
    c = cal.values.get("elbow_joint.compliance", 0.0)
    assert abs(c) < 4 * cal.std.get("elbow_joint.compliance", np.inf)
    removed = dict(cal.removed)
    assert "changes sign" in removed["shoulder_pan_joint.backlash"]   # a vertical axis: no gravity torque
    exact = _data(model, truth.Hidden(**{**hidden.__dict__, "sigma": 0.0}), _q(model, 100, 3), 4)
    assert np.max(position_errors(cal, exact)) < 3 * SIGMA


def test_clean_data_name_no_backlash(model):
    data = _data(model, truth.Hidden(**BASE), _q(model, 300, 5), 6)
    cal = calibrate(model, data, "tool0", effects=EFFECTS)
    assert [s.name for s in cal.stages if s.kept] == ["registration"]


def test_rows_of_a_swapped_marker_are_set_aside_not_fitted(model):
    """5 % of the rows measured the other reflector (150 mm away on the flange): out of the library, they are
    set aside and listed, and the clean rest names nothing beyond the registration."""
    from vjm.calibration.robust import calibrate_robust

    q = _q(model, 300, 7)
    data = _data(model, truth.Hidden(**BASE), q, 8)
    swapped = np.random.default_rng(9).permutation(len(q))[:15]
    other = truth.Hidden(**{**BASE, "marker": BASE["marker"] + np.array([150.0, 0.0, 0.0])})
    data.points["tool0"][swapped] = _data(model, other, q[swapped], 10).points["tool0"]
    clean = np.setdiff1d(np.arange(len(q)), swapped)
    exact = _data(model, truth.Hidden(**{**BASE, "sigma": 0.0}), q[clean], 11)
    plain = calibrate(model, data, "tool0", effects=EFFECTS)
    assert np.mean(position_errors(plain, exact)) > 10 * SIGMA   # fitted, the outliers pull everything
    cal = calibrate_robust(model, data, "tool0", effects=EFFECTS)
    assert sorted(cal.set_aside) == sorted(swapped.tolist())
    assert [s.name for s in cal.stages if s.kept] == ["registration"]
    assert np.max(position_errors(cal, exact)) < 3 * SIGMA


def test_a_base_tilt_is_named_through_the_compliances(model):
    tilt = (0.05, -0.03)   # rad
    comp = {"shoulder_lift_joint": 8e-6, "elbow_joint": 1.2e-5}
    hidden = truth.Hidden(offsets={"elbow_joint": 1e-3}, compliance=comp, tilt=tilt, **BASE)
    data = _data(model, hidden, _q(model, 300, 12, away=0.0), 13)
    cal = calibrate(model, data, "tool0", effects=("geometry", "compliance", "tilt"))
    assert [s.name for s in cal.stages if s.kept] == ["registration", "geometry", "compliance", "tilt"]
    for k, v in zip(("rx", "ry"), tilt):
        x, s = cal.values[f"base.tilt_{k}"], cal.std[f"base.tilt_{k}"]
        assert s < 0.2 * abs(v) and abs(x - v) < 4 * s
    for j, c in comp.items():
        assert abs(cal.values[f"{j}.compliance"] * 1000 - c) < 4 * cal.std[f"{j}.compliance"] * 1000
    # the same arm level: no tilt named
    level = truth.Hidden(**{**hidden.__dict__, "tilt": (0.0, 0.0)})
    cal = calibrate(model, _data(model, level, _q(model, 300, 12, away=0.0), 13), "tool0",
                    effects=("geometry", "compliance", "tilt"))
    assert [s.name for s in cal.stages if s.kept] == ["registration", "geometry", "compliance"]


def test_a_joint_coupled_to_another_is_named(model):
    """The wrist-2 column holds wrist_2 + 0.02 wrist_1 (a gear train written as an ordinary joint)."""
    k = 0.02
    hidden = truth.Hidden(offsets={"elbow_joint": 1e-3}, coupling={("wrist_2_joint", "wrist_1_joint"): k}, **BASE)
    data = _data(model, hidden, _q(model, 300, 14, away=0.0), 15)
    cal = calibrate(model, data, "tool0", effects=("geometry", "coupling", "compliance"))
    assert "coupling" in [s.name for s in cal.stages if s.kept]
    name = "wrist_2_joint.coupling[wrist_1_joint]"
    assert abs(cal.values[name] - k) < 4 * cal.std[name] and cal.std[name] < 0.05 * k
    others = {n: v for n, v in cal.values.items() if ".coupling[" in n and n != name}
    assert all(abs(v) < 4 * cal.std[n] + 1e-6 for n, v in others.items())
    clean = calibrate(model, _data(model, truth.Hidden(**BASE), _q(model, 300, 14, away=0.0), 15), "tool0",
                      effects=("geometry", "coupling", "compliance"))
    assert [s.name for s in clean.stages if s.kept] == ["registration"]
