"""Staged selection over nested least-squares fits: the parameters come in blocks, a nuisance block always
fitted, then one block per stage tried in a fixed order, each stage's fit nesting the fits before it.

1. The nuisance block is fitted first (:func:`least_squares_fit`, Levenberg-Marquardt).
2. Each stage in turn: its candidates pass the model's screen (a parameter the data cannot see), then
   :func:`identifiable` keeps those whose Jacobian column adds a direction beyond ``tol`` to the span of the
   parameters kept before (Gram-Schmidt on unit-norm columns) and lists the others with the parameters they
   combine.  The stage is kept when the F test (:func:`vjm.stats.fit.f_test`) of its residual drop has a
   p-value below ``alpha`` and, with cross-validation, its held-out RMS drops too.
3. Once all are tried (:func:`backward_stages`), each stage kept is tested again beside all the others: one
   that the stages after it explain (its F test against the final set fails) is dropped, the least needed
   first, until every one left is needed; the stages kept after the first dropped are refitted in turn so
   that their records are those of the stages kept.

It knows nothing of the measurement model: a :class:`Nested` gives the fits, the Jacobian, the held-out
error and the screen as callables on parameter indices.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Callable, NamedTuple

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


class Best(NamedTuple):
    """The fit of the stages kept: parameter indices, values, standard deviations, RSS and held-out RMS."""

    idx: list
    x: np.ndarray
    std: np.ndarray
    rss: float
    cv: float


@dataclass(frozen=True)
class Nested:
    """A least-squares model whose parameters (``names``) are labelled by block (``kinds``): the ``nuisance``
    kinds, fitted first as the stage ``first``, then one kind per stage."""

    names: tuple
    kinds: tuple
    #: (parameter indices, start values) -> (values, standard deviations, RSS)
    fit: Callable
    #: (values of every parameter) -> the Jacobian of the residuals (m, len(names))
    jacobian: Callable
    #: (parameter indices, values) -> the record of the fitted rows' errors kept with a stage
    summary: Callable
    #: residuals (coordinates): the F test's count
    m: int
    #: points measured: a stage's RMS is sqrt(RSS / points)
    points: int
    first: str
    nuisance: tuple
    #: (parameter indices, values fitted on all rows) -> the cross-validated RMS; None: no cross-validation
    cv: Callable | None = None
    #: (stage, candidate indices) -> (those the data can see, [(index, why)] the others); None: all
    screen: Callable | None = None
    #: {kind: the kinds acting through its parameters}: dropped with it in the backward re-test
    through: dict = field(default_factory=dict)


def least_squares_fit(fun: Callable, jac: Callable, x0: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Levenberg-Marquardt fit of the residuals ``fun(x)`` (Jacobian ``jac(x)``) from ``x0``: (x, std, rss), the
    standard deviations those of ``s^2 (J^T J)^-1`` with ``s^2 = RSS / (m - p)``."""
    if len(x0) == 0:
        r = fun(x0)
        return x0, x0, float(r @ r)
    sol = least_squares(fun, x0, jac=jac, method="lm", x_scale="jac", xtol=1e-10, ftol=1e-10, gtol=1e-10)
    r = sol.fun
    rss = float(r @ r)
    dof = max(len(r) - len(x0), 1)
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


def _cv(nf: Nested, idx: list, x: np.ndarray) -> float:
    return nf.cv(idx, x) if nf.cv is not None else float("nan")


def _rms(nf: Nested, rss: float) -> float:
    return float(np.sqrt(rss / nf.points))


def forward_stages(nf: Nested, order, alpha: float, tol: float, removed=()) -> tuple[list, Best, list]:
    """The nuisance fit, then each stage of ``order`` tried in turn on the stages kept before it (the module
    docstring): (the stages, the best fit, the parameters removed [(index, why)], ``removed``'s first)."""
    active = [i for i, k in enumerate(nf.kinds) if k in nf.nuisance]
    x, sd, rss = nf.fit(active, np.zeros(len(active)))
    cv = _cv(nf, active, x)
    stages = [Stage(nf.first, True, len(active), rss, _rms(nf, rss), float("nan"), cv, nf.summary(active, x))]
    best = Best(active, x, sd, rss, cv)
    removed = list(removed)
    for name in order:
        x_all = np.zeros(len(nf.names))
        x_all[best.idx] = best.x
        J = nf.jacobian(x_all)   # at the stage's start: an effect may act through the parameters kept
        cands = [i for i, k in enumerate(nf.kinds) if k == name]
        if nf.screen is not None:
            cands, out = nf.screen(name, cands)
            removed += out
        kept, rem = identifiable(J, nf.names, best.idx, cands, tol)
        removed += rem
        trial = best.idx + kept
        x0 = np.zeros(len(trial))
        x0[:len(best.idx)] = best.x
        xt, sdt, rsst = nf.fit(trial, x0)
        pv = f_test(best.rss, len(best.idx), rsst, len(trial), nf.m)
        ok = bool(kept) and pv < alpha
        cvt = _cv(nf, trial, xt) if nf.cv is not None and ok else float("nan")
        ok = ok and not (nf.cv is not None and cvt >= best.cv)
        stages.append(Stage(name, ok, len(trial), rsst, _rms(nf, rsst), pv, cvt, nf.summary(trial, xt)))
        if ok:
            best = Best(trial, xt, sdt, rsst, cvt)
    return stages, best, removed


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
        for name in named:
            if first is None and name == named[-1]:
                continue   # without the last one is the set before it: its own F test passed
            gone = {name, *nf.through.get(name, ())}
            idx = [i for i in best.idx if nf.kinds[i] not in gone]
            x, sd, rss = nf.fit(idx, np.array([best.x[best.idx.index(i)] for i in idx]))
            pv = f_test(rss, len(idx), best.rss, len(best.idx), nf.m)
            if pv >= alpha and (worst is None or pv > worst[1]):
                worst = (name, pv, Best(idx, x, sd, rss, float("nan")), gone)
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
        x, sd, rss = nf.fit(idx, np.array([best.x[best.idx.index(i)] for i in idx]))
        cv = _cv(nf, idx, x)
        stages[k] = prev = replace(s, n_params=len(idx), rss=rss, rms=_rms(nf, rss),
                                   p_value=f_test(prev.rss, prev.n_params, rss, len(idx), nf.m), cv_rms=cv,
                                   stats=nf.summary(idx, x))
        if len(idx) == len(best.idx):
            best = Best(idx, x, sd, rss, cv)
    return stages, best


def select_stages(nf: Nested, order, alpha: float, tol: float, removed=()) -> tuple[list, Best, list]:
    """:func:`forward_stages` then :func:`backward_stages`: (the stages, the best fit, the parameters removed)."""
    stages, best, removed = forward_stages(nf, order, alpha, tol, removed)
    stages, best = backward_stages(nf, stages, best, alpha)
    return stages, best, removed
