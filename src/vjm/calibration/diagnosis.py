"""``vjm diagnose`` (and ``vjm calibrate``) on absolute poses: a robot's measured points, diagnosed by the
calibration engine (one home for the fit: :func:`vjm.calibration.engine.calibrate`).

The data (:class:`vjm.calibration.poses.AbsolutePoses`, read as it is through a column map) hold per row the
joint values and the points an instrument measured in its own frame.  The diagnosis fits the
registration (each instrument set-up's frame and the markers' offsets: a nuisance, reported apart with its
standard deviations), then tries the effects in order: with none asked, every registered effect that applies
to the robot and the data (:func:`candidates`; ``--effect`` names narrow, ``--effect -name`` excludes one).
The plan (candidates, parameters, an estimate of the time) is told before the work and a line per stage
while it runs.  Each parameter is fitted within its physical domain (:func:`vjm.effects.absolute.domain`).
An effect is named when its F test passes at ``alpha``, no parameter of it has to leave its domain (else it
"stands in for something else"), and its k-fold held-out gain exceeds the gain's fold-to-fold standard
error and a practical threshold (``min_gain`` mm; default 1 % of the error the effect starts from, and at
least 10 % of the stated instrument sigma where the file states sigmas): a significant effect below it is "significant
but negligible", its gain in mm reported.  Parameters the identification Jacobian cannot tell apart are
removed and listed; joints whose load hardly varies are reported not observable.

The verdict: ``no_discrepancy`` (nothing named beyond the registration), ``explained`` (effects named) or
``unexplained``: the file states the instrument's sigmas and the final fit's residuals exceed them (a
chi-square test at ``alpha``), or an effect that stands in for something else buys what the effects named do
not (by the practical threshold): a gap no effect of the library closes within its physical domain.  Without
sigma columns the lack of fit is not judged, and the summary says so beside the verdict.

The outcome is a :class:`vjm.discrepancy.diagnosis.Diagnosis` (one result type for every data kind) whose
report is a :class:`PoseReport`.  Written as one output set: ``report.json``, ``report.html``, ``summary.txt``,
and the calibrated URDF and robot file (``calibrated.urdf``, ``calibrated.yaml``, :mod:`vjm.calibration.write`); with ``--targets``, also
``commands.csv``, the joint values reaching those points under self-weight on the calibrated model
(:func:`vjm.calibration.write.calibrated_commands`).
"""
from __future__ import annotations

import dataclasses
import json
import sys
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from linkfea.files.atomic import plain

from ..discrepancy.diagnosis import Diagnosis
from ..discrepancy.report import render_html
from ..discrepancy.stages.record import FrozenReport
from ..discrepancy.summary import pose_text
from ..errors import VjmError
from ..maps.grid import plan
from ..stats.fit import chi2_p
from ..stats.staged import Practical
from . import report as cr
from .engine import check_data, effect_names, predict_points
from .poses import quiet_limits, warn_limits

#: the files of an absolute-pose diagnosis, one output set
POSE_FILES = cr.FILES + ("report.html",)
#: those of a parallel machine's (:mod:`vjm.calibration.parallel_diagnosis`): no calibrated robot file
PLATFORM_FILES = ("report.json", "summary.txt", "report.html")
SCHEMA = "vjm.diagnosis.absolute/1"
#: memory (B) and time (s) per row of a calibration at the default effects and folds, for the estimate before
#: the work: 6 kB measured (UR10, 20,000 rows); 1.5 ms (200,000 rows on one machine) to 10 ms (20,000 rows on a
#: shared 2-core one)
ROW_COST = (8e3, 5e-3)
#: time (s) per row and candidate parameter of a stage's fit (the plan's estimate: each stage fits the
#: parameters kept before it and its own, once and once per fold): the UR10's whole library on series A,
#: 106 s measured on 2 cores other jobs loaded to 8
FIT_COST = 2e-6
#: the practical threshold of an effect's held-out gain where the file states sigmas: this fraction of them
SIGMA_FRACTION = 0.1
#: the F test's level of an effect when none is given (that of ``vjm calibrate``)
DEFAULT_ALPHA = 1e-3


