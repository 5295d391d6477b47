"""Nonlinear least squares, evidence (BIC, likelihood ratio / F test, grouped
cross-validation) and forward selection of model terms.

The engine knows nothing about mechanics.  A :class:`Problem` is a function
returning *whitened* residuals ``r = (y - f(theta)) / sigma`` for a tuple of
term names (the always-present baseline terms first) and the stacked parameter
vector of those terms, plus a posture label per residual for cross-validation.

Statistics
----------
With known measurement sigmas the residuals are standard normal under the
right model, so ``chi2 = sum r^2`` and

* likelihood ratio test of a nested model with ``q`` more parameters:
  ``chi2_0 - chi2_1 ~ chi2(q)``;
* ``BIC = chi2 + k ln n``.

With unknown sigmas (scaled by a common guess) the variance is a nuisance
parameter:

* F test: ``F = ((RSS_0 - RSS_1)/q) / (RSS_1/(n - k_1)) ~ F(q, n - k_1)``;
* ``BIC = n ln(RSS/n) + k ln n``.

With unknown sigmas and several variance components (``Problem.components``:
translations and rotations, each with its own unknown variance) every fit is a
maximum-likelihood fit with the variances profiled out (least squares
reweighted by each component's ``RSS_g/n_g`` until they settle), and

* likelihood ratio test: ``sum_g n_g ln(RSS_g0 / RSS_g1) ~ chi2(q)``;
* ``BIC = sum_g n_g ln(RSS_g/n_g) + k ln n``,

so that naming an effect that changes one component's scatter does not move
the yardstick of the next test.

Parameter covariance is ``s^2 (J^T J)^-1`` at the optimum (``s^2 = 1`` with
known sigmas, ``RSS/(n-k)`` otherwise, J and RSS reweighted by the components'
variances); intervals are ``theta +- 1.96 se``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import optimize, stats

from ..errors import VjmError
from .components import REWEIGHT_ROUNDS, REWEIGHT_TOL, component_labels, group_fields, group_var
from .terms import Problem

Z95 = 1.959963984540054


@dataclass(frozen=True)
class FitResult:
    """Least-squares fit of a set of terms."""

    names: tuple
    theta: np.ndarray
    se: np.ndarray
    chi2: float  # sum of squared whitened residuals (RSS in guess units if sigma unknown)
    n: int
    k: int
    sigma_known: bool
    success: bool
    residuals: np.ndarray = field(repr=False, default=None)
    #: indices (into theta) of the parameters that ended on a bound of their range
    at_bound: tuple = ()
    message: str = ""
    #: parameter covariance ``s^2 (J^T J)^-1`` (k, k); None where no fit was made
    cov: np.ndarray | None = field(repr=False, default=None)
    #: unknown sigmas with several variance components: RSS (in ``residuals``' units), count and
    #: fitted variance (RSS_g / n_g) of each component; empty otherwise
    group_rss: tuple = ()
    group_n: tuple = ()

    @property
    def dof(self) -> int:
        return self.n - self.k

    @property
    def group_var(self) -> tuple:
        """Fitted variance of each component (RSS_g / n_g, maximum likelihood)."""
        return tuple(r / max(m, 1) for r, m in zip(self.group_rss, self.group_n))

    @property
    def log_rss(self) -> float:
        """``sum_g n_g ln(RSS_g / n_g)`` (one component: ``n ln(RSS/n)``): -2 x the profiled log-likelihood."""
        if self.group_rss:
            return float(sum(m * np.log(max(r, 1e-300) / max(m, 1)) for r, m in zip(self.group_rss, self.group_n)))
        return float(self.n * np.log(max(self.chi2, 1e-300) / self.n))

    @property
    def bic(self) -> float:
        if self.sigma_known:
            return float(self.chi2 + self.k * np.log(self.n))
        return float(self.log_rss + self.k * np.log(self.n))

    @property
    def reduced_chi2(self) -> float:
        return float(self.chi2 / max(self.dof, 1))

    def values(self, problem: Problem) -> dict:
        """name -> {param: {value, se, ci95, unit}} per term."""
        out, i = {}, 0
        for nm in self.names:
            d = {}
            for p in problem.terms[nm].params:
                v, s = float(self.theta[i]), float(self.se[i])
                d[p.name] = {"value": v, "se": s, "ci95": [v - Z95 * s, v + Z95 * s], "unit": p.unit}
                i += 1
            out[nm] = d
        return out

    def bound_params(self, problem: Problem, name: str) -> list:
        """Names of the parameters of term ``name`` that ended on a bound."""
        out, i = [], 0
        for nm in self.names:
            for p in problem.terms[nm].params:
                if nm == name and i in self.at_bound:
                    out.append(p.name)
                i += 1
        return out

    def term_theta(self, problem: Problem, name: str) -> np.ndarray:
        i = 0
        for nm in self.names:
            k = len(problem.terms[nm].params)
            if nm == name:
                return self.theta[i:i + k]
            i += k
        raise KeyError(name)


def _start_vector(problem, names, warm):
    x0 = []
    for nm in names:
        if warm is not None and nm in warm.names:
            x0.extend(warm.term_theta(problem, nm))
        else:
            x0.extend(p.start for p in problem.terms[nm].params)
    return np.array(x0, dtype=float)


def fit_terms(problem: Problem, names, mask=None, warm: FitResult | None = None) -> FitResult:
    """Fit the parameters of ``names`` by nonlinear least squares.

    With unknown sigmas and several variance components (``problem.components``), each
    component's residuals are weighted by its fitted variance ``RSS_g/n_g``, refitted until
    the variances settle (the maximum-likelihood fit with the variances profiled out; ``warm``'s
    variances start it).

    Parameters
    ----------
    mask : optional bool (m,) selecting the residuals used (cross-validation).
    warm : a previous fit whose values start the shared terms.
    """
    names = tuple(names)
    params = problem.params(names)
    lo = np.array([p.lower for p in params])
    hi = np.array([p.upper for p in params])
    xs = np.array([p.scale for p in params])
    x0 = np.clip(_start_vector(problem, names, warm), lo, hi)
    # strictly feasible start for trf: nudge off a bound by a small fraction of the scale
    x0 = np.where(x0 <= lo, lo + 1e-3 * xs, x0)
    x0 = np.where(x0 >= hi, hi - 1e-3 * xs, x0)
    comp = component_labels(problem, mask)

    def raw(u):
        r = problem.residuals(names, u * xs)
        return r if mask is None else r[mask]

    if len(params) == 0:
        r = raw(x0)
        return FitResult(names, x0, np.zeros(0), float(r @ r), r.size, 0, problem.sigma_known, True, r,
                         **group_fields(r, comp))
    # per-component weights 1/sd (relative): from the warm fit's variances, else equal
    wg = None
    if comp is not None:
        wg = np.ones(comp[1])
        if warm is not None and len(warm.group_rss) == comp[1]:
            wg = 1.0 / np.sqrt(np.maximum(warm.group_var, 1e-300))

    # optimise u = theta / scale so that finite-difference steps and tolerances are
    # relative to each parameter's typical magnitude (compliances are ~1e-7)
    u0 = x0 / xs
    for _ in range(REWEIGHT_ROUNDS if comp is not None else 1):
        w = None if wg is None else wg[comp[0]]

        def fun(u, w=w):
            r = raw(u)
            return r if w is None else r * w

        sol = optimize.least_squares(fun, u0, bounds=(lo / xs, hi / xs), diff_step=1e-6,
                                     method="trf", xtol=1e-8, ftol=1e-8, gtol=1e-8, max_nfev=100)
        if comp is None:
            break
        u0 = sol.x
        new = 1.0 / np.sqrt(group_var(raw(sol.x), *comp)[2])
        # settled: the components' relative weights are those the fit's own residuals give
        ratio = new / wg
        wg = new
        if np.all(np.abs(ratio / ratio[0] - 1.0) <= REWEIGHT_TOL):
            break
    r = raw(sol.x) if comp is not None else sol.fun
    n, k = r.size, len(params)
    chi2 = float(r @ r)
    chi2w = float(sol.fun @ sol.fun)
    # covariance in u (well-conditioned columns), mapped back to theta; the
    # pseudo-inverse gives a parameter the data cannot see a huge (honest) standard error
    Js = sol.jac
    JtJ = Js.T @ Js
    try:
        cov = np.linalg.pinv(JtJ, rcond=1e-12, hermitian=True) * np.outer(xs, xs)
    except np.linalg.LinAlgError:
        cov = np.full((k, k), np.inf)
    s2 = 1.0 if problem.sigma_known else chi2w / max(n - k, 1)
    se = np.sqrt(np.maximum(np.diag(cov) * s2, 0.0))
    zero = np.diag(JtJ) <= 0
    se[zero] = np.inf
    theta = sol.x * xs
    # on a bound: the optimiser's active set, or within 1e-4 of the parameter's scale of it
    # (trf stays strictly inside, so a clipped parameter ends a hair away from its bound)
    tol = 1e-4 * xs
    at = (sol.active_mask != 0) | (theta - lo <= tol) | (hi - theta <= tol)
    return FitResult(names, theta, se, chi2, n, k, problem.sigma_known, bool(sol.success), r,
                     tuple(int(i) for i in np.flatnonzero(at)), str(sol.message), cov * s2, **group_fields(r, comp))


def compare(problem: Problem, small: FitResult, big: FitResult) -> tuple[float, float]:
    """(delta_bic, p_value) of ``big`` against the nested ``small``: chi-square test (known sigmas),
    F test (one unknown variance) or likelihood-ratio test (several variance components profiled)."""
    q = big.k - small.k
    dbic = big.bic - small.bic
    if q <= 0:
        return float(dbic), 1.0
    if problem.sigma_known:
        stat = max(small.chi2 - big.chi2, 0.0)
        p = stats.chi2.sf(stat, q)
    elif big.group_rss and len(big.group_rss) == len(small.group_rss):
        # likelihood ratio with each component's variance profiled out
        p = stats.chi2.sf(max(small.log_rss - big.log_rss, 0.0), q)
    else:
        p = f_test(small.chi2, small.k, big.chi2, big.k, big.n)
    return float(dbic), float(p)


def f_test(rss0: float, k0: int, rss1: float, k1: int, n: int) -> float:
    """p-value of the F test of a least-squares fit of ``k1`` parameters against the nested fit of ``k0``, from
    their residual sums of squares ``rss0``, ``rss1`` over ``n`` residuals of one unknown variance:
    ``F = ((RSS_0 - RSS_1)/q) / (RSS_1/(n - k_1)) ~ F(q, n - k_1)``, ``q = k1 - k0``; 1 where no test can be
    made (nothing added, no residual degree of freedom, a perfect fit)."""
    q, d2 = k1 - k0, n - k1
    if q <= 0 or d2 <= 0 or rss1 <= 0:
        return 1.0
    F = max(rss0 - rss1, 0.0) / q / (rss1 / d2)
    return float(stats.f.sf(F, q, d2))


def f_ratio(extra: float, q: int, rest: float, d2: int) -> tuple[float, float]:
    """(F, p-value) of ``q`` added degrees of freedom that remove the sum of squares ``extra`` against the
    residual sum ``rest`` on ``d2`` degrees of freedom: ``F = (extra/q) / (rest/d2) ~ F(q, d2)`` (the callers
    checked that both counts are positive; a residual sum below 1e-300 per degree is taken as 1e-300)."""
    F = extra / q / max(rest / d2, 1e-300)
    return float(F), float(stats.f.sf(F, q, d2))


def chi2_p(stat: float, dof: int) -> float:
    """p-value of a chi-square statistic ``stat`` on ``dof`` degrees of freedom (known sigmas)."""
    return float(stats.chi2.sf(stat, dof))


def chi2_range(alpha: float, dof: float) -> tuple[float, float]:
    """The two-sided acceptance range, at level ``alpha``, of a reduced chi-square (chi2 / dof) on ``dof``
    degrees of freedom: the residuals' variance in units of the stated one is consistent inside it."""
    return float(stats.chi2.ppf(alpha / 2, dof) / dof), float(stats.chi2.ppf(1 - alpha / 2, dof) / dof)


