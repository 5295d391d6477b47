"""Benchmark: nonlinear deflection + compensation along a toolpath, warm-started equilibria against
the cold reference solver, side by side in one run (issue 29, item 2).

The path: bench_path.py's zigzag (rows 0.5 mm apart over the 60 x 40 mm pocket at z = -1, the
milling model, a 60 mm tool) on the 3-PUU.  "cold" is the solver before the warm start: every
equilibrium of the deflection and of the compensation's checks by vjm.stiffness.nonlinear.deflection_map
(from the unloaded posture, to its 1e-11 step tolerance); "numpy" is vjm.toolpath.equilibrium's
warm-started path in numpy (KERNEL = False), "compiled" the same path by vjm.stiffness.nonlinear_kernel.
Links: the beams of puu.yaml, or FEA results (``--foot out/foot/result.json --leg
out/leg/result.json``, as `make demo` computes them).

``--million``: a one-million-point program (the zigzag, 1M samples) through ``vjm.path`` (CSV in,
compensated CSV written as it goes into a temporary folder, workers=2), its wall time and the
process's peak resident memory.
The machine is shared: wall times carry the load average printed; the ratio of the solvers,
measured alternately in one run, is the figure to read.

    PYTHONPATH=src nice python benchmarks/bench_path_speed.py [--n 4096] [--foot F --leg L] [--million]
        [--modes cold,numpy,compiled]
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
from vjm.stiffness import nonlinear
from vjm.toolpath import deflect, run
from vjm.toolpath import equilibrium as eq
from vjm.toolpath.equilibrium import Solved


def cold_equilibria(model, P, W, offsets=None, start=None):
    """The solver before the warm start: every pair cold by the reference, no state kept."""
    t = nonlinear.deflection_map(model, P, W, strict=False, offsets=offsets)
    return Solved(t, np.zeros((len(t), 1)), len(t), 0, 0)


#: the solvers compared: the reference from the unloaded posture at every equilibrium, the warm-started
#: path in numpy (equilibrium.KERNEL = False) and compiled (vjm.stiffness.nonlinear_kernel)
MODES = ("cold", "numpy", "compiled")


def _cpu():
    """CPU seconds of this process and its finished worker processes (the path's passes, workers > 1)."""
    a, b = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return a.ru_utime + a.ru_stime + b.ru_utime + b.ru_stime


def timed(model, tp, W, workers, mode):
    saved = deflect.equilibria, eq.KERNEL
    if mode == "cold":
        deflect.equilibria = cold_equilibria
    eq.KERNEL = mode == "compiled"
    try:
        t0, c0 = time.perf_counter(), _cpu()
        d, _, comp, n_cold = run._deflect_and_compensate(model, tp, W, TOOL, "nonlinear", workers, True, print)
        return time.perf_counter() - t0, _cpu() - c0, d, comp, n_cold
    finally:
        deflect.equilibria, eq.KERNEL = saved


def side_by_side(model, n, workers, reps=2, modes=MODES):
    tp = zigzag(n)
    W = MILL.wrenches(tp)
    warm = zigzag(eq.KERNEL_MIN + 200)
    timed(model, warm, MILL.wrenches(warm), 1, "compiled")  # the kernel's compile or its load from the cache
    wall = {m: [] for m in modes}
    cpu = {m: [] for m in modes}
    out = {}
    for _ in range(reps):
        for mode in modes:
            dt, dc_, d, comp, n_cold = timed(model, tp, W, workers, mode)
            wall[mode].append(dt)
            cpu[mode].append(dc_)
            out[mode] = (d, comp, n_cold)
    ref = modes[0]
    dr, cr, _ = out[ref]
    for mode in modes:
        tw, uc = min(wall[mode]), min(cpu[mode])
        d, c, nc = out[mode]
        dd = np.abs(d - dr).max() / np.abs(dr[:, :3]).max()
        dcmd = np.abs(c.commanded - cr.commanded).max() / np.abs(dr[:, :3]).max()
        print(f"{mode:>8}: {tp.n} points, workers={workers}, best of {reps}: {tw:.2f} s wall, {uc:.2f} s CPU "
              f"({tp.n / uc:,.0f} points per CPU second); CPU ratio {min(cpu[ref]) / uc:.2f} and wall ratio "
              f"{min(wall[ref]) / tw:.2f} against {ref}; cold starts {nc} of {2 * tp.n} equilibria; "
              f"against {ref}: deflection {dd:.1e}, commands {dcmd:.1e} of the largest deflection "
              f"({1e3 * np.abs(dr[:, :3]).max():.1f} um); residual max {c.residual.max():.2g} mm")


def _peak():
    """Peak resident memory of this process so far, MB (and of its largest finished worker process)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _peak_children():
    return resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024


def million(model, workers=2, n=1_000_000):
    tp = zigzag(n + 81)
    with tempfile.TemporaryDirectory() as tmp:
        f = os.path.join(tmp, "raster.csv")
        with open(f, "w") as fh:
            fh.write("x,y,z\n")
            np.savetxt(fh, tp.points, fmt="%.4f", delimiter=",")
        del tp
        t0, c0 = time.perf_counter(), _cpu()
        res = vjm.path(model, f, wrench=MILL, tool=TOOL, workers=workers, uncertainty=False,
                       progress=lambda s: print(f"  [{time.perf_counter() - t0:7.1f} s, {_peak():,.0f} MB] {s}",
                                                flush=True))
        dt, dc = time.perf_counter() - t0, _cpu() - c0
        t1 = time.perf_counter()
        with open(os.path.join(tmp, "raster_compensated.csv"), "w") as fh:  # as the output set writes it
            res.write_compensated(fh)
        with open(os.path.join(tmp, "path.csv"), "w") as fh:
            res.write_table(fh)
        dw = time.perf_counter() - t1
    peak = _peak()
    print(f"million: {res.toolpath.n:,} points in {dt:.0f} s wall ({res.toolpath.n / dt:,.0f} points/s, "
          f"workers={workers}; {dc:.0f} s CPU with the worker processes'), then {dw:.0f} s writing the "
          f"compensated CSV and path.csv; {_cpu():.0f} s CPU in all; peak resident memory {peak:,.0f} MB "
          f"(the largest worker process {_peak_children():,.0f} MB); residual max "
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
        modes = tuple(opt("--modes", ",".join(MODES)).split(","))
        side_by_side(model, int(opt("--n", 4096)), int(opt("--workers", 2)), modes=modes)
    print(f"load average {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    sys.path.insert(0, os.path.dirname(__file__))
    main()
