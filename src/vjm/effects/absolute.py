"""The effects of absolute-pose calibration: a robot's geometry and elastic effects, a parallel machine's
offsets and attachments, each one :class:`PoseEffect` registered with :func:`register_pose`.

An absolute-pose effect is an :class:`~vjm.effects.base.Effect` whose parameters are fitted with the
instrument frames by the calibration engine (:mod:`vjm.calibration.engine`) instead of added to a
compliance.  Each class declares, once:

- its ``name`` (a stage of the fit, tried in the order of registration), and ``default``: one of the core
  effects (:func:`defaults`); with none asked the diagnosis tries every effect that applies
  (:func:`applicable`, :meth:`PoseEffect.usable`);
- ``model_kinds`` ("serial": a serial or tree robot; "parallel": a parallel machine) and ``data_kinds``
  (the data kinds of :mod:`vjm.discrepancy.stages.kinds` that show it);
- its parameters: ``over`` (what they repeat over: ``"joint"`` every joint on the measured frame's path,
  ``"free"`` those that are not mimics, ``"pair"`` ordered pairs of free joints, ``"beam"`` the links
  bending as beams, ``"actuator"``, ``"chain"``, ``"once"``) and ``patterns``, one :class:`Pattern` per
  parameter of each item: how the name is formed (``"{joint}.compliance"``), its unit, its step kind for the
  Jacobian's differences and its physical domain (``lower``, ``upper``, ``upper_from`` a limit the model
  file may state, ``open`` the lower bound excluded): it bounds the total, the model's nominal value plus
  the fitted correction (:func:`domain`), and the fit keeps to it;
- ``rank``: where its parameters stand in the parameter vector; ``on_demand`` False: they are always
  listed there (their columns are computed anyway), True: only when the effect is tried;
- the hooks of the engine: ``options`` (what the measurement problem must hold: ``"payload"`` the gravity
  torques of a unit mass at the marker, ``"tilt"`` the torques of a gravity along each base axis,
  ``"flex"`` the loads of :mod:`vjm.calibration.flex`, ``"thermal"`` the rows' temperature), ``screen``
  (which rows' spread decides that a parameter is not observable: ``"torque"``, ``"lateral"``,
  ``"temperature"``, ``"sign"``, or None), ``carries`` (the effects acting through its parameters, dropped
  with it), ``single_marker`` (weighed at one measured point);
- ``hand_written``: the serial measurement model (:mod:`vjm.calibration.serial`) computes its predictions
  and Jacobian columns itself.  An effect without (a new one) gives ``joint_motion(model, q, values)``, the
  joints' extra motion (n, nq) it causes; its Jacobian columns are central differences of the prediction;
- ``vjm simulate`` on a robot: ``NAME:param=value,...``; the parameters it takes are :meth:`hidden_params`
  (default: the effect's own parameters, when it has a ``joint_motion``), applied by
  :meth:`true_model` and :meth:`true_joints`.
"""
from __future__ import annotations

import dataclasses
import functools
import re
from dataclasses import dataclass, field

import numpy as np

from ..errors import VjmError
from .base import Effect, Param

#: the registered absolute-pose effects {name: instance}, in the order the stages are tried
POSES: dict = {}
#: the geometry's parameters of a joint, in the order of the serial model's origin error (offset, then a twist)
GEOMETRY = ("offset", "dx", "dy", "dz", "ex", "ey", "ez")
#: the nuisance's ranks (registration, then the markers), before every effect's
NUISANCE_RANK = {"reg": -2, "marker": -1}
INF = float("inf")


@dataclass(frozen=True)
class Pattern:
    """One parameter per item an effect repeats over: ``name`` formed with the item's fields (``{joint}``,
    ``{other}``, ``{link}``, ``{actuator}``, ``{chain}``), its ``unit`` (``"site"``: the item's own, an
    actuator's mm or rad), the ``step`` kind of its Jacobian's differences (:data:`vjm.calibration.serial._STEP`
    or a load-driven kind) and its physical domain: ``lower`` and ``upper``, ``upper_from`` the attribute of the
    model stating a tighter upper bound (``payload_limit``: the rated load, when the file states one), ``open``
    the lower bound excluded (a scale > 0: a value on it is out of the domain)."""

    name: str
    unit: str
    step: str
    lower: float = -INF
    upper: float = INF
    upper_from: str | None = None
    open: bool = False

    def bounds(self, model=None) -> tuple[float, float]:
        """(lower, upper) of the total on ``model`` (its ``upper_from`` limit, if it states one)."""
        cap = getattr(model, self.upper_from, None) if self.upper_from else None
        return self.lower, self.upper if cap is None else min(self.upper, float(cap))


