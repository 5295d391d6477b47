"""Compensation of the self-weight sag: the joint values to command so that the deflected tool reaches a target.

A robot commanded to the rigid inverse kinematics ``q0 = IK(T)`` of a target ``T`` misses it by its sag: its
joints and links give under its own weight (and a payload), and the tool lands at ``D(q0) = F(q0) + s(q0)``,
``F`` the rigid forward kinematics and ``s`` the equilibrium on the deflected geometry
(:meth:`~vjm.robot.model.RobotModel.self_weight`).  The compensated command solves the equilibrium problem
``D(q) = T`` itself:

1. the rigid IK from the seed (damped least squares, as :mod:`vjm.robot.ik`) puts q on the seed's branch;
2. from there, Levenberg-Marquardt on the deflected pose's error ``T - D(q)``, every residual evaluated with
   the full self-weight equilibrium at q.  The step uses the rigid Jacobian (the sag's derivative, about
   ``|s| / reach`` of it, is left out of the step, never out of the residual), so the iteration converges
   linearly with a rate of that order (1e-3 on an arm sagging a millimetre over a metre): 2 to 4 iterations
   to a micrometre and below.

A target is a pose (4x4): position and orientation reached, the rotation error weighted by
:data:`vjm.robot.ik.LENGTH` mm/rad; or a point (3,): the position only, the orientation free (the redundant
directions settled nearest the seed by the damping), unless ``orientation`` gives one.  A targets file
(:func:`read_targets`) and the commands.csv of its compensation (:func:`compensate_file`, ``vjm compensate``,
``vjm calibrate/diagnose --targets``) are read and written here too.  Per target the
result (a :class:`vjm.compensation.Compensation`: ``commanded`` the joint commands, ``residual``, ...) says
``converged`` (the deflected pose within ``tol``), ``reached`` (False: the rigid IK does not
reach it -- out of reach or the joint limits in the way; not compensated), ``singular`` (the tool Jacobian's
smallest singular value below :data:`vjm.robot.ik.SINGULAR` of its largest at the command) and the
``iterations`` of step 2.  Units mm, rad.
"""
from __future__ import annotations

import csv
import io
import os
import warnings

import numpy as np

from linkfea.files.outputs import COMMANDS_CSV_MARK

from ..compensation import Compensation
from ..errors import VjmError, VjmWarning
from ..kinematics.poses import rotation_matrix
from ..kinematics.transforms import rotation_vector
from ..modelio.csvtext import header
from .ik import LENGTH, SINGULAR, levenberg_marquardt, rotation_vectors

#: default tolerance (mm; rotations times LENGTH) of the deflected tool pose
TOL = 1e-6
#: iterations of the compensation (step 2); the rigid IK (step 1) has up to 200
MAX_ITER = 50
#: the first line of a commands.csv (how vjm knows a file it may replace), and its name in an output set
MARK = COMMANDS_CSV_MARK
FILE = "commands.csv"
#: memory and time per target of :func:`compensate_file`, for the estimate before the work (UR10: 5 kB and
#: 0.8-1.5 ms measured on 20,000 and 200,000 targets; the memory with a margin for the peaks of the solver's arrays)
TARGET_BYTES, TARGET_SECONDS = 8e3, 1.5e-3


def targets_of(targets, orientation=None) -> tuple[np.ndarray, bool]:
    """Target frames (n, 4, 4) and whether only their positions count: poses (n, 4, 4) or (4, 4), or points
    (n, 3) with an ``orientation`` (rotation vector (3,) or (n, 3), rad) or none (orientation free)."""
    a = np.asarray(targets, dtype=float)
    if a.shape[-2:] == (4, 4):
        T = a.reshape(-1, 4, 4)
        if orientation is not None:
            raise VjmError("compensate: an orientation goes with target points (n, 3), not poses (n, 4, 4)")
        free = False
    elif a.ndim in (1, 2) and a.shape[-1] == 3:
        P = a.reshape(-1, 3)
        T = np.zeros((len(P), 4, 4))
        T[:, :3, 3], T[:, 3, 3] = P, 1.0
        free = orientation is None
        T[:, :3, :3] = np.eye(3) if free else rotation_matrix(np.broadcast_to(
            rotation_vectors(orientation, "compensate: orientation"), (len(P), 3)))
    else:
        raise VjmError(f"compensate: targets must be poses (n, 4, 4) or points (n, 3) in mm, got shape {a.shape}")
    if len(T) == 0 or not np.all(np.isfinite(T)):
        raise VjmError("compensate: targets must be at least one pose or point of finite numbers (mm, rad)")
    return T, free


def _deflected(model, q, tool, gravity, payload, sag: bool):
    """The tool frames (n, 4, 4) at q, deflected by the self-weight equilibrium if ``sag`` (NaN where it is not
    found), and the sag twists (n, 6)."""
    T = model.forward(q, tool)
    if not sag:
        return T, np.zeros((len(q), 6))
    s = model.self_weight(q, tool, gravity, payload, strict=False)
    D = T.copy()
    D[:, :3, 3] += s[:, :3]
    D[:, :3, :3] = rotation_matrix(np.nan_to_num(s[:, 3:])) @ T[:, :3, :3]
    D[np.isnan(s[:, 0])] = np.nan
    return D, s


