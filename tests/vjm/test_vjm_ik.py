"""The numeric inverse kinematics on large batches (vjm.kinematics.ik): anchors along a curve through the
poses, the compiled kernels (vjm.kinematics.ik_kernel) and the numpy path; the hexapod's legs also in
closed form (vjm.kinematics.closed_form), checked against Newton."""
import numpy as np
import pytest

import vjm
from vjm.kinematics import ik
from vjm.kinematics.chain import forward
from vjm.kinematics.poses import as_poses

HEXAPOD = "data/machines/hexapod_6ups.yaml"


@pytest.fixture(params=[False, True], ids=["newton", "closed_form"])
def hexapod(request, monkeypatch, hexapod_poses):
    """The hexapod batch, its legs solved by Newton (``CLOSED_FORM`` off) or in closed form."""
    monkeypatch.setattr(ik, "CLOSED_FORM", request.param)
    return hexapod_poses


@pytest.fixture(scope="module")
def hexapod_poses():
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


def _turns(d, angle):
    """|d| (n, k), whole turns taken off the columns that are angles (the closed form keeps an angle within
    half a turn of its seed value; Newton, continued from the seed, may land a turn away near a half turn)."""
    d = np.abs(d)
    return np.where(angle, np.abs(d - 2.0 * np.pi * np.round(d / (2.0 * np.pi))), d)


def _random_frames(n, seed, tilt=0.3):
    rng = np.random.default_rng(seed)
    X = np.zeros((n, 6))
    X[:, :2] = rng.uniform(-80.0, 80.0, (n, 2))
    X[:, 2] = rng.uniform(470.0, 630.0, n)
    X[:, 3:] = rng.uniform(-tilt, tilt, (n, 3))
    return as_poses(X, 6)


@pytest.mark.parametrize("compiled", [False, True], ids=["numpy", "compiled"])
def test_closed_form_legs_are_newtons_solution(monkeypatch, compiled):
    """The hexapod's legs in closed form against Newton from the seed, on 400 random frames tilted up to
    0.3 rad, on the compiled and the numpy path: the same reachable mask; the U joint's angles and the
    strut's length equal to 1e-9 (mm, rad; angles up to whole turns); the S joint's angles close the leg
    on the platform (1e-9 mm, 1e-12).  (This S joint works near its gimbal lock, its middle angle near a
    right angle, where its two sets of angles meet: Newton may take either, the closed form takes the
    seed's side; the joint's motion, and so the stiffness, is the same.)  The form is recognised."""
    from vjm.kinematics import closed_form
    from vjm.kinematics.chain import forward

    if compiled:
        pytest.importorskip("numba")
    m = vjm.load_model(HEXAPOD)
    F = _random_frames(400, 3)
    monkeypatch.setattr(ik, "COMPILED_FROM", 1 if compiled else 10**9)
    out = {}
    for cf in (False, True):
        monkeypatch.setattr(ik, "CLOSED_FORM", cf)
        _, vals, ok, _ = m.arch.solve_all(m, F)
        out[cf] = (vals, ok)
    (vn, okn), (vc, okc) = out[False], out[True]
    assert okn.sum() > 300 and np.array_equal(okn, okc)
    U = [m.chains[0].index(v) for v in ("a1", "a2", "l")]
    assert max(np.max(_turns(a[okn][:, U] - b[okn][:, U], np.array([True, True, False])))
               for a, b in zip(vn, vc)) <= 1e-9
    for ch, v in zip(m.chains, vc):
        T = forward(ch, v[okc])
        assert np.max(np.abs(T[:, :3, 3] - F[okc, :3, 3])) <= 1e-9
        assert np.max(np.abs(T[:, :3, :3] - F[okc, :3, :3])) <= 1e-12
    ch = m.chains[0]
    cl = ik.closure(ch, m.arch._unknowns(ch))
    assert closed_form.pattern(cl.chain) is not None
    assert closed_form.pattern(ik.closure(vjm.load_model("data/machines/orthoglide_puu.yaml").chains[0],
                                          m.arch._unknowns(ch)[:0]).chain) is None


