"""What an effect is: the :class:`Effect` base class, the registry, and the checks of an effect's values.

An effect is one small class registered with :func:`register`.  It declares a ``name``, a one-line
``description``, its parameters (:class:`Param`, with the ``null`` value at which the effect is absent)
and implements one of two hooks:

* ``kind = "model"``: ``apply(model, theta) -> model``, a modified (still immutable) VJM model.  The
  prediction is then ``t = C'(p) w`` with the modified model's compliance, and the fitted effect is saved
  as real model parameters; ``vjm path`` reads them from the model file like any other.
* ``kind = "additive"``: ``extra(ctx, theta, C) -> (n, 6)`` twists added to ``C(p) w`` (``ctx`` is the
  :class:`~vjm.effects.context.Context` of the data set, ``C`` the (n, 6, 6) compliance of each
  measurement).  The fitted effect is saved under the model file's ``effects:`` mapping, and ``vjm path``
  applies it in its nonlinear equilibrium through :meth:`Effect.load` and :meth:`Effect.nonlinear`;
  their defaults add ``extra`` to the equilibrium's twist, so an effect that writes only ``extra`` works
  in ``vjm path`` as ``vjm diagnose`` fitted it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import VjmError
from ..stats.terms import Param as Param  # an effect's parameter (re-exported by vjm.effects)
from . import modelops as mo

REGISTRY: dict = {}


def register(cls):
    """Class decorator adding an effect to the library (name must be unique)."""
    inst = cls()
    if not inst.name or inst.name in REGISTRY:
        raise ValueError(f"effect name {inst.name!r} is empty or already registered")
    REGISTRY[inst.name] = inst
    return cls


@dataclass(frozen=True)
class Nonlinear:
    """How an additive effect enters the nonlinear equilibrium of ``vjm path`` (:meth:`Effect.nonlinear`).

    ``offsets``: rest values imposed on springs of the model, ``{spring name: (n, k, 1)}`` (an actuator's
    slip); ``scale``: the equilibrium's twist becomes ``C w + scale (twist - C w)``; ``twist``: (n, 6)
    added to the twist afterwards (linear, as ``vjm diagnose`` fits it).  None: nothing of that kind.
    """

    offsets: dict | None = None
    scale: float | None = None
    twist: np.ndarray | None = None


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
        and on the data set (``ctx``, a :class:`~vjm.effects.context.Context`, e.g. the
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

    # ------------------------------------------------ an additive effect in vjm path's nonlinear equilibrium

    def theta(self, model, values: dict) -> np.ndarray:
        """The parameter vector of a model file's ``effects:`` entry ``values`` (optional ones left out at
        their null); a VjmError naming the entry if a value is not a number."""
        out = []
        for p in self.param_specs(model):
            if p.name not in values and p.name in self.optional:
                out.append(float(p.null))
                continue
            try:
                out.append(float(values[p.name]))
            except (KeyError, TypeError, ValueError):
                raise VjmError(f"effects.{self.name} must give a number {p.name}, got {values!r}") from None
        return np.array(out)

    def load(self, model, values: dict, P, W) -> np.ndarray:
        """The platform wrenches (n, 6) ``W`` at poses ``P`` with what the effect adds to the load
        (a weight); default: ``W`` itself."""
        return W

    def nonlinear(self, model, values: dict, ctx) -> Nonlinear:
        """How the effect enters the nonlinear equilibrium at the poses and total loads of ``ctx`` (a
        :class:`~vjm.effects.context.Context` of the path's points).  Default: the ``extra`` twist
        ``vjm diagnose`` fits, added to the equilibrium's (nothing at the null)."""
        theta = self.theta(model, values)
        if all(float(t) == float(p.null) for t, p in zip(theta, self.param_specs(model))):
            return Nonlinear()
        C = ctx.compliance()[ctx.idx]
        if self.needs_model:
            return Nonlinear(twist=self.extra(ctx, theta, C, model=None, key=None))  # type: ignore[call-arg]
        return Nonlinear(twist=self.extra(ctx, theta, C))


def get(name: str, where: str = "effect") -> Effect:
    """The registered effect ``name``; a VjmError naming the closest known name otherwise."""
    from linkfea.runtime.checks import did_you_mean

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
    from linkfea.runtime.checks import ArgumentError, Bounds, did_you_mean, number

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
