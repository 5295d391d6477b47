"""Warm-started equilibria along a path (vjm.toolpath.equilibrium) against the reference solver
(vjm.stiffness.nonlinear.deflection_map, cold, to its own 1e-11 step tolerance), and the compensation of a
continuous path checked by a separate equilibrium solve at the written points."""
import numpy as np

import vjm
from vjm.kinematics.poses import rotation_matrix
from vjm.stiffness import nonlinear
from vjm.toolpath import Milling
from vjm.toolpath import equilibrium as eq
from vjm.toolpath.points import read_csv_text

PUU = "data/orthoglide/puu.yaml"
HEXAPOD = "data/machines/hexapod_6ups.yaml"


def _line_with_corner(n=240):
    """n points 0.5 mm apart: along +x, then along +y (the milling force turns with the feed)."""
    k = n // 2
    a = np.column_stack([np.linspace(-40, -40 + 0.5 * (k - 1), k), np.full(k, -10.0), np.full(k, 5.0)])
    b = np.column_stack([np.full(n - k, a[-1, 0]), a[-1, 1] + 0.5 * np.arange(1, n - k + 1), np.full(n - k, 5.0)])
    return np.vstack([a, b])


def _wrenches(P, force=60.0):
    feed = np.gradient(P, axis=0)
    feed /= np.linalg.norm(feed, axis=1, keepdims=True)
    W = np.zeros((len(P), 6))
    W[:, :3] = -force * feed + [0.0, 0.0, 20.0]
    W[:, 3:] = np.cross(np.broadcast_to([0.0, 0.0, -60.0], P.shape), W[:, :3])  # a 60 mm tool's lever
    return W


