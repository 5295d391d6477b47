"""Absolute-pose calibration of a robot: registration, geometry, joint compliance under self-weight.

On an :class:`~vjm.calibration.poses.AbsolutePoses` data set (points measured by an instrument in its own frame)
the measurement model of :mod:`vjm.calibration.serial` is fitted by Levenberg-Marquardt (scipy), in stages:

1. **registration** (nuisance, always fitted, reported apart): the instrument frame of each group
   (6 parameters) and the marker's offset on its frame (3), started from a Kabsch fit on the nominal model;
2. **geometry**: joint offsets and per-joint URDF-origin errors.  The identification Jacobian decides what
   can be identified: its columns (scaled to unit norm, in a fixed order: offsets, then each joint's
   ``dx dy dz ex ey ez``) are kept one by one while they add a direction beyond ``tol`` to the span of the
   registration and of the columns kept before (Gram-Schmidt); the others are combinations of those,
   removed and listed with the parameters they combine (a base frame against the first joint, a
   translation along parallel axes ...) -- never fitted as degenerate parameters;
3. **compliance**: a torsional compliance per joint, the deflection ``-(c0 + c) g_j(q)`` under the nominal model's
   gravity torque, ``c`` the correction fitted to the model file's ``c0`` (the fit starts from what the model
   file states: its joint and link springs and payload, :mod:`vjm.calibration.nominal`).  A joint whose gravity torque hardly varies over the data (its spread below
   ``flat`` of the largest joint's) cannot be told from an offset: it is reported not observable.
   Then **coupling** (asked only): a joint turning by ``k`` times another's value (a wrist's gear train, or
   a column holding a combination of joints written as an ordinary joint), the same selection deciding
   (after the compliance: tried before it, 30 couplings pass for an arm's sag);
   Then the effects of :mod:`vjm.calibration.flex` (asked only): **lateral** joint compliance, link **bending**,
   compliance **varying** with the joint's value (their loads hardly varying: not observable), and the
   **thermal** length scale (a ``meta_temperature`` column; its spread under 0.1 K: not observable);
4. **tilt**: the base tilted against the gravity the model assumes (2 angles, about the base x and y axes):
   seen only through the compliances kept, the torques ``g(q)`` being those of the tilted gravity
   (geometrically a tilt is the instrument frame's rotation, taken by the registration);
5. **backlash**: a clearance per joint taken up on the side its gravity torque pushes to, the deflection
   ``-b sign(g_j(q))``.  A joint whose gravity torque keeps one sign (the other sign on fewer than
   ``flat`` of the rows) cannot tell it from an offset: reported not observable;
6. **payload**: an unknown mass at the marker (a probe, a tool), weighed through the compliances kept: its
   gravity torque ``-J_p^T g`` per kg adds to the robot's own.

The selection is that of :mod:`vjm.stats.staged` (this module gives it the measurement model): every
parameter is fitted within its physical domain (:func:`vjm.effects.absolute.domain`, on the total: the
model's ``nominal`` value plus the correction), and a stage is kept when no parameter of it has to leave
the domain, the F test of its residual drop has a p-value below ``alpha`` (clean data keep the
registration only) and what it buys -- with ``folds``, the drop of its error held out over blocks of
neighbouring rows (:func:`block_folds`), beyond that drop's fold-to-fold standard error -- reaches
``min_gain`` mm (default 1 % of the error it starts from).  Once all are tried, each stage kept
is tested again beside the others (:func:`vjm.stats.staged.backward_stages`): one that the stages after it
explain is dropped.  Residuals are unweighted (mm), the model's errors exceeding the instruments' stated sigmas
on real data.  The final fit's standard deviations (:func:`final_uncertainty`, :mod:`vjm.stats.uncertainty`)
account for what the model misses: the formal ones scaled by the lack of fit, or a delete-one-block
jackknife over the registration groups or blocks of neighbouring poses, whichever is larger.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..effects import absolute
from ..errors import VjmError
from ..stats.fit import check_fold_count
from ..stats.staged import Best, Nested, Practical, least_squares_fit, select_stages
from ..stats.uncertainty import Uncertainty, parameter_std, pose_blocks, residual_blocks
from .flex import TEMPERATURE, flex_loads
from .nominal import model_torques, nominal_state, nominal_values
from .parallel import points as platform_points
from .result import Calibration
from .serial import (
    Layout,
    Points,
    Problem,
    full_layout,
    jacobian_fast,
    kabsch,
    merged_layout,
    predict,
    rotation_matrix,
)


def effect_names() -> tuple:
    """A robot's effects, in the order their stages are tried (:data:`vjm.effects.absolute.POSES`)."""
    return absolute.names("serial")




