"""The compiled self-weight Newton (vjm.robot.sagkernel) against the general equilibrium solver
(vjm.stiffness.nonlinear.deflection_map with the robot's body loads): the same equations, two codes."""
import os

import numpy as np

import vjm
from vjm.modelio.urdf import read_urdf
from vjm.robot.model import JointSpring, Payload, RobotModel
from vjm.robot.weight import body_loads
from vjm.stiffness.nonlinear import deflection_map

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
UR10 = os.path.join(ROOT, "data", "robots", "ur10", "ur10.yaml")
TREE = os.path.join(ROOT, "tests", "vjm", "robots", "torso_two_arms.urdf")


def _general(m, Q, tool, W, payload=None):
    kin = m.kinematics(Q, tool)
    loads = body_loads(m, kin.q, tool, np.asarray(m.gravity, dtype=float), payload or m.payload)
    return deflection_map(m, kin, W, body_loads=[loads])


def _rel(a, b):
    return np.max(np.abs(a - b), axis=1) / np.max(np.abs(b), axis=1)


def test_ur10_sag_with_payload_and_tool_force_is_the_general_solvers():
    m = vjm.load_model(UR10)
    Q = np.random.default_rng(11).uniform(-2.5, 2.5, (25, m.nq))
    pl = Payload("tool0", 12.0, (10.0, -5.0, 60.0))
    W = np.array([40.0, -25.0, 90.0, 0.0, 0.0, 0.0])
    t, info = m.self_weight(Q, payload=pl, wrench=W, return_info=True)
    assert not np.any(info["fallback"]) and np.all(info["converged"])
    ref = _general(m, Q, "tool0", W, pl)
    assert np.max(np.abs(ref[:, :3])) > 0.1  # mm: a real sag
    assert np.all(_rel(t, ref) <= 1e-9)


def test_soft_tree_arm_with_large_sag_is_the_general_solvers():
    tree = read_urdf(TREE)
    k = {n: (3e6 if tree.joints[tree.joint_index(n)].type != "prismatic" else 2e3) for n in tree.q_names}
    m = RobotModel(tree, {n: JointSpring(v) for n, v in k.items()})
    lo, hi = np.maximum(tree.limits[0], -2.0), np.minimum(tree.limits[1], 2.0)
    Q = lo + (hi - lo) * np.random.default_rng(3).uniform(0.2, 0.8, (8, m.nq))
    for tool in tree.tools:
        t, info = m.self_weight(Q, tool, return_info=True)
        assert not np.any(info["fallback"])
        ref = _general(m, Q, tool, np.zeros(6))
        assert np.max(np.abs(ref[:, 3:])) > 1e-3  # rad: beyond the linear range
        assert np.all(_rel(t, ref) <= 1e-9)


def test_a_tool_moment_goes_to_the_general_solver():
    m = vjm.load_model(UR10)
    Q = np.random.default_rng(5).uniform(-2.0, 2.0, (3, m.nq))
    W = np.array([0.0, 0.0, 0.0, 2e4, 0.0, -1e4])
    t, info = m.self_weight(Q, wrench=W, return_info=True)
    assert np.all(info["fallback"]) and np.all(info["converged"])
    assert np.array_equal(t, _general(m, Q, "tool0", W))
