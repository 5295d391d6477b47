"""The effect library: candidate physical effects a stiffness model may miss.

An effect is one small class registered with :func:`register`.  It declares a
``name``, a one-line ``description``, its parameters (:class:`Param`, with
the ``null`` value at which the effect is absent) and implements one of two
hooks:

* ``kind = "model"``: ``apply(model, theta) -> model``, a modified (still
  immutable) VJM model.  The prediction is then ``t = C'(p) w`` with the
  modified model's compliance, and the fitted effect is saved as real model
  parameters.
* ``kind = "additive"``: ``extra(ctx, theta, C) -> (n, 6)`` twists added to
  ``C(p) w`` (``ctx`` is the :class:`~vjm.discrepancy.predict.Context` of the
  data set, ``C`` the (n, 6, 6) compliance of each measurement).  The fitted
  effect is saved under the model file's ``effects:`` mapping.

Adding an effect (see docs/discrepancy.md)::

    @register
    class MyEffect(Effect):
        name = "my_effect"
        description = "one line saying what physical thing this is"
        kind = "additive"
        params = (Param("a", start=0.0, scale=1e-3, unit="mm"),)

        def extra(self, ctx, theta, C):
            return theta[0] * some_unit_twist(ctx)   # (n, 6)

It is then a candidate of ``vjm diagnose`` and usable in ``vjm simulate
--effect my_effect:a=0.002``.
"""
from __future__ import annotations

import numpy as np

from . import modelops as mo
from .fit.select import Param

REGISTRY: dict = {}


def register(cls):
    """Class decorator adding an effect to the library (name must be unique)."""
    inst = cls()
    if not inst.name or inst.name in REGISTRY:
        raise ValueError(f"effect name {inst.name!r} is empty or already registered")
    REGISTRY[inst.name] = inst
    return cls


class Effect:
    """Base class.  Subclasses set the class attributes and one hook."""

    name: str = ""
    description: str = ""
    kind: str = "additive"  # "model" or "additive"
    params: tuple = ()
    # which data kinds the effect can explain: "deflection" and/or "stiffness"
    data_kinds: tuple = ("deflection", "stiffness")

    def param_specs(self, model) -> tuple:
        """Parameters, possibly depending on the baseline model (e.g. its current value as null)."""
        return self.params

    def apply(self, model, theta):
        return model

    def extra(self, ctx, theta, C):
        return np.zeros((ctx.n, 6))

    def save(self, model, theta):
        """Model carrying the fitted effect, as written to model_updated.yaml."""
        if self.kind == "model":
            return self.apply(model, theta)
        vals = {p.name: float(v) for p, v in zip(self.param_specs(model), theta)}
        return mo.with_effect_entry(model, self.name, vals)

    def prepare(self, ctx) -> str | None:
        """Precompute what the effect needs on the data set; a reason string if it cannot."""
        return None

    def applies_to(self, model, data_kind: str) -> str | None:
        """None if the effect is a candidate for this model and data, else the reason it is not."""
        if data_kind not in self.data_kinds:
            return f"does not change the compliance matrix, so {data_kind} data cannot show it"
        return None


# ---------------------------------------------------------------- model-kind effects

@register
class LinkCoupling(Effect):
    name = "link_coupling"
    description = ("translation-rotation coupling of the legs that the model lacks: extension-torsion "
                   "c14 = kappa sqrt(c11 c44) (beam models of eq. 14 have none)")
    kind = "model"

    # Why not scale eq. 14's bending coupling c26, c35 (or the lateral-torsion
    # terms c24, c34): in the chains of this package every 6-dof spring is
    # followed, or preceded, by passive joints that release the rotations (and,
    # for a U-U leg, the lateral tip translations) those terms couple, so they
    # cannot change the end-effector deflection (checked: setting them changes
    # the 3-PUU compliance by ~1e-16 relative).  A U-U leg carries only axial
    # force and torsion, so the coupling that shows is extension-torsion.

    def param_specs(self, model):
        k0 = mo.leg_coupling(model)
        return (Param("kappa", start=k0, lower=-0.9, upper=0.9, scale=0.1, null=k0, unit="1"),)

    def applies_to(self, model, data_kind):
        if not mo.leg_is_flexible(model):
            return "the model's leg is rigid"
        return super().applies_to(model, data_kind)

    def apply(self, model, theta):
        return mo.with_leg_coupling(model, float(theta[0]))


