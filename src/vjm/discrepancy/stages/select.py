"""Selection: which candidates to name.

Forward selection (one candidate per round, family-wise level ``alpha``),
then each named effect against its correlated rivals with the others in
place, backward elimination of an effect made redundant later, and the
other explanations within Occam's window: the named effects swapped for
their rivals and the pairs of candidates a linearised screen ranks first
(two effects that partly cancel are each weak alone).  One with a lower BIC
is named.  Clean data (nothing named) are not searched: the selection's
family-wise level stands.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...stats.selection import Selection, backward_eliminate, forward_select, screen_pairs, swap_alternatives
from .. import observe
from .calibrate import Baseline
from .observability import Observability
from .problem import Setup
from .rivals import rival_check
from .thresholds import PAIR_SCREEN


@dataclass(frozen=True)
class Selected:
    sel: Selection  # the named set (the first of ``explanations``)
    rivals: dict  # named effect -> [(rival, chi2 difference, correlation)] (named effects only)
    explanations: list  # Selections within Occam's window, best first

    @property
    def first_round(self) -> dict:
        return self.sel.rounds[0] if self.sel.rounds else {}


def pair_screen(prob, sel: Selection, obs: Observability, baseline: Baseline) -> list:
    """The pairs of candidates worth fitting together: the first PAIR_SCREEN of a linearised screen of
    the calibrated baseline's residuals (candidates that fitted, unclipped, in round 1)."""
    if not sel.selected:
        return []
    first = sel.rounds[0]
    r0 = observe.project_out(prob.residuals(sel.baseline.names, sel.baseline.theta)[:, None], baseline.Q)[:, 0]
    cols = {c: obs.residual_signature(c, baseline) for c in obs.tested
            if c in first and first[c]["converged"] and not first[c]["clipped"]}
    return screen_pairs(r0, cols, PAIR_SCREEN)


def select(s: Setup, baseline: Baseline, obs: Observability, alpha, max_effects, folds, progress=None) -> Selected:
    """Forward selection, rival swaps, backward elimination, pair screen and swaps."""
    prob = s.prob
    sel = forward_select(prob, obs.tested, alpha=alpha, max_effects=max_effects, folds=folds, progress=progress, extra_tests=1)
    sel, rivals = rival_check(prob, sel, obs.tested, obs.sens, baseline.cols, alpha)
    # a named effect that another one (added or swapped in later) made redundant is dropped
    sel = backward_eliminate(prob, sel)
    swaps = {a: [b for b, d, _ in rivals.get(a, []) if np.isfinite(d)] for a in sel.selected}
    explanations = swap_alternatives(prob, sel, swaps, tries=pair_screen(prob, sel, obs, baseline))
    sel = explanations[0]
    return Selected(sel, {a: v for a, v in rivals.items() if a in sel.selected}, explanations)