@dataclass(frozen=True)
class Site:
    """What the parameters of a measurement model are formed over: ``items`` {over: ({field: value}, ...)}
    and, for a pattern whose unit is ``"site"``, the unit of each item ``units`` {value: unit}."""

    kind: str
    items: dict
    units: dict = field(default_factory=dict)


class PoseEffect(Effect):
    """Base class of the absolute-pose effects (the module docstring)."""

    kind = "pose"
    model_kinds: tuple = ("serial",)
    data_kinds: tuple = ("absolute",)
    default: bool = False
    over: str = "once"
    patterns: tuple = ()
    rank: int = 1000
    on_demand: bool = True
    options: tuple = ()
    screen: str | None = None
    carries: tuple = ()
    single_marker: bool = False
    hand_written: bool = False
    #: a catch-all (a joint turning with another's value can mimic many physical effects): tried after every
    #: physical effect, which name what they can first
    last: bool = False
    #: other spellings in ``vjm simulate``: {alias: the parameter pattern its keys fill}
    aliases: dict = {}

    def _expand(self, site: Site):
        for item in site.items.get(self.over, ()):
            own = site.units.get(next(iter(item.values()), None), "")   # an item's own unit (an actuator's)
            for p in self.patterns:
                yield p, p.name.format(**item), own if p.unit == "site" else p.unit, own if p.step == "site" else p.step

    def parameters(self, site: Site) -> list:
        """[(name, unit, step kind)] of the effect's parameters on ``site``, item after item."""
        return [(name, unit, step) for _, name, unit, step in self._expand(site)]

    def param_specs(self, model, ctx=None) -> tuple:
        """The parameters on the site ``ctx`` (:class:`Site`) as :class:`Param` (unit, bounds, null 0)."""
        if ctx is None:
            return ()
        return tuple(Param(name, 0.0, p.lower, p.upper, null=0.0, unit=unit) for p, name, unit, _ in self._expand(ctx))

    def usable(self, model, data) -> str | None:
        """Why the data cannot show the effect (a column it needs missing), or None: a candidate of the
        whole-library default on them."""
        return None

    def applies_to(self, model, data_kind: str) -> str | None:
        kind = getattr(model, "kind", None)
        if kind not in self.model_kinds:
            return f"an effect of {' or '.join(self.model_kinds)} models, not of a {kind} one"
        if data_kind not in self.data_kinds:
            return f"{data_kind} data cannot show it"
        return None

    # ---------------------------------------------------------------- a new effect in the measurement model

    def joint_motion(self, model, q: np.ndarray, values: dict) -> np.ndarray | None:
        """The joints' extra motion (n, nq) rad or mm under the parameters ``values`` (every parameter's,
        missing ones 0), or None: nothing."""
        return None

    # ---------------------------------------------------------------- vjm simulate on a robot

    def hidden_params(self, model, site: Site) -> dict:
        """{key: whether it must be > 0} of ``NAME:key=value`` in ``vjm simulate``; empty: it is not simulated."""
        if type(self).joint_motion is PoseEffect.joint_motion:
            return {}
        return {n: False for n, _, _ in self.parameters(site)}

    def check_hidden(self, model, key: str, value: float) -> None:
        """A VjmError if ``value`` of ``key`` cannot be hidden in ``model``."""

    def true_model(self, model, values: dict):
        """The robot whose measurements hold the effect (default: ``model``)."""
        return model

    def true_joints(self, model, Q: np.ndarray, values: dict) -> np.ndarray:
        """The joints' true values (n, nq) at the reported ``Q`` (default: plus :meth:`joint_motion`)."""
        dq = self.joint_motion(model, Q, values)
        return Q if dq is None else Q + dq

    def describe(self, model, values: dict) -> str:
        """The hidden values, as the simulated file's header states them."""
        return ", ".join(f"{self.name} {k}={v:g}" for k, v in values.items())


