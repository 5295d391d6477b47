"""Staged selection over nested least-squares fits: the parameters come in blocks, a nuisance block always
fitted, then one block per stage tried in a fixed order, each stage's fit nesting the fits before it.

1. The nuisance block is fitted first (:func:`least_squares_fit`, Levenberg-Marquardt).
2. Each stage in turn: its candidates pass the model's screen (a parameter the data cannot see), then
   :func:`identifiable` keeps those whose Jacobian column adds a direction beyond ``tol`` to the span of the
   parameters kept before (Gram-Schmidt on unit-norm columns) and lists the others with the parameters they
   combine.  The stage is fitted within the parameters' physical domain (:func:`domain_fit`: the fast
   unbounded fit, the bounded one only where it leaves the domain).  It is kept when
   - no parameter's unbounded value is beyond its bound by more than :data:`BEYOND` standard deviations: a
     stage that fits only so "stands in for something else", is not named, and its record keeps the values
     it wanted;
   - the F test (:func:`vjm.stats.fit.f_test`) of its residual drop has a p-value below ``alpha``;
   - what it buys is worth it: its held-out gain (the drop of the cross-validated RMS; without
     cross-validation, of the fitted RMS) exceeds the fold-to-fold standard error of that gain and the
     practical threshold (:class:`Practical`: 1 % of the error it starts from by default).  A significant
     stage that fails this is "significant but negligible", its gain in mm kept with it.
3. Once all are tried (:func:`backward_stages`), each stage kept is tested again beside all the others: one
   that the stages after it explain (its F test against the final set fails) is dropped, the least needed
   first, until every one left is needed; the stages kept after the first dropped are refitted in turn so
   that their records are those of the stages kept.

It knows nothing of the measurement model: a :class:`Nested` gives the fits, the Jacobian, the held-out
error and the screen as callables on parameter indices.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Any, Callable, NamedTuple

import numpy as np
from scipy.optimize import least_squares

from .fit import f_test


@dataclass(frozen=True)
class Stage:
    """One stage of the fit: its name, whether it was kept, its parameter count, residual sum of squares,
    RMS error per point, the F test's p-value against the stage before (nan for the first) and the
    cross-validated RMS (nan without cross-validation)."""

    name: str
    kept: bool
    n_params: int
    rss: float
    rms: float
    p_value: float
    cv_rms: float = float("nan")
    #: the model's summary of the fitted rows' errors after the stage (``Nested.summary``)
    stats: dict = field(default_factory=dict)
    #: why a stage that passed when tried is not named in the end (:func:`backward_stages`), else ""
    note: str = ""
    #: what the stage buys (mm): the drop of the held-out RMS (of the fitted RMS without cross-validation),
    #: its fold-to-fold standard error and the practical threshold it was held to (nan: not judged)
    gain: float = float("nan")
    gain_se: float = float("nan")
    threshold: float = float("nan")
    #: "" (named, or not significant), "negligible" (significant but below the practical threshold or its
    #: standard error) or "stands_in" (fits only by leaving the parameters' physical domain)
    category: str = ""
    #: the parameters out of their domain in the stage's unbounded fit: ({parameter, value, std, bound}, ...)
    wanted: tuple = ()


class Best(NamedTuple):
    """The fit of the stages kept: parameter indices, values, standard deviations, RSS, held-out RMS and the
    per-fold held-out (sum of squares, count) rows (None without cross-validation)."""

    idx: list
    x: np.ndarray
    std: np.ndarray
    rss: float
    cv: float
    folds: np.ndarray | None = None


@dataclass(frozen=True)
class Practical:
    """The practical threshold of a stage's gain: ``absolute`` mm when given, else ``fraction`` of the error the
    stage starts from, and at least ``floor`` mm (a part of the instrument's stated sigma: where the model's
    errors are many times the sigma, the sigma alone would name effects worth a micrometre)."""

    absolute: float | None = None
    fraction: float = 0.01
    floor: float = 0.0

    def threshold(self, start: float) -> float:
        if self.absolute is not None:
            return float(self.absolute)
        return max(float(self.floor), self.fraction * float(start))


@dataclass(frozen=True)
class Nested:
    """A least-squares model whose parameters (``names``) are labelled by block (``kinds``): the ``nuisance``
    kinds, fitted first as the stage ``first``, then one kind per stage."""

    names: tuple
    kinds: tuple
    #: (parameter indices, start values[, (lower, upper) bounds]) -> (values, standard deviations, RSS)
    fit: Callable
    #: (values of every parameter, column indices) -> those columns of the Jacobian of the residuals (m, len(cols))
    jacobian: Callable
    #: (parameter indices, values) -> the record of the fitted rows' errors kept with a stage
    summary: Callable
    #: residuals (coordinates): the F test's count
    m: int
    #: points measured: a stage's RMS is sqrt(RSS / points)
    points: int
    first: str
    nuisance: tuple
    #: (parameter indices, values fitted on all rows[, bounds]) -> the held-out (sum of squares, count) per
    #: fold (k, 2) (:func:`fold_errors`); None: no cross-validation
    cv: Callable | None = None
    #: (stage, candidate indices) -> (those the data can see, [(index, why)] the others); None: all
    screen: Callable | None = None
    #: {kind: the kinds acting through its parameters}: dropped with it in the backward re-test
    through: dict = field(default_factory=dict)
    #: (lower, upper, open) arrays over ``names``: each parameter's physical domain; None: unbounded
    bounds: tuple | None = None
    #: what a stage must buy to be named besides its F test
    practical: Practical = Practical()
    #: values of every parameter -> the residuals (m,): a stage whose Gauss-Newton step from the fit before it
    #: buys under half the practical threshold is not fitted (:func:`linear_gain`); None: every stage fitted
    residual: Callable | None = None


class Fitted(NamedTuple):
    """A fit within the domain (:func:`domain_fit`): values, standard deviations, RSS, the parameters its
    unbounded fit put out of their domain [(index, value, std, bound, standard deviations beyond)], the
    solver's bounds (None: unbounded) and the unbounded fit's values and RSS."""

    x: np.ndarray
    std: np.ndarray
    rss: float
    wanted: list
    bounds: tuple | None
    free_x: np.ndarray
    free_rss: float


def least_squares_fit(fun: Callable, jac: Callable, x0: np.ndarray, bounds: tuple | None = None,
                      keep: dict | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """Levenberg-Marquardt fit of the residuals ``fun(x)`` (Jacobian ``jac(x)``) from ``x0``: (x, std, rss), the
    standard deviations those of ``s^2 (J^T J)^-1`` with ``s^2 = RSS / (m - p)``.  ``bounds`` (lower, upper):
    the trust-region reflective solver within them instead, ``x0`` moved into them first.  ``keep``: given
    the solution's ``x``, residuals ``fun`` and Jacobian ``jac`` (what the held-out folds step from)."""
    if len(x0) == 0:
        r = fun(x0)
        return x0, x0, float(r @ r)
    if bounds is None:
        sol = least_squares(fun, x0, jac=jac, method="lm", x_scale="jac", xtol=1e-10, ftol=1e-10, gtol=1e-10)
    else:
        lo, hi = (np.asarray(b, dtype=float) for b in bounds)
        sol = least_squares(fun, np.clip(x0, lo, hi), jac=jac, bounds=(lo, hi), method="trf", x_scale="jac",
                            xtol=1e-10, ftol=1e-10, gtol=1e-10)
    r = sol.fun
    rss = float(r @ r)
    dof = max(len(r) - len(x0), 1)
    J = sol.jac   # the solver's, at the solution
    if keep is not None:
        keep.update(x=sol.x.copy(), fun=r, jac=J)
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


