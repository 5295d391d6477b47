"""The vocabulary of a fitting problem: :class:`Param`, :class:`Term` (a named block of parameters, the
baseline calibration or one effect) and :class:`Problem` (whitened residuals of a set of terms).

Effect authors declare an effect's parameters with :class:`Param`; the engine
(:mod:`vjm.stats.fit`, :mod:`vjm.stats.selection`) fits and selects terms of a :class:`Problem`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np


@dataclass(frozen=True)
class Param:
    """One fitted parameter.

    ``null`` is the value at which the term has no effect (the nested model),
    ``scale`` a typical magnitude (used to scale the optimisation).
    """

    name: str
    start: float
    lower: float = -np.inf
    upper: float = np.inf
    scale: float = 1.0
    null: float = 0.0
    unit: str = ""


@dataclass(frozen=True)
class Term:
    """A named block of parameters: the baseline calibration or one effect."""

    name: str
    params: tuple
    description: str = ""


@dataclass(frozen=True)
class Problem:
    """What the selection engine needs from a data set and a model.

    Attributes
    ----------
    residuals : callable(names, theta) -> (m,) whitened residuals.
    terms : dict name -> Term (baseline terms and candidates).
    groups : (m,) int posture label of each residual (cross-validation unit).
    sigma_known : whether residuals are whitened by known sigmas.
    baseline : names of the always-fitted terms.
    components : (m,) int variance component of each residual (0, 1, ...), or None for one;
        used with unknown sigmas only (each component's variance is then fitted apart).
    """

    residuals: Callable
    terms: dict
    groups: np.ndarray
    sigma_known: bool
    baseline: tuple = ()
    components: np.ndarray | None = None

    @property
    def n_components(self) -> int:
        """Number of variance components fitted apart (1 with known sigmas)."""
        if self.sigma_known or self.components is None:
            return 1
        return int(np.unique(self.components).size)

    @property
    def n(self) -> int:
        return int(len(self.groups))

    def params(self, names):
        return [p for nm in names for p in self.terms[nm].params]
