"""What a calibration fitted: :class:`Calibration`, and the ``calibration:`` block of a model file.

One type for both fits of a machine's parameters:

- the absolute-pose fit (:mod:`vjm.calibration.engine`, robots and parallel machines): the parameters
  of the measurement model (names of :mod:`vjm.calibration.serial` or :mod:`vjm.calibration.parallel`)
  with their standard deviations, and the registration -- the instrument frames of the data's groups and
  the markers' offsets -- with the stages tried and the rows set aside;
- the deflection diagnosis' final fit (:mod:`vjm.discrepancy.covariance`): ``term.param`` names, values,
  the covariance ``s^2 (J^T J)^-1`` and every named term's full parameter values, written into
  model_updated.yaml's ``calibration:`` block (:func:`to_mapping`) and read back by ``vjm path`` for its
  uncertainty band (:func:`from_mapping`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from linkfea.files.atomic import plain

from ..errors import VjmError


@dataclass(frozen=True, eq=False)
class Calibration:
    """The fitted parameters: ``values`` and standard deviations ``std`` ({name: value}, in the fit's order),
    their covariance ``cov`` (k, k) in that order where the fit keeps it (else None), and the effect and unit
    of each parameter whose name does not say them (``kinds`` {name: (effect, unit)}).

    For absolute poses, the ``model`` fitted and the registration: the groups' base instrument frames
    ``frames`` {group: (R0, t0)}, the measured ``frame`` and its marker's base offset ``p0`` (the fitted
    corrections are parameters: ``reg[group].r* / t*``, ``frame.p*``), the parameters ``removed``
    [(name, why)] and the ``stages``.  For the deflection diagnosis, ``terms``: the full parameter values
    of every named term ({term: {param: value}}, the ones held at their start too)."""

    # every field has a default: a fit with no registration (the deflection diagnosis') names only its parameters
    model: Any = None
    frame: str = ""
    values: dict = field(default_factory=dict)
    std: dict = field(default_factory=dict)
    frames: dict = field(default_factory=dict)
    p0: np.ndarray | None = None
    removed: tuple = ()
    stages: tuple = ()
    #: rows of the data set aside as outliers (indices), not fitted (:mod:`vjm.calibration.robust`)
    set_aside: tuple = ()
    #: the other measured frames and their markers' base offsets ((frame, p0), ...): several points per row
    extra: tuple = ()
    #: {parameter: (effect, unit)} where the names do not say them (a parallel machine's, vjm.calibration.parallel)
    kinds: dict = field(default_factory=dict)
    cov: np.ndarray | None = None
    terms: dict = field(default_factory=dict)
    #: how ``std`` was computed, in words ("" : the formal ``s^2 (J^T J)^-1``)
    std_method: str = ""

    @property
    def names(self) -> tuple:
        """The fitted parameters' names, in the order of ``cov``."""
        return tuple(self.values)

    @property
    def measured(self) -> tuple:
        """((frame, base marker offset), ...) of every measured point, the first ``frame``'s."""
        return ((self.frame, self.p0), *self.extra)

    def robot_values(self) -> dict:
        """The robot's fitted parameters (geometry and compliance), without the nuisance."""
        markers = tuple(f"{f}.p{c}" for f, _ in self.measured for c in "xyz")
        return {k: v for k, v in self.values.items() if not k.startswith("reg[") and k not in markers}

    @property
    def marker(self) -> np.ndarray:
        return self.p0 + np.array([self.values.get(f"{self.frame}.p{k}", 0.0) for k in "xyz"])

    @property
    def markers(self) -> dict:
        """{measured frame: its marker's fitted offset (3,) mm}, the first ``frame``'s first."""
        return {f: p + np.array([self.values.get(f"{f}.p{k}", 0.0) for k in "xyz"]) for f, p in self.measured}


def with_covariance(names, values, cov, terms: dict | None = None) -> Calibration:
    """The :class:`Calibration` of a fit that kept its covariance: the standard deviations are its diagonal's
    square roots."""
    cov = np.asarray(cov, dtype=float)
    std = np.sqrt(np.maximum(np.diag(cov), 0.0))
    return Calibration(values={n: float(v) for n, v in zip(names, values)},
                       std={n: float(s) for n, s in zip(names, std)}, cov=cov, terms=dict(terms or {}))


def to_mapping(cal: Calibration, source: str) -> dict:
    """The ``calibration:`` block of a model file: ``source`` (what fitted it), ``parameters`` (names),
    ``values``, ``covariance`` and ``terms``, plain lists and floats (a non-finite one: None)."""
    return plain({"source": source, "parameters": list(cal.names), "values": list(cal.values.values()),
                  "covariance": np.asarray(cal.cov, float), "terms": cal.terms})


def from_mapping(d, source: str = "model file") -> Calibration:
    """A :class:`Calibration` from the ``calibration:`` block of a model file (``source`` names it in errors)."""
    try:
        names = tuple(str(x) for x in d["parameters"])
        values = np.asarray(d["values"], dtype=float)
        cov = np.asarray(d["covariance"], dtype=float)
        terms = {str(k): {str(a): float(b) for a, b in v.items()} for k, v in (d.get("terms") or {}).items()}
    except (KeyError, TypeError, ValueError, AttributeError):
        raise VjmError(f"{source}: calibration must give parameters, values and covariance") from None
    k = len(names)
    if values.shape != (k,) or cov.shape != (k, k) or not np.all(np.isfinite(cov)):
        raise VjmError(f"{source}: calibration.covariance must be a finite {k}x{k} matrix and values {k} numbers")
    if not np.allclose(cov, cov.T, rtol=1e-9, atol=0.0) or np.any(np.linalg.eigvalsh(0.5 * (cov + cov.T)) <
                                                                  -1e-9 * max(np.abs(cov).max(), 1e-300)):
        raise VjmError(f"{source}: calibration.covariance must be symmetric positive semi-definite")
    for nm in names:
        if "." not in nm:
            raise VjmError(f"{source}: calibration parameter {nm!r} must be named term.param")
    if len(set(names)) != k:
        raise VjmError(f"{source}: calibration parameters must be named once each")
    return with_covariance(names, values, cov, terms)