def _error(D, targets, w: float) -> np.ndarray:
    e = np.empty((len(D), 6))
    e[:, :3] = targets[:, :3, 3] - D[:, :3, 3]
    e[:, 3:] = w * rotation_vector(targets[:, :3, :3] @ np.swapaxes(D[:, :3, :3], 1, 2)) if w else 0.0
    return np.where(np.isfinite(e), e, np.inf)


def _solve(model, targets, q0, tool, w: float, tol: float, max_iter: int, lam0: float, load=None):
    """Levenberg-Marquardt from q0 on the (deflected, with ``load`` = (gravity, payload)) pose error:
    q (n, nq), residual (n,), iterations (n,)."""
    sag = load is not None
    g, pl = load if sag else (None, None)
    W = np.r_[np.ones(3), np.full(3, w)]

    def error(q, idx):
        return _error(_deflected(model, q, tool, g, pl, sag)[0], targets[idx], w)

    return levenberg_marquardt(model, q0, error, tool, W, tol, max_iter, lam0)


def _singular(model, q, tool, w: float) -> np.ndarray:
    J = model.jacobian(q, tool)
    J = J[:, :3] if not w else J * np.r_[np.ones(3), np.full(3, w)][None, :, None]
    s = np.linalg.svd(J, compute_uv=False)
    return s[:, -1] < SINGULAR * s[:, 0]


def compensate(model, targets, seed, tool=None, gravity=None, payload=None, tol: float = TOL,
               orientation=None, max_iter: int = MAX_ITER) -> Compensation:
    """:meth:`vjm.robot.RobotModel.compensate` (see the module docstring): the commands reaching ``targets``
    (poses (n, 4, 4) or points (n, 3), mm) under self-weight, in the configuration of ``seed`` ((nq,) or
    (n, nq)); ``gravity`` and ``payload`` as :meth:`~vjm.robot.RobotModel.self_weight` takes them."""
    from .weight import check_inertials

    if not (np.isfinite(tol) and tol > 0):
        raise VjmError(f"compensate: tol must be a number > 0 (mm), got {tol!r}")
    check_inertials(model)
    tool = model._tool(tool)
    T, free = targets_of(targets, orientation)
    n = len(T)
    s0 = np.asarray(seed, dtype=float)
    q0 = model.check_q(s0)[0]
    if len(q0) == 1:
        q0 = np.repeat(q0, n, axis=0)
    if len(q0) != n:
        raise VjmError(f"compensate: {len(q0)} seeds for {n} targets; give one seed or one per target")
    w = 0.0 if free else LENGTH
    plain, r0, _ = _solve(model, T, q0, tool, w, tol, 200, 1e-2)
    reached = r0 <= tol
    q = plain.copy()
    res = np.full(n, np.inf)
    its = np.zeros(n, dtype=int)
    miss = np.full(n, np.nan)
    sag = np.full((n, 6), np.nan)
    k = np.flatnonzero(reached)
    if k.size:
        load = (gravity, payload)
        D0, _ = _deflected(model, plain[k], tool, gravity, payload, True)
        miss[k] = np.linalg.norm(T[k, :3, 3] - D0[:, :3, 3], axis=1)
        q[k], res[k], its[k] = _solve(model, T[k], plain[k], tool, w, tol, max_iter, 1e-6, load)
        sag[k] = _deflected(model, q[k], tool, gravity, payload, True)[1]
    return Compensation(q, res, plain=plain, converged=res <= tol, reached=reached,
                        singular=_singular(model, q, tool, w), miss=miss, sag=sag, iterations=its, tol=float(tol),
                        positions_only=free)


