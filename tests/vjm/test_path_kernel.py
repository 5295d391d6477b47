"""The compiled Newton steps (vjm.stiffness.nonlinear_kernel) against the numpy equations they evaluate
(vjm.stiffness.nonlinear._linearize, _newton_step; vjm.toolpath.equilibrium.residual_ok), and the compiled
path equilibria against the numpy path (equilibrium.KERNEL = False) on the 3-PUU and the hexapod:
the same cold starts, the same deflections to the chord steps' tolerance."""
import numpy as np
import pytest

import vjm
from vjm.stiffness import nonlinear as nl
from vjm.toolpath import equilibrium as eq

pytest.importorskip("numba")
from vjm.stiffness import nonlinear_kernel as K

PUU = "data/orthoglide/puu.yaml"
HEXAPOD = "data/machines/hexapod_6ups.yaml"
PRPAR = "data/orthoglide/prpar.yaml"  # its parallelogram's compliance, and its rigid directions, change with the pose


def _puu_path(n=160):
    """A line along x then along y at z = 5 mm, 0.5 mm apart; the milling-like force turns with the feed."""
    k = n // 2
    a = np.column_stack([np.linspace(-40, -40 + 0.5 * (k - 1), k), np.full(k, -10.0), np.full(k, 5.0)])
    b = np.column_stack([np.full(n - k, a[-1, 0]), a[-1, 1] + 0.5 * np.arange(1, n - k + 1), np.full(n - k, 5.0)])
    P = np.vstack([a, b])
    feed = np.gradient(P, axis=0)
    feed /= np.linalg.norm(feed, axis=1, keepdims=True)
    W = np.zeros((n, 6))
    W[:, :3] = -60.0 * feed + [0.0, 0.0, 20.0]
    W[:, 3:] = np.cross(np.broadcast_to([0.0, 0.0, -60.0], P.shape), W[:, :3])
    return P, W


def _hexapod_path(n=40):
    P = np.column_stack([np.linspace(-20, 20, n), np.linspace(5, -5, n), np.full(n, 550.0),
                         np.zeros(n), np.zeros(n), np.linspace(0, 0.1, n)])
    return P, np.tile([200.0, -100.0, 300.0, 2000.0, 0.0, -1000.0], (n, 1))


@pytest.fixture(autouse=True)
def _kernel_on_short_paths(monkeypatch):
    monkeypatch.setattr(eq, "KERNEL_MIN", 0)


def _both(monkeypatch, m, P, W, **kw):
    monkeypatch.setattr(eq, "KERNEL", False)
    ref = eq.equilibria(m, P, W, **kw)
    monkeypatch.setattr(eq, "KERNEL", True)
    return ref, eq.equilibria(m, P, W, **kw)


