"""Cost of the links' FEA error bars carried to the machine maps (vjm.sweep.spread), side by side.

For the bundled Orthoglide 3-PUU and 3-PRPaR with both links given an error bar (the foot's
estimate at the default mesh, and 3% on the leg/bar), times ``Model.map`` on a 41 x 41 slice
(z = 0) and on the 41^3 grid without the spread, with the linear spread (the default of
``vjm map``) and with the bar's ends, best of ``REPEAT`` each, all in one run.  With result JSONs
of ``make demo`` (``--foot``, ``--leg``, ``--bar``) it also prints Table 1 with their real bars.

Usage: ``python benchmarks/bench_spread.py [--foot out/foot/result.json --leg ... --bar ...]``.
"""
import argparse
import time

import numpy as np

import vjm
from vjm import LinkSpring
from vjm.studies.table1 import report_lines, table1_rows

REPEAT = 3
FOOT_BAR = np.array([0.018, 0.040, 0.017, 0.058, 0.020, 0.016])
LEG_BAR = np.full(6, 0.03)


def best(f, *args, **kw):
    t_best = np.inf
    for _ in range(REPEAT):
        t = time.perf_counter()
        f(*args, **kw)
        t_best = min(t_best, time.perf_counter() - t)
    return t_best


def main():
    ap = argparse.ArgumentParser()
    for k in ("foot", "leg", "bar"):
        ap.add_argument(f"--{k}")
    a = ap.parse_args()
    print("model   grid        | Model.map: no spread, spread (ratio) | stiffness_map at the reachable points: "
          "no spread, linear (ratio), ends (ratio)")
    for name in ("puu", "prpar"):
        b = vjm.load_model(name)
        m = b.replace(foot=LinkSpring(b.foot.value, None, FOOT_BAR), leg=LinkSpring(b.leg.value, None, LEG_BAR))
        for grid, sl in ((41, "z=0"), (41, None)):
            g = m.grid(grid, sl).points
            P = g[m.reachable(g)]
            m.map(grid, sl)  # warm caches and imports
            tm0 = best(m.map, grid, sl)
            tm1 = best(m.map, grid, sl, spread=True)
            t0 = best(m.stiffness_map, P)
            t1 = best(m.stiffness_map, P, spread=True)
            t2 = best(m.stiffness_map, P, spread=True, spread_method="ends")
            r = m.stiffness_map(P, spread=True)
            print(f"{name:<7} {'41x41 z=0' if sl else '41^3':<11} | {tm0:7.3f} s {tm1:7.3f} s ({tm1 / tm0:.2f}x) | "
                  f"{t0:7.3f} s {t1:7.3f} s ({t1 / t0:.2f}x) {t2:7.3f} s ({t2 / t0:.2f}x) | {len(P)} points, "
                  f"largest k_tran spread {100 * np.nanmax(r.k_tran_spread / r.k_tran):.2g}%, "
                  f"k_rot {100 * np.nanmax(r.k_rot_spread / r.k_rot):.2g}%")
    if a.foot:
        models = [vjm.load_model("puu", foot=a.foot, leg=a.leg), vjm.load_model("prpar", foot=a.foot, leg=a.bar)]
        for line in report_lines(table1_rows(models), models):
            print(line)


if __name__ == "__main__":
    main()
