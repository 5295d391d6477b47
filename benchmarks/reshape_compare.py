"""Before/after harness for a refactor of ``src/vjm``: no numeric result may move by more than round-off.

``run`` runs a fixed list of reference jobs (``vjm diagnose``/``calibrate`` on the four IPA UR10 series
and the documented A -> C, D run; simulated deflections of parallel machines and their diagnosis,
deflection and stiffness data; absolute poses of a hexapod and of simulated robots; ``vjm compensate``,
``vjm map``, ``vjm stiffness``, ``vjm table1``), each into ``OUTDIR/<job>/``; ``compare`` compares two such
trees file by file::

    python benchmarks/reshape_compare.py run OUTDIR [--vjm CMD] [--jobs 2] [--only JOB ...] [--root DIR]
    python benchmarks/reshape_compare.py compare DIR_A DIR_B [--rtol 1e-9] [--atol 1e-12]
                                                 [--rename OLD=NEW ...] [--text-ok] [--strict-digits]

``--vjm`` is the command prefix that runs the CLI, split like a shell line; leading ``NAME=value`` words
are set in its environment, e.g. ``--vjm "PYTHONPATH=/work/base/src /work/main/.venv/bin/python -m vjm.cli"``.
Default: the ``vjm`` executable of the venv beside this file (``<root>/.venv/bin/vjm``).  The jobs run with
the working directory ``--root`` (default: the checkout holding this file), so the data paths are relative
(``data/...``: the same files for a before and an after tree); ``OPENBLAS_NUM_THREADS``,
``OMP_NUM_THREADS``, ``MKL_NUM_THREADS`` = 1 (``--blas-threads``) so that the sums do not depend on the
threads' split, ``PYTHONHASHSEED=0`` and ``MPLBACKEND=Agg``.  Input files the harness makes itself (the
hexapod's absolute poses, targets) are written into the job's folder by numpy/scipy code of this file
(no vjm), and are compared too.

Per job and step, ``OUTDIR/<job>/<step>.cmd`` (the command, with ``vjm`` for the prefix and ``<OUT>`` for
OUTDIR), ``.stdout``, ``.stderr``, ``.rc`` (exit status), and the step's outputs (``<step>/`` for an
``--out`` folder, ``<step>.csv`` for ``vjm simulate``/``compensate``).  ``OUTDIR/timing.json`` has the
wall and CPU seconds of every step (never compared).  A step that fails is recorded and the job goes on
(a failing step whose exit status is the reference's is "same").

``compare`` walks both trees; per file (by content):

* JSON (``*.json``, or any file that parses as a JSON object/array, e.g. ``vjm stiffness --json``'s
  stdout): same structure and keys, every number within ``|a-b| <= atol + rtol max(|a|,|b|)``, strings
  compared as text (below); the largest relative difference is reported with its key path;
* ``*.npz``: same arrays (names, shapes, dtypes), numbers as above;
* text (CSV, YAML, URDF, txt, HTML, stdout, stderr, rc, cmd, anything else that is UTF-8): line by line,
  each line split into numbers and the text between them; numbers as above, the text exactly;
* PNG, JPG, SVG, PDF: presence only.

The relative difference is ``|a-b| / max(|a|,|b|)``; the largest is reported over the numbers larger than
``100 atol`` (those below are round-off noise about zero, 1e-15 against -3e-21: counted apart).  Mind that
the default atol 1e-12 lets values of order 1e-9 (compliances in rad/(N mm), their standard deviations)
move by 1e-3 relative without failing: such a move is still shown as the round-off line's ``max rel``.

Ignored (masked on both sides before comparing), a closed list:

* the harness's own ``timing.json``;
* JSON keys that are timings: ``seconds``, ``time_s``, ``elapsed``, ``elapsed_s``, ``wall_s``, ``cpu_s``,
  ``timing``, ``timings``, ``duration``, ``duration_s`` (any key matching ``TIMING_KEY``);
* in the output-set manifests ``.linkfea-outputs.json``: the files' hashes (the files themselves are
  compared), ``run`` (a random id) and ``written`` (a date); the set names and file lists are compared;
* in text: durations printed by the tools, "<number> s" after "in", "took", "wall", "elapsed", "time",
  "cpu" ("Fitted in 13.7 s."), durations in ``Xm Ys`` / ``h:mm:ss`` form, and rates "<n> points/s";
  ISO dates and times (``2026-11-27T12:42:17+0000``, ``2026-11-27 12:42``);
* absolute paths: DIR_A, DIR_B and the folders the runs wrote to (``outdir`` of their ``timing.json``, in
  case a run folder was moved) as ``<OUT>``; the checkout each run's jobs ran in (``root``: error messages
  print absolute data paths) as ``<ROOT>``, its ``src`` as ``<SRC>``; anything under ``/tmp`` or
  ``/var/tmp`` as ``<TMP>``; Python source locations in warnings and tracebacks (``file.py:123``,
  ``line 123``), which a refactor moves; object addresses (``0x7f...``).

``--text-ok`` reports files whose numbers agree but whose other text differs (a module named in a comment,
a reworded message) as ``text differs (numbers agree)`` without failing.  A number printed with few
digits may flip its last digit on a round-off change (0.4395 printed .3f); in text (not in JSON, CSV
numbers with many digits never get there) a float token differing by at most one unit of its last printed
digit is counted apart and reported as ``round-off (... last printed digit flipped in N tokens)`` unless
``--strict-digits``.

Output: one line per file, ``same``, ``round-off (max rel 3e-13 at PATH)``, or ``DIFFERS: ...`` / ``MISSING
in A|B``; exit status 1 if any file differs or is missing on one side.  ``--rename OLD=NEW`` (repeatable)
matches a file named OLD in DIR_A with NEW in DIR_B (a base name, or a path relative to the job folder
when it has a ``/``).
"""
from __future__ import annotations

