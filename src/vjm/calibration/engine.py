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
3. **compliance**: a torsional compliance per joint, the deflection ``-c g_j(q)`` under the nominal model's
   gravity torque.  A joint whose gravity torque hardly varies over the data (its spread below
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

A stage is kept when the F test of its residual drop has a p-value below ``alpha`` (clean data keep the
registration only) and, with ``folds``, when its cross-validated error drops too.  Once all are tried, each
stage kept is tested again beside the others (:func:`_backward`): one that the stages after it explain is
dropped.  Uncertainties are ``s^2 (J^T J)^-1`` with the residual variance ``s^2``; residuals
are unweighted (mm), the model's errors exceeding the instruments' stated sigmas on real data.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import f as f_dist

from ..effects import absolute
from ..errors import VjmError
from .flex import TEMPERATURE, flex_loads
from .parallel import points as platform_points
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


@dataclass(frozen=True)
class Stage:
    """One stage of the fit: its name, whether it was kept, its parameter count, residual sum of squares
    (mm^2), RMS position error (mm), the F test's p-value against the stage before (nan for the first)
    and the cross-validated RMS (mm; nan without ``folds``)."""

    name: str
    kept: bool
    n_params: int
    rss: float
    rms: float
    p_value: float
    cv_rms: float = float("nan")
    #: mean, std, max and p95 (mm) of the fitted rows' position errors after the stage (:func:`error_stats`)
    stats: dict = field(default_factory=dict)
    #: why a stage that passed when tried is not named in the end (:func:`_backward`), else ""
    note: str = ""


@dataclass(frozen=True, eq=False)
class Calibration:
    """A fitted measurement model: ``values`` and ``std`` of the fitted parameters (names of
    :mod:`vjm.calibration.serial`), the groups' base registration ``frames`` {group: (R0, t0)}, the marker's
    base offset ``p0``, the parameters ``removed`` [(name, why)], and the ``stages``."""

    model: Any
    frame: str
    values: dict
    std: dict
    frames: dict
    p0: np.ndarray
    removed: tuple = ()
    stages: tuple = ()
    #: rows of the data set aside as outliers (indices), not fitted (:mod:`vjm.calibration.robust`)
    set_aside: tuple = ()
    #: the other measured frames and their markers' base offsets ((frame, p0), ...): several points per row
    extra: tuple = ()
    #: {parameter: (effect, unit)} where the names do not say them (a parallel machine's, vjm.calibration.parallel)
    kinds: dict = field(default_factory=dict)

    @property
    def measured(self) -> tuple:
        """((frame, base marker offset), ...) of every measured point, the first ``frame``'s."""
        return ((self.frame, self.p0), *self.extra)

    def robot_values(self) -> dict:
        """The robot's fitted parameters (geometry and compliance), without the nuisance."""
        markers = tuple(f"{f}.p{c}" for f, _ in self.measured for c in "xyz")
        return {k: v for k, v in self.values.items() if not k.startswith("reg[") and k not in markers}

    @property
    def marker(self) -> np.ndarray:
        return self.p0 + np.array([self.values.get(f"{self.frame}.p{k}", 0.0) for k in "xyz"])

    @property
    def markers(self) -> dict:
        """{measured frame: its marker's fitted offset (3,) mm}, the first ``frame``'s first."""
        return {f: p + np.array([self.values.get(f"{f}.p{k}", 0.0) for k in "xyz"]) for f, p in self.measured}


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
    return Problem(model, frame, q, gidx, groups, tuple(frames[g][0] for g in groups),
                   tuple(frames[g][1] for g in groups), np.asarray(p0, dtype=float), model.gravity_torques(q),
                   unit_torques(model, q, frame, p0) if payload else None,
                   np.stack([model.gravity_torques(q, e) for e in np.eye(3)]) if tilt else None,
                   flex_loads(model, q, frame, _temperature(data) if thermal else None) if flex or thermal else None)


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


def fit(prob, layout: Layout, meas: np.ndarray, x0: np.ndarray, fixed: dict | None = None):
    """Levenberg-Marquardt fit of ``layout``'s parameters: (x, std, rss)."""
    fixed = fixed or {}
    fun, jac = _residual_fn(prob, layout, meas, fixed)
    if layout.size == 0:
        r = fun(x0)
        return x0, x0, float(r @ r)
    sol = least_squares(fun, x0, jac=jac, method="lm", x_scale="jac", xtol=1e-10, ftol=1e-10, gtol=1e-10)
    r = sol.fun
    rss = float(r @ r)
    dof = max(len(r) - layout.size, 1)
    J = jac(sol.x)
    # columns scaled to unit norm first: the parameters' units (mm, rad, rad/(N mm)) span 1e12
    s = np.maximum(np.linalg.norm(J, axis=0), 1e-300)
    cov = np.linalg.pinv((J / s).T @ (J / s)) / np.outer(s, s) * (rss / dof)
    return sol.x, np.sqrt(np.maximum(np.diag(cov), 0.0)), rss


def _combination(Jn: np.ndarray, col: np.ndarray, names: list) -> str:
    # the normal equations of the (independent, unit-norm) columns kept: only the largest coefficients are
    # named, and a lstsq of the tall matrix costs 0.25 s per parameter on 12k rows
    coef = np.linalg.lstsq(Jn.T @ Jn, Jn.T @ col, rcond=None)[0]
    top = np.argsort(-np.abs(coef))[:3]
    return ", ".join(names[i] for i in top if abs(coef[i]) > 1e-3) or "nothing"


def select(J: np.ndarray, layout: Layout, base: list, candidates: list, tol: float) -> tuple[list, list]:
    """Which ``candidates`` (column indices of J, in order) add a direction beyond ``tol`` to the span of
    ``base`` and of the candidates kept before them: (kept, [(index, why)] removed)."""
    Js = J / np.maximum(np.linalg.norm(J, axis=0), 1e-300)
    Q = np.linalg.qr(Js[:, base])[0] if base else np.zeros((len(J), 0))
    kept, removed = [], []
    for i in candidates:
        v = Js[:, i].copy()
        if not np.any(v):
            removed.append((i, "no effect on the measured points"))
            continue
        for _ in range(2):
            v -= Q @ (Q.T @ v)
        nv = float(np.linalg.norm(v))
        if nv > tol:
            Q = np.column_stack([Q, v / nv])
            kept.append(i)
        else:
            span = base + kept
            removed.append((i, "not identifiable: a combination of "
                            + _combination(Js[:, span], Js[:, i], [layout.names[k] for k in span])))
    return kept, removed


def _f_test(rss0: float, p0: int, rss1: float, p1: int, m: int) -> float:
    if p1 <= p0 or rss1 <= 0:
        return 1.0
    F = ((rss0 - rss1) / (p1 - p0)) / (rss1 / (m - p1))
    return float(f_dist.sf(F, p1 - p0, m - p1))


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
                   flex=None if prob.flex is None else prob.flex.rows(mask))