def identifiable(J: np.ndarray, names, base: list, candidates: list, tol: float) -> tuple[list, list]:
    """Which ``candidates`` (column indices of J, in order) add a direction beyond ``tol`` to the span of
    ``base`` and of the candidates kept before them, the columns scaled to unit norm (Gram-Schmidt): (kept,
    [(index, why)] removed, a removed one named with the parameters ``names`` it combines)."""
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
                            + _combination(Js[:, span], Js[:, i], [names[k] for k in span])))
    return kept, removed


def fold_errors(fit: Callable, held_out: Callable, folds) -> np.ndarray:
    """The held-out (sum of squares, count) of each fold (k, 2): ``fit(train)`` the parameters fitted on the
    rows of the mask ``train``, ``held_out(test, parameters)`` the (sum of squares, count) of ``test``'s rows."""
    return np.array([held_out(test, fit(~test)) for test in folds], dtype=float).reshape(-1, 2)


def _pooled(folds: np.ndarray | None) -> float:
    return float(np.sqrt(folds[:, 0].sum() / max(folds[:, 1].sum(), 1.0))) if folds is not None else float("nan")


def _per_fold(folds: np.ndarray) -> np.ndarray:
    return np.sqrt(folds[:, 0] / np.maximum(folds[:, 1], 1.0))