import argparse
import concurrent.futures as cf
import difflib
import json
import math
import os
import re
import shlex
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# --------------------------------------------------------------------------------------------------------
# The reference jobs
# --------------------------------------------------------------------------------------------------------

UR10 = "data/robots/ur10/ur10.yaml"
PUMA = "data/robots/puma560/puma560.yaml"
IPA = "data/realdata/ur10_ipa"
COLUMNS = f"{IPA}/columns.yaml"
SERIES = {"A": f"{IPA}/Series_A/measurements_grid.csv",
          "B": f"{IPA}/Series_B/measurements_joint_configurations.csv",
          "C": f"{IPA}/Series_C/measurements_random_poses.csv",
          "D": f"{IPA}/Series_D/measurements_iso_cubes.csv"}
PUU, PRPAR, HEX = "data/orthoglide/puu.yaml", "data/orthoglide/prpar.yaml", "data/machines/hexapod_6ups.yaml"
Q_UR10 = "0,-1.2,1.5,-1.9,-1.57,0"


@dataclass
class Job:
    name: str
    steps: list  # [(step name, [args after the vjm prefix]; "{J}" = the job's folder)]
    make: object = None  # a function (job folder) writing the job's input files, or None
    notes: str = ""


def _targets(path: Path, orient: bool) -> None:
    """Points near the UR10's working configuration (tool0 at (884, 164, 436) mm, z down)."""
    pts = [(884.0, 164.0, 436.0), (800.0, 250.0, 400.0), (700.0, -150.0, 500.0), (950.0, 50.0, 300.0),
           (600.0, 400.0, 450.0)]
    with open(path, "w", encoding="utf-8") as f:
        if orient:
            f.write("x,y,z,rx,ry,rz\n")
            for p in pts:
                f.write(f"{p[0]!r},{p[1]!r},{p[2]!r},3.141592653589793,0.0,0.0\n")
        else:
            f.write("x,y,z\n")
            for p in pts:
                f.write(f"{p[0]!r},{p[1]!r},{p[2]!r}\n")


def _puma_targets(path: Path) -> None:
    with open(path, "w", encoding="utf-8") as f:
        f.write("x,y,z\n")
        for p in [(192.6, -150.05, 728.3), (250.0, -150.0, 700.0), (150.0, -100.0, 650.0)]:
            f.write(",".join(repr(v) for v in p) + "\n")


# The 6-UPS hexapod of data/machines/hexapod_6ups.yaml written out from its numbers (as tests/truth_parallel.py,
# no vjm): base joints at radius 350 mm (z = 0), platform joints at radius 200 mm, home z = 550 mm.
def _hexapod_poses(path: Path, n: int, seed: int, t) -> None:
    import numpy as np
    from scipy.spatial.transform import Rotation

    def circle(r, deg):
        a = np.radians(deg)
        return np.column_stack([r * np.cos(a), r * np.sin(a), np.zeros_like(a)])

    base = circle(350.0, [10, 130, 250, -10, 110, 230])
    top = circle(200.0, [50, 170, 290, -50, 70, 190])
    offsets = np.array([0.5, -0.3, 0.0, 0.25, 0.0, -0.4])  # mm: hidden strut offsets
    marker = np.array([20.0, -10.0, 35.0])
    R_i = Rotation.from_rotvec([0.3, -0.2, 1.1]).as_matrix()
    rng = np.random.default_rng(seed)
    p = np.column_stack([rng.uniform(-70, 70, (n, 2)), 550.0 + rng.uniform(-70, 70, n)])
    w = rng.uniform(-0.08, 0.08, (n, 3))
    R = Rotation.from_rotvec(w).as_matrix()
    c = np.einsum("nij,kj->nki", R, top) + p[:, None, :]
    q = np.linalg.norm(c - base[None], axis=2) - offsets
    x = p + Rotation.from_rotvec(w).apply(marker)
    m = x @ R_i.T + np.asarray(t, dtype=float) + rng.normal(0.0, 0.01, (n, 3))
    with open(path, "w", encoding="utf-8") as f:
        f.write("A1.l,A2.l,A3.l,B1.l,B2.l,B3.l,platform.x,platform.y,platform.z\n")
        for a, b in zip(q, m):
            f.write(",".join(f"{v:.10f}" for v in np.r_[a, b]) + "\n")


