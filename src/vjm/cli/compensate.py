"""``vjm compensate robot.yaml targets.csv``: the joint values to command so that the tool reaches each target
under self-weight (:mod:`vjm.robot.compensate`), written to one CSV.

``targets.csv`` has a header with the columns ``x, y, z`` (mm) and optionally ``rx, ry, rz`` (the tool's
rotation vector, rad; then the orientation is reached too, else it is free), in the robot's base frame; other
columns are ignored and ``#`` lines skipped.  ``--seed q1,...`` (default: the model file's ``home:``) chooses
the configuration (shoulder, elbow, wrist branch); ``--payload KG[@x,y,z]`` adds a point mass at a point (mm)
of the tool frame.

``commands.csv`` (written atomically; an existing file is replaced only if vjm compensate wrote it): a ``#``
line, then one row per target: ``target`` (its row, 1 = the first under the header), the joint values (rad, mm
for prismatic joints), ``residual_mm`` (the deflected tool's distance to the target; rotations times
:data:`vjm.robot.ik.LENGTH`), ``converged`` (1 or 0), ``status`` (``ok``, ``singular`` -- converged next to a
singular posture --, ``unreachable`` -- the rigid IK does not reach it: out of reach or the joint limits in the
way --, ``not converged``), ``iterations`` and ``sag_mm`` (how far the plain IK command would miss: the sag
compensated).  A row that did not converge has no joint values: nothing there to command.  Such rows are
flagged and counted in a warning; when no target converges nothing is written (an error).
"""
from __future__ import annotations

import csv
import io
import os
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np
import typer

from linkfea.files.outputs import COMMANDS_CSV_MARK, is_commands_csv

from ..errors import ArgumentError, VjmError, VjmWarning, user_errors
from ..robot.compensate import TOL, Compensation
from ..robot.model import Payload
from .common import _fail, _load
from .robot_map import numbers, seed_of

#: the first line of a commands.csv (how vjm knows a file it may replace)
MARK = COMMANDS_CSV_MARK
FILE = "commands.csv"


@dataclass(frozen=True)
class Request:
    """What ``vjm compensate`` was asked (the command line's text, checked by :func:`check`)."""

    targets: str
    seed: str | None = None
    tool: str | None = None
    payload: str | None = None
    tol: float = TOL


def read_targets(path) -> tuple[np.ndarray, np.ndarray | None]:
    """Points (n, 3) mm and rotation vectors (n, 3) rad or None of a targets CSV (see the module docstring)."""
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
    return out[:, :3], (out[:, 3:] if rot else None)


def payload_of(text: str | None, tool: str) -> Payload | None:
    """--payload KG[@x,y,z]: a point mass at a point (mm, default the origin) of the tool frame."""
    if text is None:
        return None
    mass, _, at = text.partition("@")
    m = numbers(mass, "--payload")
    com = numbers(at, "--payload") if at else np.zeros(3)
    if m.shape != (1,) or not m[0] >= 0 or com.shape != (3,):
        raise ArgumentError("payload", f"expects KG[@x,y,z]: a mass >= 0 (kg) at a point (mm) of the tool frame, "
                                       f"got {text!r}")
    return Payload(tool, float(m[0]), com)


def commands_text(model, c: Compensation, source: str, tool: str) -> str:
    """The text of commands.csv (see the module docstring)."""
    status = np.where(~c.reached, "unreachable", np.where(~c.converged, "not converged",
                                                          np.where(c.singular, "singular", "ok")))
    what = "positions (orientation free)" if c.positions_only else "poses"
    lines = [f"{MARK} from {os.path.basename(str(model.path or model.name))}; targets {source} ({what}); tool {tool}; "
             f"tol {c.tol:g} mm; units rad (mm prismatic), mm",
             ",".join(["target", *model.q_names, "residual_mm", "converged", "status", "iterations", "sag_mm"])]
    for i in range(len(c.q)):
        q = [repr(float(v)) for v in c.q[i]] if c.converged[i] else [""] * model.nq
        res = f"{c.residual[i]:.6g}" if np.isfinite(c.residual[i]) else ""
        sag = f"{c.miss[i]:.6g}" if np.isfinite(c.miss[i]) else ""
        lines.append(",".join([str(i + 1), *q, res, str(int(c.converged[i])), str(status[i]), str(c.iterations[i]),
                               sag]))
    return "\n".join(lines) + "\n"


