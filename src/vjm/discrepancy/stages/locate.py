"""Locate: where the gap is, before naming (calibrated baseline) and after (final model).

Follows the selection: with sigma unknown the residuals are normalized by
the final model's residual scale.  The data kind does the work
(:meth:`~vjm.discrepancy.stages.kinds.DeflectionKind.locate`).
"""
from __future__ import annotations

from .goodness import Goodness
from .kinds import Located
from .problem import Setup
from .select import Selected


def locate(s: Setup, chosen: Selected, fit: Goodness) -> Located:
    """RMS nominal / calibrated / final and the localization of the gap before and after."""
    return s.kind.locate(s.data, s.pred, s.prob, s.weights, fit.scales, chosen.sel.baseline, chosen.sel.final,
                         s.U, s.idx, s.q)
