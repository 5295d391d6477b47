"""Poses per second of the full 6x6 stiffness of the Orthoglide 3-PUU over a 50^3 grid.

Compares the batched ``Model.stiffness_map`` with a plain per-pose Python loop of
the same math (same chains, Jacobians, bordered solve with numpy.linalg per pose)
in the same run.  Each is timed ``REPEAT`` times and the best time is kept (as
``timeit`` does: the other runs only add the noise of other processes on the
machine).  Usage: ``python benchmarks/bench_vjm.py [N]``.
"""
import os
import platform
import sys
import time

import numpy as np

import vjm
from vjm.chain import jacobian
from vjm.stiffness import spring_compliance

REPEAT = 3
#: issue 4 target
TARGET_RATE, TARGET_RATIO = 100_000, 50


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


def main(n=50):
    m = vjm.load_model("data/orthoglide/puu.yaml")
    ax = np.linspace(-73.65, 126.35, n)
    P = np.stack(np.meshgrid(ax, ax, ax, indexing="ij"), -1).reshape(-1, 3)
    m.stiffness_map(P[:100])  # warm-up
    load0 = os.getloadavg()[0]
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
    print(f"machine: {os.cpu_count()} cores, load average {load0:.1f} -> {load1:.1f} (other processes), "
          f"Python {platform.python_version()}, numpy {np.__version__}, one thread")


#: issue 12 targets: hexapod map poses/s with the general IK; description / built-in time ratio
TARGET_HEXAPOD, TARGET_DESC_RATIO = 20_000, 3.0


def machines(n=30):
    import scipy.spatial  # noqa: F401  (imported by the IK on first use: keep it out of the timing)

    from vjm.kinematics import as_poses

    hexa = vjm.load_model("data/machines/hexapod_6ups.yaml")
    lo, hi = hexa.arch.workspace
    axes = [np.linspace(lo[k], hi[k], n) for k in range(3)]
    G = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    X = np.hstack([G, np.tile([0.02, -0.03, 0.05], (len(G), 1))])
    hexa.stiffness_map(X[:100])  # warm-up
    load0 = os.getloadavg()[0]
    def fresh_map(m, P):
        m._kin_cache.clear()  # time the inverse kinematics too, not the model's cache of small batches
        return m.stiffness_map(P)

    th, ch, _ = best_times(lambda: fresh_map(hexa, X))
    F = as_poses(X, 6)
    tk, ck, kins = best_times(lambda: [hexa._solve_kinematics(F[a:a + 2048]) for a in range(0, len(F), 2048)])
    ts, cs, _ = best_times(lambda: [hexa.stiffness_map(k) for k in kins])
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
    print(f"Orthoglide 3-PUU, {len(P)} poses (50^3 grid): description file {tb:.2f} s ({len(P) / tb:,.0f} poses/s), "
          f"built-in module {ta:.2f} s ({len(P) / ta:,.0f} poses/s); ratio {tb / ta:.2f}x, max relative "
          f"difference of K {err:.1e}")
    print(f"  CPU time: description file {cb:.2f} s, built-in module {ca:.2f} s; ratio {cb / ca:.2f}x")
    print(f"target (within {TARGET_DESC_RATIO:g}x): {'met' if tb / ta <= TARGET_DESC_RATIO else 'NOT met'}")
    print(f"machine: {os.cpu_count()} cores, load average {load0:.1f} -> {load1:.1f} (other processes), "
          f"Python {platform.python_version()}, numpy {np.__version__}, one thread")


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "machines":
        machines(int(sys.argv[2]) if len(sys.argv) > 2 else 30)
    else:
        main(int(sys.argv[1]) if len(sys.argv) > 1 else 50)
