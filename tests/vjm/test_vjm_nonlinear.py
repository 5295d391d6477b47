"""Issue 4 test 2: the linear stiffness is the slope of an independent nonlinear equilibrium;
and the batched nonlinear solver itself (derivatives, batching, hard cases, failures)."""
import numpy as np
import pytest

import vjm
from vjm.errors import VjmError
from vjm.kinematics.chain import forward
from vjm.kinematics.transforms import elementary, vee
from vjm.stiffness.nonlinear import _linearize, _setup, deflection, deflection_map

PUU = "data/orthoglide/puu.yaml"
PRPAR = "data/orthoglide/prpar.yaml"


@pytest.fixture(scope="module")
def puu():
    return vjm.load_model(PUU)


@pytest.fixture(scope="module")
def prpar():
    return vjm.load_model(PRPAR)


def _slope(m, p):
    """Central differences of the nonlinear deflection under +-10 N and +-100 N mm, (6, 6)."""
    e = np.array([10.0, 10.0, 10.0, 100.0, 100.0, 100.0])
    W = np.concatenate([np.diag(e), -np.diag(e)])
    D = deflection_map(m, np.broadcast_to(p, (12, 3)), W)
    return ((D[:6] - D[6:]) / (2 * e[:, None])).T


@pytest.mark.parametrize("p", [(0.0, 0.0, 0.0), (30.0, -50.0, 80.0), (-73.65, -73.65, -73.65)])
def test_linear_compliance_is_slope_of_nonlinear_equilibrium(puu, p):
    """3-PUU.  vjm.stiffness.nonlinear minimises spring energy minus work over all joint coordinates of
    the three chains, with finite rotations and loop closure (Newton on the KKT system, its own
    derivatives of the chain product): it shares neither the Jacobians nor the bordered
    solve with the linear model.  Central differences under +-10 N and +-100 N mm cancel the
    even (quadratic) nonlinear terms; the cubic ones are ~ (deflection / L)^2 < 1e-8, so each
    column of C = K^-1 must match to 1e-4 relative (observed ~1e-6, round-off of the solve)."""
    C = puu.stiffness(p).C
    fd = _slope(puu, p)
    for k in range(6):
        assert np.linalg.norm(fd[:, k] - C[:, k]) <= 1e-4 * np.linalg.norm(C[:, k])


def test_prpar_linear_compliance_is_slope_of_nonlinear_equilibrium(prpar):
    """Same check on the 3-PRPaR at a general posture: the nonlinear model holds the
    parallelogram spring rigid along its own mobility (carried exactly by the passive coupled
    joint), which must leave the linear limit unchanged; 1e-4 relative as above."""
    p = (30.0, -50.0, 80.0)
    C = prpar.stiffness(p).C
    fd = _slope(prpar, p)
    for k in range(6):
        assert np.linalg.norm(fd[:, k] - C[:, k]) <= 1e-4 * np.linalg.norm(C[:, k])


def test_nonlinear_departs_from_linear_under_large_load(puu):
    """Sanity of the nonlinear model: under a load giving ~0.3 mm deflections the equilibrium
    differs from C w by more than round-off but by less than the deflection itself."""
    p, w = (30.0, -50.0, 80.0), np.array([500.0, -300.0, 200.0, 2e4, 0.0, 0.0])
    lin, nl = puu.deflection(p, w), deflection(puu, p, w)
    diff = np.linalg.norm(nl[:3] - lin[:3])
    assert 1e-4 * np.linalg.norm(lin[:3]) < diff < 0.5 * np.linalg.norm(lin[:3])


def _closure_complex(cd, k, v, u, p0):
    """Closure residual of chain k straight from eq. 1 (vjm.kinematics.chain.forward), complex-safe."""
    T = forward(cd.chain, v)
    R = elementary("rx", u[:, 3])[:, :3, :3] @ elementary("ry", u[:, 4])[:, :3, :3] \
        @ elementary("rz", u[:, 5])[:, :3, :3] @ cd.R0
    return np.concatenate([T[:, :3, 3] - (p0 + u[:, :3]), vee(T[:, :3, :3] @ np.swapaxes(R, 1, 2))], axis=1)


