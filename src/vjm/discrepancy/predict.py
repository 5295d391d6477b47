"""Batched predictions of a data set by a model with calibration and effects.

All measurements are predicted at once: the compliance is computed once per
unique posture (``stiffness_map``), gathered per measurement and contracted
with the wrenches by ``einsum``; each effect adds its part on the data set's
:class:`~vjm.effects.context.Context`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..effects import REGISTRY
from ..effects import modelops as mo
from ..effects.context import Context
from ..memo import Recent
from ..stats.terms import Param, Problem, Term
from .data import Deflections, StiffnessObs

CALIBRATION = "calibration"


def calibration_term(model) -> Term:
    """Baseline calibration: multipliers on the model's own nominal stiffness parameters."""
    ps = [Param("actuator_scale", start=1.0, lower=0.02, upper=50.0, scale=0.1, null=1.0,
                unit="x nominal actuator stiffness")]
    ps.append(Param("link_scale", start=1.0, lower=0.02, upper=50.0, scale=0.1, null=1.0,
                    unit="x nominal link (foot and leg) compliances, torsion excluded"))
    return Term(CALIBRATION, tuple(ps), "refit of the model's nominal actuator stiffness and link compliances")


def apply_calibration(model, theta):
    model = mo.with_actuator_scale(model, float(theta[0]))
    if len(theta) > 1:
        model = mo.with_link_scale(model, float(theta[1]))
    return model


