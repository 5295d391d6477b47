"""The diagnosis in words and tables, for every data kind: the verdict line, the one-paragraph
``summary(report)`` and a statsmodels-like Summary (absolute poses: the text of summary.txt,
:func:`pose_text`).

``Summary(report)`` prints as fixed-width text (``str()``) and renders as an
HTML table set (``as_html()``, ``_repr_html_`` for notebooks); both come
from the same rows, so they cannot disagree.
"""
from __future__ import annotations

import html
from collections.abc import Mapping

Z95 = 1.959963984540054


def _named_words(rep) -> list:
    groups = [tuple(g) for g in rep.get("confounded", [])]
    out = []
    for nm in rep["named_effects"]:
        g = next((g for g in groups if nm in g), None)
        out.append(" or ".join(g) + " (this data cannot tell them apart)" if g else nm)
    return out


def alternative_lines(rep) -> list:
    """One sentence per other explanation the data do not exclude (Occam's window on BIC)."""
    return [f"Also supported by this data: {' + '.join(a['named_effects']) or 'no effect'} (BIC {a['delta_bic']:+.1f} "
            f"against the named set, within {rep.get('alternatives_window', 6.0):.1f}: posterior odds of at least "
            f"1:20; reduced chi2 {a['chi2_red']:.3f})" for a in rep.get("alternatives", [])]


def outlier_words(rep) -> str:
    """How many rows were set aside as gross outliers, and which ("" when none were)."""
    o = rep.get("outliers")
    if not o:
        return ""
    rows = ", ".join(str(r) for r in o["rows"][:8]) + (", ..." if len(o["rows"]) > 8 else "")
    return (f"{o['n_rows']} of {o['n_rows_total']} rows ({100 * o['fraction']:.1f} %) set aside as gross outliers "
            f"(file rows {rows})")


def is_pose_report(rep) -> bool:
    """Whether ``rep`` is an absolute-pose diagnosis' report (:class:`vjm.calibration.diagnosis.PoseReport`)."""
    return rep.get("kind") == "absolute_poses"


def verdict_line(rep) -> str:
    """One sentence: the verdict, the named effects (or groups) and the lack of fit (and the rows set aside)."""
    if is_pose_report(rep):
        return _pose_verdict_line(rep)
    line = _verdict_line(rep)
    o = outlier_words(rep)
    if o and rep["verdict"] != "untrusted_data":
        line = line[:-1] + f"; {o}, the verdict is on the other rows."
    return line


def _verdict_line(rep) -> str:
    lof = rep["lack_of_fit"]
    if lof.get("p_value") is None:
        fit_s = lof.get("note", "lack of fit cannot be judged")
    else:
        fit_s = (f"lack of fit chi2_red {lof['chi2_red']:.3g} on {lof['dof']} dof, p = {lof['p_value']:.2g} "
                 f"(level {lof['alpha']:.2g})")
    named = _named_words(rep)
    v = rep["verdict"]
    if v == "untrusted_data":
        return (f"Verdict: untrusted data: {outlier_words(rep)}, more than "
                f"{100 * rep['outliers']['limit_fraction']:.0f} % of the rows: the data cannot be trusted and no "
                "effect is named.")
    if v == "no_discrepancy":
        return f"Verdict: no discrepancy: the calibrated model fits the data ({fit_s})."
    if v == "explained":
        return f"Verdict: explained by {'; '.join(named)}; the final model fits ({fit_s})."
    if v == "insufficient_data":
        return (f"Verdict: insufficient data: {'; '.join(named)} fits ({fit_s}), but this design is too weak to "
                "name it (see the warnings; measure more postures and loads, e.g. with --suggest).")
    head = "Verdict: unexplained: a significant gap remains"
    if named:
        head += f" after naming {'; '.join(named)}"
    lv = lof.get("load_levels") or {}
    if lv.get("significant"):
        fit_s += (f"; the deflection does not scale with the load between levels "
                  f"{', '.join(f'{m:.4g}' for m in lv['levels_N'])} N, p = {lv['p_value']:.2g}")
    return f"{head} ({fit_s}); no candidate of the library explains it."


def _f(v, fmt="{:.4g}"):
    if v is None:
        return "-"
    try:
        return fmt.format(v)
    except (TypeError, ValueError):
        return str(v)