def _make_hexapod(d: Path) -> None:
    _hexapod_poses(d / "poses.csv", 60, 1, (1500.0, -300.0, 200.0))
    _hexapod_poses(d / "validate.csv", 40, 2, (-800.0, 900.0, 100.0))


def _make_compensate(d: Path) -> None:
    _targets(d / "targets.csv", False)
    _targets(d / "targets_orient.csv", True)
    _puma_targets(d / "targets_puma.csv")


def _ur10_jobs() -> list:
    jobs = []
    for s, csv in SERIES.items():
        for cmd in ("diagnose", "calibrate"):
            jobs.append(Job(f"ur10_{s}_{cmd}", [(cmd, [cmd, UR10, csv, "--columns", COLUMNS, "--out", "{J}/" + cmd])]))
    val = ["--validate", SERIES["C"], "--validate", SERIES["D"]]
    jobs.append(Job("ur10_A_CD_diagnose", [("diagnose", ["diagnose", UR10, SERIES["A"], "--columns", COLUMNS, *val,
                                                        "--out", "{J}/diagnose"])],
                    notes="docs/ur10.md 'From the command line'"))
    jobs.append(Job("ur10_A_CD_calibrate", [("calibrate", ["calibrate", UR10, SERIES["A"], "--columns", COLUMNS, *val,
                                                          "--targets", "{J}/targets.csv", "--out", "{J}/calibrate"])],
                    make=lambda d: _targets(d / "targets.csv", False),
                    notes="docs/ur10.md, with --targets (commands.csv)"))
    return jobs


def _simdiag(name, model, sim_args, diag_args=()) -> Job:
    return Job(name, [("simulate", ["simulate", model, *sim_args, "--out", "{J}/simulate.csv"]),
                      ("diagnose", ["diagnose", model, "{J}/simulate.csv", *diag_args, "--out", "{J}/diagnose"])])


