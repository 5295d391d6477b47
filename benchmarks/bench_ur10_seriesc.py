"""Series C of the IPA UR10 set: what the held-out mean error (0.464 mm with geometry + joint compliance
fitted on 3,000 rows of A, C registered on 30 of its poses) is made of, and what does not lower it.

Each line is one try, the robot's effects those of ``vjm calibrate``'s default (geometry, joint compliance):

1. the reference (bench_ur10.py's row), C registered on 30, 60, 200 of its poses (the robot frozen);
2. a similarity registration: a scale per set-up (a tracker's length scale: air temperature and pressure)
   besides its rigid frame, fitted on the same poses;
3. C's registration poses fitted together with A's rows (C's frame registered with them, the robot refitted);
4. A's rows fitted together with all of series B (another set-up, both elbow configurations);
5. the identification's threshold (``tol``: the least new direction a geometric parameter must add);
6. bounds, not held out: C registered on all of its poses (the best any registration can do), and the robot
   calibrated on C's odd rows, its even rows held out (what the model family reaches on C's own poses).

Usage: ``python benchmarks/bench_ur10_seriesc.py`` (about 3 minutes on 2 shared cores).
"""
import os
import sys
from dataclasses import replace

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_ur10 import load_ur10, split, training_rows

from vjm.calibration.engine import calibrate, instrument_frame, position_errors, predict_points, register

EFFECTS = ("geometry", "compliance")


def concat(a, b):
    """The rows of two data sets (their groups kept), points only."""
    pts = {k: np.concatenate([a.points[k], b.points[k]]) for k in a.points}
    return replace(a, q=np.concatenate([a.q, b.q]), points=pts, rotations={}, sigmas={},
                   group=np.concatenate([a.groups, b.groups]), meta={})


def similarity(P, Q):
    """(s, R, t) minimising sum |s R P_i + t - Q_i|^2 (Umeyama)."""
    cp, cq = P.mean(0), Q.mean(0)
    U, S, Vt = np.linalg.svd((P - cp).T @ (Q - cq))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    s = float(np.trace(np.diag(S) @ D) / np.sum((P - cp) ** 2))
    return s, R, cq - s * R @ cp


def line(what, e) -> None:
    print(f"| {what} | {e.mean():.3f} / {e.std():.3f} / {e.max():.3f} |", flush=True)


def main() -> None:
    model, sets = load_ur10(("A", "B", "C"))
    A, C = sets["A"], sets["C"]
    train = A.subset(training_rows(A, 3000))
    cal = calibrate(model, train, "tool0", effects=EFFECTS)
    print("| try | C held out: mean / std / max (mm) |\n|---|---|")
    for k in (30, 60, 200):
        few, rest = split(C, k)
        reg = register(cal, few)
        line(f"reference, C registered on {k} poses", position_errors(reg, rest))
        R, t = instrument_frame(reg, "C")
        s, R2, t2 = similarity((predict_points(reg, few) - t) @ R, few.points["tool0"])
        moved = s * ((predict_points(reg, rest) - t) @ R) @ R2.T + t2
        line(f"similarity registration on {k} poses (scale - 1 = {s - 1:.1e})",
             np.linalg.norm(moved - rest.points["tool0"], axis=1))
    for k in (30, 60):
        few, rest = split(C, k)
        line(f"A's rows and {k} of C's fitted together", position_errors(calibrate(model, concat(train, few), "tool0",
                                                                                  effects=EFFECTS), rest))
    for tol in (1e-4, 1e-2, 1e-1):
        few, rest = split(C, 30)
        other = calibrate(model, train, "tool0", effects=EFFECTS, tol=tol)
        line(f"identification threshold {tol:g} ({len(other.robot_values())} robot parameters; 1e-3: "
             f"{len(cal.robot_values())})", position_errors(register(other, few), rest))
    with_b = calibrate(model, concat(train, sets["B"]), "tool0", effects=EFFECTS)
    few, rest = split(C, 30)
    line("A's rows and all of B fitted together, C registered on 30", position_errors(register(with_b, few), rest))
    line("bound: C registered on all its poses (not held out)", position_errors(register(cal, C), C))
    odd = np.arange(C.n) % 2 == 1
    own = calibrate(model, C.subset(odd), "tool0", effects=EFFECTS)
    line("bound: calibrated on C's odd rows, its even rows held out", position_errors(own, C.subset(~odd)))


if __name__ == "__main__":
    main()