def register_pose(cls):
    """Class decorator adding an absolute-pose effect (its name unique among them)."""
    inst = cls()
    if not inst.name or inst.name in POSES:
        raise ValueError(f"absolute-pose effect name {inst.name!r} is empty or already registered")
    POSES[inst.name] = inst
    return cls


def names(model_kind: str) -> tuple:
    """The effects of a ``model_kind`` ("serial", "parallel"), in the order they are tried: that of their
    registration, the catch-alls (:attr:`PoseEffect.last`) after the others."""
    return tuple(n for n, e in _tried() if model_kind in e.model_kinds)


def _tried() -> list:
    return sorted(POSES.items(), key=lambda kv: kv[1].last)


def defaults(model_kind: str) -> tuple:
    """The effects tried when none are asked, in order."""
    return tuple(n for n, e in POSES.items() if model_kind in e.model_kinds and e.default)


def applicable(model, data_kind: str, data=None) -> tuple:
    """The effects tried when none are asked for: every registered effect that applies to ``model`` and the
    ``data_kind`` (:meth:`PoseEffect.applies_to`) and that ``data`` can show (:meth:`PoseEffect.usable`), in
    the order they are tried."""
    return tuple(n for n, e in _tried() if e.applies_to(model, data_kind) is None
                 and (data is None or e.usable(model, data) is None))


def domain(names, model=None, nominal=None, model_kind: str = "serial") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The physical domain of the corrections of the parameters ``names``: (lower, upper, open), the total
    ``nominal[name] + correction`` kept within the declared bounds of the pattern forming each name
    (:class:`Pattern`; a registration's or a marker's parameter, or one no effect forms, unbounded);
    ``nominal`` the model's nominal values (missing ones 0), ``open`` the lower bounds excluded."""
    nominal = nominal or {}
    lo = np.full(len(names), -INF)
    hi = np.full(len(names), INF)
    op = np.zeros(len(names), dtype=bool)
    for i, n in enumerate(names):
        p = pattern_of(n, model_kind)
        if p is None:
            continue
        a, b = p.bounds(model)
        v = float(nominal.get(n, 0.0))
        lo[i], hi[i], op[i] = a - v, b - v, p.open
    return lo, hi, op


def pattern_of(name: str, model_kind: str = "serial") -> Pattern | None:
    """The :class:`Pattern` forming the parameter ``name`` (None: a registration's, a marker's, or none)."""
    if name.startswith("reg["):
        return None
    for e in POSES.values():
        if model_kind in e.model_kinds:
            for p in e.patterns:
                if _regex(p.name).match(name):
                    return p
    return None


def of_kind(model_kind: str) -> list:
    """The effects of a ``model_kind``, in the order of their parameters (:attr:`PoseEffect.rank`)."""
    return sorted((e for e in POSES.values() if model_kind in e.model_kinds), key=lambda e: e.rank)


def rank(kind: str) -> int:
    """Where a parameter kind (an effect's name, or ``reg``/``marker``) stands in the parameter vector."""
    return NUISANCE_RANK[kind] if kind in NUISANCE_RANK else POSES[kind].rank


def options(effects) -> dict:
    """The problem options the ``effects`` need: {option: bool} over payload, tilt, flex, thermal."""
    need = {o for e in effects if e in POSES for o in POSES[e].options}
    return {o: o in need for o in ("payload", "tilt", "flex", "thermal")}


def screen(name: str) -> str | None:
    """How the effect ``name``'s candidates are screened for observability (None: not screened)."""
    return POSES[name].screen if name in POSES else None


def carried(name: str) -> tuple:
    """The effects acting through ``name``'s parameters (dropped with it)."""
    return POSES[name].carries if name in POSES else ()


@functools.lru_cache(maxsize=None)
def _regex(pattern: str) -> re.Pattern:
    parts = re.split(r"(\{\w+\})", pattern)
    return re.compile("".join("(.+?)" if p.startswith("{") else re.escape(p) for p in parts) + "$")


