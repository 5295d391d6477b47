"""Absolute-pose calibration against pinocchio's truth (tests/truth_serial.py): a UR10 with hidden joint
offsets, origin errors and joint compliance under self-weight, seen by an instrument in an unknown frame
through a marker at an unknown offset, with noise."""
import os
import warnings

import numpy as np
import pytest

truth = pytest.importorskip("truth_serial")

import vjm  # noqa: E402
from vjm.calibration.engine import calibrate, instrument_frame, position_errors, predict_points, register  # noqa: E402
from vjm.calibration.poses import AbsolutePoses  # noqa: E402
from vjm.calibration.serial import kabsch, rotation_matrix  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(__file__)))
URDF = os.path.join(ROOT, "data", "robots", "ur10", "ur10.urdf")
RIGID = os.path.join(ROOT, "tests", "ur10_rigid.yaml")
SIGMA = 0.01  # mm
INSTRUMENT = (rotation_matrix([0.3, -0.2, 2.0]), np.array([2000.0, -1500.0, 300.0]))
MARKER = np.array([10.0, -20.0, 110.0])


@pytest.fixture(scope="module")
def model():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return vjm.load_model(RIGID)   # the model pinocchio's truth simulates: the URDF, rigid


def _data(model, hidden, q, seed, group="A"):
    pts = truth.measure(URDF, "tool0", model.q_names, q, hidden, np.random.default_rng(seed))
    return AbsolutePoses(tuple(model.q_names), q, {"tool0": pts}, group=np.full(len(q), group, dtype=object))


HIDDEN = truth.Hidden(
    offsets={"shoulder_pan_joint": 1e-3, "shoulder_lift_joint": 2e-3, "elbow_joint": -1.5e-3, "wrist_1_joint": 1e-3,
             "wrist_2_joint": -8e-4, "wrist_3_joint": 5e-4},
    origins={"shoulder_lift_joint": (0.3, 0.0, 0.0, 0.0, 0.0, 3e-4), "elbow_joint": (0.4, 0.0, -0.3, 5e-4, 0.0, 0.0),
             "wrist_1_joint": (0.0, 0.2, 0.5, 0.0, -4e-4, 0.0)},
    compliance={"shoulder_lift_joint": 4e-6, "elbow_joint": 8e-6},   # rad/(N m)
    R=INSTRUMENT[0], t=INSTRUMENT[1], marker=MARKER, sigma=SIGMA)
CLEAN = truth.Hidden(R=INSTRUMENT[0], t=INSTRUMENT[1], marker=MARKER, sigma=SIGMA)


@pytest.fixture(scope="module")
def hidden_fit(model):
    data = _data(model, HIDDEN, truth.ur10_postures(300, 1), 2)
    return data, calibrate(model, data, "tool0")


def test_kabsch_recovers_a_rigid_motion():
    rng = np.random.default_rng(3)
    P = rng.normal(size=(20, 3)) * 100
    R, t = rotation_matrix([0.5, -1.0, 2.5]), np.array([1.0, 2.0, 3.0])
    R2, t2 = kabsch(P, P @ R.T + t)
    assert np.allclose(R2, R, atol=1e-12) and np.allclose(t2, t, atol=1e-9)


def test_hidden_effects_are_named_and_recovered(model, hidden_fit):
    _, cal = hidden_fit
    kept = {s.name: s.kept for s in cal.stages}
    assert kept == {"registration": True, "geometry": True, "compliance": True}
    for j in ("shoulder_lift_joint", "elbow_joint"):
        c, s = cal.values[f"{j}.compliance"] * 1000, cal.std[f"{j}.compliance"] * 1000   # rad/(N m)
        assert s < 0.1 * HIDDEN.compliance[j]
        assert abs(c - HIDDEN.compliance[j]) < 4 * s
    removed = dict(cal.removed)
    # the first joint's offset turns the whole arm about the base axis: the instrument frame's rotation
    assert "reg[A]" in removed["shoulder_pan_joint.offset"]
    assert "not observable" in removed["shoulder_pan_joint.compliance"]   # a vertical axis: no gravity torque
    assert "tool0.p" in removed["wrist_3_joint.offset"]                    # the marker turning about the last axis


