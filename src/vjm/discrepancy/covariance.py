"""What the deflection diagnosis' final fit calibrated, written with the updated model (``calibration:`` in
model_updated.yaml).

``vjm path`` reads it back to put a +- band on the deflection along a toolpath
(:mod:`vjm.toolpath.uncertainty`).  Names are ``term.param`` (``calibration.actuator_scale``,
``gravity.weight``), values and covariance those of the final fit (``s^2 (J^T J)^-1``, the
parameters the data could see); ``terms`` gives every named term's full parameter values.  The block's
reader and writer are :func:`vjm.calibration.result.from_mapping` and :func:`~vjm.calibration.result.to_mapping`.
"""
from __future__ import annotations

import os

import numpy as np

from linkfea.files.atomic import write_text

from .. import effects as fx
from ..calibration.result import Calibration, to_mapping, with_covariance
from .predict import CALIBRATION, calibration_term

#: the ``source:`` line of the block: what fitted it
SOURCE = "vjm diagnose: final fit, covariance s^2 (J^T J)^-1 of the parameters it fitted"


def calibration(prob, pred, final) -> Calibration | None:
    """What the final fit calibrated (names, values, covariance, every named term's full values), or None if
    its covariance is not finite."""
    cov = getattr(final, "cov", None)
    if cov is None or not np.all(np.isfinite(cov)) or final.k == 0:
        return None
    names, terms = [], {}
    for nm in final.names:
        names += [f"{nm}.{p.name}" for p in prob.terms[nm].params]
        specs = calibration_term(pred.model).params if nm == CALIBRATION else \
            fx.get(nm).param_specs(pred.model, pred.ctx)
        full = pred.full_theta(nm, final.term_theta(prob, nm))
        terms[nm] = {p.name: float(v) for p, v in zip(specs, full)}
    return with_covariance(names, final.theta, cov, terms)


def save_model_with(model, cal: Calibration | None, path) -> None:
    """Write ``model`` as the model file does, with the ``calibration:`` block of ``cal`` appended (atomic)."""
    from ..modelio.write import model_file_text, model_to_dict

    path = os.path.abspath(os.fspath(path))
    d = model_to_dict(model, os.path.dirname(path))
    if cal is not None:
        d["calibration"] = to_mapping(cal, SOURCE)
    write_text(path, model_file_text(d))
