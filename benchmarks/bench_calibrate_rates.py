"""Benchmark: how often the robot calibration names each library effect, and how often a clean set names one.

Truth from tests/truth_serial.py (pinocchio, no vjm code): a UR10 seen by an instrument in a random frame
through a marker at a random offset, 150 random configurations, 0.01 mm noise.  For each effect of
:mod:`vjm.calibration.engine`'s library, ``--sets`` random truth sets carry it, with a random size in a
fixed range, on top of a realistic arm (joint offsets, an origin error and joint compliances; for the
geometry and compliance rows only that effect), and the calibration is run with geometry, joint compliance
and that effect: the rate at which the effect is named (its stage kept) is its power.  The same number of
clean sets (the realistic arm without the effect; for geometry and compliance no effect at all) give its
false-effect rate.  The choice rule is the calibration's default: the F test at ``alpha`` = 1e-3.

Usage: ``python benchmarks/bench_calibrate_rates.py [--sets 3] [--out table.md]`` (about 4 minutes).
"""
from __future__ import annotations

import argparse
import os
import sys
import time
import warnings

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tests"))
import truth_serial as truth  # noqa: E402

import vjm  # noqa: E402
from vjm.calibration.engine import calibrate  # noqa: E402
from vjm.calibration.poses import AbsolutePoses  # noqa: E402
from vjm.calibration.serial import rotation_matrix  # noqa: E402

URDF = os.path.join(ROOT, "data", "robots", "ur10", "ur10.urdf")
ROWS, SIGMA = 150, 0.01


def _u(rng, lo: float, hi: float) -> float:
    """A random size in [lo, hi] with a random sign."""
    return float(rng.uniform(lo, hi) * rng.choice([-1.0, 1.0]))


def _geometry(rng) -> dict:
    return {"offsets": {j: _u(rng, 1e-3, 3e-3) for j in ("shoulder_lift_joint", "elbow_joint", "wrist_1_joint")},
            "origins": {"elbow_joint": (0.0, 0.0, _u(rng, 0.3, 1.0), _u(rng, 2e-4, 6e-4), 0.0, 0.0)}}


def _compliance(rng) -> dict:
    return {"compliance": {"shoulder_lift_joint": rng.uniform(3e-6, 1e-5), "elbow_joint": rng.uniform(3e-6, 1e-5)}}


#: effect -> the hidden truth of its size range (tests/truth_serial.py units: rad, mm, rad/(N m), 1/(N m^2), kg)
EFFECTS = {
    "geometry": _geometry,
    "compliance": _compliance,
    "coupling": lambda rng: {"coupling": {("wrist_2_joint", "wrist_1_joint"): _u(rng, 0.01, 0.03)}},
    "lateral": lambda rng: {"lateral": {"elbow_joint": rng.uniform(2e-5, 5e-5)}},
    "bending": lambda rng: {"bending": {"elbow_joint": rng.uniform(1e-5, 3e-5)}},
    "varying": lambda rng: {"varying": {"elbow_joint": _u(rng, 2e-6, 5e-6)}},
    "thermal": lambda rng: {"alpha": rng.uniform(1.5e-5, 3e-5)},
    "tilt": lambda rng: {"tilt": (_u(rng, 0.02, 0.05), _u(rng, 0.02, 0.05))},
    "backlash": lambda rng: {"backlash": {"elbow_joint": rng.uniform(2e-4, 5e-4)}},
    "payload": lambda rng: {"payload": rng.uniform(3.0, 8.0)},
}


def _configurations(model, rng, n: int) -> np.ndarray:
    """n configurations, the upper arm above the base plate, the elbow's gravity torque at least 3 N m from 0
    (so that a backlash's side is not decided by noise)."""
    q = rng.uniform(-np.pi, np.pi, (3 * n, 6))
    q[:, 1] = rng.uniform(-np.pi, 0.0, 3 * n)
    g = truth.gravity_torques(URDF, model.q_names, q)
    return q[np.abs(g[:, 2]) > 3.0][:n]


def truth_set(model, effect: str, hidden_effect: bool, seed: int) -> AbsolutePoses:
    """One random truth set: the instrument and marker random, the realistic arm, the effect if asked."""
    rng = np.random.default_rng(seed)
    arm: dict = {} if effect in ("geometry", "compliance") else {**_geometry(rng), **_compliance(rng)}
    if hidden_effect:
        arm.update(EFFECTS[effect](rng))
    hidden = truth.Hidden(R=rotation_matrix(rng.normal(size=3)), t=rng.uniform(-2000, 2000, 3),
                          marker=rng.uniform(-50, 50, 3) + [0.0, 0.0, 100.0], sigma=SIGMA, **arm)
    q = _configurations(model, rng, ROWS)
    temp = rng.uniform(15.0, 35.0, len(q))
    pts = truth.measure(URDF, "tool0", model.q_names, q, hidden, rng, temperature=temp)
    return AbsolutePoses(tuple(model.q_names), q, {"tool0": pts}, group=np.full(len(q), "A", dtype=object),
                         meta={"meta_temperature": temp}, source=f"{effect} {seed}")


def named(model, data, effect: str) -> bool:
    tried = ("geometry", "compliance") + (() if effect in ("geometry", "compliance") else (effect,))
    cal = calibrate(model, data, "tool0", effects=tried)
    return any(s.name == effect and s.kept for s in cal.stages)


def run(sets: int) -> list:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        # the model pinocchio's truth simulates (the URDF, rigid): the calibration corrects the model it is given
        model = vjm.load_model(os.path.join(ROOT, "tests", "ur10_rigid.yaml"))
    rows = []
    for k, effect in enumerate(EFFECTS):
        t0 = time.perf_counter()
        power = [named(model, truth_set(model, effect, True, 1000 * k + s), effect) for s in range(sets)]
        false = [named(model, truth_set(model, effect, False, 1000 * k + 500 + s), effect) for s in range(sets)]
        rows.append((effect, float(np.mean(power)), float(np.mean(false)), time.perf_counter() - t0))
        print(f"{effect}: named {sum(power)}/{sets}, on clean sets {sum(false)}/{sets} "
              f"({rows[-1][3]:.0f} s)", file=sys.stderr)
    return rows


def table(rows, sets: int) -> str:
    lines = [f"| effect | named when hidden ({sets} sets) | named on clean sets ({sets} sets) |", "|---|---|---|"]
    lines += [f"| {e} | {100 * p:.0f} % | {100 * f:.0f} % |" for e, p, f, _ in rows]
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sets", type=int, default=3, help="random truth sets per effect, with it and without it")
    ap.add_argument("--out", help="write the table (markdown) here too")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    text = table(run(args.sets), args.sets) + f"\n\n({time.perf_counter() - t0:.0f} s)\n"
    print(text)
    if args.out:
        with open(args.out, "w") as f:
            f.write(text)


if __name__ == "__main__":
    main()