@pytest.mark.parametrize("name, path", [(PUU, _puu_path), (HEXAPOD, _hexapod_path)])
def test_compiled_equations_are_the_numpy_ones(name, path):
    """At perturbed states (not an equilibrium: every term counts) the kernel's closure residual, its
    gradient and the Hessian of lam . g equal nonlinear._linearize's, its Newton step
    nonlinear._newton_step's, and its residual check equilibrium.residual_ok's verdict."""
    m = vjm.load_model(name)
    P, W = path(6)
    b = eq._Block(m, P, W, None)
    tab, (v0, R0, S, D, fixed, kappa, kd, xr, Wd, Pd) = eq._pack(b)
    s = eq.equilibria(m, P, W)
    nv = s.state.shape[1] - 6 - b.nc
    z = np.concatenate([eq._to_x(b.chains, s.state[:, :nv]), s.state[:, nv:]], axis=1)
    z = z * (1.0 + 0.05 * np.random.default_rng(3).standard_normal(z.shape))
    g, G, Hs = nl._linearize(b.chains, z[:, :b.nx], z[:, b.nx:b.nx + 6], z[:, b.nx + 6:], b.P)[:3]
    dz = nl._newton_step(b.chains, z, np.ones(len(z)), b.W, b.P, b.kappa, b.kd, b.x_rest, b.nx, b.nc)
    ok = eq.residual_ok(b.chains, z, b.W, b.P, b.kappa, b.x_rest, b.nx, b.lref)
    assert len(S) == len(D) == 1  # constant compliances: one spring basis packed for every point
    for i in range(len(z)):
        pt = (v0[i], R0[i], S[0], D[0], fixed[i])
        gk, Gk, Hk = np.empty(b.nc), np.empty((b.nc, b.nx + 6)), np.empty((b.nx + 6, b.nx + 6))
        K.linearize(tab, pt, z[i], Pd[i], True, gk, Gk, Hk)
        # closure: round-off of the machine's size (positions of ~500 mm cancel), and of 1 rad
        np.testing.assert_allclose(gk.reshape(-1, 6)[:, :3], g[i].reshape(-1, 6)[:, :3], rtol=0, atol=1e-14 * b.lref)
        np.testing.assert_allclose(gk.reshape(-1, 6)[:, 3:], g[i].reshape(-1, 6)[:, 3:], rtol=0, atol=1e-14)
        np.testing.assert_allclose(Gk, G[i], rtol=0, atol=1e-12 * np.abs(G[i]).max())
        np.testing.assert_allclose(Hk, Hs[i], rtol=0, atol=1e-12 * np.abs(Hs[i]).max())
        assert np.abs(Hs[i]).max() > 0  # the multipliers are not zero: the Hessian is checked
        dk = K.newton_step(tab, pt, z[i], Wd[i], Pd[i], kappa[i], kd[i], xr[i])
        np.testing.assert_allclose(dk, dz[i], rtol=0, atol=1e-9 * np.abs(dz[i]).max())
        # the step came from the chains' blocks (no chain block needs pivots outside it), and the
        # general elimination of the whole matrix gives it too
        rhs = np.empty(len(dk))
        K._rhs(gk, Gk, z[i], Wd[i], kappa[i], xr[i], rhs)
        assert K.nonlinear_block.factor(tab, b.nx, kd[i], Gk, Hk, K.nonlinear_block.workspace(tab))
        np.testing.assert_allclose(K.nonlinear_block.full_solve(tab, b.nx, kd[i], Gk, Hk, rhs), dk, rtol=0,
                                   atol=1e-9 * np.abs(dk).max())
        assert K.residual_ok(tab, pt, z[i], Wd[i], Pd[i], kappa[i], xr[i], b.lref, eq.RTOL, nl.ROUNDOFF) == ok[i]
    assert not ok.any()  # perturbed states fail the check in both


# agreement of the deflections, of the largest one: the numpy path takes full Newton steps until the
# residual check passes, the compiled one chord steps with an earlier point's factorization until, also,
# a step is below 1e-5 of the deflection.  Measured against the cold reference solver: numpy 3e-7,
# compiled 2.2e-6 on the 3-PUU (from given starts 4e-11 and 3e-7); 6e-11 and 5e-11 on the hexapod
@pytest.mark.parametrize("name, path, segments, tol", [(PUU, _puu_path, 4, 1e-5), (HEXAPOD, _hexapod_path, 2, 1e-5)])
def test_compiled_path_equilibria_agree_with_the_numpy_path(monkeypatch, name, path, segments, tol):
    """Marched along a path, then restarted from the states at nearby poses (the compensation's checks):
    the same cold starts, far fewer factorizations, the same deflections to the steps' tolerance."""
    monkeypatch.setattr(eq, "SEGMENTS", segments)
    m = vjm.load_model(name)
    P, W = path()
    ref, s = _both(monkeypatch, m, P, W)
    scale = np.repeat([np.abs(ref.twist[:, :3]).max(), np.abs(ref.twist[:, 3:]).max()], 3)
    assert scale[0] > 1e-3  # micrometres of deflection: the check is not empty
    assert np.all(np.abs(s.twist - ref.twist) <= tol * scale)
    assert (s.cold, s.warm_failed) == (ref.cold, ref.warm_failed) == (segments, 0)  # the first point of each run
    assert s.newton < ref.newton and s.chord > 0  # the factorizations are kept from point to point
    P2 = P + np.random.default_rng(1).normal(0, 2e-3, P.shape)
    ref2, s2 = _both(monkeypatch, m, P2, W, start=ref.state)
    assert np.all(np.abs(s2.twist - ref2.twist) <= tol * scale)
    assert s2.cold == ref2.cold == 0 and s2.newton < ref2.newton
    # against the reference solver, cold, to its own tolerance
    np.testing.assert_allclose(s2.twist, nl.deflection_map(m, P2, W), rtol=0, atol=tol * scale.max())


def test_compiled_starts_that_fail_go_to_the_reference_solver(monkeypatch):
    """NaN starts fail the check in the kernel too; those points are solved cold and counted."""
    m = vjm.load_model(PUU)
    P, W = _puu_path(20)
    s = eq.equilibria(m, P, W, start=np.full((len(P), 3 * 17 + 6 + 18), np.nan))
    assert s.cold == len(P) and s.warm_failed == len(P)
    np.testing.assert_allclose(s.twist, nl.deflection_map(m, P, W), rtol=0, atol=1e-12)


