"""Benchmark: nonlinear deflection + compensation along a toolpath, warm-started equilibria against
the cold reference solver, side by side in one run (issue 29, item 2).

The path: bench_path.py's zigzag (rows 0.5 mm apart over the 60 x 40 mm pocket at z = -1, the
milling model, a 60 mm tool) on the 3-PUU.  "cold" is the solver before the warm start: every
equilibrium of the deflection and of the compensation's checks by vjm.nonlinear.deflection_map
(from the unloaded posture, to its 1e-11 step tolerance); "warm" is vjm.toolpath.equilibrium.
Links: the beams of puu.yaml, or FEA results (``--foot out/foot/result.json --leg
out/leg/result.json``, as `make demo` computes them).

``--million``: a one-million-point program (the zigzag, 1M samples) through ``vjm.path`` (CSV in,
compensated CSV text out, workers=2), its wall time and the process's peak resident memory.
The machine is shared: wall times carry the load average printed; the ratio of the two solvers,
measured alternately in one run, is the figure to read.

    PYTHONPATH=src nice python benchmarks/bench_path_speed.py [--n 4096] [--foot F --leg L] [--million]
"""
import os
import sys

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import resource
import tempfile
import time

import numpy as np
from bench_path import MILL, PUU, TOOL, zigzag

import vjm
from vjm import nonlinear
from vjm.toolpath import deflect, run
from vjm.toolpath.equilibrium import Solved


def cold_equilibria(model, P, W, offsets=None, start=None):
    """The solver before the warm start: every pair cold by the reference, no state kept."""
    t = nonlinear.deflection_map(model, P, W, strict=False, offsets=offsets)
    return Solved(t, np.zeros((len(t), 1)), len(t), 0, 0)


def timed(model, tp, W, workers, cold):
    saved = deflect.equilibria
    if cold:
        deflect.equilibria = cold_equilibria
    try:
        t0, c0 = time.perf_counter(), time.process_time()
        d, _, comp, n_cold = run._deflect_and_compensate(model, tp, W, TOOL, "nonlinear", workers, True, print)
        return time.perf_counter() - t0, time.process_time() - c0, d, comp, n_cold
    finally:
        deflect.equilibria = saved


def side_by_side(model, n, workers, reps=2):
    tp = zigzag(n)
    W = MILL.wrenches(tp)
    times = {True: [], False: []}
    cpu = {True: [], False: []}
    out = {}
    for _ in range(reps):
        for cold in (True, False):
            dt, dc_, d, comp, n_cold = timed(model, tp, W, workers, cold)
            times[cold].append(dt)
            cpu[cold].append(dc_)
            out[cold] = (d, comp, n_cold)
    (dc, cc, _), (dw, cw, nw) = out[True], out[False]
    tc, tw = min(times[True]), min(times[False])
    uc, uw = min(cpu[True]), min(cpu[False])
    print(f"side by side, {tp.n} points, workers={workers}, best of {reps}: cold {tc:.2f} s wall, {uc:.2f} s CPU "
          f"({tp.n / uc:,.0f} points per CPU second); warm {tw:.2f} s wall, {uw:.2f} s CPU ({tp.n / uw:,.0f} "
          f"points per CPU second): ratio {tc / tw:.2f} wall, {uc / uw:.2f} CPU; warm cold starts {nw} of "
          f"{2 * tp.n} equilibria")
    dd = np.abs(dw - dc).max() / np.abs(dc[:, :3]).max()
    dcmd = np.abs(cw.commanded - cc.commanded).max() / np.abs(dc[:, :3]).max()
    print(f"  agreement: deflection {dd:.1e}, commands {dcmd:.1e} of the largest deflection "
          f"({1e3 * np.abs(dc[:, :3]).max():.1f} um); residual max warm {cw.residual.max():.2g} mm, "
          f"cold {cc.residual.max():.2g} mm")


def _peak():
    """Peak resident memory of this process so far, MB."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def million(model, workers=2, n=1_000_000):
    tp = zigzag(n + 81)
    with tempfile.TemporaryDirectory() as tmp:
        f = os.path.join(tmp, "raster.csv")
        with open(f, "w") as fh:
            fh.write("x,y,z\n")
            np.savetxt(fh, tp.points, fmt="%.4f", delimiter=",")
        del tp
        t0 = time.perf_counter()
        res = vjm.path(model, f, wrench=MILL, tool=TOOL, workers=workers, uncertainty=False,
                       progress=lambda s: print(f"  [{time.perf_counter() - t0:7.1f} s, {_peak():,.0f} MB] {s}",
                                                flush=True))
        dt = time.perf_counter() - t0
    peak = _peak()
    print(f"million: {res.toolpath.n:,} points in {dt:.0f} s wall ({res.toolpath.n / dt:,.0f} points/s, "
          f"workers={workers}); peak resident memory {peak:,.0f} MB; residual max "
          f"{res.compensation.residual.max():.2g} mm; {[x for x in res.notes if 'cold' in x]}")


def main():
    args = sys.argv[1:]

    def opt(name, default=None):
        return args[args.index(name) + 1] if name in args else default

    foot, leg = opt("--foot"), opt("--leg")
    model = vjm.load_model(PUU, foot=foot, leg=leg)
    print(f"links: {'FEA ' + str(foot) + ', ' + str(leg) if foot else 'beams of puu.yaml'}; load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores (shared machine)")
    if "--million" in args:
        million(model)
    else:
        side_by_side(model, int(opt("--n", 4096)), int(opt("--workers", 2)))
    print(f"load average {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    sys.path.insert(0, os.path.dirname(__file__))
    main()