def unit_torques(model, q: np.ndarray, frame: str, p) -> np.ndarray:
    """The gravity torques (n, nq) N mm of 1 kg at the point ``p`` (mm) of ``frame``, ``-J_p^T g``."""
    T = model.forward(q, frame).reshape(-1, 4, 4)
    J = model.jacobian(q, frame).reshape(len(q), 6, -1)
    r = np.einsum("nij,j->ni", T[:, :3, :3], np.asarray(p, dtype=float))
    Jp = J[:, :3, :] + np.cross(J[:, 3:, :], r[:, :, None], axis=1)
    return -np.einsum("nik,i->nk", Jp, np.asarray(model.gravity, dtype=float))


def _problem(model, data, frame: str, frames: dict, p0: np.ndarray, payload: bool = False,
             tilt: bool = False, flex: bool = False, thermal: bool = False) -> Problem:
    q = data.q_for(model.q_names)
    groups = tuple(sorted({str(g) for g in data.groups}))
    missing = [g for g in groups if g not in frames]
    if missing:
        raise VjmError(f"{data.source}: group(s) {', '.join(missing)} not registered")
    gidx = np.array([groups.index(str(g)) for g in data.groups])
    # the model as the file states it (joint and link springs, payload): the fit corrects it (vjm.calibration.nominal)
    return Problem(model, frame, q, gidx, groups, tuple(frames[g][0] for g in groups),
                   tuple(frames[g][1] for g in groups), np.asarray(p0, dtype=float), model_torques(model, q),
                   unit_torques(model, q, frame, p0) if payload else None,
                   np.stack([model_torques(model, q, e) for e in np.eye(3)]) if tilt else None,
                   flex_loads(model, q, frame, _temperature(data) if thermal else None) if flex or thermal else None,
                   nominal_state(model, q, frame, p0, payload))


def _problems(model, data, measured, frames: dict, **opts):
    """The :class:`Problem` of one measured point ``measured`` ((frame, p0),), or the :class:`Points` of several."""
    parts = tuple(_problem(model, data, f, frames, p, **opts) for f, p in measured)
    return parts[0] if len(parts) == 1 else Points(parts)


def _layout(model, measured, groups, effects=()) -> Layout:
    frames = [f for f, _ in measured]
    return full_layout(model, frames[0], groups, effects) if len(frames) == 1 else \
        merged_layout(model, frames, groups, effects)


def _measurements(data, measured) -> np.ndarray:
    return np.concatenate([data.points[f] for f, _ in measured])


def _initial(model, data, fr: tuple, p0) -> tuple[dict, list]:
    """Instrument frames and each measured frame's marker offset: :func:`initial_registration` per frame,
    then one Kabsch fit per group on all the points (the markers ``p0``, one per frame, if given)."""
    if len(fr) == 1:
        frames, p = initial_registration(model, data, fr[0], None if p0 is None else np.reshape(p0, (-1, 3))[0])
        return frames, [p]
    ps = [initial_registration(model, data, f)[1] for f in fr] if p0 is None else list(p0)
    q = data.q_for(model.q_names)
    parts = []
    for f, p in zip(fr, ps):
        T = model.forward(q, f).reshape(-1, 4, 4)
        parts.append(np.einsum("nij,j->ni", T[:, :3, :3], p) + T[:, :3, 3])
    pb = np.concatenate(parts)
    m = np.concatenate([data.points[f] for f in fr])
    g = np.tile(np.array([str(x) for x in data.groups]), len(fr))
    return {k: kabsch(pb[g == k], m[g == k]) for k in sorted(set(g))}, ps


