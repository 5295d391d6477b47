"""Self-weight of a serial or tree robot: the equilibrium on the deflected geometry.

The links' weights (and a payload's) are dead loads ``m g`` at their centres of mass; as the
springs deflect, the centres of mass move and the gravity torques change.  The equilibrium is
the stationary point of ``1/2 sum theta^T K theta - sum m g . p_com(theta) - w . tool``, solved
by :func:`vjm.stiffness.nonlinear.deflection_map` -- the same Newton solver (exact Hessian, load steps on
failure) as a parallel machine's, the weights entering as its body loads.  Each configuration is
first solved by the compiled Newton of those same equations on the chain's own variables
(:mod:`vjm.robot.sagkernel`, :func:`fast_sag`); what it does not converge, and what it does not
cover (a tool moment, a passive joint, a spring with a rigid direction), goes to ``deflection_map``
(``info["fallback"]``).  It converges when the
Newton step of the tool pose is below ``tol`` (default 1e-11) times its size; where it does not,
an :class:`~vjm.errors.EquilibriumError` names the configurations (``strict=False``: NaN rows
and ``info["converged"]`` False).

A body on a branch of a tree that leaves the path to the tool (the other arm of a torso) loads
the path as a rigid body hanging from the last joint the two share: its own springs' effect on
where its weight acts is neglected (second order).
"""
from __future__ import annotations

import numpy as np

from ..errors import VjmError
from ..kinematics.chain import forward
from ..kinematics.transforms import rotation_vector
from ..stiffness.nonlinear import MAX_ROT_STEP, ROUNDOFF
from .tree import ChainSprings, chain_values, path_chain


def _frame_at(model, joint: int, q: np.ndarray) -> np.ndarray:
    """World frames (n, 4, 4) of a joint's frame at q (rigid)."""
    if joint < 0:
        return np.broadcast_to(np.eye(4), (len(q), 4, 4))
    ch, _ = path_chain(model.tree, joint, np.eye(4), ChainSprings(), "frame")
    return forward(ch, chain_values(ch, model.tree, q))


def _attach(model, marks: dict, joint: int, point: np.ndarray, q: np.ndarray, own: bool):
    """(factor index, local point (n, 3)) where a point fixed to ``joint`` loads the chain with ``marks``,
    or None if it hangs from the base."""
    if joint in marks:
        return marks[joint][0 if own else 1], np.broadcast_to(point, (len(q), 3))
    a = joint
    while a >= 0 and a not in marks:
        a = model.tree.joints[a].parent
    if a < 0:
        return None
    Tb = _frame_at(model, joint, q)
    Ta = _frame_at(model, a, q)
    pw = np.einsum("nij,j->ni", Tb[:, :3, :3], point) + Tb[:, :3, 3]
    local = np.einsum("nji,nj->ni", Ta[:, :3, :3], pw - Ta[:, :3, 3])
    return marks[a][1], local


def check_inertials(model) -> None:
    """Every moving link declares its inertial (a mass of 0 included), or VjmError naming the first that does not."""
    massive = set(model.tree.declared) | {b.joint for b in model.tree.bodies if b.mass > 0}
    for i, j in enumerate(model.tree.joints):
        if i not in massive:
            raise VjmError(f"{model._where}self-weight: link {j.child or j.name!r} (moved by joint {j.name!r}) has no inertial "
                           f"(mass and centre of mass); give them in the URDF or under masses: in the model file")


def body_loads(model, q: np.ndarray, tool: str, gravity, payload) -> list:
    """The body loads (factor index, point, force) of the chain to ``tool`` (see vjm.stiffness.nonlinear)."""
    _, marks = model.chain(tool)
    g = np.asarray(gravity, dtype=float)
    loads = []
    for b in model.tree.bodies:
        if b.joint < 0 or b.mass == 0:
            continue
        hit = _attach(model, marks, b.joint, np.asarray(b.com, dtype=float), q, own=True)
        if hit is not None:
            loads.append((hit[0], hit[1], b.mass * g))
    if payload is not None and payload.mass > 0:
        hit = point_load(model, q, tool, payload.frame, payload.com, payload.mass * g)
        if hit is not None:
            loads.append(hit)
    return loads


def _stiffness6(c6: np.ndarray):
    """Stiffnesses (m6, 6, 6) of 6-dof springs of compliances c6, or None if one has a rigid direction
    (the general solver's business: see :func:`vjm.stiffness.nonlinear._spring_basis`)."""
    d = np.sqrt(np.abs(np.einsum("mii->mi", c6)))
    if np.any(d == 0.0):
        return None
    A = c6 / (d[:, :, None] * d[:, None, :])
    A = 0.5 * (A + np.swapaxes(A, 1, 2))
    ev = np.linalg.eigvalsh(A)
    if np.any(ev[:, 0] <= 1e-10 * ev[:, -1]):
        return None
    K = np.linalg.inv(A) / (d[:, :, None] * d[:, None, :])
    return 0.5 * (K + np.swapaxes(K, 1, 2))


