"""Report of a diagnosis: report.json, report.html, PNG figures, model file.

The files are one output set (:mod:`linkfea.files.outputs`): written to temporaries
in the target folder and committed together, so the folder holds the complete
old report or the complete new one, never a mix; files of other origin in the
folder are never touched.
"""
from __future__ import annotations

import html
import json
from collections.abc import Mapping

import numpy as np

from linkfea.files.atomic import plain
from linkfea.files.outputs import OutputSet, check_folder

from .summary import (
    POSE_UNITS,
    SIZE_HOW,
    Summary,
    alternative_lines,
    held_words,
    is_pose_report,
    remedy_words,
    stiffness_words,
    verdict_line,
)

#: the files a report folder may hold (next_measurements.csv with --suggest)
REPORT_FILES = ("report.json", "report.html", "before_after.png", "residuals_per_posture.png",
                "model_updated.yaml", "next_measurements.csv")
SET_NAME = "vjm diagnose"


def _pose_cells(w) -> list:
    """A posture's cells: x, y, z (mm), and ox, oy, oz (rad) of a 6-dof platform's orientation."""
    return ([_fmt(w[k], "{:.1f}") for k in ("x", "y", "z")]
            + [_fmt(w[k], "{:.4f}") for k in ("ox", "oy", "oz") if k in w])


def _pose_header(loc) -> list:
    rows = loc.get("worst_postures", [])
    return ["x", "y", "z"] + (["ox [rad]", "oy [rad]", "oz [rad]"] if rows and "ox" in rows[0] else [])