def cross_validated_rms(prob, layout: Layout, meas: np.ndarray, x0: np.ndarray, folds: int) -> float:
    """RMS position error (mm) of ``layout``'s fit over ``folds`` interleaved folds, each predicted by the
    fit on the others (started from ``x0``)."""
    n = len(prob.q)
    fold = np.arange(n) % folds
    k = len(meas) // n   # measured points per row, stacked frame after frame
    rss = 0.0
    for f in range(folds):
        tr = fold != f
        x, _, _ = fit(_rows(prob, tr), layout, meas[np.tile(tr, k)], x0)
        r = _predict(_rows(prob, ~tr), layout, x) - meas[np.tile(~tr, k)]
        rss += float(np.sum(r * r))
    return float(np.sqrt(rss / len(meas)))


def calibrate(model, data, frame: str | tuple | None = None, effects=("geometry", "compliance"), alpha: float = 1e-3,
              tol: float = 1e-3, flat: float = 0.05, p0=None, folds: int = 0) -> Calibration:
    """Fit registration, then the ``effects`` stages (see the module docstring) on ``data``.

    ``folds`` > 1: a stage is kept only if its cross-validated RMS (:func:`cross_validated_rms`) is also
    below the stage before's -- an effect that improves the fitted rows but not the held-out ones is
    not kept."""
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
    _enough_rows(model, data, fr, effects, folds)
    use = _options(effects)
    if use["thermal"]:
        _temperature(data)   # before any fitting
    frames, ps = _initial(model, data, fr, p0)
    measured = tuple(zip(fr, ps))
    prob = _problems(model, data, measured, frames, **use)
    meas = _measurements(data, measured)
    full = _layout(model, measured, prob.groups, effects)
    stages, best, removed = run_stages(prob, full, meas, [s for s in known if s in effects], alpha, tol, flat,
                                       folds)
    lay = full.pick(best[0])
    return Calibration(model, fr[0], dict(zip(lay.names, best[1])), dict(zip(lay.names, best[2])), frames, ps[0],
                       tuple((full.names[i], why) for i, why in removed), tuple(stages), extra=measured[1:])


