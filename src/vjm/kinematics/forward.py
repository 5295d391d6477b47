"""Forward kinematics of a parallel machine: the platform pose at given actuator values.

Every chain of a parallel machine ends on the platform frame ``X`` (its last factors are the inverse of
its platform attachment, :mod:`vjm.architectures.described`).  With the actuators given, the unknowns
are each chain's passive coordinates and the platform pose (its position, and its rotation for a 6-dof
platform; a 3-dof platform keeps the seed's orientation), the equations each chain's closure
``E_k(v_k, a_k) = X``: the position error (mm) and the orientation error ``vee(R_k R^T)`` (rad, times
the machines' size ``ell`` so both count in mm).  A 6-UPS hexapod has 36 unknowns and 36 equations, a
3-PUU 15 unknowns and 18 consistent equations: Gauss-Newton (a pseudo-inverse per row, batched over the
rows) is Newton's step on the square system and the least-squares one on the other.

The Jacobian's columns are the chains' own twist columns (eq. 3-5 of :func:`vjm.kinematics.chain.jacobian`:
the end frame's twist at its point, world frame), minus the platform's twist; the platform's rotation is
updated on the left (``R <- exp(dw) R``).  The same linearisation at a solution gives the derivative of
the platform pose by the actuator values and by a translation of each chain's base (implicit
differentiation of the closure, :func:`sensitivities`).

Rows are started from a given state (the seed posture's, or a previous solution); a row whose Newton
iteration does not close is continued along the straight path of actuator values from the start's
(``PATH_STEPS`` steps, each started from the previous one), which keeps it on the start's assembly branch;
a row that still does not close is flagged (``ok`` False).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import VjmError
from .chain import forward, jacobian
from .ik import CLOSE_TOL, MAX_STEP, PATH_STEPS, STALL_TOL, _step_limits, chain_size
from .poses import rotation_matrix
from .transforms import vee

#: Newton iterations per start.  The step limit (MAX_STEP), the closure and stall tolerances and the
#: continuation's PATH_STEPS are the inverse kinematics' (:mod:`vjm.kinematics.ik`).
MAX_ITER = 30


@dataclass(frozen=True, eq=False)
class Assembly:
    """A parallel machine's chains prepared for the forward kinematics: the chains, the platform's
    ``dof`` (3: orientation fixed at ``R0``; 6), the size ``ell`` (mm), each chain's passive variables
    (indices) and actuated variable, and the seed state (actuator values ``q0`` (nc,), passive values
    ``v0`` (np,) and platform frame ``X0`` (4, 4))."""

    chains: tuple
    dof: int
    R0: np.ndarray
    ell: float
    passive: tuple
    actuated: tuple
    q0: np.ndarray
    v0: np.ndarray
    X0: np.ndarray

    @property
    def n_chains(self) -> int:
        return len(self.chains)

    @property
    def n_passive(self) -> int:
        return sum(len(p) for p in self.passive)

    @property
    def n_unknowns(self) -> int:
        return self.n_passive + self.dof


@dataclass(frozen=True, eq=False)
class State:
    """A solution of the closure per row: passive values ``v`` (n, np), platform frames ``X`` (n, 4, 4),
    closed mask ``ok`` (n,) and closure error ``err`` (n,) mm."""

    v: np.ndarray
    X: np.ndarray
    ok: np.ndarray
    err: np.ndarray

    def rows(self, mask) -> "State":
        return State(self.v[mask], self.X[mask], self.ok[mask], self.err[mask])


def actuator_names(model) -> tuple:
    """The actuated variables of a parallel machine, ``<chain>.<variable>`` (e.g. ``A1.l``), chain order."""
    out = []
    for ch in model.chains:
        if len(ch.actuated) != 1:
            raise VjmError(f"chain {ch.name} has {len(ch.actuated)} actuated variables; the forward kinematics "
                           f"takes one per chain")
        out.append(f"{ch.name}.{ch.var_names[ch.actuated[0]]}")
    return tuple(out)


def seed_pose(model) -> np.ndarray:
    """The platform frame (4, 4) the forward kinematics starts from: the description's seed posture, or
    the centre of the workspace box of a built-in architecture."""
    from ..modelio.description import seed_frame
    from .poses import as_poses

    if getattr(model, "description", None) is not None:
        return seed_frame(model.description)
    lo, hi = model.workspace.lo, model.workspace.hi
    return as_poses(0.5 * (np.asarray(lo, float) + np.asarray(hi, float)), model.dof)[0]


def assembly(model) -> Assembly:
    """The :class:`Assembly` of a parallel machine (its seed state from the inverse kinematics at
    :func:`seed_pose`)."""
    actuator_names(model)
    chains = tuple(model.chains)
    X0 = seed_pose(model)
    kin = model.kinematics(X0[None] if model.dof == 6 else X0[None, :3, 3])
    passive = tuple(tuple(ch.passive) for ch in chains)
    v0 = np.concatenate([kin.values[k][0, list(p)] for k, p in enumerate(passive)])
    ell = max(chain_size(ch) for ch in chains)
    return Assembly(chains, int(model.dof), X0[:3, :3].copy(), ell, passive,
                    tuple(ch.actuated[0] for ch in chains), kin.q[0].copy(), v0, X0)


def seed_state(asm: Assembly, n: int) -> State:
    """The seed state repeated for ``n`` rows."""
    return State(np.tile(asm.v0, (n, 1)), np.tile(asm.X0, (n, 1, 1)), np.ones(n, bool), np.zeros(n))


def _values(asm: Assembly, k: int, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Chain k's variable values (n, n_vars): its passives from ``v``, its actuator from ``q``, springs 0."""
    ch = asm.chains[k]
    start = sum(len(p) for p in asm.passive[:k])
    out = np.zeros((len(q), ch.n_vars))
    out[:, list(asm.passive[k])] = v[:, start:start + len(asm.passive[k])]
    out[:, asm.actuated[k]] = q[:, k]
    return out


