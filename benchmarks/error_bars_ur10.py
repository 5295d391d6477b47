"""Do the four IPA UR10 series, each diagnosed alone, agree within their standard deviations?

Each series (data/realdata/ur10_ipa, A-D: its own tracker set-up) is calibrated alone as ``vjm diagnose`` does
(the default effects, 5-fold cross-validation, outlying rows set aside), and for the shoulder-lift and
elbow compliances every pair's ``|v_i - v_j| / sqrt(s_i^2 + s_j^2)`` is printed: with the formal standard
deviations (``s^2 (J^T J)^-1``, before) and with those the calibration reports (:mod:`vjm.stats.uncertainty`).
The compliances are the totals (the model file's plus the fitted correction), fitted with the final model
whether the selection named them or not.

Usage: ``python benchmarks/error_bars_ur10.py``.
"""
import itertools
import os
import sys
import time

import numpy as np

from vjm.calibration import engine
from vjm.calibration.nominal import nominal_values
from vjm.calibration.robust import calibrate_robust
from vjm.stats.uncertainty import parameter_std

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_ur10 import load_ur10
from error_bars import final_fit

JOINTS = ("shoulder_lift_joint", "elbow_joint")


def main() -> None:
    model, sets = load_ur10(("A", "B", "C", "D"))
    res = {}
    t0 = time.perf_counter()
    for s, d in sets.items():
        t = time.perf_counter()
        cal = calibrate_robust(model, d, "tool0", effects=("geometry", "compliance", "payload"), folds=5)
        rows = d.subset(np.setdiff1d(np.arange(d.n), np.asarray(cal.set_aside, dtype=int)))
        prob, lay, x, meas = final_fit(model, rows, cal)
        # the compliances compared whether named or not (a correction to the model's too small to name is
        # still a value with its interval): added to the final fit where the selection left them out
        extra = [f"{j}.compliance" for j in JOINTS if f"{j}.compliance" not in lay.names]
        if extra:
            lay = engine.Layout(lay.names + tuple(extra), lay.kinds + ("",) * len(extra),
                                lay.units + ("",) * len(extra))
            x = engine.fit(prob, lay, meas, np.concatenate([x, np.zeros(len(extra))]))[0]
        formal = parameter_std(engine._jacobian(prob, lay, x), (engine._predict(prob, lay, x) - meas).ravel(),
                               []).formal
        reported = engine.final_uncertainty(prob, lay, x, meas, rows, ("tool0",)).std
        nom = nominal_values(model, lay.names)
        res[s] = {j: (nom[k] + x[i], formal[i], reported[i])
                  for j in JOINTS for k in [f"{j}.compliance"] for i in [lay.names.index(k)]}
        named = [st.name for st in cal.stages[1:] if st.kept]
        print(f"{s}: {d.n} rows, {time.perf_counter() - t:.0f} s; named {', '.join(named)}; {cal.std_method}",
              flush=True)
    for j in JOINTS:
        print(f"\n{j} compliance, rad/(N mm)\n\n| series | value | formal std | reported std |\n|---|---|---|---|")
        for s, r in res.items():
            v, f, n = r[j]
            print(f"| {s} | {v:.3g} | {f:.2g} ({100 * f / abs(v):.0f} %) | {n:.2g} ({100 * n / abs(v):.0f} %) |")
        print("\n| pair | formal | reported |\n|---|---|---|")
        for a, b in itertools.combinations(res, 2):
            (va, fa, na), (vb, fb, nb) = res[a][j], res[b][j]
            print(f"| {a}-{b} | {abs(va - vb) / np.hypot(fa, fb):.2f} | {abs(va - vb) / np.hypot(na, nb):.2f} |")
    print(f"\n{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