@dataclass(frozen=True, kw_only=True)
class PoseReport(FrozenReport):
    """What an absolute-pose diagnosis' report.json holds, in the file's order (lengths mm; see
    :func:`vjm.calibration.report.report` for the calibration's part); mappings and sequences frozen.
    ``machine`` and ``actuators`` (a parallel machine's) are left out of a robot's file."""

    schema: str = SCHEMA
    model: str
    data: str
    rows: int
    frame: object
    frames: tuple
    effects_tried: tuple
    alpha: float
    effects: tuple
    stages: tuple
    parameters: Mapping
    #: how the parameters' standard deviations were computed (:mod:`vjm.stats.uncertainty`)
    std_method: str = ""
    held_out: Mapping
    registration: Mapping
    not_identifiable: tuple
    not_observable: tuple
    set_aside: tuple
    seconds: float
    kind: str = "absolute_poses"
    machine: str | None = None
    actuators: tuple | None = None
    verdict: str
    named_effects: tuple
    lack_of_fit: Mapping = field(default_factory=dict)
    #: effects that fit only out of their physical domain, with the values they wanted
    stands_in: tuple = ()
    #: effects whose F test passes but whose gain is below its standard error or the practical threshold
    negligible: tuple = ()
    min_gain: Mapping = field(default_factory=dict)

    OPTIONAL = ("machine", "actuators")


def check_options(effects, suggest: int = 0, forces_only: bool = False, noise=None, known=None, default=None,
                  what: str = "absolute poses") -> tuple:
    """The effects tried, and a refusal of the options that have no meaning on absolute poses (``what`` they
    are in the error line).  ``effects``: names of ``known`` (default a robot's effects,
    :func:`vjm.calibration.engine.effect_names`), each positive name a candidate (in this order) and each
    ``-name`` one excluded; without a positive name the candidates are ``default`` (None: a robot's default
    ones) less those excluded."""
    if suggest:
        raise VjmError("--suggest designs (posture, load) rows of deflection data; absolute poses have no loads "
                       "to design (measure more configurations)")
    if forces_only:
        raise VjmError("--forces-only goes with --suggest, for deflection data")
    if noise is not None:
        raise VjmError("--tracker: absolute poses state their sigmas in <frame>.sigma columns (or the column map)")
    known = tuple(effect_names() if known is None else known)
    asked = asked_effects(effects)
    out = [n[1:] for n in effects or () if n.startswith("-")]
    bad = [n for n in out if n not in known]
    if bad:
        raise VjmError(f"--effect -{bad[0]}: not an effect of {what} to exclude; effects: {', '.join(known)}")
    eff = asked or tuple(cr.default_effects() if default is None else default)
    bad = sorted(set(eff) - set(known))
    if bad:
        raise VjmError(f"--effect {bad[0]}: not an effect of {what}; effects: {', '.join(known)}")
    eff = tuple(e for e in eff if e not in out)
    if not eff:
        raise VjmError(f"--effect: every candidate excluded (-{', -'.join(out)}); effects: {', '.join(known)}")
    return eff


def asked_effects(effects) -> tuple:
    """The effects asked for by name in ``effects`` (its ``-name`` exclusions left out)."""
    return tuple(n for n in effects or () if not n.startswith("-"))


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
    p = chi2_p(stat, dof)
    return {"judged": True, "chi2": stat, "dof": dof, "p_value": p, "lack_of_fit": p < alpha,
            "rms_over_sigma": float(np.sqrt(stat / r.size))}


def _verdict(named: list, lof: dict, open_gap: bool = False) -> str:
    if lof.get("lack_of_fit") or open_gap:
        return "unexplained"
    return "explained" if named else "no_discrepancy"


def open_gap(stands: list) -> bool:
    """Whether an effect that stands in for something else (``stands``, :func:`vjm.calibration.report.stands_in`)
    buys, out of its domain, at least the practical threshold more than the effects named: what the data show is
    then not explained."""
    return any(s["beyond_named_mm"] >= s["threshold_mm"] for s in stands)


def pose_report(rep: dict, cal, data, alpha: float, **machine) -> PoseReport:
    """The typed report of a calibration's report mapping (:func:`vjm.calibration.report.report`): the lack
    of fit judged, the verdict and the effects named added (``machine``: a parallel machine's ``machine`` and
    ``actuators``)."""
    lof = lack_of_fit(cal, data, alpha)
    named = [e["effect"] for e in rep["effects"]]
    gap = open_gap(rep.get("stands_in", ()))
    fields = {**rep, "schema": SCHEMA, **machine, "verdict": _verdict(named, lof, gap), "named_effects": named,
              "lack_of_fit": lof}
    return PoseReport(**fields)


