"""What each named effect does to the tool, in the user's terms: millimetres at the measured poses and at home,
and a joint compliance as the stiffness the model file states.

An effect's size is the difference of two predictions of the calibrated measurement model
(:func:`vjm.calibration.engine.predict_points`): with every fitted parameter, and without the effect's.  "Without"
leaves its fitted parameters out and, for a robot, the model's own part of it too (a joint's spring, a link
spring, the payload), so that the size is the whole effect whether the fit's parameters are totals or corrections to the
model file's values.  The same registration is used on both sides, so the difference is the tool's motion, not
what the instrument frames would absorb: "compliance buys 0.018 mm" of residual is compatible with a sag of
0.7 mm, most of which the geometry and the registration take up on the fitted rows.

- :func:`effect_sizes`: one :class:`EffectSize` per named effect: the mean and largest displacement over the
  measured rows (mm; with several measured points, each row's largest), at the model file's ``home:`` (None
  without one, or for a parallel machine), and its parts -- each joint's (each item's) parameter alone;
- a joint compliance's part carries its :class:`Stiffness`: the calibrated model file's stiffness (N mm/rad;
  N/mm for a prismatic joint) with the 95 % interval of the compliance's, inverted, and the source model's.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

from .engine import measurement, predict_points
from .flex import TEMPERATURE
from .poses import AbsolutePoses

#: the two-sided 95 % normal quantile of the intervals
Z95 = 1.959963984540054
#: the effects the calibrated robot file (and its URDF) carries, so that ``vjm compensate`` on it removes them;
#: the others are fitted but have no place in a robot file (:mod:`vjm.calibration.write` lists them in its head)
CARRIED = ("geometry", "compliance", "payload", "tilt")
#: effects whose displacement is a sag under the weight
SAGS = ("compliance", "payload")


@dataclass(frozen=True)
class Stiffness:
    """A fitted joint compliance as a model file states it: ``stiffness`` (``unit``, the inverse of the
    ``compliance`` in ``compliance_unit``) and the 95 % interval [``low``, ``high``] of the compliance's
    (``compliance`` +- 1.96 ``std``) inverted: ``high`` is inf where that interval reaches 0.  ``nominal``:
    the source model file's stiffness (None: the joint is rigid there, or its stiffness is not a constant);
    ``stiffness`` None: no constant stiffness fitted > 0 (the calibrated file keeps the source's entry), and
    ``compliance`` is then the fitted value."""

    joint: str
    compliance: float
    std: float | None
    stiffness: float | None
    low: float | None
    high: float | None
    nominal: float | None
    unit: str
    compliance_unit: str


@dataclass(frozen=True)
class Size:
    """The tool's displacement (mm) between the calibrated model with and without ``parameters``: ``mean_mm``
    and ``max_mm`` over the measured rows, ``home_mm`` at ``home:`` (None: none)."""

    name: str
    parameters: tuple
    mean_mm: float
    max_mm: float
    home_mm: float | None
    stiffness: Stiffness | None = None


@dataclass(frozen=True)
class EffectSize:
    """A named effect's size (``total``), its ``parts`` (one per joint or item with parameters of its own,
    largest at the measured rows first; empty for an effect of one item) and whether the calibrated robot file
    carries it (``carried``: ``vjm compensate`` on it removes it; None for a machine without one)."""

    effect: str
    total: Size
    parts: tuple
    carried: bool | None


def home_poses(cal, data) -> AbsolutePoses | None:
    """One row at the model file's ``home:`` in the first group of ``data`` (its instrument frame: the
    displacement's length does not depend on it), at the data's mean temperature where they state one; None
    without a home."""
    home = getattr(cal.model, "home", None)
    if home is None:
        return None
    meta = {TEMPERATURE: np.array([float(np.mean(data.meta[TEMPERATURE]))])} if TEMPERATURE in data.meta else {}
    return AbsolutePoses(tuple(cal.model.q_names), np.asarray(home, dtype=float)[None, :],
                         {f: np.zeros((1, 3)) for f in cal.markers}, group=np.array([str(data.groups[0])], dtype=object),
                         meta=meta, source="home")


def _bare(model, names) -> object:
    """The model without its own part of the parameters ``names``: the joint springs of the compliances, the link
    springs scaled and the payload (a fit of corrections starts from them; a fit of totals does not read them)."""
    if getattr(model, "kind", None) != "serial":
        return model
    joints = {n[:-len(".compliance")] for n in names if n.endswith(".compliance")}
    links = {n[:-len(".link_scale")] for n in names if n.endswith(".link_scale")}
    changes: dict = {}
    if joints & set(model.joint_springs):
        changes["joint_springs"] = {k: v for k, v in model.joint_springs.items() if k not in joints}
    if links & set(model.links):
        changes["links"] = {k: v for k, v in model.links.items() if k not in links}
    if "payload.mass" in names and model.payload is not None:
        changes["payload"] = None
    return model.replace(**changes) if changes else model


@dataclass(frozen=True, eq=False)
class Rows:
    """Rows to predict (``data``), a robot's measurement model of them (``prob``, built once: an effect without
    a part in the model file changes only the values; None for a parallel machine) and the calibrated model's
    points there (``full``)."""

    data: Any
    prob: Any
    full: np.ndarray


def rows_of(cal, data) -> Rows:
    """The :class:`Rows` of ``data`` under the calibration ``cal``."""
    prob = measurement(cal, data) if cal.model.kind == "serial" else None
    return Rows(data, prob, predict_points(cal, data, prob))


def displacement(cal, rows: Rows, names) -> np.ndarray:
    """|prediction with every parameter - prediction without ``names``| (n,) mm per row of ``rows`` (with several
    measured points, the row's largest)."""
    names = set(names)
    bare = _bare(cal.model, names)
    without = replace(cal, model=bare, values={k: v for k, v in cal.values.items() if k not in names})
    d = np.linalg.norm(rows.full - predict_points(without, rows.data, rows.prob if bare is cal.model else None), axis=1)
    return d.reshape(len(cal.measured), rows.data.n).max(axis=0)


def _size(cal, at: tuple, name: str, names: tuple, stiffness: Stiffness | None = None) -> Size:
    """The :class:`Size` of ``names`` on ``at`` (the measured :class:`Rows`, home's or None)."""
    rows, home = at
    d = displacement(cal, rows, names)
    h = None if home is None else float(displacement(cal, home, names)[0])
    return Size(name, tuple(names), float(d.mean()), float(d.max()), h, stiffness)


def file_joints(cal) -> dict:
    """The calibrated robot file's ``joints:`` entries (:func:`vjm.calibration.write.calibrated_mapping`)."""
    from .write import calibrated_mapping

    return calibrated_mapping(cal, "calibrated.urdf")[0].get("joints") or {}


def stiffness_of(cal, joint: str, z: float = Z95, joints: dict | None = None) -> Stiffness:
    """The calibrated model file's stiffness of ``joint`` (its entry in ``joints``, default :func:`file_joints`:
    the fitted compliance's inverse as the file rounds it) with the interval of the compliance's ``c +- z std``."""
    from .write import Rounded

    prismatic = cal.model.tree.joints[cal.model.tree.joint_index(joint)].kind[0] == "t"
    unit, cunit = ("N/mm", "mm/N") if prismatic else ("N mm/rad", "rad/(N mm)")
    spring = cal.model.joint_springs.get(joint)
    nominal = None if spring is None or spring.stiffness is None else float(spring.stiffness)
    key = f"{joint}.compliance"
    s = cal.std.get(key)
    k = (file_joints(cal) if joints is None else joints).get(joint, {}).get("stiffness")
    if not isinstance(k, Rounded):   # no constant fitted > 0: the file keeps the source's entry
        from .nominal import nominal_values

        total = nominal_values(cal.model, [key])[key] + float(cal.values[key])   # the fitted value: a correction
        return Stiffness(joint, total, s, None, None, None, nominal, unit, cunit)
    c = 1.0 / float(k)
    lo_c, hi_c = (c, c) if s is None else (c - z * s, c + z * s)
    return Stiffness(joint, c, s, float(k), 1.0 / hi_c, float("inf") if lo_c <= 0 else 1.0 / lo_c, nominal, unit,
                     cunit)


def _items(effect: str, names: tuple) -> dict:
    """{item: its parameters} of an effect's parameters: a joint's (a link's, an actuator's) by the name's
    prefix; one item (no parts) for an effect whose parameters all share it or have none."""
    items: dict = {}
    for n in names:
        items.setdefault(n.rsplit(".", 1)[0] if "." in n else n, []).append(n)
    return items if len(items) > 1 else {}


def effect_sizes(cal, data, effects: dict) -> tuple:
    """An :class:`EffectSize` per named effect of ``effects`` ({effect: its fitted parameters}, in order) on the
    fitted rows of ``data`` (the rows set aside left out)."""
    keep = np.setdiff1d(np.arange(data.n), np.asarray(cal.set_aside, dtype=int))
    rows = data.subset(keep)
    home = home_poses(cal, rows)
    at = (rows_of(cal, rows), None if home is None else rows_of(cal, home))
    serial = getattr(cal.model, "kind", None) == "serial"
    joints = file_joints(cal) if serial and "compliance" in effects else {}
    out = []
    for effect, names in effects.items():
        if not names:
            continue
        parts = []
        for item, own in _items(effect, tuple(names)).items():
            st = stiffness_of(cal, item, joints=joints) if serial and effect == "compliance" else None
            parts.append(_size(cal, at, item, tuple(own), st))
        parts.sort(key=lambda p: -p.mean_mm)
        out.append(EffectSize(effect, _size(cal, at, effect, tuple(names)), tuple(parts),
                              (effect in CARRIED) if serial else None))
    return tuple(out)


def as_mapping(size: EffectSize) -> dict:
    """An :class:`EffectSize` as report.json holds it (an interval's inf: None, as JSON has no inf)."""
    def clean(v):
        if isinstance(v, dict):
            return {k: clean(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [clean(x) for x in v]
        return None if isinstance(v, float) and not np.isfinite(v) else v

    return clean(asdict(size))
