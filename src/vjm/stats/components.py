"""Variance components of a residual problem with unknown sigmas (translations and rotations apart).

Helpers of :func:`~vjm.stats.fit.fit_terms`: the component label of each residual
used, and each component's residual sum of squares, count and maximum-likelihood variance.
"""
from __future__ import annotations

import numpy as np


def component_labels(problem, mask):
    """(labels (m,) 0..G-1 of the residuals used, G) when the components' variances are fitted apart, else None."""
    if problem.n_components < 2:
        return None
    c = np.asarray(problem.components)
    c = c if mask is None else c[mask]
    _, lab = np.unique(c, return_inverse=True)
    return lab.reshape(-1), int(lab.max()) + 1


#: reweighting rounds of a fit with several unknown variance components, and the relative change of
#: a component's variance below which they have settled
REWEIGHT_ROUNDS = 6
REWEIGHT_TOL = 1e-3


def group_var(r, lab, G):
    rss = np.bincount(lab, r * r, minlength=G)
    cnt = np.bincount(lab, minlength=G)
    return rss, cnt, np.maximum(rss / np.maximum(cnt, 1), 1e-300)


def group_fields(r, comp) -> dict:
    if comp is None:
        return {}
    rss, cnt, _ = group_var(r, *comp)
    return {"group_rss": tuple(float(v) for v in rss), "group_n": tuple(int(v) for v in cnt)}
