"""Benchmark: ``vjm path`` on the 3-PUU (data/orthoglide/puu.yaml).

Targets (issue 22):

* linear deflection ``C(p) w`` of >= 100k path points in <= 2 s on one core;
* nonlinear compensation of 10k points in <= 30 s on 2 cores (``workers=2``);
* the calibration band covers the true deflection of simulated truth machines in the stated
  fraction of cases (95 %) over >= 100 draws.

The path: a zigzag pocket of 0.5 mm stepover at z = -1 mm over the 60 x 40 mm pocket of
data/toolpaths/pocket.nc, sampled as needed, with the milling model (kc 700 N/mm^2, f_z 0.05 mm,
a_p 1 mm, full 8 mm slot: 35 N against the feed) and a 60 mm tool.

Coverage: the model is the output of a real ``vjm diagnose`` run (calibration + a weight, its
covariance written to model_updated.yaml); a truth machine draws its parameters from that
covariance (``N(theta_hat, Sigma)``) and is built by the model operations of the calibration
(actuator stiffness and link compliances scaled, a weight on the platform); its deflection along
the path is solved by the nonlinear equilibrium; the band of the calibrated model must contain it.
Run with ``nice``; the machine is shared, so wall times carry the load average printed.

    .venv/bin/python benchmarks/bench_path.py [--quick]
"""
import os
import sys

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import tempfile
import time

import numpy as np

import vjm
from vjm.toolpath import Milling
from vjm.toolpath.compensate import compensate
from vjm.toolpath.deflect import tcp_deflection
from vjm.toolpath.points import Toolpath

PUU = "data/orthoglide/puu.yaml"
TOOL = np.array([0.0, 0.0, -60.0])
MILL = Milling(kc=700.0, feed_per_tooth=0.05, depth=1.0, width=8.0)


