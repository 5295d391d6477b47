"""``vjm diagnose`` on a parallel machine's absolute poses: the platform's point measured by an instrument at
commanded actuator values, diagnosed by the calibration engine (:func:`vjm.calibration.parallel_fit.calibrate_platform`,
the robot's stages on the measurement model of :mod:`vjm.calibration.parallel`).

The file has a column per actuator, named ``<chain>.<variable>`` (``A1.l`` of a hexapod's strut, ``x.q0``
of an Orthoglide's carriage: :func:`vjm.kinematics.forward.actuator_names`), and the measured point
``platform.x``, ``platform.y``, ``platform.z`` (mm, instrument frame; optional ``platform.sigma``,
``group``), read as it is through a column map (``--columns``) like a robot's.  The report is that of a
robot's poses (:mod:`vjm.calibration.diagnosis`): the effects named in order of what each buys (actuator
offsets, chains' base attachments), the gap before and after, the held-out error (k-fold, or
``--validate`` files, the machine frozen, on the fitted registration when measured in the fitted set-up or
each registered on ``--register`` of its poses), the registration
apart, what is not identifiable, the rows set aside as outliers (:mod:`vjm.calibration.robust`, as a robot's).
Written: ``report.json``, ``report.html``, ``summary.txt`` (no calibrated URDF: the machine is no robot
file).  No elastic effect is tried: the rows carry no load.
"""
from __future__ import annotations

import os
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

from ..discrepancy.diagnosis import Diagnosis
from ..effects import absolute as absolute_effects
from ..errors import VjmError
from ..kinematics.forward import actuator_names
from . import diagnosis as absolute
from . import report as cr
from .diagnosis import DEFAULT_ALPHA, calibrated, check_min_gain, pose_report, progress_lines, write
from .parallel import FRAME, effect_names
from .parallel_fit import calibrate_platform, register_platform
from .robust import calibrate_robust


def check_options(effects, suggest: int = 0, forces_only: bool = False, noise=None) -> tuple:
    """The effects tried (names of :func:`vjm.calibration.parallel.effect_names`; None: the default ones), and a
    refusal of the options that have no meaning on a parallel machine's absolute poses."""
    return absolute.check_options(effects, suggest, forces_only, noise, known=effect_names(),
                                  default=absolute_effects.defaults("parallel"),
                                  what="a parallel machine's absolute poses")


def read(path, model, columns=None, group: str | None = None, named: bool = True):
    """A parallel machine's absolute poses (its actuators' columns required), one group per file without a
    ``group`` column (``named``: the file's name; else no group, a validation file's set-up decided later)."""
    from .poses import read_column_map, read_poses

    cmap = read_column_map(columns) if columns is not None else None
    d = read_poses(path, cmap, group=group)
    names = actuator_names(model)
    missing = [a for a in names if a not in d.joints]
    if missing:
        raise VjmError(f"{path}: no column for actuator(s) {', '.join(missing)}: a parallel machine's absolute "
                       f"poses have a column per actuator, <chain>.<variable> ({', '.join(names)}; or map them in "
                       f"the column map)")
    return d if d.group is not None or not named else d.with_group(Path(path).name)


def _fit(model, data, frame, **kw):
    return calibrate_platform(model, data, **kw)


def validate(cal, data, k: int) -> dict:
    """A validation file's held-out errors, the machine frozen (:func:`vjm.calibration.report.held_out`): on the
    fitted registration when it is in the fitted set-up, else its set-up registered on ``k`` of its poses."""
    return cr.held_out(cal, data, k, register_platform)


def diagnose_platform_poses(model, data, model_name: str | None = None, alpha: float | None = None, effects=None,
                            folds: int = 5, columns=None, validate_files=(), register: int = 30,
                            outliers: bool = True, progress=None, same_setup: bool = False,
                            min_gain: float | None = None) -> Diagnosis:
    """Diagnose a parallel machine's absolute poses (the module docstring): ``model`` and ``data`` loaded or
    their files, ``columns`` a column map file, ``validate_files`` held-out files (then no k-fold),
    ``outliers`` rows no effect explains set aside (:mod:`vjm.calibration.robust`), ``same_setup``: validation
    files without a ``group`` column measured in the fitted data's one set-up
    (:func:`vjm.calibration.report.held_setup`)."""
    from ..modelio.read import load_model

    eff = check_options(effects)
    min_gain = check_min_gain(min_gain)
    opt = cr.Options(FRAME, eff, DEFAULT_ALPHA if alpha is None else alpha, 0 if validate_files else folds, register,
                     same_setup)
    cr.check_options(replace(opt, effects=()))
    m: Any = load_model(model) if isinstance(model, (str, os.PathLike)) else model
    d = read(data, m, columns) if isinstance(data, (str, os.PathLike)) else (
        data if data.group is not None else data.with_group(os.path.basename(data.source) or "data"))
    fitted = tuple(dict.fromkeys(map(str, d.group)))
    vals = [cr.held_setup(read(v, m, columns, named=False), fitted, same_setup) for v in validate_files]
    for v in vals:
        if v.group[0] not in fitted:
            cr.check_validation(v, register)
    t0 = time.perf_counter()
    if outliers:
        cal = calibrate_robust(m, d, FRAME, fit=_fit, effects=eff, alpha=opt.alpha, folds=opt.folds,
                               min_gain=min_gain)
    else:
        cal = calibrate_platform(m, d, eff, opt.alpha, folds=opt.folds, min_gain=min_gain)
    held = [validate(cal, v, register) for v in vals]
    rep = cr.report(cal, opt, model_name or getattr(m, "path", None) or "<model>", d, held, time.perf_counter() - t0)
    report = pose_report(rep, cal, d, opt.alpha, machine="parallel", actuators=list(d.joints))
    progress_lines(report, progress)
    before, after = cr.row_errors(cal, d)
    return Diagnosis(report, "platform_absolute", write, calibrated, calibration=cal, rms_pose_before=before,
                     rms_pose_after=after)
