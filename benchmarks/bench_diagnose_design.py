"""Benchmark: how small a design `vjm diagnose` names each library effect on, and how many
``--suggest`` rounds resolve what a design leaves open.

Data come from tests/truth.py (nothing from vjm.discrepancy): random postures of the Q1-Q2
cube, loads in opposite pairs (forces, moments and both, magnitudes 0.2-1 x 100 N / 5000 N mm),
noise 1 um / 10 urad with sigma columns.

* **Smallest design** (``--only designs``): for each seen library effect of the 3-PUU at its
  test size (tests/truth.py ``LIBRARY``), designs of increasing size (postures x loads per
  posture, :data:`LADDER`), ``--reps`` independent sets each.  Each set's outcome: *alone* (verdict
  ``explained``, the effect named and nothing else), *group* (``explained``, named at group
  level: tests/truth.py ``names_exactly``), *insufficient* (verdict ``insufficient_data``),
  *nothing* (``no_discrepancy``), *unexplained*, or *wrong* (``explained`` with a name that
  neither is the effect nor stands for a group holding it: the failure the verdict must avoid).
  The smallest design is the first of the ladder from which on every design run named the effect
  alone in every set (the ladder stops after two such designs in a row).
* **Suggest rounds** (``--only rounds``): the power benchmark's sets
  (benchmarks/bench_diagnose_false_alarm.py: 24 postures x 12 loads, each effect at the size
  where its signature adds a chi-square of 100, seeds 30000 + set), and weak designs
  (``--weak P:L``); a round is: diagnose with ``--suggest N``, measure the suggested rows on
  the true machine, diagnose the union.  Rounds are counted until the effect is named alone
  (at most ``--max-rounds``).

* **Two load levels** (``--only levels``): ``--level-sets`` sets of 12 postures x 6 force
  directions at 50 and 100 N (tests/truth.py ``level_design``), clean, with softening actuators
  (out of the library) and with a softer leg in extension (linear): verdicts and how often the
  load-level test fires.

Run (CPU-heavy: nice it):

    PYTHONPATH=src nice -n 10 .venv/bin/python benchmarks/bench_diagnose_design.py \
        [--only designs|rounds] [--reps 2] [--effect NAME ...] [--suggest 24] [--weak 3:4] [--json out.json]
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "src"))
sys.path.append(os.path.join(os.path.dirname(HERE), "tests"))
sys.path.append(HERE)
import bench_diagnose_false_alarm as fa  # noqa: E402
import truth as tr  # noqa: E402

from vjm.discrepancy.workflow import diagnose  # noqa: E402

ALPHA = 0.01
#: designs (postures, loads per posture), by number of rows
LADDER = ((1, 2), (1, 6), (2, 4), (3, 4), (4, 6), (6, 6), (6, 12), (12, 12), (24, 12))


def outcome(rep, name) -> str:
    v = rep["verdict"]
    if v != "explained":
        return {"insufficient_data": "insufficient", "no_discrepancy": "nothing"}.get(v, v)
    if list(rep["named_effects"]) == [name]:
        return "alone"
    return "group" if tr.names_exactly(rep, [name]) else "wrong"


def run(model, data, work, suggest=0):
    mp = tr.write_model(model, os.path.join(work, "model.yaml"))
    dp = data.write(os.path.join(work, "data.csv"))
    dg = diagnose(mp, dp, alpha=ALPHA, suggest=suggest)
    return dg.report, dg.next_measurements


def smallest(rows) -> list | None:
    """[postures, loads] of the first design from which on every design run named the effect alone in
    every set (None: the last one run did not)."""
    first = None
    for x in rows:
        ok = all(s["outcome"] == "alone" for s in x["sets"])
        first = (first or [x["postures"], x["loads"]]) if ok else None
    return first


def designs(names, reps, log=print) -> dict:
    out = {}
    with tempfile.TemporaryDirectory() as work:
        for name in names:
            given, truth = tr.hide(name)
            rows = []
            for k, (npo, nl) in enumerate(LADDER):
                res = []
                for r in range(reps):
                    P, W = tr.design(npo, nl, seed=60_000 + 100 * k + r)
                    rep, _ = run(given, tr.measure(truth, P, W, seed=61_000 + 100 * k + r), work)
                    res.append({"outcome": outcome(rep, name), "named": rep["named_effects"]})
                rows.append({"postures": npo, "loads": nl, "sets": res})
                log(f"  {name} {npo} x {nl}: " + ", ".join(f"{x['outcome']} {x['named']}" for x in res), flush=True)
                if all(x["outcome"] == "alone" for x in res) and len(rows) >= 2 and \
                        all(x["outcome"] == "alone" for x in rows[-2]["sets"]):
                    break  # named alone on two designs in a row: the larger ones are not run
            out[name] = {"ladder": rows, "smallest": smallest(rows)}
    return out


def rounds_from(name, given, truth, P, W, seed, n_suggest, max_rounds, work) -> dict:
    data = tr.measure(truth, P, W, seed=seed)
    hist = []
    for rnd in range(max_rounds + 1):
        rep, rows = run(given, data, work, suggest=n_suggest if rnd < max_rounds else 0)
        o = outcome(rep, name)
        sg = rep.get("suggest") or {}
        hist.append({"outcome": o, "named": rep["named_effects"], "rows": int(len(data.P)),
                     "rows_to_separate": sg.get("rows_to_separate")})
        if o == "alone" or rows is None:
            break
        data = data + tr.measure(truth, rows[:, :3], rows[:, 3:], seed=seed + 1 + rnd)
    done = hist[-1]["outcome"] == "alone"
    return {"rounds": len(hist) - 1 if done else None, "history": hist}


def rounds(names, reps, n_suggest, max_rounds, weak, log=print) -> dict:
    out = {}
    with tempfile.TemporaryDirectory() as work:
        for name in names:
            h = tr.LIBRARY[name]
            lam0 = fa.noncentrality(*fa._case(name, h.size, 24, 12, 30_000))
            p = 4.0 if name == "geometric_nonlinearity" else 2.0
            s0 = h.size * (fa.START_CHI2 / lam0) ** (1.0 / p)
            res = {"power": [], "weak": []}
            for r in range(reps):
                given, truth, P, W = fa._case(name, s0, 24, 12, 30_000 + r)
                res["power"].append(rounds_from(name, given, truth, P, W, 30_007 + r, n_suggest, max_rounds, work))
                if weak:
                    given, truth = tr.hide(name)
                    P, W = tr.design(*weak, seed=62_000 + r)
                    res["weak"].append(rounds_from(name, given, truth, P, W, 63_000 + r, n_suggest, max_rounds, work))
            out[name] = res
            log(f"  {name}: power sets " + ", ".join(str(x["rounds"]) for x in res["power"]) + "; weak "
                + ", ".join(str(x["rounds"]) for x in res["weak"]) + " rounds", flush=True)
    return out


def levels(n_sets, log=print) -> dict:
    """Data at two load levels (12 postures x 6 force directions at 50 and 100 N, translations only):
    verdicts and the load-level test on clean sets, on softening actuators (out of the library) and
    on a softer leg in extension (linear, in the library)."""
    cases = {"clean": (tr.NOMINAL, tr.Truth(tr.variant(tr.NOMINAL))),
             "softening 2e-7 mm/N^2": (tr.NOMINAL, tr.Truth(tr.variant(tr.NOMINAL), softening=2e-7)),
             "leg_axial": tr.hide("leg_axial")}
    out = {}
    with tempfile.TemporaryDirectory() as work:
        for key, (given, truth) in cases.items():
            res = []
            for r in range(n_sets):
                P, W = tr.level_design(12, 6, seed=64_000 + r, forces_only=True)
                rep, _ = run(given, tr.measure(truth, P, W, seed=65_000 + r, sigma_r=None), work)
                lv = rep["lack_of_fit"]["load_levels"]
                res.append({"verdict": rep["verdict"], "named": rep["named_effects"], "level_p": lv["p_value"],
                            "level_significant": lv["significant"], "lof_p": rep["lack_of_fit"]["p_value"]})
            out[key] = res
            log(f"  {key}: " + ", ".join(f"{x['verdict']} {x['named']} {x['level_p']:.2g}" for x in res), flush=True)
    return out


def markdown(ds, rs, meta, lv=None) -> str:
    lines = []
    if lv:
        lines += ["| two load levels (50, 100 N) | sets | verdicts | load-level test significant | "
                  "overall lack of fit significant |", "| --- | --- | --- | --- | --- |"]
        for key, res in lv.items():
            vs = {v: sum(x["verdict"] == v for x in res) for v in sorted({x["verdict"] for x in res})}
            lines.append(f"| {key} | {len(res)} | {vs} | {sum(x['level_significant'] for x in res)} | "
                         f"{sum(x['lof_p'] is not None and x['lof_p'] < 0.01 / 25 for x in res)} (p < 4e-4) |")
        lines.append("")
    if ds:
        lines += ["| effect | smallest design named alone (postures x loads) | outcomes per design "
                  "(alone / group / insufficient / nothing / unexplained / wrong) |", "| --- | --- | --- |"]
        for name, r in ds.items():
            sm = "not on the ladder" if r["smallest"] is None else f"{r['smallest'][0]} x {r['smallest'][1]}"
            cells = []
            for x in r["ladder"]:
                c = {k: sum(s["outcome"] == k for s in x["sets"]) for k in
                     ("alone", "group", "insufficient", "nothing", "unexplained", "wrong")}
                cells.append(f"{x['postures']}x{x['loads']}: " + "/".join(str(v) for v in c.values()))
            lines.append(f"| `{name}` | {sm} | {'; '.join(cells)} |")
        wrong = sum(s["outcome"] == "wrong" for r in ds.values() for x in r["ladder"] for s in x["sets"])
        total = sum(len(x["sets"]) for r in ds.values() for x in r["ladder"])
        lines += ["", f"Wrong names (verdict explained, a name that is not the effect's nor a group's holding it): "
                      f"{wrong}/{total} sets.", ""]
    if rs:
        lines += ["| effect | rounds, power sets | rounds, weak design | rows to separate (first round) |",
                  "| --- | --- | --- | --- |"]
        for name, r in rs.items():
            def fmt(xs):
                return ", ".join("-" if x["rounds"] is None else str(x["rounds"]) for x in xs) or "-"
            sep = [x["history"][0]["rows_to_separate"] for k in ("power", "weak") for x in r[k]]
            lines.append(f"| `{name}` | {fmt(r['power'])} | {fmt(r['weak'])} | "
                         f"{', '.join('-' if v is None else str(v) for v in sep)} |")
    lines.append(f"\n{meta}")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--only", choices=("designs", "rounds", "levels"))
    ap.add_argument("--level-sets", type=int, default=20)
    ap.add_argument("--reps", type=int, default=2)
    ap.add_argument("--effect", action="append")
    ap.add_argument("--suggest", type=int, default=24, help="rows suggested per round")
    ap.add_argument("--max-rounds", type=int, default=4)
    ap.add_argument("--weak", default="3:4", help="weak starting design P:L for the rounds ('' for none)")
    ap.add_argument("--json")
    ap.add_argument("--merge", nargs="+", help="print the tables of earlier --json results")
    a = ap.parse_args(argv)
    if a.merge:
        parts = []
        for path in a.merge:
            with open(path, encoding="utf-8") as fh:
                parts.append(json.load(fh))
        ds = {k: {**v, "smallest": smallest(v["ladder"])} for p in parts for k, v in (p.get("designs") or {}).items()}
        rs = {k: v for p in parts for k, v in (p.get("rounds") or {}).items()}
        lv = {k: v for p in parts for k, v in (p.get("levels") or {}).items()}
        print(markdown(ds or None, rs or None, "; ".join(p["meta"] for p in parts), lv or None))
        return
    names = a.effect or [n for n, h in tr.LIBRARY.items() if h.seen and h.machine == "puu"]
    weak = tuple(int(x) for x in a.weak.split(":")) if a.weak else None
    t0 = time.perf_counter()
    ds = designs(names, a.reps) if a.only in (None, "designs") else None
    rs = rounds(names, a.reps, a.suggest, a.max_rounds, weak) if a.only in (None, "rounds") else None
    lv = levels(a.level_sets) if a.only in (None, "levels") else None
    meta = (f"{a.reps} sets per cell, noise 1 um / 10 urad, alpha {ALPHA}, --suggest {a.suggest}; wall "
            f"{time.perf_counter() - t0:.0f} s, load average {os.getloadavg()[0]:.1f}")
    print(markdown(ds, rs, meta, lv))
    if a.json:
        with open(a.json, "w", encoding="utf-8") as fh:
            json.dump({"designs": ds, "rounds": rs, "levels": lv, "meta": meta}, fh, indent=1)


if __name__ == "__main__":
    main()