def linearize(asm: Assembly, q: np.ndarray, v: np.ndarray, X: np.ndarray, shift: np.ndarray | None = None):
    """The closure's residual r (n, 6 nc) mm, its Jacobian A (n, 6 nc, nu) by the unknowns (passives,
    then the platform's dp and, for 6 dof, dw) and Ba (n, 6 nc, nc) by the actuator values, at actuator
    values ``q`` (n, nc), passives ``v`` and platform frames ``X``; ``shift`` (nc, 3) mm translates each
    chain's base (world frame).  Rotation rows are scaled by ``ell``."""
    n, nc, ell = len(q), asm.n_chains, asm.ell
    A = np.zeros((n, 6 * nc, asm.n_unknowns))
    Ba = np.zeros((n, 6 * nc, nc))
    r = np.empty((n, 6 * nc))
    col = 0
    for k, ch in enumerate(asm.chains):
        E, J = jacobian(ch, _values(asm, k, q, v))
        rows = slice(6 * k, 6 * k + 6)
        p = E[:, :3, 3] + (0.0 if shift is None else shift[k])
        r[:, 6 * k:6 * k + 3] = p - X[:, :3, 3]
        r[:, 6 * k + 3:6 * k + 6] = ell * vee(E[:, :3, :3] @ np.swapaxes(X[:, :3, :3], 1, 2))
        J = J.copy()
        J[:, 3:] *= ell
        m = len(asm.passive[k])
        A[:, rows, col:col + m] = J[:, :, list(asm.passive[k])]
        Ba[:, rows, k] = J[:, :, asm.actuated[k]]
        col += m
        A[:, 6 * k:6 * k + 3, asm.n_passive:asm.n_passive + 3] = -np.eye(3)
        if asm.dof == 6:
            A[:, 6 * k + 3:6 * k + 6, asm.n_passive + 3:] = -ell * np.eye(3)
    return r, A, Ba


