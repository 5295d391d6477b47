"""Serial chains as products of elementary transforms (seed eq. 1) and their Jacobians (eq. 2-5).

A :class:`Chain` is an immutable description: a product of constant 4x4
matrices and elementary factors ``kind(coef * q[var])`` (kind in Tx..Rz).
Each variable has a role:

* ``actuated``: an actuator coordinate ``q0`` carrying a 1-dof virtual spring
  ``theta0`` (``Va(q0 + theta0)``): its column belongs to ``J_theta``;
* ``passive``: an ideal passive joint: its column belongs to ``J_q``;
* ``spring``: a coordinate of a virtual spring (1-dof, or 6-dof
  ``Tx Ty Tz Rx Ry Rz`` as in eq. 18, with a full 6x6 stiffness).

A variable may appear in several factors (``coef`` = +1/-1), which is how
the parallelogram's coupled rotations ``Ry(q) Tx(L) Ry(-q)`` (eq. 20) are
written.

Twists are those of the end-effector frame, expressed in the base (world)
frame at the end-effector point: ``(dp, omega)`` with ``omega = vee(dR R^T)``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import VjmError
from .transforms import AXIS, KINDS, ROTATION, elementary, generator, vee

ROLES = ("actuated", "passive", "spring")


@dataclass(frozen=True)
class Factor:
    """One factor of the product: a constant ``T`` or ``kind(coef * q[var])``."""

    kind: str
    var: int = -1
    coef: float = 1.0
    T: np.ndarray | None = field(default=None, compare=False)


@dataclass(frozen=True)
class Spring:
    """A virtual spring acting on chain variables ``vars`` (1 or 6 of them).

    ``name`` is the key under which its compliance is supplied to the
    stiffness solver (e.g. ``"actuator"``, ``"foot"``, ``"leg"``, ``"u1"``).
    """

    name: str
    vars: tuple[int, ...]


@dataclass(frozen=True)
class Chain:
    """Immutable kinematic chain description."""

    name: str
    factors: tuple[Factor, ...]
    var_names: tuple[str, ...]
    roles: tuple[str, ...]
    springs: tuple[Spring, ...]

    @property
    def n_vars(self) -> int:
        return len(self.var_names)

    @property
    def passive(self) -> tuple[int, ...]:
        return tuple(i for i, r in enumerate(self.roles) if r == "passive")

    @property
    def actuated(self) -> tuple[int, ...]:
        return tuple(i for i, r in enumerate(self.roles) if r == "actuated")

    def index(self, name: str) -> int:
        try:
            return self.var_names.index(name)
        except ValueError:
            raise VjmError(f"chain {self.name!r} has no variable {name!r}") from None

    def spring(self, name: str) -> Spring:
        for s in self.springs:
            if s.name == name:
                return s
        raise VjmError(f"chain {self.name!r} has no spring {name!r}")


class ChainBuilder:
    """Write a chain left to right, as the product reads (eq. 1).

    Examples
    --------
    >>> b = ChainBuilder("x")
    >>> b.actuated("tx", "q0", spring="actuator"); b.spring6("leg"); b.const(np.eye(4))
    >>> b.build().n_vars
    7
    """

    def __init__(self, name: str):
        self.name = name
        self._factors: list[Factor] = []
        self._names: list[str] = []
        self._roles: list[str] = []
        self._springs: list[Spring] = []

    def _var(self, name: str, role: str) -> int:
        if name in self._names:
            i = self._names.index(name)
            if self._roles[i] != role:
                raise VjmError(f"chain {self.name!r}: variable {name!r} used with two roles")
            return i
        self._names.append(name)
        self._roles.append(role)
        return len(self._names) - 1

    def const(self, T) -> None:
        T = np.asarray(T, dtype=float)
        if T.shape != (4, 4):
            raise VjmError(f"chain {self.name!r}: constant factor must be 4x4, got {T.shape}")
        self._factors.append(Factor("const", T=T))

    def _joint(self, kind: str, var: int, coef: float) -> None:
        if kind not in KINDS:
            raise VjmError(f"chain {self.name!r}: unknown elementary transform {kind!r}")
        self._factors.append(Factor(kind, var, float(coef)))

    def actuated(self, kind: str, name: str, spring: str = "actuator") -> None:
        """Actuated joint ``kind(q0 + theta0)`` with its 1-dof spring named ``spring``."""
        i = self._var(name, "actuated")
        self._joint(kind, i, 1.0)
        self._springs.append(Spring(spring, (i,)))

    def passive(self, kind: str, name: str, coef: float = 1.0) -> None:
        """Ideal passive joint; reuse ``name`` with ``coef=-1`` for coupled rotations."""
        self._joint(kind, self._var(name, "passive"), coef)

    @property
    def size(self) -> int:
        """Factors written so far (the index the next one will have)."""
        return len(self._factors)

    def coupled(self, kind: str, name: str, coef: float, spring: str | None = None) -> None:
        """Another factor ``kind(coef * q)`` of the actuated variable ``name`` (a URDF mimic joint
        following its master): the variable and its spring ``spring`` are written here if the
        chain has not met them yet (a master on another branch of a tree)."""
        new = name not in self._names
        i = self._var(name, "actuated")
        self._joint(kind, i, coef)
        if new and spring is not None:
            self._springs.append(Spring(spring, (i,)))

    def spring1(self, kind: str, name: str) -> None:
        """1-dof virtual spring ``kind(theta)`` (e.g. the compliance of a joint)."""
        i = self._var(name, "spring")
        self._joint(kind, i, 1.0)
        self._springs.append(Spring(name, (i,)))

    def spring6(self, name: str) -> None:
        """6-dof virtual spring ``Tx Ty Tz Rx Ry Rz`` (eq. 18) at the current frame."""
        idx = []
        for k in KINDS:
            i = self._var(f"{name}.{k}", "spring")
            self._joint(k, i, 1.0)
            idx.append(i)
        self._springs.append(Spring(name, tuple(idx)))

    def build(self) -> Chain:
        return Chain(self.name, tuple(self._factors), tuple(self._names),
                     tuple(self._roles), tuple(self._springs))


def _as_values(chain: Chain, values) -> np.ndarray:
    v = np.asarray(values)
    if v.ndim == 1:
        v = v[None, :]
    if v.ndim != 2 or v.shape[1] != chain.n_vars:
        raise VjmError(f"chain {chain.name!r}: expected values of shape (n, {chain.n_vars}), got {np.shape(values)}")
    return v


def forward(chain: Chain, values) -> np.ndarray:
    """End transforms (n, 4, 4) of the chain for variable values (n, n_vars)."""
    v = _as_values(chain, values)
    n = v.shape[0]
    P = np.broadcast_to(np.eye(4, dtype=v.dtype), (n, 4, 4))
    for f in chain.factors:
        if f.kind == "const":
            P = P @ f.T
        else:
            a = f.coef * v[:, f.var]
            if np.any(a != 0):
                P = P @ elementary(f.kind, a)
    return np.ascontiguousarray(P)


def end_frames(chain: Chain, values) -> np.ndarray:
    """:func:`forward` for many poses: the same end transforms (n, 4, 4) to round-off, by the column
    products of :func:`_frame_product` (a few elementwise operations per factor)."""
    v = _as_values(chain, values)
    return frame_matrix(_frame_product(chain, np.ascontiguousarray(v.T, dtype=float))[0])


def _frame_product(chain: Chain, vt: np.ndarray):
    """Prefix frames of the product, pose axis last ("structure of arrays").

    The frame ``P`` (3 x 4 upper part of a homogeneous matrix) is held as four
    column arrays ``(x, y, z, o)`` of shape (3, n): right-multiplying by an
    elementary factor then touches two columns (rotation) or one (translation)
    and a constant factor is a short linear combination of columns (often a
    mere relabelling), so the product costs a few elementwise operations per
    factor instead of n small 4x4 matrix products.

    Parameters
    ----------
    vt : array (n_vars, n), float

    Returns
    -------
    cols : the four columns of the end frame
    recs : per elementary factor ``(var, kind, coef, e, o)``: the axis ``e``
        (3, n) and origin ``o`` (3, n) of the frame ``P V`` just after it
    """
    n = vt.shape[1]
    one = np.ones(n)
    zero = np.zeros(n)
    cols = [np.stack([one, zero, zero]), np.stack([zero, one, zero]), np.stack([zero, zero, one]),
            np.zeros((3, n))]
    recs = []
    for f in chain.factors:
        if f.kind == "const":
            T = f.T
            new = []
            for j in range(4):
                terms = [(k, T[k, j]) for k in range(4) if k < 3 and T[k, j] != 0.0]
                acc = cols[3] if j == 3 else None
                for k, c in terms:
                    t = cols[k] if c == 1.0 else c * cols[k]
                    acc = t if acc is None else acc + t
                new.append(acc if acc is not None else np.zeros((3, n)))
            cols = new
            continue
        ax = AXIS[f.kind]
        a = vt[f.var] if f.coef == 1.0 else f.coef * vt[f.var]
        if np.any(a != 0):
            cols = list(cols)
            if ROTATION[f.kind]:
                i, j = [(1, 2), (2, 0), (0, 1)][ax]  # plane of rotation, as transforms.elementary
                c, s = np.cos(a), np.sin(a)
                ci, cj = cols[i], cols[j]
                cols[i] = ci * c + cj * s
                cols[j] = cj * c - ci * s
            else:
                cols[3] = cols[3] + cols[ax] * a
        recs.append((f.var, f.kind, f.coef, cols[ax], cols[3]))
    return cols, recs


def _jacobian_soa(chain: Chain, vt: np.ndarray):
    """End point (3, n) and Jacobian transposed with the pose axis last, (n_vars, 6, n).

    Same closed form as :func:`jacobian` (eq. 3-5); row ``i`` of the result is
    the twist of variable ``i``, contiguous over poses.
    """
    cols, recs = _frame_product(chain, vt)
    n = vt.shape[1]
    pe = cols[3]
    Jt = np.zeros((chain.n_vars, 6, n))
    rot = [r for r in recs if ROTATION[r[1]]]
    tra = [r for r in recs if not ROTATION[r[1]]]
    seen = set()

    def put(rows, vals):
        # first occurrence of a variable is assigned, repeats (coupled factors) are added
        first = [k for k, v in enumerate(rows) if v not in seen and v not in rows[:k]]
        rest = [k for k in range(len(rows)) if k not in first]
        Jt[[rows[k] for k in first]] = vals[first]
        for k in rest:
            Jt[rows[k]] += vals[k]
        seen.update(rows)

    if rot:
        E = np.stack([r[3] for r in rot])
        D = pe - np.stack([r[4] for r in rot])
        coef = np.array([r[2] for r in rot])
        V = np.empty((len(rot), 6, n))
        V[:, 0] = E[:, 1] * D[:, 2] - E[:, 2] * D[:, 1]   # v = e x (p_end - o)
        V[:, 1] = E[:, 2] * D[:, 0] - E[:, 0] * D[:, 2]
        V[:, 2] = E[:, 0] * D[:, 1] - E[:, 1] * D[:, 0]
        V[:, 3:] = E
        if np.any(coef != 1.0):
            V *= coef[:, None, None]
        put([r[0] for r in rot], V)
    if tra:
        V = np.zeros((len(tra), 6, n))
        V[:, :3] = np.stack([r[3] for r in tra])
        coef = np.array([r[2] for r in tra])
        if np.any(coef != 1.0):
            V *= coef[:, None, None]
        put([r[0] for r in tra], V)
    return cols, Jt


def jacobian(chain: Chain, values) -> tuple[np.ndarray, np.ndarray]:
    """End transform and Jacobian of every variable, by the semi-analytic method (eq. 3-5).

    Splitting the product at a factor ``V(a)`` as ``T = P V(a) S`` and
    inserting the generator gives ``dT/da = coef * (P V) G S`` (eq. 3-4).  The
    twist is read from ``dT T^-1 = (P V) G (P V)^-1`` (eq. 5): with
    ``P V = (R, o)`` and axis ``e = R[:, axis]``, a rotation gives
    ``omega = e, v = e x (p_end - o)`` and a translation gives ``v = e``.
    This closed form of the product is what is evaluated (it needs only the
    prefix frames); :func:`jacobian_semi_analytic` multiplies the 4x4
    matrices literally and the tests check that both agree.

    Parameters
    ----------
    chain : Chain
    values : array (n, n_vars)
        Nominal values: actuator and passive coordinates from the inverse
        kinematics, 0 for spring coordinates in the linear model.

    Returns
    -------
    T : array (n, 4, 4)
    J : array (n, 6, n_vars)
        Columns ``(dx, dy, dz, rx, ry, rz)`` of the end-effector twist in the
        world frame at the end-effector point, per unit of each variable.
    """
    v = _as_values(chain, values)
    cols, Jt = _jacobian_soa(chain, np.ascontiguousarray(v.T, dtype=float))
    return frame_matrix(cols), np.ascontiguousarray(Jt.transpose(2, 1, 0))


def frame_matrix(cols) -> np.ndarray:
    """Homogeneous matrices (n, 4, 4) from the column arrays of :func:`_frame_product`."""
    n = cols[0].shape[1]
    T = np.zeros((n, 4, 4))
    for j in range(4):
        T[:, :3, j] = cols[j].T
    T[:, 3, 3] = 1.0
    return T


def jacobian_semi_analytic(chain: Chain, values) -> np.ndarray:
    """Literal eq. 3-5: ``dT = coef * P V G S`` and read ``(dT[:3,3], vee(dT[:3,:3] R^T))``.

    Reference implementation (slower): kept to show that :func:`jacobian`
    evaluates exactly the seed's product.
    """
    v = _as_values(chain, values)
    n = v.shape[0]
    mats = []
    for f in chain.factors:
        if f.kind == "const":
            mats.append(np.broadcast_to(f.T, (n, 4, 4)))
        else:
            mats.append(elementary(f.kind, f.coef * v[:, f.var]))
    m = len(mats)
    pre: list = [None] * m
    P = np.broadcast_to(np.eye(4), (n, 4, 4))
    for k in range(m):
        P = P @ mats[k]
        pre[k] = P
    suf: list = [None] * m
    S = np.broadcast_to(np.eye(4), (n, 4, 4))
    for k in range(m - 1, -1, -1):
        suf[k] = S
        S = mats[k] @ S
    T = pre[-1]
    J = np.zeros((n, 6, chain.n_vars))
    for k, f in enumerate(chain.factors):
        if f.kind == "const":
            continue
        dT = f.coef * (pre[k] @ generator(f.kind) @ suf[k])
        J[:, :3, f.var] += dT[:, :3, 3]
        J[:, 3:, f.var] += vee(dT[:, :3, :3] @ np.swapaxes(T[:, :3, :3], 1, 2))
    return J
