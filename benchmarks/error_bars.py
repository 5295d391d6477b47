"""Do the calibration's error bars cover the truth?  Simulated UR10 poses (pinocchio, tests/truth_serial.py),
fitted by :func:`vjm.calibration.engine.calibrate` (geometry and joint compliance), over ``--seeds`` seeds:

1. **model error**: the truth has joint compliances and a bent upper arm (an Euler-Bernoulli cantilever,
   ``--bending`` 1/EI), the fit has no bending: how often does the 95 % interval ``value +- 1.96 std`` of the
   shoulder-lift and elbow compliances cover the truth, with the formal standard deviations and with those
   the calibration reports (:mod:`vjm.stats.uncertainty`)?
2. **no model error**: the same without the bending: the mean reported standard deviation against the spread
   (standard deviation) of the fitted values over the seeds.
3. the linearised delete-one-block jackknife against the refitted one (each block deleted and the final
   model fitted again) on ``--refits`` seeds of the first case.

The model fitted is the UR10's URDF (no nominal joint springs: the fitted compliance is the total one).

Usage: ``python benchmarks/error_bars.py [--seeds 50] [--rows 200] [--bending 2.5e-5] [--refits 3]``.
"""
import argparse
import os
import sys
import time
import warnings

import numpy as np

import vjm
from vjm.calibration import engine
from vjm.calibration.poses import AbsolutePoses
from vjm.calibration.serial import rotation_matrix
from vjm.stats.uncertainty import jackknife_std, parameter_std, pose_blocks, residual_blocks

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tests"))
import truth_serial as truth  # noqa: E402

URDF = os.path.join(ROOT, "data", "robots", "ur10", "ur10.urdf")
JOINTS = ("shoulder_lift_joint", "elbow_joint")
COMPLIANCE = {"shoulder_lift_joint": 4e-6, "elbow_joint": 8e-6}   # rad/(N m)
MM = 1e-3   # rad/(N m) -> rad/(N mm)
Z95 = 1.959963984540054


def hidden(bending: float, sigma: float) -> "truth.Hidden":
    return truth.Hidden(
        offsets={"shoulder_lift_joint": 2e-3, "elbow_joint": -1.5e-3, "wrist_1_joint": 1e-3},
        origins={"elbow_joint": (0.4, 0.0, -0.3, 5e-4, 0.0, 0.0)}, compliance=COMPLIANCE,
        bending={"shoulder_lift_joint": bending} if bending else {},
        R=rotation_matrix([0.3, -0.2, 2.0]), t=np.array([2000.0, -1500.0, 300.0]),
        marker=np.array([10.0, -20.0, 110.0]), sigma=sigma)


def poses(n: int, rng) -> np.ndarray:
    q = rng.uniform(-np.pi, np.pi, (n, 6))
    q[:, 1] = rng.uniform(-np.pi, 0.0, n)   # the upper arm above the base plate
    return q


def drift(t: np.ndarray, size: float) -> np.ndarray:
    """The marker's drift (len(t), 3) mm at the times t in [0, 1] (the rows' order): slow, along all three axes."""
    return size * np.column_stack([np.sin(2 * np.pi * t), np.cos(3 * np.pi * t), 2 * t - 1])


def dataset(model, h, n: int, seed: int, size: float = 0.0, chunks: int = 25) -> AbsolutePoses:
    """n random poses measured in turn; with a drift ``size``, the marker moving on the flange as they are."""
    rng = np.random.default_rng(seed)
    q = poses(n, rng)
    if not size:
        pts = truth.measure(URDF, "tool0", model.q_names, q, h, rng)
    else:
        parts = np.array_split(np.arange(n), chunks)
        moved = h.marker + drift((np.arange(chunks) + 0.5) / chunks, size)
        pts = np.concatenate([truth.measure(URDF, "tool0", model.q_names, q[p], truth.Hidden(
            **{**h.__dict__, "marker": mk}), rng) for p, mk in zip(parts, moved)])
    return AbsolutePoses(tuple(model.q_names), q, {"tool0": pts}, group=np.full(n, "A", dtype=object))


def final_fit(model, data, cal):
    """(problem, layout, x, measurements) of a calibration's final fit, rebuilt."""
    prob = engine._problems(model, data, cal.measured, cal.frames, **engine._uses(cal.values))
    meas = engine._measurements(data, cal.measured)
    lay = engine.Layout(tuple(cal.values), ("",) * len(cal.values), ("",) * len(cal.values))
    return prob, lay, np.array(list(cal.values.values())), meas