def owner(name: str, model_kind: str = "serial") -> tuple:
    """(effect, unit) of the parameter ``name`` of a ``model_kind`` (the first effect whose pattern forms
    it); a VjmError if none does."""
    for e in POSES.values():
        if model_kind in e.model_kinds:
            for p in e.patterns:
                if _regex(p.name).match(name):
                    return e, p.unit
    raise VjmError(f"{name}: not a parameter of any absolute-pose effect of a {model_kind} model")


def owner_of(name: str, model_kind: str = "serial") -> PoseEffect | None:
    """The effect forming the parameter ``name`` (None: none, a registration's or a marker's)."""
    if name.startswith("reg["):
        return None
    try:
        return owner(name, model_kind)[0]
    except VjmError:
        return None


def get_pose(name: str, model_kind: str, where: str = "effect") -> PoseEffect:
    """The effect ``name`` (or an alias of one) of a ``model_kind``; a VjmError naming ``where`` otherwise."""
    for e in POSES.values():
        if model_kind in e.model_kinds and (e.name == name or name in e.aliases):
            return e
    raise VjmError(f"{where}: unknown effect {name!r}; effects: {', '.join(names(model_kind))}")


# ------------------------------------------------------------------------------------------- a robot's

_TORQUE_UNIT = "rad/(N mm)"


@register_pose
class Geometry(PoseEffect):
    """Joint offsets and per-joint URDF-origin errors (a small twist after the origin)."""

    name = "geometry"
    description = "joint offsets and errors of the joints' URDF origins"
    default = True
    over = "joint"
    patterns = (Pattern("{joint}.offset", "rad", "rad"),
                *(Pattern(f"{{joint}}.{k}", "mm" if k[0] == "d" else "rad", "mm" if k[0] == "d" else "rad")
                  for k in GEOMETRY[1:]))
    rank = 10
    on_demand = False
    hand_written = True
    aliases = {"offset": "{joint}.offset"}

    def hidden_params(self, model, site):
        return {f"{n}.offset": False for n in model.q_names}

    def true_joints(self, model, Q, values):
        off = np.zeros(model.nq)
        for k, v in values.items():
            off[model.q_names.index(k[:-len(".offset")])] = v
        return Q + off

    def describe(self, model, values):
        return ", ".join(f"offset {n}={values.get(f'{n}.offset', 0.0):g}" for n in model.q_names
                         if values.get(f"{n}.offset", 0.0) != 0.0)


@register_pose
class Compliance(PoseEffect):
    """A torsional compliance per joint: the deflection ``-c g_j(q)`` under the gravity torque."""

    name = "compliance"
    description = "each joint's torsional compliance under the robot's self-weight"
    default = True
    over = "free"
    patterns = (Pattern("{joint}.compliance", _TORQUE_UNIT, "c", lower=0.0),)
    rank = 20
    on_demand = False
    screen = "torque"
    carries = ("tilt", "payload", "varying")
    hand_written = True
    aliases: dict = {}

    def hidden_params(self, model, site):
        # a factor on the model file's compliance: the true sag is the model's own self-weight equilibrium
        return {n: True for n in model.q_names}

    def check_hidden(self, model, key, value):
        if key not in model.joint_springs:
            raise VjmError(f"{self.name}:{key}: the joint is rigid in the model file (no stiffness to scale)")

    def true_model(self, model, values):
        """``model`` with each named joint's compliance times its factor (a constant, table or expression)."""
        springs = dict(model.joint_springs)
        for name, f in values.items():
            s = springs[name]
            if s.stiffness is not None:
                springs[name] = dataclasses.replace(s, stiffness=float(s.stiffness) / f)
            elif s.table is not None:
                springs[name] = dataclasses.replace(s, table=(s.table[0], tuple(np.asarray(s.table[1]) / f)))
            else:
                springs[name] = dataclasses.replace(s, expression=f"({s.expression}) / {f!r}")
        return dataclasses.replace(model, joint_springs=springs)

    def true_joints(self, model, Q, values):
        return Q

    def describe(self, model, values):
        return ", ".join(f"compliance {n}x{f:g}" for n, f in values.items())


