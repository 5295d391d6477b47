"""Parallelogram stiffness (seed eq. 20-22) from its two bar chains, and the seed's closed form.

Geometry (eq. 21-22): two bars of length ``L`` at ``z = -d/2`` ("up") and
``z = +d/2`` ("down") of the parallelogram's base frame, each between two
pivots of axis y.  The parallelogram angle ``q`` rotates the bars about y;
the distal link stays parallel to the base link.  Each bar is a 6-dof
spring (its compliance in its tip frame: origin at the bar's distal end,
x along the bar, as eq. 14 and linkfea) followed by the distal pivot.

The result is the stiffness at the middle of the distal link in the
*base* axes: exactly the spring ``V_s(theta_7..12)`` of eq. 20, which sits
after ``Ry(q) Tx(L) Ry(-q)``.  Its one zero direction is the
parallelogram's own mobility (translation along ``(-sin q, 0, -cos q)``).
"""
from __future__ import annotations

import functools

import numpy as np

from ..errors import VjmError
from ..kinematics.chain import ChainBuilder, jacobian
from ..kinematics.transforms import homogeneous
from ..memo import Recent
from ..stiffness.linalg import cholesky, lower_inverse
from ..stiffness.linear import chain_stiffness
from .base import ACTUATOR, FOOT, LEG, actuator_compliance, joint_spring_compliance

#: 1-dof springs of a parallelogram leg's end revolutes (with ``joints.passive_stiffness``)
PARALLELOGRAM_JOINT_SPRINGS = ("r1x", "r1y", "r2x", "r2y")


def _tz(a):
    return homogeneous(p=(0.0, 0.0, a))


@functools.lru_cache(maxsize=8)
def bar_chains(L: float, d: float):
    """The "up" and "down" chains of eq. 21-22 (variables: pivots p1, p2 and the bar spring)."""
    out = []
    for name, z in (("up", -d / 2.0), ("dn", d / 2.0)):
        b = ChainBuilder(f"parallelogram.{name}")
        b.const(_tz(z))
        b.passive("ry", "p1")
        b.const(homogeneous(p=(L, 0.0, 0.0)))
        b.spring6("bar")
        b.passive("ry", "p2")
        b.const(_tz(-z))
        out.append(b.build())
    return tuple(out)


def parallelogram_stiffness(C_bar, L: float, d: float, q) -> tuple[np.ndarray, np.ndarray]:
    """Numerical parallelogram stiffness from the up and down chains (eq. 21-22 -> eq. 11, 13).

    Parameters
    ----------
    C_bar : (6, 6) compliance of one bar in its tip frame (mm/N, rad/(N mm))
    L, d : bar length and distance between the bars, mm
    q : (n,) parallelogram angles, rad

    Returns
    -------
    K : (n, 6, 6) stiffness at the middle of the distal link, base axes
    rank : (n, 2) rank of each bar chain's pivot Jacobian
    """
    q = np.atleast_1d(np.asarray(q, dtype=float))
    Ks, ranks = [], []
    for ch, J in zip(bar_chains(L, d), _bar_jacobians(float(L), float(d), q)):
        K, r = chain_stiffness(ch, J, {"bar": np.asarray(C_bar, dtype=float)})
        Ks.append(K)
        ranks.append(r)
    return Ks[0] + Ks[1], np.stack(ranks, axis=1)


#: the bar chains' Jacobians of the last angle sets: a fit of a bar's compliance evaluates the same
#: poses again and again, and the Jacobians (half of a parallelogram's cost) depend on the angles only
_JACOBIANS = Recent(8)
#: ... kept for angle sets of at most this many poses (a large map computes them once anyway)
JACOBIAN_MEMO_POSES = 4096


def _recent(memo: Recent, key, q: np.ndarray, compute):
    """``compute()``, kept in ``memo`` under ``key`` for angle sets q of at most JACOBIAN_MEMO_POSES."""
    return memo.get(key, compute) if q.size <= JACOBIAN_MEMO_POSES else compute()


def _bar_jacobians(L: float, d: float, q: np.ndarray) -> tuple:
    """The Jacobians of :func:`bar_chains` at parallelogram angles q (read-only arrays, memoized)."""
    def compute():
        out = []
        for ch in bar_chains(L, d):
            v = np.zeros((q.size, ch.n_vars))
            v[:, ch.index("p1")] = q
            v[:, ch.index("p2")] = -q
            J = jacobian(ch, v)[1]
            J.flags.writeable = False
            out.append(J)
        return tuple(out)

    return _recent(_JACOBIANS, (L, d, q.tobytes()), q, compute)


def mobility_direction(q) -> np.ndarray:
    """Unit twist (n, 6) of the parallelogram's own motion, base axes at the distal middle."""
    q = np.atleast_1d(np.asarray(q, dtype=float))
    m = np.zeros((q.size, 6))
    m[:, 0] = -np.sin(q)
    m[:, 2] = -np.cos(q)
    return m


