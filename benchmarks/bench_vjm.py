"""Poses per second of the full 6x6 stiffness of the Orthoglide 3-PUU over a 50^3 grid.

Compares the batched ``Model.stiffness_map`` with a plain per-pose Python loop of
the same math (same chains, Jacobians, bordered solve with numpy.linalg per pose)
in the same run.  Usage: ``python benchmarks/bench_vjm.py [N]``.
"""
import sys
import time

import numpy as np

import vjm
from vjm.chain import jacobian
from vjm.stiffness import spring_compliance


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


def main(n=50):
    m = vjm.load_model("data/orthoglide/puu.yaml")
    ax = np.linspace(-73.65, 126.35, n)
    P = np.stack(np.meshgrid(ax, ax, ax, indexing="ij"), -1).reshape(-1, 3)
    m.stiffness_map(P[:100])  # warm-up
    t = time.perf_counter()
    res = m.stiffness_map(P)
    tb = time.perf_counter() - t
    sub = P[:: max(1, len(P) // 2000)]
    t = time.perf_counter()
    Cl = loop_stiffness(m, sub)
    tl = time.perf_counter() - t
    idx = np.arange(0, len(P), max(1, len(P) // 2000))[: len(sub)]
    err = np.max(np.abs(Cl - res.C[idx]) / np.max(np.abs(Cl), axis=(1, 2))[:, None, None])
    rb, rl = len(P) / tb, len(sub) / tl
    print(f"3-PUU, {len(P)} poses ({n}^3 grid), full 6x6 K, C, k_tran, k_rot")
    print(f"batched stiffness_map: {tb:.2f} s, {rb:,.0f} poses/s")
    print(f"per-pose Python loop : {tl:.2f} s for {len(sub)} poses, {rl:,.0f} poses/s")
    print(f"speed-up {rb / rl:.0f}x; max relative difference of C {err:.1e}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 50)
