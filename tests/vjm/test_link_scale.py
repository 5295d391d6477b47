"""A link spring's scale (``link_scale``, vjm.calibration.flex) against pinocchio's truth (tests/truth_serial.py):
the UR10 whose upper arm is 1.3 times as compliant as its beam in data/robots/ur10/ur10.yaml states, its forearm
as stated -- each link spring six passive joints at the spring frame, deflected by the (scaled) 6x6 times their
generalized gravity in the equilibrium.  The calibration recovers both scales and the held-out error drops to
the noise."""
import os
import warnings

import numpy as np
import pytest

truth = pytest.importorskip("truth_serial")

import vjm  # noqa: E402
from vjm.calibration.engine import _problem, calibrate, position_errors  # noqa: E402
from vjm.calibration.flex import link_scale_text  # noqa: E402
from vjm.calibration.poses import AbsolutePoses  # noqa: E402
from vjm.calibration.serial import full_layout, jacobian, jacobian_fast, rotation_matrix  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(__file__)))
URDF = os.path.join(ROOT, "data", "robots", "ur10", "ur10.urdf")
SIGMA = 0.005   # mm
SCALE = {"upper_arm": 1.3, "forearm": 1.0}
BASE = dict(offsets={"shoulder_lift_joint": 2e-3, "elbow_joint": -1.5e-3, "wrist_1_joint": 1e-3},
            compliance={"shoulder_lift_joint": 4e-6, "elbow_joint": 8e-6},   # rad/(N m)
            R=rotation_matrix([0.3, -0.2, 2.0]), t=np.array([2000.0, -1500.0, 300.0]),
            marker=np.array([10.0, -20.0, 110.0]), sigma=SIGMA)
#: the springs' frames as the model file places them (link, the next joint, xyz m, rpy)
SPRINGS = {"upper_arm": ("upper_arm_link", "elbow_joint", (0.0, 0.0, 0.612), (0.0, -np.pi / 2, 0.0)),
           "forearm": ("forearm_link", "wrist_1_joint", (0.0, 0.0, 0.5723), (0.0, -np.pi / 2, 0.0))}


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    """The bundled UR10 file with its link springs, the truth's joints: the wrists rigid (the truth has no
    spring there, and the fit starts from the file's springs)."""
    with open(os.path.join(ROOT, "data", "robots", "ur10", "ur10.yaml"), encoding="utf-8") as f:
        text = "".join(line for line in f if not line.strip().startswith("wrist_"))
    path = tmp_path_factory.mktemp("ur10") / "ur10.yaml"
    path.write_text(text.replace("urdf: ur10.urdf", f"urdf: {URDF}"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return vjm.load_model(path)


def _springs(model, folder, scale):
    """The truth's URDF (the springs' passive joints) and its hidden effects, each spring ``scale`` times the
    model file's."""
    with open(URDF, encoding="utf-8") as f:
        text = f.read()
    passive = {}
    for name, (link, child, xyz, rpy) in SPRINGS.items():
        text = truth.with_link_spring(text, link, child, xyz, rpy, name)
        C = truth.si_compliance(model.links[name].spring.compliance) * scale[name]
        passive[tuple(f"{name}_{a}" for a in ("tx", "ty", "tz", "rx", "ry", "rz"))] = lambda row, C=C: C
    path = folder / "ur10_springs.urdf"
    path.write_text(text)
    return str(path), truth.Hidden(**BASE, passive=passive)


@pytest.fixture(scope="module")
def flexible(model, tmp_path_factory):
    return _springs(model, tmp_path_factory.mktemp("links"), SCALE)


def _data(model, urdf, hidden, n, seed):
    rng = np.random.default_rng(seed)
    q = rng.uniform(-np.pi, np.pi, (n, 6))
    q[:, 1] = rng.uniform(-np.pi, 0.0, n)
    pts = truth.measure(urdf, "tool0", model.q_names, q, hidden, rng)
    return AbsolutePoses(tuple(model.q_names), q, {"tool0": pts}, group=np.full(n, "A", dtype=object))


def _total(cal, name: str) -> float:
    """The link's scale: the model's nominal scale in the fit's start (1: the link spring as the file states it,
    its sag in the start) plus the fitted correction."""
    from vjm.calibration.nominal import nominal_values

    return nominal_values(cal.model, [name])[name] + cal.values[name]


def test_a_link_more_compliant_than_its_cad_is_scaled(model, flexible):
    urdf, hidden = flexible
    data = _data(model, urdf, hidden, 200, 1)
    cal = calibrate(model, data, "tool0", effects=("geometry", "compliance", "link_scale"))
    assert [s.name for s in cal.stages if s.kept][-1] == "link_scale"
    for name, value in SCALE.items():
        key = f"{name}.link_scale"
        assert abs(_total(cal, key) - value) < 4 * cal.std[key], (key, cal.values[key], cal.std[key])
    assert cal.std["upper_arm.link_scale"] < 0.06   # the forearm's, near the wrist, is less observable
    held = _data(model, urdf, hidden, 100, 2)
    without = calibrate(model, data, "tool0", effects=("geometry", "compliance"))
    e, e0 = np.mean(position_errors(cal, held)), np.mean(position_errors(without, held))
    assert e < 2 * SIGMA and e < 0.95 * e0, (e, e0)   # the start holds the links at 1: 0.3 of the sag is left


def test_the_links_as_stated_recover_scale_one_and_the_line_reads_so(model, tmp_path):
    urdf, hidden = _springs(model, tmp_path, {"upper_arm": 1.0, "forearm": 1.0})
    data = _data(model, urdf, hidden, 200, 3)
    cal = calibrate(model, data, "tool0", effects=("geometry", "compliance", "link_scale"))
    # the start holds the links as stated: no correction is named, or one within 4 standard deviations of none
    key = "upper_arm.link_scale"
    assert key not in cal.values or abs(_total(cal, key) - 1.0) < 4 * cal.std[key], cal.stages
    assert link_scale_text("upper_arm", 1.3, 0.1) == "the upper arm is 1.3 +- 0.1 times as compliant as its CAD predicts"
    assert link_scale_text("forearm", 0.96, 0.023) == "the forearm is 0.96 +- 0.02 times as compliant as its CAD predicts"


def test_link_scale_jacobian_matches_central_differences(model):
    rng = np.random.default_rng(5)
    q = rng.uniform(-np.pi, np.pi, (30, 6))
    d = AbsolutePoses(tuple(model.q_names), q, {"tool0": np.zeros((30, 3))}, group=np.full(30, "A", dtype=object))
    prob = _problem(model, d, "tool0", {"A": (np.eye(3), np.zeros(3))}, BASE["marker"], flex=True)
    lay = full_layout(model, "tool0", prob.groups, ("link_scale", "lateral", "bending"))
    assert [n for n, k in zip(lay.names, lay.kinds) if k == "link_scale"] == ["upper_arm.link_scale",
                                                                              "forearm.link_scale"]
    x = rng.normal(size=lay.size) * 1e-2
    for i, kind in enumerate(lay.kinds):
        x[i] = 0.0 if kind in ("compliance", "backlash") else x[i]
        x[i] = {"link_scale": 1.3, "lateral": 3e-8, "bending": 2e-11}.get(kind, x[i])
    J1, J2 = jacobian(prob, lay, x), jacobian_fast(prob, lay, x)
    scale = np.linalg.norm(J1, axis=0) / np.sqrt(len(J1)) + 1e-3
    assert np.max(np.abs(J1 - J2) / scale) < 1e-5