def _temperature(data) -> np.ndarray:
    if TEMPERATURE not in data.meta:
        raise VjmError(f"{data.source}: the thermal effect needs the rows' temperature, a {TEMPERATURE} column (C)")
    return np.asarray(data.meta[TEMPERATURE], dtype=float)


def _options(effects) -> dict:
    """The problem options the effects tried need (each effect's :attr:`~vjm.effects.absolute.PoseEffect.options`)."""
    return absolute.options(effects)


def _uses(values: dict) -> dict:
    """The problem options a calibration's parameters need: those of the effects that form them."""
    return absolute.options({e.name for k in values if (e := absolute.owner_of(k, "serial")) is not None})


def initial_registration(model, data, frame: str, p0=None, rounds: int = 8) -> tuple[dict, np.ndarray]:
    """Instrument frames {group: (R, t)} and marker offset (3,) mm from the nominal model: Kabsch fits of
    each group's points alternating with the linear least squares of the marker offset (kept at ``p0`` if
    given)."""
    q = data.q_for(model.q_names)
    return registration_from_frames(model.forward(q, frame).reshape(-1, 4, 4), data.points[frame], data.groups, p0,
                                    rounds)


def registration_from_frames(T: np.ndarray, m: np.ndarray, group, p0=None, rounds: int = 8) -> tuple[dict, np.ndarray]:
    """:func:`initial_registration` of the nominal frames T (n, 4, 4) carrying the marker and the points m
    (n, 3) measured, rows in the groups ``group`` (n,)."""
    groups = sorted({str(g) for g in group})
    rows = {g: np.array([str(x) == g for x in group]) for g in groups}
    p = np.zeros(3) if p0 is None else np.asarray(p0, dtype=float)
    frames: dict = {}
    for _ in range(1 if p0 is not None else rounds):
        pb = np.einsum("nij,j->ni", T[:, :3, :3], p) + T[:, :3, 3]
        frames = {g: kabsch(pb[r], m[r]) for g, r in rows.items()}
        if p0 is not None:
            break
        # m - R T_o - t = R T_R p: stack the groups, their t's as unknowns too
        A = np.zeros((3 * len(T), 3 + 3 * len(groups)))
        b = np.zeros(3 * len(T))
        for gi, g in enumerate(groups):
            R, _ = frames[g]
            idx = np.flatnonzero(rows[g])
            RT = np.einsum("ij,njk->nik", R, T[idx, :3, :3])
            for c in range(3):
                A[3 * idx + c, :3] = RT[:, c, :]
                A[3 * idx + c, 3 + 3 * gi + c] = 1.0
                b[3 * idx + c] = m[idx, c] - (T[idx, :3, 3] @ R.T)[:, c]
        p = np.linalg.lstsq(A, b, rcond=None)[0][:3]
    return frames, p


def _predict(prob, layout: Layout, x: np.ndarray, fixed: dict | None = None) -> np.ndarray:
    """The predictions of a measurement model: a robot's :class:`Problem` (:mod:`vjm.calibration.serial`), or an
    object answering ``predict`` (a parallel machine's :class:`vjm.calibration.parallel.PlatformProblem`)."""
    own = getattr(prob, "predict", None)
    return own(layout, x, fixed) if own is not None else predict(prob, layout, x, fixed)


