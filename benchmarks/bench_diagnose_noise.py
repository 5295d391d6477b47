"""Benchmark: `vjm diagnose` with sigmas estimated (no sigma columns) on independent-truth data.

Data come from tests/truth.py (nothing from vjm.discrepancy): 16 random postures x 12 loads per
set (the 3-PRPaR's bar effects: its moments up to 20 N m, as its acceptance design), noise
1 um / 10 urad, the file without ``sigma_t``/``sigma_r`` columns.

* ``clean``: false alarms on clean sets of the model given (puu.yaml): any verdict other than
  ``no_discrepancy``, seeds 50000 + set.
* ``hidden``: one library effect hidden per set (tests/truth.py ``LIBRARY`` entries with
  ``seen=True``, at their sizes), cycling through them set by set (set s hides the (s mod m)-th),
  seeds 60000 + set.  An *extra* effect is a named effect that is neither the hidden one nor in a
  confounded group with it; *missed*: the hidden effect not accounted for (tests/truth.py
  ``accounts_for``).

Run (CPU-heavy: nice it; split over processes with --first; ``--src`` diagnoses with another
source tree, e.g. an earlier commit's, side by side):

    nice -n 10 .venv/bin/python benchmarks/bench_diagnose_noise.py --case clean|hidden \\
        --sets 100 --first 0 --json out.json [--src /path/to/other/src]
    .venv/bin/python benchmarks/bench_diagnose_noise.py --merge a.json b.json ...

and copy the printed Markdown into docs/benchmarks.md and docs/discrepancy.md.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _paths(src):
    sys.path.insert(0, src or os.path.join(ROOT, "src"))
    sys.path.append(os.path.join(ROOT, "tests"))


def one_set(case: str, s: int, work: str) -> dict:
    import truth as tr

    from vjm.discrepancy.workflow import diagnose

    if case == "clean":
        given, truth, name = tr.NOMINAL, tr.Truth(tr.variant(tr.NOMINAL)), None
        P, W = tr.design(16, 12, seed=50_000 + s)
    else:
        seen = [n for n, h in tr.LIBRARY.items() if h.seen]
        name = seen[s % len(seen)]
        given, truth = tr.hide(name)
        kw = {"moment": tr.DESIGNS["prpar"]["moment"]} if tr.LIBRARY[name].machine == "prpar" else {}
        P, W = tr.design(16, 12, seed=60_000 + s, **kw)
    mp = tr.write_model(given, os.path.join(work, "model.yaml"))
    dp = tr.measure(truth, P, W, seed=70_000 + s, known_sigmas=False).write(os.path.join(work, "data.csv"))
    t0 = time.process_time()
    rep = diagnose(mp, dp, alpha=0.01).report
    named = list(rep["named_effects"])
    out = {"set": s, "hidden": name, "verdict": rep["verdict"], "named": named, "confounded": rep["confounded"],
           "cpu_s": time.process_time() - t0}
    if name is None:
        out["alarm"] = rep["verdict"] != "no_discrepancy"
    else:
        out["extra"] = [n for n in named if n != name and not any(n in g and name in g for g in rep["confounded"])]
        out["missed"] = not tr.accounts_for(dict(rep), name)
    return out


def summarise(rows: list) -> dict:
    clean = [r for r in rows if r["hidden"] is None]
    hid = [r for r in rows if r["hidden"] is not None]
    per: dict = {}
    for r in hid:
        e = per.setdefault(r["hidden"], {"sets": 0, "extra": 0, "missed": 0, "extra_names": {}})
        e["sets"] += 1
        e["extra"] += bool(r["extra"])
        e["missed"] += bool(r["missed"])
        for n in r["extra"]:
            e["extra_names"][n] = e["extra_names"].get(n, 0) + 1
    return {"clean": {"sets": len(clean), "alarms": sum(r["alarm"] for r in clean),
                      "named": sorted({n for r in clean for n in r["named"]})},
            "hidden": {"sets": len(hid), "extra": sum(bool(r["extra"]) for r in hid),
                       "missed": sum(bool(r["missed"]) for r in hid), "per_effect": per},
            "cpu_per_set_s": sum(r["cpu_s"] for r in rows) / max(len(rows), 1)}


def markdown(label: str, sm: dict) -> str:
    c, h = sm["clean"], sm["hidden"]
    lines = [f"**{label}**: false alarms on clean sets {c['alarms']}/{c['sets']}"
             + (f" (named {', '.join(c['named'])})" if c["named"] else "")
             + f"; sets naming an extra effect beside the hidden one {h['extra']}/{h['sets']}, hidden effect "
               f"missed {h['missed']}/{h['sets']}; {sm['cpu_per_set_s']:.1f} s CPU per set.", ""]
    if h["per_effect"]:
        lines += ["| hidden effect | sets | extra effect named | missed | extra names |", "| --- | --- | --- | --- | --- |"]
        for n, e in sorted(h["per_effect"].items()):
            names = ", ".join(f"{k} {v}" for k, v in sorted(e["extra_names"].items())) or "-"
            lines.append(f"| `{n}` | {e['sets']} | {e['extra']} | {e['missed']} | {names} |")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--case", choices=("clean", "hidden"))
    ap.add_argument("--sets", type=int, default=200)
    ap.add_argument("--first", type=int, default=0)
    ap.add_argument("--src", help="source tree to diagnose with (default: this one's src)")
    ap.add_argument("--json", help="append one JSON line per set to this file")
    ap.add_argument("--merge", nargs="+", help="print the tables of earlier --json files")
    ap.add_argument("--label", default="this code")
    a = ap.parse_args(argv)
    if a.merge:
        rows = [json.loads(line) for p in a.merge for line in open(p, encoding="utf-8") if line.strip()]
        rows = list({(r["hidden"] is None, r["set"]): r for r in rows}.values())  # a set run twice counts once
        print(markdown(a.label, summarise(rows)))
        return
    _paths(a.src)
    with tempfile.TemporaryDirectory() as work:
        for s in range(a.first, a.first + a.sets):
            r = one_set(a.case, s, work)
            print(json.dumps(r), flush=True)
            if a.json:
                with open(a.json, "a", encoding="utf-8") as fh:
                    fh.write(json.dumps(r) + "\n")


if __name__ == "__main__":
    main()
