"""Orthoglide 3-PUU (seed eq. 15-19) and 3-PRPaR (eq. 20-22).

World frame: origin at the end-effector point in the isotropic posture
(legs mutually perpendicular and parallel to the prismatic axes), axes along
the three actuators.  Chain ``i`` in {x, y, z} reads (eq. 1)::

    T_base^i Tx(q0 + theta0) T_foot Vs(foot) Rz(q1) Ry(q2) Tx(L) Vs(leg) Ry(q3) Rz(q4) T_tool^i

with ``T_foot = I`` (eq. 17).  ``T_base^i`` and ``T_tool^i`` are eq. 15-16
(the last matrix printed as ``T_base^z`` in eq. 16 is ``T_tool^z``).  Rigid
inverse kinematics: ``q3 = -q2, q4 = -q1`` (the platform only translates).

Spring frames (each a 6-dof spring ``Tx Ty Tz Rx Ry Rz``, compliance order
Fx..Mz):

* foot: at the carriage, on the actuator axis where the leg's first joint
  sits, axes of the chain base (x along the actuator axis);
* leg (3-PUU): at the leg's distal end, before the second U joint, x along
  the leg, y along the first U joint's second axis;
* leg (3-PRPaR): the parallelogram spring of eq. 20 at the middle of its
  distal link, axes parallel to the parallelogram's base link; its stiffness
  is computed at each posture from the two bars (``leg`` then gives ONE
  bar's compliance in the bar's tip frame).

With ``joints.passive_stiffness`` each U joint gets a 1-dof spring about its
constrained direction (``Rz(q1) Rx(.) Ry(q2)`` and ``Ry(q3) Rx(.) Rz(q4)``)
and each revolute of the 3-PRPaR gets two (about its two perpendicular axes).
"""
from __future__ import annotations

import numpy as np

from ..errors import VjmError
from ..kinematics.chain import ChainBuilder
from ..kinematics.transforms import homogeneous
from .base import ACTUATOR, FOOT, LEG, Architecture, actuator_compliance, as_points, joint_spring_compliance
from .parallelogram import PARALLELOGRAM_JOINT_SPRINGS, add_parallelogram_leg, parallelogram_leg_compliances

#: rotation part of T_base^i (columns: chain x, y, z axes in world), eq. 15-16
BASE_R = {
    "x": np.eye(3),
    "y": np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
    "z": np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]),
}
CHAINS = ("x", "y", "z")
#: 1-dof springs of the two U joints of a 3-PUU leg (with ``joints.passive_stiffness``)
U_JOINT_SPRINGS = ("u1", "u2")


def base_transform(i: str, L: float, r: float) -> np.ndarray:
    R = BASE_R[i]
    return homogeneous(R, R @ np.array([-L - r, 0.0, 0.0]))


def tool_transform(i: str, r: float) -> np.ndarray:
    # T_tool^i brings the end frame back to world axes: R_base R_tool = I
    return homogeneous(BASE_R[i].T, (r, 0.0, 0.0))


def _reach(model, P):
    L, r = model.geometry["L"], model.geometry["r"]
    ok = np.ones(len(P), dtype=bool)
    for i in CHAINS:
        R = BASE_R[i]
        loc = (P - R @ np.array([-L - r, 0.0, 0.0])) @ R
        ok &= (loc[:, 1] ** 2 + loc[:, 2] ** 2) / L**2 <= 1.0 + 1e-12
    return ok


def _leg_ik(model, P):
    """Chain-local leg direction and actuator coordinate for each chain: u (n,3,3), q0 (n,3)."""
    L, r = model.geometry["L"], model.geometry["r"]
    P = as_points(P)
    n = P.shape[0]
    u = np.empty((n, 3, 3))
    q0 = np.empty((n, 3))
    for k, i in enumerate(CHAINS):
        R = BASE_R[i]
        # R^T (P - t) column by column: R is a permutation, so this is mostly relabelling
        d = P - R @ np.array([-L - r, 0.0, 0.0])
        loc = [sum(d[:, a] * R[a, j] for a in range(3) if R[a, j] != 0.0) for j in range(3)]
        uy, uz = loc[1] / L, loc[2] / L
        ux2 = 1.0 - uy**2 - uz**2
        bad = ux2 < -1e-12
        if np.any(bad):
            p = P[np.argmax(bad)]
            raise VjmError(f"pose ({p[0]:.6g}, {p[1]:.6g}, {p[2]:.6g}) mm is unreachable: the {i} leg "
                           f"(length L = {L:g} mm) cannot reach it")
        ux = np.sqrt(np.clip(ux2, 0.0, None))
        u[:, k, 0], u[:, k, 1], u[:, k, 2] = ux, uy, uz
        q0[:, k] = loc[0] - r - L * ux
    return u, q0


