"""``vjm diagnose`` on the whole IPA UR10 set (16,811 rows), timed: series A (11,911 rows) diagnosed, B, C and D
(4,900 rows) held out as new tracker set-ups, each registered on 30 of its poses, the robot frozen.

The command runs as a user runs it (a child process, the files read as they are through the column map);
the wall time and the CPU time (user + system, the child's) are printed with what it names and the
held-out errors.

Usage: ``python benchmarks/bench_ur10_diagnose.py [--out DIR] [--blas-threads N ...]`` (default: a temporary
folder; each ``--blas-threads`` value one run with ``OPENBLAS_NUM_THREADS`` set to it, in turn: on cores other
jobs load, OpenBLAS's threads wait on each other).
"""
import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
IPA = os.path.join(ROOT, "data", "realdata", "ur10_ipa")
FIT = "Series_A/measurements_grid.csv"
HELD = ("Series_B/measurements_joint_configurations.csv", "Series_C/measurements_random_poses.csv",
        "Series_D/measurements_iso_cubes.csv")


def command(out: str) -> list:
    """The ``vjm diagnose`` command line of the benchmark."""
    cmd = [sys.executable, "-m", "vjm.cli", "diagnose", os.path.join(ROOT, "data", "robots", "ur10", "ur10.yaml"),
           os.path.join(IPA, FIT), "--columns", os.path.join(IPA, "columns.yaml"), "--out", out]
    for f in HELD:
        cmd += ["--validate", os.path.join(IPA, f)]
    return cmd


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=None)
    ap.add_argument("--blas-threads", type=int, action="append", default=None)
    args = ap.parse_args()
    for threads in args.blas_threads or [None]:
        out = args.out or os.path.join(tempfile.mkdtemp(prefix="ur10_diagnose_"), "report")
        env = {**os.environ,
               "PYTHONPATH": os.pathsep.join([os.path.join(ROOT, "src"), os.environ.get("PYTHONPATH", "")])}
        if threads is not None:
            env["OPENBLAS_NUM_THREADS"] = str(threads)
        once(out, env, threads)


def once(out: str, env: dict, threads) -> None:
    load = os.getloadavg()[0]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    res = subprocess.run(command(out), env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if res.returncode != 0:
        sys.exit(f"vjm diagnose failed ({res.returncode}): {res.stderr.strip()}")
    rep = json.load(open(os.path.join(out, "report.json")))
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    rows = rep["rows"] + sum(v["rows"] + v["registered_on"] for v in rep["held_out"]["validate"])
    blas = "" if threads is None else f", OPENBLAS_NUM_THREADS={threads}"
    print(f"vjm diagnose, {rows} rows{blas}: {wall:.1f} s wall, {cpu:.1f} s CPU (load average before: "
          f"{load:.1f}); verdict {rep['verdict']}, named {', '.join(rep['named_effects'])}")
    for v in rep["held_out"]["validate"]:
        e = v["errors_mm"]
        print(f"  held out {os.path.basename(os.path.dirname(v['file']))}: "
              + " / ".join(f"{e[k]:.3f}" for k in ("mean", "std", "max", "p95")) + " mm")


if __name__ == "__main__":
    main()
