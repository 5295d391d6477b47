"""What this data set can see: sensitivity SVD, observability and confounding.

Everything here works on the *whitened* sensitivity of the residuals to each
term's parameters, evaluated on the data's own postures and loads:

* a column ``J[:, p] * span_p`` is the change of the whitened residuals when
  parameter ``p`` sweeps its whole allowed range (linearised), so its norm is
  the largest chi-square change the parameter can make, in noise units;
* a parameter whose column norm is below 1 (less than one sigma of evidence
  even at the edge of its range) or that is (nearly) a combination of the
  term's other columns (pivoted QR) is *not observable* on this data: it is
  held fixed, and a term with nothing observable is never fitted;
* two terms whose column spaces, once the calibration's columns are
  projected out, have a canonical correlation near 1 cannot be told apart;
* a term whose columns lie (nearly) in the calibration's span can be
  mimicked by the calibration.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg

#: a parameter is observable when sweeping its range moves the whitened residuals by more than this
NOISE_NORM = 1.0
#: relative diagonal of the pivoted QR below which a column is a combination of the others
REL_RANK = 1e-3


@dataclass(frozen=True)
class TermSensitivity:
    """Whitened, range-scaled sensitivity of one term."""

    name: str
    J: np.ndarray  # (m, k) columns = d r / d theta_p * span_p
    norms: np.ndarray  # (k,) column norms (chi-square units, sqrt)
    free: tuple  # indices of the observable parameters
    fixed: tuple  # indices held fixed (unobservable)

    @property
    def observable(self) -> bool:
        return len(self.free) > 0

    @property
    def Jfree(self) -> np.ndarray:
        return self.J[:, list(self.free)]


def reference_point(params):
    """Where to evaluate a sensitivity: one typical step off the null, inside the bounds.

    At the null itself some parameters have no effect at all (the length of a
    foot whose compliance is zero), so the point is ``null + scale`` (or
    ``null - scale`` at an upper bound).
    """
    th = []
    for p in params:
        v = p.null + p.scale
        if v > p.upper:
            v = p.null - p.scale
        th.append(min(max(v, p.lower), p.upper))
    return np.array(th, float)


def span(p) -> float:
    """Allowed range of a parameter, capped at 100 typical steps (unbounded or huge ranges)."""
    return float(min(p.upper - p.lower, 100.0 * p.scale))


def jacobian(residuals, names, theta, idx, steps):
    """Forward-difference whitened Jacobian of ``residuals(names, theta)`` w.r.t. ``theta[idx]``."""
    r0 = residuals(names, theta)
    J = np.empty((r0.size, len(idx)))
    for c, (i, h) in enumerate(zip(idx, steps)):
        t = np.array(theta, float)
        t[i] += h
        J[:, c] = (residuals(names, t) - r0) / h
    return J


def calibration_columns(problem, base_theta, cal_name):
    """Whitened columns of the calibration at the baseline fit, scaled by each parameter's scale."""
    ps = problem.terms[cal_name].params
    steps = [1e-3 * p.scale for p in ps]
    J = jacobian(problem.residuals, (cal_name,), base_theta, range(len(ps)), steps)
    return J * np.array([p.scale for p in ps])


def term_sensitivity(problem, base_theta, cal_name, name) -> TermSensitivity:
    """Sensitivity of candidate ``name`` on top of the calibrated baseline, and its observable parameters."""
    ps = problem.terms[name].params
    th_ref = reference_point(ps)
    theta = np.concatenate([base_theta, th_ref])
    kc = len(base_theta)
    steps = []
    for p, v in zip(ps, th_ref):
        h = 1e-2 * p.scale
        steps.append(h if v + h <= p.upper else -h)
    J = jacobian(problem.residuals, (cal_name, name), theta, range(kc, kc + len(ps)), steps)
    J = J * np.array([span(p) for p in ps])
    norms = np.linalg.norm(J, axis=0)
    seen = [i for i in range(len(ps)) if np.isfinite(norms[i]) and norms[i] >= NOISE_NORM]
    free = []
    if seen:
        # pivoted QR on the columns that can show: keep those not (nearly) spanned by the others
        Js = J[:, seen] / norms[seen]
        _, R, piv = linalg.qr(Js, mode="economic", pivoting=True)
        d = np.abs(np.diag(R))
        keep = d >= REL_RANK * d[0]
        free = sorted(seen[int(piv[j])] for j in range(len(piv)) if keep[j])
    fixed = tuple(i for i in range(len(ps)) if i not in free)
    return TermSensitivity(name, J, norms, tuple(free), fixed)


#: sine of the angle below which a column counts as lying in the span of the columns before it
DEPENDENT = 0.05


