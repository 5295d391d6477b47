"""``vjm simulate robot.yaml``: absolute-pose rows that vjm calibrate's reader takes; the points are where
pinocchio puts the frame at the reported joints plus the hidden offsets (a rigid robot), the sag scales
with a hidden compliance factor (small deflections: linear elasticity), and the noise has its sigma."""
import os

import numpy as np
import pytest

from vjm.calibration.poses import read_poses
from vjm.cli import main

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
UR10_DIR = os.path.join(ROOT, "data", "robots", "ur10")
UR10 = os.path.join(UR10_DIR, "ur10.yaml")
URDF = os.path.join(UR10_DIR, "ur10.urdf")
NAMES = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
         "wrist_3_joint")


def _simulate(tmp_path, name, model, *args):
    out = tmp_path / name
    assert main(["simulate", str(model), "--out", str(out), *args]) == 0
    return read_poses(out, joints=NAMES)


def test_rigid_robot_points_are_pinocchio_frames_at_the_joints_plus_hidden_offsets(tmp_path):
    pin = pytest.importorskip("pinocchio")
    from test_robot_pinocchio import _pin_model, _pin_q

    import vjm

    (tmp_path / "rigid.yaml").write_text(f"urdf: {URDF}\ntools: [tool0]\n")
    d = _simulate(tmp_path, "rigid.csv", tmp_path / "rigid.yaml", "--poses", "random:6", "--noise-t", "0",
                  "--effect", "offset:elbow_joint=0.003,wrist_2_joint=-0.002")
    assert d.q.shape == (6, 6) and set(d.points) == {"tool0"}
    off = np.array([0, 0, 0.003, 0, -0.002, 0])
    tree = vjm.load_model(str(tmp_path / "rigid.yaml")).tree
    pm = _pin_model(URDF)
    pd = pm.createData()
    for q, p in zip(d.q, d.points["tool0"]):
        pin.framesForwardKinematics(pm, pd, _pin_q(pm, tree, q + off))
        assert p == pytest.approx(1000.0 * np.asarray(pd.oMf[pm.getFrameId("tool0")].translation), abs=1e-9)


def test_sag_scales_with_a_hidden_compliance_factor_and_noise_has_its_sigma(tmp_path):
    import vjm

    m = vjm.load_model(UR10)
    args = ["--poses", "random:5", "--seed", "4"]
    clean = _simulate(tmp_path, "a.csv", UR10, *args, "--noise-t", "0")
    double = _simulate(tmp_path, "b.csv", UR10, *args, "--noise-t", "0", "--effect",
                       "compliance:shoulder_lift_joint=2,elbow_joint=2")
    assert np.array_equal(clean.q, double.q)  # the same configurations (one seed)
    rigid = m.forward(clean.q)[:, :3, 3]
    s1 = clean.points["tool0"] - rigid
    s2 = double.points["tool0"] - rigid
    # doubling the shoulder's and the elbow's compliances adds, to first order, their share of the linear
    # sag once more: J_j (-g_j / k_j) over those joints, g the holding torques (closed form, no solver)
    J = m.jacobian(clean.q)
    g = m.gravity_torques(clean.q)
    k = np.array([m.joint_springs[n].stiffness for n in NAMES])
    lin = -np.einsum("nij,nj->ni", J[:, :3, 1:3], g[:, 1:3] / k[1:3])   # those two joints' linear share
    extra = s2 - s1
    assert np.linalg.norm(extra - lin) <= 0.02 * np.linalg.norm(lin)  # second order: sag / arm ~ 1e-3
    assert np.linalg.norm(lin) > 0.1  # the check sees a sag of tenths of a millimetre
    noisy = _simulate(tmp_path, "c.csv", UR10, "--poses", "random:300", "--seed", "4", "--noise-t", "0.05")
    exact = m.forward(noisy.q)[:, :3, 3] + m.self_weight(noisy.q)[:, :3]
    assert np.std(noisy.points["tool0"] - exact) == pytest.approx(0.05, rel=0.1)
    assert np.all(noisy.sigmas["tool0"] == 0.05)
