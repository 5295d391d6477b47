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

from ..stats.terms import Param
from . import modelops as mo

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
    #: an additive effect whose ``extra`` also takes ``model=, key=``: the model being fitted
    #: (calibration and model-changing effects applied) and a key identifying it for caching
    needs_model: bool = False
    #: parameters a model file's ``effects:`` entry may leave out (then at their null)
    optional: tuple = ()

    def param_specs(self, model, ctx=None) -> tuple:
        """Parameters, possibly depending on the baseline model (e.g. its current value as null)
        and on the data set (``ctx``, a :class:`~vjm.discrepancy.predict.Context`, e.g. the
        actuator travel it covers); ``ctx`` None when no data is at hand (``vjm simulate``)."""
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
#
# Link effects are per link (foot, leg -- "bar" for parallelogram legs) and per
# deformation mode of the link's 6-dof spring (frame x along the link): axial,
# bending about y, bending about z, torsion, and the two translation-rotation
# couplings a beam has (bending: c26, c35 of eq. 14; extension-torsion: c14).
# Whether a mode can show at the end-effector is not argued here (the passive
# joints release some of them at some postures): diagnose decides it from the
# data's sensitivity (see vjm.discrepancy.observe) and never fits what the data
# cannot see.

_LINKS = (("foot", "foot"), ("leg", "leg"), ("leg", "bar"))


def _link_applies(model, key, label):
    if mo.link_label(model, key) != label:
        return f"the model has no {label} (its {key} is a {mo.link_label(model, key)})"
    if getattr(model, key).compliance is None:
        return f"the model's {label} is rigid" + (" (see foot_compliance)" if key == "foot" else "")
    return None


class LinkMode(Effect):
    """A link's compliance in one deformation mode is ``factor`` x the model's."""

    kind = "model"
    key = "leg"
    label = "leg"
    mode = "axial"
    params = (Param("factor", start=1.0, lower=0.05, upper=20.0, scale=0.1, null=1.0, unit="x model compliance"),)

    def applies_to(self, model, data_kind):
        return _link_applies(model, self.key, self.label) or super().applies_to(model, data_kind)

    def apply(self, model, theta):
        return mo.with_mode_factor(model, self.key, self.mode, float(theta[0]))


class LinkBendingCoupling(Effect):
    """A link's bending translation-rotation coupling (c26, c35) as a fraction of a beam's."""

    kind = "model"
    key = "leg"
    label = "leg"

    def param_specs(self, model, ctx=None):
        k0 = mo.bending_coupling(model, self.key)
        # the whole positive-definite range: a tighter bound clips estimates a link can have
        lo, hi = mo.bending_coupling_limits(model, self.key)
        return (Param("kappa", start=k0, lower=min(lo, k0), upper=max(hi, k0), scale=0.1, null=k0,
                      unit="x beam-consistent coupling (eq. 14 = 1)"),)

    def applies_to(self, model, data_kind):
        return _link_applies(model, self.key, self.label) or super().applies_to(model, data_kind)

    def apply(self, model, theta):
        return mo.with_bending_coupling(model, self.key, float(theta[0]))


class LinkExtensionTorsion(Effect):
    """A link's extension-torsion coupling c14 = kappa sqrt(c11 c44)."""

    kind = "model"
    key = "leg"
    label = "leg"

    def param_specs(self, model, ctx=None):
        k0 = mo.extension_torsion(model, self.key)
        lo, hi = mo.extension_torsion_limits(model, self.key)
        return (Param("kappa", start=k0, lower=min(lo, k0), upper=max(hi, k0), scale=0.1, null=k0, unit="1"),)

    def applies_to(self, model, data_kind):
        return _link_applies(model, self.key, self.label) or super().applies_to(model, data_kind)

    def apply(self, model, theta):
        return mo.with_extension_torsion(model, self.key, float(theta[0]))


_MODE_WORDS = {"axial": "axial (extension) compliance", "bending_y": "bending compliance about its y axis",
               "bending_z": "bending compliance about its z axis", "torsion": "torsion compliance"}

for _key, _label in _LINKS:
    for _mode, _words in _MODE_WORDS.items():
        register(type(f"{_label}_{_mode}", (LinkMode,), {
            "name": f"{_label}_{_mode}", "key": _key, "label": _label, "mode": _mode,
            "description": f"the {_label}'s {_words} differs from the model's: factor x the model's "
                           f"(a section stiffness / factor)"}))
    register(type(f"{_label}_bending_coupling", (LinkBendingCoupling,), {
        "name": f"{_label}_bending_coupling", "key": _key, "label": _label,
        "description": f"the {_label}'s bending translation-rotation coupling (c26, c35) differs from the model's: "
                       "kappa x a cantilever's (eq. 14: c26 = L^2/2EIz)"}))
    register(type(f"{_label}_extension_torsion", (LinkExtensionTorsion,), {
        "name": f"{_label}_extension_torsion", "key": _key, "label": _label,
        "description": f"extension-torsion coupling of the {_label} that the model lacks: c14 = kappa sqrt(c11 c44) "
                       "(pretwisted or unsymmetric links; straight beams have none)"}))