@register_pose
class Coupling(PoseEffect):
    """A joint turning by ``k`` times another's value (a wrist's gear train, a misread joint)."""

    name = "coupling"
    description = "a joint turning by a multiple of another joint's value"
    over = "pair"
    patterns = (Pattern("{joint}.coupling[{other}]", "rad/rad", "rad"),)
    rank = 40
    hand_written = True
    last = True


@register_pose
class Lateral(PoseEffect):
    """A joint's bearing tilting under the moment normal to its axis (:mod:`vjm.calibration.flex`)."""

    name = "lateral"
    description = "each joint's lateral (bearing) compliance under the moment normal to its axis"
    over = "bearing"   # a revolute joint's; a prismatic joint's carriage tilts as a guide (guide_tilt)
    patterns = (Pattern("{joint}.lateral", _TORQUE_UNIT, "lat", lower=0.0),)
    rank = 50
    options = ("flex",)
    screen = "lateral"
    hand_written = True


@register_pose
class Bending(PoseEffect):
    """A long link bending as a cantilever under what it carries (:mod:`vjm.calibration.flex`)."""

    name = "bending"
    description = "the long links bending as Euler-Bernoulli cantilevers (1/EI)"
    over = "beam"
    patterns = (Pattern("{link}.bending", "1/(N mm^2)", "bend", lower=0.0),)
    rank = 60
    options = ("flex",)
    hand_written = True


@register_pose
class Varying(PoseEffect):
    """A joint's compliance varying with its value, ``c + c' q`` (:mod:`vjm.calibration.flex`)."""

    name = "varying"
    description = "each joint's compliance varying with the joint's value"
    over = "free"
    patterns = (Pattern("{joint}.varying", "rad/(N mm rad)", "var"),)
    rank = 70
    options = ("flex",)
    screen = "torque"
    hand_written = True


@register_pose
class Thermal(PoseEffect):
    """The robot's lengths scaled by ``1 + alpha (T - 20 C)`` (a ``meta_temperature`` column)."""

    name = "thermal"
    description = "the lengths scaled with the temperature of each row"
    patterns = (Pattern("thermal.alpha", "1/K", "K"),)
    rank = 80
    options = ("thermal",)
    screen = "temperature"
    hand_written = True

    def usable(self, model, data):
        # the column of the calibration's flex loads (vjm.calibration.flex.TEMPERATURE)
        return None if "meta_temperature" in getattr(data, "meta", {}) else "no meta_temperature column"


@register_pose
class Tilt(PoseEffect):
    """The base tilted against the gravity the model assumes, seen through the compliances."""

    name = "tilt"
    description = "the base tilted against the model's gravity (2 angles)"
    patterns = (Pattern("base.tilt_rx", "rad", "rad"), Pattern("base.tilt_ry", "rad", "rad"))
    rank = 90
    options = ("tilt",)
    hand_written = True


@register_pose
class Backlash(PoseEffect):
    """A clearance per joint taken up on the side its gravity torque pushes to: ``-b sign(g_j(q))``."""

    name = "backlash"
    description = "each joint's clearance, taken up on the side of its gravity torque"
    over = "free"
    patterns = (Pattern("{joint}.backlash", "rad", "rad", lower=0.0),)
    rank = 30
    on_demand = False
    screen = "sign"
    hand_written = True


@register_pose
class Payload(PoseEffect):
    """An unknown mass at the marker, weighed through the compliances."""

    name = "payload"
    description = "an unknown mass at the measured point (a probe, a tool)"
    default = True
    patterns = (Pattern("payload.mass", "kg", "kg", lower=0.0, upper_from="payload_limit"),)
    rank = 100
    options = ("payload",)
    single_marker = True
    hand_written = True


# --------------------------------------------------------------------------------- a parallel machine's

@register_pose
class ActuatorOffset(PoseEffect):
    """An offset per actuator: the zero of its encoder (:mod:`vjm.calibration.parallel`)."""

    name = "offset"
    description = "each actuator's offset (the zero of its encoder)"
    model_kinds = ("parallel",)
    data_kinds = ("platform_absolute",)
    default = True
    over = "actuator"
    patterns = (Pattern("{actuator}.offset", "site", "site"),)
    rank = 10
    hand_written = True