def test_marched_equilibria_agree_with_the_cold_reference_and_count_the_run_heads(monkeypatch):
    monkeypatch.setattr(eq, "SEGMENTS", 8)  # runs of 30 points
    m = vjm.load_model(PUU)
    P = _line_with_corner()
    W = _wrenches(P)
    ref = nonlinear.deflection_map(m, P, W)
    s = eq.equilibria(m, P, W)
    scale = np.abs(ref).max(axis=0)
    assert np.all(np.abs(s.twist - ref) <= 1e-6 * scale)
    assert scale[:3].max() > 1e-3  # micrometres of deflection: the check is not empty
    # a smooth path needs no cold start beyond the first point of each run
    L = -(-len(P) // eq.SEGMENTS)
    assert s.cold == len(range(0, len(P), L)) and s.warm_failed == 0
    # warm points settle in about one Newton step (cold ones take up to WARM_STEPS)
    assert s.newton - eq.WARM_STEPS * s.cold < 1.5 * (len(P) - s.cold)


def test_every_returned_state_passes_the_residual_check_and_bad_starts_fall_back():
    """States from nearby poses (the compensated commands' situation) start the solve; starts that
    cannot converge (NaN) are solved by the reference and counted, never returned wrong."""
    m = vjm.load_model(PUU)
    P = _line_with_corner(80)
    W = _wrenches(P)
    s = eq.equilibria(m, P, W)
    P2 = P + np.random.default_rng(1).normal(0, 2e-3, P.shape)
    ref2 = nonlinear.deflection_map(m, P2, W)
    s2 = eq.equilibria(m, P2, W, start=s.state)
    assert s2.cold == 0 and s2.newton <= 2 * len(P)
    np.testing.assert_allclose(s2.twist, ref2, rtol=0, atol=1e-6 * np.abs(ref2).max())
    b = eq._Block(m, P2, W, None)
    ch = b.chains
    z = np.concatenate([eq._to_x(ch, s2.state[:, :s2.state.shape[1] - 6 - b.nc]),
                        s2.state[:, -6 - b.nc:]], axis=1)
    assert eq.residual_ok(ch, z, b.W, b.P, b.kappa, b.x_rest, b.nx, b.lref).all()
    # a perturbed state fails the same check: it can fail
    z_bad = z.copy()
    z_bad[:, b.nx:b.nx + 3] *= 1.01
    assert not eq.residual_ok(ch, z_bad, b.W, b.P, b.kappa, b.x_rest, b.nx, b.lref).any()
    s3 = eq.equilibria(m, P2, W, start=np.full_like(s.state, np.nan))
    assert s3.cold == len(P) and s3.warm_failed == len(P)
    np.testing.assert_allclose(s3.twist, ref2, rtol=0, atol=1e-9 * np.abs(ref2).max())


def test_hexapod_marched_equilibria_agree_with_the_reference():
    m = vjm.load_model(HEXAPOD)
    n = 60
    P = np.column_stack([np.linspace(-20, 20, n), np.linspace(5, -5, n), np.full(n, 550.0),
                         np.zeros(n), np.zeros(n), np.linspace(0, 0.1, n)])
    W = np.tile([200.0, -100.0, 300.0, 2000.0, 0.0, -1000.0], (n, 1))
    ref = nonlinear.deflection_map(m, P, W)
    s = eq.equilibria(m, P, W)
    assert np.all(np.abs(s.twist - ref) <= 1e-6 * np.abs(ref).max(axis=0))


def _loaded_tcp(m, c, W, tool):
    """Loaded TCP points of commands c (n, 3) under TCP wrenches W, by vjm.stiffness.nonlinear from the
    unloaded posture, with the tool lever written out here."""
    Wp = np.array(W, dtype=float)
    Wp[:, 3:] += np.cross(np.broadcast_to(tool, c.shape), W[:, :3])
    t = nonlinear.deflection_map(m, c - tool, Wp)
    return c - tool + t[:, :3] + np.einsum("nij,j->ni", rotation_matrix(t[:, 3:]), tool)


def test_compensated_continuous_path_checked_by_a_separate_equilibrium(tmp_path):
    """The written commands of a 300-point path, solved again by vjm.stiffness.nonlinear with the tool lever written
    out here, put the loaded TCP on the programmed points within 1e-3 of the deflection; the cold starts
    are reported."""
    m = vjm.load_model(PUU)
    tool = np.array([0.0, 0.0, -60.0])
    P = _line_with_corner(300) + [30.0, 0.0, -20.0]
    f = tmp_path / "p.csv"
    f.write_text("x,y,z\n" + "\n".join(",".join(repr(float(v)) for v in r) for r in P) + "\n")
    mill = Milling(kc=700.0, feed_per_tooth=0.05, depth=1.0, width=8.0)
    res = vjm.path(m, f, wrench=mill, tool=tool)
    W = res.wrench
    cmd = read_csv_text(res.compensated_text).points

    d0 = np.linalg.norm(_loaded_tcp(m, P, W, tool) - P, axis=1)
    err = np.linalg.norm(_loaded_tcp(m, cmd, W, tool) - P, axis=1)
    assert d0.min() > 1e-4
    assert np.all(err <= 1e-3 * d0)
    assert any("cold starts" in n for n in res.notes)
    assert res.compensation.cold == 0  # the check equilibria all started from the deflection's


def test_compensated_path_on_a_pose_dependent_compliance_checked_by_a_separate_equilibrium(tmp_path):
    """The 3-PRPaR (its parallelogram's rigid directions change along the path), 1,200 points through the
    compiled equilibria: the written commands, solved again from the unloaded posture, put the loaded TCP
    on the programmed points within 2e-4 of the deflection (the compensation stops at 1e-4 by its own
    check equilibria).  A rigid coordinate carried over at its neighbour's deformation once left 9e-4."""
    m = vjm.load_model("data/orthoglide/prpar.yaml")
    tool = np.array([0.0, 0.0, -60.0])
    P = (_line_with_corner(1200) - [-40.0, -10.0, 5.0]) * 0.2 + [-10.0, -10.0, -15.0]
    f = tmp_path / "p.csv"
    f.write_text("x,y,z\n" + "\n".join(",".join(repr(float(v)) for v in r) for r in P) + "\n")
    res = vjm.path(m, f, wrench=Milling(kc=700.0, feed_per_tooth=0.05, depth=1.0, width=8.0), tool=tool)
    W = res.wrench
    cmd = read_csv_text(res.compensated_text).points

    d0 = np.linalg.norm(_loaded_tcp(m, P, W, tool) - P, axis=1)
    assert len(P) >= eq.KERNEL_MIN and d0.min() > 1e-2
    assert np.all(np.linalg.norm(_loaded_tcp(m, cmd, W, tool) - P, axis=1) <= 2e-4 * d0)


def test_passes_report_the_time_left_and_give_the_one_pass_result(tmp_path, monkeypatch):
    """A program longer than one pass (CHUNK made small here) reports progress with the rate and the
    time left, and its deflection and commands agree with a single pass (to the solvers' tolerance)."""
    from vjm.toolpath import passes

    m = vjm.load_model(PUU)
    P = _line_with_corner(120)
    f = tmp_path / "p.csv"
    W = _wrenches(P)
    f.write_text("x,y,z,Fx,Fy,Fz,Mx,My,Mz\n" + "\n".join(",".join(repr(float(v)) for v in r)
                                                        for r in np.hstack([P, W])) + "\n")
    one = vjm.path(m, f)
    monkeypatch.setattr(passes, "CHUNK", 50)
    lines = []
    three = vjm.path(m, f, progress=lines.append)
    left = [s for s in lines if "points/s" in s and "s left" in s]
    assert [s.split(" of ")[0].strip() for s in left] == ["50", "100"]
    scale = np.abs(one.deflection[:, :3]).max()
    np.testing.assert_allclose(three.deflection, one.deflection, rtol=0, atol=1e-6 * scale)
    np.testing.assert_allclose(three.compensation.commanded, one.compensation.commanded, rtol=0, atol=1e-6 * scale)
    # the same passes over two worker processes (the first pass here, the others forked): the same numbers
    lines = []
    procs = vjm.path(m, f, workers=2, progress=lines.append)
    assert [s.split(" of ")[0].strip() for s in lines if "s left" in s] == ["50", "100"]
    np.testing.assert_allclose(procs.deflection, three.deflection, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(procs.compensation.commanded, three.compensation.commanded, rtol=0,
                               atol=1e-12 * scale)
    assert procs.compensation.residual.max() == three.compensation.residual.max()
    assert [n for n in procs.notes if "cold" in n] == [n for n in three.notes if "cold" in n]
