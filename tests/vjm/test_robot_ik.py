"""Numerical IK of a serial robot holding a configuration, and maps over Cartesian points."""
import numpy as np
import pytest

import vjm
from vjm.kinematics.transforms import rotation_vector
from vjm.robot.ik import pose_targets

UR10 = "data/robots/ur10/ur10.yaml"


def test_ik_returns_the_configuration_of_its_seed():
    """The same tool poses reached from two seeds on different elbow branches give two solutions, each the
    configuration the poses were made from."""
    m = vjm.load_model(UR10)
    rng = np.random.default_rng(0)
    up = np.array([0.0, -1.2, 1.5, -1.9, -1.57, 0.0])
    Q = up + rng.uniform(-0.2, 0.2, (20, 6))
    T = m.forward(Q)
    r = m.inverse(T, up)
    assert np.all(r.reached) and not np.any(r.singular)
    assert np.max(np.abs(r.q - Q)) < 1e-9
    # the other elbow branch of the first pose: solve from a seed with the elbow flipped
    q0 = Q[0]
    down_seed = q0 + np.array([0.0, -0.9, -2.0 * q0[2], 0.9, 0.0, 0.0])
    d = m.inverse(T[0], down_seed)
    assert d.reached[0] and np.sign(d.q[0, 2]) != np.sign(q0[2])
    assert m.forward(d.q[0]) == pytest.approx(T[0], abs=1e-8)


def test_unreachable_and_singular_points_are_flagged():
    m = vjm.load_model(UR10)
    seed = np.array([0.0, -1.2, 1.5, -1.9, -1.57, 0.0])
    far = m.inverse(pose_targets([[3000.0, 0.0, 0.0]]), seed)
    assert not far.reached[0]
    wrist = seed.copy()
    wrist[4] = 0.0  # wrist 1 and wrist 3 axes aligned: a wrist singularity
    s = m.inverse(m.forward(wrist), wrist)
    assert s.reached[0] and s.singular[0]


def test_cartesian_map_is_the_stiffness_at_the_ik_solutions():
    m = vjm.load_model(UR10)
    seed = np.array([0.0, -1.2, 1.5, -1.9, -1.57, 0.0])
    T0 = m.forward(seed)
    rot = rotation_vector(T0[:3, :3])
    pts = T0[:3, 3] + np.array([[0.0, 0, 0], [50.0, 0, 0], [100.0, 20, -30], [5000.0, 0, 0]])
    ik, r, sag = m.cartesian_map(pts, seed, orientation=rot, self_weight=True)
    assert ik.reached.tolist() == [True, True, True, False]
    assert r.points == pytest.approx(pts[:3], abs=1e-6)
    assert r.k_tran[1] == pytest.approx(m.stiffness(ik.q[1]).k_tran, rel=1e-12)
    assert sag.shape == (3, 6)