#: a parameter whose unbounded value is beyond its bound by more than this many standard deviations fits only
#: by leaving its domain (within them, the bounded fit holds it on the bound: noise around a null value)
BEYOND = 2.0


def domain_fit(nf: Nested, idx: list, x0: np.ndarray, stage: str | None = None) -> Fitted:
    """The fit of the parameters ``idx`` within their domain (``nf.bounds``): the fast unbounded fit, and where
    it leaves the domain the bounded one from there, with what the unbounded fit wanted (:class:`Fitted`).
    Not when a parameter of the kind ``stage`` is beyond its bound by more than :data:`BEYOND` standard
    deviations: that stage is not named whatever its bounded fit (it stands in for something else)."""
    x, sd, rss = nf.fit(idx, x0)
    if nf.bounds is None or not idx:
        return Fitted(x, sd, rss, [], None, x, rss)
    lo, hi, op = (np.asarray(b)[idx] for b in nf.bounds)
    out = (x < lo) | (x > hi) | (op & (x <= lo))
    if not np.any(out):
        return Fitted(x, sd, rss, [], None, x, rss)
    wanted = []
    for k in np.flatnonzero(out):
        bound = lo[k] if x[k] <= lo[k] else hi[k]
        wanted.append((idx[k], float(x[k]), float(sd[k]), float(bound),
                       float(abs(x[k] - bound) / sd[k]) if sd[k] > 0 else float("inf")))
    if stage is not None and any(z > BEYOND and nf.kinds[i] == stage for i, _, _, _, z in wanted):
        return Fitted(x, sd, rss, wanted, None, x, rss)
    # an open lower bound (a scale > 0) kept off its value: the solver's bounds are closed
    fin = np.isfinite(lo)
    lo_s = np.where(op & fin, lo + 1e-6 * np.maximum(1.0, np.abs(np.where(fin, lo, 0.0))), lo)
    xb, sdb, rssb = nf.fit(idx, np.clip(x, lo_s, hi), (lo_s, hi))
    return Fitted(xb, sdb, rssb, wanted, (lo_s, hi), x, rss)


def _cv(nf: Nested, idx: list, x: np.ndarray, bounds=None) -> np.ndarray | None:
    if nf.cv is None:
        return None
    return nf.cv(idx, x) if bounds is None else nf.cv(idx, x, bounds)


def _rms(nf: Nested, rss: float) -> float:
    return float(np.sqrt(rss / nf.points))


def _wanted(nf: Nested, f: Fitted, kind: str) -> tuple:
    """The parameters of ``kind`` that ``f``'s unbounded fit put beyond their bound by more than :data:`BEYOND`
    standard deviations."""
    return tuple({"parameter": nf.names[i], "value": v, "std": sd, "bound": b, "beyond_std": z}
                 for i, v, sd, b, z in f.wanted if z > BEYOND and nf.kinds[i] == kind)


def _out_of_domain(nf: Nested, stage: Stage, f: Fitted, after: float, thr: float) -> Stage:
    """``stage`` not named: it stands in for something else (its parameters' unbounded values in ``f``), buying
    ``rms(f unbounded) .. after`` (mm) out of its domain: "negligible" when that is below ``thr``."""
    far = _wanted(nf, f, stage.name)
    gain = after - _rms(nf, f.free_rss)
    cat = "stands_in" if gain >= thr else "negligible"
    why = ", ".join(f"{w['parameter']} = {w['value']:.3g} +- {w['std']:.2g} (bound {w['bound']:.3g})" for w in far)
    note = (f"{'stands in for something else' if cat == 'stands_in' else 'significant but negligible'}: it fits "
            f"only out of its physical domain ({why}); buys {gain:.3g} mm there")
    return replace(stage, kept=False, rss=f.free_rss, rms=_rms(nf, f.free_rss), gain=gain, threshold=thr,
                   category=cat, wanted=far, note=note)