def chi2_margin(alpha: float, dof: int = 1) -> float:
    """The upper ``alpha`` quantile of chi-square on ``dof`` degrees of freedom (a likelihood-ratio margin)."""
    return float(stats.chi2.ppf(1.0 - alpha, dof))


def normal_upper(p: float) -> float:
    """The standard normal deviate with upper-tail probability ``p`` (a z threshold)."""
    return float(stats.norm.isf(p))


#: --folds at most this: each fold refits the whole selection, and held-out folds of a row or two say nothing
MAX_FOLDS = 50


def check_fold_count(folds: int, count: int, what: str) -> None:
    """Refuse more ``folds`` than the data have ``what`` (``count`` postures or rows, singular) to hold out: a
    fold would hold out nothing, and the report would name a cross-validation that was not made."""
    if folds > count:
        most = f"at most {count} folds" if count >= 2 else "too few to cross-validate (give no --folds)"
        raise VjmError(f"--folds {folds}: the data hold {count} {what}{'s' if count != 1 else ''}, and each fold "
                       f"holds out at least one: {most}")


def grouped_folds(groups, k: int = 5, seed: int = 0) -> list:
    """Boolean test masks of a k-fold split that keeps each group (posture) whole."""
    g = np.asarray(groups)
    uniq = np.unique(g)
    k = int(min(k, uniq.size))
    if k < 2:
        return []
    perm = np.random.default_rng(seed).permutation(uniq)
    fold_of = {u: i % k for i, u in enumerate(perm)}
    f = np.array([fold_of[x] for x in g])
    return [f == i for i in range(k)]


