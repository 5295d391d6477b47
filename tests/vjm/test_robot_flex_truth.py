"""The flex effects of vjm.calibration.flex against pinocchio's truth (tests/truth_serial.py): a UR10 with joint
offsets and joint compliances plus one hidden effect -- lateral joint compliance, link bending, a compliance
varying with the joint's value, a length scale with temperature -- is calibrated with that effect in the
library: the effect is named and its value recovered; the same arm without it names nothing beyond the
geometry and the joint compliance."""
import os
import warnings

import numpy as np
import pytest

truth = pytest.importorskip("truth_serial")

import vjm  # noqa: E402
from vjm.calibration.engine import _problem, calibrate, position_errors  # noqa: E402
from vjm.calibration.poses import AbsolutePoses  # noqa: E402
from vjm.calibration.serial import full_layout, jacobian, jacobian_fast, rotation_matrix  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(__file__)))
URDF = os.path.join(ROOT, "data", "robots", "ur10", "ur10.urdf")
RIGID = os.path.join(ROOT, "tests", "ur10_rigid.yaml")
SIGMA = 0.01  # mm
BASE = dict(offsets={"shoulder_lift_joint": 2e-3, "elbow_joint": -1.5e-3, "wrist_1_joint": 1e-3},
            compliance={"shoulder_lift_joint": 4e-6, "elbow_joint": 8e-6},   # rad/(N m)
            R=rotation_matrix([0.3, -0.2, 2.0]), t=np.array([2000.0, -1500.0, 300.0]),
            marker=np.array([10.0, -20.0, 110.0]), sigma=SIGMA)
#: effect -> (hidden truth, the vjm parameter, its true value in vjm's units (N, mm))
CASES = {
    "lateral": ({"lateral": {"elbow_joint": 3e-5}}, "elbow_joint.lateral", 3e-8),
    "bending": ({"bending": {"elbow_joint": 2e-5}}, "forearm_link.bending", 2e-11),
    "varying": ({"varying": {"elbow_joint": 3e-6}}, "elbow_joint.varying", 3e-9),
    "thermal": ({"alpha": 2.3e-5}, "thermal.alpha", 2.3e-5),
}


@pytest.fixture(scope="module")
def model():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return vjm.load_model(RIGID)   # the model pinocchio's truth simulates: the URDF, rigid


def _data(model, hidden, n, seed):
    rng = np.random.default_rng(seed)
    q = rng.uniform(-np.pi, np.pi, (n, 6))
    q[:, 1] = rng.uniform(-np.pi, 0.0, n)
    temp = rng.uniform(15.0, 35.0, n)
    pts = truth.measure(URDF, "tool0", model.q_names, q, hidden, rng, temperature=temp)
    return AbsolutePoses(tuple(model.q_names), q, {"tool0": pts}, group=np.full(n, "A", dtype=object),
                         meta={"meta_temperature": temp})


@pytest.mark.parametrize("effect", sorted(CASES))
def test_a_hidden_flex_effect_is_named_and_recovered(model, effect):
    extra, name, value = CASES[effect]
    data = _data(model, truth.Hidden(**BASE, **extra), 150, 1)
    cal = calibrate(model, data, "tool0", effects=("geometry", "compliance", effect))
    assert [s.name for s in cal.stages if s.kept] == ["registration", "geometry", "compliance", effect]
    assert abs(cal.values[name] - value) < 4 * cal.std[name] and cal.std[name] < 0.2 * value
    assert np.mean(position_errors(cal, data)) < 2 * SIGMA


def test_clean_data_name_no_flex_effect(model):
    data = _data(model, truth.Hidden(**BASE), 150, 2)
    cal = calibrate(model, data, "tool0", effects=("geometry", "compliance", *CASES))
    assert [s.name for s in cal.stages] == ["registration", "geometry", "compliance", "lateral", "bending", "varying",
                                            "thermal"]
    assert [s.name for s in cal.stages if s.kept] == ["registration", "geometry", "compliance"]


def test_flex_jacobian_matches_central_differences():
    with warnings.catch_warnings():   # the bundled model: its joint and link springs are the nominal deflection
        warnings.simplefilter("ignore")
        model = vjm.load_model(os.path.join(ROOT, "data", "robots", "ur10", "ur10.yaml"))
    rng = np.random.default_rng(5)
    d = _data(model, truth.Hidden(**BASE), 30, 3)
    prob = _problem(model, d, "tool0", {"A": (np.eye(3), np.zeros(3))}, BASE["marker"], flex=True, thermal=True)
    lay = full_layout(model, "tool0", prob.groups, ("lateral", "bending", "varying", "thermal"))
    x = rng.normal(size=lay.size) * 1e-2
    for i, kind in enumerate(lay.kinds):   # each flex effect deflecting by about 1e-3; no torsion nor backlash
        x[i] = 0.0 if kind in ("compliance", "backlash") else x[i]
        x[i] = {"lateral": 3e-8, "bending": 2e-11, "varying": 3e-9, "thermal": 2.3e-5}.get(kind, x[i])
    J1, J2 = jacobian(prob, lay, x), jacobian_fast(prob, lay, x)
    scale = np.linalg.norm(J1, axis=0) / np.sqrt(len(J1)) + 1e-3
    assert np.max(np.abs(J1 - J2) / scale) < 1e-5