def _judge(nf: Nested, best: Best, name: str, trial: list, f: Fitted, pv: float, pv_free: float,
           alpha: float) -> dict[str, Any]:
    """Whether the stage ``name`` whose trial fit is ``f`` is named (the module docstring): its domain (the F
    test of its unbounded fit ``pv_free`` passing with a parameter of its own beyond its bound by more than
    :data:`BEYOND` standard deviations: it stands in for something else; the parameters of the stages before
    it are held in their domain), its F test within the domain ``pv``, then what it buys held out against its
    standard error and the practical threshold."""
    start = best.cv if nf.cv is not None else _rms(nf, best.rss)
    thr = nf.practical.threshold(start)
    if _wanted(nf, f, name) and pv_free < alpha:
        return {"ok": False, "out": (f, _rms(nf, best.rss), thr)}
    if not pv < alpha:
        return {"ok": False}
    fitted = _rms(nf, best.rss) - _rms(nf, f.rss)
    if nf.cv is None or fitted < 0.5 * thr:
        # without folds, or a gain on the fitted rows below half the threshold: the held-out gain, smaller, is
        # not worth its folds
        gain, se, folds = fitted, float("nan"), None
        ok = nf.cv is None and gain >= thr
    else:
        folds = _cv(nf, trial, f.x, f.bounds)
        gain = best.cv - _pooled(folds)
        d = _per_fold(best.folds) - _per_fold(folds)
        se = float(np.std(d, ddof=1) / np.sqrt(len(d))) if len(d) > 1 else float("inf")
        ok = gain > se and gain >= thr
    rec: dict[str, Any] = {"ok": ok, "gain": gain, "gain_se": se, "threshold": thr, "folds": folds}
    if not ok and gain > 0:
        held = "held out" if folds is not None else "on the fitted rows"
        rec.update(category="negligible",
                   note=f"significant but negligible: buys {gain:.3g} mm {held}"
                        + (f" (+- {se:.2g} mm fold to fold)" if se == se else "") + f", threshold {thr:.3g} mm")
    return rec


def forward_stages(nf: Nested, order, alpha: float, tol: float, removed=(), progress=None) -> tuple[list, Best, list]:
    """The nuisance fit, then each stage of ``order`` tried in turn on the stages kept before it (the module
    docstring): (the stages, the best fit, the parameters removed [(index, why)], ``removed``'s first);
    ``progress`` called with a line per stage."""
    t0 = time.perf_counter()
    active = [i for i, k in enumerate(nf.kinds) if k in nf.nuisance]
    x, sd, rss = nf.fit(active, np.zeros(len(active)))
    folds = _cv(nf, active, x)
    cv = _pooled(folds)
    stages = [Stage(nf.first, True, len(active), rss, _rms(nf, rss), float("nan"), cv, nf.summary(active, x))]
    best = Best(active, x, sd, rss, cv, folds)
    _say(progress, 0, len(order), stages[0], t0)
    removed = list(removed)
    for k, name in enumerate(order, 1):
        x_all = np.zeros(len(nf.names))
        x_all[best.idx] = best.x
        cands = [i for i, kd in enumerate(nf.kinds) if kd == name]
        if nf.screen is not None:
            cands, out = nf.screen(name, cands)
            removed += out
        # at the stage's start (an effect may act through the parameters kept): the columns of those and of
        # the candidates only
        cols = best.idx + cands
        J = nf.jacobian(x_all, cols)
        kept, rem = identifiable(J, [nf.names[i] for i in cols], list(range(len(best.idx))),
                                 list(range(len(best.idx), len(cols))), tol)
        kept = [cols[i] for i in kept]
        removed += [(cols[i], why) for i, why in rem]
        trial = best.idx + kept
        x0 = np.zeros(len(trial))
        x0[:len(best.idx)] = best.x
        lin = linear_gain(nf, best, x_all, J[:, list(range(len(best.idx))) + [cols.index(i) for i in kept]],
                          trial) if kept else None
        if lin is not None:
            stages.append(_linear_stage(nf, best, name, len(trial), alpha, *lin))
            _say(progress, k, len(order), stages[-1], t0)
            continue
        f = domain_fit(nf, trial, x0, name) if kept else Fitted(best.x, best.std, best.rss, [], None, best.x, best.rss)
        # the F test of the fit within the domain; one that passes only out of it stands in for something else
        pv = f_test(best.rss, len(best.idx), f.rss, len(trial), nf.m)
        pv_free = f_test(best.rss, len(best.idx), f.free_rss, len(trial), nf.m)
        j: dict[str, Any] = _judge(nf, best, name, trial, f, pv, pv_free, alpha) if kept else {"ok": False}
        ok = j["ok"]
        x_s = f.free_x if "out" in j else f.x
        st = Stage(name, ok, len(trial), f.rss, _rms(nf, f.rss), pv_free if "out" in j else pv,
                   _pooled(j.get("folds")), nf.summary(trial, x_s), j.get("note", ""), j.get("gain", float("nan")),
                   j.get("gain_se", float("nan")), j.get("threshold", float("nan")), j.get("category", ""))
        stages.append(_out_of_domain(nf, st, *j["out"]) if "out" in j else st)
        if ok:
            best = Best(trial, f.x, f.std, f.rss, _pooled(j["folds"]), j["folds"])
        _say(progress, k, len(order), stages[-1], t0)
    return stages, best, removed