def interleaved_folds(n: int, k: int) -> list:
    """Boolean test masks of a k-fold split of ``n`` rows in their order, row ``i`` in fold ``i mod k``.

    Absolute poses are split so, not by :func:`grouped_folds`: their groups are the instrument's set-ups, and
    a set-up held out whole leaves its frame with no row to be registered on."""
    fold = np.arange(n) % k
    return [fold == f for f in range(k)]


def cross_validated(fit, held_out, folds) -> float:
    """Root mean square held-out error over ``folds`` (boolean test masks; NaN if none): ``fit(train)`` the
    parameters fitted on the rows of the mask ``train``, ``held_out(test, parameters)`` the (sum of squares,
    count) of the errors of the rows of ``test`` -- counted as the caller means its RMS (residuals, points)."""
    if not folds:
        return float("nan")
    sq, cnt = 0.0, 0
    for test in folds:
        s, c = held_out(test, fit(~test))
        sq += s
        cnt += c
    return float(np.sqrt(sq / max(cnt, 1)))


def cv_error(problem: Problem, names, folds, warm: FitResult | None = None) -> float:
    """Root mean square held-out whitened residual over grouped folds (NaN if no folds)."""
    names = tuple(names)

    def held_out(test, theta):
        r = problem.residuals(names, theta)[test]
        return float(r @ r), r.size

    return cross_validated(lambda train: fit_terms(problem, names, mask=train, warm=warm).theta, held_out, folds)


