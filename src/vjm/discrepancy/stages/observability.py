"""Observability: what this data can see of each candidate.

A candidate with no observable parameter, or whose signature the
calibration imitates entirely, is never fitted; one with some unobservable
parameters is fitted with those held at their start values.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...stats.terms import Term
from .. import observe
from ..predict import CALIBRATION
from .calibrate import Baseline
from .problem import Setup


@dataclass(frozen=True)
class Observability:
    sens: dict  # name -> observe.TermSensitivity (every candidate)
    unobservable: dict  # name -> why it is never fitted
    full_terms: dict  # name -> Term with all its parameters (before any is held)
    tested: list  # candidates that are fitted

    def residual_signature(self, name: str, baseline: Baseline) -> np.ndarray:
        """The candidate's whitened sensitivity columns with the calibration's span projected out."""
        return observe.project_out(self.sens[name].Jfree, baseline.Q)


def observability(s: Setup, baseline: Baseline, progress=None) -> Observability:
    """Sensitivities; unseen candidates set aside, unseen parameters held (in ``s.pred``, ``s.terms``)."""
    sens, unobservable, full_terms = {}, {}, {}
    for nm in s.candidates:
        ts = observe.term_sensitivity(s.prob, baseline.fit.theta, CALIBRATION, nm)
        sens[nm] = ts
        full_terms[nm] = s.terms[nm]
        if not ts.observable:
            unobservable[nm] = (f"not observable on this data: over its whole allowed range it changes the "
                                f"predictions by at most {float(np.max(ts.norms, initial=0.0)):.2g} sigma (root of the "
                                f"chi-square change); never fitted")
            continue
        # what is left of its signature once the calibration has done what it can
        part = observe.project_out(ts.Jfree, baseline.Q)
        left = float(np.max(np.linalg.norm(part, axis=0), initial=0.0))
        if left < observe.NOISE_NORM:
            unobservable[nm] = (f"not separable from the calibration on this data: what the calibration cannot "
                                f"imitate of it stays below {left:.2g} sigma over its whole range; never fitted")
        elif ts.fixed:
            specs = s.terms[nm].params
            s.pred.fixed[nm] = (len(specs), ts.free, [p.start for p in specs])
            s.terms[nm] = Term(nm, tuple(specs[i] for i in ts.free), s.terms[nm].description)
    tested = [c for c in s.candidates if c not in unobservable]
    if progress and unobservable:
        progress("not observable on this data: " + ", ".join(unobservable))
    return Observability(sens, unobservable, full_terms, tested)
