"""Absolute-pose calibration of a parallel machine: the engine of :mod:`vjm.calibration.engine` on the
measurement model of :mod:`vjm.calibration.parallel`.

The stages are those of a robot's calibration (:func:`vjm.calibration.engine.run_stages`, the staged selection of
:mod:`vjm.stats.staged`, one engine):

1. **registration** (nuisance, always fitted, reported apart): the instrument frame of each group and the
   marker's offset on a 6-dof platform, started from a Kabsch fit on the nominal forward kinematics
   (:func:`vjm.calibration.engine.registration_from_frames`);
2. **offset**: an offset per actuator (the zero of its encoder);
3. **attachment**: each chain's base translated (where its first joint is fixed).

Each stage's candidates are kept by the Gram-Schmidt selection of the identification Jacobian (the
closure's implicit derivative): a base translation the registration and the offsets already span (the
bases moved together as a rigid body, a base shifted along its actuator's axis ...) is removed and listed.
A stage is named when its F test passes at ``alpha`` and, with ``folds``, its cross-validated error drops.
The machine carries no load per row: no elastic effect is tried.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import VjmError
from ..kinematics import forward as fk
from ..stats.fit import check_fold_count
from ..stats.staged import Practical
from .engine import final_uncertainty, fit, registration_from_frames, run_stages
from .parallel import FRAME, effect_names, full_layout, nominal_state, problem
from .result import Calibration
from .serial import Layout

#: why a 3-dof platform's marker offset is no parameter
FIXED_MARKER = ("not identifiable: a 3-dof platform does not turn; its marker offset is the instrument "
                "frame's translation")


def check_frame(data) -> None:
    """The data must measure one point, the platform's (``platform.x/.y/.z``)."""
    other = [f for f in data.points if f != FRAME]
    if other:
        raise VjmError(f"{data.source}: measured point {other[0]}: a parallel machine's measured point is on its "
                       f"platform; name its columns {FRAME}.x, {FRAME}.y, {FRAME}.z")


def _enough_rows(data, full: Layout, effects, folds: int) -> None:
    groups = np.asarray([str(x) for x in data.groups])
    few = [g for g in sorted(set(groups)) if np.sum(groups == g) < 3]
    if few:
        raise VjmError(f"{data.source}: group {few[0] or '(none)'} has fewer than 3 rows: its instrument frame "
                       f"cannot be registered")
    size = sum(k in ("reg", "marker", *effects) for k in full.kinds)
    n = data.n * (folds - 1) // folds if folds else data.n
    if 3 * n <= size:
        raise VjmError(f"{data.source}: {data.n} rows ({3 * n} coordinates{' per fold' if folds else ''}) for up to "
                       f"{size} parameters: measure more poses")
    if folds:
        check_fold_count(folds, data.n, "row")


def calibrate_platform(model, data, effects=None, alpha: float = 1e-3, tol: float = 1e-3,
                       folds: int = 0, min_gain: float | None = None) -> Calibration:
    """Fit the registration, then the ``effects`` stages (the module docstring) of a parallel machine on
    absolute poses ``data`` (columns: its actuators, :func:`vjm.kinematics.forward.actuator_names`, and the
    platform's point); ``effects`` None: all of a parallel machine's; ``min_gain`` what an effect must buy (mm;
    None: 1 % of the error it starts from)."""
    if folds == 1 or folds < 0:
        raise VjmError(f"folds must be 0 (no cross-validation) or at least 2, got {folds}")
    known = effect_names()
    effects = known if effects is None else effects
    bad = sorted(set(effects) - set(known))
    if bad:
        raise VjmError(f"unknown effect(s) {', '.join(bad)}; a parallel machine's effects: {', '.join(known)}")
    check_frame(data)
    asm = fk.assembly(model)
    groups = tuple(sorted({str(g) for g in data.groups}))
    full = full_layout(model, asm, groups)
    _enough_rows(data, full, effects, folds)
    nominal = nominal_state(asm, data.q_for(fk.actuator_names(model)), data.source)
    meas = data.points[FRAME]
    frames, p0 = registration_from_frames(nominal.X, meas, data.groups, None if asm.dof == 6 else np.zeros(3))
    prob = problem(model, asm, data, frames, p0, nominal)
    stages, best, removed = run_stages(prob, full, meas, [e for e in known if e in effects], alpha, tol, 0.0, folds,
                                       practical=Practical(min_gain))
    lay = full.pick(best.idx)
    gone = [(full.names[i], why) for i, why in removed]
    if asm.dof == 3:
        gone = [(f"{FRAME}.p{c}", FIXED_MARKER) for c in "xyz"] + gone
    unc = final_uncertainty(prob, lay, best.x, meas, data, (FRAME,))
    return Calibration(model, FRAME, dict(zip(lay.names, best.x)), dict(zip(lay.names, unc.std)), frames, p0,
                       tuple(gone), tuple(stages), kinds={n: (k, u) for n, k, u in zip(full.names, full.kinds,
                                                                                         full.units)},
                       std_method=unc.method)


def register_platform(cal: Calibration, data) -> Calibration:
    """The calibration with the instrument frames of ``data``'s groups fitted on ``data``, the machine's
    parameters and the marker frozen (a new set-up of the instrument)."""
    check_frame(data)
    asm = fk.assembly(cal.model)
    fixed = cal.robot_values()
    p = cal.marker
    groups = tuple(sorted({str(g) for g in data.groups}))
    first = problem(cal.model, asm, data, {g: (np.eye(3), np.zeros(3)) for g in groups}, p)
    X = first.state(fixed).X
    frames, _ = registration_from_frames(X, data.points[FRAME], data.groups, p)
    prob = problem(cal.model, asm, data, frames, p, first.nominal)
    full = full_layout(cal.model, asm, groups)
    lay = full.pick([i for i, k in enumerate(full.kinds) if k == "reg"])
    x, sd, _ = fit(prob, lay, data.points[FRAME], np.zeros(lay.size), fixed)
    return replace(cal, values={**fixed, **dict(zip(lay.names, x))},
                   std={**{k: v for k, v in cal.std.items() if k in fixed}, **dict(zip(lay.names, sd))},
                   frames=frames, p0=p)