def jobs() -> list:
    js = _ur10_jobs()
    # deflection data of parallel machines: simulate + diagnose
    js.append(_simdiag("puu_clearance", PUU, ["--effect", "clearance:backlash=0.003", "--poses", "random:30",
                                              "--loads", "axes:100", "--noise-t", "0.001", "--seed", "1"]))
    js.append(_simdiag("prpar_passive_clearance", PRPAR, ["--effect", "passive_clearance:backlash=0.0005", "--poses",
                                                          "random:20", "--loads", "axes:100", "--noise-t", "0.001",
                                                          "--seed", "2"]))
    js.append(_simdiag("hexapod_gravity", HEX, ["--effect", "gravity:weight=300", "--poses", "random:12", "--tilt",
                                                "0.05", "--loads", "axes:200,400", "--noise-t", "0.001", "--seed", "3"]))
    # stiffness observations (x,y,z,quantity,value kind): the seed's Table 1
    js.append(Job("seed_table1_diagnose", [
        ("puu", ["diagnose", PUU, "data/seed_table1.csv", "--out", "{J}/puu"]),
        ("prpar", ["diagnose", PRPAR, "data/seed_table1.csv", "--out", "{J}/prpar"])]))
    # absolute poses of a parallel machine (hexapod, poses made here) and of robots (vjm simulate)
    js.append(Job("hexapod_poses", [
        ("diagnose", ["diagnose", HEX, "{J}/poses.csv", "--validate", "{J}/validate.csv", "--out", "{J}/diagnose"]),
        ("diagnose_folds", ["diagnose", HEX, "{J}/poses.csv", "--effect", "offset", "--effect", "attachment",
                            "--out", "{J}/diagnose_folds"])],
        make=_make_hexapod))
    hidden = ["--noise-t", "0.01", "--effect", "offset:elbow_joint=0.002", "--effect", "compliance:shoulder_lift_joint=2"]
    js.append(Job("ur10_sim_poses", [  # 60 poses with 5-fold CV cost 160 s of CPU: 40 poses and a --validate set
        ("simulate", ["simulate", UR10, "--poses", "random:40", *hidden, "--seed", "4", "--out", "{J}/simulate.csv"]),
        ("simulate_validate", ["simulate", UR10, "--poses", "random:40", *hidden, "--seed", "6", "--out",
                               "{J}/simulate_validate.csv"]),
        ("diagnose", ["diagnose", UR10, "{J}/simulate.csv", "--validate", "{J}/simulate_validate.csv", "--out",
                      "{J}/diagnose"]),
        ("calibrate", ["calibrate", UR10, "{J}/simulate.csv", "--folds", "0", "--out", "{J}/calibrate"])]))
    js.append(Job("puma560_sim_poses", [
        ("simulate", ["simulate", PUMA, "--poses", "random:40", "--noise-t", "0.01", "--effect", "offset:q2=0.002",
                      "--effect", "compliance:q3=2", "--seed", "5", "--out", "{J}/simulate.csv"]),
        ("diagnose", ["diagnose", PUMA, "{J}/simulate.csv", "--out", "{J}/diagnose"])],
        notes="diagnose refuses a DH robot (no URDF to write back): exit 2 is the reference"))
    # robot tools
    js.append(Job("compensate", [
        ("ur10", ["compensate", UR10, "{J}/targets.csv", "--out", "{J}/ur10.csv"]),
        ("ur10_orient", ["compensate", UR10, "{J}/targets_orient.csv", "--out", "{J}/ur10_orient.csv"]),
        ("ur10_payload", ["compensate", UR10, "{J}/targets.csv", "--payload", "5@0,0,100", "--out",
                          "{J}/ur10_payload.csv"]),
        ("puma560", ["compensate", PUMA, "{J}/targets_puma.csv", "--seed", "0,0.8,-0.5,0,0.6,0", "--out",
                     "{J}/puma560.csv"])],
        make=_make_compensate))
    js.append(Job("map_robot", [
        ("joint", ["map", UR10, "--joints", "shoulder_lift_joint=-2:0:15,elbow_joint=0.3:2.5:15", "--q", Q_UR10,
                   "--self-weight", "--out", "{J}/joint"]),
        ("cartesian", ["map", UR10, "--box", "600:900,-100:200,300:500", "--grid", "4", "--out", "{J}/cartesian"])]))
    js.append(Job("stiffness", [
        ("ur10", ["stiffness", UR10, "--q", Q_UR10, "--self-weight", "--json"]),
        ("ur10_text", ["stiffness", UR10, "--q", Q_UR10, "--self-weight"]),
        ("puma560", ["stiffness", PUMA, "--q", "0,0.8,-0.5,0,0.6,0", "--self-weight", "--json"]),
        ("puu", ["stiffness", PUU, "--at", "10,20,30", "--json"]),
        ("hexapod", ["stiffness", HEX, "--at", "10,-20,560,0,0,0.1", "--json"])]))
    js.append(Job("parallel_map_table1", [
        ("table1", ["table1", PUU, PRPAR]),
        ("map_puu", ["map", PUU, "--grid", "11", "--slice", "z=0", "--out", "{J}/map_puu"])]))
    return js


# --------------------------------------------------------------------------------------------------------
# run
# --------------------------------------------------------------------------------------------------------

def _prefix(vjm: str | None, root: Path) -> tuple[list, dict]:
    """(argv prefix, extra environment) of the --vjm command."""
    if not vjm:
        return [str(root / ".venv" / "bin" / "vjm")], {}
    words, env = shlex.split(vjm), {}
    while words and re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*=.*", words[0]):
        k, _, v = words.pop(0).partition("=")
        env[k] = v
    if not words:
        raise SystemExit(f"--vjm {vjm!r}: no command")
    return words, env


def _run_step(prefix, args, env, cwd, d: Path, step: str, out: Path, timeout: float) -> dict:
    (d / f"{step}.cmd").write_text(" ".join(shlex.quote(a) for a in ["vjm", *args]).replace(str(out), "<OUT>") + "\n")
    argv = [*prefix, *args]
    t0 = time.perf_counter()
    with open(d / f"{step}.stdout", "wb") as so, open(d / f"{step}.stderr", "wb") as se:
        p = subprocess.Popen(argv, cwd=cwd, env=env, stdout=so, stderr=se, stdin=subprocess.DEVNULL)
        deadline = time.monotonic() + timeout
        rc, ru = None, None
        while rc is None:
            pid, status, ru = os.wait4(p.pid, os.WNOHANG)
            if pid:
                rc = os.waitstatus_to_exitcode(status)
                p.returncode = rc
                break
            if time.monotonic() > deadline:
                p.kill()
                _, status, ru = os.wait4(p.pid, 0)
                rc = "timeout"
                break
            time.sleep(0.05)
    wall = time.perf_counter() - t0
    (d / f"{step}.rc").write_text(f"{rc}\n")
    return {"rc": rc, "wall_s": round(wall, 2), "cpu_s": round(ru.ru_utime + ru.ru_stime, 2) if ru else None}