def test_calibrated_model_predicts_held_out_poses(model, hidden_fit):
    _, cal = hidden_fit
    q = truth.ur10_postures(150, 4)
    exact = _data(model, truth.Hidden(**{**HIDDEN.__dict__, "sigma": 0.0}), q, 5)
    e = position_errors(cal, exact)
    assert np.max(e) < 3 * SIGMA
    reg_only = calibrate(model, _data(model, HIDDEN, truth.ur10_postures(300, 1), 2), "tool0", effects=())
    assert np.mean(position_errors(reg_only, exact)) > 0.3   # the hidden effects are mm-sized: the test has teeth


def test_instrument_frame_and_marker_are_recovered(hidden_fit):
    _, cal = hidden_fit
    R, t = instrument_frame(cal, "A")
    # the first joint's hidden offset turns the arm about the base z axis: the registration takes it
    expected = INSTRUMENT[0] @ rotation_matrix([0.0, 0.0, HIDDEN.offsets["shoulder_pan_joint"]])
    assert np.degrees(np.linalg.norm(truth.pin.log3(R.T @ expected))) < 0.002
    # and the second joint's origin error along its x (the base's -z, its origin being turned by pi/2 about y)
    # moves the whole arm along the base z axis: the registration takes that too
    shift = INSTRUMENT[0] @ np.array([0.0, 0.0, -HIDDEN.origins["shoulder_lift_joint"][0]])
    assert np.linalg.norm(t - INSTRUMENT[1] - shift) < 0.02
    assert np.linalg.norm(cal.marker - MARKER) < 2.0   # mm: up to what the wrist's origin errors absorb


def test_clean_data_give_registration_only(model):
    data = _data(model, CLEAN, truth.ur10_postures(300, 6), 7)
    cal = calibrate(model, data, "tool0", effects=("geometry", "compliance", "payload"))
    assert [s.name for s in cal.stages if s.kept] == ["registration"]
    assert set(cal.robot_values()) == set()
    for k, v in zip("xyz", cal.marker - MARKER):
        assert abs(v) < 4 * cal.std[f"tool0.p{k}"] + 1e-6
    R, t = instrument_frame(cal, "A")
    assert np.linalg.norm(t - INSTRUMENT[1]) < 0.1


def test_a_new_set_up_is_registered_with_the_robot_frozen(model, hidden_fit):
    _, cal = hidden_fit
    R2 = rotation_matrix([-0.1, 0.4, -1.0])
    moved = truth.Hidden(**{**HIDDEN.__dict__, "R": R2, "t": np.array([-500.0, 2500.0, -100.0])})
    q = truth.ur10_postures(60, 8)
    few, rest = _data(model, moved, q[:12], 9, "B"), _data(model, moved, q[12:], 10, "B")
    cal2 = register(cal, few)
    assert cal2.robot_values() == cal.robot_values()
    assert np.mean(position_errors(cal2, rest)) < 4 * SIGMA
    assert predict_points(cal2, rest).shape == (48, 3)
    cal3 = register(cal, few, marker=True)   # the marker re-fitted too: the same (it did not move)
    assert np.linalg.norm(cal3.marker - cal.marker) < 0.1 and np.mean(position_errors(cal3, rest)) < 4 * SIGMA


def test_one_pass_jacobian_matches_central_differences():
    from vjm.calibration import engine as cm
    from vjm.calibration.serial import full_layout, jacobian, jacobian_fast

    with warnings.catch_warnings():   # the bundled model: its joint and link springs are the nominal deflection
        warnings.simplefilter("ignore")
        model = vjm.load_model(os.path.join(ROOT, "data", "robots", "ur10", "ur10.yaml"))
    rng = np.random.default_rng(11)
    q = truth.ur10_postures(40, 12)
    d = AbsolutePoses(tuple(model.q_names), q, {"tool0": np.zeros((40, 3))},
                      group=np.array(["A"] * 20 + ["B"] * 20, dtype=object))
    frames = {"A": (rotation_matrix([0.1, 0.2, 0.3]), np.ones(3)), "B": (np.eye(3), np.zeros(3))}
    prob = cm._problem(model, d, "tool0", frames, MARKER, tilt=True)
    lay = full_layout(model, "tool0", prob.groups, ("tilt", "coupling"))
    assert {"backlash", "tilt", "coupling"} <= set(lay.kinds)
    x = rng.normal(size=lay.size) * 1e-2
    x[[i for i, u in enumerate(lay.units) if u == "c"]] = 1e-8   # rad/(N mm): 1e-3 rad at 100 N m
    J1, J2 = jacobian(prob, lay, x), jacobian_fast(prob, lay, x)
    scale = np.linalg.norm(J1, axis=0) / np.sqrt(len(J1)) + 1e-3   # per column rms (1e-3: the columns that vanish)
    assert np.max(np.abs(J1 - J2) / scale) < 1e-5