def parallelogram_compliance(K: np.ndarray, q) -> np.ndarray:
    """Pseudo-inverse of the rank-5 parallelogram stiffness (n, 6, 6).

    Along its mobility the parallelogram offers no stiffness; in a chain that
    direction is carried by the passive joint ``q`` (eq. 20), which makes the
    spring's compliance there irrelevant, so the exact pseudo-inverse is used:
    ``C = (K + k m m^T)^-1 - m m^T / k`` for any ``k > 0``.
    """
    m = mobility_direction(q)
    k = np.trace(K[:, :3, :3], axis1=1, axis2=2) / 3.0
    mm = m[:, :, None] * m[:, None, :]
    B = lower_inverse(cholesky(K + k[:, None, None] * mm))
    C = np.swapaxes(B, 1, 2) @ B - mm / k[:, None, None]
    return 0.5 * (C + np.swapaxes(C, 1, 2))


def closed_form(K_bar, d: float, q) -> np.ndarray:
    """The seed's analytic K_Plg (section 4.2), in the bar frame, shape (n, 6, 6).

    The bar frame has its origin at the middle of the distal link, x along the
    bars, y along the pivot axes (so z is the parallelogram's mobility, whose
    row and column are zero).  ``K_ij`` are entries of one bar's 6x6 stiffness
    ``inv(C_bar)`` in its tip frame.
    """
    Kb = np.asarray(K_bar, dtype=float)
    q = np.atleast_1d(np.asarray(q, dtype=float))
    c, s, s2 = np.cos(q), np.sin(q), np.sin(2 * q)
    K = np.zeros((q.size, 6, 6))
    K[:, 0, 0] = Kb[0, 0]
    K[:, 1, 1] = Kb[1, 1]
    K[:, 1, 5] = K[:, 5, 1] = Kb[1, 5]
    K[:, 3, 3] = Kb[3, 3] + d**2 * c**2 * Kb[1, 1] / 4.0
    K[:, 3, 5] = K[:, 5, 3] = d**2 * s2 * Kb[1, 1] / 8.0
    K[:, 4, 4] = d**2 * c**2 * Kb[0, 0] / 4.0
    K[:, 5, 5] = Kb[5, 5] + d**2 * s**2 * Kb[1, 1] / 4.0
    return 2.0 * K


def add_parallelogram_leg(b: ChainBuilder, L: float, joint_springs: bool, last: str) -> None:
    """Append a parallelogram leg (seed eq. 20) to a chain: the first joint's two rotations
    ``Rz(q1) Ry(q2)``, ``Tx(L) Ry(-q2)`` with the equivalent 6-dof spring ``leg`` in base axes,
    then ``Rz(last)``.  With ``joint_springs`` each end gets 1-dof springs about the two axes
    its rotations leave constrained (``r1x, r1y`` and ``r2x, r2y``)."""
    r1x, r1y, r2x, r2y = PARALLELOGRAM_JOINT_SPRINGS
    b.passive("rz", "q1")
    if joint_springs:
        b.spring1("rx", r1x)
        b.spring1("ry", r1y)
    b.passive("ry", "q2")
    b.const(homogeneous(p=(L, 0.0, 0.0)))
    b.passive("ry", "q2", coef=-1.0)
    b.spring6(LEG)
    b.passive("rz", last)
    if joint_springs:
        b.spring1("rx", r2x)
        b.spring1("ry", r2y)


#: the parallelogram compliances of the last bar compliances and angle sets: a fit that changes other
#: springs (the actuators, a foot, joint springs, an additive term) evaluates the same legs again
_LEGS = Recent(8)


def _leg_compliance(C_bar: np.ndarray, L: float, d: float, q: np.ndarray) -> np.ndarray:
    """The legs' equivalent compliance (n, 6, 6) from bar compliance ``C_bar`` at angles q (read-only, memoized)."""
    def compute():
        C = parallelogram_compliance(parallelogram_stiffness(C_bar, L, d, q)[0], q)
        C.flags.writeable = False
        return C

    return _recent(_LEGS, (C_bar.tobytes(), L, d, q.tobytes()), q, compute)


def parallelogram_leg_compliances(model, chain_values, q_act) -> list[dict]:
    """Per chain, the spring compliances of a machine with parallelogram legs (3-PRPaR, Delta):
    the actuator, the foot, the leg's equivalent spring from its two bars at the chain's
    parallelogram angle ``q2`` (eq. 20-22) and the optional joint springs."""
    if model.leg.compliance is None:
        raise VjmError("leg: a parallelogram leg needs compliant bars (rigid: true would leave its "
                       "stiffness undefined); give the bar's compliance")
    L, d = model.geometry["L"], model.geometry["d"]
    cj = joint_spring_compliance(model)
    # the chains' angles in one batch: the same arithmetic pose by pose, a third of the calls (a fit
    # evaluates this thousands of times on a few postures, where the calls' overhead is the cost)
    qs = [chain_values[k][:, ch.index("q2")] for k, ch in enumerate(model.chains)]
    q_all = np.concatenate(qs)
    legs = np.split(_leg_compliance(np.asarray(model.leg.compliance, dtype=float), float(L), float(d), q_all),
                    np.cumsum([len(q) for q in qs])[:-1])
    out = []
    for k in range(len(model.chains)):
        dct = {ACTUATOR: actuator_compliance(model, q_act[:, k]), LEG: legs[k]}
        if model.foot.compliance is not None:
            dct[FOOT] = model.foot.compliance
        if cj is not None:
            for s in PARALLELOGRAM_JOINT_SPRINGS:
                dct[s] = cj
        out.append(dct)
    return out
