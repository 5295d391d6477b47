"""Absolute positions of a point on a parallel machine's platform, as an instrument sees them.

The sibling of :mod:`vjm.calibration.serial` (a serial or tree robot's measurement model) for a parallel
machine (:class:`vjm.ParallelModel`): the measured point ``p`` on the platform at commanded actuator
values ``a``, in the instrument frame of group ``g``::

    m = R_g (X(a + offsets; base shifts) p) + t_g

- ``X``: the platform frame of the forward kinematics (:mod:`vjm.kinematics.forward`) at the actuator
  values plus an **offset** per actuator (``<chain>.<variable>.offset``, mm or rad: the zero of its
  encoder), each chain's base translated by its **attachment** error (``<chain>.base.dx/dy/dz`` mm, world
  frame: where its first joint is fixed);
- ``p``: the marker's offset on the platform (``platform.px..pz`` mm); a 3-dof platform does not turn,
  so its marker offset is the instrument frame's translation: it is not a parameter there;
- ``R_g, t_g``: the instrument frame (``reg[<group>].tx..rz``), the nuisance fitted with everything.

The machine has no load per row (no self-weight model): the elastic effects of a robot do not apply.

A :class:`PlatformProblem` answers what the calibration engine (:mod:`vjm.calibration.engine`) asks of a
measurement model: the predictions and their Jacobian for a parameter :class:`~vjm.calibration.serial.Layout`,
and the problem on a subset of the rows.  The Jacobian is the implicit derivative of the closure
(:func:`vjm.kinematics.forward.sensitivities`), exact at the solved platform frames.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..effects import absolute
from ..errors import VjmError
from ..kinematics import forward as fk
from ..kinematics.transforms import ROTATION
from .serial import Layout, instrument_jacobian, layout_of, rotation_matrix

#: the measured frame of a parallel machine
FRAME = "platform"


def effect_names() -> tuple:
    """A parallel machine's effects, in the order they are tried (:data:`vjm.effects.absolute.POSES`)."""
    return absolute.names("parallel")


def actuator_units(asm: fk.Assembly) -> tuple:
    """"mm" or "rad" per actuator (its variable's elementary transform)."""
    out = []
    for ch, a in zip(asm.chains, asm.actuated):
        kind = next(f.kind for f in ch.factors if f.kind != "const" and f.var == a)
        out.append("rad" if ROTATION[kind] else "mm")
    return tuple(out)


def site(model, asm: fk.Assembly) -> absolute.Site:
    """What a parallel machine's effects repeat over (:class:`vjm.effects.absolute.Site`): the actuators (each
    with its unit, mm or rad), the chains."""
    acts = fk.actuator_names(model)
    return absolute.Site("parallel", {"actuator": tuple({"actuator": a} for a in acts),
                                      "chain": tuple({"chain": ch.name} for ch in asm.chains), "once": ({},)},
                         dict(zip(acts, actuator_units(asm))))


def full_layout(model, asm: fk.Assembly, groups) -> Layout:
    """Every parameter: each group's registration, the marker (6-dof platforms), then each effect's
    (:mod:`vjm.effects.absolute`, in the order of their rank): the actuator offsets, the chains' base
    translations."""
    markers = [f"{FRAME}.p{c}" for c in "xyz"] if asm.dof == 6 else []
    return layout_of(groups, markers, site(model, asm), absolute.of_kind("parallel"))


