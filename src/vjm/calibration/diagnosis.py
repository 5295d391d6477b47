"""``vjm diagnose`` on absolute poses: a robot's measured points, diagnosed by the calibration engine of
:mod:`vjm.robot` (one home for the fit: :func:`vjm.calibration.engine.calibrate`).

The data (:class:`vjm.calibration.poses.AbsolutePoses`, read as it is through a column map) hold per row the
joint values and the points an instrument measured in its own frame.  The diagnosis fits the
registration (each instrument set-up's frame and the markers' offsets: a nuisance, reported apart with its
standard deviations), then tries the effects in order (default: geometry, joint compliance under
self-weight, a payload): an effect is named when its F test passes at ``alpha`` and, without
``--validate`` files, its k-fold cross-validated error drops (an effect that improves the fitted rows but
not the held-out ones is not named).  Parameters the identification Jacobian cannot tell apart are removed
and listed; joints whose load hardly varies are reported not observable.

The verdict: ``no_discrepancy`` (nothing named beyond the registration), ``explained`` (effects named) or
``unexplained`` (the file states the instrument's sigmas and the final fit's residuals exceed them: a
chi-square test at ``alpha``; a gap no effect of the library closes).  Without sigma columns the lack of fit
is not judged.

Written as one output set: ``report.json``, ``report.html``, ``summary.txt``, and the calibrated URDF and
robot file (``calibrated.urdf``, ``calibrated.yaml``, :mod:`vjm.calibration.write`); with ``--targets``, also
``commands.csv``, the joint values reaching those points under self-weight on the calibrated model
(:func:`vjm.cli.compensate.calibrated_commands`).
"""
from __future__ import annotations

import html
import json
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.stats import chi2

from linkfea.files.atomic import plain

from ..errors import VjmError
from . import report as cr
from .engine import effect_names, predict_points

#: the files of an absolute-pose diagnosis, one output set
POSE_FILES = cr.FILES + ("report.html",)
#: those of a parallel machine's (:mod:`vjm.calibration.parallel_diagnosis`): no calibrated robot file
PLATFORM_FILES = ("report.json", "summary.txt", "report.html")
SCHEMA = "vjm.diagnosis.absolute/1"
#: the F test's level of an effect when none is given (that of ``vjm calibrate``)
DEFAULT_ALPHA = 1e-3


@dataclass(frozen=True, eq=False)
class PoseDiagnosis:
    """Outcome of a diagnosis of absolute poses: the report (what report.json holds) and the calibration."""

    report: dict
    calibration: Any
    #: the text of commands.csv (``--targets``), or None
    commands: str | None = None

    @property
    def verdict(self) -> str:
        """"no_discrepancy", "explained" or "unexplained" (see the module docstring)."""
        return self.report["verdict"]

    @property
    def named(self) -> list:
        """The effects named, in order of what each buys."""
        return list(self.report["named_effects"])

    @property
    def confounded(self) -> list:
        """Always empty: parameters the data cannot tell apart are removed by rank, listed in ``not_identifiable``."""
        return []

    def summary(self) -> str:
        return summary(self.report)

    def save(self, out_dir, force: bool = False) -> None:
        """Write the report set (:data:`POSE_FILES`)."""
        write(self, out_dir, force)

    def __repr__(self) -> str:
        return f"<PoseDiagnosis {self.verdict}: named {self.named or 'nothing'}>"


def check_options(effects, suggest: int = 0, forces_only: bool = False, noise=None, known=None, default=None,
                  what: str = "absolute poses") -> tuple:
    """The effects tried (``effects`` names of ``known``, default a robot's effects,
    :func:`vjm.calibration.engine.effect_names`; None: ``default``, the default ones), and a refusal of the options that have no meaning on absolute poses
    (``what`` they are in the error line)."""
    if suggest:
        raise VjmError("--suggest designs (posture, load) rows of deflection data; absolute poses have no loads "
                       "to design (measure more configurations)")
    if forces_only:
        raise VjmError("--forces-only goes with --suggest, for deflection data")
    if noise is not None:
        raise VjmError("--tracker: absolute poses state their sigmas in <frame>.sigma columns (or the column map)")
    known = tuple(effect_names() if known is None else known)
    eff = tuple(effects) if effects else tuple(cr.default_effects() if default is None else default)
    bad = sorted(set(eff) - set(known))
    if bad:
        raise VjmError(f"--effect {bad[0]}: not an effect of {what}; effects: {', '.join(known)}")
    return eff