class Summary:
    """Tables of a diagnosis: header (verdict, fit, data), named effects, candidates, warnings."""

    def __init__(self, report: Mapping):
        self.report = report

    def brief(self) -> str:
        """What ``vjm diagnose`` prints: the one-paragraph summary (absolute poses: summary.txt's text)."""
        return pose_text(self.report) if is_pose_report(self.report) else self.report["summary"]

    def tables(self) -> list:
        """[(title, header, rows)] with string cells."""
        r = self.report
        lof = r["lack_of_fit"]
        cal = ", ".join(f"{k} {v['value']:.3g} +- {Z95 * v['se']:.2g}" for k, v in r["calibration"].items())
        head = [["verdict", r["verdict"]],
                ["named effects", "; ".join(_named_words(r)) or "none"],
                ["lack of fit", "cannot be judged (sigmas unknown, no repeats)" if lof.get("p_value") is None else
                 f"chi2_red {lof['chi2_red']:.3g}, dof {lof['dof']}, p = {lof['p_value']:.3g} (level {lof['alpha']:.2g})"],
                ["observations", f"{r['n_observations']} at {r['n_postures']} postures ({r['data_kind']})"],
                *([["outliers set aside", outlier_words(r)]] if r.get("outliers") else []),
                ["sigma", r["sigma_source"]],
                ["calibration", cal],
                ["RMS before -> after", f"{_f(r['rms_before'])} -> {_f(r['rms_after'])} {r['rms_units']}"],
                ["reduced chi2 before -> after", f"{_f(r['chi2_before'], '{:.3f}')} -> {_f(r['chi2_after'], '{:.3f}')}"],
                ["candidates tested", f"{r.get('n_tested', '-')} (Bonferroni, family-wise alpha {r['alpha']})"]]
        fin = []
        for t, d in r["final_params"].items():
            for k, v in d.items():
                fin.append([t, k, _f(v["value"]), _f(v["se"]), f"[{_f(v['ci95'][0])}, {_f(v['ci95'][1])}]", v["unit"]])
        cand = []
        for nm, c in r["candidates"].items():
            state = ("named" if c.get("named") else "not observable" if c.get("observable") is False else
                     "skipped" if c.get("skipped") else "not converged" if c.get("converged") is False else
                     "at bound" if c.get("at_bound") else "")
            cand.append([nm, _f(c.get("delta_bic"), "{:.1f}"), _f(c.get("p_value"), "{:.2g}"),
                         _f(c.get("threshold"), "{:.2g}"), state])
        notes = [[w] for w in r.get("dropped", {}).values()] + [[d["why"]] for d in r.get("confounding", [])]
        notes += [[a] for a in alternative_lines(r)]
        notes += [[f] for f in r.get("flags", [])]
        if r["verdict"] == "unexplained":
            notes.append([f"remaining gap: {r['localization_after']['summary']}"])
        if r.get("suggest"):
            k = r["suggest"].get("rows_to_separate")
            enough = "" if k is None else f"; its first {k} rows are expected to separate the group"
            notes.append([f"next measurements ({r['suggest']['n']} rows, {r['suggest']['file']}): "
                          f"{r['suggest']['criterion']}{enough}"])
        out = [("Diagnosis", ["", ""], head),
               ("Final model parameters", ["term", "parameter", "value", "se", "95% CI", "unit"], fin),
               ("Candidates (round 1, each on top of the calibrated model)",
                ["effect", "dBIC", "p", "level", "state"], cand)]
        if notes:
            out.append(("Notes", ["note"], notes))
        return out

    def as_text(self) -> str:
        if is_pose_report(self.report):
            return pose_text(self.report)
        lines = [verdict_line(self.report), ""]
        for title, header, rows in self.tables():
            w = [max(len(str(x)) for x in col) for col in zip(header, *rows)] if rows else [len(h) for h in header]
            width = sum(w) + 2 * (len(w) - 1)
            lines += [title.center(max(width, len(title))), "=" * max(width, len(title))]
            if any(header):
                lines.append("  ".join(str(h).ljust(n) for h, n in zip(header, w)))
                lines.append("-" * max(width, len(title)))
            lines += ["  ".join(str(c).ljust(n) for c, n in zip(row, w)) for row in rows]
            lines.append("")
        return "\n".join(lines)

    def as_html(self) -> str:
        if is_pose_report(self.report):
            text = html.escape(pose_text(self.report))
            return f"<pre>{text}</pre>"
        parts = [f"<p><b>{html.escape(verdict_line(self.report))}</b></p>"]
        for title, header, rows in self.tables():
            h = "".join(f"<th>{html.escape(str(c))}</th>" for c in header) if any(header) else ""
            body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>" for r in rows)
            parts.append(f"<table><caption>{html.escape(title)}</caption>"
                         f"{'<tr>' + h + '</tr>' if h else ''}{body}</table>")
        return "\n".join(parts)

    def __str__(self) -> str:
        return self.as_text()

    def _repr_html_(self) -> str:
        return self.as_html()


