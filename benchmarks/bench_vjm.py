"""Poses per second of the full 6x6 stiffness of the Orthoglide 3-PUU over a 50^3 grid.

Compares the batched ``Model.stiffness_map`` with a plain per-pose Python loop of
the same math (same chains, Jacobians, bordered solve with numpy.linalg per pose)
in the same run.  Each is timed ``REPEAT`` times and the best time is kept (as
``timeit`` does: the other runs only add the noise of other processes on the
machine).  The batched map runs both paths side by side: the compiled kernels
(``kernel="numba"``, :mod:`vjm.maps.map_kernel`) and the numpy reference (``kernel="numpy"``), timed
in CPU time of this process (what other processes on a shared machine disturb least).
Usage: ``python benchmarks/bench_vjm.py [N]``, ``... machines [N]`` (hexapod and description
files), ``... compile`` (the kernels' one-time compile and their load from the cache), ``... phases``
(where the time of the compiled 3-PUU map goes).
"""
import os
import platform
import subprocess
import sys
import tempfile
import time

import numpy as np

import vjm
from vjm.kinematics.chain import jacobian
from vjm.stiffness.linear import spring_compliance

REPEAT = 3
#: issue 4 target
TARGET_RATE, TARGET_RATIO = 100_000, 50
#: issue 29 targets: poses/s of the compiled map, 3-PUU and hexapod description file
TARGET_KERNEL_PUU, TARGET_KERNEL_HEXAPOD = 500_000, 150_000


def loop_stiffness(m, P):
    """Per-pose reference: eq. 11 solved with numpy.linalg (SVD null space), K summed, C inverted."""
    out = np.empty((len(P), 6, 6))
    for n, p in enumerate(P):
        q, vals = m.arch.inverse_kinematics(m, p[None])
        comps = m.arch.compliances(m, p[None], vals, q)
        K = np.zeros((6, 6))
        for ch, v, c in zip(m.chains, vals, comps):
            _, J = jacobian(ch, v)
            S = spring_compliance(ch, J, c)[0]
            Jq = J[0][:, list(ch.passive)]
            U, s, _ = np.linalg.svd(Jq)
            r = int(np.sum(s > 1e-9 * s[0]))
            N = U[:, r:]
            K += N @ np.linalg.solve(N.T @ S @ N, N.T)
        out[n] = np.linalg.inv(K)
    return out


def best_time(f, repeat=REPEAT):
    best, out = np.inf, None
    for _ in range(repeat):
        t = time.perf_counter()
        out = f()
        best = min(best, time.perf_counter() - t)
    return best, out


def best_times(f, repeat=REPEAT):
    """Best wall-clock and best process CPU time of ``repeat`` runs (CPU time: what other
    processes on a shared machine disturb least), and the last result."""
    wall, cpu, out = np.inf, np.inf, None
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        out = f()
        wall, cpu = min(wall, time.perf_counter() - t), min(cpu, time.process_time() - c)
    return wall, cpu, out


def interleaved_times(fs, repeat=REPEAT):
    """:func:`best_times` of several functions run in turn (a, b, a, b, ...), so that a change of
    the load on a shared machine falls on all of them alike: {key: (wall, cpu, last result)}."""
    best = {k: [np.inf, np.inf, None] for k in fs}
    for _ in range(repeat):
        for k, f in fs.items():
            t, c = time.perf_counter(), time.process_time()
            out = f()
            b = best[k]
            b[0], b[1], b[2] = min(b[0], time.perf_counter() - t), min(b[1], time.process_time() - c), out
    return {k: tuple(v) for k, v in best.items()}


