"""The updated model: the nominal one with the fitted calibration and the named effects."""
from __future__ import annotations

from ... import effects as fx
from ..predict import CALIBRATION, apply_calibration
from .problem import Setup
from .select import Selected


def updated_model(s: Setup, chosen: Selected):
    """What model_updated.yaml holds (full parameter vectors: the held ones at their values)."""
    prob, pred, final = s.prob, s.pred, chosen.sel.final
    upd = apply_calibration(s.model, pred.full_theta(CALIBRATION, final.term_theta(prob, CALIBRATION)))
    for nm in chosen.sel.selected:
        upd = fx.get(nm).save(upd, pred.full_theta(nm, final.term_theta(prob, nm)))
    return upd