def zigzag(n: int) -> Toolpath:
    """n points of a zigzag over x 0..60, y 0..40 at z = -1 (rows 0.5 mm apart)."""
    rows = 81
    per = max(2, n // rows)
    pts = []
    for k in range(rows):
        x = np.linspace(0.0, 60.0, per)
        pts.append(np.column_stack([x if k % 2 == 0 else x[::-1], np.full(per, 0.5 * k), np.full(per, -1.0)]))
    P = np.vstack(pts)[:n]
    m = len(P)
    return Toolpath(P, np.arange(2, m + 2), np.ones(m, bool), np.ones(m, bool), None, "zigzag", "csv",
                    None, np.arange(m), ("x", "y", "z"))


def bench_linear(model, n=100_000):
    tp = zigzag(n)
    W = MILL.wrenches(tp)
    tcp_deflection(model, tp.poses[:2000], W[:2000], TOOL, "linear")  # warm-up (imports, caches)
    t0, c0 = time.perf_counter(), time.process_time()
    d = tcp_deflection(model, tp.poses, W, TOOL, "linear")
    dt, dc = time.perf_counter() - t0, time.process_time() - c0
    print(f"linear: {tp.n} points in {dt:.2f} s wall, {dc:.2f} s CPU ({1e6 * dc / tp.n:.1f} us/point), one thread; "
          f"max error {1e3 * np.linalg.norm(d[:, :3], axis=1).max():.2f} um")
    return dt


def bench_compensation(model, n=10_000, workers=2):
    tp = zigzag(n)
    W = MILL.wrenches(tp)
    t0, c0 = time.perf_counter(), time.process_time()
    d0 = tcp_deflection(model, tp.poses, W, TOOL, "nonlinear", workers)
    t1 = time.perf_counter()
    comp = compensate(model, tp.poses, W, TOOL, d0, workers)
    t2, c2 = time.perf_counter(), time.process_time()
    print(f"nonlinear: {tp.n} points, workers={workers}: deflection {t1 - t0:.1f} s + compensation "
          f"{t2 - t1:.1f} s = {t2 - t0:.1f} s wall, {c2 - c0:.1f} s CPU (both threads); "
          f"{comp.iterations} check equilibria; residual max "
          f"{comp.residual.max():.2g} mm (uncompensated max {np.linalg.norm(d0[:, :3], axis=1).max():.3g} mm)")
    return t2 - t0


def calibrated_model(folder):
    """A model_updated.yaml from vjm diagnose on simulated data (a 250 N weight hidden, 1 um noise)."""
    from vjm.discrepancy.diagnosis import write_diagnosis
    from vjm.discrepancy.simulate import design_loads, design_poses, simulate
    from vjm.discrepancy.workflow import diagnose

    m = vjm.load_model(PUU)
    rng = np.random.default_rng(3)
    P0 = design_poses(m, "random:12", rng)
    L = design_loads("axes:100", len(P0), rng)
    P = np.repeat(P0, L.shape[1], axis=0)
    W = L.reshape(-1, 6)
    data = simulate(m, [("gravity", {"weight": 250.0})], P, W, 1e-3, None, seed=5)
    dg = diagnose(m, data, effects=["gravity", "clearance"], folds=2)
    write_diagnosis(dg, folder)
    return os.path.join(folder, "model_updated.yaml"), dg


def truth_model(model, cal, theta):
    """The calibrated model with its parameters moved from the estimate to ``theta``."""
    from vjm.toolpath.uncertainty import perturbed

    out = model
    for i in range(len(cal.names)):
        out = perturbed(out, cal, i, float(theta[i] - cal.values[i]))
    return out


def bench_coverage(draws=200, n_points=40):
    from vjm.toolpath.uncertainty import read

    with tempfile.TemporaryDirectory() as tmp:
        path, dg = calibrated_model(os.path.join(tmp, "rep"))
        model = vjm.load_model(path)
    cal = read(vjm.load_model(path)) if os.path.exists(path) else None
    if cal is None:  # the folder is gone: rebuild from the diagnosis in memory
        from vjm.toolpath.uncertainty import from_mapping

        cal = from_mapping(dg.covariance)
    tp = zigzag(n_points)
    W = MILL.wrenches(tp)
    res = vjm.path(model, tp, wrench=MILL, tool=TOOL, compensate=False, uncertainty=False)
    from vjm.toolpath.uncertainty import band, sensitivities

    G = sensitivities(model, cal, lambda mm: tcp_deflection(mm, tp.poses, W, TOOL, "nonlinear"))
    b = band(res.deflection, G, cal.cov)
    rng = np.random.default_rng(11)
    inside_n, inside_c = [], []
    for _ in range(draws):
        theta = rng.multivariate_normal(cal.values, cal.cov)
        dt = tcp_deflection(truth_model(model, cal, theta), tp.poses, W, TOOL, "nonlinear")
        inside_n.append(np.abs(np.linalg.norm(dt[:, :3], axis=1) - res.error) <= b.norm)
        inside_c.append(np.abs(dt[:, :3] - res.deflection[:, :3]) <= b.components)
    cn, cc = np.mean(inside_n), np.mean(inside_c)
    per_draw = np.mean(inside_n, axis=1)
    se = np.sqrt(0.95 * 0.05 / draws)
    print(f"coverage: {draws} truth machines drawn from the covariance of "
          f"{', '.join(f'{n} = {v:.4g} +- {s:.2g}' for n, v, s in zip(cal.names, cal.values, cal.se))}; "
          f"{n_points} points each; band (1.96 sigma) up to {1e3 * b.norm.max():.3g} um on a deflection of "
          f"{1e3 * res.error.max():.3g} um")
    print(f"coverage: norm {100 * cn:.1f} %, components {100 * cc:.1f} % (target 95 %, +-{100 * 2 * se:.1f} % "
          f"for {draws} independent draws); per draw, norm: min {100 * per_draw.min():.0f} %, "
          f"median {100 * np.median(per_draw):.0f} %")
    return cn, cc


def main():
    quick = "--quick" in sys.argv
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores (shared machine)")
    model = vjm.load_model(PUU)
    bench_linear(model, 20_000 if quick else 100_000)
    bench_compensation(model, 1000 if quick else 10_000)
    bench_coverage(20 if quick else 200)
    print(f"load average {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