def clipped(problem: Problem, fr: FitResult, name: str) -> list:
    """Parameters of term ``name`` that ended on a bound other than their null value.

    A parameter on the bound at its null (a weight >= 0 fitted as 0) means
    "no effect"; on any other bound the fit was clipped and its value and
    test are not to be trusted.
    """
    out = []
    specs = {p.name: p for p in problem.terms[name].params}
    th = dict(zip([p.name for p in problem.terms[name].params], fr.term_theta(problem, name)))
    for pn in fr.bound_params(problem, name):
        p = specs[pn]
        if abs(th[pn] - p.null) > 1e-3 * p.scale:
            out.append(pn)
    return out


def lack_of_fit(fr: FitResult, pure_error: tuple | None = None) -> dict:
    """Lack-of-fit test of a final model.

    Known sigmas: ``chi2 ~ chi2(n - k)`` (``chi2_red`` = chi2 / dof).  Unknown
    sigmas: with ``pure_error = (ss_pe, dof_pe)`` from repeated measurements
    (whitened by the same common guess, or by each component's fitted variance), ``F = (SS_lof / dof_lof) / (SS_pe /
    dof_pe)`` ~ F(dof_lof, dof_pe), reported as ``chi2_red`` (the lack-of-fit
    variance in units of the pure-error variance); without repeats the test
    cannot be made (``p_value`` None and a note).
    """
    dof = fr.dof
    if fr.sigma_known:
        p = float(stats.chi2.sf(fr.chi2, dof)) if dof > 0 else None
        return {"chi2_red": fr.chi2 / max(dof, 1), "dof": int(dof), "p_value": p,
                "test": "chi2 test of the final model (known sigmas)"}
    if pure_error is not None:
        ss_pe, dof_pe = pure_error
        dof_lof = dof - dof_pe
        # several variance components: both in units of each component's fitted variance (pure_error's
        # ``var``), where the final model's RSS is the number of residuals
        chi2 = float(sum(fr.group_n)) if fr.group_rss else fr.chi2
        if dof_pe > 0 and dof_lof > 0 and ss_pe > 0:
            F = max(chi2 - ss_pe, 0.0) / dof_lof / (ss_pe / dof_pe)
            return {"chi2_red": float(F), "dof": int(dof_lof), "dof_pure_error": int(dof_pe),
                    "p_value": float(stats.f.sf(F, dof_lof, dof_pe)),
                    "test": "F test of lack of fit against pure error from repeated measurements"}
    return {"chi2_red": None, "dof": int(dof), "p_value": None,
            "test": "none",
            "note": "sigmas unknown and no repeated measurements: lack of fit cannot be judged"}