def summary(rep) -> str:
    """The one-paragraph terminal summary of a report (``vjm diagnose`` prints it; report.json holds it)."""
    cal = rep["calibration"]
    cal_s = ", ".join(f"{k} {v['value']:.3g} +- {Z95 * v['se']:.2g}" for k, v in cal.items())
    parts = [verdict_line(rep)]
    for nm in rep["named_effects"]:
        c = rep["candidates"][nm]
        ps = ", ".join(f"{k} = {v['value']:.4g} +- {Z95 * v['se']:.2g} {v['unit']}" for k, v in c["final_params"].items())
        parts.append(f"{nm}: {ps} (round dBIC {c['round_delta_bic']:.1f}, p = {c['round_p_value']:.2g}).")
    for why in rep.get("dropped", {}).values():
        parts.append(why + ".")
    for d in rep.get("confounding", []):
        parts.append(d["why"] + ".")
    parts += [a + "." for a in alternative_lines(rep)]
    if rep["verdict"] == "unexplained":
        parts.append(f"Where the remaining gap is: {rep['localization_after']['summary']}.")
    for f in rep.get("flags", []):
        parts.append(f"Warning: {f}.")
    if rep.get("unobservable"):
        parts.append("Not observable on this data (not fitted): " + ", ".join(rep["unobservable"]) + ".")
    return (" ".join(parts[:1]) + f" {rep['n_observations']} observations at {rep['n_postures']} postures "
            f"({rep['data_kind']} data, sigma {rep['sigma_source']}); baseline calibration: {cal_s}. "
            + " ".join(parts[1:]) +
            f" RMS {rep['rms_nominal']:.3g} (nominal) -> {rep['rms_before']:.3g} (calibrated) -> {rep['rms_after']:.3g} "
            f"{rep['rms_units']}; reduced chi2 {rep['chi2_nominal']:.3g} -> {rep['chi2_before']:.3g} -> "
            f"{rep['chi2_after']:.3g}. Gap before naming: {rep['localization']['summary']}.")


def _pose_verdict_line(rep) -> str:
    v = rep["verdict"]
    lof = rep["lack_of_fit"]
    # without sigmas nothing says the residuals are the instrument's noise: the verdict says so beside it
    unjudged = "; lack of fit not judged: no sigmas" if lof.get("judged") is False else ""
    if v == "no_discrepancy":
        return f"Verdict: no_discrepancy (nothing named beyond the registration){unjudged}."
    line = f"Verdict: {v}; named: {', '.join(rep['named_effects']) or 'nothing'}{unjudged}."
    if v == "unexplained" and lof.get("lack_of_fit"):
        line += (f" The residuals stay {lof['rms_over_sigma']:.3g}x the stated sigmas (chi-square p = "
                 f"{lof['p_value']:.2g}): a gap no effect tried closes.")
    elif v == "unexplained":
        line += _stands_in_words(rep.get("stands_in") or ())
    return line


def _stands_in_words(stands) -> str:
    """What the effects that stand in for something else buy beyond those named, out of their domain."""
    return "".join(f" {s['effect']} stands in for something else: out of its physical domain it buys "
                   f"{s['beyond_named_mm']:.3g} mm more than the effects named (threshold {s['threshold_mm']:.3g} "
                   f"mm), a gap no effect tried closes within its domain." for s in stands
                   if s["beyond_named_mm"] >= s["threshold_mm"])


def held_words(v) -> str:
    """How a validation file was registered: on the fitted set-up (every row held out), or on a few of its
    poses (the others held out)."""
    if v.get("registered_on", 0):
        return f"registered on {v['registered_on']} of its poses"
    return "registered on the fitted set-up"


def _stats(st) -> str:
    return " / ".join(f"{st[k]:.3f}" for k in ("mean", "std", "max", "p95"))


def _p(p: float) -> str:
    return f"p = {p:.2g}" if p > 0 else "p < 1e-300"


#: the report's units, said once (a joint's compliance and stiffness as the model file states them)
POSE_UNITS = ("Units: mm, rad, N, kg; a joint's compliance in rad/(N mm) (mm/N for a prismatic joint), its stiffness "
              "in N mm/rad (N/mm), as the model file states it.")
#: how each named effect's size is measured, said once beside the sizes
SIZE_HOW = "the calibrated model with against without the effect's parameters, the same registration on both sides"


def _mm(v) -> str:
    return "-" if v is None else f"{v:.3f} mm"


def stiffness_words(st) -> str:
    """A fitted joint compliance as the model file's stiffness with its 95 % interval (and the source's)."""
    if st is None:
        return ""
    if st["stiffness"] is None:
        return (f"no constant stiffness fitted > 0 (fitted compliance {st['compliance']:.3g} {st['compliance_unit']}): "
                f"calibrated.yaml keeps the model file's entry")
    hi = "inf" if st["high"] is None else f"{st['high']:.3g}"
    nom = "" if st["nominal"] is None else f"; the model file says {st['nominal']:.3g}"
    return f"stiffness {st['stiffness']:.4g} {st['unit']} (95 % interval {st['low']:.3g} .. {hi}{nom})"


