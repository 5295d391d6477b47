"""Benchmark: the outlier breakdown of `vjm diagnose` (gross errors in the rows, stages/outliers.py).

Each set comes from tests/truth.py (nothing from vjm.discrepancy): a hidden 3 um actuator
clearance on the 3-PUU, its own random postures of the Q1-Q2 cube and loads (``--postures`` x
``--loads``), its own 1 um / 10 urad noise (sigma columns given), then ``truth.with_outliers``: a
fraction of the rows, each with one measured component off by 20-60 sigma (random sign).  Every set
is diagnosed with the outlier stage (default) and without it (``outliers=False``, every row used
as it is: the stage's first pass, so both come from one run).  A set succeeds when the clearance alone is named (``truth.names_exactly``) with
verdict ``explained``.  Rates come with their Clopper-Pearson 95 % intervals; the rows set aside are
compared with the corrupted ones; CPU seconds per set (process time: the plain diagnosis, and the
whole with the outlier stage).

Run (CPU-heavy: nice it):

    PYTHONPATH=src nice -n 10 .venv/bin/python benchmarks/bench_diagnose_outliers.py \
        [--sets 20] [--fractions 0.01 0.03 0.05 0.10] [--postures 12] [--loads 12] [--json out.json]

and copy the printed Markdown table into docs/benchmarks.md.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from collections import Counter

import numpy as np
from scipy.stats import beta

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tests"))
import truth as tr

ALPHA = 0.01


def clopper_pearson(k: int, n: int, conf: float = 0.95) -> tuple[float, float]:
    a = 1.0 - conf
    lo = 0.0 if k == 0 else beta.ppf(a / 2, k, n - k + 1)
    hi = 1.0 if k == n else beta.ppf(1 - a / 2, k + 1, n - k)
    return float(lo), float(hi)


def diagnose_both(model_path: str, data_path: str) -> tuple:
    """(report without the outlier stage, CPU s; report with it, CPU s) from one diagnosis: the plain
    diagnosis is the outlier stage's first pass (``vjm.diagnose(..., outliers=False)`` returns exactly it;
    tests/discrepancy/test_diagnose_outliers.py), so the two are measured side by side at the cost of one."""
    from vjm.discrepancy.data import read_csv
    from vjm.discrepancy.stages.record import assemble
    from vjm.discrepancy.workflow import run_stages, set_aside
    from vjm.modelio.read import load_model

    model, data = load_model(model_path), read_csv(data_path)

    def run(rows):
        return run_stages(model, rows, ALPHA, None, 5, 3, None)

    def report(p, found):
        return assemble(p, found, None, model_name="model.yaml", alpha=ALPHA, folds=5)

    t = time.process_time()
    first = run(data)
    cpu_off = time.process_time() - t
    p, found = set_aside(first, run, first.s.weights.sigma_known)
    rep = report(p, found)
    return report(first, None), cpu_off, rep, time.process_time() - t


def one_set(i: int, frac: float, args, work: str) -> dict:
    given, truth = tr.hide(("clearance", 3e-3))
    P, W = tr.design(args.postures, args.loads, seed=10_000 + i)
    clean = tr.measure(truth, P, W, seed=20_000 + i)
    m, rows = tr.with_outliers(clean, frac, np.random.default_rng(30_000 + i))
    mp = tr.write_model(given, os.path.join(work, "model.yaml"))
    dp = m.write(os.path.join(work, "data.csv"))
    out = {"corrupted": (rows + 2).tolist()}
    off, cpu_off, on, cpu_on = diagnose_both(mp, dp)
    for tag, rep, cpu in (("on", on, cpu_on), ("off", off, cpu_off)):
        out[tag] = {"verdict": rep.verdict, "named": list(rep.named_effects), "cpu": cpu,
                    "ok": rep.verdict == "explained" and tr.names_exactly(rep.to_dict(), ["clearance"]),
                    "aside": list((rep.outliers or {}).get("rows", []))}
    return out


def rate(k, n) -> str:
    lo, hi = clopper_pearson(k, n)
    return f"{k}/{n} ({100 * lo:.0f}-{100 * hi:.0f} %)"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sets", type=int, default=20)
    ap.add_argument("--fractions", type=float, nargs="+", default=[0.01, 0.03, 0.05, 0.10])
    ap.add_argument("--postures", type=int, default=12)
    ap.add_argument("--loads", type=int, default=12)
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    results = {}
    with tempfile.TemporaryDirectory() as work:
        for frac in args.fractions:
            res = []
            for i in range(args.sets):
                r = one_set(i, frac, args, work)
                res.append(r)
                print(f"{frac:.2f} set {i}: on {r['on']['verdict']} {r['on']['named']} ({r['on']['cpu']:.1f} s) "
                      f"aside {len(r['on']['aside'])}/{len(r['corrupted'])} exact "
                      f"{r['on']['aside'] == r['corrupted']}; off {r['off']['verdict']} {r['off']['named']} "
                      f"({r['off']['cpu']:.1f} s)", file=sys.stderr, flush=True)
            results[frac] = res
    n_rows = args.postures * args.loads
    print(f"\n{args.sets} sets per fraction, {args.postures} postures x {args.loads} loads ({n_rows} rows), "
          "hidden clearance 3 um, outliers 20-60 sigma on one component\n")
    print("| outliers | rows | clearance alone, `explained`: outlier stage on | off (today) | "
          "set aside = corrupted rows | all corrupted set aside | verdicts (on) | verdicts (off) | "
          "CPU per set on / off |")
    print("|---|---|---|---|---|---|---|---|---|")
    for frac, res in results.items():
        n = len(res)
        k_on = sum(r["on"]["ok"] for r in res)
        k_off = sum(r["off"]["ok"] for r in res)
        exact = sum(r["on"]["aside"] == r["corrupted"] for r in res)
        allin = sum(set(r["corrupted"]) <= set(r["on"]["aside"]) for r in res)
        v_on = ", ".join(f"{v} {c}" for v, c in Counter(r["on"]["verdict"] for r in res).most_common())
        v_off = ", ".join(f"{v} {c}" for v, c in Counter(r["off"]["verdict"] for r in res).most_common())
        cpu_on = np.mean([r["on"]["cpu"] for r in res])
        cpu_off = np.mean([r["off"]["cpu"] for r in res])
        print(f"| {100 * frac:.0f} % | {len(res[0]['corrupted'])} | **{rate(k_on, n)}** | {rate(k_off, n)} | "
              f"{exact}/{n} | {allin}/{n} | {v_on} | {v_off} | {cpu_on:.1f} s / {cpu_off:.1f} s |")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump({str(k): v for k, v in results.items()}, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