def run_stages(prob, full: Layout, meas: np.ndarray, order, alpha: float, tol: float, flat: float, folds: int,
               removed: list | None = None) -> tuple[list, tuple, list]:
    """The engine of :func:`calibrate` on any measurement model ``prob`` (see :func:`_predict`) and its
    parameters ``full`` (kinds ``reg`` and ``marker`` the nuisance, fitted first; then one kind per stage of
    ``order``): (the stages, the best fit (indices, x, std, rss, cv), the parameters removed [(index, why)])."""
    active = [i for i, k in enumerate(full.kinds) if k in ("reg", "marker")]
    x, sd, rss = fit(prob, full.pick(active), meas, np.zeros(len(active)))
    m = meas.size
    cv = cross_validated_rms(prob, full.pick(active), meas, x, folds) if folds else float("nan")
    stages = [Stage("registration", True, len(active), rss, float(np.sqrt(rss / len(meas))), float("nan"), cv,
                    _stats(prob, full.pick(active), x, meas))]
    best = (active, x, sd, rss, cv)
    removed = list(removed or [])
    for name in order:
        x_all = np.zeros(full.size)
        x_all[best[0]] = best[1]
        J = _jacobian(prob, full, x_all)   # at the stage's start: the payload acts through the compliances
        cands = [i for i, k in enumerate(full.kinds) if k == name]
        how = absolute.screen(name)
        if how is not None:
            cands, flat_out = (_one_sign if how == "sign" else _flat_joints)(prob, full, cands, flat, how)
            removed += flat_out
        kept, rem = select(J, full, best[0], cands, tol)
        removed += rem
        trial = best[0] + kept
        x0 = np.zeros(len(trial))
        x0[:len(best[0])] = best[1]
        xt, sdt, rsst = fit(prob, full.pick(trial), meas, x0)
        pv = _f_test(best[3], len(best[0]), rsst, len(trial), m)
        ok = bool(kept) and pv < alpha
        cvt = cross_validated_rms(prob, full.pick(trial), meas, xt, folds) if folds and ok else float("nan")
        ok = ok and not (folds and cvt >= best[4])
        stages.append(Stage(name, ok, len(trial), rsst, float(np.sqrt(rsst / len(meas))), pv, cvt,
                            _stats(prob, full.pick(trial), xt, meas)))
        if ok:
            best = (trial, xt, sdt, rsst, cvt)
    stages, best = _backward(prob, full, meas, stages, best, alpha, folds)
    return stages, best, removed


def _backward(prob, full: Layout, meas: np.ndarray, stages: list, best: tuple, alpha: float, folds: int):
    """Each effect named checked again beside all the others: one that the effects named after it explain (its
    F test against the final set fails) is no longer named -- a joint offset fitted first passes for part of
    a sag the compliance, tried after it, explains -- the least needed first, until every one left is needed;
    then the stages left after the first dropped are refitted in turn (with their cross-validated error), so
    that their records (error before and after each) are those of the effects named."""
    stages, m, first = list(stages), meas.size, None
    while True:
        worst = None
        named = [s.name for s in stages[1:] if s.kept]
        for name in named:
            if first is None and name == named[-1]:
                continue   # without the last one is the set before it: its own F test passed
            gone = {name, *absolute.carried(name)}   # effects acting through its parameters
            idx = [i for i in best[0] if full.kinds[i] not in gone]
            x, sd, rss = fit(prob, full.pick(idx), meas, np.array([best[1][best[0].index(i)] for i in idx]))
            pv = _f_test(rss, len(idx), best[3], len(best[0]), m)
            if pv >= alpha and (worst is None or pv > worst[1]):
                worst = (name, pv, (idx, x, sd, rss, float("nan")), gone)
        if worst is None:
            break
        best = worst[2]
        for k, s in enumerate(stages):
            if s.name in worst[3] and s.kept:
                first = k if first is None else min(first, k)
                stages[k] = replace(s, kept=False, note=f"explained by the effects named after it (p = {worst[1]:.2g} "
                                                        f"beside them)")
    if first is None:
        return stages, best
    prev = [s for s in stages[:first] if s.kept][-1]
    for k in range(first, len(stages)):
        s = stages[k]
        if not s.kept:
            continue
        upto = {t.name for t in stages[1:k + 1] if t.kept}
        idx = [i for i in best[0] if full.kinds[i] in ("reg", "marker") or full.kinds[i] in upto]
        x, sd, rss = fit(prob, full.pick(idx), meas, np.array([best[1][best[0].index(i)] for i in idx]))
        cv = cross_validated_rms(prob, full.pick(idx), meas, x, folds) if folds else float("nan")
        stages[k] = prev = replace(s, n_params=len(idx), rss=rss, rms=float(np.sqrt(rss / len(meas))),
                                   p_value=_f_test(prev.rss, prev.n_params, rss, len(idx), m), cv_rms=cv,
                                   stats=_stats(prob, full.pick(idx), x, meas))
        if len(idx) == len(best[0]):
            best = (idx, x, sd, rss, cv)
    return stages, best


def _enough_rows(model, data, fr: tuple, effects, folds: int) -> None:
    """Refuse a set too small for the fit: 3 rows per group (a Kabsch start), and more coordinates than the
    parameters the effects may take (in each fold's training rows)."""
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


def predict_points(cal: Calibration, data) -> np.ndarray:
    """The calibrated model's points (n, 3) mm in the instrument frames of ``data``'s (registered) groups;
    with several measured points (k n, 3), frame after frame (``cal.measured``)."""
    if cal.model.kind == "parallel":
        return platform_points(cal, data)
    prob = _problems(cal.model, data, cal.measured, cal.frames, **_uses(cal.values))
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