def _actuated_foot(i: str, L: float, r: float) -> ChainBuilder:
    """Chain ``i`` up to the carriage (eq. 17): base, prismatic actuator with its spring, foot spring."""
    b = ChainBuilder(i)
    b.const(base_transform(i, L, r))
    b.actuated("tx", "q0")
    b.spring6(FOOT)
    return b


class OrthoglidePUU(Architecture):
    name = "orthoglide-3PUU"
    springs: tuple[str, ...] = (ACTUATOR, FOOT, LEG) + U_JOINT_SPRINGS
    geometry_keys: tuple[str, ...] = ("L", "r")
    #: the Orthoglide's Cartesian workspace cube, Q1 to Q2 (seed Fig. 4c)
    workspace = ((-73.65,) * 3, (126.35,) * 3)
    #: the seed's named points (its Table 1, data/seed_table1.csv): the isotropic posture and the cube's corners
    landmarks = {"Q0 isotropic": (0.0, 0.0, 0.0), "Q1": (-73.65,) * 3, "Q2": (126.35,) * 3}

    def reachable(self, model, P):
        return _reach(model, as_points(P))

    def chains(self, model):
        L, r = model.geometry["L"], model.geometry["r"]
        js = model.joints.passive_stiffness is not None
        out = []
        for i in CHAINS:
            b = _actuated_foot(i, L, r)
            b.passive("rz", "q1")
            if js:
                b.spring1("rx", U_JOINT_SPRINGS[0])
            b.passive("ry", "q2")
            b.const(homogeneous(p=(L, 0.0, 0.0)))
            b.spring6(LEG)
            b.passive("ry", "q3")
            if js:
                b.spring1("rx", U_JOINT_SPRINGS[1])
            b.passive("rz", "q4")
            b.const(tool_transform(i, r))
            out.append(b.build())
        return tuple(out)

    def inverse_kinematics(self, model, P):
        u, q0 = _leg_ik(model, P)
        q1 = np.arctan2(u[..., 1], u[..., 0])
        q2 = -np.arcsin(np.clip(u[..., 2], -1.0, 1.0))
        # rigid posture: q3 = -q2 and q4 = -q1 keep the platform's orientation (seed 4.1); the
        # parallelogram legs of the 3-PRPaR have no q3 (eq. 20 couples it to q2)
        vals = []
        for k, ch in enumerate(model.chains):
            v = np.zeros((q0.shape[0], ch.n_vars))
            for name, val in (("q0", q0[:, k]), ("q1", q1[:, k]), ("q2", q2[:, k]),
                              ("q3", -q2[:, k]), ("q4", -q1[:, k])):
                if name in ch.var_names:
                    v[:, ch.index(name)] = val
            vals.append(v)
        return q0, vals

    def compliances(self, model, P, chain_values, q_act):
        cj = joint_spring_compliance(model)
        out = []
        for k in range(3):
            d = {ACTUATOR: actuator_compliance(model, q_act[:, k])}
            if model.foot.compliance is not None:
                d[FOOT] = model.foot.compliance
            if model.leg.compliance is not None:
                d[LEG] = model.leg.compliance
            if cj is not None:
                for s in U_JOINT_SPRINGS:
                    d[s] = cj
            out.append(d)
        return out


class OrthoglidePRPaR(OrthoglidePUU):
    """The 3-PUU with parallelogram legs (same actuators, workspace and leg inverse kinematics)."""

    name = "orthoglide-3PRPaR"
    geometry_keys = ("L", "r", "d")
    leg_bars = 2
    springs: tuple[str, ...] = (ACTUATOR, FOOT, LEG) + PARALLELOGRAM_JOINT_SPRINGS

    def chains(self, model):
        L, r = model.geometry["L"], model.geometry["r"]
        js = model.joints.passive_stiffness is not None
        out = []
        for i in CHAINS:
            b = _actuated_foot(i, L, r)
            add_parallelogram_leg(b, L, js, last="q4")
            b.const(tool_transform(i, r))
            out.append(b.build())
        return tuple(out)

    def compliances(self, model, P, chain_values, q_act):
        return parallelogram_leg_compliances(model, chain_values, q_act)
