"""The numeric inverse kinematics on large batches (vjm.kinematics.ik): anchors along a curve through the
poses, the compiled kernels (vjm.kinematics.ik_kernel) and the numpy path."""
import numpy as np
import pytest

import vjm
from vjm.kinematics import ik
from vjm.kinematics.chain import forward
from vjm.kinematics.poses import as_poses

HEXAPOD = "data/machines/hexapod_6ups.yaml"


@pytest.fixture(scope="module")
def hexapod():
    """The hexapod and 600 random platform frames in random order (more than COMPILED_FROM and
    4 x ANCHOR_EVERY poses: anchors and compiled kernels in use), ten of them out of reach
    (platform 1.5 m up: struts beyond their 750 mm limit)."""
    m = vjm.load_model(HEXAPOD)
    rng = np.random.default_rng(11)
    X = np.zeros((600, 6))
    X[:, :2] = rng.uniform(-80.0, 80.0, (600, 2))
    X[:, 2] = rng.uniform(480.0, 620.0, 600)
    X[:, 3:] = rng.uniform(-0.12, 0.12, (600, 3))
    far = np.zeros(600, dtype=bool)
    far[rng.choice(600, 10, replace=False)] = True
    X[far, 2] = 1500.0
    assert 600 >= max(ik.COMPILED_FROM, 4 * ik.ANCHOR_EVERY)
    return m, as_poses(X, 6), far


def test_large_batch_closes_and_matches_single_poses(hexapod):
    """A batch of 600 poses: every reachable pose closes in every chain (forward kinematics of the
    solution lands on the platform frame: 1e-9 mm, 1e-12 rad), exactly the poses out of reach are
    reported, and each pose's values equal those of the pose solved alone from the seed (no
    anchors, numpy path) to 1e-9 (mm, rad): the starting point changes nothing but round-off."""
    m, F, far = hexapod
    _, vals, ok, first = m.arch.solve_all(m, F)
    assert np.array_equal(ok, ~far)
    assert first[0] == np.flatnonzero(far)[0]
    for ch, v in zip(m.chains, vals):
        T = forward(ch, v[ok])
        assert np.max(np.abs(T[:, :3, 3] - F[ok, :3, 3])) <= 1e-9
        assert np.max(np.abs(T[:, :3, :3] - F[ok, :3, :3])) <= 1e-12
    for i in range(0, 600, 41):
        _, vi, oki, _ = m.arch.solve_all(m, F[i:i + 1])
        assert oki[0] == ok[i]
        if ok[i]:
            assert max(np.max(np.abs(a[0] - b[i])) for a, b in zip(vi, vals)) <= 1e-9


def test_compiled_kernels_equal_numpy_path(hexapod, monkeypatch):
    """The compiled kernels and the numpy path take the same steps: same reachable mask, values
    equal to 1e-9 (mm, rad), on the same batch."""
    pytest.importorskip("numba")
    m, F, _ = hexapod
    _, vc, okc, _ = m.arch.solve_all(m, F)
    monkeypatch.setattr(ik, "COMPILED_FROM", 10**9)
    _, vn, okn, _ = m.arch.solve_all(m, F)
    assert np.array_equal(okc, okn)
    assert max(np.max(np.abs(a[okc] - b[okc])) for a, b in zip(vc, vn)) <= 1e-9


def test_orthoglide_description_batch_equals_closed_form():
    """3-PUU description file on 2,000 random points in a box larger than its workspace: the
    numeric IK's reachable mask is the built-in module's closed form (the leg's length L reaches
    the point; points within 1e-6 relative of that boundary left out) and its actuator
    coordinates equal the closed form's to 1e-9 mm."""
    a = vjm.load_model("data/orthoglide/puu.yaml")
    b = vjm.load_model("data/machines/orthoglide_puu.yaml")
    rng = np.random.default_rng(5)
    P = rng.uniform(-320.0, 320.0, (2000, 3))
    L = a.geometry["L"]
    # chain i's carriage axis is world axis i and the leg's far end is offset from P along it:
    # the leg reaches P when P's distance from that axis is below L
    s = np.stack([(np.sum(P**2, axis=1) - P[:, i] ** 2) / L**2 for i in range(3)], axis=1)
    keep = np.all(np.abs(s - 1.0) > 1e-6, axis=1)
    P, s = P[keep], s[keep]
    reach = np.all(s < 1.0, axis=1)
    assert 300 < reach.sum() < len(P) - 300
    F = as_poses(P, 3)
    qb, _, okb, _ = b.arch.solve_all(b, F)
    assert np.array_equal(okb, reach)
    assert np.array_equal(a.arch.reachable(a, P), reach)
    qa = a.inverse_kinematics(P[reach])
    assert np.max(np.abs(qb[reach] - qa)) <= 1e-9