def test_a_payload_at_the_marker_is_weighed_through_the_compliances(model):
    hidden = truth.Hidden(**{**HIDDEN.__dict__, "payload": 5.0})
    data = _data(model, hidden, truth.ur10_postures(200, 13), 14)
    cal = calibrate(model, data, "tool0", effects=("geometry", "compliance", "payload"))
    assert [s.kept for s in cal.stages] == [True, True, True, True]
    m, s = cal.values["payload.mass"], cal.std["payload.mass"]
    assert s < 0.5 and abs(m - 5.0) < 4 * s
    for j in ("shoulder_lift_joint", "elbow_joint"):
        c, sc = cal.values[f"{j}.compliance"] * 1000, cal.std[f"{j}.compliance"] * 1000
        assert abs(c - HIDDEN.compliance[j]) < 4 * sc
    exact = _data(model, truth.Hidden(**{**hidden.__dict__, "sigma": 0.0}), truth.ur10_postures(100, 15), 16)
    assert np.max(position_errors(cal, exact)) < 3 * SIGMA


def test_the_calibrated_urdf_reproduces_the_calibrated_positions_in_pinocchio(model, hidden_fit, tmp_path):
    from vjm.calibration.write import write_calibrated
    from vjm.errors import VjmError

    data, cal = hidden_fit
    urdf, yml = tmp_path / "ur10_cal.urdf", tmp_path / "ur10_cal.yaml"
    write_calibrated(cal, URDF, str(urdf), str(yml))
    with pytest.raises(VjmError, match="exists"):
        write_calibrated(cal, URDF, str(urdf), str(tmp_path / "other.yaml"))
    q = data.q[:50]
    # the joints' sag under self-weight, as the calibration models it (its compliances)
    c = np.array([cal.values.get(f"{j}.compliance", 0.0) for j in model.q_names])
    qd = q - c * model.gravity_torques(q)
    R, t = instrument_frame(cal, "A")
    sub = data.subset(np.arange(50))
    base = (predict_points(cal, sub) - t) @ R     # the calibrated points in the robot's base frame, mm
    pm = truth.pin.buildModelFromUrdf(str(urdf))
    pd = pm.createData()
    fid = pm.getFrameId("tool0_marker")
    idx = [pm.idx_qs[pm.getJointId(n)] for n in model.q_names]
    got = np.empty((50, 3))
    for k, row in enumerate(qd):
        qq = np.zeros(pm.nq)
        qq[idx] = row
        truth.pin.framesForwardKinematics(pm, pd, qq)
        got[k] = pd.oMf[fid].translation * 1000.0
    assert np.max(np.abs(got - base)) < 1e-6           # mm: 1e-9 m
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        back = vjm.load_model(str(yml))
    assert np.max(np.abs(back.forward(qd, "tool0_marker")[:, :3, 3] - base)) < 1e-6
    c, s = cal.values["elbow_joint.compliance"], cal.std["elbow_joint.compliance"]
    # the file rounds the stiffness at the second significant digit of its standard deviation s / c^2
    assert back.joint_springs["elbow_joint"].stiffness == pytest.approx(1 / c, rel=0, abs=0.05 * s / c ** 2)


def test_cross_validation_keeps_what_predicts_held_out_rows(model):
    clean = calibrate(model, _data(model, CLEAN, truth.ur10_postures(150, 17), 18), "tool0", folds=3)
    st = clean.stages[0]
    # noise only: the held-out folds' RMS is the noise's (sigma sqrt(3) per point), a little above the fit's
    assert st.rms < st.cv_rms < 1.15 * SIGMA * np.sqrt(3)
    assert [s.name for s in clean.stages if s.kept] == ["registration"]
    cal = calibrate(model, _data(model, HIDDEN, truth.ur10_postures(150, 19), 20), "tool0", folds=3)
    cv = [s.cv_rms for s in cal.stages]
    assert [s.kept for s in cal.stages] == [True, True, True] and cv[0] > cv[1] > cv[2]
    assert cv[2] < 1.3 * SIGMA * np.sqrt(3)