def _jacobian(prob, layout: Layout, x: np.ndarray, fixed: dict | None = None) -> np.ndarray:
    own = getattr(prob, "jacobian", None)
    return own(layout, x, fixed) if own is not None else jacobian_fast(prob, layout, x, fixed)


def _residual_fn(prob, layout: Layout, meas: np.ndarray, fixed: dict):
    def fun(x):
        return (_predict(prob, layout, x, fixed) - meas).ravel()

    def jac(x):
        return _jacobian(prob, layout, x, fixed)

    return fun, jac


def fit(prob, layout: Layout, meas: np.ndarray, x0: np.ndarray, fixed: dict | None = None, bounds=None,
        keep: dict | None = None):
    """Levenberg-Marquardt fit of ``layout``'s parameters (:func:`vjm.stats.staged.least_squares_fit`; within
    ``bounds`` (lower, upper) if given): (x, std, rss); ``keep`` given the solution's residuals and Jacobian."""
    fun, jac = _residual_fn(prob, layout, meas, fixed or {})
    return least_squares_fit(fun, jac, x0, bounds, keep)


def _flat_joints(prob: Problem, layout: Layout, cands: list, flat: float, how: str = "torque") -> tuple[list, list]:
    """The candidates whose load hardly varies (its spread below ``flat`` of the largest joint's) set apart as
    not observable: the gravity torque for a compliance (and a varying one), the moment normal to the axis
    for a lateral compliance, the temperature for the thermal scale (spread below 0.1 K): ``how``, the effect's
    :attr:`~vjm.effects.absolute.PoseEffect.screen`."""
    tree = prob.model.tree
    keep, out = [], []
    if not cands:
        return keep, out
    if how == "temperature":
        sd = float(np.std(prob.flex.dT))
        return ([], [(cands[0], f"not observable: the temperature hardly varies (spread {sd:.3g} K)")]) if sd < 0.1 \
            else (list(cands), [])
    if how == "lateral":
        spread = np.array([np.sum(np.std(prob.flex.lateral[:, tree.joint_index(n)], axis=0)) for n in tree.q_names])
        what, unit = "moment normal to its axis", "N m"
    else:
        spread = np.std(prob.torques, axis=0)
        what, unit = "gravity torque", "N m"
    top = float(np.max(spread, initial=0.0))
    for i in cands:
        j = list(tree.q_names).index(layout.names[i].rsplit(".", 1)[0])
        if top == 0 or spread[j] < flat * top:
            out.append((i, f"not observable: its {what} hardly varies (spread {spread[j] / 1000:.3g} {unit}, "
                           f"largest {top / 1000:.3g} {unit})"))
        else:
            keep.append(i)
    return keep, out


def _one_sign(prob: Problem, layout: Layout, cands: list, flat: float, how: str = "sign") -> tuple[list, list]:
    qn = list(prob.model.tree.q_names)
    keep, out = [], []
    for i in cands:
        tau = prob.torques[:, qn.index(layout.names[i][:-len(".backlash")])]
        minority = min(np.mean(tau > 0), np.mean(tau < 0))
        if minority < flat:
            out.append((i, f"not observable: its gravity torque changes sign on {100 * minority:.3g} % of the rows "
                           f"(a backlash on one side is an offset)"))
        else:
            keep.append(i)
    return keep, out


def _rows(prob, mask: np.ndarray):
    if hasattr(prob, "rows"):
        return prob.rows(mask)
    if isinstance(prob, Points):
        return Points(tuple(_rows(p, mask) for p in prob.parts))
    return replace(prob, q=prob.q[mask], gidx=prob.gidx[mask], torques=prob.torques[mask],
                   unit_torques=None if prob.unit_torques is None else prob.unit_torques[mask],
                   gravity_basis=None if prob.gravity_basis is None else prob.gravity_basis[:, mask],
                   flex=None if prob.flex is None else prob.flex.rows(mask),
                   nominal=None if prob.nominal is None else prob.nominal.rows(mask))


