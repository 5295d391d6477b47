"""The calibration's uncertainty carried to the deflection along a path: a +- band.

``vjm diagnose`` writes, into model_updated.yaml, a ``calibration:`` block with
the fitted parameters (``term.param`` names, values) and their covariance
``s^2 (J^T J)^-1`` at the optimum, read back here as a
:class:`~vjm.calibration.result.Calibration`.  The deflection's sensitivity to each
parameter is taken by central differences on the updated model (a step of a
tenth of the parameter's standard error), and the band is first-order:
``var(d_i) = g_i^T Sigma g_i``.  The band is reported on the deflection's
norm (``g`` = the sensitivity of ``|d|``) and per component; ``z = 1.96``
gives 95 %.

Perturbing the updated model: the calibration's scales and the link-mode
factors multiply what the model already holds (``(v + h) / v``); every other
parameter (weights, backlashes, couplings) is set to ``v + h``.  The link scale
also scales a foot that an effect added after the calibration; the fit applied
it to the nominal links only (a second-order difference when both are named).
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..calibration.result import Calibration, from_mapping
from ..errors import VjmError

Z95 = 1.959963984540054


def read(model) -> Calibration | None:
    """The ``calibration:`` block of the file the model was read from, or None."""
    path = getattr(model, "path", None)
    if not path or not os.path.isfile(path):
        return None
    from ..modelio.yamldata import read_yaml

    d = read_yaml(path)  # the model file, read once already: the same checks (tags, keys given twice)
    if not isinstance(d, dict) or d.get("calibration") is None:
        return None
    return from_mapping(d["calibration"], os.path.basename(path))


def perturbed(model, cal: Calibration, i: int, h: float):
    """The model with parameter ``i`` of ``cal`` moved by ``h``."""
    from .. import effects as fx
    from ..effects import modelops as mo
    from ..effects.library import LinkMode

    term, param = cal.names[i].split(".", 1)
    v = float(cal.values[cal.names[i]])
    if term == "calibration":
        if v <= 0:
            raise VjmError(f"calibration.{param} must be > 0, got {v}")
        f = (v + h) / v
        if param == "actuator_scale":
            return mo.with_actuator_scale(model, f)
        if param == "link_scale":
            return mo.with_link_scale(model, f)
        raise VjmError(f"unknown calibration parameter {param!r}")
    eff = fx.get(term)
    if eff.kind == "additive":
        e = dict(model.effects)
        vals = dict(e.get(term) or cal.terms.get(term, {}))
        vals[param] = v + h
        e[term] = vals
        return model.replace(effects=e)
    specs = eff.param_specs(model)
    full = cal.terms.get(term, {})
    theta = np.array([float(full.get(p.name, v if p.name == param else p.start)) for p in specs])
    j = [p.name for p in specs].index(param)
    if isinstance(eff, LinkMode):  # a factor on what the model holds
        theta = np.ones(len(specs))
        theta[j] = (v + h) / v
    else:
        theta[j] = v + h
    return eff.apply(model, theta)


def sensitivities(model, cal: Calibration, deflection) -> np.ndarray:
    """(n, 6, k) derivatives of ``deflection(model) -> (n, 6)`` with respect to the k parameters."""
    cols = []
    for i, name in enumerate(cal.names):
        se = float(cal.std[name])
        h = 0.1 * se if np.isfinite(se) and se > 0 else 1e-3 * max(abs(float(cal.values[name])), 1e-12)
        up = deflection(perturbed(model, cal, i, h))
        dn = deflection(perturbed(model, cal, i, -h))
        cols.append((up - dn) / (2 * h))
    return np.stack(cols, axis=-1)


@dataclass(frozen=True)
class Band:
    """Half-widths (z sigma) of the deflection's norm (n,) and of its translations (n, 3), mm."""

    norm: np.ndarray
    components: np.ndarray
    z: float


def band(d, G, cov, z: float = Z95) -> Band:
    """The +- band of deflections ``d`` (n, 6) with sensitivities ``G`` (n, 6, k) and covariance ``cov``."""
    Gt = G[:, :3]
    var_c = np.einsum("nik,kl,nil->ni", Gt, cov, Gt)
    nrm = np.linalg.norm(d[:, :3], axis=1, keepdims=True)
    u = np.divide(d[:, :3], nrm, out=np.zeros_like(d[:, :3]), where=nrm > 0)
    gn = np.einsum("ni,nik->nk", u, Gt)
    var_n = np.einsum("nk,kl,nl->n", gn, cov, gn)
    return Band(z * np.sqrt(np.maximum(var_n, 0.0)), z * np.sqrt(np.maximum(var_c, 0.0)), z)
