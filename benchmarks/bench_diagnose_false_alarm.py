"""Benchmark: false-alarm rate and power of `vjm diagnose` on independent-truth data.

Data come from tests/truth.py (richer 3-PUU model files solved by vjm and
vjm.stiffness.nonlinear plus terms written out there; nothing from vjm.discrepancy),
each set with its own random postures of the Q1-Q2 cube, its own loads
(opposite pairs of forces, moments and both, magnitudes 0.2-1 x 100 N /
5000 N mm) and its own noise (1 um, 10 urad; sigma columns given).

* **False alarms**: ``--sets`` (>= 200) clean independent sets of the model
  given (puu.yaml); a false alarm is any verdict other than
  ``no_discrepancy``.  The rate is given with its Clopper-Pearson 95 %
  interval, to compare with the nominal alpha.
* **Power**: for each library effect of tests/truth.py (``LIBRARY``) its data show (``seen``), the
  size starts where the effect adds a chi-square of 100 to the model given
  and is halved per step, ``--reps`` independent sets per size; an effect is detected *alone* when it alone is named with verdict
  ``explained``, and *at group level* when tests/truth.py ``names_exactly``
  holds (it is named, or a named effect stands for a confounded group that
  holds it: "A or B, this data cannot tell them apart").  The ladder goes down
  while the group-level detection holds, then up until the effect is named
  alone.  Each smallest detectable size is the smallest size of the
  ladder at which at least 80 % of the sets detected it, with the RMS of its
  signature (translation um, rotation urad) there.  For
  ``geometric_nonlinearity`` (the model's own) the size is the load scale
  (x 100 N / 5000 N mm), divided by sqrt(2) per step.

Run (CPU-heavy: nice it):

    PYTHONPATH=src nice .venv/bin/python benchmarks/bench_diagnose_false_alarm.py \
        [--sets 200] [--reps 5] [--pair-reps 1] [--postures 24] [--loads 12]
        [--only false_alarm|power|pairs] [--effect NAME ...] [--json out.json]

* **Pairs**: every pair of seen library effects that can be hidden together
  (tests/truth.py ``pairs()``), at their test sizes: both named (or their confounded groups),
  verdict ``explained``.

and copy the printed Markdown tables into docs/discrepancy.md and docs/benchmarks.md.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

import numpy as np
from scipy.stats import beta

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tests"))
import truth as tr

ALPHA = 0.01
#: noise-free chi-square at or below which nothing can see an effect (tests/discrepancy/test_diagnose_truth.py)
CHI2_UNSEEN = 1.0
#: the power ladder starts where an effect's signature adds this chi-square to the model given ...
START_CHI2 = 100.0
#: ... and takes at most this many steps
MAX_STEPS = 4
#: ... and at most this many doublings from the start to find the size named alone
UP_STEPS = 5


def clopper_pearson(k: int, n: int, conf: float = 0.95) -> tuple[float, float]:
    a = 1.0 - conf
    lo = 0.0 if k == 0 else beta.ppf(a / 2, k, n - k + 1)
    hi = 1.0 if k == n else beta.ppf(1 - a / 2, k + 1, n - k)
    return float(lo), float(hi)


def run_diagnose(model: dict, data: tr.Measurements, work: str) -> dict:
    """verdict, named, confounded, lack_of_fit of one diagnosis (Python API, or the CLI without it)."""
    mp = tr.write_model(model, os.path.join(work, "model.yaml"))
    dp = data.write(os.path.join(work, "data.csv"))
    import vjm
    if hasattr(vjm, "diagnose"):
        dg = vjm.diagnose(mp, dp, alpha=ALPHA)
        rep = getattr(dg, "report", None) or {}
        return {"verdict": dg.verdict, "named": list(dg.named), "confounded": [list(g) for g in dg.confounded],
                "lack_of_fit": rep.get("lack_of_fit"), "alternatives": rep.get("alternatives", [])}
    from typer.testing import CliRunner

    from vjm.cli import app
    out = os.path.join(work, "out")
    res = CliRunner().invoke(app, ["diagnose", mp, dp, "--out", out, "--alpha", str(ALPHA)])
    if res.exit_code != 0:
        raise RuntimeError(res.output)
    with open(os.path.join(out, "report.json"), encoding="utf-8") as fh:
        rep = json.load(fh)
    return {"verdict": rep["verdict"], "named": rep["named_effects"], "confounded": rep["confounded"],
            "lack_of_fit": rep.get("lack_of_fit"), "alternatives": rep.get("alternatives", [])}


def false_alarms(n_sets: int, n_post: int, n_loads: int, log=print, first: int = 0) -> dict:
    verdicts, named = [], {}
    t0 = time.process_time()
    with tempfile.TemporaryDirectory() as work:
        for s in range(first, first + n_sets):
            P, W = tr.design(n_post, n_loads, seed=10_000 + s)
            r = run_diagnose(tr.NOMINAL, tr.measure(tr.Truth(tr.variant(tr.NOMINAL)), P, W, seed=20_000 + s), work)
            verdicts.append(r["verdict"])
            for n in r["named"]:
                named[n] = named.get(n, 0) + 1
            if len(verdicts) % 10 == 0:
                k = sum(v != "no_discrepancy" for v in verdicts)
                log(f"  clean sets {len(verdicts)}/{n_sets}: {k} alarms", flush=True)
    k = sum(v != "no_discrepancy" for v in verdicts)
    lo, hi = clopper_pearson(k, n_sets)
    return {"sets": n_sets, "rows": n_post * n_loads, "alarms": k, "rate": k / n_sets, "ci95": [lo, hi],
            "verdicts": {v: verdicts.count(v) for v in set(verdicts)}, "named": named,
            "cpu_per_set_s": (time.process_time() - t0) / n_sets, "seeds": [first, first + n_sets]}


def merge_false_alarms(parts: list[dict]) -> dict:
    """One false-alarm result from runs over disjoint seed ranges (``--first``)."""
    n = sum(p["sets"] for p in parts)
    k = sum(p["alarms"] for p in parts)
    verdicts: dict = {}
    named: dict = {}
    for p in parts:
        for d, acc in ((p["verdicts"], verdicts), (p["named"], named)):
            for key, v in d.items():
                acc[key] = acc.get(key, 0) + v
    lo, hi = clopper_pearson(k, n)
    return {"sets": n, "rows": parts[0]["rows"], "alarms": k, "rate": k / n, "ci95": [lo, hi], "verdicts": verdicts,
            "named": named, "cpu_per_set_s": sum(p["cpu_per_set_s"] * p["sets"] for p in parts) / n,
            "seeds": sorted(p["seeds"] for p in parts)}


def signature_rms(given: dict, truth: tr.Truth, P, W) -> tuple[float, float]:
    d = tr.deflections(truth, P, W) - tr.deflections(tr.Truth(given), P, W)
    return float(1e3 * np.sqrt(np.mean(d[:, :3] ** 2))), float(1e6 * np.sqrt(np.mean(d[:, 3:] ** 2)))


def _case(name, size, n_post, n_loads, seed):
    """(model given, truth, P, W) of one power set."""
    if name == "geometric_nonlinearity":  # the model's own: scale the loads instead
        given, truth = tr.hide(name)
        P, W = tr.design(n_post, n_loads, seed=seed, force=100.0 * size, moment=5000.0 * size)
    else:
        given, truth = tr.hide((name, size))
        P, W = tr.design(n_post, n_loads, seed=seed)
    return given, truth, P, W


def noncentrality(given, truth, P, W) -> float:
    """sum of (signature / sigma)^2: the chi-square the effect adds to the model given, noise 1 um / 10 urad."""
    d = tr.deflections(truth, P, W) - tr.deflections(tr.Truth(given), P, W)
    return float(np.sum((d[:, :3] / 1e-3) ** 2) + np.sum((d[:, 3:] / 1e-5) ** 2))


def _detect(name, size, reps, n_post, n_loads, k, work):
    hits, group_hits, rms, lam = 0, 0, [], []
    for r in range(reps):
        seed = 30_000 + 100 * k + r
        given, truth, P, W = _case(name, size, n_post, n_loads, seed)
        res = run_diagnose(given, tr.measure(truth, P, W, seed=seed + 7), work)
        hits += res["verdict"] == "explained" and res["named"] == [name]
        rep = {"named_effects": res["named"], "confounded": res["confounded"], "alternatives": res["alternatives"]}
        group_hits += res["verdict"] == "explained" and tr.names_exactly(rep, [name])
        rms.append(signature_rms(given, truth, P, W))
        lam.append(noncentrality(given, truth, P, W))
    return {"size": size, "detected": hits, "detected_as_group": group_hits, "reps": reps, "rms_t_um": float(np.mean([a for a, _ in rms])),
            "rms_r_urad": float(np.mean([b for _, b in rms])), "noncentrality": float(np.mean(lam))}


def _smallest(rows: list[dict], key: str, reps: int) -> dict | None:
    """The smallest size of the ladder detected (``key``) in at least 80 % of its sets."""
    ok = [r for r in rows if r[key] >= 0.8 * reps]
    return min(ok, key=lambda r: r["size"]) if ok else None


def power(reps: int, n_post: int, n_loads: int, log=print, effects=None) -> dict:
    """Each effect's size is set so that its signature adds a chi-square of ``START_CHI2`` (at the
    test size, chi-square grows as size^2; as size^4 for the load scale of the nonlinearity), then
    halved (the chi-square quartered) while at least 80 % of the sets detect it at group level (named,
    or a named effect standing for a confounded group that holds it: tests/truth.py ``names_exactly``);
    then, if it was never named *alone* in 80 % of the sets, doubled from the start up to UP_STEPS times
    until it is.  Both smallest sizes are reported."""
    out = {}
    with tempfile.TemporaryDirectory() as work:
        for name in effects or [n for n, h in tr.LIBRARY.items() if h.seen]:
            h = tr.LIBRARY[name]
            lam0 = noncentrality(*_case(name, h.size, n_post, n_loads, 30_000))
            p = 4.0 if name == "geometric_nonlinearity" else 2.0
            s0 = h.size * (START_CHI2 / lam0) ** (1.0 / p)
            step = 0.5 ** (2.0 / p)
            rows: list[dict] = []

            def run(size, name=name, h=h, rows=rows):
                row = _detect(name, size, reps, n_post, n_loads, len(rows), work)
                rows.append(row)
                log(f"  {name} size {size:.3g} {h.unit} (chi2 {row['noncentrality']:.0f}): "
                    f"alone {row['detected']}/{reps}, as group {row['detected_as_group']}/{reps}", flush=True)
                return row

            size = s0
            while len(rows) <= MAX_STEPS and run(size)["detected_as_group"] >= 0.8 * reps:
                size *= step
            size = s0
            for _ in range(UP_STEPS):
                if _smallest(rows, "detected", reps) and _smallest(rows, "detected_as_group", reps):
                    break
                size /= step
                run(size)
            out[name] = {"unit": h.unit, "ladder": sorted(rows, key=lambda r: -r["size"]),
                         "smallest": _smallest(rows, "detected", reps),
                         "smallest_group": _smallest(rows, "detected_as_group", reps)}
    return out


def pair_runs(reps: int, n_post: int, n_loads: int, log=print, only=None) -> dict:
    """Every pair of library effects that can be hidden together (tests/truth.py ``pairs()``),
    at their test sizes, ``reps`` sets each: verdict and names.  3-PUU pairs on ``n_post`` x
    ``n_loads`` random rows, 3-PRPaR pairs on that machine's acceptance design (its moments up
    to 20 N m, without which its bar modes hardly show), seeds 40000 + set; each with the pair's
    noise-free chi-square once the calibration is refit (``chi2``: below ~200 it may not show)."""
    out = {}
    with tempfile.TemporaryDirectory() as work:
        for a, b in tr.pairs():
            if only and f"{a}+{b}" not in only:
                continue
            runs = []
            machine = next((tr.LIBRARY[x].machine for x in (a, b) if tr.LIBRARY[x].machine != "puu"), "puu")
            kw = {"n_postures": n_post, "n_loads": n_loads} if machine == "puu" else dict(tr.DESIGNS[machine])
            for r in range(reps):
                P, W = tr.design(**{**kw, "seed": 40_000 + r})
                given, truth = tr.hide(a, b)
                # whether the pair shows at all, decided on the truth (calibration refit)
                chi2 = tr.signature_chi2(given, truth, P, W)[1]
                res = run_diagnose(given, tr.measure(truth, P, W, seed=41_000 + r), work)
                rep = {"named_effects": res["named"], "confounded": res["confounded"],
                       "alternatives": res["alternatives"]}
                ok = res["verdict"] == "explained" and tr.names_exactly(rep, (a, b))
                grp = res["verdict"] == "explained" and tr.names_at_group_level(rep, (a, b))
                absorbed, besides = None, None
                if not grp:
                    # decided on the truth, as the acceptance test does: one effect shows nothing
                    # besides the other, and the one that shows (either, if each is the other) is named
                    besides = tr.on_top_chi2((a, b), P, W)
                    shows = [h for h in (a, b) if besides[h] > CHI2_UNSEEN]
                    absorbed = bool(len(shows) < 2 and res["verdict"] == "explained"
                                    and any(tr.names_exactly(rep, [h]) for h in shows or (a, b)))
                runs.append({"ok": bool(ok), "group": bool(grp), "absorbed": absorbed, "chi2": chi2, "besides": besides,
                             "verdict": res["verdict"],
                             "named": res["named"], "confounded": res["confounded"],
                             "alternatives": [x["named_effects"] for x in res["alternatives"]],
                             "lack_of_fit": res["lack_of_fit"]})
            out[f"{a}+{b}"] = runs
            log(f"  {a} + {b}: {sum(x['ok'] for x in runs)}/{reps} named both, "
                f"{sum(x['group'] for x in runs)}/{reps} at group level, "
                f"{sum(bool(x['absorbed']) for x in runs)}/{reps} one absorbed " + "; ".join(
                    f"{x['verdict']} {x['named']} {x['confounded']}" for x in runs if not x["ok"]), flush=True)
    return out


def markdown(fa: dict | None, pw: dict | None, meta: str, pr: dict | None = None) -> str:
    lines = []
    if fa:
        lo, hi = fa["ci95"]
        lines += [f"False alarms on {fa['sets']} clean independent sets ({fa['rows']} rows each, {meta}):",
                  f"**{fa['alarms']}/{fa['sets']} = {100 * fa['rate']:.1f} %** "
                  f"(Clopper-Pearson 95 %: {100 * lo:.1f}-{100 * hi:.1f} %; nominal alpha {100 * ALPHA:.0f} %); "
                  f"verdicts {fa['verdicts']}; named {fa['named'] or 'none'}; "
                  f"{fa['cpu_per_set_s']:.1f} s CPU per set.", ""]
    if pw:
        lines += ["| effect | smallest size named alone | signature RMS there: translation um / rotation urad "
                  "| its chi-square on the set | smallest size named at group level (chi-square) "
                  "| ladder (size: sets named alone / at group level) |",
                  "| --- | --- | --- | --- | --- | --- |"]
        for name, r in pw.items():
            s, g = r["smallest"], r.get("smallest_group")
            ladder = ", ".join(f"{x['size']:.3g}: {x['detected']}/{x.get('detected_as_group', '-')}/{x['reps']}"
                               for x in r["ladder"])
            grp = "-" if g is None else f"{g['size']:.3g} ({g['noncentrality']:.0f})"
            if s is None:
                lines.append(f"| `{name}` | not named alone up to {r['ladder'][0]['size']:.3g} {r['unit']} | - | - | {grp} | {ladder} |")
            else:
                lines.append(f"| `{name}` | {s['size']:.3g} {r['unit']} | {s['rms_t_um']:.2f} / {s['rms_r_urad']:.1f} "
                             f"| {s['noncentrality']:.0f} | {grp} | {ladder} |")
    if pr:
        good = sum(x["ok"] for runs in pr.values() for x in runs)
        grp = sum(x.get("group", x["ok"]) for runs in pr.values() for x in runs)
        absorbed = sum(bool(x.get("absorbed")) for runs in pr.values() for x in runs)
        total = sum(len(runs) for runs in pr.values())
        lines += ["", f"Pairs of library effects at their test sizes: {good}/{total} sets named both (each named "
                      f"effect hidden or standing for a group that holds a hidden one: names_exactly), {grp}/{total} "
                      "at group level (every hidden effect named or in a group with a named one, nothing else "
                      f"claimed), verdict explained; of the others, {absorbed} where one effect shows nothing "
                      "besides the other (truth.on_top_chi2) and the one that shows is named.  Not named both:", ""]
        for k, runs in pr.items():
            for x in runs:
                if not x["ok"]:
                    lof = x.get("lack_of_fit") or {}
                    level = ("at group level" if x.get("group") else
                             "one absorbed by the other, the one that shows named" if x.get("absorbed") else "missed")
                    bs = x.get("besides")
                    level += "" if not bs else "; each besides the other: " + ", ".join(f"{h} {v:.3g}" for h, v in bs.items())
                    lines.append(f"* {k} ({level}; pair chi2 {x.get('chi2', float('nan')):.0f}): verdict "
                                 f"{x['verdict']}, named {x['named']}, alternatives {x.get('alternatives')}, confounded "
                                 f"{x.get('confounded')}, chi2_red after {lof.get('chi2_red', float('nan')):.3f}")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sets", type=int, default=200)
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--postures", type=int, default=24)
    ap.add_argument("--loads", type=int, default=12)
    ap.add_argument("--only", choices=("false_alarm", "power", "pairs"))
    ap.add_argument("--pair-reps", type=int, default=1, help="sets per pair of effects")
    ap.add_argument("--effect", action="append", help="power of these effects only (repeatable)")
    ap.add_argument("--pair", action="append", help="only this pair A+B (repeatable; split a run over processes)")
    ap.add_argument("--first", type=int, default=0, help="first clean-set seed index (split a run over processes)")
    ap.add_argument("--merge", nargs="+", help="print the tables of earlier --json results (false alarms merged)")
    ap.add_argument("--json")
    a = ap.parse_args(argv)
    if a.merge:
        res = []
        for path in a.merge:
            with open(path, encoding="utf-8") as fh:
                res.append(json.load(fh))
        fas = [r["false_alarm"] for r in res if r.get("false_alarm")]
        pws = [r["power"] for r in res if r.get("power")]
        pw = {k: v for p in pws for k, v in p.items()} or None
        prs = [r["pairs"] for r in res if r.get("pairs")]
        pr = {k: v for p in prs for k, v in p.items()} or None
        print(markdown(merge_false_alarms(fas) if fas else None, pw, "; ".join(r["meta"] for r in res), pr))
        return
    t0 = time.perf_counter()
    fa = false_alarms(a.sets, a.postures, a.loads, first=a.first) if a.only in (None, "false_alarm") else None
    pw = power(a.reps, a.postures, a.loads, effects=a.effect) if a.only in (None, "power") else None
    pr = pair_runs(a.pair_reps, a.postures, a.loads, only=a.pair) if a.only in (None, "pairs") else None
    meta = (f"{a.postures} postures x {a.loads} loads, 1 um / 10 urad noise, alpha {ALPHA}; "
            f"wall {time.perf_counter() - t0:.0f} s, load average {os.getloadavg()[0]:.1f}")
    print(markdown(fa, pw, meta, pr))
    if a.json:
        with open(a.json, "w", encoding="utf-8") as fh:
            json.dump({"false_alarm": fa, "power": pw, "pairs": pr, "meta": meta}, fh, indent=1)


if __name__ == "__main__":
    main()