def _run_job(job: Job, prefix, env, cwd, out: Path, timeout: float) -> dict:
    d = out / job.name
    d.mkdir(parents=True, exist_ok=False)
    if job.make:
        job.make(d)
    res = {}
    for step, args in job.steps:
        res[step] = _run_step(prefix, [a.replace("{J}", str(d)) for a in args], env, cwd, d, step, out, timeout)
    return res


def cmd_run(a) -> int:
    root = Path(a.root).resolve()
    out = Path(a.outdir).resolve()
    if out.exists() and any(out.iterdir()):
        raise SystemExit(f"{out}: exists and is not empty")
    out.mkdir(parents=True, exist_ok=True)
    prefix, extra = _prefix(a.vjm, root)
    env = dict(os.environ)
    n = str(a.blas_threads)
    env.update({"OPENBLAS_NUM_THREADS": n, "OMP_NUM_THREADS": n, "MKL_NUM_THREADS": n, "PYTHONHASHSEED": "0",
                "MPLBACKEND": "Agg", "COLUMNS": "120", "NO_COLOR": "1", "TERM": "dumb"})
    env.update(extra)
    js = [j for j in jobs() if not a.only or j.name in a.only]
    if a.only and len(js) != len(a.only):
        raise SystemExit(f"unknown job(s): {sorted(set(a.only) - {j.name for j in js})}")
    print(f"vjm: {' '.join(f'{k}={v}' for k, v in extra.items())} {' '.join(prefix)}; cwd {root}; "
          f"{len(js)} jobs, {a.jobs} at a time", flush=True)
    t0 = time.perf_counter()
    timing = {}
    with cf.ThreadPoolExecutor(max_workers=a.jobs) as ex:
        futs = {ex.submit(_run_job, j, prefix, env, root, out, a.timeout): j for j in js}
        for f in cf.as_completed(futs):
            j = futs[f]
            timing[j.name] = r = f.result()
            line = ", ".join(f"{s} rc={v['rc']} {v['wall_s']:.1f} s wall {v['cpu_s']:.1f} s cpu" for s, v in r.items())
            print(f"{j.name}: {line}", flush=True)
    wall = time.perf_counter() - t0
    cpu = sum(v["cpu_s"] or 0.0 for r in timing.values() for v in r.values())
    timing = {"jobs": {k: timing[k] for k in sorted(timing)}, "total_wall_s": round(wall, 1),
              "total_cpu_s": round(cpu, 1), "vjm": " ".join(prefix), "env": extra, "root": str(root), "outdir": str(out),
              "parallel_jobs": a.jobs,
              "load_average_at_end": os.getloadavg()}
    (out / "timing.json").write_text(json.dumps(timing, indent=1) + "\n")
    print(f"total: {wall:.1f} s wall, {cpu:.1f} s cpu of the children; {out / 'timing.json'}")
    return 0


# --------------------------------------------------------------------------------------------------------
# compare
# --------------------------------------------------------------------------------------------------------

IGNORED_FILES = {"timing.json"}
PRESENCE_ONLY = {".png", ".jpg", ".jpeg", ".svg", ".pdf", ".gif"}
MANIFEST = ".linkfea-outputs.json"
TIMING_KEY = re.compile(r"(?i)^(seconds|time_s|elapsed|elapsed_s|wall_s|cpu_s|timing|timings|duration|duration_s)$")
NUM = re.compile(r"(?<![A-Za-z_0-9.])[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?(?![A-Za-z_0-9])")
MASKS = [  # (pattern, replacement) applied to text on both sides, after the absolute paths
    (re.compile(r"\b\d{4}-\d{2}-\d{2}[T ]\d{2}:\d{2}(?::\d{2}(?:\.\d+)?)?(?:Z|[+-]\d{2}:?\d{2})?"), "<DATE>"),
    (re.compile(r"(?i)\b(in|took|wall|elapsed|time|cpu|after)(\s*[:=]?\s*)[0-9.]+(?:e[-+]?\d+)?\s*(s|ms|sec|seconds|min)\b"),
     r"\1\2<T> \3"),
    (re.compile(r"\b\d+\s*m\s*\d+(?:\.\d+)?\s*s\b"), "<T>"),
    (re.compile(r"\b\d+:\d{2}:\d{2}(?:\.\d+)?\b"), "<T>"),
    (re.compile(r"[0-9.,]+(?:e[-+]?\d+)?(\s*(?:points|rows|poses|evaluations|moves|configurations)\s*/\s*s)\b"), r"<T>\1"),
    (re.compile(r"(\S+\.py):\d+"), r"\1:<L>"),
    (re.compile(r"\bline \d+\b"), "line <L>"),
    (re.compile(r"/(?:tmp|var/tmp)/[^\s\"'<>,;)]*"), "<TMP>"),
    (re.compile(r"\b0x[0-9a-f]{6,}\b"), "0x<ADDR>"),
]


