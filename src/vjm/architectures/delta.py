"""Delta 3-RRPaR: rotary actuators, parallelogram legs (seed section 2.1, Fig. 2b).

World frame: origin at the centre of the base, z up.  Chain ``i`` sits at
angle ``phi_i = 0, 120, 240`` deg around z; its local frame has x radial
(outward), z tangent (the actuator axis) and y = z x x pointing down.  The
chain reads::

    T_base^i Rz(q0 + theta0) Tx(arm) Vs(foot) Rz(q1) Ry(q2) Tx(L) Ry(-q2) Vs(leg) Rz(q3) Tx(-r)

The arm (``foot``) turns about the actuator axis; the revolutes ``q1`` and
``q3`` are parallel to it; the parallelogram (bars offset by ``d`` along the
actuator axis, pivots about local y) keeps the platform parallel to the
base; ``q3 = -(q0 + q1)``.  Geometry: ``R`` base radius, ``arm`` arm length,
``L`` bar length, ``d`` bar spacing, ``r`` platform radius, all mm.
Actuator stiffness is rotary, N mm/rad.  Spring frames: foot at the arm's
tip with x along the arm; leg as the 3-PRPaR parallelogram.
"""
from __future__ import annotations

import numpy as np

from ..errors import VjmError
from ..kinematics.chain import ChainBuilder
from ..kinematics.transforms import homogeneous
from .base import FOOT, Architecture, as_points
from .parallelogram import PARALLELOGRAM_JOINT_SPRINGS, add_parallelogram_leg, parallelogram_leg_compliances

PHI = (0.0, 2 * np.pi / 3, 4 * np.pi / 3)


def base_rotation(phi: float) -> np.ndarray:
    x = np.array([np.cos(phi), np.sin(phi), 0.0])
    z = np.array([-np.sin(phi), np.cos(phi), 0.0])
    return np.stack([x, np.cross(z, x), z], axis=1)


def _arm_geometry(g, P, R):
    """Chain-base coordinates ``b`` of the platform joint, the leg's out-of-plane sine ``sz``, the
    in-plane distance ``Rb`` and ``kap = Rb cos(angle between arm and b)`` (law of cosines)."""
    b = (P - R[:, 0] * g["R"]) @ R
    b[:, 0] += g["r"]
    sz = b[:, 2] / g["L"]
    rho = g["L"] * np.sqrt(np.clip(1.0 - sz**2, 0.0, None))
    Rb = np.hypot(b[:, 0], b[:, 1])
    kap = (Rb**2 + g["arm"] ** 2 - rho**2) / (2.0 * g["arm"])
    return b, sz, Rb, kap


class DeltaRRPaR(Architecture):
    name = "delta-3RRPaR"
    geometry_keys = ("L", "r", "d", "R", "arm")
    actuator_unit = "N mm/rad"
    leg_bars = 2
    springs: tuple[str, ...] = Architecture.springs + PARALLELOGRAM_JOINT_SPRINGS
    workspace = ((-150.0, -150.0, -600.0), (150.0, 150.0, -350.0))

    def reachable(self, model, P):
        P = as_points(P)
        ok = np.ones(len(P), dtype=bool)
        for phi in PHI:
            _, sz, Rb, kap = _arm_geometry(model.geometry, P, base_rotation(phi))
            ok &= (np.abs(sz) <= 1.0 + 1e-12) & (np.abs(kap) <= (1.0 + 1e-12) * Rb)
        return ok

    def chains(self, model):
        g = model.geometry
        js = model.joints.passive_stiffness is not None
        out = []
        for k, phi in enumerate(PHI):
            R = base_rotation(phi)
            b = ChainBuilder(f"arm{k + 1}")
            b.const(homogeneous(R, R[:, 0] * g["R"]))
            b.actuated("rz", "q0")
            b.const(homogeneous(p=(g["arm"], 0.0, 0.0)))
            b.spring6(FOOT)
            add_parallelogram_leg(b, g["L"], js, last="q3")
            b.const(homogeneous(p=(-g["r"], 0.0, 0.0)))
            out.append(b.build())
        return tuple(out)

    def inverse_kinematics(self, model, P):
        g = model.geometry
        P = as_points(P)
        n = P.shape[0]
        q0 = np.empty((n, 3))
        vals = []
        for k, (phi, ch) in enumerate(zip(PHI, model.chains)):
            b, sz, Rb, kap = _arm_geometry(g, P, base_rotation(phi))
            ratio = kap / np.where(Rb > 0, Rb, 1e-300)
            bad = (np.abs(sz) > 1.0 + 1e-12) | (np.abs(ratio) > 1.0 + 1e-12)
            if np.any(bad):
                p = P[np.argmax(bad)]
                raise VjmError(f"pose ({p[0]:.6g}, {p[1]:.6g}, {p[2]:.6g}) mm is unreachable by Delta arm {k + 1}")
            beta = np.arctan2(b[:, 1], b[:, 0])
            a = np.arccos(np.clip(ratio, -1.0, 1.0))
            c1, c2 = beta - a, beta + a
            # elbow out: the arm tip farther from the machine axis
            t = np.where(np.cos(c1) >= np.cos(c2), c1, c2)
            E = g["arm"] * np.stack([np.cos(t), np.sin(t)], axis=1)
            th = np.arctan2(b[:, 1] - E[:, 1], b[:, 0] - E[:, 0])
            v = np.zeros((n, ch.n_vars))
            v[:, ch.index("q0")] = t
            v[:, ch.index("q1")] = th - t
            v[:, ch.index("q2")] = -np.arcsin(np.clip(sz, -1.0, 1.0))
            v[:, ch.index("q3")] = -th
            q0[:, k] = t
            vals.append(v)
        return q0, vals

    def compliances(self, model, P, chain_values, q_act):
        return parallelogram_leg_compliances(model, chain_values, q_act)
