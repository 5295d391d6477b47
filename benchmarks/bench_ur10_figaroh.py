"""FIGAROH's geometric calibration of the IPA UR10 set on the split of bench_ur10.py: the anchor.

FIGAROH (LAAS-CNRS's calibration toolbox on pinocchio, ``pip install figaroh``; 1.0.2 measured) fits its
``full_params`` model (per-joint origin errors kept by its QR selection, the tracker frame and the T-Mac
offset) on the same 3,000 rows of series A.  Held out as in bench_ur10.py: the other rows of A, and C
and D each registered on 30 of its own poses (a Kabsch fit, the least-squares rigid motion, of FIGAROH's
predicted points onto the measured ones) with the robot's parameters frozen.

FIGAROH 1.0.2 reads a unified YAML config and a CSV (``x1 y1 z1`` in metres, one column per joint); both
are written to a temporary folder.  Its ``known_baseframe``/``known_tipframe`` flags are set by hand (the
config does not carry them).  Usage: ``python benchmarks/bench_ur10_figaroh.py [--train 3000]``.
"""
import argparse
import os
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_ur10 as b

from vjm.calibration.engine import error_stats
from vjm.calibration.serial import kabsch

CONFIG = """tasks:
  calibration:
    enabled: true
    type: kinematic_calibration
    parameters: {calibration_level: full_params, include_non_geometric: false, outlier_threshold: 0.05}
    kinematics: {base_frame: base_link, tool_frame: tool0, free_flying_base: false}
    measurements:
      markers:
      - {reference_joint: wrist_3_joint, measurable_dof: [true, true, true, false, false, false]}
      poses: {base_pose: null, tool_pose: null}
    data: {source_file: %s, number_of_samples: %d}
  identification: {enabled: false}
"""


def fit(urdf, names, train, folder):
    """FIGAROH's calibration on ``train``: (a predictor of the marker in A's tracker frame, mm; the fit)."""
    import pandas as pd
    import pinocchio as pin
    from figaroh.calibration.base_calibration import BaseCalibration
    from figaroh.calibration.calibration_tools import calc_updated_fkm

    csv = os.path.join(folder, "train.csv")
    df = pd.DataFrame({f"{c}1": train.points["tool0"][:, i] / 1000.0 for i, c in enumerate("xyz")})
    for i, n in enumerate(names):
        df[n] = train.q[:, i]
    df.to_csv(csv, index=False)
    cfg = os.path.join(folder, "ur10_figaroh.yaml")
    with open(cfg, "w") as f:
        f.write(CONFIG % (csv, train.n))
    robot = pin.RobotWrapper(pin.buildModelFromUrdf(urdf))

    class UR10(BaseCalibration):
        pass

    cal = UR10(robot, cfg)
    cal.calib_config["known_baseframe"] = False
    cal.calib_config["known_tipframe"] = False
    cal.initialize()
    cal.solve(enable_logging=False)
    order = [robot.model.names[i] for i in cal.calib_config["actJoint_idx"]]
    cols = [names.index(n) for n in order]

    def predict(q):
        cc = dict(cal.calib_config, NbSample=len(q))
        p = calc_updated_fkm(robot.model, robot.data, cal.var_, q[:, cols], cc)
        return p.reshape(3, len(q)).T * 1000.0   # marker, then component, then sample

    return predict, cal


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--train", type=int, default=3000)
    ap.add_argument("--register", type=int, default=30)
    args = ap.parse_args(argv)
    model, sets = b.load_ur10()
    A = sets["A"]
    pick = b.training_rows(A, args.train)
    with tempfile.TemporaryDirectory() as folder:
        t0 = time.perf_counter()
        predict, cal = fit(os.path.join(b.ROOT, "data", "robots", "ur10", "ur10.urdf"), list(model.q_names),
                           A.subset(pick), folder)
        fit_s = time.perf_counter() - t0
    held = A.subset(~pick)
    res = {"A": error_stats(np.linalg.norm(predict(held.q) - held.points["tool0"], axis=1))}
    for s in ("C", "D"):
        few, rest = b.split(sets[s], args.register)
        R, t = kabsch(predict(few.q), few.points["tool0"])
        res[s] = error_stats(np.linalg.norm(predict(rest.q) @ R.T + t - rest.points["tool0"], axis=1))
    cells = [" / ".join(f"{res[s][k]:.3f}" for k in ("mean", "std", "max", "p95")) for s in ("A", "C", "D")]
    print(f"FIGAROH full_params ({len(cal.calib_config['param_name'])} parameters, fitted in {fit_s:.1f} s)")
    print("| FIGAROH geometric (full_params) | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