def test_constraint_derivatives_match_complex_step(prpar):
    """The solver's closed-form derivatives of the closure (dT/da_f = X_f T, d2T/da_f da_h =
    X_f X_h T) against complex-step differentiation of the chain product of eq. 1 (exact to
    round-off, so 1e-9 relative) for the gradient, and against central differences of that
    gradient (truncation ~ h^2, so 1e-5 relative) for the Hessian of lam . g, at a perturbed
    state of the 3-PRPaR (finite joint offsets, platform rotation, arbitrary multipliers)."""
    rng = np.random.default_rng(3)
    P, chains = _setup(prpar, np.array([[20.0, -40.0, 60.0]]))
    nx = sum(cd.S.shape[1] for cd in chains)
    x = 1e-2 * rng.standard_normal((1, nx))
    for cd, sl in zip(chains, np.split(np.arange(nx), np.cumsum([c.S.shape[1] for c in chains])[:-1])):
        x[:, sl[cd.fixed[0]]] = 0.0
    u = np.array([[0.3, -0.2, 0.1, 0.02, -0.03, 0.01]])
    lam = rng.standard_normal((1, 18)) * np.array([100.0] * 3 + [1e4] * 3)[np.arange(18) % 6]
    g, G, H = _linearize(chains, x, u, lam, P)[:3]
    h = 1e-20
    col = 0
    for k, cd in enumerate(chains):
        m = cd.S.shape[1]
        for j in range(m + 6):
            dx = np.zeros((1, m), complex)
            du = np.zeros((1, 6), complex)
            if j < m:
                dx[0, j] = 1j * h
            else:
                du[0, j - m] = 1j * h
            v = cd.v0 + np.einsum("nm,nmv->nv", x[:, col:col + m] + dx, cd.S)
            gc = _closure_complex(cd, k, v, u + du, P)
            assert np.allclose(gc.real, g[:, 6 * k:6 * k + 6], atol=1e-12)
            ref = gc.imag[0] / h
            got = G[0, 6 * k:6 * k + 6, col + j] if j < m else G[0, 6 * k:6 * k + 6, nx + j - m]
            if j < m and cd.fixed[0, j]:
                assert np.all(got == 0.0)  # rigid directions are not unknowns
                continue
            assert np.linalg.norm(got - ref) <= 1e-9 * max(np.linalg.norm(ref), 1.0)
        col += m
    # Hessian of lam . g: central differences of G^T lam
    z0 = np.concatenate([x, u], axis=1)
    free = np.flatnonzero(np.concatenate([~np.concatenate([cd.fixed for cd in chains], axis=1)[0],
                                          np.ones(6, bool)]))
    scale = np.abs(H).max()  # columns whose curvature vanishes are compared to round-off of the largest
    for j in free[::3]:
        e = 1e-5
        zp, zm = z0.copy(), z0.copy()
        zp[0, j] += e
        zm[0, j] -= e
        Gp = _linearize(chains, zp[:, :nx], zp[:, nx:], lam, P, hessian=False)[1]
        Gm = _linearize(chains, zm[:, :nx], zm[:, nx:], lam, P, hessian=False)[1]
        ref = ((Gp - Gm)[0].T @ lam[0]) / (2 * e)
        assert np.linalg.norm(H[0, :, j] - ref) <= 1e-5 * np.linalg.norm(ref) + 1e-9 * scale


def test_batched_equals_single_pair(puu, prpar):
    """deflection_map solves all pairs together (stacked KKT systems, per-pair convergence):
    each row equals the one-pair solve, to the solver's tolerance (1e-9 relative), for a batch
    mixing postures, small, large and zero loads."""
    rng = np.random.default_rng(11)
    for m in (puu, prpar):
        P = rng.uniform(-60.0, 60.0, (6, 3))
        W = rng.standard_normal((6, 6)) * np.array([300.0] * 3 + [3e4] * 3)
        W[2] = 0.0
        W[4] *= 1e-3
        D = deflection_map(m, P, W)
        assert np.all(D[2] == 0.0)
        for p, w, d in zip(P, W, D):
            single = deflection(m, p, w)
            assert np.linalg.norm(single - d) <= 1e-9 * max(np.linalg.norm(single), 1e-12)


def test_prpar_hard_case_converges_near_linear(prpar):
    """3-PRPaR at (26, 126, -74) mm under Mz = 1e4 N mm: a ~1.4e-3 rad rotation, so the
    nonlinear equilibrium is within a few percent of C w (second-order terms ~ rotation ~1e-3;
    10 % is generous).  A spurious straight-line copy of the parallelogram mobility inside its
    spring once sent Newton's method to a far equilibrium (-330 mm)."""
    p, w = (26.0, 126.0, -74.0), np.array([0.0, 0.0, 0.0, 0.0, 0.0, 1e4])
    nl = deflection(prpar, p, w)
    lin = prpar.deflection(p, w)
    assert np.linalg.norm(nl - lin) <= 0.1 * np.linalg.norm(lin)


def test_failure_is_reported_not_silent(puu):
    """A load far past what the model can carry (1e7 N mm about x and y, i.e. 10 kN m) has no
    equilibrium reachable by load stepping: the solver must say so, naming the pose, or flag
    the row (NaN, converged False) without spoiling the other rows of the batch."""
    P = np.array([[0.0, 0.0, 0.0], [30.0, -50.0, 80.0]])
    W = np.array([[0.0, 0.0, 0.0, 1e7, 1e7, 0.0], [100.0, 0.0, 0.0, 0.0, 0.0, 0.0]])
    with pytest.raises(VjmError, match=r"p = \[0\.0, 0\.0, 0\.0\] mm"):
        deflection_map(puu, P, W)
    D, info = deflection_map(puu, P, W, strict=False, return_info=True)
    assert info["converged"].tolist() == [False, True]
    assert np.all(np.isnan(D[0]))
    assert np.allclose(D[1], deflection(puu, P[1], W[1]), rtol=0, atol=1e-12)


def test_shared_spring_bases_are_taken_as_views_with_the_copies_values():
    """Constant compliances give one spring basis for every pose (a stride-0 view); taking poses by
    indices, a mask or a slice keeps a view with the values a copy per pose would have."""
    from vjm.stiffness.nonlinear import _rows

    m = vjm.load_model("data/orthoglide/puu.yaml")
    P = np.array([[0.0, 0.0, 0.0], [10.0, -5.0, 3.0], [-20.0, 15.0, 8.0], [5.0, 5.0, -12.0]])
    _, chains = _setup(m, P)
    cd = chains[0]
    assert cd.constant and np.shares_memory(cd.S[0], cd.S[3])
    full = np.array(cd.S)  # a copy per pose
    for idx in (np.array([3, 1]), np.array([True, False, True, True]), slice(1, 3)):
        r = _rows(cd.S, idx)
        assert r.strides[0] == 0
        np.testing.assert_array_equal(r, full[idx])
    np.testing.assert_array_equal(cd.take(np.array([2, 0])).D, np.array(cd.D)[[2, 0]])
