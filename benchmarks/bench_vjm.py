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


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 50)