def test_vjm_path_compiled_gives_the_numpy_commands(tmp_path, monkeypatch):
    """vjm.path end to end (deflection, compensation, the compensated CSV written as it goes) with the
    compiled kernels and with the numpy path: the same commands to the chord steps' tolerance, no cold check."""
    P, W = _puu_path(120)
    P = P + [30.0, 0.0, -20.0]
    f = tmp_path / "p.csv"
    f.write_text("x,y,z,Fx,Fy,Fz,Mx,My,Mz\n" + "\n".join(",".join(repr(float(v)) for v in r)
                                                        for r in np.hstack([P, W])) + "\n")
    m = vjm.load_model(PUU)
    out = {}
    for kernel in (False, True):
        monkeypatch.setattr(eq, "KERNEL", kernel)
        out[kernel] = vjm.path(m, f, tool=(0.0, 0.0, -60.0), uncertainty=False)
    a, b = out[False], out[True]
    scale = np.abs(a.deflection[:, :3]).max()
    assert scale > 1e-3
    assert np.abs(b.deflection - a.deflection).max() <= 1e-5 * scale
    assert np.abs(b.compensation.commanded - a.compensation.commanded).max() <= 1e-5 * scale
    assert b.compensation.cold == 0 and callable(b.compensated)
    from vjm.toolpath.points import read_csv_text

    back = [read_csv_text(r.compensated_text).points for r in (a, b)]  # written to 6 decimals of mm
    np.testing.assert_allclose(back[1], back[0], rtol=0, atol=1.01e-6)
    np.testing.assert_allclose(back[1], b.compensation.commanded, rtol=0, atol=5.1e-7)


def test_one_shared_spring_basis_gives_the_per_point_results(monkeypatch):
    """Constant compliances pack one spring basis for all points; packed per point (as a machine whose
    compliances change with the pose), the kernel gives the same equilibria to the bit, marched and from
    given starts (the compensation's checks, with their corrections from point to point)."""
    m = vjm.load_model(PUU)
    P, W = _puu_path()
    s1 = eq.equilibria(m, P, W)
    P2 = P + np.random.default_rng(1).normal(0, 2e-3, P.shape)
    t1 = eq.equilibria(m, P2, W, start=s1.state)
    b = eq._Block(m, P, W, None)
    assert len(eq._pack(b)[1][2]) == 1
    monkeypatch.setattr(nl._ChainData, "constant", property(lambda self: False))
    assert len(eq._pack(b)[1][2]) == len(P)
    s2 = eq.equilibria(m, P, W)
    t2 = eq.equilibria(m, P2, W, start=s2.state)
    for a, c in ((s1, s2), (t1, t2)):
        np.testing.assert_array_equal(a.twist, c.twist)
        np.testing.assert_array_equal(a.state, c.state)
        assert (a.newton, a.chord, a.cold) == (c.newton, c.chord, c.cold)
    assert t1.chord > 0


@pytest.mark.parametrize("compiled", [False, True])
def test_pose_dependent_compliance_path_agrees_with_the_cold_reference(monkeypatch, compiled):
    """On the 3-PRPaR the parallelogram's spring basis and its rigid directions change from point to point.
    Marched along the path and restarted from nearby states, every equilibrium is the cold reference's
    (nonlinear.deflection_map from the unloaded posture): a rigid coordinate carried over from a
    neighbour at a deformed value once gave a second equilibrium, 0.7 % of the deflection away."""
    monkeypatch.setattr(eq, "SEGMENTS", 4)
    monkeypatch.setattr(eq, "KERNEL", compiled)
    m = vjm.load_model(PRPAR)
    P, W = _puu_path()
    b = eq._Block(m, P, W, None)
    assert not all(cd.constant for cd in b.chains)
    assert len({tuple(f) for f in b.fixed}) > 1  # the rigid directions change along the path
    ref = nl.deflection_map(m, P, W)
    scale = np.abs(ref[:, :3]).max()
    s = eq.equilibria(m, P, W)
    assert np.abs(s.twist - ref)[:, :3].max() <= 1e-5 * scale
    P2 = P + np.random.default_rng(1).normal(0, 2e-3, P.shape)
    s2 = eq.equilibria(m, P2, W, start=s.state)
    assert np.abs(s2.twist - nl.deflection_map(m, P2, W))[:, :3].max() <= 1e-5 * scale