def plot_residuals(path, P, rms_before, rms_after, title):
    """Bar chart of normalized RMS residual per posture, before and after."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    m = len(rms_before)
    fig, axs = plt.subplots(2, 1, figsize=(max(6.0, 0.18 * m + 2), 6.5), constrained_layout=True)
    x = np.arange(m)
    axs[0].bar(x - 0.2, rms_before, 0.4, label="before", color="tab:red")
    axs[0].bar(x + 0.2, rms_after, 0.4, label="after", color="tab:blue")
    axs[0].axhline(1.0, color="k", lw=0.8, ls="--", label="noise level")
    axs[0].set_xlabel("posture index")
    axs[0].set_ylabel("RMS normalized residual")
    axs[0].set_title(title)
    axs[0].legend()
    sc = axs[1].scatter(P[:, 0] - P[:, 1], P[:, 2], c=rms_before, cmap="magma", s=40, label="before")
    axs[1].set_xlabel("x - y (mm)")
    axs[1].set_ylabel("z (mm)")
    axs[1].set_title("where the gap was: RMS normalized residual before, per posture")
    fig.colorbar(sc, ax=axs[1])
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_before_after(path, rms_before, rms_after, verdict):
    """One small picture: per-posture normalized RMS residual before and after, sorted, with the noise level."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.0, 2.6), constrained_layout=True)
    x = np.arange(1, len(rms_before) + 1)
    ax.plot(x, np.sort(rms_before)[::-1], "-", color="tab:red", label="before (calibrated model)")
    ax.plot(x, np.sort(rms_after)[::-1], "-", color="tab:blue", label="after (named effects added)")
    ax.axhline(1.0, color="k", lw=0.8, ls="--", label="noise level")
    ax.set_xlabel("postures, sorted by residual")
    ax.set_ylabel("RMS residual / sigma")
    ax.set_title(f"verdict: {verdict}")
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _table(rows, header):
    h = "".join(f"<th>{html.escape(str(c))}</th>" for c in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><tr>{h}</tr>{body}</table>"


def _fmt(v, f="{:.4g}"):
    if v is None:
        return "-"
    try:
        return f.format(v)
    except (TypeError, ValueError):
        return str(v)


def render_html(rep: Mapping, figures=(), rows=None) -> str:
    """report.html of a diagnosis of any kind: one-line verdict first, then the evidence (the stages' report:
    the before/after picture, the candidates; absolute poses': the effects named and their sizes, the held-out
    errors, the pictures -- with ``rows`` (the fitted rows' errors before and after, mm) the errors per pose too)."""
    if is_pose_report(rep):
        return _pose_html(rep, rows)
    return _stages_html(rep, figures)


def _stages_html(rep: Mapping, figures) -> str:
    """The stages' report: one-line verdict and the before/after picture first, then the evidence."""
    named = rep["named_effects"]
    cand_rows = []
    for name, c in rep["candidates"].items():
        ps = "; ".join(f"{k} = {_fmt(v['value'])} [{_fmt(v['ci95'][0])}, {_fmt(v['ci95'][1])}] {v['unit']}"
                       for k, v in c.get("params", {}).items())
        state = ("named" if name in named else c.get("skipped") or
                 ("fit did not converge" if c.get("converged") is False else "") or
                 (f"at bound: {', '.join(c['at_bound'])}" if c.get("at_bound") else ""))
        cand_rows.append([name, _fmt(c.get("delta_bic"), "{:.1f}"), _fmt(c.get("p_value"), "{:.2g}"),
                          _fmt(c.get("cv_error"), "{:.3f}"), state, ps, c.get("description", "")])
    loc = rep["localization"]
    worst = [_pose_cells(w) + [_fmt(w["rms_normalized"], "{:.2f}"), w["n"]] for w in loc.get("worst_postures", [])]
    dirs = [[k, _fmt(v["rms_normalized"], "{:.2f}"), v["n"]] for k, v in loc.get("by_load_direction", {}).items()]
    dirs += [[k, _fmt(v, "{:.3g}"), "-"] for k, v in loc.get("by_quantity", {}).items()]
    first = [f for f in figures if f == "before_after.png"]
    rest = [f for f in figures if f not in first]
    top = "".join(f'<figure><img src="{html.escape(f)}" alt="before and after"></figure>' for f in first)
    figs = "".join(f'<figure><img src="{html.escape(f)}" alt="{html.escape(f)}"></figure>' for f in rest)
    conf = "".join(f"<li>{html.escape(d)}</li>" for d in [d["why"] for d in rep.get("confounding", [])]
                   + alternative_lines(rep))
    flags = "".join(f"<li>{html.escape(f)}</li>" for f in rep.get("flags", []))
    unobs = "".join(f"<li><code>{html.escape(k)}</code>: {html.escape(v)}</li>" for k, v in rep.get("unobservable", {}).items())
    gap = ""
    if rep["verdict"] == "unexplained":
        la = rep["localization_after"]
        gap = (f"<h2>Where the remaining gap is</h2><p>No candidate of the library explains it. "
               f"{html.escape(la.get('summary', ''))}.</p>"
               + _table([_pose_cells(w) + [_fmt(w["rms_normalized"], "{:.2f}"), w["n"]]
                         for w in la.get("worst_postures", [])],
                        _pose_header(la) + ["RMS normalized (after)", "n"]))
    if rep["verdict"] == "insufficient_data":
        why = "".join(f"<li>{html.escape(f)}</li>" for f in rep.get("flags", []) if f.startswith("insufficient data"))
        gap = ("<h2>Why nothing is named</h2><p>An effect fits, but this design is too weak to name it; "
               f"measure more postures and loads (e.g. with <code>--suggest</code>).</p><ul>{why}</ul>")
    outl = ""
    if rep.get("outliers"):
        o = rep["outliers"]
        outl = (f"<h2>Rows set aside as gross outliers</h2><p>{o['n_rows']} of {o['n_rows_total']} rows; "
                f"|z| &gt; {o['threshold']:.2f} (robust scale {o['robust_scale']:.3g}); the diagnosis above is "
                "computed without them.</p>"
                + _table([[e["row"], e["component"], _fmt(e["z"], "{:+.1f}")] for e in o["observations"]],
                         ["file row", "component", "standardized residual"]))
    sug = ""
    if rep.get("suggest"):
        sg = rep["suggest"]
        sug = (f"<h2>What to measure next</h2><p><code>{html.escape(sg['file'])}</code>: {sg['n']} (posture, load) rows"
               f"{' (forces only)' if sg.get('forces_only') else ''}. Design: {html.escape(sg['criterion'])}.</p>")
    return f"""<!doctype html><html><head><meta charset="utf-8"><title>VJM discrepancy report</title>
<style>body{{font-family:sans-serif;max-width:1100px;margin:auto}}table{{border-collapse:collapse;margin:6px 0}}
td,th{{border:1px solid #ccc;padding:3px 6px;font-size:90%}}img{{max-width:100%}}caption{{font-weight:bold}}</style></head><body>
<h1>Discrepancy report</h1>
<p style="font-size:120%"><b>{html.escape(verdict_line(rep))}</b></p>
{top}
<p>Model: <code>{html.escape(rep['model'])}</code>; data: <code>{html.escape(rep['data'])}</code>
({rep['n_observations']} observations, {rep['n_postures']} postures, sigma {html.escape(rep['sigma_source'])}).</p>
<p>{html.escape(rep['summary'])}</p>
{gap}
{outl}
{'<h2>Cannot be told apart</h2><ul>' + conf + '</ul>' if conf else ''}
{'<h2>Warnings</h2><ul>' + flags + '</ul>' if flags else ''}
{sug}
<h2>Summary tables</h2>
{Summary(rep).as_html()}
<h2>Gap before and after</h2>
{_table([["RMS (data units)", _fmt(rep['rms_before']), _fmt(rep['rms_after'])],
         ["reduced chi2", _fmt(rep['chi2_before'], '{:.3f}'), _fmt(rep['chi2_after'], '{:.3f}')]],
        ["", "before (calibrated baseline)", "after"])}
<p>Before = baseline model after calibration of its nominal parameters; the uncalibrated
nominal model gave RMS {_fmt(rep.get('rms_nominal'))} and reduced chi2 {_fmt(rep.get('chi2_nominal'), '{:.3f}')}.</p>
<h2>Evidence per candidate (each alone on top of the calibrated baseline)</h2>
<p>delta_bic &lt; 0 favours the candidate; p from the {html.escape(rep['test'])}; cv_error is the RMS normalized
residual on held-out postures (baseline: {_fmt(rep.get('cv_baseline'), '{:.3f}')}), computed only for candidates
that pass the test. Significance level alpha = {rep['alpha']} shared by Bonferroni over the
{rep.get('n_tested', '')} candidates tested and the lack-of-fit test.</p>
{_table(cand_rows, ["effect", "delta_bic", "p_value", "cv_error", "state", "parameters (95% CI)", "description"])}
{'<h2>Not observable on this data (never fitted)</h2><ul>' + unobs + '</ul>' if unobs else ''}
<h2>Where the gap was (before)</h2><p>{html.escape(loc.get('summary', ''))}</p>
<h3>Worst postures (before)</h3>{_table(worst, _pose_header(loc) + ["RMS normalized", "n"])}
<h3>By dominant load direction (before)</h3>{_table(dirs, ["load", "RMS normalized", "n"])}
{figs}
</body></html>"""


def check_report_dir(out_dir, force: bool = False) -> None:
    """Refuse, before any work, a report folder that will not do (see :func:`linkfea.files.outputs.check_folder`)."""
    check_folder(out_dir, REPORT_FILES, force=force)


def write_report_dir(out_dir, rep: dict, model_writer, figure_writer, force: bool = False,
                     set_name: str = SET_NAME) -> None:
    """Write ``report.json``, ``report.html``, figures and the model file into ``out_dir`` as one set.

    ``model_writer(path)`` writes model_updated.yaml; ``figure_writer(path_of)`` writes PNGs
    (and the suggested measurements) to ``path_of(name)`` and returns the figures' names.
    A rerun replaces the report's own files and removes those of the previous report
    that this one does not have; other files are left alone.
    """
    check_folder(out_dir, REPORT_FILES, force=force)
    with OutputSet(out_dir, set_name) as s:
        model_writer(s.path("model_updated.yaml"))
        figures = figure_writer(s.path)
        with open(s.path("report.json"), "w", encoding="utf-8") as fh:
            json.dump(plain(rep), fh, indent=2)
        with open(s.path("report.html"), "w", encoding="utf-8") as fh:
            fh.write(render_html(plain(rep), figures))


def _pv(p) -> str:
    return "-" if p is None else (f"{p:.2g}" if p > 0 else "< 1e-300")


def _stats(st: Mapping) -> list:
    return [f"{st[k]:.4f}" for k in ("mean", "std", "max", "p95")]


def _size_rows(rep: Mapping) -> list:
    """The sizes table's rows: each named effect, then each of its joints (mm, and a compliance's stiffness)."""
    out = []
    for e in rep["effects"]:
        sz = e.get("size")
        if not sz:
            continue
        rows = [(sz["total"], html.escape(e["effect"]), remedy_words(sz))]
        rows += [(p, f"&nbsp;&nbsp;{html.escape(p['name'])}", stiffness_words(p.get("stiffness"))) for p in sz["parts"]]
        for p, name, words in rows:
            out.append([name, _fmt(p["home_mm"], "{:.3f}"), f"{p['mean_mm']:.3f}", f"{p['max_mm']:.3f}",
                        html.escape(words)])
    return out


def _raw_table(rows, header) -> str:
    """A table whose cells are HTML already (escaped where they hold text)."""
    h = "".join(f"<th>{html.escape(str(c))}</th>" for c in header)
    body = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><tr>{h}</tr>{body}</table>"


def _pose_sizes_html(rep: Mapping) -> str:
    """The section saying what each named effect does to the tool, in mm (empty when none is named)."""
    rows = _size_rows(rep)
    if not rows:
        return ""
    return (f"<h2>What each named effect does to the tool (mm)</h2><p>{html.escape(SIZE_HOW[0].upper() + SIZE_HOW[1:])}: at home (the model "
            "file's <code>home:</code>), mean and largest at the measured poses.</p>"
            + _raw_table(rows, ["effect / joint", "at home", "mean", "max", "stiffness (95 % interval), or what "
                                "removes it"]))


def _pose_figures_html(rep: Mapping, rows) -> str:
    """The report's pictures, embedded as base64 PNG (:mod:`vjm.calibration.figures`)."""
    from ..calibration.figures import embedded

    before, after = rows if rows is not None else (None, None)
    return "".join(f'<figure><img src="data:image/png;base64,{b64}" alt="{html.escape(caption)}">'
                   f"<figcaption>{html.escape(caption)}</figcaption></figure>"
                   for caption, b64 in embedded(rep, before, after))


def _pose_html(rep: Mapping, rows=None) -> str:
    """Absolute poses' report.html: the verdict, the effects named with the gap before and after each, the
    held-out errors, the registration apart, the parameters, what was removed."""
    eff = [[e["effect"], f"{e['buys_mm']:.4f}", *_stats(e["before_mm"]), *_stats(e["after_mm"]),
            _pv(e["p_value"])] for e in rep["effects"]]
    held = [[v["file"], held_words(v)[len("registered "):], v["rows"], *_stats(v["errors_mm"])]
            for v in rep["held_out"]["validate"]]
    cv = [[s["name"], "named" if s["kept"] else "not named", f"{s['rms_mm']:.4f}",
           "-" if s["cv_rms_mm"] is None else f"{s['cv_rms_mm']:.4f}", _pv(s["p_value"]),
           s.get("note", "")] for s in rep["stages"]]
    reg = rep["registration"]
    frames = [[g, " ".join(f"{x:.3f}" for x in f["t_mm"]), ", ".join(f"{k} {v:.2g}" for k, v in f["std"].items())]
              for g, f in reg["instrument_frames"].items()]
    marks = [[mk["frame"], " ".join(f"{x:.3f}" for x in mk["offset_mm"]), " ".join(f"{x:.2g}" for x in mk["std_mm"])]
             for mk in reg["markers"]]
    pars = [[k, f"{v['value']:.6g}", "-" if v["std"] is None else f"{v['std']:.2g}", v["unit"]]
            for k, v in rep["parameters"].items()]
    removed = [[r["parameter"], r["why"]] for r in rep["not_observable"] + rep["not_identifiable"]]
    st = ["mean", "std", "max", "p95"]
    return f"""<!doctype html><html><head><meta charset="utf-8"><title>VJM diagnosis of absolute poses</title>
<style>body{{font-family:sans-serif;max-width:1100px;margin:auto}}table{{border-collapse:collapse;margin:6px 0}}
td,th{{border:1px solid #ccc;padding:3px 6px;font-size:90%}}img{{max-width:100%}}</style></head><body>
<h1>Diagnosis of absolute poses</h1>
<p style="font-size:120%"><b>{html.escape(verdict_line(rep))}</b></p>
<p>Model: <code>{html.escape(str(rep['model']))}</code>; data: <code>{html.escape(rep['data'])}</code> ({rep['rows']}
rows; points {html.escape(', '.join(rep['frames']))}); effects tried: {html.escape(', '.join(rep['effects_tried']))}.</p>
<p>{html.escape(POSE_UNITS)}</p>
<h2>Effects named, in order of what each buys (position error of the fitted rows, mm)</h2>
{_table(eff, ["effect", "buys (mean)"] + [f"before {k}" for k in st] + [f"after {k}" for k in st] + ["p"])}
{_pose_sizes_html(rep)}
{_pose_figures_html(rep, rows)}
<h2>Stages</h2>{_table(cv, ["stage", "state", "RMS mm", "cross-validated RMS mm", "F test p", "note"])}
<h2>Held out (the {'machine' if rep.get('machine') == 'parallel' else 'robot'} frozen; each file on the fitted registration, or a new set-up registered on a few of its poses)</h2>
{_table(held, ["file", "registered", "rows held out"] + [f"{k} mm" for k in st]) if held else
 f"<p>{rep['held_out']['folds']}-fold cross-validation (stages above).</p>"}
<h2>Registration (a nuisance, not an effect)</h2>
{_table(frames, ["set-up", "t (mm)", "standard deviations"])}{_table(marks, ["marker on", "offset (mm)", "std (mm)"])}
<h2>Fitted parameters</h2>{_table(pars, ["parameter", "value", "std", "unit"])}
<h2>Removed: not observable, not identifiable</h2>{_table(removed, ["parameter", "why"])}
</body></html>"""
