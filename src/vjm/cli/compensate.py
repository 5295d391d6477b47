"""``vjm compensate robot.yaml targets.csv``: the joint values to command so that the tool reaches each target
under self-weight (:mod:`vjm.robot.compensate`, which reads the targets and writes the commands), written to
one CSV.

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

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np
import typer

from linkfea.files.outputs import is_commands_csv

from ..errors import ArgumentError, VjmError, user_errors
from ..robot.compensate import TOL, compensate_file, summary
from ..robot.model import Payload
from .common import _fail, _load
from .robot_map import numbers, seed_of


@dataclass(frozen=True)
class Request:
    """What ``vjm compensate`` was asked (the command line's text, checked by :func:`check`)."""

    targets: str
    seed: str | None = None
    tool: str | None = None
    payload: str | None = None
    tol: float = TOL


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
    check_file(out, is_commands_csv, "a CSV written by vjm compensate", inputs=(req.targets, model.path))
    return tool, seed, payload


def run(model, req: Request, out) -> str:
    """``vjm compensate``: check, compute, write commands.csv atomically; the one-line summary."""
    from linkfea.files.atomic import write_text

    tool, seed, payload = check(model, req, out)
    c, text = compensate_file(model, req.targets, seed, tool, payload, req.tol,
                              progress=lambda line: typer.echo(line, err=True))
    write_text(out, text)
    return summary(c)


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
