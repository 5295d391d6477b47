"""``vjm path`` on a serial robot: IK per point holding a configuration, the process wrench plus the
robot's own weight, the deflection along the path and the compensated program.

* **Frames.** The toolpath is in the robot's base frame (mm).  The TCP sits at ``tool`` (mm) in the
  axes of a tool frame of the tree (``tool_frame``, default the model's first tool).  A toolpath
  without orientations keeps the tool frame's orientation at the seed configuration (a milling
  program: choose a seed whose tool points along the spindle).
* **Configuration.** A 6R arm reaches a pose in up to eight configurations; the one held is the
  seed's (``seed``, default the model file's ``home:``).  The IK (:mod:`vjm.robot.ik`) starts the
  first point from the seed and every later point from a solved neighbour: anchor points every
  ``ANCHOR`` samples in order, the samples between them together from their anchor's solution
  (a sample that then fails is redone from its predecessor).  The configuration is checked, not
  assumed: every point must be reached (residual below 1e-8 mm), clear of singular postures
  (:data:`vjm.robot.ik.SINGULAR`), and, on a 6-joint arm, with the tool Jacobian's determinant of
  the seed's sign (the sign flips only through a singular posture, i.e. a change of
  configuration).  The first point failing is an error naming its line.
* **Deflection.** The equilibrium of :func:`vjm.stiffness.nonlinear.deflection_map` on the deflected geometry
  (as :meth:`vjm.robot.RobotModel.self_weight`), its body loads the links' weights, the payload's and
  the process force at the TCP (dead loads at their material points: the force's lever turns with
  the tool), the process moment on the tool frame.  The
  TCP's deflection is the loaded TCP minus the rigid one at the same joint commands; it includes
  the sag, so rapid moves deflect too.  A model with no inertial at all is loaded by the process
  wrench only (said in the notes); one with some links lacking one is refused.
* **Compensation.** Fixed point on the commanded TCP pose ``c``: joint commands ``q(c)`` by the IK
  from the previous ones, ``c += p - (tcp(q) + d(q))`` for the position and, when the toolpath
  gives orientations, ``R_c = Exp(-r) R_p``.  The sag changes little over a deflection, so two or
  three equilibria per point reach the tolerance of :mod:`vjm.toolpath.compensate`; the last one,
  at the final commands, is the residual's check.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..compensation import Compensation
from ..errors import EquilibriumError, VjmError
from ..kinematics.poses import rotation_matrix
from ..kinematics.transforms import rotation_vector
from ..robot import ik
from ..robot.model import SAG_TOL, RobotModel
from . import gcode as gc
from . import passes, run
from .compensate import ABS_TOL, MAX_ITER, REL_TOL
from .points import ROBOT_PATH_SECONDS, Toolpath, path_plan
from .points import read as read_toolpath
from .result import PathResult
from .wrench import PerPoint, at_platform

#: samples between two anchor points of the IK continuation (solved in order)
ANCHOR = 16
#: IK tolerance, mm (rotations times vjm.robot.ik.LENGTH)
IK_TOL = 1e-8


@dataclass(frozen=True, eq=False)
class RobotTool:
    """What ``vjm path`` needs of a robot: the model, its tool frame, the TCP offset (3,) mm in that
    frame's axes, the seed configuration (nq,) and whether the robot's weight loads it."""

    model: RobotModel
    frame: str
    offset: np.ndarray
    seed: np.ndarray
    weight: bool

    def tcp(self, q) -> np.ndarray:
        """Rigid TCP frames (n, 4, 4) at joint values q (n, nq)."""
        T = np.array(self.model.forward(q, self.frame))
        T[:, :3, 3] += T[:, :3, :3] @ self.offset
        return T

    def frame_targets(self, T_tcp) -> np.ndarray:
        """Tool-frame targets (n, 4, 4) of TCP frames."""
        T = np.array(T_tcp)
        T[:, :3, 3] -= T[:, :3, :3] @ self.offset
        return T


def setup(model, seed=None, tool_frame=None, tool=None) -> RobotTool:
    """The :class:`RobotTool` of ``model``: VjmError for an unknown frame, a seed of the wrong length, or a
    seed at a singular posture (its configuration is then undefined)."""
    from ..robot.weight import check_inertials

    frame = model._tool(tool_frame)
    if model.tree.frame(frame).joint < 0:
        raise VjmError(f"tool frame {frame!r} is fixed to the robot's base; choose one with --tool-frame "
                       f"({', '.join(model.tools)})")
    if seed is None:
        if model.home is None:
            raise VjmError(f"{model._where}give --seed {','.join(f'q{i + 1}' for i in range(model.nq))} "
                           f"({', '.join(model.q_names)}): the configuration (elbow up or down, wrist flip) to hold "
                           f"along the path, or home: in the model file")
        seed = model.home
    if np.shape(seed) != (model.nq,):
        raise VjmError(f"--seed must have {model.nq} joint values ({', '.join(model.q_names)}), got {list(seed)!r}")
    q0 = model.check_seed(seed, "--seed")
    if _singular(model, q0, frame)[0]:
        raise VjmError(f"the seed configuration {np.round(q0[0], 6).tolist()} is at a singular posture of the robot: "
                       f"its configuration (elbow, wrist) is undefined; choose one clear of it")
    weight = bool(model.tree.declared) or any(b.mass > 0 for b in model.tree.bodies)
    if weight:
        check_inertials(model)
    return RobotTool(model, frame, run._tool(tool), q0[0], weight)


def _singular(model, q, frame) -> np.ndarray:
    W = np.r_[np.ones(3), ik.LENGTH * np.ones(3)]
    s = np.linalg.svd(model.jacobian(q, frame) * W[None, :, None], compute_uv=False)
    return s[:, -1] <= ik.SINGULAR * s[:, 0]


def _det_sign(model, q, frame) -> np.ndarray:
    if model.nq != 6:  # the sign test needs a square Jacobian
        return np.ones(len(q))
    return np.sign(np.linalg.det(model.jacobian(q, frame)))


def targets(rt: RobotTool, tp: Toolpath) -> np.ndarray:
    """Programmed TCP frames (n, 4, 4): the toolpath's poses, or its points with the seed's orientation
    (its matrix itself: a rotation vector near pi, as a tool pointing down often is, loses digits)."""
    T = np.zeros((tp.n, 4, 4))
    T[:, :3, :3] = rotation_matrix(tp.poses[:, 3:]) if tp.has_orientation else rt.tcp(rt.seed[None])[0, :3, :3]
    T[:, :3, 3], T[:, 3, 3] = tp.points, 1.0
    return T


def follow(rt: RobotTool, T_tcp, where, what: str = "programmed", seed=None, start=None) -> np.ndarray:
    """Joint values (n, nq) of TCP frames along a path in the configuration of the seed (see the module
    docstring), the first from ``start`` (default the seed: a later pass of a long program starts from the
    previous pass's last point); ``seed`` (n, nq): solve each frame from these instead (the compensation's
    nearby commands)."""
    m, f = rt.model, rt.frame
    T = rt.frame_targets(T_tcp)
    n = len(T)
    if seed is not None:
        r = ik.solve(m, T, seed, f, IK_TOL)
        q, ok = r.q, r.reached
    else:
        q, ok = np.tile(rt.seed, (n, 1)), np.zeros(n, bool)
        prev, end = rt.seed if start is None else np.asarray(start, dtype=float), n
        for i in range(0, n, ANCHOR):  # anchors in order, each from the previous one
            r = ik.solve(m, T[i:i + 1], prev, f, IK_TOL)
            q[i], ok[i], prev = r.q[0], r.reached[0], r.q[0]
            if not ok[i]:  # no need to go further: the error names this point or an earlier one
                end = i
                break
        rest = np.setdiff1d(np.arange(end), np.arange(0, end, ANCHOR))
        if rest.size:  # the samples between anchors together, each from its anchor
            r = ik.solve(m, T[rest], q[(rest // ANCHOR) * ANCHOR], f, IK_TOL)
            q[rest], ok[rest] = r.q, r.reached
    sign = _det_sign(m, rt.seed[None], f)[0]
    bad = ~ok | (_det_sign(m, q, f) != sign)
    for k in np.flatnonzero(bad) if seed is None else ():  # in order: each from its (already fixed) predecessor
        r = ik.solve(m, T[k:k + 1], q[k - 1] if k else (rt.seed if start is None else start), f, IK_TOL)
        q[k], ok[k] = r.q[0], r.reached[0]
        if not ok[k] or _det_sign(m, q[k:k + 1], f)[0] != sign:
            break  # the error names this point
    _check_configuration(rt, q, ok, sign, T_tcp, where, what)
    return q


def _check_configuration(rt: RobotTool, q, ok, sign, T_tcp, where, what) -> None:
    m, f = rt.model, rt.frame
    if not ok.all():
        i = int(np.argmax(~ok))
        raise VjmError(f"{where(i)}: the {what} point {np.round(T_tcp[i, :3, 3], 6).tolist()} mm is out of the "
                       f"robot's reach with this tool orientation in the configuration of the seed (or needs a joint "
                       f"outside its limits)")
    sing = _singular(m, q, f)
    flip = _det_sign(m, q, f) != sign
    if sing.any() or flip.any():
        i = int(np.argmax(sing | flip))
        raise VjmError(f"{where(i)}: the robot is at a singular posture at the {what} point "
                       f"{np.round(T_tcp[i, :3, 3], 6).tolist()} mm" + (" (the path leaves the configuration of the "
                                                                        "seed through it)" if flip[i] else "")
                       + ": move the program or choose another --seed")


def deflect(rt: RobotTool, q, W_tcp, where) -> np.ndarray:
    """TCP deflection twists (n, 6) at joint values q under TCP wrenches W (n, 6) and the robot's weight:
    the equilibrium on the deflected geometry (:func:`vjm.stiffness.nonlinear.deflection_map`), the weights and the
    process force dead loads at their material points (the force at the TCP), the process moment on the
    tool frame."""
    from ..robot.weight import body_loads, point_load
    from ..stiffness.nonlinear import deflection_map

    m = rt.model
    kin = m.kinematics(q, rt.frame)
    loads = body_loads(m, kin.q, rt.frame, np.asarray(m.gravity, dtype=float), m.payload) if rt.weight else []
    loads.append(point_load(m, kin.q, rt.frame, rt.frame, rt.offset, np.asarray(W_tcp, dtype=float)[:, :3]))
    Wm = np.zeros((len(kin.q), 6))
    Wm[:, 3:] = np.asarray(W_tcp, dtype=float)[:, 3:]
    t = deflection_map(m, kin, Wm, tol=SAG_TOL, strict=False, body_loads=[loads])
    bad = ~np.all(np.isfinite(t), axis=1)
    if bad.any():
        raise EquilibriumError(f"{where(int(np.argmax(bad)))}: no equilibrium of the loaded robot (load too large "
                               f"for the model?)")
    lever = kin.frames[:, :3, :3] @ rt.offset
    t[:, :3] += np.einsum("nij,nj->ni", rotation_matrix(t[:, 3:]) - np.eye(3), lever)
    return t


def compensate_commands(rt: RobotTool, T_p, six: bool, W, q0, d0, where) -> tuple[Compensation, np.ndarray]:
    """(the commanded TCP poses (n, 3|6) whose loaded TCP lands on the programmed frames ``T_p``, the joint
    commands (n, nq)); ``q0``, ``d0``: the joint values and deflection at the programmed frames."""
    n = len(T_p)
    p = T_p[:, :3, 3]
    T_c = np.array(T_p)
    q, d = np.array(q0), np.array(d0)
    target = np.maximum(REL_TOL * np.linalg.norm(d0[:, :3], axis=1), ABS_TOL)
    res, resvec = np.full(n, np.inf), np.zeros((n, 3))
    active, evals = np.arange(n), 0
    while active.size and evals < MAX_ITER:
        evals += 1
        a = active
        loaded = rt.tcp(q[a])[:, :3, 3] + d[a, :3]
        T_c[a, :3, 3] += p[a] - loaded
        if six:
            T_c[a, :3, :3] = rotation_matrix(-d[a, 3:]) @ T_p[a, :3, :3]
        q[a] = follow(rt, T_c[a], lambda k, a=a: where(int(a[k])), "compensated", q[a])
        d[a] = deflect(rt, q[a], W[a], lambda k, a=a: where(int(a[k])))
        err = rt.tcp(q[a])[:, :3, 3] + d[a, :3] - p[a]
        res[a], resvec[a] = np.linalg.norm(err, axis=1), err
        done = res[a] <= target[a]
        if six:
            Rl = rotation_matrix(d[a, 3:]) @ rt.tcp(q[a])[:, :3, :3]
            rot = np.linalg.norm(rotation_vector(T_p[a, :3, :3] @ np.swapaxes(Rl, 1, 2)), axis=1)
            done &= rot <= np.maximum(REL_TOL * np.linalg.norm(d0[a, 3:], axis=1), ABS_TOL * 1e-3)
        active = a[~done]
    if active.size:
        i = int(active[0])
        raise EquilibriumError(f"{where(i)}: compensation did not converge in {MAX_ITER} equilibria "
                               f"(residual {res[i]:.3g} mm)")
    cmd = T_c[:, :3, 3] if not six else np.hstack([T_c[:, :3, 3], rotation_vector(T_c[:, :3, :3])])
    return Compensation(cmd, res, residual_vector=resvec, equilibria=evals), q


def robot_path(model, toolpath, wrench=None, tool=None, method: str = "nonlinear", compensate: bool = True,
               tolerance: float | None = None, linearize_arcs: bool = False, split_moves: bool = False,
               chord_tol: float = 1e-3, step: float = 1.0, passed: str = gc.DEFAULT_PASS, seed=None,
               tool_frame=None, progress=None) -> PathResult:
    """:func:`vjm.toolpath.run.path` on a :class:`vjm.robot.RobotModel` (see the module docstring): the same
    result and outputs; ``seed`` (nq,) the configuration to hold (default the model file's ``home:``),
    ``tool_frame`` the tree's tool frame (default its first), ``tool`` the TCP in that frame's axes (mm)."""
    from linkfea.runtime.progress import or_quiet

    if method != "nonlinear":
        raise VjmError(f"--method {method}: a robot's deflection is the equilibrium under its own weight "
                       f"(nonlinear); --method linear is for parallel machines")
    if tolerance is not None and not (np.isfinite(tolerance) and tolerance > 0):
        raise VjmError(f"--tolerance must be a number > 0 (mm), got {tolerance!r}")
    if not (np.isfinite(chord_tol) and chord_tol > 0) or not (np.isfinite(step) and step > 0):
        raise VjmError(f"--chord-tol and --step must be numbers > 0 (mm), got {chord_tol!r}, {step!r}")
    rt = setup(model, seed, tool_frame, tool)
    tp = toolpath if isinstance(toolpath, Toolpath) else read_toolpath(toolpath, chord_tol, step, passed)
    W = (wrench or PerPoint()).wrenches(tp)
    check_load(rt, tp, W)
    plan = path_plan(tp.n, ROBOT_PATH_SECONDS)  # a CSV's points, or a program's samples (checked before sampling)
    progress = or_quiet(progress)
    if plan.long:  # a run of more than a minute says so before it starts
        progress(f"{plan.describe()}; progress follows")
    progress(f"inverse kinematics, equilibria under the process wrench{' and the weight' if rt.weight else ''}"
             + (" and compensation" if compensate else "") + f" at {tp.n:,} points")
    d, comp = _passes(rt, tp, W, compensate, progress)
    after = text = None
    if comp is not None:
        after = run.blend_after(run._all_vertices(tp, linearize_arcs, split_moves), comp.commanded,
                                comp.residual_vector)
        text = run.compensated_text(tp, comp.commanded, linearize_arcs, split_moves)
    return PathResult(tp, W, d, method, tolerance, comp, None, after, _notes(rt, tp, after, d, split_moves), text)


def check_load(rt: RobotTool, tp: Toolpath, W) -> None:
    """Refuse a wrench far beyond the model's range (as :func:`vjm.toolpath.run.check_load`): its linear
    deflection at the seed beyond ``run.LARGE_DEFLECTION`` x the tool's distance from the base, or
    ``run.LARGE_ROTATION``, before any equilibrium is tried."""
    if not W.size or not np.abs(W).max() > 0:
        return
    i = int(np.argmax(np.abs(W).max(axis=1)))
    T = rt.tcp(rt.seed[None])[0]
    lever = T[:3, :3] @ rt.offset
    with np.errstate(all="ignore"):  # 1e300 N: the products overflow, which is the answer
        d = rt.model.deflection(rt.seed, at_platform(W[i:i + 1], lever[None])[0], rt.frame)
        t, r = float(np.linalg.norm(d[:3] + np.cross(d[3:], lever))), float(np.linalg.norm(d[3:]))
    size = float(np.linalg.norm(T[:3, 3]))
    if not (t <= run.LARGE_DEFLECTION * size and r <= run.LARGE_ROTATION):
        raise VjmError(f"{tp.where(i)}: the wrench {','.join(f'{v:g}' for v in W[i])} (N, N mm) deflects the tool "
                       f"by {t:.3g} mm and {r:.3g} rad in the linear model at the seed, beyond "
                       f"{run.LARGE_DEFLECTION:g} x the tool's reach ({size:.3g} mm) or {run.LARGE_ROTATION:g} rad, "
                       f"where the model holds; check the wrench and its units")


def _passes(rt: RobotTool, tp: Toolpath, W, compensate: bool, progress):
    """(deflection (n, 6), Compensation or None) in passes of ``passes.CHUNK`` points, each pass's IK starting
    from the previous pass's last joint values (the configuration carried through)."""
    import time

    T_p = targets(rt, tp)
    n = tp.n
    d = np.empty((n, 6))
    cmd, res, resvec = np.empty_like(tp.poses), np.empty(n), np.empty((n, 3))
    iters, last, t0 = 0, None, time.perf_counter()
    for a in range(0, n, passes.CHUNK):
        sl = slice(a, min(n, a + passes.CHUNK))

        def where(i, a=a):
            return tp.where(i + a)

        q = follow(rt, T_p[sl], where, start=last)
        last = q[-1]
        d[sl] = deflect(rt, q, W[sl], where)
        if compensate:
            c, _ = compensate_commands(rt, T_p[sl], tp.has_orientation, W[sl], q, d[sl], where)
            cmd[sl], res[sl], resvec[sl], iters = c.commanded, c.residual, c.residual_vector, max(iters, c.equilibria)
        passes._eta(progress, sl.stop, n, t0)
    return d, (Compensation(cmd, res, residual_vector=resvec, equilibria=iters) if compensate else None)


def _notes(rt: RobotTool, tp: Toolpath, after, d, split_moves: bool) -> tuple:
    m = rt.model
    notes = [f"serial robot {m.name or m.path}: TCP {rt.offset.tolist()} mm in the axes of {rt.frame!r}; the "
             f"configuration of the seed q = {np.round(rt.seed, 4).tolist()} held along the path (IK per point, "
             f"checked reached, clear of singular postures" + (", Jacobian determinant of the seed's sign)"
                                                                 if m.nq == 6 else ")")]
    if not tp.has_orientation:
        notes.append("toolpath without orientations: the tool keeps its orientation at the seed; only positions "
                     "are compensated")
    notes.append("deflection: the equilibrium on the deflected geometry under the process wrench"
                 + (" and the robot's own weight (rapid moves sag too)" if rt.weight else
                    "; the model has no inertials: its weight is left out"))
    if after is not None and tp.kind == "gcode" and not split_moves:
        worse = np.flatnonzero(np.linalg.norm(after[:, :3], axis=1) > np.linalg.norm(d[:, :3], axis=1))
        if worse.size:
            notes.append(f"warning: along {worse.size} of {int(tp.cutting.sum())} cutting samples (first: "
                         f"{tp.where(int(worse[0]))}) the compensated program is farther from the path than the "
                         f"original; --split-moves fixes that")
    return tuple(notes)