def progress_lines(rep: PoseReport, progress) -> None:
    """A line per stage to ``progress`` (if given)."""
    if progress:
        for s in rep["stages"]:
            progress(f"{s['name']}: {'named' if s['kept'] else 'not named'}, RMS {s['rms_mm']:.4f} mm")


def candidates(model, data, effects) -> tuple:
    """The effects tried on ``data``: those ``effects`` names (they narrow), or every registered effect that
    applies to the robot and the data (:func:`vjm.effects.absolute.applicable`) less the ``-name``s excluded."""
    from ..effects.absolute import applicable

    asked = asked_effects(effects)
    if asked:
        return asked
    out = {n[1:] for n in effects or () if n.startswith("-")}
    return tuple(e for e in applicable(model, "absolute", data) if e not in out)


def check_min_gain(min_gain) -> float | None:
    """``--min-gain`` (mm): a finite number >= 0, or None (the default threshold)."""
    if min_gain is None:
        return None
    if isinstance(min_gain, bool) or not isinstance(min_gain, (int, float)) or not np.isfinite(min_gain) \
            or min_gain < 0:
        raise VjmError(f"--min-gain must be a finite number of mm >= 0 (what an effect must buy), got {min_gain!r}")
    return float(min_gain)


def practical_gain(data, frames, min_gain: float | None) -> tuple[Practical, float | None, str]:
    """(the practical threshold, its mm when fixed, how it was set): the ``min_gain`` asked; else 1 % of the
    error each effect starts from, and at least :data:`SIGMA_FRACTION` of the median stated sigma where the file
    states every point's (the larger: residuals many times the sigmas would let effects of a micrometre pass)."""
    if min_gain is not None:
        return Practical(min_gain), min_gain, "--min-gain"
    if frames and all(f in data.sigmas for f in frames):
        sig = float(np.median(np.concatenate([np.ravel(data.sigmas[f]) for f in frames])))
        return (Practical(None, floor=SIGMA_FRACTION * sig), None,
                f"1 % of the error each effect starts from, at least {100 * SIGMA_FRACTION:g} % of the stated "
                f"sigma ({SIGMA_FRACTION * sig:.3g} mm)")
    return Practical(), None, "1 % of the error each effect starts from"


def plan_lines(model, data, opt) -> list:
    """The plan told before the work: the candidates and their parameters, the folds, an estimate of the time
    (:data:`FIT_COST` per row and parameter of each stage's fits)."""
    from .engine import parameter_counts

    counts = parameter_counts(model, opt.frame, data, opt.effects)
    fits = 1 + opt.folds
    total, cost = counts.get("nuisance", 0), 0.0
    cost += total * fits
    for e in opt.effects:
        total += counts.get(e, 0)
        cost += total * fits
    est = FIT_COST * data.n * len(opt.frame) * cost
    return [f"plan: {len(opt.effects)} candidate effects, {total} parameters ("
            + ", ".join(f"{e} {counts.get(e, 0)}" for e in opt.effects)
            + f"; registration {counts.get('nuisance', 0)}), {data.n} rows, "
            + (f"{opt.folds}-fold cross-validation" if opt.folds else "no cross-validation")
            + f"; about {est:.0f} s"]


def read(path, model, columns=None):
    """A robot's absolute poses (its joints' columns required, through the column map file ``columns``), one
    instrument set-up named by the file without a ``group`` column; a robot whose calibration cannot be
    written back refused first."""
    from .poses import read_column_map, read_poses

    cr.robot_of(model)
    cr.check_writeback(model)
    d = read_poses(path, read_column_map(columns) if columns is not None else None, model.q_names)
    return d if d.group is not None else d.with_group(Path(path).name)


