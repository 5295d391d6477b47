"""Noise: the noise the file states, checked against the final model's residuals.

With stated sigmas the residuals of a right model, whitened by them, have
unit variance: per component group (translations, rotations) the sum of
squares ``RSS_g`` of the ``n_g`` residuals is chi-square with about
``n_g - k n_g / n`` degrees of freedom.  A ratio ``s_g^2 = RSS_g / dof_g``
outside that distribution's central ``1 - alpha`` range says the stated sigma
looks ``s_g`` times too small (or too large).

Larger residuals than stated have two causes the ratio alone cannot tell
apart: noise larger than stated, or an effect the model lacks (outside the
library).  The **structure test** tells them apart where the design allows:
at each posture, each component's residuals are regressed on an offset and
the applied wrench (a free local correction: a load-independent term plus a
compliance linear in the load), and on an offset and the wrench of the row
before it at that posture (a memory of the previous load);
F tests of the final model against final model + these local corrections,
``F = ((RSS_g - RSS_local)/p) / (RSS_local/dof_local)``, do not depend on
the noise level.  Noise leaves nothing for the local corrections; a missing
effect that does not depend linearly on the load at a posture (a contact that
stiffens, a backlash, a force that is not the applied one) or that remembers
the previous load (hysteresis, friction) does.

Rule (documented in docs/discrepancy.md): when a group's residuals are
significantly larger than stated, **and** so is their bulk (the robust scale
1.4826 x median |r| beyond its own upper limit: a few gross values inflate the
sum of squares but not the bulk, and are left to the outlier stage),
**and** the structure test can be made
(more loads at a posture than the correction has parameters) **and** finds no
structure, the stated sigma of that group is taken as too small: the
selection is run again with it multiplied by ``max(1, s_g)``, so a
misstated noise level is not named as an effect, and the verdict is
flagged.  Otherwise (structure found, or no test possible) the stated sigma
stands: the lack of fit is reported ``unexplained`` as before.  Sigmas that
look too large are flagged only (the tests are then conservative).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import cast

import numpy as np

from ...stats.fit import FitResult, chi2_range, f_ratio, normal_upper
from ..data import Deflections
from .kinds import DeflectionKind
from .problem import Setup

#: the structure test needs at least this many residual degrees of freedom in a group
MIN_LOCAL_DOF = 10
GROUPS = (("t", "sigma_t", slice(0, 3), 1e3, "um"), ("r", "sigma_r", slice(3, 6), 1e6, "urad"))


@dataclass(frozen=True)
class NoiseCheck:
    """The stated sigmas against the final residuals, per group; ``scale`` the factors the tests used."""

    groups: dict = field(default_factory=dict)  # "t"/"r" -> numbers of the check (report.json "noise")
    scale: tuple = (1.0, 1.0)  # (translations, rotations): multiplies the stated sigmas in the tests
    flags: list = field(default_factory=list)

    @property
    def rescale(self) -> bool:
        return any(f > 1.0 for f in self.scale)

    def record(self) -> dict:
        return {"groups": self.groups, "scale_used": list(self.scale)}


def _data(s: Setup) -> Deflections:
    # the noise check runs on stated sigmas per component, which only deflection data have (check_stated)
    return cast(Deflections, s.data)


def residual_matrix(s: Setup, r: np.ndarray) -> np.ndarray:
    """(n, 6) the whitened residuals ``r`` (measured components, row-major) at their places, NaN elsewhere."""
    mask = _data(s).mask
    E = np.full(mask.shape, np.nan)
    E[mask] = r
    return E


def previous_loads(s: Setup) -> np.ndarray:
    """(n, 6) the wrench of the row before each one in the file when it was at the same posture, else 0."""
    W, idx = _data(s).W, s.idx
    prev = np.zeros_like(W)
    same = idx[1:] == idx[:-1]
    prev[1:][same] = W[:-1][same]
    return prev


def _local_f(s: Setup, E: np.ndarray, cols: slice, X_all: np.ndarray) -> dict:
    """F test of the residuals ``E`` of components ``cols`` against a free correction linear in the
    regressors ``X_all`` (n, k) at each posture (whitened like the residuals)."""
    mask, idx, sig = _data(s).mask, s.idx, s.weights.sig
    rss_all = rss_loc = 0.0
    p = dof = 0
    for u in range(len(s.U)):
        at = idx == u
        for j in range(cols.start, cols.stop):
            rows = at & mask[:, j]
            X = X_all[rows] / sig[rows, j][:, None]  # whitened: a correction c . w in mm is (c . w) / sigma
            e = E[rows, j]
            rank = np.linalg.matrix_rank(X) if X.size else 0
            if e.size <= rank or rank == 0:
                continue
            coef, *_ = np.linalg.lstsq(X, e, rcond=None)
            res = e - X @ coef
            rss_all += float(e @ e)
            rss_loc += float(res @ res)
            p += rank
            dof += e.size - rank
    if dof < MIN_LOCAL_DOF or rss_loc <= 0:
        return {"F": None, "dof": [int(p), int(dof)], "p_value": None}
    F, pv = f_ratio(rss_all - rss_loc, p, rss_loc, dof)
    return {"F": F, "dof": [int(p), int(dof)], "p_value": pv}


def structure_test(s: Setup, E: np.ndarray, cols: slice) -> dict:
    """Whether the residuals ``E`` (n, 6, whitened) of the components ``cols`` depend on the loads at each
    posture: F tests against a free correction, an offset plus a term linear in the applied wrench (a
    load-independent term, or an effect not linear in the load), and against an offset plus a term
    linear in the previous row's wrench at that posture (a memory of the previous load: hysteresis,
    friction); ``p_value`` the smaller one's times 2 (Bonferroni; None when neither test can be made:
    no posture with more loads than such a correction has parameters)."""
    one = np.ones((len(s.idx), 1))  # an offset at each posture (a load-independent term: a weight, a drift)
    tests = {"load": _local_f(s, E, cols, np.hstack([one, _data(s).W])),
             "previous_load": _local_f(s, E, cols, np.hstack([one, previous_loads(s)]))}
    ps = [t["p_value"] for t in tests.values() if t["p_value"] is not None]
    return {**tests, "p_value": None if not ps else float(min(1.0, len(ps) * min(ps)))}


def _group_numbers(s: Setup, E: np.ndarray, k: int, n: int, cols, alpha) -> dict | None:
    mask = _data(s).mask[:, cols]
    e = E[:, cols][mask]
    if e.size == 0:
        return None
    dof = max(e.size - k * e.size / n, 1.0)
    ratio2 = float(e @ e) / dof
    lo, hi = chi2_range(alpha, dof)
    state = "too_small" if ratio2 > hi else "too_large" if ratio2 < lo else "consistent"
    # the same ratio from the bulk of the residuals (1.4826 x their median absolute value) and its upper
    # limit (the MAD scale's standard error is about 1.166 / sqrt(n) relative): a few gross values inflate
    # the RMS ratio but not this one, so they are left to the outlier stage instead of taken as noise
    robust = float(1.4826 * np.median(np.abs(e)))
    robust_hi = 1.0 + normal_upper(alpha / 2) * 1.166 / np.sqrt(e.size)
    return {"ratio": float(np.sqrt(ratio2)), "range": [float(np.sqrt(lo)), float(np.sqrt(hi))], "stated": state,
            "dof": float(dof), "robust_ratio": robust, "robust_hi": float(robust_hi)}


def check_stated(s: Setup, final: FitResult, alpha: float, scale=(1.0, 1.0)) -> NoiseCheck | None:
    """The stated sigmas (``s.weights`` divided by ``scale``) against ``final``'s residuals; None unless
    the sigmas of deflection data are stated.  ``alpha``: level of the range and of the structure test."""
    if not s.weights.sigma_known or s.weights.sig is None:   # sig: the deflections' sigmas per component
        return None
    rerun = any(f != 1.0 for f in scale)
    E = residual_matrix(s, final.residuals)
    f6 = np.where(np.arange(6) < 3, scale[0], scale[1])
    E = E * f6  # in units of the stated sigmas
    groups, flags, new = {}, [], list(scale)
    for i, (key, name, cols, unit, uname) in enumerate(GROUPS):
        g = _group_numbers(s, E, final.k, final.n, cols, alpha)
        if g is None:
            continue
        typical = float(np.median((s.weights.sig / f6)[:, cols][_data(s).mask[:, cols]])) * unit
        g["stated_sigma"] = typical
        g["unit"] = uname
        if g["stated"] == "too_small":
            g["structure"] = st = structure_test(s, E, cols)
            bulk = g["robust_ratio"] > g["robust_hi"]  # the bulk of the residuals is wider, not a few rows
            noise_like = bulk and st["p_value"] is not None and st["p_value"] >= alpha
            g["taken_as_noise"] = bool(noise_like)
            if not bulk:
                flags.append(f"the final model's residuals are {g['ratio']:.2f}x the stated {name} "
                             f"({typical:.3g} {uname}), but their bulk is not ({g['robust_ratio']:.2f}x, robust "
                             "scale): the excess sits in a few rows (gross outliers, or an effect at a few "
                             "postures), not in the noise")
            elif noise_like:
                new[i] = max(scale[i], g["ratio"])
                # the second look (after a rerun at ``scale``) reports the scale the tests did use
                used = scale[i] if rerun else new[i]
                flags.append(f"stated {name} looks {g['ratio']:.1f}x too small: the final model's residuals are "
                             f"{g['ratio']:.2f}x the stated {typical:.3g} {uname} (statistical range "
                             f"{g['range'][0]:.2f}-{g['range'][1]:.2f}x) and do not depend on the loads "
                             f"(p = {st['p_value']:.2g}); the tests used "
                             + (f"{used:.2f}x the stated {name}" if used > 1.0 else f"the stated {name}"))
            else:
                why = ("depends on the load at each posture, or on the load before it (p = "
                       f"{st['p_value']:.2g}): an effect the model lacks rather than noise"
                       if st["p_value"] is not None else
                       "cannot be told from an effect the model lacks (too few loads per posture for the "
                       "structure test)")
                flags.append(f"the final model's residuals are {g['ratio']:.2f}x the stated {name} "
                             f"({typical:.3g} {uname}); the excess {why}")
        elif g["stated"] == "too_large":
            flags.append(f"stated {name} looks {1 / g['ratio']:.1f}x too large: the final model's residuals are "
                         f"{g['ratio']:.2f}x the stated {typical:.3g} {uname} (statistical range "
                         f"{g['range'][0]:.2f}-{g['range'][1]:.2f}x); the tests are conservative")
        groups[key] = g
    return NoiseCheck(groups, tuple(new), flags)


def estimated(s: Setup, scales) -> dict:
    """Unknown sigmas: the fitted noise of each group (``scales``: Goodness.scales), in um / urad."""
    if s.weights.sig is None or s.weights.sigma_known or not isinstance(s.kind, DeflectionKind):
        return {}
    sig = s.kind.sigmas(s.weights, scales)
    out = {}
    for key, _name, cols, unit, uname in GROUPS:
        m = _data(s).mask[:, cols]
        if m.any():
            out[key] = {"estimated_sigma": float(np.median(sig[:, cols][m]) * unit), "unit": uname}
    return {"groups": out}