@dataclass
class Result:
    status: str = "same"  # same | roundoff | text | differs
    maxrel: float = 0.0
    where: str = ""
    digits: int = 0
    nearzero: int = 0
    msgs: list = field(default_factory=list)

    def num(self, a: float, b: float, where: str, cfg, digit_unit: float | None = None) -> None:
        if a == b or (math.isnan(a) and math.isnan(b)):
            return
        if math.isinf(a) or math.isinf(b) or math.isnan(a) or math.isnan(b):
            self.fail(f"{where}: {a!r} vs {b!r}")
            return
        d, s = abs(a - b), max(abs(a), abs(b))
        rel = d / s if s else math.inf
        if d <= cfg.atol + cfg.rtol * s:
            if self.status == "same":
                self.status = "roundoff"
            if s <= 100 * cfg.atol:  # noise about zero (1e-15 vs -3e-21): relative size meaningless
                self.nearzero += 1
            elif rel > self.maxrel:
                self.maxrel, self.where = rel, where
            return
        if digit_unit is not None and not cfg.strict_digits and d <= digit_unit * (1 + 1e-9):
            self.digits += 1
            if self.status == "same":
                self.status = "roundoff"
            return
        self.fail(f"{where}: {a!r} vs {b!r} (rel {rel:.2g})")

    def fail(self, msg: str) -> None:
        self.status = "differs"
        self.msgs.append(msg)

    def text(self, msg: str) -> None:
        if self.status != "differs":
            self.status = "text"
        self.msgs.append(msg)


def _run_meta(d: Path, key: str) -> str | None:
    try:
        return json.loads((d / "timing.json").read_text())[key]
    except (OSError, ValueError, KeyError):
        return None


class Normalizer:
    def __init__(self, root: Path, other: Path):
        subs = [(str(root), "<OUT>"), (str(other), "<OUT>")]
        for d in (root, other):  # the checkout each run's jobs ran in (error messages print absolute data paths)
            r, o = _run_meta(d, "root"), _run_meta(d, "outdir")  # and the folder it wrote to (if moved since)
            if r:
                subs += [(r + "/src", "<SRC>"), (r, "<ROOT>")]
            if o:
                subs.append((o, "<OUT>"))
        for src in ("/work/main/src", "/work/base/src", str(ROOT / "src")):
            subs.append((src, "<SRC>"))
        self.subs = sorted(set(subs), key=lambda s: -len(s[0]))

    def __call__(self, s: str) -> str:
        for old, new in self.subs:
            s = s.replace(old, new)
        for pat, rep in MASKS:
            s = pat.sub(rep, s)
        return s


def _digit_unit(tok: str) -> float | None:
    """One unit of the last printed digit of a float token ("0.440" -> 1e-3, "1.5e-238" -> 1e-239); None for
    an integer token."""
    m = re.fullmatch(r"[-+]?(\d*)(?:\.(\d*))?(?:[eE]([-+]?\d+))?", tok)
    if not m or (m.group(2) is None and m.group(3) is None):
        return None
    return 10.0 ** (-len(m.group(2) or "") + int(m.group(3) or 0))


def _cmp_line(a: str, b: str, where: str, res: Result, cfg) -> None:
    ta, tb = NUM.split(a), NUM.split(b)
    na, nb = NUM.findall(a), NUM.findall(b)
    if ta != tb or len(na) != len(nb):
        res.text(f"{where}: {a.strip()[:150]!r} vs {b.strip()[:150]!r}")
        # still compare the numbers when they line up
        if len(na) != len(nb):
            return
    for i, (x, y) in enumerate(zip(na, nb)):
        if x == y:
            continue
        ux, uy = _digit_unit(x), _digit_unit(y)
        unit = max(ux, uy) if ux is not None and uy is not None else None
        res.num(float(x), float(y), f"{where} #{i + 1}", cfg, unit)