def _held_out(prob, full: Layout, meas: np.ndarray, folds: int, last: dict | None = None):
    """The held-out (sum of squares, count) per fold (:func:`vjm.stats.staged.fold_errors`) of a stage's
    parameters (indices of ``full``) over ``folds`` blocks of neighbouring rows (:func:`block_folds`), each
    fold predicted by the fit on the others: one Gauss-Newton
    step from the fit on all rows ``x0`` (exact for a linear model; the corrections fitted here are small),
    held within ``bounds`` (lower, upper) if given -- one Jacobian for every fold, not a fit per fold: that of
    the last fit (``last``: its parameters' indices ``idx``, ``x``, residuals and Jacobian) when it is at ``x0``."""
    n = len(prob.q)
    k = len(meas) // n   # measured points per row, stacked frame after frame
    masks = block_folds(getattr(prob, "gidx", np.zeros(n, dtype=int)), folds)

    def cv(idx: list, x0: np.ndarray, bounds=None) -> np.ndarray:
        if last and "x" in last and last.get("idx") == list(idx) and np.array_equal(last["x"], x0):
            r, J = last["fun"], last["jac"]
        else:
            fun, jac = _residual_fn(prob, full.pick(idx), meas, {})
            r, J = fun(x0), jac(x0)
        s = np.maximum(np.linalg.norm(J, axis=0), 1e-300)
        # a parameter held on its bound stays there: the step is that of the others
        free = np.ones(len(x0), dtype=bool) if bounds is None else \
            ~np.isclose(x0, bounds[0], rtol=0, atol=1e-12 * np.maximum(1.0, np.abs(x0))) & \
            ~np.isclose(x0, bounds[1], rtol=0, atol=1e-12 * np.maximum(1.0, np.abs(x0)))
        Js = (J / s)[:, free]
        G, b = Js.T @ Js, Js.T @ r
        out = []
        for test in masks:
            te = np.repeat(np.tile(test, k), 3)
            Jt, rt = Js[te], r[te]
            dx = np.zeros(len(x0))
            dx[free] = -np.linalg.lstsq(G - Jt.T @ Jt, b - Jt.T @ rt, rcond=1e-13)[0]
            if bounds is not None:
                dx = (np.clip(x0 + dx / s, *bounds) - x0) * s
            e = rt + Jt @ dx[free]
            out.append((float(e @ e), int(te.sum()) // 3))   # the RMS of the points' position errors
        return np.array(out, dtype=float)

    return cv


def block_folds(group: np.ndarray, k: int) -> list:
    """Boolean test masks of ``k`` folds: fold ``f`` holds the ``f``-th of ``k`` contiguous blocks of each
    group's rows in their order.  Neighbouring poses (a grid's, a path's) share their errors: an interleaved
    split keeps a held-out row's neighbours in the fit and lets an effect that only follows them pass as
    held out (on the UR10's series A, 30 joint couplings gain 0.007 mm over interleaved folds, 1 % of the error,
    and 0.002 +- 0.002 mm over blocks); every group keeps rows to be registered on."""
    group = np.asarray(group)
    fold = np.zeros(len(group), dtype=int)
    for g in np.unique(group):
        rows = np.flatnonzero(group == g)
        fold[rows] = (np.arange(len(rows)) * k) // len(rows)
    return [fold == f for f in range(k)]


def calibrate(model, data, frame: str | tuple | None = None, effects=("geometry", "compliance"), alpha: float = 1e-3,
              tol: float = 1e-3, flat: float = 0.05, p0=None, folds: int = 0, nominal: dict | None = None,
              min_gain: float | Practical | None = None, progress=None) -> Calibration:
    """Fit registration, then the ``effects`` stages (see the module docstring) on ``data``.

    ``folds`` > 1: a stage is kept only if its cross-validated RMS (:func:`_held_out`) drops by more than the
    fold-to-fold standard error of that drop -- an effect that improves the fitted rows but not the held-out
    ones is not kept.  A stage must also buy ``min_gain`` mm (None: 1 % of the error it starts from).  Each
    parameter is fitted within its physical domain (:func:`vjm.effects.absolute.domain`), the total
    ``nominal[name]`` (the model's nominal value, missing ones 0) plus the correction.  ``progress`` is called
    with a line per stage tried."""
    if folds == 1 or folds < 0:
        raise VjmError(f"folds must be 0 (no cross-validation) or at least 2, got {folds}")
    fr = (frame or _only_frame(data),) if isinstance(frame, str) or frame is None else tuple(frame)
    known = effect_names()
    bad = set(effects) - set(known)
    if bad:
        raise VjmError(f"unknown effect(s) {', '.join(sorted(bad))}; effects: {', '.join(known)}")
    one = [e for e in known if e in effects and absolute.POSES[e].single_marker]
    if len(fr) > 1 and one:
        raise VjmError(f"a {one[0]} is weighed at the marker: with several measured points, leave it out of the "
                       f"effects")
    use = check_data(model, data, fr, effects, folds)
    frames, ps = _initial(model, data, fr, p0)
    measured = tuple(zip(fr, ps))
    prob = _problems(model, data, measured, frames, **use)
    meas = _measurements(data, measured)
    full = _layout(model, measured, prob.groups, effects)
    stages, best, removed = run_stages(prob, full, meas, [s for s in known if s in effects], alpha, tol, flat,
                                       folds, bounds=absolute.domain(full.names, model, _nominal(model, full, nominal)),
                                       practical=min_gain if isinstance(min_gain, Practical) else Practical(min_gain),
                                       progress=progress)
    lay = full.pick(best.idx)
    unc = final_uncertainty(prob, lay, best.x, meas, data, fr)
    return Calibration(model, fr[0], dict(zip(lay.names, best.x)), dict(zip(lay.names, unc.std)), frames, ps[0],
                       tuple((full.names[i], why) for i, why in removed), tuple(stages), extra=measured[1:],
                       std_method=unc.method)


def final_uncertainty(prob, lay: Layout, x: np.ndarray, meas: np.ndarray, data, fr: tuple) -> Uncertainty:
    """The final fit's standard deviations (:func:`vjm.stats.uncertainty.parameter_std`): scaled by the lack of
    fit, and a jackknife over the registration groups or blocks of neighbouring poses (the rows' joint values)."""
    r = (_predict(prob, lay, x) - meas).ravel()
    parts = [(residual_blocks(rows, data.n, len(fr), meas.shape[1]), what) for rows, what in
             pose_blocks(data.q, data.groups)]
    sig = np.concatenate([data.sigmas[f] for f in fr]).ravel() if all(f in data.sigmas for f in fr) else None
    return parameter_std(_jacobian(prob, lay, x), r, parts, sig)


def _nominal(model, full: Layout, nominal: dict | None) -> dict:
    """The model file's values of the parameters (:func:`vjm.calibration.nominal.nominal_values`): the physical
    domain bounds their totals; ``nominal`` given, those instead."""
    if nominal is not None or model.kind != "serial":
        return nominal or {}
    return nominal_values(model, full.names)


def check_data(model, data, fr: tuple, effects, folds: int) -> dict:
    """Refuse, before any fitting, data that cannot show the ``effects`` on the measured frames ``fr``: too few
    rows, no temperature for the thermal effect, an effect with nothing to fit on this robot (its own
    reason); the problem options the effects need."""
    _enough_rows(model, data, fr, effects, folds)
    use = _options(effects)
    if use["thermal"]:
        _temperature(data)
    for e in effects:
        why = getattr(absolute.POSES[e], "usable", lambda m, d: None)(model, data)
        if why:
            raise VjmError(f"{e}: {why}: the effect has nothing to fit")
    return use


def run_stages(prob, full: Layout, meas: np.ndarray, order, alpha: float, tol: float, flat: float, folds: int,
               removed: list | None = None, bounds: tuple | None = None, practical: Practical = Practical(),
               progress=None) -> tuple[list, Best, list]:
    """The staged selection of :mod:`vjm.stats.staged` on any measurement model ``prob`` (see :func:`_predict`)
    and its parameters ``full`` (kinds ``reg`` and ``marker`` the nuisance, fitted first; then one kind per
    stage of ``order``): (the stages, the best fit (indices, x, std, rss, cv), the parameters removed
    [(index, why)]).  ``bounds`` (lower, upper, open) the parameters' domain (:func:`vjm.effects.absolute.domain`;
    None: unbounded), ``practical`` what a stage must buy."""

    def screen(name: str, cands: list) -> tuple[list, list]:
        how = absolute.screen(name)   # the effect's declared screening (vjm.effects.absolute)
        if how is not None:
            return (_one_sign if how == "sign" else _flat_joints)(prob, full, cands, flat, how)
        return cands, []

    bounded = bounds is not None and bool(np.any(np.isfinite(bounds[0])) or np.any(np.isfinite(bounds[1])))
    last: dict = {}   # the last fit's solution: the held-out folds step from its Jacobian

    def fit_(idx: list, x0: np.ndarray, b=None):
        last.clear()
        last["idx"] = list(idx)
        return fit(prob, full.pick(idx), meas, x0, bounds=b, keep=last)

    nf = Nested(full.names, full.kinds, fit_,
                lambda x, cols: _jacobian(prob, full.pick(cols), x[cols]),
                lambda idx, x: _stats(prob, full.pick(idx), x, meas),
                meas.size, len(meas), "registration", ("reg", "marker"),
                cv=_held_out(prob, full, meas, folds, last) if folds else None, screen=screen,
                through={n: absolute.carried(n) for n in order}, bounds=bounds if bounded else None,
                practical=practical, residual=lambda x: (_predict(prob, full, x) - meas).ravel())
    return select_stages(nf, order, alpha, tol, removed or (), progress)



def parameter_counts(model, frames, data, effects) -> dict:
    """{effect: its candidate parameters on the measured ``frames``, "nuisance": the registration's and the
    markers'} of a calibration of ``data`` (the plan told before the work)."""
    groups = tuple(sorted({str(g) for g in data.groups}))
    counts: dict = {}
    for k in _layout(model, [(f, None) for f in frames], groups, effects).kinds:
        key = "nuisance" if k in ("reg", "marker") else k
        counts[key] = counts.get(key, 0) + 1
    return counts


def _enough_rows(model, data, fr: tuple, effects, folds: int) -> None:
    """Refuse a set too small for the fit: 3 rows per group (a Kabsch start), and more coordinates than the
    parameters the effects may take (in each fold's training rows), and no more folds than rows."""
    groups = {str(g) for g in data.groups}
    few = [g for g in sorted(groups) if np.sum(np.asarray([str(x) for x in data.groups]) == g) < 3]
    if few:
        raise VjmError(f"{data.source}: group {few[0] or '(none)'} has fewer than 3 rows: its instrument frame "
                       f"cannot be registered")
    size = sum(k in ("reg", "marker", *effects) for k in _layout(model, [(f, None) for f in fr], tuple(sorted(groups)),
                                                                  effects).kinds)
    n = data.n * (folds - 1) // folds if folds else data.n
    if 3 * n * len(fr) <= size:
        raise VjmError(f"{data.source}: {data.n} rows ({3 * n} coordinates{' per fold' if folds else ''}) for up to "
                       f"{size} parameters: measure more poses")
    if folds:
        check_fold_count(folds, data.n, "row")


def _stats(prob, layout: Layout, x: np.ndarray, meas: np.ndarray) -> dict:
    return error_stats(np.linalg.norm(_predict(prob, layout, x) - meas, axis=1))


def _only_frame(data) -> str:
    if len(data.points) != 1:
        raise VjmError(f"{data.source}: several measured points ({', '.join(data.points)}): name the frame")
    return next(iter(data.points))


def register(cal: Calibration, data, marker: bool = False) -> Calibration:
    """The calibration with the instrument frames of ``data``'s groups fitted on ``data`` (the robot's
    parameters frozen; the marker offsets too unless ``marker``)."""
    now = tuple((f, p + np.array([cal.values.get(f"{f}.p{c}", 0.0) for c in "xyz"])) for f, p in cal.measured)
    frames, _ = _initial(cal.model, data, tuple(f for f, _ in now), [p for _, p in now])
    prob = _problems(cal.model, data, now, frames, **_uses(cal.values))
    full = _layout(cal.model, now, prob.groups)
    keep = [i for i, k in enumerate(full.kinds) if k == "reg" or (marker and k == "marker")]
    lay = full.pick(keep)
    fixed = cal.robot_values()
    x, sd, _ = fit(prob, lay, _measurements(data, now), np.zeros(lay.size), fixed)
    values = {k: v for k, v in cal.values.items() if not any(k.startswith(f"reg[{g}]") for g in prob.groups)}
    measured = cal.measured
    if marker:   # the markers' offsets start again from where they are, fitted with the registration
        markers = {f"{f}.p{c}" for f, _ in now for c in "xyz"}
        values = {k: v for k, v in values.items() if k not in markers}
        measured = now
    std = {k: v for k, v in cal.std.items() if k in values}
    values.update(zip(lay.names, x))
    std.update(zip(lay.names, sd))
    return replace(cal, values=values, std=std, frames={**cal.frames, **frames}, p0=measured[0][1],
                   extra=tuple(measured[1:]))


def measurement(cal: Calibration, data):
    """The robot's measurement model of ``data``'s rows (what :func:`predict_points` evaluates; built once, it
    predicts the same rows for any values of the calibration's parameters or a part of them)."""
    return _problems(cal.model, data, cal.measured, cal.frames, **_uses(cal.values))


def predict_points(cal: Calibration, data, prob=None) -> np.ndarray:
    """The calibrated model's points (n, 3) mm in the instrument frames of ``data``'s (registered) groups;
    with several measured points (k n, 3), frame after frame (``cal.measured``); ``prob`` the robot's
    :func:`measurement` of those rows where it is built already."""
    if cal.model.kind == "parallel":
        return platform_points(cal, data)
    prob = measurement(cal, data) if prob is None else prob
    lay = Layout(tuple(cal.values), ("",) * len(cal.values), ("",) * len(cal.values))
    return predict(prob, lay, np.array(list(cal.values.values())))


def position_errors(cal: Calibration, data) -> np.ndarray:
    """|measured - predicted| (n,) mm; with several measured points per row, the largest of the row's."""
    e = np.linalg.norm(_measurements(data, cal.measured) - predict_points(cal, data), axis=1)
    return e.reshape(len(cal.measured), data.n).max(axis=0)


def error_stats(e) -> dict:
    """mean, std, max and 95th percentile (mm) of position errors."""
    e = np.asarray(e, dtype=float)
    return {"mean": float(e.mean()), "std": float(e.std()), "max": float(e.max()), "p95": float(np.percentile(e, 95))}


def instrument_frame(cal: Calibration, group: str) -> tuple[np.ndarray, np.ndarray]:
    """The fitted instrument frame (R, t) of a group: instrument = R base + t."""
    R0, t0 = cal.frames[group]
    w = np.array([cal.values.get(f"reg[{group}].r{k}", 0.0) for k in "xyz"])
    t = np.array([cal.values.get(f"reg[{group}].t{k}", 0.0) for k in "xyz"])
    return rotation_matrix(w) @ R0, t0 + t
