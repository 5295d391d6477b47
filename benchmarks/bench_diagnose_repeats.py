"""Benchmark: the diagnosis checks of the test suite, repeated over noise draws, as rates.

The tests hold one representative noise draw per case; this script runs the same checks over
many draws and reports how often they hold, with Clopper-Pearson 95 % intervals:

* ``clean``: tests/discrepancy/test_discrepancy_workflow.py's clean data (the 3-PUU with a rigid foot,
  30 random postures x 6 axis loads of 100 N, 1 um noise, simulated by vjm.discrepancy) over
  ``--seeds`` draws from seed 100: how many name an effect (a false alarm).  At alpha = 0.01
  family-wise per round, about 1 % are expected.
* ``effects``: tests/discrepancy/test_discrepancy_effects.py's ``check_hidden_effect`` (each effect of
  ``TRUTH`` hidden: named alone, verdict explained, every parameter within 3 standard errors,
  reduced chi2 <= 1.5, RMS reduced) over ``--seeds`` draws from seed 0, per effect.  The 3-se
  check alone fails in 0.27 % of draws per parameter by design.

Independent-truth false alarms and power: benchmarks/bench_diagnose_false_alarm.py.  Run
(CPU-heavy: nice it):

    PYTHONPATH=src nice .venv/bin/python benchmarks/bench_diagnose_repeats.py \
        [--only clean|effects] [--seeds 20] [--effect NAME ...]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
TESTS = os.path.join(os.path.dirname(HERE), "tests")
sys.path[:0] = [TESTS, HERE, *(os.path.join(TESTS, d) for d in ("discrepancy", "vjm", "linkfea"))]

from bench_diagnose_false_alarm import clopper_pearson  # noqa: E402


def clean(seeds: int) -> dict:
    import test_discrepancy_workflow as tw

    from vjm.discrepancy.simulate import simulate
    from vjm.discrepancy.workflow import diagnose

    named = []
    for seed in range(100, 100 + seeds):
        rep = diagnose(tw.MODEL, simulate(tw.MODEL, [], tw.P, tw.W, tw.NOISE, None, seed)).report
        named.append(rep["named_effects"])
        print(f"  clean seed {seed}: named {rep['named_effects']}, verdict {rep['verdict']}", flush=True)
    k = sum(bool(n) for n in named)
    return {"sets": seeds, "alarms": k, "ci95": clopper_pearson(k, seeds)}


def effects(seeds: int, names=None) -> dict:
    import test_discrepancy_effects as te

    out = {}
    for name in names or sorted(te.TRUTH):
        fails = []
        for seed in range(seeds):
            try:
                te.check_hidden_effect(name, seed)
            except AssertionError as exc:
                fails.append((seed, str(exc)[:200]))
        out[name] = {"draws": seeds, "failed": fails, "ci95_pass": clopper_pearson(seeds - len(fails), seeds)}
        print(f"  {name}: {seeds - len(fails)}/{seeds} draws pass every check {[s for s, _ in fails]}", flush=True)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", choices=("clean", "effects"))
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--effect", nargs="*")
    a = ap.parse_args(argv)
    t0 = time.process_time()
    if a.only in (None, "clean"):
        r = clean(a.seeds)
        lo, hi = r["ci95"]
        print(f"| clean sets named something | {r['alarms']}/{r['sets']} (95 % {100 * lo:.1f}-{100 * hi:.1f} %) |")
    if a.only in (None, "effects"):
        for name, r in effects(a.seeds, a.effect).items():
            lo, hi = r["ci95_pass"]
            print(f"| {name} | {r['draws'] - len(r['failed'])}/{r['draws']} pass (95 % {100 * lo:.0f}-{100 * hi:.0f} %) |")
    print(f"CPU {time.process_time() - t0:.0f} s, load average {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
