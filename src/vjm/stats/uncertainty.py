"""Parameter standard deviations that account for what the model misses.

The formal covariance of a least-squares fit, ``s^2 (J^T J)^-1``, holds when the residuals are independent
and the model is right.  On real machines neither holds: the residuals are the model's errors as much as the
instrument's, and they are correlated -- neighbouring poses share the error of an effect the model lacks, an
instrument set-up shares its own.  Two estimates, the larger kept parameter by parameter
(:func:`parameter_std`):

1. **the lack-of-fit-scaled formal one.**  Without sigmas, ``s^2 (J^T J)^-1`` with ``s^2 = RSS / (m - p)``
   (the residuals' own scatter); with the instrument's sigmas, the covariance those sigmas give,
   ``(J^T J)^-1 J^T diag(sigma^2) J (J^T J)^-1`` (the fit is unweighted), times ``chi2_red`` where the
   residuals exceed them (``chi2_red = sum (r / sigma)^2 / (m - p)`` > 1): never narrower than the sigmas,
   and as wide as the lack of fit;
2. **a delete-one-block jackknife** over clusters of rows (:func:`pose_blocks`): the registration groups
   (instrument set-ups) where there are at least :data:`BLOCKS` of them, else blocks of neighbouring poses
   (in joint space) and, apart, blocks of consecutive rows (a drift in time) within each group, the larger
   of the two jackknifes kept.  Deleting a block moves the fit by ``(J^T J - J_b^T J_b)^-1 J_b^T r_b`` (one
   Gauss-Newton step from the full fit, linearised: no refit), and the jackknife variance is
   ``(G - 1) / G sum_b (d_b - mean d)^2``.  It is the cluster-robust sandwich with its small-sample
   correction (CR3): residuals correlated within a block widen it, independent ones give the formal value.
   A parameter that only one block sees (a deleted group's own frame) keeps the formal value.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: blocks of the jackknife: registration groups when there are at least this many, else blocks of
#: neighbouring poses (16 blocks: the jackknife's standard deviation is then within about 18 % of its own)
BLOCKS = 16


@dataclass(frozen=True)
class Uncertainty:
    """Standard deviations ``std`` (the larger of ``formal`` and ``jackknife``, parameter by parameter), the
    lack-of-fit scale ``scale`` applied to the formal ones (``sqrt(chi2_red)`` with sigmas, 1 below them;
    nan without sigmas), the blocks' count and the ``method`` in words."""

    std: np.ndarray
    formal: np.ndarray
    jackknife: np.ndarray
    scale: float
    blocks: int
    method: str


def pose_blocks(x: np.ndarray, groups, target: int = BLOCKS) -> list:
    """Partitions of the rows (each a list of index arrays) for the jackknife, with what they are:
    [(blocks, words)].  One partition, a block per registration group (``groups`` (n,)), when there are at
    least ``target`` groups; else two, each group cut into about ``target`` blocks in all (in proportion to
    the groups' rows):

    - blocks of neighbouring poses: recursive halving of the rows' coordinates ``x`` (n, d) (joint values),
      each column scaled by its spread, along the widest (a k-d partition: on a grid, blocks of the grid; on
      random poses, regions of the workspace) -- the errors of an effect the model lacks;
    - blocks of consecutive rows (the file's order, the order of measurement) -- a drift in time."""
    g = np.asarray([str(v) for v in groups])
    names = list(dict.fromkeys(g))
    n = len(g)
    if len(names) >= target:
        return [([np.flatnonzero(g == k) for k in names], f"{len(names)} registration groups")]
    x = np.asarray(x, dtype=float).reshape(n, -1)
    sd = np.std(x, axis=0)
    xs = x[:, sd > 0] / sd[sd > 0]
    near, order = [], []
    for k in names:
        rows = np.flatnonzero(g == k)
        cut = int(min(len(rows), max(1, round(target * len(rows) / n))))
        near += _split(xs, rows, cut)
        order += [b for b in np.array_split(rows, cut) if len(b)]
    where = f" within {len(names)} registration groups" if len(names) > 1 else ""
    return [(near, f"{len(near)} blocks of neighbouring poses (joint values){where}"),
            (order, f"{len(order)} blocks of consecutive rows (the file's order){where}")]


