"""Series B of the IPA UR10 set: the same goals reached in two joint configurations (elbow up and elbow
down, consecutive rows with the same goal and shoulder-pan angle), which land about 2 mm apart.

How much of that gap do the named effects explain?  The robot is fitted on series A (as in
``bench_ur10.py``: ``--train`` random rows), B's tracker frame is registered on ``--register`` of its poses
with the robot frozen, and for every pair the measured difference ``m2 - m1`` (tracker frame) is compared
with the model's ``p2 - p1``.  The nominal model puts both configurations on the same goal, so its
predicted difference is about 0: what a model explains is ``1 - mean |d_meas - d_model| / mean |d_meas|``.

Usage: ``python benchmarks/bench_ur10_seriesb.py [--train 3000] [--register 30]``.
"""
import argparse
import os
import sys

import numpy as np

from vjm.calibration.engine import calibrate, predict_points, register

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_ur10 import FLEX_LIBRARY, load_ur10, split, training_rows

MODELS = (("registration only", (), 0), ("geometry", ("geometry",), 0),
          ("geometry + joint compliance", ("geometry", "compliance", "payload"), 0),
          ("what the calibration names from the whole library", FLEX_LIBRARY, 5))


def pairs(data) -> np.ndarray:
    """(k, 2) row indices: consecutive rows with the same goal, shoulder-pan and wrist-2 angles (to 1 mrad), the elbow flipped."""
    g = np.column_stack([data.meta[f"meta_goal_{c}"] for c in "xyz"])
    q = data.q
    i = np.arange(data.n - 1)
    same = np.all(np.abs(q[i][:, [0, 4]] - q[i + 1][:, [0, 4]]) < 1e-3, axis=1)
    ok = (np.all(np.abs(g[i] - g[i + 1]) < 1e-6, axis=1) & same
          & (q[i, 2] * q[i + 1, 2] < 0))
    out, k = [], 0
    while k < len(i):   # disjoint pairs, in file order
        if ok[k]:
            out.append((k, k + 1))
            k += 2
        else:
            k += 1
    return np.array(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--train", type=int, default=3000)
    ap.add_argument("--register", type=int, default=30)
    args = ap.parse_args(argv)
    model, sets = load_ur10(("A", "B"))
    A, B = sets["A"], sets["B"]
    pick = training_rows(A, args.train)
    P = pairs(B)
    d = B.points["tool0"][P[:, 1]] - B.points["tool0"][P[:, 0]]
    gap = np.linalg.norm(d, axis=1)
    print(f"{len(P)} pairs; measured gap mean {gap.mean():.3f} / std {gap.std():.3f} / max {gap.max():.3f} mm")
    for name, effects, folds in MODELS:
        cal = register(calibrate(model, A.subset(pick), "tool0", effects=effects, folds=folds),
                       split(B, args.register)[0])
        p = predict_points(cal, B)
        r = np.linalg.norm(d - (p[P[:, 1]] - p[P[:, 0]]), axis=1)
        print(f"{name}: predicted gap mean {np.linalg.norm(p[P[:, 1]] - p[P[:, 0]], axis=1).mean():.3f} mm; "
              f"unexplained mean {r.mean():.3f} / std {r.std():.3f} / max {r.max():.3f} mm; explained "
              f"{100 * (1 - r.mean() / gap.mean()):.0f} %")


if __name__ == "__main__":
    main()