def _leg(kinds, wrist, coefs=(1.0,) * 6):
    """A U-P-S leg ``C0 R R T (spring) R R R C1`` with the given axes (a base offset and a platform
    attachment turned about every axis), and its seed values."""
    from vjm.kinematics.chain import ChainBuilder
    from vjm.kinematics.poses import rotation_matrix
    from vjm.kinematics.transforms import homogeneous

    b = ChainBuilder("leg")
    b.const(homogeneous(rotation_matrix(np.array([[0.2, -0.1, 0.4]]))[0], (300.0, -40.0, 10.0)))
    b.passive(kinds[0], "a1", coefs[0])
    b.passive(kinds[1], "a2", coefs[1])
    b.actuated(kinds[2], "l", spring="actuator")
    b.spring6("leg")
    for name, kind, c in zip(("s1", "s2", "s3"), wrist, coefs[3:]):
        b.passive(kind, name, c)
    b.const(homogeneous(rotation_matrix(np.array([[-0.3, 0.2, 0.1]]))[0], (-150.0, 20.0, 5.0)))
    return b.build()


@pytest.mark.parametrize("kinds, wrist, coefs", [
    (("rz", "ry", "tx"), ("rx", "ry", "rz"), (1.0,) * 6),
    (("ry", "rx", "tz"), ("rz", "ry", "rx"), (1.0, -1.0, 1.0, 1.0, -1.0, 1.0)),   # odd orders, reversed joints
    (("rx", "rz", "ty"), ("ry", "rx", "rz"), (1.0, 1.0, -1.0, 1.0, 1.0, 1.0)),
])
def test_closed_form_of_any_axis_order_closes_on_newtons_branch(kinds, wrist, coefs):
    """Legs of other axis orders (odd permutations, joints written with coefficient -1, a strut that
    extends backwards): the closed form's values multiplied out land on the frames (1e-9 mm, 1e-12), and
    equal Newton's from the seed (1e-8, angles up to whole turns), on frames near the seed's (200 of them, moved up to 40 mm and
    0.25 rad)."""
    from vjm.kinematics import closed_form
    from vjm.kinematics.chain import forward
    from vjm.kinematics.poses import rotation_matrix

    ch = _leg(kinds, wrist, coefs)
    U = [ch.index(v) for v in ("a1", "a2", "l", "s1", "s2", "s3")]
    seed = np.zeros(ch.n_vars)
    seed[U] = [0.3, -0.2, 500.0 * coefs[2], 0.1, 0.2, -0.1]
    F0 = forward(ch, seed[None])[0]
    rng = np.random.default_rng(9)
    n = 200
    dR = rotation_matrix(rng.uniform(-0.25, 0.25, (n, 3)))
    F = np.repeat(F0[None], n, axis=0)
    F[:, :3, :3] = dR @ F0[:3, :3]
    F[:, :3, 3] += rng.uniform(-40.0, 40.0, (n, 3))
    cl = ik.closure(ch, U)
    assert closed_form.pattern(cl.chain) is not None
    v, ok, _ = closed_form.solve(cl.chain, seed[U], F, cl.ell)
    assert ok.all()
    full = np.repeat(seed[None], n, axis=0)
    full[:, U] = v
    T = forward(ch, full)
    assert np.max(np.abs(T[:, :3, 3] - F[:, :3, 3])) <= 1e-9
    assert np.max(np.abs(T[:, :3, :3] - F[:, :3, :3])) <= 1e-12
    vn, okn, _ = ik._solve(cl, seed[U], F0, F, compiled=False)
    assert okn.all() and np.max(_turns(vn.T - v, np.array([k[0] == "r" for k in kinds + wrist]))) <= 1e-8


def test_hexapod_map_with_closed_form_legs_is_newtons(monkeypatch):
    """The hexapod's stiffness map (compiled kernels, 300 poses) with the legs in closed form equals the
    map with Newton's legs: K and C to 1e-10 relative, the same ranks and invertibility."""
    pytest.importorskip("numba")
    X = _random_frames(300, 4, tilt=0.1)
    res = {}
    for cf in (False, True):
        monkeypatch.setattr(ik, "CLOSED_FORM", cf)
        mm = vjm.load_model(HEXAPOD)
        res[cf] = mm.stiffness_map(X, kernel="numba")
    a, b = res[False], res[True]
    for f in ("K", "C"):
        A, B = getattr(a, f), getattr(b, f)
        scale = np.max(np.abs(A), axis=(1, 2))[:, None, None]
        assert np.max(np.abs(A - B) / scale) <= 1e-10
    assert np.array_equal(a.rank, b.rank) and np.array_equal(a.invertible, b.invertible)
