"""Held-out position errors of the IPA UR10 accuracy set (data/realdata/ur10_ipa/), read as it is.

The robot's parameters are fitted on a random part of series A (``--train`` rows); every other row of A,
and all of series C and D, are held out.  C and D are separate tracker set-ups: each is first
registered on ``--register`` of its own poses (evenly spaced in the file), the robot's parameters
frozen, and the errors are those of its other poses.  Four models, each held out:

1. nominal: the URDF, the T-Mac offset of ``Trafo_TM_F_init.txt``, only the instrument frame fitted;
2. registration only: the URDF, the instrument frame and the T-Mac offset fitted on A;
3. geometry: + the identifiable joint offsets and URDF-origin errors (vjm.calibration.engine);
4. geometry + joint compliance under self-weight (and the T-Mac's weight, a payload at the marker, if the
   F test keeps it);
5. what the calibration names from the whole library (+ lateral joint compliance, link bending, compliance
   varying with the joint's value, a thermal length scale: vjm.calibration.flex), each effect kept only if its F
   test passes and A's 5-fold cross-validated error drops -- chosen on A alone, never on C or D.

Usage: ``python benchmarks/bench_ur10.py [--train 3000] [--register 30] [--out table.md]``.
"""
import argparse
import os
import sys
import time
import warnings

import numpy as np

import vjm
from vjm.calibration.engine import Calibration, calibrate, error_stats, position_errors, register
from vjm.calibration.poses import read_column_map, read_poses

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
IPA = os.path.join(ROOT, "data", "realdata", "ur10_ipa")
FILES = {"A": "Series_A/measurements_grid.csv", "B": "Series_B/measurements_joint_configurations.csv",
         "C": "Series_C/measurements_random_poses.csv", "D": "Series_D/measurements_iso_cubes.csv"}
#: the effect library beyond geometry and joint compliance (vjm.calibration.flex), tried in this order
FLEX_LIBRARY = ("geometry", "compliance", "lateral", "bending", "varying", "thermal", "payload")
#: (row, effects, folds): folds > 0 keeps an effect only if A's k-fold cross-validated error drops too
MODELS = (("nominal", None, 0), ("registration only", (), 0), ("geometry", ("geometry",), 0),
          ("geometry + joint compliance", ("geometry", "compliance", "payload"), 0),
          ("what the calibration names from the whole library (F test and 5-fold CV on A)", FLEX_LIBRARY, 5))


def load_ur10(series=("A", "C", "D")):
    """(the UR10 model, {series: its rows}) as the UR10 benchmarks read them: ur10.yaml and the IPA
    files through their column map, each series its own registration group."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # the illustrative joint stiffnesses of ur10.yaml are not used here
        model = vjm.load_model(os.path.join(ROOT, "data", "robots", "ur10", "ur10.yaml"))
    cmap = read_column_map(os.path.join(IPA, "columns.yaml"))
    return model, {s: read_poses(os.path.join(IPA, FILES[s]), cmap, model.q_names, group=s) for s in series}


def training_rows(A, n: int):
    """The n rows of series A the calibration is fitted on (a seeded random pick), as a mask."""
    pick = np.zeros(A.n, dtype=bool)
    pick[np.random.default_rng(0).permutation(A.n)[:min(n, A.n)]] = True
    return pick


def nominal_marker() -> np.ndarray:
    """The T-Mac's point in the flange frame (mm): Trafo_TM_F_init is the flange's pose in the T-Mac frame."""
    T = np.loadtxt(os.path.join(IPA, "Series_A", "Trafo_TM_F_init.txt"))
    return -T[:3, :3].T @ T[:3, 3]


def split(data, k: int):
    """(the k evenly spaced rows registering a series, the others)."""
    mask = np.zeros(data.n, dtype=bool)
    mask[np.linspace(0, data.n - 1, k).astype(int)] = True
    return data.subset(mask), data.subset(~mask)


def run(args) -> list:
    model, sets = load_ur10()
    A = sets["A"]
    pick = training_rows(A, args.train)
    train, held = A.subset(pick), A.subset(~pick)
    rows = []
    for name, effects, folds in MODELS:
        t0 = time.perf_counter()
        if effects is None:
            cal = register(Calibration(model, "tool0", {}, {}, {}, nominal_marker()), train)
        else:
            cal = calibrate(model, train, "tool0", effects=effects, folds=folds)
        fit_s = time.perf_counter() - t0
        out = {"model": name, "fit_s": fit_s, "cal": cal, "A": error_stats(position_errors(cal, held))}
        for s in ("C", "D"):
            few, rest = split(sets[s], args.register)
            out[s] = error_stats(position_errors(register(cal, few), rest))
        rows.append(out)
        print(f"{name}: fitted in {fit_s:.1f} s", file=sys.stderr)
    return rows


def table(rows, args) -> str:
    lines = ["| model | A held out: mean / std / max / p95 | C: mean / std / max / p95 | D: mean / std / max / p95 |",
             "|---|---|---|---|"]
    for r in rows:
        cells = [" / ".join(f"{r[s][k]:.3f}" for k in ("mean", "std", "max", "p95")) for s in ("A", "C", "D")]
        lines.append(f"| {r['model']} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def details(cal) -> str:
    out = ["stages: " + "; ".join(f"{s.name} {'kept' if s.kept else 'not kept'} ({s.n_params} parameters, "
                                   f"RMS {s.rms:.3f} mm)" for s in cal.stages)]
    # the units of the fit (vjm.effects.absolute) and of the model files: N, mm
    units = {"compliance": ("rad/(N mm)", 1.0), "lateral": ("rad/(N mm)", 1.0), "varying": ("rad/(N mm)/rad", 1.0),
             "bending": ("1/(N mm^2)", 1.0), "alpha": ("1/K", 1.0), "mass": ("kg", 1.0)}
    for k, v in cal.robot_values().items():
        last = k.split(".")[-1]
        unit, f = units.get(last, ("mm" if last.startswith("d") else "rad", 1.0))
        out.append(f"- `{k}` = {v * f:.4g} +- {cal.std[k] * f:.2g} {unit}")
    out.append(f"- removed or not observable: {len(cal.removed)}: "
               + "; ".join(f"`{n}` ({why})" for n, why in cal.removed))
    return "\n".join(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--train", type=int, default=3000, help="rows of series A fitted (random, seed 0)")
    ap.add_argument("--register", type=int, default=30, help="poses of C and of D registering their set-up")
    ap.add_argument("--out", help="write the table (markdown) here too")
    args = ap.parse_args(argv)
    rows = run(args)
    text = (f"Position error (mm) held out; A: {args.train} rows fitted, the other "
            f"{11911 - args.train} held out; C, D: registered on {args.register} of their poses.\n\n"
            + table(rows, args) + "\n\nFitted (geometry + joint compliance):\n\n" + details(rows[-2]["cal"])
            + "\n\nFitted (the whole library):\n\n" + details(rows[-1]["cal"])
            + "\n\nFit times (s): " + ", ".join(f"{r['model']} {r['fit_s']:.1f}" for r in rows) + "\n")
    print(text)
    if args.out:
        with open(args.out, "w") as f:
            f.write(text)


if __name__ == "__main__":
    main()
