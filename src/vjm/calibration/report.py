"""``vjm calibrate``: a robot calibrated on absolute poses, held out, reported and written back as one set.

The run (:func:`run`) reads the robot model, the calibration file through its column map and the
``--validate`` files, fits :func:`vjm.calibration.engine.calibrate` and holds out every validation file, the
robot frozen: a file measured in the fitted set-up (:func:`held_setup`: its ``group`` column names fitted
groups, or ``--same-setup``) on the fitted registration, every row held out; any other file, a new
instrument set-up, registered on a few of its own poses, the error measured on its other poses.  :func:`report` gathers what a user judges a calibration on:

- the effects named, in order of what each buys (the drop of the mean position error of its stage), each
  with the error before and after it (mean, std, max, 95th percentile, mm, on the fitted rows), and its
  ``size``: what it does to the tool at the measured poses and at ``home:`` (mm), a joint compliance's
  stiffness with its interval (:mod:`vjm.calibration.sizes`);
- the held-out error: k-fold cross-validated RMS of the stages (``folds``), and the validation files';
- the registration (instrument frame of each group, marker offset) and its standard deviations, apart;
- the parameters removed: combinations that cannot be identified, joints that are not observable;
- the rows set aside as outliers (:mod:`vjm.calibration.robust`), with their errors.

:func:`write_set` writes ``report.json``, ``summary.txt`` (:func:`vjm.discrepancy.summary.pose_text`),
``calibrated.urdf`` and ``calibrated.yaml`` into a folder as one set (:mod:`linkfea.files.outputs`: complete or untouched, a manifest, never a user's file).
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..effects import absolute
from ..errors import VjmError
from ..stats.fit import MAX_FOLDS
from .engine import calibrate, effect_names, error_stats, instrument_frame, position_errors, register
from .nominal import totals
from .result import Calibration
from .robust import calibrate_robust
from .sizes import as_mapping, effect_sizes

FILES = ("report.json", "summary.txt", "calibrated.urdf", "calibrated.yaml")


def default_effects() -> tuple:
    """The effects tried when none are asked for, in this order: a robot's effects declared ``default``
    (:mod:`vjm.effects.absolute`)."""
    return absolute.defaults("serial")


SET_NAME = "vjm calibrate"
SCHEMA = "vjm.calibration/1"


@dataclass(frozen=True)
class Options:
    """What the command line asks: the measured ``frame`` (a name or several; None: every point the data
    measure), the ``effects``
    tried, the F test's ``alpha``, ``folds`` of cross-validation (0: none), and the number of poses
    ``register_on`` that register each validation file in a new set-up; ``same_setup``: validation files
    without a ``group`` column are in the fitted data's one set-up."""

    frame: str | tuple | None = None
    effects: tuple = field(default_factory=effect_names)
    alpha: float = 1e-3
    folds: int = 0
    register_on: int = 30
    same_setup: bool = False
    #: what an effect must buy (mm, held out) to be named; None: 1 % of the error it starts from
    min_gain: Any = None   # mm, or a vjm.stats.staged.Practical


def check_options(opt: Options) -> None:
    """Refuse bad options before any work."""
    known = effect_names()
    bad = set(opt.effects) - set(known)
    if bad:
        raise VjmError(f"--effects: unknown effect(s) {', '.join(sorted(bad))}; effects: {', '.join(known)}")
    if opt.folds == 1 or opt.folds < 0 or opt.folds > MAX_FOLDS:
        raise VjmError(f"--folds must be 0 (no cross-validation) or at least 2 and at most {MAX_FOLDS}, got "
                       f"{opt.folds}")
    if opt.register_on < 3:
        raise VjmError(f"--register must be at least 3 poses (an instrument frame has 6 parameters), got "
                       f"{opt.register_on}")
    if not 0 < opt.alpha < 1:
        raise VjmError(f"--alpha must be between 0 and 1, got {opt.alpha}")


def robot_of(model) -> None:
    """Refuse a parallel machine: the absolute-pose calibration takes serial and tree robots."""
    if model.kind != "serial":
        raise VjmError(f"{getattr(model, 'path', None) or 'the model'}: a parallel machine; vjm calibrate takes a "
                       f"serial or tree robot (a model file with urdf: or dh:)")


def check_writeback(model) -> None:
    """Refuse, before any work, a robot whose calibration cannot be written back (no URDF file nor DH table)."""
    from .write import writable

    if not writable(model):
        raise VjmError(f"{model.path}: the robot has no URDF file nor DH table to write the calibration back into")


