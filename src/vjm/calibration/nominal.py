"""What a robot's model file states beyond its kinematics, as the calibration's measurement model starts from it.

The absolute-pose calibration fits *corrections* to the model as the user gave it, never values from zero:

- **joint springs**: a joint's deflection is ``-(c0(q) + dc) g_j(q)``, with ``c0`` the compliance the model file
  states (``1 / stiffness``; a table or an expression evaluated at the row's joint value; 0 for a rigid joint) and
  ``dc`` the fitted ``<joint>.compliance``, a correction (the total compliance is ``c0 + dc``);
- **gravity torques** ``g(q)``: the model's masses *and its payload* under its gravity;
- **the other springs** (link springs: beams, linkfea results, 6x6 matrices; the joints' 6x6 bearing springs):
  their sag of the measured frame, a twist per row from the model's own self-weight equilibrium
  (:meth:`vjm.robot.RobotModel.self_weight`) with the joints' 1-dof springs taken out (they are the fitted
  part), added to the measured point to first order (``t + w x R p`` for a marker ``p`` on a frame turned by
  ``R``).  The products of the two deflections, and of the sag with the fitted geometry, are second order
  (on the bundled UR10: about 1e-3 mm, a tenth of a tracker's noise; the test of this module measures it);
- **payload**: the model's payload is a load of the nominal model; a fitted ``payload.mass`` is a correction
  ``dm`` (kg) at the marker, its torques (and, with link springs, their sag per kg) added to the nominal's.

:func:`nominal_values` gives each parameter's nominal value, so that a bound or a report speaks of the total.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np


@dataclass(frozen=True, eq=False)
class Nominal:
    """The model file's own deflection per row: the joints' compliances ``compliance`` (n, nq) rad/(N mm) (mm/N
    for a prismatic joint; 0 for a rigid one), and the twist ``sag`` (n, 6) (mm, rad; base axes, at the measured
    frame's origin) of its other springs under its weight and payload (None: it has none), that twist per kg at
    the marker ``unit_sag`` (None unless a payload is fitted), and the measured frame's rotation ``R`` (n, 3, 3)
    at the commanded configurations (the marker offset the twist's rotation moves)."""

    compliance: np.ndarray
    sag: np.ndarray | None = None
    unit_sag: np.ndarray | None = None
    R: np.ndarray | None = None

    def rows(self, mask: np.ndarray) -> Nominal:
        """The rows ``mask`` selects."""
        return replace(self, compliance=self.compliance[mask],
                       **{k: None if getattr(self, k) is None else getattr(self, k)[mask]
                          for k in ("sag", "unit_sag", "R")})

    def twist(self, mass: float = 0.0) -> np.ndarray | None:
        """The sag twist (n, 6) with a fitted payload correction ``mass`` (kg) at the marker, or None."""
        if self.sag is None:
            return None
        return self.sag if not mass or self.unit_sag is None else self.sag + mass * self.unit_sag


def joint_compliances(model, q: np.ndarray) -> np.ndarray:
    """The model file's joint compliances (n, nq) at configurations q (0 where a joint has no spring)."""
    out = np.zeros((len(q), model.nq))
    for i, name in enumerate(model.q_names):
        s = model.joint_springs.get(name)
        if s is not None:
            out[:, i] = s.compliance(q[:, i], f"joints.{name}.stiffness")
    return out


def point_torques(model, q: np.ndarray, frame: str, p, gravity=None) -> np.ndarray:
    """The gravity torques (n, nq) N mm of 1 kg at the point ``p`` (mm) of ``frame``, ``-J_p^T g``."""
    T = model.forward(q, frame).reshape(-1, 4, 4)
    J = model.jacobian(q, frame).reshape(len(q), 6, -1)
    r = np.einsum("nij,j->ni", T[:, :3, :3], np.asarray(p, dtype=float))
    Jp = J[:, :3, :] + np.cross(J[:, 3:, :], r[:, :, None], axis=1)
    g = np.asarray(model.gravity if gravity is None else gravity, dtype=float)
    return -np.einsum("nik,i->nk", Jp, g)


def model_torques(model, q: np.ndarray, gravity=None) -> np.ndarray:
    """The gravity torques (n, nq) N mm of the model's masses and of its payload, under ``gravity`` (m/s^2,
    default the model's)."""
    tau = model.gravity_torques(q, gravity)
    pl = model.payload
    if pl is not None and pl.mass > 0:
        tau = tau + pl.mass * point_torques(model, q, pl.frame, pl.com, gravity)
    return tau


def other_springs(model):
    """The model with its joints' 1-dof springs taken out (mimic joints' kept: no parameter corrects them), or
    None when nothing else is elastic (no link spring, no 6x6 joint spring, no spring on a mimic joint)."""
    kept = {n: s for n, s in model.joint_springs.items() if n not in model.q_names}
    if not (model.links or model.joint6 or kept):
        return None
    return replace(model, joint_springs=kept, raw=None)


def nominal_state(model, q: np.ndarray, frame: str, p0, payload: bool = False) -> Nominal:
    """The :class:`Nominal` of a measured ``frame`` (marker ``p0`` mm) at configurations q (n, nq); ``payload``:
    with the other springs' sag per kg at the marker."""
    c0 = joint_compliances(model, q)
    rest = other_springs(model)
    if rest is None:
        return Nominal(c0)
    sag = rest.self_weight(q, frame)
    # per kg at the marker: the linear compliance of those springs at the frame times that kilogram's wrench
    unit = rest.deflection(q, _kg_wrench(model, q, frame, p0), frame) if payload else None
    R = model.forward(q, frame).reshape(-1, 4, 4)[:, :3, :3]
    return Nominal(c0, sag, unit, np.ascontiguousarray(R))


def _kg_wrench(model, q: np.ndarray, frame: str, p0) -> np.ndarray:
    """The wrench (n, 6) at ``frame``'s origin (N, N mm, base axes) of 1 kg at its point ``p0``."""
    T = model.forward(q, frame).reshape(-1, 4, 4)
    f = np.broadcast_to(np.asarray(model.gravity, dtype=float), (len(q), 3))
    r = np.einsum("nij,j->ni", T[:, :3, :3], np.asarray(p0, dtype=float))
    return np.concatenate([f, np.cross(r, f)], axis=1)


def nominal_values(model, names) -> dict:
    """{parameter name: its nominal value in the model file}, for the calibration's parameter ``names``: a
    ``<joint>.compliance`` the joint spring's compliance (rad/(N mm), mm/N; a spring varying with the joint's
    value: its smallest over the joint's limits, the stiffest, so that ``nominal + correction >= 0`` there holds
    everywhere), ``payload.mass`` the model's payload (kg), a ``<link>.link_scale`` 1 (the link spring as stated); 0 for
    every other (the model states nothing of
    it: an origin error, an offset, a backlash ...).  The fitted value of a parameter is a correction: its total
    is this plus the fitted value."""
    out = {}
    for n in names:
        v = 0.0
        if n.endswith(".compliance"):
            s = model.joint_springs.get(n[:-len(".compliance")])
            if s is not None:
                v = float(np.min(s.compliance(_span(model, n[:-len(".compliance")], s), f"joints.{n}")))
        elif n == "payload.mass" and model.payload is not None:
            v = float(model.payload.mass)
        elif n.endswith(".link_scale") and n[:-len(".link_scale")] in getattr(model, "links", {}):
            v = 1.0   # the link spring as the file states it, its sag in the start
        out[n] = v
    return out


def _span(model, joint: str, spring) -> np.ndarray:
    """Joint values over which a varying spring's compliance is taken: the table's knots and the joint's
    limits (a continuous joint: one turn), 201 values between."""
    if spring.stiffness is not None:
        return np.zeros(1)
    j = model.tree.joints[model.tree.joint_index(joint)]
    lo = j.lower if np.isfinite(j.lower) else -np.pi
    hi = j.upper if np.isfinite(j.upper) else np.pi
    q = np.linspace(lo, hi, 201)
    if spring.table is not None:
        knots = np.asarray(spring.table[0], dtype=float)
        q = np.concatenate([q, knots[(knots >= lo) & (knots <= hi)]])
    return q


def totals(model, values: dict) -> dict:
    """{parameter: {"nominal": its model-file value, "total": nominal + fitted}} of the fitted ``values`` whose
    nominal value is not 0 (a report's words for them: the fitted value is the correction)."""
    nom = nominal_values(model, values)
    return {k: {"nominal": nom[k], "total": nom[k] + float(v)} for k, v in values.items() if nom[k] != 0.0}