def fast_sag(model, a: np.ndarray, tool: str, g: np.ndarray, pl, W, tol: float, max_iter: int):
    """The equilibrium of configurations a (n, nq) by the compiled Newton (:mod:`vjm.robot.sagkernel`):
    twists (n, 6), Newton iterations (n,) and converged (n,); None where the kernel does not apply (a
    passive joint, a tool moment, a spring with a rigid direction)."""
    ch, _ = model.chain(tool)
    n = len(a)
    if ch.passive or W.shape != (n, 6) or np.any(W[:, 3:] != 0.0):
        return None
    vt, s1, c1, s6, c6 = model.spring_arrays(ch, a)
    k6 = _stiffness6(c6) if len(c6) else np.zeros((0, 6, 6))
    if k6 is None:
        return None
    from .sagkernel import sag_kernel

    kinds, var, coef, T = model._encoded(ch)
    loads = body_loads(model, a, tool, g, pl)
    if np.any(W[:, :3] != 0.0):  # the tool force: a load at the chain's end
        loads.append((len(kinds) - 1, np.zeros((n, 3)), W[:, :3]))
    loads.sort(key=lambda x: x[0])
    lidx = np.array([i for i, _, _ in loads], dtype=np.int64)
    lpt = np.ascontiguousarray(np.array([np.broadcast_to(c, (n, 3)).T for _, c, _ in loads]).reshape(-1, 3, n))
    lf = np.ascontiguousarray(np.array([np.broadcast_to(f, (n, 3)).T for _, _, f in loads]).reshape(-1, 3, n))
    lref = sum(float(np.linalg.norm(f.T[:3, 3])) for f in ch.factors if f.kind == "const")
    out = (np.empty((n, 3)), np.empty((n, 3, 3)), np.empty((n, 3)), np.empty((n, 3, 3)), np.zeros(n, dtype=np.int64),
           np.zeros(n, dtype=bool))
    sag_kernel(kinds, var, coef, T, vt, s1, c1, s6, k6, lidx, lpt, lf, float(tol), int(max_iter),
               MAX_ROT_STEP, ROUNDOFF * lref, ROUNDOFF, *out)
    p0, R0, p, R, iters, ok = out
    t = np.concatenate([p - p0, rotation_vector(R @ np.swapaxes(R0, 1, 2))], axis=1)
    return t, iters, ok


def point_load(model, q: np.ndarray, tool: str, frame: str, point, force):
    """The body load (factor index, point, force) of a dead force (3,) or (n, 3) (N, world axes) at
    ``point`` (mm) of the named ``frame``, on the chain to ``tool``; None where it hangs from the base."""
    _, marks = model.chain(tool)
    f = model.tree.frame(frame)
    p = f.placement[:3, :3] @ np.asarray(point, dtype=float) + f.placement[:3, 3]
    hit = _attach(model, marks, f.joint, p, q, own=False)
    return None if hit is None else (hit[0], hit[1], force)


def self_weight(model, q, tool, gravity, payload, wrench, tol, max_iter, return_info, strict):
    """:meth:`vjm.robot.RobotModel.self_weight` (see the module docstring)."""
    from ..stiffness.nonlinear import deflection_map

    check_inertials(model)
    tool = model._tool(tool)
    a, single = model.check_q(q)
    n = len(a)
    g = model.gravity if gravity is None else gravity
    g = np.asarray(g, dtype=float)
    if g.shape != (3,) or not np.all(np.isfinite(g)):
        raise VjmError(f"gravity must be 3 finite numbers (m/s^2, base frame), got {gravity!r}")
    pl = model.payload if payload is None else payload
    W = np.zeros(6) if wrench is None else wrench
    try:
        Wn = np.array(np.broadcast_to(np.asarray(W, dtype=float), (n, 6)))
    except (ValueError, TypeError):
        Wn = np.full((n, 6), np.nan)  # the general solver names the fault
    fast = fast_sag(model, a, tool, g, pl, Wn, tol, max_iter) if np.all(np.isfinite(Wn)) else None
    t = np.full((n, 6), np.nan)
    info = {"converged": np.zeros(n, bool), "iterations": np.zeros(n, int), "load_steps": np.ones(n, int),
            "chain_wrench": Wn[:, None, :].copy(), "fallback": np.ones(n, bool)}
    todo = np.arange(n)
    if fast is not None:
        tf, it, ok = fast
        t[ok], info["iterations"][ok], info["converged"][ok], info["fallback"][ok] = tf[ok], it[ok], True, False
        todo = np.flatnonzero(~ok)
    if todo.size:  # the general solver: trees' other arms, rigid directions, load steps where Newton alone fails
        kin = model.kinematics(a[todo], tool)
        loads = body_loads(model, kin.q, tool, g, pl)
        Wt = W if Wn.shape != (n, 6) or np.isnan(Wn).any() else Wn[todo]
        tg, ig = deflection_map(model, kin, Wt, tol=tol, max_iter=max_iter, return_info=True, strict=strict,
                                body_loads=[loads])
        t[todo] = tg
        for k in ("converged", "iterations", "load_steps", "chain_wrench"):
            info[k][todo] = ig[k]
    if return_info:
        return (t[0], {k: v[0] for k, v in info.items() if k != "springs"}) if single else (t, info)
    return t[0] if single else t
