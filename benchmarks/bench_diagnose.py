"""Benchmark: `diagnose` on 1000 measurements with the full effect library.

Target (issue 5): at most 30 s on 2 cores.  Data: the 3-PUU model with one
hidden effect (clearance), 167 random reachable postures x 6 axis loads of
100 N (1002 measurements, translations only), 1 um noise.  Run:

    .venv/bin/python benchmarks/bench_diagnose.py [MODEL]

and copy the printed line into docs/benchmarks.md (## diagnose).
"""
import os
import sys
import time

import numpy as np

from vjm.discrepancy import modelops as mo
from vjm.discrepancy.diagnose import diagnose
from vjm.discrepancy.simulate import design_loads, design_poses, simulate


def main(model_path="data/orthoglide/puu.yaml"):
    model = mo.load_model(model_path)
    rng = np.random.default_rng(7)
    P0 = design_poses(model, "random:167", rng)
    L = design_loads("axes:100", len(P0), rng)
    P = np.repeat(P0, L.shape[1], axis=0)
    W = L.reshape(-1, 6)
    data = simulate(model, [("clearance", {"backlash": 0.003})], P, W, 1e-3, None, seed=1)
    t0 = time.perf_counter()
    dg = diagnose(model, data)
    dt = time.perf_counter() - t0
    rep = dg.report
    print(f"diagnose: {data.n} measurements ({len(P0)} postures), {len(rep['candidates'])} candidates, "
          f"named {rep['named_effects']}, {dt:.1f} s wall on {os.cpu_count()} cpu(s) "
          f"[{'PASS' if dt <= 30 else 'FAIL'} vs 30 s target]")


if __name__ == "__main__":
    main(*sys.argv[1:])
