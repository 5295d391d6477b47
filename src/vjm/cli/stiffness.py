"""``vjm stiffness``: the Cartesian stiffness of a model at one point, or of a robot at one configuration."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import numpy as np
import typer

from ..errors import VjmError, user_errors
from .common import FOOT, LEG, _fail, _load, _point


def stiffness(model: Path = typer.Argument(..., help="model YAML"),
              at: Optional[str] = typer.Option(None, "--at", help="end-effector point x,y,z in mm [,rx,ry,rz: "
                                                                 "platform rotation vector in rad, 6-dof platforms]"),
              q: Optional[str] = typer.Option(None, "--q", help="serial or tree robots: the joint values q1,q2,... "
                                                                "(rad, mm for prismatic joints)"),
              tool: Optional[str] = typer.Option(None, "--tool", help="robots: one tool frame (default: every tool)"),
              strict_limits: bool = typer.Option(False, "--strict-limits",
                                                 help="robots: a q outside a joint's limits is an error, not a warning"),
              self_weight: bool = typer.Option(False, "--self-weight",
                                               help="robots: also the tool's sag under the robot's own weight"),
              as_json: bool = typer.Option(False, "--json", help="print JSON (K, C, k_tran, k_rot, rank, frame, units)"),
              foot: Optional[Path] = FOOT, leg: Optional[Path] = LEG):
    """Cartesian stiffness of MODEL at one point (--at), or of a robot at one configuration (--q)."""
    try:
        from ..sweep.spread import bars

        m = _load(model, foot, leg)
        if m.kind == "serial":
            if at is not None or q is None:
                raise VjmError(f"{model} is a serial robot, evaluated in joint space: give --q q1,...,q{m.nq} "
                               f"({', '.join(m.q_names)}), not --at")
            _robot_stiffness(m, q, tool, strict_limits, self_weight, as_json)
            return
        if q is not None or at is None:
            raise VjmError("give --at x,y,z (mm) for a parallel machine (--q is for serial robots)")
        r = m.stiffness(_point(at), spread=bool(bars(m)))
    except user_errors() as exc:
        _fail(exc)
    if as_json:
        from linkfea.files.atomic import file_sha256

        doc = r.to_dict()
        if m.path:  # which model file was used (a bare name may find a local or a bundled one)
            doc["model_file"] = {"path": str(m.path), "sha256": file_sha256(m.path)}
        typer.echo(json.dumps(doc, indent=1))
        return
    np.set_printoptions(precision=4, linewidth=120)
    typer.echo(f"{m.architecture if m.description is None else m.name} at ({at}) mm  "
               f"[world axes, at the end-effector point]")
    typer.echo(f"K (N/mm, N/rad, N mm/rad):\n{r.K}")
    pm = ("", "") if r.k_tran_spread is None else (f" +- {r.k_tran_spread:.2g}", f" +- {r.k_rot_spread:.2g}")
    typer.echo(f"k_tran = {r.k_tran:.4g}{pm[0]} mm/N   (largest eigenvalue of C[:3,:3])")
    typer.echo(f"k_rot  = {r.k_rot:.4g}{pm[1]} rad/(N mm)   (largest eigenvalue of C[3:,3:])")
    if r.k_tran_spread is not None:
        typer.echo("+-: spread from the links' FEA error bars (vjm.sweep.spread; beam and inline links contribute none)")
    typer.echo(f"rank(K) = {r.rank}, rank(J_q) per chain = {np.asarray(r.chain_rank).tolist()}")


def _robot_stiffness(m, q_text: str, tool, strict_limits: bool, self_weight: bool, as_json: bool) -> None:
    """``vjm stiffness robot.yaml --q ...``: K, C at every tool frame (or one), and the sag if asked."""
    try:
        q = np.array([float(v) for v in q_text.split(",")])
    except ValueError:
        q = np.array([np.nan])
    if q.shape != (m.nq,) or not np.all(np.isfinite(q)):
        raise VjmError(f"--q expects {m.nq} numbers q1,...,q{m.nq} for {m.path or m.name} ({', '.join(m.q_names)}; "
                       f"rad, mm for prismatic joints), got {q_text!r}")
    m = m.replace(strict_limits=strict_limits or m.strict_limits)
    tools = [m._tool(tool)] if tool is not None else list(m.tools)
    res = {t: m.stiffness(q, t) for t in tools}
    sag = {t: m.self_weight(q, t) for t in tools} if self_weight else {}
    if as_json:
        doc = {t: {**r.to_dict(), **({"self_weight_twist_mm_rad": sag[t].tolist()} if t in sag else {})}
               for t, r in res.items()}
        typer.echo(json.dumps({"q": q.tolist(), "joints": list(m.q_names), "tools": doc}, indent=1))
        return
    np.set_printoptions(precision=4, linewidth=120)
    for t, r in res.items():
        typer.echo(f"{m.name} at q = ({q_text}), tool {t} at {np.round(r.points, 3).tolist()} mm  "
                   f"[world axes, at the tool point]")
        typer.echo(f"K (N/mm, N/rad, N mm/rad):\n{r.K}")
        typer.echo(f"k_tran = {r.k_tran:.4g} mm/N   (largest eigenvalue of C[:3,:3])")
        typer.echo(f"k_rot  = {r.k_rot:.4g} rad/(N mm)   (largest eigenvalue of C[3:,3:])")
        typer.echo(f"rank(K) = {r.rank}" + ("" if r.invertible else " (no spring deflects some directions: rigid there)"))
        if t in sag:
            typer.echo(f"self-weight sag (dx dy dz mm, rx ry rz rad): {np.array2string(sag[t], precision=4)}")
