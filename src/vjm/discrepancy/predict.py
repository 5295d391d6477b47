"""Batched predictions of a data set by a model with calibration and effects.

All measurements are predicted at once: the compliance is computed once per
unique posture (``stiffness_map``), gathered per measurement and contracted
with the wrenches by ``einsum``.  Quantities that depend only on the nominal
model (actuator influence for ``clearance``, nonlinear-minus-linear deflection
for ``geometric_nonlinearity``) are computed once, lazily, per data set.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..stats.terms import Param, Problem, Term
from . import effects as fx
from . import modelops as mo
from .data import Deflections, StiffnessObs

CALIBRATION = "calibration"


def unique_postures(P, decimals=6):
    """Unique postures (m, 3) and the index (n,) of each row into them."""
    P = np.asarray(P, float)
    key = np.round(P, decimals)
    _, first, idx = np.unique(key, axis=0, return_index=True, return_inverse=True)
    # the first row of each group, unrounded: U[idx] reproduces P exactly for repeated postures
    return P[first], idx.reshape(-1)


def _slip_toward(A, W) -> np.ndarray:
    """(n, 6) ``sum_s a_s sign(a_s . w)``: every joint of influence ``A`` (n, k, 6) slipping by one unit
    toward the force it carries under ``W`` (n, 6); the work ``w . t`` is >= 0."""
    tau = np.einsum("ncj,nj->nc", A, W)
    # forces below 1e-9 of the largest are "zero": no preferred side, no slip
    s = np.where(np.abs(tau) > 1e-9 * np.abs(tau).max(initial=1e-300), np.sign(tau), 0.0)
    return np.einsum("nc,ncj->nj", s, A)


@dataclass
class Context:
    """Per-data-set precomputations on the nominal model (cached lazily)."""

    model: object
    P: np.ndarray  # (m, 3) unique postures
    idx: np.ndarray  # (n,) measurement -> posture
    W: np.ndarray  # (n, 6) wrenches (zeros for stiffness observations)
    noise_t: float | None = None  # typical translation noise, mm (for screening candidates)
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def n(self) -> int:
        return int(self.idx.size)

    def q(self) -> np.ndarray:
        """(m, n_chains) actuator coordinates of the unique postures (nominal geometry)."""
        if "q" not in self._cache:
            self._cache["q"] = mo.actuator_coords(self.model, self.P)
        return self._cache["q"]

    def clearance_unit(self) -> np.ndarray:
        """(n, 6) twist of a unit backlash in every actuator, each slipping in the direction of its force.

        By the unit-load theorem an imposed slip ``e`` of actuator i moves the
        end-effector by ``a_i e``, where ``a_i`` maps the applied wrench to that
        actuator's force (``tau_i = a_i . w``).  With the slip following the
        force sign, ``t = sum_i a_i sign(a_i . w)``, whose work ``w . t`` is >= 0.
        """
        if "clear" not in self._cache:
            self._cache["clear"] = _slip_toward(mo.actuator_influence(self.model, self.P)[self.idx], self.W)
        return self._cache["clear"]

    def passive_clearance_unit(self, model=None, key=None) -> np.ndarray:
        """(n, 6) twist of a unit slip (1 rad) in every passive-joint spring, each toward its moment.

        As :meth:`clearance_unit`, with the moments ``tau_s = a_s . w`` the passive joints carry
        about their constrained directions (:func:`~vjm.discrepancy.modelops.joint_spring_influence`).
        ``model``: the model being fitted (calibration and model-changing effects applied), whose
        load paths set the moments (a link's coupling changes how the load reaches the joints);
        ``key`` identifies it in the cache.  Default: the nominal model.
        """
        if model is None:
            model, key = self.model, "nominal"
        k = ("pclear", key)
        if k not in self._cache:
            if len(self._cache) > 64:
                self._cache = {n: v for n, v in self._cache.items() if not (isinstance(n, tuple) and n[0] == "pclear")}
            self._cache[k] = _slip_toward(mo.joint_spring_influence(model, self.P)[self.idx], self.W)
        return self._cache[k]

    def nonlinear_delta(self) -> np.ndarray:
        """(n, 6) nonlinear-equilibrium deflection minus the linear ``C w`` of the nominal model."""
        if "nl" not in self._cache:
            self._cache["nl"] = mo.nonlinear_delta(self.model, self.P[self.idx], self.W)
        return self._cache["nl"]


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
    _cache: dict = field(default_factory=dict, repr=False)
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

    def build_model(self, names, theta):
        """Model with the calibration and the model-kind effects of ``names`` applied."""
        model, i = self.model, 0
        blocks = []
        for nm in names:
            k = len(self.terms[nm].params)
            blocks.append((nm, self.full_theta(nm, np.asarray(theta[i:i + k], float))))
            i += k
        for nm, th in blocks:
            if nm == CALIBRATION:
                model = apply_calibration(model, th)
        for nm, th in blocks:
            if nm != CALIBRATION and fx.REGISTRY[nm].kind == "model":
                model = fx.REGISTRY[nm].apply(model, th)
        return model, blocks

    def compliance(self, names, theta):
        """(compliance at the unique postures, blocks, model, key): cached on the model-changing
        parameters only (finite differences on additive parameters then cost no stiffness map)."""
        model, blocks = self.build_model(names, theta)
        key = tuple((nm, th.tobytes()) for nm, th in blocks
                    if nm == CALIBRATION or fx.REGISTRY[nm].kind == "model")
        C = self._cache.get(key)
        if C is None:
            C = mo.compliance_map(model, self.ctx.P)
            if len(self._cache) > 64:
                self._cache.clear()
            self._cache[key] = C
        return C, blocks, model, key

    def twists(self, names, theta) -> np.ndarray:
        """(n, 6) predicted twists of all measurements."""
        Cu, blocks, model, key = self.compliance(names, theta)
        C = Cu[self.ctx.idx]
        t = np.einsum("nij,nj->ni", C, self.ctx.W)
        for nm, th in blocks:
            eff = fx.REGISTRY[nm] if nm != CALIBRATION else None
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
        changes = [(nm, th) for nm, th in blocks if nm != CALIBRATION and fx.REGISTRY[nm].kind == "model"]
        dkey = (eff.name, tuple(nm for nm, _ in changes))
        free = self._calibration_free.get(dkey)
        if free is False or all(nm != CALIBRATION for nm, _ in blocks):
            return model, key
        base = self.model
        for nm, th in changes:
            base = fx.REGISTRY[nm].apply(base, th)
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
        return mo.kvalues_map(model, self.ctx.P)


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