@register
class FootCompliance(Effect):
    name = "foot_compliance"
    description = ("a flexible foot where the model has a rigid one: foot compliance = s x the leg's own "
                   "compliance matrix (a beam-like foot)")
    kind = "model"
    params = (Param("scale", start=0.0, lower=0.0, upper=50.0, scale=0.1, null=0.0, unit="x leg compliance"),)

    def applies_to(self, model, data_kind):
        if not mo.foot_is_rigid(model):
            return "the model already has a flexible foot (calibrate it instead)"
        return None

    def apply(self, model, theta):
        return mo.with_foot_compliance_scale(model, float(theta[0]))


@register
class PassiveJointCompliance(Effect):
    name = "passive_joint_compliance"
    description = "elastic passive joints: 1-dof rotational springs in the constrained directions of the U-joints/pivots"
    kind = "model"
    params = (Param("compliance", start=0.0, lower=0.0, upper=1e-3, scale=1e-7, null=0.0, unit="rad/(N mm)"),)

    def applies_to(self, model, data_kind):
        if mo.passive_compliance(model) > 0:
            return "the model already has elastic passive joints (calibrate them instead)"
        return None

    def apply(self, model, theta):
        return mo.with_passive_compliance(model, float(theta[0]))


@register
class ActuatorTravelStiffness(Effect):
    name = "actuator_travel_stiffness"
    description = ("actuator compliance varying linearly along the travel, as a ball screw between bearing and nut: "
                   "c(q) = 1/k + slope (q - q_ref)")
    kind = "model"

    def param_specs(self, model):
        s0 = mo.actuator_slope(model)
        b = mo.actuator_slope_bound(model)
        return (Param("compliance_slope", start=s0, lower=-b, upper=b, scale=b / 100.0, null=s0,
                      unit="(mm/N)/mm"),)

    def apply(self, model, theta):
        return mo.with_actuator_slope(model, float(theta[0]))


# ---------------------------------------------------------------- additive effects

@register
class Gravity(Effect):
    name = "gravity"
    description = "an unknown weight W on the platform: adds C(p) (0, 0, -W, 0, 0, 0) whatever the applied load"
    kind = "additive"
    data_kinds = ("deflection",)
    params = (Param("weight", start=0.0, scale=1.0, null=0.0, unit="N"),)

    def extra(self, ctx, theta, C):
        return -theta[0] * C[:, :, 2]


@register
class Clearance(Effect):
    name = "clearance"
    description = ("backlash in the actuated joints: each actuator slips by b in the direction of its force, "
                   "seen at the end-effector through the unit-load influence of that actuator")
    kind = "additive"
    data_kinds = ("deflection",)
    params = (Param("backlash", start=0.0, lower=0.0, upper=1.0, scale=1e-3, null=0.0, unit="mm"),)

    def extra(self, ctx, theta, C):
        return theta[0] * ctx.clearance_unit()


@register
class GeometricNonlinearity(Effect):
    name = "geometric_nonlinearity"
    description = ("load-dependent stiffness: s x (nonlinear equilibrium deflection - linear C w) of the model "
                   "itself; s = 1 is the model's own geometric nonlinearity, s > 1 a stronger one")
    kind = "additive"
    data_kinds = ("deflection",)
    params = (Param("scale", start=0.0, scale=1.0, null=0.0, unit="x model nonlinearity"),)

    #: screening threshold: skip when the model's own nonlinearity is below this fraction of the noise
    screen = 0.1

    def prepare(self, ctx):
        from ..errors import VjmError

        try:
            # cheap screen first: the nonlinear part grows like the square of the linear
            # deflection, so the rows deflecting most bound it
            from . import modelops

            n = ctx.n
            C = modelops.compliance_map(ctx.model, ctx.P)[ctx.idx]
            lin = np.linalg.norm(np.einsum("nij,nj->ni", C[:, :3], ctx.W), axis=1)
            probe = np.argsort(-lin)[: min(n, 6)]
            d = modelops.nonlinear_delta(ctx.model, ctx.P[ctx.idx[probe]], ctx.W[probe])
            big = float(np.max(np.abs(d[:, :3]))) if n else 0.0
            if ctx.noise_t is not None and big < self.screen * ctx.noise_t:
                return (f"the model's own geometric nonlinearity at these loads is at most {big:.2g} mm, "
                        f"below {self.screen} x the noise ({ctx.noise_t:.2g} mm): it cannot be detected")
            ctx.nonlinear_delta()
        except VjmError as exc:
            return f"the model's nonlinear equilibrium failed: {exc}"
        return None

    def extra(self, ctx, theta, C):
        return theta[0] * ctx.nonlinear_delta()


def get(name: str) -> Effect:
    from ..errors import VjmError

    try:
        return REGISTRY[name]
    except KeyError:
        raise VjmError(f"unknown effect '{name}'; known: {', '.join(REGISTRY)}") from None
