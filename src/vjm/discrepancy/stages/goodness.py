"""Goodness of fit: how well the final model fits: lack of fit and reduced chi-square, nominal to final."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...stats.fit import lack_of_fit
from .observability import Observability
from .problem import Setup
from .select import Selected


@dataclass(frozen=True)
class Goodness:
    lack_of_fit: dict  # vjm.stats.fit.lack_of_fit + its level ("alpha") and "significant"
    s2: float  # scale of the whitened residuals: 1 with known sigma, else the final residual variance
    chi2_nominal: float  # reduced chi-square of the nominal model
    chi2_before: float  # ... of the calibrated baseline
    chi2_after: float  # ... of the final model
    #: scale of each variance component (translations, rotations) when fitted apart, else (s2,)
    s2_groups: tuple = ()

    @property
    def scales(self):
        """What :meth:`DataKind.sigmas` multiplies the weights by: per component group, or one."""
        return self.s2_groups or self.s2


def pure_error(prob, groups, var=None) -> tuple[float, int] | None:
    """(SS, dof) of repeated measurements (``groups``: same id = same posture, load and component) in the
    problem's whitened units (each variance component divided by its ``var`` when given), or None without
    repeats."""
    r = prob.residuals((), np.zeros(0))  # any fixed prediction: the within-group scatter of r is that of y
    if var is not None:
        _, lab = np.unique(prob.components, return_inverse=True)
        r = r / np.sqrt(np.asarray(var))[lab.reshape(-1)]
    grp = np.asarray(groups).reshape(-1)
    cnt = np.bincount(grp)
    dof = int(np.sum(np.maximum(cnt - 1, 0)))
    if dof == 0:
        return None
    mean = np.bincount(grp, r) / np.maximum(cnt, 1)
    ss = float(np.sum((r - mean[grp]) ** 2))
    return ss, dof


def goodness(s: Setup, obs: Observability, chosen: Selected, alpha) -> Goodness:
    """The lack-of-fit test shares ``alpha`` with the selection rounds (Bonferroni)."""
    prob, sigma_known = s.prob, s.weights.sigma_known
    base, final = chosen.sel.baseline, chosen.sel.final
    var = final.group_var or None
    lof = lack_of_fit(final, pure_error(prob, s.kind.repeat_groups(s.data), var) if not sigma_known else None)
    lof["alpha"] = alpha / (len(obs.tested) + 1)
    lof["significant"] = bool(lof["p_value"] is not None and lof["p_value"] < lof["alpha"])
    s2 = 1.0 if sigma_known else final.chi2 / max(final.dof, 1)
    # each component's variance, corrected for the parameters fitted (their share of them)
    s2g = tuple(v * final.n / max(final.dof, 1) for v in final.group_var)
    r_nom = prob.residuals((), np.zeros(0))
    return Goodness(lof, s2, float(r_nom @ r_nom / s2 / r_nom.size), float(base.chi2 / s2 / max(base.dof, 1)),
                    float(final.chi2 / s2 / max(final.dof, 1)), s2g)
