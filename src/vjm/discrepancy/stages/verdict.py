"""Verdict: the verdict and the warnings that go with it."""
from __future__ import annotations

from dataclasses import dataclass

from ...stats.fit import Z95, clipped
from .. import observe
from ..plausible import workspace_flags
from ..predict import CALIBRATION
from .calibrate import Baseline
from .goodness import Goodness
from .load_levels import LevelTest
from .problem import Setup
from .select import Selected
from .thresholds import COLLINEAR, PLAUSIBLE


@dataclass(frozen=True)
class Verdict:
    verdict: str  # "no_discrepancy", "explained", "unexplained" or "insufficient_data" (stages.outliers: "untrusted_data")
    flags: list  # warnings, one sentence each


def fit_flags(prob, sel, final) -> list:
    """Warnings: calibration at a bound or far from nominal, fits that did not converge or were clipped."""
    flags = []
    vals = final.values(prob)[CALIBRATION]
    at = set(clipped(prob, final, CALIBRATION))
    for k, v in vals.items():
        if k in at:
            flags.append(f"calibration {k} = {v['value']:.3g} is at a bound of its range: the calibration is "
                         "absorbing something it should not (a missing effect or a wrong model)")
        elif not (PLAUSIBLE[0] <= v["value"] <= PLAUSIBLE[1]):
            flags.append(f"calibration {k} = {v['value']:.3g} +- {Z95 * v['se']:.2g} is implausibly far from nominal "
                         f"(outside {PLAUSIBLE[0]}-{PLAUSIBLE[1]}x): check the model or a missing effect it absorbs")
    for r, info in enumerate(sel.rounds):
        for nm, d in info.items():
            if not d["converged"]:
                flags.append(f"round {r + 1}: the fit of {nm} did not converge ({d['fit'].message}); not named")
            elif d["clipped"] and d["p_value"] < d["threshold"]:
                flags.append(f"round {r + 1}: {nm} ended with {', '.join(d['clipped'])} on a bound of its range; "
                             "not named (the effect's shape or range does not fit the data)")
    return flags


def calibration_flags(prob, baseline: Baseline) -> list:
    """Warnings: calibration factors held at nominal, and pairs of factors the data cannot tell apart."""
    free = [p.name for p in prob.terms[CALIBRATION].params]
    flags = [f"calibration {k} held at {v:g}: on this data it cannot be told apart from {', '.join(free)}"
             for k, v in baseline.held.items()]
    for i in range(len(free)):
        for j in range(i + 1, len(free)):
            c = observe.canonical_correlation(baseline.cols[:, [i]], baseline.cols[:, [j]])
            if c >= COLLINEAR:
                flags.append(f"calibration {free[i]} and {free[j]} cannot be told apart on this data "
                             f"(correlation {c:.3f}): their values are not to be trusted separately")
    return flags


def level_flags(levels: LevelTest | None) -> list:
    """Warning: the compliance the data show differs between load levels (:mod:`.load_levels`)."""
    if levels is None or not levels.significant:
        return []
    mags = ", ".join(f"{m:.4g}" for m in levels.levels_N)
    return [f"the deflection does not scale with the load between the load levels ({mags} N): a compliance "
            f"that differs between levels (p = {levels.p_value:.2g}, level {levels.alpha:.2g}) is a "
            "load-dependent stiffness (hardening or softening spring, preloaded clearance, contact), which no "
            "effect of the library is"]


def verdict(s: Setup, baseline: Baseline, chosen: Selected, fit: Goodness, levels: LevelTest | None = None,
            weak: list | None = None) -> Verdict:
    """"unexplained" when the final model still lacks fit (overall, or across load levels),
    else "insufficient_data" if something is named on a design too weak to name it (``weak``: the
    reasons, :func:`.strength.weak_design`), else "explained" if something is named."""
    sel = chosen.sel
    flags = fit_flags(s.prob, sel, sel.final) + workspace_flags(s.model, s.data) + calibration_flags(s.prob, baseline)
    flags += level_flags(levels)
    if fit.lack_of_fit["significant"] or (levels is not None and levels.significant):
        v = "unexplained"
    elif sel.selected and weak:
        v = "insufficient_data"
        flags += [f"insufficient data to name {', '.join(sel.selected)}: {w}" for w in weak]
    elif sel.selected:
        v = "explained"
    else:
        v = "no_discrepancy"
    return Verdict(v, flags)