@dataclass(frozen=True, eq=False)
class PlatformProblem:
    """What the prediction needs besides the parameters: the model and its :class:`Assembly`, the rows'
    actuator values (n, nc), their group index, the groups' base registration (R0, t0), the marker's base
    offset p0, and the nominal forward kinematics (the start of every solve)."""

    model: Any
    asm: fk.Assembly
    q: np.ndarray
    gidx: np.ndarray
    groups: tuple
    R0: tuple
    t0: tuple
    p0: np.ndarray
    nominal: fk.State
    frame: str = FRAME
    #: the last solve {"key": bytes, "state": State}: the fit asks the Jacobian where it last predicted
    _last: dict = field(default_factory=dict, repr=False)

    def rows(self, mask) -> "PlatformProblem":
        """The problem on the rows ``mask``."""
        return PlatformProblem(self.model, self.asm, self.q[mask], self.gidx[mask], self.groups, self.R0, self.t0,
                               self.p0, self.nominal.rows(mask))

    def _inputs(self, vals: dict) -> tuple[np.ndarray, np.ndarray]:
        names = fk.actuator_names(self.model)
        off = np.array([vals.get(f"{n}.offset", 0.0) for n in names])
        shift = np.array([[vals.get(f"{ch.name}.base.d{c}", 0.0) for c in "xyz"] for ch in self.asm.chains])
        return self.q + off, shift

    def state(self, vals: dict) -> fk.State:
        """The forward kinematics under the parameters ``vals`` (from the nominal solution)."""
        q, shift = self._inputs(vals)
        key = q.tobytes() + shift.tobytes()
        if self._last.get("key") != key:
            self._last.update(key=key, state=fk.solve(self.asm, q, self.nominal, shift))
        return self._last["state"]

    def _marker(self, vals: dict) -> np.ndarray:
        return self.p0 + np.array([vals.get(f"{self.frame}.p{c}", 0.0) for c in "xyz"])

    def predict(self, layout: Layout, x: np.ndarray, fixed: dict | None = None) -> np.ndarray:
        """The measured points (n, 3) mm in the instrument frames for parameters ``x`` of ``layout``."""
        vals = {**(fixed or {}), **dict(zip(layout.names, x))}
        X = self.state(vals).X
        pb = np.einsum("nij,j->ni", X[:, :3, :3], self._marker(vals)) + X[:, :3, 3]
        out = np.empty_like(pb)
        for gi, g in enumerate(self.groups):
            rows = self.gidx == gi
            out[rows] = pb[rows] @ _rotation(vals, g, self.R0[gi]).T + self.t0[gi] + _translation(vals, g)
        return out

    def jacobian(self, layout: Layout, x: np.ndarray, fixed: dict | None = None) -> np.ndarray:
        """d predict / d x (3n, size): the closure's implicit derivative for the machine's parameters, the
        platform's rotation for the marker, the registration's own columns."""
        vals = {**(fixed or {}), **dict(zip(layout.names, x))}
        q, shift = self._inputs(vals)
        st = self.state(vals)
        ta, ts = fk.sensitivities(self.asm, q, st, shift)
        R = st.X[:, :3, :3]
        r = np.einsum("nij,j->ni", R, self._marker(vals))
        pb = r + st.X[:, :3, 3]

        def moved(tw):   # the marker point's motion (n, 3, k) of platform twists (n, 6, k)
            return tw[:, :3] + np.cross(tw[:, 3:], r[:, :, None], axis=1)

        cols = {f"{n}.offset": c for n, c in zip(fk.actuator_names(self.model), np.moveaxis(moved(ta), 2, 0))}
        cols.update({f"{ch.name}.base.d{c}": v for (ch, c), v in
                     zip([(ch, c) for ch in self.asm.chains for c in "xyz"], np.moveaxis(moved(ts), 2, 0))})
        cols.update({f"{self.frame}.p{c}": R[:, :, i] for i, c in enumerate("xyz")})
        return instrument_jacobian(pb, cols, layout, vals, self.groups, self.gidx, self.R0)


def _rotation(vals: dict, g: str, R0: np.ndarray) -> np.ndarray:
    return rotation_matrix(np.array([vals.get(f"reg[{g}].r{c}", 0.0) for c in "xyz"])) @ R0


def _translation(vals: dict, g: str) -> np.ndarray:
    return np.array([vals.get(f"reg[{g}].t{c}", 0.0) for c in "xyz"])


def nominal_state(asm: fk.Assembly, q: np.ndarray, source: str = "data") -> fk.State:
    """The nominal forward kinematics of the rows; VjmError naming the rows where it does not close."""
    st = fk.solve(asm, q)
    bad = np.flatnonzero(~st.ok)
    if bad.size:
        rows = ", ".join(str(i + 1) for i in bad[:10]) + (" ..." if bad.size > 10 else "")
        raise VjmError(f"{source}: the forward kinematics does not close at the actuator values of {bad.size} row(s) "
                       f"(data rows {rows}; closure error {st.err[bad[0]]:.3g} mm): values outside the machine's "
                       f"assembly from its seed posture")
    return st


def problem(model, asm: fk.Assembly, data, frames: dict, p0, nominal: fk.State | None = None) -> PlatformProblem:
    """The :class:`PlatformProblem` of ``data`` (absolute poses whose joints are the actuators) with the
    groups' registration ``frames`` {group: (R0, t0)} and the marker's base offset ``p0``."""
    q = data.q_for(fk.actuator_names(model))
    groups = tuple(sorted({str(g) for g in data.groups}))
    missing = [g for g in groups if g not in frames]
    if missing:
        raise VjmError(f"{data.source}: group(s) {', '.join(missing)} not registered")
    gidx = np.array([groups.index(str(g)) for g in data.groups])
    st = nominal_state(asm, q, data.source) if nominal is None else nominal
    return PlatformProblem(model, asm, q, gidx, groups, tuple(frames[g][0] for g in groups),
                           tuple(frames[g][1] for g in groups), np.asarray(p0, dtype=float), st)


def points(cal, data) -> np.ndarray:
    """A parallel machine's calibrated points (n, 3) mm in the instrument frames of ``data``'s (registered)
    groups (a :class:`vjm.calibration.result.Calibration` ``cal`` of this module's parameters)."""
    prob = problem(cal.model, fk.assembly(cal.model), data, cal.frames, cal.p0)
    lay = Layout(tuple(cal.values), ("",) * len(cal.values), ("",) * len(cal.values))
    return prob.predict(lay, np.array(list(cal.values.values())))
