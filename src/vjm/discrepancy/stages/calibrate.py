"""The calibrated baseline: the calibration this data can separate, fitted alone (:class:`Baseline`).

A calibration factor whose column is (nearly) a combination of the ones
before it (e.g. link_scale next to actuator_scale on postures near Q0, where
leg and actuator are in series along the same axis) is held at nominal.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...stats.fit import FitResult, fit_terms
from ...stats.terms import Term
from .. import observe
from ..predict import CALIBRATION
from .problem import Setup


@dataclass(frozen=True)
class Baseline:
    """The calibrated baseline (the model's calibration factors fitted, no effect named) and the span of its
    sensitivities: what every candidate is tested against."""

    held: dict  # factor -> value it is held at (not separable on this data)
    fit: FitResult  # the calibration alone, fitted
    cols: np.ndarray  # (n_obs, k) whitened sensitivity columns of the calibration at ``base``
    Q: np.ndarray  # orthonormal basis of their span


def calibrate(s: Setup, progress=None) -> Baseline:
    """Hold the inseparable calibration factors (in ``s.pred`` and ``s.terms``) and fit the rest."""
    cal_specs = s.terms[CALIBRATION].params
    th_cal = np.array([p.start for p in cal_specs])
    cal_free = observe.independent_columns(observe.calibration_columns(s.prob, th_cal, CALIBRATION))
    held = {cal_specs[i].name: float(th_cal[i]) for i in range(len(cal_specs)) if i not in cal_free}
    if held:
        s.pred.fixed[CALIBRATION] = (len(cal_specs), tuple(cal_free), list(th_cal))
        s.terms[CALIBRATION] = Term(CALIBRATION, tuple(cal_specs[i] for i in cal_free), s.terms[CALIBRATION].description)
        if progress:
            progress("calibration held at nominal (not separable on this data): " + ", ".join(held))
    base = fit_terms(s.prob, (CALIBRATION,))
    cols = observe.calibration_columns(s.prob, base.theta, CALIBRATION)
    return Baseline(held, base, cols, observe._orth(cols))