@register
class FootCompliance(Effect):
    name = "foot_compliance"
    description = ("a flexible foot where the model has a rigid one: a cantilever of unknown section and length "
                   "(tip compliances axial, bending_y, bending_z, torsion; eq. 14 couplings from the length)")
    kind = "model"

    def param_specs(self, model, ctx=None):
        ct = 1.0 / model.actuator.stiffness  # mm/N: the actuator's compliance sets the scale
        lr = float(model.geometry.get("r", 50.0))
        return (Param("axial", start=0.0, lower=0.0, upper=10 * ct, scale=0.1 * ct, null=0.0, unit="mm/N"),
                Param("bending_y", start=0.0, lower=0.0, upper=10 * ct, scale=0.1 * ct, null=0.0, unit="mm/N"),
                Param("bending_z", start=0.0, lower=0.0, upper=10 * ct, scale=0.1 * ct, null=0.0, unit="mm/N"),
                Param("torsion", start=0.0, lower=0.0, upper=10 * ct / lr**2, scale=0.1 * ct / lr**2, null=0.0,
                      unit="rad/(N mm)"),
                Param("length", start=lr, lower=0.1 * lr, upper=10 * lr, scale=0.2 * lr, null=lr, unit="mm"))

    def applies_to(self, model, data_kind):
        if not mo.foot_is_rigid(model):
            return "the model already has a flexible foot (see foot_axial, foot_bending_y, ...)"
        return None

    def apply(self, model, theta):
        return mo.with_foot_cantilever(model, *(float(t) for t in theta))


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
                   "c(q) = c0 (1 + slope (q - q_ref)); the constant c0 is the calibration's actuator_scale")
    kind = "model"

    def param_specs(self, model, ctx=None):
        s0 = mo.actuator_relative_slope(model)
        if ctx is not None:
            lo, hi = mo.relative_slope_bounds(model, ctx.q())
        else:
            L = float(model.geometry.get("L", 100.0))
            lo, hi = -0.9 / L, 0.9 / L
        lo, hi = min(lo, s0), max(hi, s0)
        return (Param("slope", start=s0, lower=lo, upper=hi, scale=0.05 * (hi - lo), null=s0, unit="1/mm"),)

    def apply(self, model, theta):
        return mo.with_actuator_relative_slope(model, float(theta[0]))


# ---------------------------------------------------------------- additive effects

@register
class Gravity(Effect):
    """A weight on the platform.  On a 6-dof platform its centre of mass may lie off the end-effector
    point: ``first_moment`` = weight x lever arm (N mm, platform axes), which the platform carries
    round as it tilts, so the moment of the weight about the end-effector point, ``(R m) x g``,
    changes with the orientation R.  Linear in its parameters (a weight and a first moment, not a
    weight times a lever arm), so the lever arm ``m / W`` is unknown, never an unfittable nuisance,
    when the weight is small.  A lever arm along g at zero orientation (a centre of mass above the
    end-effector point) shows only at tilt."""

    name = "gravity"
    description = ("an unknown weight W >= 0 on the platform along the known gravity direction g "
                   "(geometry.gravity, default -z): adds C(p) (W g, 0, 0, 0) whatever the applied load; "
                   "on a 6-dof platform with its centre of mass off the end-effector point also the moment "
                   "(R m) x g of the first moment m = W x lever arm (platform axes) at orientation R")
    kind = "additive"
    data_kinds = ("deflection",)
    # an upward force is not a weight: W >= 0 (a negative fit is another, unexplained, effect)
    params = (Param("weight", start=0.0, lower=0.0, upper=1e5, scale=1.0, null=0.0, unit="N"),)
    #: the first moment of a 6-dof platform's weight about the end-effector point (platform axes); its scale
    #: (100 N at 100 mm) sets the range the observability test sweeps (100 x: 1 kN at 1 m)
    moments = tuple(Param(f"first_moment_{a}", start=0.0, lower=-1e8, upper=1e8, scale=1e4, null=0.0,
                          unit="N mm (weight x lever arm, platform axes)") for a in "xyz")

    #: a model file's ``gravity:`` entry may leave the first moment out (a weight at the point)
    optional = tuple(p.name for p in moments)

    def param_specs(self, model, ctx=None):
        """The weight; and the first moment on a 6-dof platform (and with no model at hand: a model
        file's ``effects:`` entry, checked before its machine is known)."""
        return self.params + (self.moments if model is None or model.dof == 6 else ())

    def extra(self, ctx, theta, C):
        g = mo.gravity_direction(ctx.model)
        t = theta[0] * np.einsum("nij,j->ni", C[:, :, :3], g)
        if len(theta) > 1 and np.any(theta[1:4]):
            Rm = np.einsum("nij,j->ni", mo.platform_rotations(ctx.P), np.asarray(theta[1:4], float))[ctx.idx]
            t = t + np.einsum("nij,nj->ni", C[:, :, 3:], np.cross(Rm, g))
        return t