def lack_of_fit(cal, data, alpha: float) -> dict:
    """Chi-square test of the final fit's residuals against the sigmas the file states (every measured point's),
    on the rows fitted; ``{"judged": False, ...}`` without sigma columns."""
    frames = list(cal.markers)
    if not all(f in data.sigmas for f in frames):
        return {"judged": False, "why": "no sigma columns (<frame>.sigma or .sigma_x/_y/_z) for every point"}
    keep = np.setdiff1d(np.arange(data.n), np.asarray(cal.set_aside, dtype=int))
    rows = data.subset(keep)
    r = predict_points(cal, rows) - np.concatenate([rows.points[f] for f in frames])
    s = np.concatenate([rows.sigmas[f] for f in frames])
    stat = float(np.sum((r / s) ** 2))
    dof = max(r.size - len(cal.values), 1)
    p = float(chi2.sf(stat, dof))
    return {"judged": True, "chi2": stat, "dof": dof, "p_value": p, "lack_of_fit": p < alpha,
            "rms_over_sigma": float(np.sqrt(stat / r.size))}


def _verdict(named: list, lof: dict) -> str:
    if lof.get("lack_of_fit"):
        return "unexplained"
    return "explained" if named else "no_discrepancy"


def diagnose_poses(model, data, model_name: str | None = None, alpha: float | None = None, effects=None,
                   folds: int = 5, columns=None, validate=(), register: int = 30, outliers: bool = True,
                   progress=None) -> PoseDiagnosis:
    """Diagnose absolute poses (see the module docstring): ``model`` and ``data`` loaded or their files,
    ``columns`` a column map file, ``validate`` held-out files (each a new set-up, registered on ``register``
    of its poses, the robot frozen; then no k-fold), ``outliers`` rows no effect explains set aside."""
    eff = check_options(effects)
    opt = cr.Options(None, eff, DEFAULT_ALPHA if alpha is None else alpha, 0 if validate else folds, register)
    cr.check_options(opt)
    m, d, vals, opt = cr.inputs(model, data, columns, list(validate), opt, bool(effects), "measured point")
    t0 = time.perf_counter()
    cal, held = cr.run(m, d, vals, opt, robust=outliers)
    rep = cr.report(cal, opt, model_name or getattr(m, "path", None) or "<model>", d, held, time.perf_counter() - t0)
    lof = lack_of_fit(cal, d, opt.alpha)
    named = [e["effect"] for e in rep["effects"]]
    rep = {**rep, "schema": SCHEMA, "kind": "absolute_poses", "verdict": _verdict(named, lof),
           "named_effects": named, "lack_of_fit": lof}
    if progress:
        for s in rep["stages"]:
            progress(f"{s['name']}: {'named' if s['kept'] else 'not named'}, RMS {s['rms_mm']:.4f} mm")
    return PoseDiagnosis(rep, cal)


def _verdict_line(rep: dict) -> str:
    v = rep["verdict"]
    if v == "no_discrepancy":
        return "Verdict: no_discrepancy (nothing named beyond the registration)."
    line = f"Verdict: {v}; named: {', '.join(rep['named_effects']) or 'nothing'}."
    lof = rep["lack_of_fit"]
    if v == "unexplained":
        line += (f" The residuals stay {lof['rms_over_sigma']:.3g}x the stated sigmas (chi-square p = "
                 f"{lof['p_value']:.2g}): a gap no effect tried closes.")
    return line


def summary(rep: dict) -> str:
    """The text of summary.txt: the verdict, then the calibration's summary."""
    return _verdict_line(rep) + "\n" + cr.summary(rep)