def independent_columns(J, tol=DEPENDENT) -> tuple:
    """Indices of the columns of J kept in order (Gram-Schmidt): a column whose component
    orthogonal to the kept ones is below ``tol`` x its norm (correlation above ~0.9987) is dropped."""
    kept: list = []
    Q = np.zeros((J.shape[0], 0))
    for j in range(J.shape[1]):
        v = J[:, j]
        n = np.linalg.norm(v)
        if not np.isfinite(n) or n == 0:
            continue
        r = v - Q @ (Q.T @ v)
        if np.linalg.norm(r) < tol * n:
            continue
        kept.append(j)
        Q = np.hstack([Q, (r / np.linalg.norm(r))[:, None]])
    return tuple(kept)


def _orth(A, tol=1e-10):
    """Orthonormal basis of the column space of A (SVD, relative tolerance)."""
    if A.size == 0:
        return A
    U, s, _ = np.linalg.svd(A, full_matrices=False)
    return U[:, s > tol * max(s[0], 1e-300)] if s.size else U[:, :0]


def project_out(A, Q):
    """Columns of A with their component in span(Q) removed (Q orthonormal)."""
    return A - Q @ (Q.T @ A) if Q.size else A


def canonical_correlation(A, B) -> float:
    """Largest canonical correlation (cosine of the smallest principal angle) between span(A) and span(B)."""
    qa, qb = _orth(A), _orth(B)
    if qa.shape[1] == 0 or qb.shape[1] == 0:
        return 0.0
    return float(min(np.linalg.svd(qa.T @ qb, compute_uv=False)[0], 1.0))


def mimicry(A, C):
    """How well the calibration columns C reproduce span(A): (R, coefficients).

    R is the largest canonical correlation; the coefficients (k_cal, k_A) give
    the least-squares calibration change that best imitates each of A's columns.
    """
    if C.size == 0 or A.size == 0:
        return 0.0, np.zeros((C.shape[1] if C.ndim == 2 else 0, A.shape[1] if A.ndim == 2 else 0))
    coef, *_ = np.linalg.lstsq(C, A, rcond=None)
    return canonical_correlation(A, C), coef


def partial_correlation(A, B, C) -> float:
    """Canonical correlation of span(A) and span(B) once the calibration's span(C) is projected out."""
    Q = _orth(C)
    Ar, Br = project_out(A, Q), project_out(B, Q)
    # a term that the calibration reproduces entirely has no partial signature left (round-off only)
    if np.linalg.norm(Ar) <= 1e-6 * np.linalg.norm(A) or np.linalg.norm(Br) <= 1e-6 * np.linalg.norm(B):
        return 0.0
    return canonical_correlation(Ar, Br)


def reach(p) -> float:
    """How far a parameter can move from its null, in units of its :func:`span`."""
    return float(min(max(p.upper - p.null, p.null - p.lower), 100.0 * p.scale) / span(p))


def hiding_share(B, N, s, z, reaches=None) -> tuple[float, float]:
    """How much of a fitted signal a term B could carry unseen inside the span of others.

    B : (m, kb) columns of the term (calibration projected out); N : (m, kn) columns of the
    terms in the model; s : (m,) what those terms explain at their fitted values; z : the
    root of the chi-square(1) quantile of the test level.  Along B's direction closest to
    span(N) (unit vector u, first canonical direction), the model can replace ``t u`` by
    terms of N at a chi-square cost ``t^2 |u_perp|^2`` (u_perp: u with span(N) projected
    out), so B can carry up to ``t = z / |u_perp|`` unseen.  Returns (R, share): R the
    canonical correlation of span(B) with span(N), share that amount over ``|<s, u>|``,
    the part of the fitted signal along u (inf when there is none).  With ``reaches`` (per
    column of B: how far its parameter can move from the null, in units of the step B's
    column is scaled to), the amount is also capped at what B can put along u within its
    range, ``sum_j |<B_j, u>| reach_j`` (linearised): a term that would need more than its
    range cannot carry it.
    """
    qb, qn = _orth(B), _orth(N)
    if qb.shape[1] == 0 or qn.shape[1] == 0:
        return 0.0, 0.0
    U, sv, _ = np.linalg.svd(qb.T @ qn)
    u = qb @ U[:, 0]
    perp = float(np.linalg.norm(u - qn @ (qn.T @ u)))
    a = abs(float(s @ u))
    R = float(min(sv[0], 1.0))
    if a == 0.0:
        return R, float("inf")
    t = z / max(perp, 1e-300)
    if reaches is not None:
        t = min(t, float(np.sum(np.abs(B.T @ u) * np.asarray(reaches, float))))
    return R, float(t / a)