def compute(model, targets_path, seed, tool, payload, tol: float) -> tuple[Compensation, str]:
    """The compensation of a targets file and the text of commands.csv; VjmError if no target converges, a
    warning naming the rows that did not."""
    P, W = read_targets(targets_path)
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
    return c, commands_text(model, c, os.path.basename(str(targets_path)), tool)


def check(model, req: Request, out) -> tuple:
    """Every option checked before any work: (tool, seed, payload)."""
    from linkfea.files.outputs import check_file

    if not (np.isfinite(req.tol) and req.tol > 0):
        raise ArgumentError("tol", f"must be a number > 0 (mm), got {req.tol!r}")
    if model.kind != "serial":
        raise VjmError(f"{getattr(model, 'path', None) or 'the model'}: a parallel machine; vjm compensate takes a "
                       f"serial or tree robot (a model file with urdf: or dh:)")
    tool = model._tool(req.tool)
    seed = seed_of(model, req.seed, "--seed")
    payload = payload_of(req.payload, tool)
    if not os.path.isfile(req.targets):
        raise VjmError(f"{req.targets}: no such file (the targets: x,y,z[,rx,ry,rz] in mm, rad)")
    check_file(out, is_commands_csv, "a CSV written by vjm compensate")
    return tool, seed, payload


def run(model, req: Request, out) -> str:
    """``vjm compensate``: check, compute, write commands.csv atomically; the one-line summary."""
    from linkfea.files.atomic import write_text

    tool, seed, payload = check(model, req, out)
    c, text = compute(model, req.targets, seed, tool, payload, req.tol)
    write_text(out, text)
    return summary(c)


def summary(c: Compensation) -> str:
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
    return seed_of(model, None, "--seed")


def calibrated_commands(cal, targets, seed) -> str:
    """commands.csv of a calibration: the compensation of ``targets`` on the model written back (the calibrated
    URDF and robot file, loaded again), its first tool (the first measured point's marker) as the tool."""
    import tempfile

    from ..calibration.write import calibrated_urdf, robot_file
    from ..modelio.read import load_model

    with tempfile.TemporaryDirectory() as d:
        with open(os.path.join(d, "calibrated.urdf"), "w", encoding="utf-8") as fh:
            fh.write(calibrated_urdf(cal, cal.model.tree.source))
        with open(os.path.join(d, "calibrated.yaml"), "w", encoding="utf-8") as fh:
            fh.write(robot_file(cal, "calibrated.urdf"))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", VjmWarning)   # its joints' limits as the source's: said there
            m = load_model(os.path.join(d, "calibrated.yaml"))
        return compute(m, targets, seed, m.tools[0], None, TOL)[1]


def compensate_cmd(model: Path = typer.Argument(..., help="robot model YAML (urdf: or dh:)"),
                   targets: Path = typer.Argument(..., help="targets CSV: x,y,z[,rx,ry,rz] (mm, rad; the robot's base "
                                                            "frame); without rx,ry,rz the orientation is free"),
                   seed: Optional[str] = typer.Option(None, "--seed", help="the configuration: joint values q1,... "
                                                      "(rad, mm prismatic) or home (default: the file's home:)"),
                   tool: Optional[str] = typer.Option(None, "--tool", help="the tool frame (default: the first)"),
                   payload: Optional[str] = typer.Option(None, "--payload", help="KG[@x,y,z]: a point mass at a point "
                                                         "(mm) of the tool frame"),
                   tol: float = typer.Option(1e-6, "--tol", help="tolerance of the deflected tool pose, mm"),
                   out: Path = typer.Option(..., "--out", help="commands CSV (joint values, residual_mm, converged)")):
    """The joint values to command so that the tool, sagging under the robot's weight, reaches each target."""
    try:
        from .compensate import Request, run

        m = _load(model, None, None)
        text = run(m, Request(str(targets), seed, tool, payload, tol), out)
    except user_errors() as exc:
        _fail(exc)
    typer.echo(f"{text}; wrote {out}")