@dataclass
class Predictor:
    """Predicts a data set for any combination of calibration and effects."""

    model: object
    ctx: Context
    terms: dict  # name -> Term (calibration + effects)
    #: name -> (n_full, free indices, full default vector): parameters held fixed because the
    #: data cannot see them (the Term then lists the free ones only)
    fixed: dict = field(default_factory=dict)
    #: the maps (and models) of the last model-changing parameter vectors, the models of the last
    #: calibrations, the postures' kinematics per kinematic key: a fit's finite differences ask again
    _maps: Recent = field(default_factory=lambda: Recent(64), repr=False)
    _calibrated: Recent = field(default_factory=lambda: Recent(8), repr=False)
    _kinematics: Recent = field(default_factory=lambda: Recent(8), repr=False)
    #: (needs_model effect, model-changing effects) -> whether the calibration leaves what it reads
    _calibration_free: dict = field(default_factory=dict, repr=False)

    def full_theta(self, name, th):
        """An effect's full parameter vector from the fitted (free) part."""
        if name not in self.fixed:
            return np.asarray(th, float)
        _, free, full = self.fixed[name]
        out = np.array(full, float)
        out[list(free)] = th
        return out

    def blocks(self, names, theta) -> list:
        """[(name, full parameter vector)] of ``names`` from the fitted vector ``theta``."""
        blocks, i = [], 0
        for nm in names:
            k = len(self.terms[nm].params)
            blocks.append((nm, self.full_theta(nm, np.asarray(theta[i:i + k], float))))
            i += k
        return blocks

    def build_model(self, names, theta):
        """Model with the calibration and the model-kind effects of ``names`` applied."""
        blocks = self.blocks(names, theta)
        return self._build(blocks), blocks

    def _build(self, blocks):
        model = self.model
        for nm, th in blocks:
            if nm == CALIBRATION:
                model = self.calibrated(th)
        for nm, th in blocks:
            if nm != CALIBRATION and REGISTRY[nm].kind == "model":
                model = REGISTRY[nm].apply(model, th)
        return model

    def calibrated(self, th):
        """The model with calibration ``th``, kept for the last few: the finite differences of a fit's
        other parameters all start from the same calibrated model."""
        return self._calibrated.get(th.tobytes(), lambda: apply_calibration(self.model, th))

    def compliance(self, names, theta):
        """(compliance at the unique postures, blocks, model, key): the model and its map cached on the
        model-changing parameters only (finite differences on additive parameters then cost neither)."""
        blocks = self.blocks(names, theta)
        key = tuple((nm, th.tobytes()) for nm, th in blocks
                    if nm == CALIBRATION or REGISTRY[nm].kind == "model")
        def compute():
            model = self._build(blocks)
            return mo.compliance_map(model, self.kinematics(model), repeated=True), model   # a fit's map: compiled

        C, model = self._maps.get(key, compute)
        return C, blocks, model, key

    def twists(self, names, theta) -> np.ndarray:
        """(n, 6) predicted twists of all measurements."""
        Cu, blocks, model, key = self.compliance(names, theta)
        C = Cu[self.ctx.idx]
        t = np.einsum("nij,nj->ni", C, self.ctx.W)
        for nm, th in blocks:
            eff = REGISTRY[nm] if nm != CALIBRATION else None
            if eff is not None and eff.kind == "additive":
                if eff.needs_model:
                    m, k = self.model_for(eff, blocks, model, key, C)
                    t = t + eff.extra(self.ctx, th, C, model=m, key=k)
                else:
                    t = t + eff.extra(self.ctx, th, C)
        return t

    def model_for(self, eff, blocks, model, key, C):
        """(model, key) that a ``needs_model`` effect reads: the model being fitted, or the same
        model without the calibration where the calibration does not change what the effect
        reads there (then one computation serves every calibration the fit tries).

        Decided once per effect and set of model-changing effects, by the effect's unit response
        on that model at the nominal calibration and at two others (actuators x 1.37, links
        x 0.71): equal to 1e-10 of its size (a machine whose load paths are statically
        determinate, as the 3-PUU's, agrees to round-off; the 3-PRPaR's parallelograms differ
        by percents).  The nominal calibration is the one used then, so the numbers do not
        depend on the order in which a fit visits its parameters.
        """
        changes = [(nm, th) for nm, th in blocks if nm != CALIBRATION and REGISTRY[nm].kind == "model"]
        dkey = (eff.name, tuple(nm for nm, _ in changes))
        free = self._calibration_free.get(dkey)
        if free is False or all(nm != CALIBRATION for nm, _ in blocks):
            return model, key
        base = self.model
        for nm, th in changes:
            base = REGISTRY[nm].apply(base, th)
        bkey = ("uncalibrated", *((nm, th.tobytes()) for nm, th in changes))
        if free is None:
            unit = np.ones(len(eff.param_specs(self.model, self.ctx)))
            ref = eff.extra(self.ctx, unit, C, model=base, key=bkey)
            tol = 1e-10 * np.abs(ref).max(initial=0.0)
            free = True
            for probe in ((1.37, 1.0), (1.0, 0.71)):
                m = apply_calibration(base, np.array(probe))
                alt = eff.extra(self.ctx, unit, C, model=m, key=("probe", probe, *bkey[1:]))
                free = free and bool(np.abs(alt - ref).max(initial=0.0) <= tol)
            self._calibration_free[dkey] = free
            if not free:
                return model, key
        return base, bkey

    def kvalues(self, names, theta) -> np.ndarray:
        """(m, 2) k_tran, k_rot of the unique postures."""
        model, _ = self.build_model(names, theta)
        return mo.kvalues_map(model, self.kinematics(model), repeated=True)

    def kinematics(self, model):
        """The kinematics of the unique postures for ``model`` (a parallel machine's, solved once per
        kinematic key: a fit's models differ in their springs, and their maps then skip reading the poses
        again), or the postures themselves for a model of another kind."""
        key = getattr(model, "kinematic_key", None)
        if key is None:
            return self.ctx.P
        return self._kinematics.get(key, lambda: model.kinematics(self.ctx.P))


def deflection_problem(pred: Predictor, data: Deflections, sig, sigma_known, candidates) -> Problem:
    """Whitened residual problem for deflection data (measured components only); ``sig`` (n, 6)
    standard deviations (relative ones when not ``sigma_known``: translations and rotations are then
    two variance components)."""
    mask = data.mask
    y = data.T[mask]
    s = np.asarray(sig, float)[mask]
    groups = np.broadcast_to(pred.ctx.idx[:, None], mask.shape)[mask]
    components = np.broadcast_to((np.arange(6) >= 3).astype(int), mask.shape)[mask]

    def residuals(names, theta):
        return (y - pred.twists(names, theta)[mask]) / s

    return Problem(residuals, pred.terms, groups, sigma_known, (CALIBRATION,), components.copy())


def stiffness_problem(pred: Predictor, data: StiffnessObs, sig_rel, sigma_known) -> Problem:
    """Residuals of stiffness observations in log space: ln(pred/obs)/sigma_rel."""
    pidx = pred.ctx.idx
    q = data.quantity
    ly = np.log(data.value)

    def residuals(names, theta):
        k = pred.kvalues(names, theta)[pidx, q]
        return (np.log(np.maximum(k, 1e-300)) - ly) / sig_rel

    return Problem(residuals, pred.terms, pidx.copy(), sigma_known, (CALIBRATION,))