def linear_gain(nf: Nested, best: Best, x_all: np.ndarray, J: np.ndarray,
                trial: list) -> tuple[float, float, float, str] | None:
    """(RSS, gain in mm, threshold, where) of a stage's Gauss-Newton step from the fit before it (the Jacobian
    ``J`` of its ``trial`` parameters there: the first step of its fit) when that gain -- on the fitted rows,
    then held out (the folds from that step) -- is under half the practical threshold: the stage cannot be
    named, its fit is skipped (30 couplings on 12k rows: 80 s); else None."""
    if nf.residual is None:
        return None
    r = nf.residual(x_all)
    step = np.linalg.lstsq(J, -r, rcond=None)[0]
    rss = float(np.sum((r + J @ step) ** 2))
    start = best.cv if nf.cv is not None else _rms(nf, best.rss)
    thr = nf.practical.threshold(start)
    gain = _rms(nf, best.rss) - _rms(nf, rss)
    if gain < 0.5 * thr:
        return rss, gain, thr, "on the fitted rows"
    if nf.cv is None or not thr > 0:
        return None
    x = np.concatenate([best.x, np.zeros(len(trial) - len(best.idx))]) + step
    held = best.cv - _pooled(_cv(nf, trial, x))
    return (rss, held, thr, "held out") if held < 0.5 * thr else None


def _linear_stage(nf: Nested, best: Best, name: str, size: int, alpha: float, rss: float, gain: float,
                  thr: float, where: str) -> Stage:
    """The record of a stage not fitted (:func:`linear_gain`): its linearised RSS, F test and gain."""
    pv = f_test(best.rss, len(best.idx), rss, size, nf.m)
    cat, note = ("negligible", f"significant but negligible: buys {gain:.3g} mm {where} (one Gauss-Newton "
                 f"step), threshold {thr:.3g} mm") if pv < alpha else ("", "")
    return Stage(name, False, size, rss, _rms(nf, rss), pv, float("nan"), nf.summary(best.idx, best.x), note, gain,
                 float("nan"), thr, cat)


def _say(progress, k: int, n: int, s: Stage, t0: float) -> None:
    if progress is None:
        return
    what = "named" if s.kept else (s.note.split(":")[0] if s.note else "not named")
    held = f", held out {s.cv_rms:.4f} mm" if s.cv_rms == s.cv_rms else ""
    progress(f"stage {k}/{n} {s.name}: {s.n_params} parameters, {what}, RMS {s.rms:.4f} mm{held} "
             f"({time.perf_counter() - t0:.1f} s)")


def backward_stages(nf: Nested, stages: list, best: Best, alpha: float) -> tuple[list, Best]:
    """Each stage kept checked again beside all the others: one that the stages kept after it explain (its F
    test against the final set fails) is no longer kept -- a joint offset fitted first passes for part of a
    sag the compliance, tried after it, explains -- the least needed first (with the stages acting through
    it, ``nf.through``), until every one left is needed; then the stages kept after the first dropped are
    refitted in turn (with their cross-validated error), so that their records (error before and after
    each) are those of the stages kept."""
    stages, first = list(stages), None
    while True:
        worst = None
        named = [s.name for s in stages[1:] if s.kept]
        gone_out = _sits_on_bound(nf, stages, best)
        if gone_out is not None:
            k, stage, best = gone_out
            stages[k] = stage
            for i, t in enumerate(stages):
                if t.kept and t.name in nf.through.get(stage.name, ()):
                    stages[i] = replace(t, kept=False, note=f"acts through {stage.name}, which stands in for "
                                                            f"something else")
                    k = min(k, i)
            first = k if first is None else min(first, k)
            continue
        worst = _least_needed(nf, best, named, alpha, skip_last=first is None)
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
        idx = [i for i in best.idx if nf.kinds[i] in nf.nuisance or nf.kinds[i] in upto]
        f = domain_fit(nf, idx, np.array([best.x[best.idx.index(i)] for i in idx]))
        folds = _cv(nf, idx, f.x, f.bounds)
        cv = _pooled(folds)
        stages[k] = prev = replace(s, n_params=len(idx), rss=f.rss, rms=_rms(nf, f.rss),
                                   p_value=f_test(prev.rss, prev.n_params, f.rss, len(idx), nf.m), cv_rms=cv,
                                   stats=nf.summary(idx, f.x),
                                   gain=(prev.cv_rms - cv) if nf.cv is not None else prev.rms - _rms(nf, f.rss))
        if len(idx) == len(best.idx):
            best = Best(idx, f.x, f.std, f.rss, cv, folds)
    return stages, best