def one(model, h, n: int, seed: int, size: float = 0.0, refit: bool = False) -> dict:
    data = dataset(model, h, n, seed, size)
    cal = engine.calibrate(model, data, "tool0", effects=("geometry", "compliance"))
    prob, lay, x, meas = final_fit(model, data, cal)
    r = (engine._predict(prob, lay, x) - meas).ravel()
    J = engine._jacobian(prob, lay, x)
    parts = [(residual_blocks(rows, data.n), what) for rows, what in pose_blocks(data.q, data.groups)]
    unc = parameter_std(J, r, parts)
    idx = [lay.names.index(f"{j}.compliance") for j in JOINTS]
    out = {"value": x[idx] * 1000, "formal": unc.formal[idx] * 1000, "std": np.array([cal.std[lay.names[i]]
                                                                                      for i in idx]) * 1000,
           "jack": unc.jackknife[idx] * 1000, "method": cal.std_method}
    if refit:   # each block of neighbouring poses deleted, the final model fitted again from the full fit
        rows, blocks = pose_blocks(data.q, data.groups)[0][0], parts[0][0]
        d = []
        for b in rows:
            keep = np.setdiff1d(np.arange(data.n), b)
            sub = data.subset(keep)
            pr, _, _, ms = final_fit(model, sub, cal)
            d.append(engine.fit(pr, lay, ms, x)[0][idx])
        d = np.array(d)
        G = len(rows)
        out["refit"] = np.sqrt((G - 1) / G * np.sum((d - d.mean(axis=0)) ** 2, axis=0)) * 1000
        out["linear"] = jackknife_std(J, r, blocks)[idx] * 1000
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=50)
    ap.add_argument("--rows", type=int, default=200)
    ap.add_argument("--bending", type=float, default=2.5e-5, help="the upper arm's 1/EI, 1/(N m^2)")
    ap.add_argument("--sigma", type=float, default=0.01, help="noise, mm")
    ap.add_argument("--drift", type=float, default=0.05, help="the marker's drift, mm")
    ap.add_argument("--refits", type=int, default=3)
    args = ap.parse_args(argv)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = vjm.load_model(URDF)
    truth_c = np.array([COMPLIANCE[j] for j in JOINTS])
    t0 = time.perf_counter()
    cases = (("with a hidden marker drift", 0.0, args.drift), ("with a hidden upper-arm bending", args.bending, 0.0),
             ("without model error", 0.0, 0.0))
    for label, bend, size in cases:
        h = hidden(bend, args.sigma)
        runs = [one(model, h, args.rows, s, size) for s in range(args.seeds)]
        v = np.array([o["value"] for o in runs])
        print(f"\n{label} ({args.seeds} seeds, {args.rows} rows, noise {args.sigma} mm; {runs[0]['method']})")
        for k, j in enumerate(JOINTS):
            cover = {w: np.mean(np.abs(v[:, k] - truth_c[k]) <= Z95 * np.array([o[w][k] for o in runs]))
                     for w in ("formal", "std")}
            spread = np.std(v[:, k], ddof=1)
            # printed in the model files' unit, rad/(N mm) (the truth's is pinocchio's rad/(N m))
            print(f"  {j}: truth {truth_c[k] * MM:.3g}, mean fitted {v[:, k].mean() * MM:.4g} rad/(N mm); spread over "
                  f"seeds {spread * MM:.3g}; mean std formal {np.mean([o['formal'][k] for o in runs]) * MM:.3g}, "
                  f"reported {np.mean([o['std'][k] for o in runs]) * MM:.3g} (ratio to the spread "
                  f"{np.mean([o['std'][k] for o in runs]) / spread:.2f}); 95 % coverage formal "
                  f"{100 * cover['formal']:.0f} %, reported {100 * cover['std']:.0f} %")
    h = hidden(args.bending, args.sigma)
    for s in range(args.refits):
        o = one(model, h, args.rows, s, refit=True)
        print(f"  seed {s}: jackknife std linearised / refitted, rad/(N mm): " + ", ".join(
            f"{j} {a * MM:.3g} / {b * MM:.3g}" for j, a, b in zip(JOINTS, o["linear"], o["refit"])))
    print(f"\n{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