def _split(x: np.ndarray, rows: np.ndarray, k: int) -> list:
    if k <= 1 or x.shape[1] == 0:
        return [rows]
    c = int(np.argmax(np.std(x[rows], axis=0)))
    o = rows[np.argsort(x[rows, c], kind="stable")]
    k1 = k // 2
    cut = int(round(len(o) * k1 / k))
    return _split(x, o[:cut], k1) + _split(x, o[cut:], k - k1)


def jackknife_std(J: np.ndarray, r: np.ndarray, blocks) -> np.ndarray:
    """The linearised delete-one-block jackknife's standard deviations (p,) of the least-squares fit whose
    residuals ``r`` (m,) and Jacobian ``J`` (m, p) are given, ``blocks`` index arrays into the residuals (see
    the module docstring); nan for a parameter that a block alone sees, or with fewer than 2 blocks."""
    p = J.shape[1]
    if len(blocks) < 2:
        return np.full(p, np.nan)
    # columns scaled to unit norm: the parameters' units (mm, rad, rad/(N mm)) span 1e12
    s = np.maximum(np.linalg.norm(J, axis=0), 1e-300)
    Js = J / s
    A = Js.T @ Js
    d = np.full((len(blocks), p), np.nan)
    for i, b in enumerate(blocks):
        Jb = Js[b]
        Ab = A - Jb.T @ Jb
        seen = np.diag(Ab) > 1e-9   # a parameter the other blocks do not see: undefined without the block
        sub = np.ix_(seen, seen)
        d[i, seen] = np.linalg.lstsq(Ab[sub], (Jb.T @ r[b])[seen], rcond=1e-12)[0]
    G = len(blocks)
    var = (G - 1) / G * np.sum((d - d.mean(axis=0)) ** 2, axis=0)   # nan where a block left a parameter unseen
    return np.sqrt(var) / s


def parameter_std(J: np.ndarray, r: np.ndarray, partitions, sigma: np.ndarray | None = None) -> Uncertainty:
    """The standard deviations of the module docstring for a fit (residuals ``r`` (m,), Jacobian ``J`` (m, p),
    unweighted): ``partitions`` [(blocks, words)], each block an index array into the residuals (the
    jackknife the largest over the partitions); ``sigma`` (m,) the instrument's sigmas if stated."""
    m, p = J.shape
    s = np.maximum(np.linalg.norm(J, axis=0), 1e-300)
    Js = J / s
    Ai = np.linalg.pinv(Js.T @ Js)
    dof = max(m - p, 1)
    if sigma is None:
        formal = np.sqrt(np.maximum(np.diag(Ai), 0.0) * float(r @ r) / dof) / s
        scale = float("nan")
        how = "s^2 (J^T J)^-1, s^2 = RSS/(m-p): no sigmas"
    else:
        sigma = np.asarray(sigma, dtype=float)
        chi2_red = float(np.sum((r / sigma) ** 2)) / dof
        scale = float(np.sqrt(max(chi2_red, 1.0)))
        B = Ai @ Js.T
        formal = np.sqrt(np.einsum("ij,j,ij->i", B, sigma ** 2, B)) / s * scale
        how = f"the stated sigmas' times sqrt(chi2_red) = {scale:.3g}"
    jk = np.full(p, np.nan)
    for blocks, _ in partitions:
        jk = np.fmax(jk, jackknife_std(J, r, blocks))
    std = np.where(np.isfinite(jk), np.fmax(formal, jk), formal)
    method = (f"the larger of the formal standard deviation ({how}) and a linearised delete-one-block jackknife "
              f"over {' and over '.join(w for _, w in partitions)}")
    return Uncertainty(std, formal, jk, scale, max((len(b) for b, _ in partitions), default=0), method)


def residual_blocks(row_blocks, n: int, k: int = 1, width: int = 3) -> list:
    """The residual indices of blocks of rows: each row ``width`` residuals, the ``k`` measured points of a row
    stacked point after point (``n`` rows each), as the measurement model stacks them."""
    return [np.concatenate([width * (f * n + np.asarray(b)) + c for f in range(k) for c in range(width)])
            for b in row_blocks]
