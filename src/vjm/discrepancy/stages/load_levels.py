"""Load levels: lack of fit across load levels (deflection data applied at a few magnitudes).

Every linear effect of the library, and the model itself, gives a deflection
that scales with the load: at the same posture and direction, twice the load,
twice the deflection.  The final model already holds the effects that do not
scale (a weight, a clearance, the geometric nonlinearity).  What is left is
tested against one alternative: *the compliance differs between load levels*
(a hardening or softening spring, a preloaded clearance, a Hertz contact).
The alternative's columns are, on the rows of each level separately, the
final model's whitened prediction (its compliance scaled per level) and a
compliance at the tool along the force (translation F, a contact or a spring
in series), with the span of the final model's own parameters and of the same
two compliances common to every level projected out (so that only their
*difference* between levels is tested); the drop in chi-square they give is, under the
final model, chi-square with as many degrees of freedom as independent
columns are left (an F ratio against the remaining residual when the sigmas
are estimated).  It shares the lack-of-fit test's level.

Without levels (magnitudes spread continuously, or one magnitude) the check is
not made: a load-dependent stiffness then shows only through the ordinary
lack of fit, and may be calibrated away.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...stats.fit import chi2_p, f_ratio
from .. import observe
from ..data import Deflections
from ..loads import load_levels
from .goodness import Goodness
from .kinds import DeflectionKind
from .problem import Setup
from .select import Selected

#: singular values of the projected level columns below this fraction of the largest are dropped
RANK_TOL = 1e-8


@dataclass(frozen=True)
class LevelTest:
    """The load-level lack-of-fit test of the final model."""

    levels_N: tuple  # the load magnitudes, N
    alpha: float  # its level (the lack-of-fit test's)
    statistic: float | None  # chi2 drop (known sigmas) or F ratio; None when no column is left
    dof: int
    p_value: float | None
    significant: bool
    test: str  # what was tested, "none" when nothing could be

    def record(self) -> dict:
        """report.json's ``lack_of_fit.load_levels``."""
        return {"levels_N": list(self.levels_N), "alpha": self.alpha, "statistic": self.statistic, "dof": self.dof,
                "p_value": self.p_value, "significant": self.significant, "test": self.test}


def _final_jacobian(prob, final) -> np.ndarray:
    """Whitened Jacobian of the final model's residuals w.r.t. its parameters (forward differences)."""
    ps = prob.params(final.names)
    steps = [(1e-3 * p.scale if final.theta[i] + 1e-3 * p.scale <= p.upper else -1e-3 * p.scale)
             for i, p in enumerate(ps)]
    return observe.jacobian(prob.residuals, final.names, final.theta, range(len(ps)), steps)


def level_check(s: Setup, chosen: Selected, fit: Goodness) -> LevelTest | None:
    """The load-level lack-of-fit test of the final model, or None (no levels, or stiffness data)."""
    if not isinstance(s.kind, DeflectionKind) or not isinstance(s.data, Deflections):
        return None
    lv = load_levels(s.data.W)
    if lv is None:
        return None
    prob, final, mask = s.prob, chosen.sel.final, s.data.mask
    sig = s.kind.sigmas(s.weights, 1.0)[mask]
    r = prob.residuals(final.names, final.theta)
    pred = s.pred.twists(final.names, final.theta)[mask] / sig
    lev = np.broadcast_to(lv.index[:, None], mask.shape)[mask]
    # at each level: the final model's compliance x a factor, and a compliance at the tool along the force
    tool = np.where(np.arange(6) < 3, np.pad(s.data.W[:, :3], ((0, 0), (0, 3))), 0.0)[mask] / sig
    X = np.stack([np.where(lev == j, c, 0.0) for j in range(lv.count) for c in (pred, tool)], axis=1)
    # the null: the final model's parameters and the same two compliances at every level
    same = X.reshape(len(r), lv.count, 2).sum(axis=1)
    Q = observe._orth(np.hstack([_final_jacobian(prob, final), same]))
    Xp = X - Q @ (Q.T @ X)
    r = r - Q @ (Q.T @ r)
    U, sv, _ = np.linalg.svd(Xp, full_matrices=False)
    keep = sv > RANK_TOL * max(float(sv[0]) if sv.size else 0.0, 1e-300)
    dof = int(keep.sum())
    alpha = float(fit.lack_of_fit["alpha"])
    mags = tuple(float(m) for m in lv.magnitude)
    if dof == 0:
        return LevelTest(mags, alpha, None, 0, None, False, "none")
    drop = float(np.sum((U[:, keep].T @ r) ** 2))
    if s.weights.sigma_known:
        p = chi2_p(drop, dof)
        test = "chi2 test of a compliance that differs between load levels (known sigmas)"
        stat = drop
    else:
        rest = max(final.dof - dof, 1)
        stat, p = f_ratio(drop, dof, final.chi2 - drop, rest)
        test = "F test of a compliance that differs between load levels (sigma estimated)"
    return LevelTest(mags, alpha, stat, dof, p, bool(p < alpha), test)