def diagnose_poses(model, data, model_name: str | None = None, alpha: float | None = None, effects=None,
                   folds: int = 5, columns=None, validate=(), register: int = 30, outliers: bool = True,
                   progress=None, frame=None, same_setup: bool = False, min_gain: float | None = None) -> Diagnosis:
    """Diagnose absolute poses (see the module docstring): ``model`` and ``data`` loaded or their files,
    ``columns`` a column map file, ``validate`` held-out files (then no k-fold; the robot frozen, each on the
    fitted registration when its rows are in the fitted set-up: a ``group`` column of fitted groups, or none
    and ``same_setup``; else a new set-up registered on ``register`` of its poses), ``outliers`` rows no effect
    explains set aside, ``frame`` the measured points fitted (a name or several; None: every point of the
    data); ``min_gain`` the practical threshold in mm (None: the default, the module docstring)."""
    eff = check_options(effects)
    min_gain = check_min_gain(min_gain)
    opt = cr.Options(frame or None, eff, DEFAULT_ALPHA if alpha is None else alpha, folds, register, same_setup)
    cr.check_options(opt)
    m, d, vals, opt = cr.inputs(model, data, columns, list(validate), opt, bool(asked_effects(effects)),
                                "--frame" if frame else "measured point")
    practical, gain, how = practical_gain(d, opt.frame, min_gain)
    opt = dataclasses.replace(opt, effects=cr.effects_for(candidates(m, d, effects), opt.frame, False)
                              if not asked_effects(effects) else opt.effects, min_gain=practical)
    say = progress or (lambda line: print(line, file=sys.stderr))
    # before the work: a long run says so, one too large for the memory is refused
    plan("vjm calibrate", d.n, *ROW_COST, unit="rows", hint="calibrate on a subset of the rows (postures spread "
         "over the workspace, not repeats)", progress=say)
    check_data(m, d, (opt.frame,) if isinstance(opt.frame, str) else tuple(opt.frame), opt.effects, opt.folds)
    for line in plan_lines(m, d, opt):   # after the checks: a refusal is the one line said
        say(line)
    t0 = time.perf_counter()
    with quiet_limits():  # the joint limits said once on the whole data, not once per fold and evaluation
        cal, held = cr.run(m, d, vals, opt, robust=outliers, progress=say)
        rep = cr.report(cal, opt, model_name or getattr(m, "path", None) or "<model>", d, held,
                        time.perf_counter() - t0)
        rep["min_gain"] = {"mm": gain, "set_by": how}
        report = pose_report(rep, cal, d, opt.alpha)
        before, after = cr.row_errors(cal, d)
    for x in [d, *vals]:
        warn_limits(m, x)
    progress_lines(report, progress)
    return Diagnosis(report, "absolute", write, calibrated, calibration=cal, rms_pose_before=before,
                     rms_pose_after=after)


def calibrated(dg: Diagnosis):
    """The calibrated model in memory: a robot's (:func:`vjm.calibration.write.calibrated_model`); None for a
    parallel machine, whose calibration is reported, not written back into a model."""
    from .write import calibrated_model

    return calibrated_model(dg.calibration) if dg.calibration.model.kind == "serial" else None


def write(dg: Diagnosis, out_dir, force: bool = False, set_name: str = "vjm diagnose") -> None:
    """report.json, report.html, summary.txt, calibrated.urdf and calibrated.yaml (a parallel machine's: the
    first three, :data:`PLATFORM_FILES`), one set ``set_name``."""
    rep = plain(dg.report.to_dict())
    rows = None if dg.rms_pose_after is None else (dg.rms_pose_before, dg.rms_pose_after)
    extra = {"report.html": render_html(rep, rows=rows), "summary.txt": pose_text(rep)}
    if dg.commands is not None:
        extra["commands.csv"] = dg.commands
    if dg.calibration.model.kind != "serial":
        _write_platform(out_dir, {"report.json": json.dumps(rep, indent=1) + "\n", **extra}, force, set_name)
        return
    cr.write_set(out_dir, dg.calibration, rep, force, set_name=set_name, extra=extra)


def _write_platform(out_dir, texts: dict, force: bool, set_name: str) -> None:
    """A parallel machine's report set (:data:`PLATFORM_FILES`)."""
    from linkfea.files.outputs import OutputSet
    from linkfea.files.outputs import check_folder as check

    check(out_dir, PLATFORM_FILES, force=force)
    with OutputSet(Path(out_dir), set_name) as s:
        for name in PLATFORM_FILES:
            Path(s.path(name)).write_text(texts[name], encoding="utf-8")