def check_frame(model, data, frame=None, option: str = "--frame") -> tuple:
    """The measured frames: ``frame`` (a name, or several), or every point the data measure; each must be
    measured by the data and be a frame of the model (errors name the ``option`` that chose them)."""
    frames = tuple(data.points) if not frame else ((frame,) if isinstance(frame, str) else tuple(frame))
    twice = sorted({f for f in frames if frames.count(f) > 1})
    if twice:
        raise VjmError(f"{option} {twice[0]} is given twice: each measured point counts once")
    names = {f.name for f in model.tree.frames}
    for f in frames:
        if f not in data.points:
            raise VjmError(f"{option} {f}: {data.source} measures {', '.join(data.points)}")
        if f not in names:
            raise VjmError(f"{option} {f}: not a frame of the model ({model.path}); measured points must be frames "
                           f"or links of the URDF")
    return frames


def effects_for(effects: tuple, frames: tuple, asked: bool) -> tuple:
    """The effects tried on ``frames``: a payload is weighed at one marker, so with several measured points it
    leaves the default effects (``asked`` False) and is refused when asked for."""
    one = [e for e in effects if e in absolute.POSES and absolute.POSES[e].single_marker]
    if len(frames) > 1 and one:
        if asked:
            raise VjmError(f"--effects {one[0]}: a {one[0]} is weighed at one marker; the data measure "
                           f"{len(frames)} points ({', '.join(frames)}): leave it out or name one --frame")
        return tuple(e for e in effects if e not in one)
    return effects


def check_validation(data, k: int) -> None:
    """A validation file registered on its own poses needs more rows than the ``k`` that register it."""
    if data.n <= k:
        raise VjmError(f"{data.source}: {data.n} rows; a validation file needs more than --register ({k}) rows "
                       f"(or its rows in the fitted set-up: a group column of the fitted data's groups, or "
                       f"--same-setup)")


def held_setup(data, fitted: tuple, same_setup: bool = False):
    """A validation file's rows as held out: in the fitted set-up (its ``group`` column names only groups of the
    ``fitted`` data, or it has none and ``same_setup`` says it was measured in the fitted data's one set-up),
    they keep that group and its fitted registration; otherwise they are one new set-up
    (``validate:<file>``), registered on a few of its poses.  A file's ``group`` column decides for it, with or
    without ``same_setup``.  A file mixing fitted and other groups, and ``same_setup`` with several fitted
    set-ups, are refused."""
    name = os.path.basename(data.source) or "data"
    if data.group is None:
        if not same_setup:
            return data.with_group(f"validate:{name}")
        if len(fitted) != 1:
            raise VjmError(f"--same-setup: the fitted data hold {len(fitted)} set-ups (groups {', '.join(fitted)}); "
                           f"give {name} a group column naming its set-up")
        return data.with_group(fitted[0])
    groups = sorted(set(map(str, data.group)))
    other = [g for g in groups if g not in fitted]
    if not other:
        return data
    if len(other) < len(groups):
        raise VjmError(f"{name}: rows of the fitted set-up(s) {', '.join(g for g in groups if g in fitted)} and of "
                       f"other groups ({', '.join(other)}); hold out one set-up per file")
    return data.with_group(f"validate:{name}")


def in_fitted_setup(cal: Calibration, data) -> bool:
    """Whether every row of ``data`` is in a set-up the calibration registered."""
    return set(map(str, data.groups)) <= set(map(str, cal.frames))


def split(data, k: int):
    """(k evenly spaced rows of ``data`` that register its set-up, the other rows)."""
    check_validation(data, k)
    mask = np.zeros(data.n, dtype=bool)
    mask[np.linspace(0, data.n - 1, k).astype(int)] = True
    return data.subset(mask), data.subset(~mask)


def held_out(cal: Calibration, data, k: int, reg=register) -> dict:
    """A validation file's held-out errors, the robot or machine frozen: every row on the fitted registration
    when it is in the fitted set-up (:func:`held_setup`), else its set-up registered by ``reg`` on ``k`` of its
    poses and the error on the others (``registered_on``: 0 and ``k``)."""
    if in_fitted_setup(cal, data):
        return {"file": data.source, "registered_on": 0, "registered": "on the fitted set-up", "rows": int(data.n),
                "errors_mm": error_stats(position_errors(cal, data))}
    few, rest = split(data, k)
    return {"file": data.source, "registered_on": k, "registered": f"on {k} of its poses", "rows": int(rest.n),
            "errors_mm": error_stats(position_errors(reg(cal, few), rest))}


def validate(cal: Calibration, data, k: int) -> dict:
    """A robot's validation file held out (:func:`held_out`)."""
    return held_out(cal, data, k)


def _unit(name: str) -> str:
    """The unit of a robot's parameter, as its effect declares it (:mod:`vjm.effects.absolute`)."""
    return absolute.owner(name, "serial")[1]


def _num(v: float):
    return None if np.isnan(v) else float(v)