def _cmp_text(a: str, b: str, res: Result, cfg, norm) -> None:
    la, lb = norm(a).splitlines(), norm(b).splitlines()
    if len(la) != len(lb):
        diff = [d for d in difflib.unified_diff(la, lb, lineterm="", n=0) if not d.startswith(("---", "+++"))][:4]
        res.text(f"{len(la)} vs {len(lb)} lines: " + " | ".join(x[:150] for x in diff))
        m = difflib.SequenceMatcher(None, la, lb, autojunk=False)
        for tag, i1, i2, j1, j2 in m.get_opcodes():
            if tag == "replace" and i2 - i1 == j2 - j1:
                for k in range(i2 - i1):
                    _cmp_line(la[i1 + k], lb[j1 + k], f"line {i1 + k + 1}", res, cfg)
        return
    for i, (x, y) in enumerate(zip(la, lb)):
        if x != y:
            _cmp_line(x, y, f"line {i + 1}", res, cfg)


def _cmp_json(a, b, path: str, res: Result, cfg, norm, manifest: bool = False) -> None:
    if isinstance(a, bool) or isinstance(b, bool):
        if a != b:
            res.fail(f"{path}: {a!r} vs {b!r}")
    elif isinstance(a, (int, float)) and isinstance(b, (int, float)):
        res.num(float(a), float(b), path, cfg)
    elif isinstance(a, dict) and isinstance(b, dict):
        ka, kb = set(a), set(b)
        if ka != kb:
            res.fail(f"{path}: keys only in A {sorted(ka - kb)[:5]}, only in B {sorted(kb - ka)[:5]}")
        for k in a:
            if k not in b or TIMING_KEY.match(str(k)):
                continue
            if manifest and (k in ("run", "written") or path.endswith("/files")):
                continue
            _cmp_json(a[k], b[k], f"{path}/{k}", res, cfg, norm, manifest)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            res.fail(f"{path}: length {len(a)} vs {len(b)}")
        for i, (x, y) in enumerate(zip(a, b)):
            _cmp_json(x, y, f"{path}[{i}]", res, cfg, norm, manifest)
    elif isinstance(a, str) and isinstance(b, str):
        if a != b:
            x, y = norm(a), norm(b)
            if x != y:
                _cmp_line(x, y, path, res, cfg)
    elif a is None and b is None:
        pass
    else:
        res.fail(f"{path}: {type(a).__name__} {str(a)[:60]!r} vs {type(b).__name__} {str(b)[:60]!r}")


def _cmp_npz(pa: Path, pb: Path, res: Result, cfg) -> None:
    import numpy as np
    with np.load(pa, allow_pickle=False) as A, np.load(pb, allow_pickle=False) as B:
        if set(A.files) != set(B.files):
            res.fail(f"arrays {sorted(A.files)} vs {sorted(B.files)}")
        for k in sorted(set(A.files) & set(B.files)):
            x, y = A[k], B[k]
            if x.shape != y.shape or x.dtype != y.dtype:
                res.fail(f"{k}: {x.dtype}{x.shape} vs {y.dtype}{y.shape}")
                continue
            if x.dtype.kind not in "fciub":
                if not np.array_equal(x, y):
                    res.fail(f"{k}: arrays differ")
                continue
            x, y = x.astype(complex if x.dtype.kind == "c" else float).ravel(), y.astype(
                complex if y.dtype.kind == "c" else float).ravel()
            both_nan = np.isnan(x) & np.isnan(y)
            neq = (x != y) & ~both_nan
            if not neq.any():
                continue
            d, s = np.abs(x - y), np.maximum(np.abs(x), np.abs(y))
            bad = neq & ~(d <= cfg.atol + cfg.rtol * s)
            with np.errstate(divide="ignore", invalid="ignore"):
                rel = np.where(neq, d / s, 0.0)
            i = int(np.nanargmax(rel))
            if bad.any():
                j = int(np.flatnonzero(bad)[0])
                res.fail(f"{k}[{j}]: {x[j]!r} vs {y[j]!r} ({int(bad.sum())} values beyond tolerance, max rel "
                         f"{np.nanmax(rel):.2g})")
            else:
                res.num(float(x[i].real), float(y[i].real), f"{k}[{i}]", cfg) if x.dtype.kind != "c" else None
                if res.status == "same":
                    res.status = "roundoff"


def _load_json(p: Path):
    try:
        t = p.read_text(encoding="utf-8")
    except (UnicodeDecodeError, OSError):
        return None
    s = t.lstrip()
    if not s or s[0] not in "[{":
        return None
    try:
        return json.loads(t)
    except json.JSONDecodeError:
        return None


def compare_file(pa: Path, pb: Path, cfg, norm) -> Result:
    res = Result()
    ext = pa.suffix.lower()
    if ext in PRESENCE_ONLY:
        return res
    if ext == ".npz":
        _cmp_npz(pa, pb, res, cfg)
        return res
    ja, jb = _load_json(pa), _load_json(pb)
    if ja is not None and jb is not None:
        _cmp_json(ja, jb, "", res, cfg, norm, manifest=pa.name == MANIFEST)
        return res
    ba, bb = pa.read_bytes(), pb.read_bytes()
    if ba == bb:
        return res
    try:
        ta, tb = ba.decode("utf-8"), bb.decode("utf-8")
    except UnicodeDecodeError:
        res.fail("binary files differ")
        return res
    _cmp_text(ta, tb, res, cfg, norm)
    return res


