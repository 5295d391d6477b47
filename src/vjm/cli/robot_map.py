"""``vjm map`` on a serial or tree robot: a joint-space map or a Cartesian grid through the IK, one output set.

``--joints q2=-2:0:41,q3=0:2.5:41`` varies two joints (``name=lo:hi[:n]``, rad or mm; n defaults to
``--grid``) with the others at ``--q`` (default: the model file's ``home:``)
(:func:`vjm.maps.robot_joint.joint_map`).  Without ``--joints`` the map is over a Cartesian grid of
tool points (``--grid``, ``--slice z=...``, ``--box``; default box: the tool's reach), each reached by
the IK in the configuration of ``--q`` with the tool held at ``--orientation`` (default: its
orientation at ``--q``) (:func:`vjm.maps.robot_cartesian.cartesian_grid_map`); unreachable and singular
points are masked and counted.  ``--self-weight`` adds the sag under the robot's own weight.

Files: the map's ``save`` (:mod:`vjm.maps.robot_output`, one set): ``map.npz`` (every array), ``map.csv`` (one
row a point), ``k_tran.png``, ``k_rot.png``, ``sag.png`` (with ``--self-weight``) and ``summary.json``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from linkfea.files.outputs import check_folder

from ..errors import ArgumentError, VjmError
from ..maps import robot_output
from ..maps.grid import Workspace, grid_plan, plan

#: bytes a robot map holds per point (q, K, the IK's arrays, the CSV row) and seconds per Cartesian point
BYTES = 1200
IK_SECONDS = 0.02


@dataclass(frozen=True)
class Request:
    """What ``vjm map robot.yaml`` was asked (the command line's text, checked by :func:`run`)."""

    grid: int = 30
    slice: str | None = None
    box: str | None = None
    joints: str | None = None
    q: str | None = None
    orientation: str | None = None
    tool: str | None = None
    self_weight: bool = False


def files(req: Request) -> tuple[str, ...]:
    return robot_output.files(req.self_weight)


def numbers(text: str, option: str, sep: str = ",") -> np.ndarray:
    """The numbers of an option's text separated by ``sep``; ArgumentError naming the option if one is not finite."""
    try:
        v = np.array([float(x) for x in text.split(sep)])
    except ValueError:
        v = np.array([np.nan])
    if not np.all(np.isfinite(v)):
        raise ArgumentError(option.lstrip("-"), f"expects finite numbers separated by '{sep}', got {text!r}")
    return v


def seed_of(model, text: str | None, option: str = "--q") -> np.ndarray:
    """``option`` q1,...,qn, or nothing or ``home``: the model file's ``home:``; its length and limits checked."""
    if text is None or text.strip() == "home":
        if model.home is None:
            raise VjmError(f"{model.path or model.name} has no home: configuration; give {option} "
                           f"q1,...,q{model.nq} ({', '.join(model.q_names)})")
        return model.check_q(np.asarray(model.home, dtype=float))[0][0]
    q = numbers(text, option)
    if q.shape != (model.nq,):
        raise VjmError(f"{option} expects {model.nq} numbers q1,...,q{model.nq} for {model.path or model.name} "
                       f"({', '.join(model.q_names)}; rad, mm for prismatic joints) or home, got {text!r}")
    return model.check_seed(q, option)[0]


def parse_joints(model, text: str, n_default: int) -> tuple[tuple, tuple, tuple]:
    """``"q2=-2:0:41,q3=0:2.5:41"`` -> names, ranges ((lo, hi), (lo, hi)), points per joint; each range
    within the joint's limits."""
    items = [t.strip() for t in text.split(",") if t.strip()]
    if len(items) != 2:
        raise ArgumentError("joints", f"varies two joints, name=lo:hi[:n] each, e.g. {model.q_names[0]}=-2:0:41,"
                                      f"{model.q_names[-1]}=0:2.5:41; got {text!r}")
    lo_lim, hi_lim = model.tree.limits
    names, ranges, ns = [], [], []
    for item in items:
        name, _, spec = item.partition("=")
        name = name.strip()
        if name not in model.q_names:
            raise ArgumentError("joints", f"names {name!r}, not a joint with a coordinate of its own; joints: "
                                          f"{', '.join(model.q_names)}")
        if name in names:
            raise ArgumentError("joints", f"names joint {name!r} twice; a joint map varies two different joints")
        parts = spec.split(":")
        if len(parts) not in (2, 3):
            raise ArgumentError("joints", f"{name}: expects lo:hi or lo:hi:n (rad, mm for prismatic joints), "
                                          f"got {spec!r}")
        lo, hi = numbers(":".join(parts[:2]), "--joints", ":")
        n = n_default if len(parts) == 2 else _count(parts[2], name)
        j = model.q_names.index(name)
        if not lo < hi:
            raise ArgumentError("joints", f"{name}: the range {lo:g}:{hi:g} is empty; give lo < hi")
        if lo < lo_lim[j] - 1e-12 or hi > hi_lim[j] + 1e-12:
            raise ArgumentError("joints", f"{name}: the range {lo:g}:{hi:g} leaves the joint's limits "
                                          f"[{lo_lim[j]:g}, {hi_lim[j]:g}]")
        names.append(name)
        ranges.append((lo, hi))
        ns.append(n)
    return tuple(names), tuple(ranges), tuple(ns)


def _count(text: str, name: str) -> int:
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 2:
        raise ArgumentError("joints", f"{name}: the number of values must be a whole number >= 2, got {text!r}")
    return n


def parse_box(text: str) -> Workspace:
    """``"x0:x1,y0:y1,z0:z1"`` (mm) -> the box."""
    parts = text.split(",")
    if len(parts) != 3:
        raise ArgumentError("box", f"expects x0:x1,y0:y1,z0:z1 (mm), got {text!r}")
    lh = np.array([numbers(p, "--box", ":") for p in parts if len(p.split(":")) == 2])
    if lh.shape != (3, 2):
        raise ArgumentError("box", f"expects x0:x1,y0:y1,z0:z1 (mm), got {text!r}")
    if not np.all(lh[:, 1] > lh[:, 0]):
        raise ArgumentError("box", f"needs lo < hi on every axis, got {text!r}")
    return Workspace(lh[:, 0].copy(), lh[:, 1].copy())


def check(model, req: Request):
    """Every option checked before any work: ``(kind, tool, seed, spec)``, ``spec`` the joints' names,
    ranges and counts of a ``"joint"`` map, or the grid (None: the tool's reach, laid later) and the tool's
    rotation (None: as at the seed) of a ``"cartesian"`` one."""
    from ..kinematics.poses import rotation_matrix

    tool = model._tool(req.tool)
    seed = seed_of(model, req.q)
    if req.joints is not None:
        for option, given in (("--slice", req.slice), ("--box", req.box), ("--orientation", req.orientation)):
            if given is not None:
                raise ArgumentError(option.lstrip("-"), "is for a Cartesian map; a joint map (--joints) has none")
        names, ranges, ns = parse_joints(model, req.joints, req.grid)
        plan(f"the joint map ({ns[0]} x {ns[1]})", ns[0] * ns[1], BYTES, hint="use fewer values per joint")
        return "joint", tool, seed, (names, ranges, ns)
    p = grid_plan(req.grid, req.slice, "the robot's Cartesian map", BYTES)
    if p.n * IK_SECONDS > 3600:
        raise VjmError(f"{p.describe()}: the IK of {p.n:,} points would take about {p.n * IK_SECONDS / 3600:.1f} h; "
                       f"use a coarser grid or a slice")
    box = parse_box(req.box) if req.box is not None else None
    rot = None
    if req.orientation is not None:
        w = numbers(req.orientation, "--orientation")
        if w.shape != (3,):
            raise ArgumentError("orientation", f"expects the tool's rotation vector rx,ry,rz (rad), got "
                                               f"{req.orientation!r}")
        rot = rotation_matrix(w)
    grid = (box or Workspace(np.zeros(3), np.ones(3))).grid(req.grid, req.slice)  # the slice checked now
    return "cartesian", tool, seed, (grid if box is not None else None, rot)


def run(model, req: Request, out, force: bool = False) -> str:
    """``vjm map robot.yaml``: check, compute, write the set (the map's ``save``); the one-line summary."""
    from ..maps.robot_cartesian import cartesian_grid_map, reach_box

    kind, tool, seed, spec = check(model, req)
    check_folder(out, files(req), force=force)
    if kind == "joint":
        names, ranges, ns = spec
        res = model.joint_map(seed, names, ranges, ns, tool, req.self_weight)
    else:
        grid, rot = spec
        box_from = "the tool's reach" if grid is None else "--box"
        grid = grid if grid is not None else reach_box(model, tool).grid(req.grid, req.slice)
        res = cartesian_grid_map(model, grid, seed, rot, tool, req.self_weight, req.grid, req.slice, box_from)
    res.save(out, force)
    return res.summary()