def main(n=50):
    m = vjm.load_model("data/orthoglide/puu.yaml")
    ax = np.linspace(-73.65, 126.35, n)
    P = np.stack(np.meshgrid(ax, ax, ax, indexing="ij"), -1).reshape(-1, 3)
    m.stiffness_map(P[:100])  # warm-up
    m.stiffness_map(P[:3000], kernel="numba")  # compile or load the kernels
    load0 = os.getloadavg()[0]
    side = interleaved_times({k: (lambda k=k: m.stiffness_map(P, kernel=k)) for k in ("numba", "numpy")})
    tb, res = best_time(lambda: m.stiffness_map(P))
    step = max(1, len(P) // 2000)
    sub = P[::step]
    tl, Cl = best_time(lambda: loop_stiffness(m, sub))
    load1 = os.getloadavg()[0]
    C = res.C[::step]
    err = np.max(np.abs(Cl - C) / np.max(np.abs(Cl), axis=(1, 2))[:, None, None])
    rb, rl = len(P) / tb, len(sub) / tl
    met = rb >= TARGET_RATE and rb / rl >= TARGET_RATIO
    print(f"3-PUU, {len(P)} poses ({n}^3 grid), full 6x6 K, C, k_tran, k_rot; best of {REPEAT}")
    print(f"batched stiffness_map: {tb:.2f} s, {rb:,.0f} poses/s")
    print(f"per-pose Python loop : {tl:.2f} s for {len(sub)} poses, {rl:,.0f} poses/s")
    print(f"speed-up {rb / rl:.0f}x; max relative difference of C {err:.1e}")
    print(f"target (>= {TARGET_RATE:,} poses/s and >= {TARGET_RATIO}x): {'met' if met else 'NOT met'}")
    _side_by_side("3-PUU", len(P), side, TARGET_KERNEL_PUU)
    print(f"machine: {os.cpu_count()} cores, load average {load0:.1f} -> {load1:.1f} (other processes), "
          f"Python {platform.python_version()}, numpy {np.__version__}, one thread")


def _side_by_side(name, n, side, target):
    """Print the compiled and the numpy map (best wall and CPU time of REPEAT) and their agreement."""
    (wk, ck, rk), (wn, cn, rn) = side["numba"], side["numpy"]
    err = max(np.max(np.abs(getattr(rk, f) - getattr(rn, f)).reshape(n, -1)
                     / np.max(np.abs(getattr(rn, f)).reshape(n, -1), axis=1)[:, None]) for f in ("K", "C"))
    same = bool((rk.rank == rn.rank).all() and (rk.invertible == rn.invertible).all())
    print(f"{name} map, compiled kernels: CPU {ck:.2f} s, {n / ck:,.0f} poses/s (wall {n / wk:,.0f})")
    print(f"{name} map, numpy path      : CPU {cn:.2f} s, {n / cn:,.0f} poses/s (wall {n / wn:,.0f})")
    print(f"  ratio (CPU) {cn / ck:.2f}x; max relative difference of K, C {err:.1e}; same ranks: {same}; "
          f"target (>= {target:,} poses/s): {'met' if n / ck >= target else 'NOT met'} in CPU time")


#: issue 12 targets: hexapod map poses/s with the general IK; description / built-in time ratio
TARGET_HEXAPOD, TARGET_DESC_RATIO = 20_000, 3.0


def _with_legs(closed, f):
    """f() with the 6-UPS legs in closed form (``closed``) or by Newton (vjm.kinematics.ik.CLOSED_FORM)."""
    from vjm.kinematics import ik

    was, ik.CLOSED_FORM = ik.CLOSED_FORM, closed
    try:
        return f()
    finally:
        ik.CLOSED_FORM = was


def machines(n=30):
    import scipy.spatial  # noqa: F401  (imported by the IK on first use: keep it out of the timing)

    from vjm.kinematics.poses import as_poses

    hexa = vjm.load_model("data/machines/hexapod_6ups.yaml")
    lo, hi = hexa.arch.workspace
    axes = [np.linspace(lo[k], hi[k], n) for k in range(3)]
    G = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    X = np.hstack([G, np.tile([0.02, -0.03, 0.05], (len(G), 1))])
    hexa.stiffness_map(X[:100])  # warm-up
    hexa.stiffness_map(X[:3000], kernel="numba")  # compile or load the kernels
    load0 = os.getloadavg()[0]

    def fresh_map(m, P, kernel=None):
        m._kin_cache.clear()  # time the inverse kinematics too, not the model's cache of small batches
        return m.stiffness_map(P, kernel=kernel)

    side = interleaved_times({k: (lambda k=k: fresh_map(hexa, X, k)) for k in ("numba", "numpy")})
    legs = interleaved_times({cf: (lambda cf=cf: _with_legs(cf, lambda: fresh_map(hexa, X, "numba")))
                              for cf in (True, False)}, repeat=5)

    th, ch, _ = best_times(lambda: fresh_map(hexa, X))
    F = as_poses(X, 6)
    tk, ck, kins = best_times(lambda: [hexa._solve_kinematics(F[a:a + 2048]) for a in range(0, len(F), 2048)])
    ts, cs, _ = best_times(lambda: [hexa.stiffness_map(k) for k in kins])
    # the stiffness alone on either path; a fresh Kinematics each run (no geometry kept from the last)
    stiff = interleaved_times({k: (lambda k=k: [hexa.stiffness_map(kin.take(slice(None)), kernel=k) for kin in kins])
                               for k in ("numba", "numpy")})
    a = vjm.load_model("data/orthoglide/puu.yaml")
    b = vjm.load_model("data/machines/orthoglide_puu.yaml")
    ax = np.linspace(-73.65, 126.35, 50)
    P = np.stack(np.meshgrid(ax, ax, ax, indexing="ij"), -1).reshape(-1, 3)
    b.stiffness_map(P[:100])
    tb, cb, rb = best_times(lambda: fresh_map(b, P))
    ta, ca, ra = best_times(lambda: fresh_map(a, P))
    load1 = os.getloadavg()[0]
    err = np.max(np.abs(rb.K - ra.K) / np.max(np.abs(ra.K), axis=(1, 2))[:, None, None])
    rh, nh = len(X) / th, len(X)
    print(f"6-UPS hexapod, {nh} poses ({n}^3 grid of its workspace box, orientation (0.02, -0.03, 0.05) rad), "
          f"general IK; best of {REPEAT}")
    print(f"stiffness_map: {th:.2f} s, {rh:,.0f} poses/s  (IK alone {nh / tk:,.0f} poses/s, "
          f"stiffness from the kinematics {nh / ts:,.0f} poses/s)")
    print(f"  CPU time: {ch:.2f} s, {nh / ch:,.0f} poses/s  (IK alone {nh / ck:,.0f}, stiffness {nh / cs:,.0f})")
    print(f"target (>= {TARGET_HEXAPOD:,} poses/s): {'met' if rh >= TARGET_HEXAPOD else 'NOT met'}")
    _side_by_side("hexapod", nh, side, TARGET_KERNEL_HEXAPOD)
    (_, cc, rc), (_, cn, rn) = legs[True], legs[False]
    err = max(np.max(np.abs(getattr(rc, f) - getattr(rn, f)).reshape(nh, -1)
                     / np.max(np.abs(getattr(rn, f)).reshape(nh, -1), axis=1)[:, None]) for f in ("K", "C"))
    same = bool((rc.rank == rn.rank).all() and (rc.invertible == rn.invertible).all())
    print(f"  compiled map, legs in closed form: CPU {cc:.3f} s, {nh / cc:,.0f} poses/s; legs by Newton: CPU "
          f"{cn:.3f} s, {nh / cn:,.0f} poses/s; ratio {cn / cc:.2f}x (best of 5, interleaved); max relative "
          f"difference of K, C {err:.1e}; same ranks: {same}")
    print(f"  stiffness from the kinematics alone (CPU): compiled {nh / stiff['numba'][1]:,.0f} poses/s, "
          f"numpy {nh / stiff['numpy'][1]:,.0f} poses/s; inverse kinematics alone {nh / ck:,.0f} poses/s")
    print(f"Orthoglide 3-PUU, {len(P)} poses (50^3 grid): description file {tb:.2f} s ({len(P) / tb:,.0f} poses/s), "
          f"built-in module {ta:.2f} s ({len(P) / ta:,.0f} poses/s); ratio {tb / ta:.2f}x, max relative "
          f"difference of K {err:.1e}")
    print(f"  CPU time: description file {cb:.2f} s, built-in module {ca:.2f} s; ratio {cb / ca:.2f}x")
    print(f"target (within {TARGET_DESC_RATIO:g}x): {'met' if tb / ta <= TARGET_DESC_RATIO else 'NOT met'}")
    print(f"machine: {os.cpu_count()} cores, load average {load0:.1f} -> {load1:.1f} (other processes), "
          f"Python {platform.python_version()}, numpy {np.__version__}, one thread")


def phases(n=50):
    """Where the time of the compiled 3-PUU map goes: each phase of ``stiffness_map`` run alone over
    the n^3 grid (best of REPEAT, CPU us per pose); the rest is the block bookkeeping and the first
    touch of the output arrays."""
    from vjm.kinematics.poses import as_poses
    from vjm.stiffness.linear import machine_block_compiled

    m = vjm.load_model("data/orthoglide/puu.yaml")
    ax = np.linspace(-73.65, 126.35, n)
    P = np.stack(np.meshgrid(ax, ax, ax, indexing="ij"), -1).reshape(-1, 3)
    m.stiffness_map(P[:3000], kernel="numba")
    us = 1e6 / len(P)
    tot = best_times(lambda: m.stiffness_map(P, kernel="numba"))[1]
    _, tf, frames = best_times(lambda: as_poses(P, m.dof))
    blocks = [frames[a:a + 2048] for a in range(0, len(P), 2048)]
    _, tk, kins = best_times(lambda: [m._solve_kinematics(f) for f in blocks])
    _, tc, comps = best_times(lambda: [m.compliances(k) for k in kins])
    outs = [(np.zeros((k.n, 6, 6)), np.zeros((k.n, 6, 6)), np.empty(k.n), np.empty(k.n), np.empty(k.n, dtype=int),
             np.empty(k.n, dtype=bool), np.empty((k.n, 3), dtype=int)) for k in kins]
    ts = best_times(lambda: [machine_block_compiled(k.chains, k.values, c, k.points, o, lambda i, g: None)
                             for k, c, o in zip(kins, comps, outs)])[1]
    print(f"3-PUU map, {len(P)} poses, CPU us per pose: total {tot * us:.2f} ({len(P) / tot:,.0f} poses/s); "
          f"as_poses {tf * us:.2f}, inverse kinematics {tk * us:.2f}, compliances {tc * us:.2f}, stiffness and "
          f"assembly {ts * us:.2f}, rest {(tot - tf - tk - tc - ts) * us:.2f}")


_FIRST_MAP = """
import time, numpy as np, vjm
m = vjm.load_model("data/orthoglide/puu.yaml")
P = np.random.default_rng(0).uniform(-50, 50, (300, 3))
c, w = time.process_time(), time.perf_counter()
m.stiffness_map(P, kernel="{kernel}")
print(time.process_time() - c, time.perf_counter() - w)
"""


def compile_cost():
    """The first 300-pose 3-PUU map of a fresh process: compiling the kernels (empty numba cache),
    loading them from the cache, and the numpy path; CPU and wall seconds of that call."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        rows = [("compiled, empty cache (compiles)", "numba"), ("compiled, cache filled (loads)", "numba"),
                ("numpy path", "numpy")]
        for label, kernel in rows:
            out = subprocess.run([sys.executable, "-c", _FIRST_MAP.format(kernel=kernel)], env=env, check=True,
                                 capture_output=True, text=True).stdout.split()
            print(f"first map of a process, {label}: CPU {float(out[0]):.2f} s, wall {float(out[1]):.2f} s")
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} (other processes)")


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "compile":
        compile_cost()
    elif len(sys.argv) > 1 and sys.argv[1] == "phases":
        phases()
    elif len(sys.argv) > 1 and sys.argv[1] == "machines":
        machines(int(sys.argv[2]) if len(sys.argv) > 2 else 30)
    else:
        main(int(sys.argv[1]) if len(sys.argv) > 1 else 50)