def lstsq(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """The least-squares solutions (n, nu, k) of A x = B, A (n, m, nu), B (n, m, k): the normal equations of
    the unit-norm columns, batched (an LU per row: the SVD of a pseudo-inverse costs ten times more); the
    closure's Jacobian has full column rank off singular postures.  A square system is solved as it is."""
    if A.shape[1] == A.shape[2]:
        return np.linalg.solve(A, B)
    s = np.maximum(np.linalg.norm(A, axis=1), 1e-300)[:, None, :]
    As = A / s
    At = np.swapaxes(As, 1, 2)
    H = At @ As
    H[:, np.arange(H.shape[1]), np.arange(H.shape[1])] *= 1.0 + 1e-13
    return np.linalg.solve(H, At @ B) / np.swapaxes(s, 1, 2)


def _step(asm: Assembly, v, X, dz):
    """The state after the step ``dz`` (n, nu), limited to MAX_STEP (rad, or times ``ell`` for lengths)."""
    big = np.max(np.abs(dz) / _limits(asm), axis=1)
    dz = dz * np.where(big > 1.0, 1.0 / np.maximum(big, 1.0), 1.0)[:, None]
    v2 = v + dz[:, :asm.n_passive]
    X2 = X.copy()
    X2[:, :3, 3] += dz[:, asm.n_passive:asm.n_passive + 3]
    if asm.dof == 6:
        X2[:, :3, :3] = rotation_matrix(dz[:, asm.n_passive + 3:]) @ X[:, :3, :3]
    return v2, X2


def _limits(asm: Assembly) -> np.ndarray:
    """The largest step of each unknown: the passives' as the inverse kinematics limits them, then the
    platform's translation (times ``ell``) and rotation (rad)."""
    lim = [_step_limits(ch, asm.passive[k], asm.ell) for k, ch in enumerate(asm.chains)]
    return np.concatenate(lim + [np.full(3, MAX_STEP * asm.ell), np.full(asm.dof - 3, MAX_STEP)])


def newton(asm: Assembly, q: np.ndarray, start: State, shift=None, max_iter: int = MAX_ITER) -> State:
    """Gauss-Newton on the closure from ``start`` at actuator values ``q`` (n, nc): the :class:`State`."""
    v, X = start.v.copy(), start.X.copy()
    n = len(q)
    ok = np.zeros(n, bool)
    err = np.full(n, np.inf)
    live = np.arange(n)
    prev = np.full(n, np.inf)
    for it in range(max_iter + 1):
        r, A, _ = linearize(asm, q[live], v[live], X[live], shift)
        e = np.max(np.abs(r), axis=1)
        err[live] = e
        done = (e <= CLOSE_TOL * asm.ell) | ((e <= STALL_TOL * asm.ell) & (e >= 0.5 * prev[live]))
        ok[live[done]] = True
        if it == max_iter:
            ok[live] |= e <= STALL_TOL * asm.ell
            break
        prev[live] = e
        keep = ~done & np.isfinite(e)
        live, r, A = live[keep], r[keep], A[keep]
        if not live.size:
            break
        dz = -lstsq(A, r[:, :, None])[:, :, 0]
        v[live], X[live] = _step(asm, v[live], X[live], dz)
    return State(v, X, ok, err)


def solve(asm: Assembly, q, start: State | None = None, shift=None) -> State:
    """The platform frames at actuator values ``q`` (n, nc), from ``start`` (default: the seed state),
    rows left open continued along the path of actuator values from the start's (module docstring)."""
    q = np.asarray(q, dtype=float)
    if q.ndim != 2 or q.shape[1] != asm.n_chains:
        raise VjmError(f"actuator values must have shape (n, {asm.n_chains}), got {q.shape}")
    start = seed_state(asm, len(q)) if start is None else start
    st = newton(asm, q, start, shift)
    bad = np.flatnonzero(~st.ok)
    if bad.size:
        q_from = _start_actuators(asm, start.rows(bad), shift)
        cur = start.rows(bad)
        for s in np.linspace(0.0, 1.0, PATH_STEPS + 1)[1:]:
            cur = newton(asm, q_from + s * (q[bad] - q_from), cur, shift)
        v, X, ok, err = st.v.copy(), st.X.copy(), st.ok.copy(), st.err.copy()
        v[bad], X[bad], ok[bad], err[bad] = cur.v, cur.X, cur.ok, cur.err
        st = State(v, X, ok, err)
    return st


def _start_actuators(asm: Assembly, start: State, shift) -> np.ndarray:
    """The actuator values (n, nc) of a start state (where its chains reach its platform frames): each
    chain's actuator solved with its passives as the start's, by the least squares of its closure."""
    q = np.tile(asm.q0, (len(start.v), 1))
    for _ in range(3):
        r, _, Ba = linearize(asm, q, start.v, start.X, shift)
        for k in range(asm.n_chains):
            b = Ba[:, 6 * k:6 * k + 6, k]
            q[:, k] -= np.einsum("ni,ni->n", b, r[:, 6 * k:6 * k + 6]) / np.maximum(np.einsum("ni,ni->n", b, b),
                                                                                   1e-300)
    return q


def sensitivities(asm: Assembly, q: np.ndarray, st: State, shift=None) -> tuple[np.ndarray, np.ndarray]:
    """The platform's twist (dp, dw) per unit of each actuator value (n, 6, nc) and of each chain base's
    translation (n, 6, 3 nc) at the solution ``st``: implicit differentiation of the closure,
    ``dz = -A^+ B``."""
    _, A, Ba = linearize(asm, q, st.v, st.X, shift)
    nc = asm.n_chains
    Bs = np.zeros((len(q), 6 * nc, 3 * nc))
    for k in range(nc):
        Bs[:, 6 * k:6 * k + 3, 3 * k:3 * k + 3] = np.eye(3)
    tw = np.zeros((len(q), 6, 4 * nc))
    tw[:, :asm.dof] = -lstsq(A, np.concatenate([Ba, Bs], axis=2))[:, asm.n_passive:]
    return tw[:, :, :nc], tw[:, :, nc:]


def platform_frames(model, q, start: State | None = None) -> State:
    """The forward kinematics of ``model`` at actuator values ``q`` (n, nc) (:func:`solve` from the seed)."""
    return solve(assembly(model), q, start)


def closure_gap(asm: Assembly, q: np.ndarray, st: State) -> np.ndarray:
    """The largest position error (n,) mm of the chains' end frames against the solved platform frames."""
    gap = np.zeros(len(q))
    for k, ch in enumerate(asm.chains):
        E = forward(ch, _values(asm, k, q, st.v))
        gap = np.maximum(gap, np.linalg.norm(E[:, :3, 3] - st.X[:, :3, 3], axis=1))
    return gap