def _table(rows, header) -> str:
    h = "".join(f"<th>{html.escape(str(c))}</th>" for c in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><tr>{h}</tr>{body}</table>"


def _pv(p) -> str:
    return "-" if p is None else (f"{p:.2g}" if p > 0 else "< 1e-300")


def _stats(st: dict) -> list:
    return [f"{st[k]:.4f}" for k in ("mean", "std", "max", "p95")]


def render_html(rep: dict) -> str:
    """report.html: the verdict, the effects named with the gap before and after each, the held-out errors,
    the registration apart, the parameters, what was removed."""
    eff = [[e["effect"], f"{e['buys_mm']:.4f}", *_stats(e["before_mm"]), *_stats(e["after_mm"]),
            _pv(e["p_value"])] for e in rep["effects"]]
    held = [[v["file"], v["registered_on"], v["rows"], *_stats(v["errors_mm"])] for v in rep["held_out"]["validate"]]
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
td,th{{border:1px solid #ccc;padding:3px 6px;font-size:90%}}</style></head><body>
<h1>Diagnosis of absolute poses</h1>
<p style="font-size:120%"><b>{html.escape(_verdict_line(rep))}</b></p>
<p>Model: <code>{html.escape(str(rep['model']))}</code>; data: <code>{html.escape(rep['data'])}</code> ({rep['rows']}
rows; points {html.escape(', '.join(rep['frames']))}); effects tried: {html.escape(', '.join(rep['effects_tried']))}.</p>
<h2>Effects named, in order of what each buys (position error of the fitted rows, mm)</h2>
{_table(eff, ["effect", "buys (mean)"] + [f"before {k}" for k in st] + [f"after {k}" for k in st] + ["p"])}
<h2>Stages</h2>{_table(cv, ["stage", "state", "RMS mm", "cross-validated RMS mm", "F test p", "note"])}
<h2>Held out (each file registered on a few of its poses, the {'machine' if rep.get('machine') == 'parallel' else 'robot'} frozen)</h2>
{_table(held, ["file", "registered on", "rows held out"] + [f"{k} mm" for k in st]) if held else
 f"<p>{rep['held_out']['folds']}-fold cross-validation (stages above).</p>"}
<h2>Registration (a nuisance, not an effect)</h2>
{_table(frames, ["set-up", "t (mm)", "standard deviations"])}{_table(marks, ["marker on", "offset (mm)", "std (mm)"])}
<h2>Fitted parameters</h2>{_table(pars, ["parameter", "value", "std", "unit"])}
<h2>Removed: not observable, not identifiable</h2>{_table(removed, ["parameter", "why"])}
</body></html>"""


def write(dg: PoseDiagnosis, out_dir, force: bool = False) -> None:
    """report.json, report.html, summary.txt, calibrated.urdf and calibrated.yaml, one set ``vjm diagnose``."""
    rep = plain(dg.report)
    extra = {"report.html": render_html(rep), "summary.txt": summary(rep)}
    if dg.commands is not None:
        extra["commands.csv"] = dg.commands
    if not is_robot(dg.calibration.model):
        _write_platform(out_dir, {"report.json": json.dumps(rep, indent=1) + "\n", **extra}, force)
        return
    cr.write_set(out_dir, dg.calibration, rep, force, set_name="vjm diagnose", extra=extra)


def _write_platform(out_dir, texts: dict, force: bool) -> None:
    """A parallel machine's report set (:data:`PLATFORM_FILES`), one set ``vjm diagnose``."""
    from pathlib import Path

    from linkfea.files.outputs import OutputSet
    from linkfea.files.outputs import check_folder as check

    check(out_dir, PLATFORM_FILES, force=force)
    with OutputSet(Path(out_dir), "vjm diagnose") as s:
        for name in PLATFORM_FILES:
            Path(s.path(name)).write_text(texts[name], encoding="utf-8")


def check_folder(out_dir, force: bool = False, commands: bool = False, robot: bool = True) -> None:
    """Refuse, before any work, an output folder that will not do (``commands``: commands.csv too; ``robot``
    False: a parallel machine's set, :data:`PLATFORM_FILES`)."""
    from linkfea.files.outputs import check_folder as check

    check(out_dir, (POSE_FILES if robot else PLATFORM_FILES) + (("commands.csv",) if commands else ()), force=force)


def is_robot(model) -> bool:
    """A serial or tree robot (a model file with ``urdf:`` or ``dh:``): its data are absolute poses."""
    return hasattr(model, "tree")