def remedy_words(size) -> str:
    """What removes an effect: ``vjm compensate`` on the calibrated robot file, when the file carries it."""
    if size.get("carried") is None:
        return ""
    return ("vjm compensate calibrated.yaml removes it" if size["carried"] else
            "calibrated.yaml does not carry it: vjm compensate does not remove it")


def size_lines(rep) -> list:
    """One line per named effect (and one per joint of it) saying its size in mm: at home, and mean and largest
    at the measured poses (:mod:`vjm.calibration.sizes`)."""
    lines = []
    for e in rep["effects"]:
        s = e.get("size")
        if not s:
            continue
        t = s["total"]
        verb = "sags" if e["effect"] in ("compliance", "payload") else "moves"
        home = "" if t["home_mm"] is None else f"{_mm(t['home_mm'])} at home, "
        fix = remedy_words(s)
        lines.append(f"  {e['effect']} {verb} the tool {home}{_mm(t['mean_mm'])} on average and {_mm(t['max_mm'])} "
                     f"at most at the measured poses" + (f"; {fix}" if fix else ""))
        for p in s["parts"]:
            home = "" if p["home_mm"] is None else f"{_mm(p['home_mm'])} at home, "
            st = stiffness_words(p.get("stiffness"))
            lines.append(f"    {p['name']}: {home}{_mm(p['mean_mm'])} mean, {_mm(p['max_mm'])} max"
                         + (f"; {st}" if st else ""))
    return lines


def pose_text(rep) -> str:
    """The text of an absolute-pose diagnosis' summary.txt: the verdict, the position error before and after
    each effect named, the held-out errors, what was removed and set aside."""
    reg = rep["stages"][0]
    lines = [_pose_verdict_line(rep),
             f"Calibration of {rep['model']} on {rep['data']} ({rep['rows']} rows, "
             f"point{'s' if len(rep['frames']) > 1 else ''} {', '.join(rep['frames'])}).",
             "Position error (mm) mean / std / max / p95, fitted rows:",
             f"  registration only: {_stats(reg['errors_mm'])}"]
    if not rep["effects"]:
        lines.append("  no effect named beyond the registration.")
    for e in rep["effects"]:
        lines.append(f"  {e['effect']} buys {e['buys_mm']:.3f} mm: {_stats(e['before_mm'])} -> "
                     f"{_stats(e['after_mm'])} ({_p(e['p_value'])}; {len(e['parameters'])} parameters)")
    for s in rep["stages"][1:]:
        if not s["kept"]:
            lines.append(f"  {s['name']}: not named ({s['note'] or _p(s['p_value'])}"
                         + (f", cross-validated RMS {s['cv_rms_mm']:.3f} mm" if s["cv_rms_mm"] is not None else "")
                         + ")")
    sizes = size_lines(rep)
    if sizes:
        lines += [f"What each named effect does to the tool ({SIZE_HOW}):", *sizes]
    if rep["held_out"]["folds"]:
        cv = [f"{s['name']} {s['cv_rms_mm']:.3f}" for s in rep["stages"] if s["cv_rms_mm"] is not None]
        lines.append(f"Held out, {rep['held_out']['folds']}-fold cross-validated RMS (mm): " + ", ".join(cv))
    for v in rep["held_out"]["validate"]:
        rest = f"{v['rows']} others" if v.get("registered_on", 0) else f"all {v['rows']} rows"
        lines.append(f"Held out, {v['file']} ({held_words(v)}, "
                     f"{'machine' if rep.get('machine') == 'parallel' else 'robot'} frozen; "
                     f"{rest}): {_stats(v['errors_mm'])}")
    if rep.get("std_method"):
        lines.append(f"Standard deviations: {rep['std_method']}.")
    lines.append(f"Not identifiable (removed): {len(rep['not_identifiable'])}; not observable: "
                 + (", ".join(r["parameter"] for r in rep["not_observable"]) or "none"))
    if rep["set_aside"]:
        rows = [str(r["row"] + 1) for r in rep["set_aside"]]
        lines.append(f"Set aside as outliers (not fitted): {len(rows)} rows, data rows (1 = the first under the "
                     f"header) " + ", ".join(rows[:20]) + (" ..." if len(rows) > 20 else ""))
    lines.append(POSE_UNITS)
    lines.append(f"Fitted in {rep['seconds']:.1f} s.")
    return "\n".join(lines) + "\n"