def read_targets(path) -> tuple[np.ndarray, np.ndarray | None]:
    """Points (n, 3) mm and rotation vectors (n, 3) rad or None of a targets CSV: a header with the columns
    ``x, y, z`` and optionally ``rx, ry, rz`` (other columns ignored, ``#`` lines skipped)."""
    try:
        with open(path, encoding="utf-8-sig") as fh:
            lines = [ln for ln in fh.read().splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    except (OSError, UnicodeDecodeError) as e:
        raise VjmError(f"{path}: cannot read the targets ({getattr(e, 'strerror', None) or e})") from None
    if not lines:
        raise VjmError(f"{path}: no header; a targets file has the columns x,y,z[,rx,ry,rz] (mm, rad)")
    rows = list(csv.reader(io.StringIO("\n".join(lines))))
    head = [h.strip().lower() for h in rows[0]]
    missing = [c for c in ("x", "y", "z") if c not in head]
    if missing:
        raise VjmError(f"{path}: no column {', '.join(missing)}; a targets file has the columns x,y,z[,rx,ry,rz] "
                       f"(mm, rad in the robot's base frame), got {', '.join(head)}")
    twice = [c for c in ("x", "y", "z", "rx", "ry", "rz") if head.count(c) > 1]
    if twice:
        raise VjmError(f"{path}: column {twice[0]!r} appears twice in the header; which one holds the target is not "
                       f"said: rename or remove one")
    rot = [c for c in ("rx", "ry", "rz") if c in head]
    if rot and len(rot) != 3:
        raise VjmError(f"{path}: columns {', '.join(rot)} without the other rotation components; give rx,ry,rz "
                       f"(the tool's rotation vector, rad) or none")
    cols = [head.index(c) for c in ("x", "y", "z", *rot)]
    if len(rows) < 2:
        raise VjmError(f"{path}: no target under the header")
    out = np.empty((len(rows) - 1, len(cols)))
    for i, r in enumerate(rows[1:]):
        try:
            out[i] = [float(r[k]) for k in cols]
        except (ValueError, IndexError):
            out[i] = np.nan
        if not np.all(np.isfinite(out[i])):
            raise VjmError(f"{path}: target {i + 1} (under the header): x,y,z{',rx,ry,rz' if rot else ''} must be "
                           f"finite numbers, got {','.join(r)!r}")
    return out[:, :3], (rotation_vectors(out[:, 3:], f"{path}") if rot else None)


def commands_text(model, c: Compensation, source: str, tool: str, model_file: str | None = None) -> str:
    """The text of commands.csv (see :mod:`vjm.cli.compensate`); ``model_file``: the model file named in its
    first line (default: the model's own file, or its name)."""
    status = np.where(~c.reached, "unreachable", np.where(~c.converged, "not converged",
                                                          np.where(c.singular, "singular", "ok")))
    what = "positions (orientation free)" if c.positions_only else "poses"
    named = model_file or os.path.basename(str(model.path or model.name))
    lines = [f"{MARK} from {named}; targets {source} ({what}); tool {tool}; tol {c.tol:g} mm; units rad "
             f"(mm prismatic), mm",
             header(["target", *model.q_names, "residual_mm", "converged", "status", "iterations", "sag_mm"])]
    for i in range(len(c.commanded)):
        q = [repr(float(v)) for v in c.commanded[i]] if c.converged[i] else [""] * model.nq
        res = f"{c.residual[i]:.6g}" if np.isfinite(c.residual[i]) else ""
        sag = f"{c.miss[i]:.6g}" if np.isfinite(c.miss[i]) else ""
        lines.append(",".join([str(i + 1), *q, res, str(int(c.converged[i])), str(status[i]), str(c.iterations[i]),
                               sag]))
    return "\n".join(lines) + "\n"


def compensate_file(model, targets_path, seed, tool, payload=None, tol: float = TOL,
                    model_file: str | None = None, progress=None) -> tuple[Compensation, str]:
    """The compensation of a targets file and the text of its commands.csv; VjmError if no target converges,
    a warning naming the rows that did not.  The targets are counted before the work: VjmError if they cannot
    fit in the memory this process can get; ``progress`` told how long a long run will take."""
    from ..maps.grid import plan

    P, W = read_targets(targets_path)
    plan("vjm compensate", len(P), TARGET_BYTES, TARGET_SECONDS, unit="targets",
         hint="split the targets into several files", progress=progress)
    c = model.compensate(P, seed, tool, payload=payload, tol=tol, orientation=W)
    bad = np.flatnonzero(~c.converged)
    if bad.size == len(P):
        why = "unreachable (out of reach or the joint limits in the way)" if not np.any(c.reached) else "not converged"
        raise VjmError(f"{targets_path}: no target can be commanded: target {bad[0] + 1} {why}"
                       + (f", and {len(P) - 1} others" if len(P) > 1 else ""))
    if bad.size:
        warnings.warn(f"{bad.size} of {len(P)} targets not reached under self-weight (targets "
                      + ", ".join(str(i + 1) for i in bad[:10]) + (" ..." if bad.size > 10 else "")
                      + "): flagged in commands.csv, without joint values", VjmWarning, stacklevel=2)
    return c, commands_text(model, c, os.path.basename(str(targets_path)), tool, model_file)


def summary(c: Compensation) -> str:
    """One line: the targets commanded, the sag compensated, the largest residual and iteration count."""
    ok = c.converged
    line = f"{int(ok.sum())} of {len(ok)} targets commanded"
    if np.any(ok):
        line += (f"; sag compensated {np.nanmin(c.miss[ok]):.4g}..{np.nanmax(c.miss[ok]):.4g} mm, residual at most "
                 f"{np.max(c.residual[ok]):.2g} mm after {int(np.max(c.iterations[ok]))} iterations at most")
    return line


def check_targets(model, targets) -> np.ndarray:
    """``--targets`` of ``vjm calibrate`` and ``vjm diagnose``, before any work: the file read, and the seed (the
    robot file's ``home:``, the configuration the targets are reached in)."""
    if model.home is None:
        raise VjmError(f"--targets: {model.path or model.name} has no home: configuration, the seed of the "
                       f"commands' configuration; add home: [q1, ..., q{model.nq}] to it")
    read_targets(targets)
    return model.check_q(np.asarray(model.home, dtype=float))[0][0]