@register
class Clearance(Effect):
    name = "clearance"
    description = ("backlash in the actuated joints: each actuator slips by b in the direction of its force, "
                   "seen at the end-effector through the unit-load influence of that actuator")
    kind = "additive"
    data_kinds = ("deflection",)
    params = (Param("backlash", start=0.0, lower=0.0, upper=1.0, scale=1e-3, null=0.0, unit="mm"),)

    def param_specs(self, model, ctx=None):
        # a rotary actuator (the Delta's arms) slips by an angle
        if model is not None and mo.actuator_is_rotary(model):
            return (Param("backlash", start=0.0, lower=0.0, upper=1.0, scale=1e-3, null=0.0, unit="rad"),)
        return self.params

    def extra(self, ctx, theta, C):
        return theta[0] * ctx.clearance_unit()


@register
class PassiveClearance(Effect):
    name = "passive_clearance"
    description = ("clearance in the passive joints: each U-joint cross or pivot tilts by b about its constrained "
                   "direction(s), toward the moment it carries there, seen at the end-effector through the "
                   "unit-load influence of that joint")
    kind = "additive"
    data_kinds = ("deflection",)
    params = (Param("backlash", start=0.0, lower=0.0, upper=0.05, scale=1e-5, null=0.0, unit="rad"),)

    def applies_to(self, model, data_kind):
        if not mo.joint_spring_names(model):
            return "the model's passive joints have no constrained directions to slip in"
        return super().applies_to(model, data_kind)

    #: the slips follow the moments of the model being fitted (its load paths), not the nominal one's
    needs_model = True

    def extra(self, ctx, theta, C, model=None, key=None):
        return theta[0] * ctx.passive_clearance_unit(model, key)


@register
class GeometricNonlinearity(Effect):
    name = "geometric_nonlinearity"
    description = ("load-dependent stiffness: s x (nonlinear equilibrium deflection - linear C w) of the model "
                   "itself; s = 1 is the model's own geometric nonlinearity, s > 1 a stronger one")
    kind = "additive"
    data_kinds = ("deflection",)
    # s >= 0: the nonlinear part's direction is the model's own (finite rotations of its legs under the
    # load); a stronger or weaker nonlinearity scales it, a negative s would reverse the geometry's own
    # stiffening / softening, which no machine does (a negative fit is another, unexplained, effect)
    params = (Param("scale", start=0.0, lower=0.0, scale=1.0, null=0.0, unit="x model nonlinearity"),)

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


def get(name: str, where: str = "effect") -> Effect:
    """The registered effect ``name``; a VjmError naming the closest known name otherwise."""
    from linkfea.checks import did_you_mean

    from ..errors import VjmError

    try:
        return REGISTRY[name]
    except (KeyError, TypeError):
        raise VjmError(f"{where}: unknown effect {name!r}{did_you_mean(str(name), REGISTRY)}; "
                       f"known: {', '.join(REGISTRY)}") from None


def check_values(name: str, values, model, where: str, fit_range: bool = True) -> dict:
    """``{param: value}`` of effect ``name``, checked against its parameters: known names, finite
    numbers within each parameter's range.  VjmError naming ``where`` (and the parameter) otherwise.

    ``fit_range=False`` (a simulated truth, which may lie beyond what a fit explores, to test
    clipping) keeps only the sign of a parameter whose range is non-negative (a weight, a gap)."""
    from linkfea.checks import ArgumentError, Bounds, did_you_mean, number

    from ..errors import VjmError

    eff = get(name, where)
    if not isinstance(values, dict):
        raise VjmError(f"{where}: expected a mapping parameter -> value, got {values!r}")
    specs = {p.name: p for p in eff.param_specs(model)}
    out = {}
    for k, v in values.items():
        if k not in specs:
            raise VjmError(f"{where}: unknown parameter {k!r} of {name}{did_you_mean(str(k), specs)}; "
                           f"known: {', '.join(specs)}")
        p = specs[k]
        if fit_range:
            rng = Bounds(float(p.lower) if np.isfinite(p.lower) else None,
                         float(p.upper) if np.isfinite(p.upper) else None, unit=p.unit)
        else:
            rng = Bounds(0.0 if p.lower >= 0 else None, None, unit=p.unit)
        try:
            out[k] = number(v, f"{where}.{k}", rng)
        except ArgumentError as exc:
            raise VjmError(str(exc)) from None
    return out