def _stage(s) -> dict:
    return {"name": s.name, "kept": s.kept, "n_params": s.n_params, "rms_mm": s.rms,
            "p_value": _num(s.p_value), "cv_rms_mm": _num(s.cv_rms), "errors_mm": s.stats, "note": s.note,
            "gain_mm": _num(getattr(s, "gain", float("nan"))), "gain_se_mm": _num(getattr(s, "gain_se", float("nan"))),
            "threshold_mm": _num(getattr(s, "threshold", float("nan"))), "category": getattr(s, "category", "")}


def stands_in(cal: Calibration) -> list:
    """The effects that fit only out of their physical domain ("stands in for something else"): the values
    each wanted (beyond their bound by more than 2 standard deviations), what it buys out of its domain
    (fitted rows, mm) and how much more than the effects named (``beyond_named_mm``)."""
    final = [s for s in cal.stages if s.kept][-1]
    return [{"effect": s.name, "why": s.note, "buys_mm": float(s.gain), "threshold_mm": float(s.threshold),
             "beyond_named_mm": float(final.rms - s.rms), "rms_mm": s.rms,
             "wanted": [dict(w) for w in s.wanted]}
            for s in cal.stages if getattr(s, "category", "") == "stands_in"]


def negligible(cal: Calibration) -> list:
    """The effects whose F test passes but whose gain is below its fold-to-fold standard error or the practical
    threshold ("significant but negligible"): the gain (mm), its standard error and the threshold."""
    return [{"effect": s.name, "gain_mm": float(s.gain), "gain_se_mm": _num(s.gain_se),
             "threshold_mm": float(s.threshold), "p_value": _num(s.p_value), "why": s.note}
            for s in cal.stages if getattr(s, "category", "") == "negligible"]


def effects_named(cal: Calibration) -> list:
    """The kept stages beyond the registration, in order of what each buys: (drop of the mean error, before,
    after, stage), largest drop first; before/after are the fitted rows' errors around the stage."""
    out = []
    before = cal.stages[0].stats
    for s in cal.stages[1:]:
        if s.kept:
            out.append({"effect": s.name, "buys_mm": before["mean"] - s.stats["mean"], "before_mm": before,
                        "after_mm": s.stats, "p_value": s.p_value,
                        "cv_rms_mm": None if np.isnan(s.cv_rms) else s.cv_rms,
                        "parameters": [k for k in cal.robot_values()
                                       if (cal.kinds[k][0] if k in cal.kinds else _kind(k)) == s.name]})
            before = s.stats
    return sorted(out, key=lambda e: -e["buys_mm"])


def _kind(name: str) -> str:
    """The effect forming a robot's parameter (:mod:`vjm.effects.absolute`)."""
    return absolute.owner(name, "serial")[0].name


def registration(cal: Calibration) -> dict:
    """The nuisance, apart: each group's instrument frame (instrument = R base + t) and the marker, with the
    standard deviations of the fitted corrections."""
    groups = {}
    for g in cal.frames:
        R, t = instrument_frame(cal, g)
        groups[str(g)] = {"R": R.tolist(), "t_mm": t.tolist(),
                          "std": {k[len(f"reg[{g}]."):]: cal.std.get(k) for k in cal.values if k.startswith(f"reg[{g}].")}}
    markers = [{"frame": f, "offset_mm": p.tolist(), "std_mm": [cal.std.get(f"{f}.p{c}", 0.0) for c in "xyz"]}
               for f, p in cal.markers.items()]
    return {"instrument_frames": groups, "marker": markers[0], "markers": markers,
            "std_units": "t*: mm, r*: rad (a rotation vector after the Kabsch start)"}


def sized(cal: Calibration, data, effects: list) -> list:
    """The named ``effects`` (:func:`effects_named`), each with its ``size`` (:func:`vjm.calibration.sizes.effect_sizes`
    on the fitted rows of ``data``)."""
    sizes = {s.effect: s for s in effect_sizes(cal, data, {e["effect"]: e["parameters"] for e in effects})}
    return [{**e, "size": as_mapping(sizes[e["effect"]]) if e["effect"] in sizes else None} for e in effects]


def row_errors(cal: Calibration, data) -> tuple[np.ndarray, np.ndarray]:
    """The fitted rows' position errors (n,) mm: with the registration only (the model as its file states it,
    each set-up's instrument frame and the markers fitted again), and calibrated."""
    keep = np.setdiff1d(np.arange(data.n), np.asarray(cal.set_aside, dtype=int))
    rows = data.subset(keep)
    robot = cal.robot_values()
    bare = replace(cal, values={k: v for k, v in cal.values.items() if k not in robot},
                   std={k: v for k, v in cal.std.items() if k not in robot})
    if cal.model.kind == "parallel":
        from .parallel_fit import register_platform

        before = register_platform(bare, rows)
    else:
        before = register(bare, rows, marker=True)
    return position_errors(before, rows), position_errors(cal, rows)