@register_pose
class Attachment(PoseEffect):
    """Each chain's base translated: where its first joint is fixed (:mod:`vjm.calibration.parallel`)."""

    name = "attachment"
    description = "each chain's base attachment translated"
    model_kinds = ("parallel",)
    data_kinds = ("platform_absolute",)
    default = True
    over = "chain"
    patterns = tuple(Pattern(f"{{chain}}.base.d{c}", "mm", "mm") for c in "xyz")
    rank = 20
    hand_written = True


# ------------------------------------------------------------------------- a robot's, beyond its joints

@register_pose
class GuideTilt(PoseEffect):
    """A prismatic guide's carriage (a linear axis, a gantry, a track, a telescopic column) tilting under the
    moment it carries, its compliance growing as the guide extends: stated at the two ends of the joint's
    travel (``over`` ``"guide"``: one per driving joint, its mimic segments sharing it), both >= 0 -- the
    compliance is then >= 0 over the whole travel (:mod:`vjm.calibration.flex`)."""

    name = "guide_tilt"
    description = "a prismatic guide's carriage tilting under the moment it carries, more as it extends"
    over = "guide"
    patterns = (Pattern("{joint}.guide_tilt_lower", _TORQUE_UNIT, "guide", lower=0.0),
                Pattern("{joint}.guide_tilt_upper", _TORQUE_UNIT, "guide", lower=0.0))
    rank = 110
    options = ("flex",)
    screen = "lateral"
    hand_written = True

    def usable(self, model, data) -> str | None:
        """Why the effect has nothing to fit on ``model`` measured at ``data``'s frames, or None."""
        from ..calibration.flex import guide_axes

        frames = list(getattr(data, "points", ()))
        if any(guide_axes(model, f) for f in frames):
            return None
        return (f"no prismatic joint with a finite travel (a linear axis, a track, a column) on the path to "
                f"{', '.join(frames)}")


@register_pose
class ColumnTilt(GuideTilt):
    """A telescopic stage tilting in its fixed guide about the guide's exit (the joint's frame before its
    motion), under the moment it carries, its compliance growing as it extends: :class:`GuideTilt`'s
    compliance about another point -- a carriage on rails turns about itself, a column's stage about the top
    of the guide that holds it, which stays while the stage slides."""

    name = "column_tilt"
    description = "a telescopic stage tilting about its guide's exit under the moment it carries, more as it extends"
    patterns = (Pattern("{joint}.column_tilt_lower", _TORQUE_UNIT, "guide", lower=0.0),
                Pattern("{joint}.column_tilt_upper", _TORQUE_UNIT, "guide", lower=0.0))
    rank = 111


@register_pose
class LinkScale(PoseEffect):
    """The model's link springs (beams, linkfea results) scaled, one factor per link spring (``over``
    ``"spring"``): the parameter multiplies the link's nominal deflection under what it carries
    (:mod:`vjm.calibration.flex`).  The model's own value of the scale is 1 (:meth:`nominal`): with the nominal
    deflection in the baseline the parameter is the correction on top of it; its domain is that of the
    total, a scale > 0 (0: a rigid link)."""

    name = "link_scale"
    description = "each link spring of the model scaled: how compliant the link is against its CAD or FEA"
    over = "spring"
    patterns = (Pattern("{link}.link_scale", "1", "scale", lower=0.0, open=True),)
    rank = 120
    options = ("flex",)
    hand_written = True

    def usable(self, model, data) -> str | None:
        """Why the effect has nothing to fit on ``model`` measured at ``data``'s frames, or None."""
        from ..calibration.flex import link_springs

        frames = list(getattr(data, "points", ()))
        if any(link_springs(model, f) for f in frames):
            return None
        return f"the model states no link spring (links: a beam, a linkfea result) on the path to {', '.join(frames)}"

    def nominal(self, model, site: Site) -> dict:
        """The model file's value of each parameter's total: 1 (the link spring as stated)."""
        return {n: 1.0 for n, _, _ in self.parameters(site)}