def _files(d: Path) -> dict:
    out = {}
    for p in sorted(d.rglob("*")):
        if p.is_file() and not p.is_symlink():
            rel = p.relative_to(d).as_posix()
            if rel not in IGNORED_FILES:
                out[rel] = p
    return out


def _renamed(rel: str, table: dict) -> str:
    parts = rel.split("/")
    job, inner = parts[0], "/".join(parts[1:])
    if inner in table:
        return f"{job}/{table[inner]}"
    if parts[-1] in table:
        return "/".join(parts[:-1] + [table[parts[-1]]])
    return rel


def cmd_compare(a) -> int:
    da, db = Path(a.dir_a).resolve(), Path(a.dir_b).resolve()
    table = dict(r.split("=", 1) for r in a.rename)
    fa, fb = _files(da), _files(db)
    norm = Normalizer(da, db)
    pairs, seen_b = [], set()
    for rel in fa:
        relb = _renamed(rel, table)
        pairs.append((rel, relb))
        seen_b.add(relb)
    bad = 0
    counts = {"same": 0, "roundoff": 0, "text": 0, "differs": 0, "missing": 0}
    for rel, relb in pairs:
        name = rel if rel == relb else f"{rel} -> {relb}"
        if relb not in fb:
            print(f"{name}: MISSING in B")
            bad += 1
            counts["missing"] += 1
            continue
        try:
            r = compare_file(fa[rel], fb[relb], a, norm)
        except Exception as e:  # a file that cannot be read as its kind
            r = Result()
            r.fail(f"{type(e).__name__}: {e}")
        counts[r.status] += 1
        if r.status == "same":
            print(f"{name}: same")
        elif r.status == "roundoff":
            extra = f"; last printed digit flipped in {r.digits} tokens" if r.digits else ""
            extra += f"; {r.nearzero} values within atol of zero differ" if r.nearzero else ""
            mr = f"max rel {r.maxrel:.2g} at {r.where}" if r.maxrel else "within tolerance"
            print(f"{name}: round-off ({mr}{extra})")
        elif r.status == "text" and a.text_ok:
            print(f"{name}: text differs (numbers agree): {'; '.join(r.msgs[:3])}")
        else:
            bad += 1
            print(f"{name}: DIFFERS: {'; '.join(r.msgs[:4])}" + (f" (+{len(r.msgs) - 4} more)" if len(r.msgs) > 4 else ""))
    for rel in fb:
        if rel not in seen_b:
            print(f"{rel}: MISSING in A")
            bad += 1
            counts["missing"] += 1
    print(f"{len(pairs)} files of A: " + ", ".join(f"{v} {k}" for k, v in counts.items()) + f"; {bad} bad")
    return 1 if bad else 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run", help="run the reference jobs into OUTDIR/<job>/")
    r.add_argument("outdir")
    r.add_argument("--vjm", default=None, help="command prefix running the CLI (default <root>/.venv/bin/vjm)")
    r.add_argument("--root", default=str(ROOT), help="working directory of the jobs (data/ relative to it)")
    r.add_argument("--jobs", type=int, default=2, help="jobs run at a time [2]")
    r.add_argument("--blas-threads", type=int, default=1)
    r.add_argument("--timeout", type=float, default=1800.0, help="seconds per step")
    r.add_argument("--only", nargs="*", default=None, help="job names (default: all)")
    r.add_argument("--list", action="store_true", help="list the jobs and exit")
    c = sub.add_parser("compare", help="compare two run folders file by file")
    c.add_argument("dir_a")
    c.add_argument("dir_b")
    c.add_argument("--rtol", type=float, default=1e-9)
    c.add_argument("--atol", type=float, default=1e-12)
    c.add_argument("--rename", action="append", default=[], metavar="OLD=NEW")
    c.add_argument("--text-ok", action="store_true", help="text-only differences do not fail")
    c.add_argument("--strict-digits", action="store_true", help="a flipped last printed digit in text fails")
    a = ap.parse_args(argv)
    if a.cmd == "run":
        if a.list:
            for j in jobs():
                print(f"{j.name}: " + "; ".join(f"{s}: vjm {' '.join(x)}" for s, x in j.steps)
                      + (f"  [{j.notes}]" if j.notes else ""))
            return 0
        return cmd_run(a)
    return cmd_compare(a)


if __name__ == "__main__":
    sys.exit(main())