def report(cal: Calibration, opt: Options, model_path, data, validations: list, seconds: float) -> dict:
    """The report's mapping (see the module docstring)."""
    removed = [{"parameter": n, "why": why} for n, why in cal.removed]
    aside = position_errors(cal, data.subset(list(cal.set_aside))) if cal.set_aside else []
    total = totals(cal.model, cal.robot_values()) if cal.model.kind == "serial" else {}
    return {
        "schema": SCHEMA, "model": str(model_path), "data": data.source, "rows": int(data.n), "frame": cal.frame,
        "frames": list(cal.markers),
        "effects_tried": list(opt.effects), "alpha": opt.alpha,
        "effects": sized(cal, data, effects_named(cal)),
        "stages": [_stage(s) for s in cal.stages],
        # "value" is what the fit found: for a parameter the model file states, the correction to "nominal"
        "parameters": {k: {"value": v, "std": cal.std.get(k), "unit": cal.kinds[k][1] if k in cal.kinds else _unit(k),
                           **total.get(k, {})} for k, v in cal.robot_values().items()},
        "std_method": cal.std_method,
        "held_out": {"folds": opt.folds, "validate": validations},
        "registration": registration(cal),
        "not_identifiable": [r for r in removed if not r["why"].startswith("not observable")],
        "not_observable": [r for r in removed if r["why"].startswith("not observable")],
        "set_aside": [{"row": i, "error_mm": float(e)} for i, e in zip(cal.set_aside, aside)],   # row: 0-based
        "seconds": seconds,
        "stands_in": stands_in(cal),
        "negligible": negligible(cal),
    }


def inputs(model, data, columns, validate_paths, opt: Options, asked: bool, option: str = "--frame") -> tuple:
    """(robot model, data, validation sets, options with the measured frames and the effects tried) of a run,
    checked before any fitting; ``model`` and ``data`` a loaded model and data set, or their files (a data file
    without a ``group`` column is one instrument set-up, named by the file; each validation file a new one)."""
    from ..modelio.read import load_model
    from .poses import check_against, check_distinct, read_column_map, read_poses

    m: Any = load_model(model) if isinstance(model, (str, os.PathLike)) else model
    robot_of(m)
    check_writeback(m)
    cmap = read_column_map(columns) if columns is not None else None
    if isinstance(data, (str, os.PathLike)):
        d = read_poses(data, cmap, m.q_names)
        d = d if d.group is not None else d.with_group(Path(data).name)
    else:
        d = data if data.group is not None else data.with_group(os.path.basename(data.source) or "data")
    frames = check_frame(m, d, opt.frame, option)
    opt = replace(opt, frame=frames, effects=effects_for(opt.effects, frames, asked))
    fitted = tuple(dict.fromkeys(map(str, d.group)))
    vals = [held_setup(read_poses(v, cmap, m.q_names), fitted, opt.same_setup) for v in validate_paths]
    for v in vals:
        check_frame(m, v, frames, option)
        if v.group[0] not in fitted:
            check_validation(v, opt.register_on)
    check_distinct(d)
    for x in [d, *vals]:
        check_against(m, x, frames)
    return m, d, vals, opt


def run(model, data, validate_sets: list, opt: Options, robust: bool = True, progress=None) -> tuple[Calibration, list]:
    """Fit and hold out: (the calibration, the validation files' held-out errors); ``robust``: rows no effect
    explains set aside (:mod:`vjm.calibration.robust`); ``progress`` told a line per stage."""
    fit = calibrate_robust if robust else calibrate
    cal = fit(model, data, opt.frame, effects=opt.effects, alpha=opt.alpha, folds=opt.folds, min_gain=opt.min_gain,
              progress=progress)
    return cal, [validate(cal, v, opt.register_on) for v in validate_sets]


def write_set(out, cal: Calibration, rep: dict, force: bool = False, set_name: str = SET_NAME,
              extra: dict | None = None) -> list[Path]:
    """The four files of :data:`FILES` under ``out``, as one set ``set_name``; ``extra`` {name: text} adds
    files or replaces the text of one of them."""
    from linkfea.files.atomic import plain
    from linkfea.files.outputs import OutputSet, check_folder

    from ..discrepancy.summary import pose_text
    from .write import calibrated_files

    extra = extra or {}
    out = Path(out)
    check_folder(out, FILES + tuple(k for k in extra if k not in FILES), force=force)
    check_writeback(cal.model)
    texts = {"report.json": json.dumps(plain(rep), indent=1) + "\n", "summary.txt": pose_text(rep),
             **calibrated_files(cal), **extra}   # a DH table's set has no calibrated.urdf
    files = tuple(k for k in FILES if k in texts) + tuple(k for k in extra if k not in FILES)
    with OutputSet(out, set_name) as s:
        for name in files:
            Path(s.path(name)).write_text(texts[name], encoding="utf-8")
    return [out / n for n in files]