def _least_needed(nf: Nested, best: Best, named: list, alpha: float, skip_last: bool):
    """The named stage least needed beside the others (its F test against the fit of all fails, the largest
    p-value), with the stages acting through it: (name, p-value, the fit without them, their names), or None.
    The p-values are first those of the linearised fit at ``best`` (removing the block ``g`` raises the RSS by
    ``x_g^T (C_gg)^-1 x_g``, ``C = (J^T J)^-1``: one Jacobian, no refit); the candidates are then refitted in
    that order, the first whose refit's F test fails taken."""
    named = named[:-1] if skip_last else named   # without the last one is the set before it: it passed
    if not named:
        return None
    x_all = np.zeros(len(nf.names))
    x_all[best.idx] = best.x
    J = nf.jacobian(x_all, best.idx)
    sc = np.maximum(np.linalg.norm(J, axis=0), 1e-300)
    C = np.linalg.pinv((J / sc).T @ (J / sc))
    xs = best.x * sc
    order = []
    for name in named:
        gone = {name, *nf.through.get(name, ())}
        g = [k for k, i in enumerate(best.idx) if nf.kinds[i] in gone]
        rise = float(xs[g] @ np.linalg.lstsq(C[np.ix_(g, g)], xs[g], rcond=None)[0])
        order.append((f_test(best.rss + rise, len(best.idx) - len(g), best.rss, len(best.idx), nf.m), name, gone))
    for pv_lin, name, gone in sorted(order, key=lambda t: -t[0]):
        if pv_lin < alpha:
            return None
        idx = [i for i in best.idx if nf.kinds[i] not in gone]
        f = domain_fit(nf, idx, np.array([best.x[best.idx.index(i)] for i in idx]))
        pv = f_test(f.rss, len(idx), best.rss, len(best.idx), nf.m)
        if pv >= alpha:
            return name, pv, Best(idx, f.x, f.std, f.rss, float("nan")), gone
    return None


def _sits_on_bound(nf: Nested, stages: list, best: Best):
    """The named stage whose parameters the unbounded fit of all those named puts furthest beyond their bounds
    (more than :data:`BEYOND` standard deviations), not named (it stands in for something else: :func:`_out_of_domain`),
    and the fit without it (with the stages acting through it): (its index, its record, the fit), or None."""
    if nf.bounds is None:
        return None
    f = domain_fit(nf, best.idx, best.x)
    kept = {s.name: k for k, s in enumerate(stages) if k and s.kept}
    far = [(z, nf.kinds[i]) for i, _, _, _, z in f.wanted if z > BEYOND and nf.kinds[i] in kept]
    if not far:
        return None
    name = max(far)[1]
    gone = {name, *nf.through.get(name, ())}
    idx = [i for i in best.idx if nf.kinds[i] not in gone]
    g = domain_fit(nf, idx, np.array([best.x[best.idx.index(i)] for i in idx]))
    thr = nf.practical.threshold(best.cv if nf.cv is not None else _rms(nf, best.rss))
    k = kept[name]
    return k, _out_of_domain(nf, stages[k], f, _rms(nf, g.rss), thr), Best(idx, g.x, g.std, g.rss, float("nan"))


def select_stages(nf: Nested, order, alpha: float, tol: float, removed=(), progress=None) -> tuple[list, Best, list]:
    """:func:`forward_stages` then :func:`backward_stages`: (the stages, the best fit, the parameters removed)."""
    stages, best, removed = forward_stages(nf, order, alpha, tol, removed, progress)
    stages, best = backward_stages(nf, stages, best, alpha)
    return stages, best, removed
