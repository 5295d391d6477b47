"""``vjm path MODEL TOOLPATH --out DIR``: deflection along a toolpath and the compensated toolpath."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from ..errors import VjmError, one_line, user_errors


def _numbers(text: Optional[str], option: str, k: int):
    if text is None:
        return None
    try:
        v = [float(x) for x in text.split(",")]
    except ValueError:
        raise VjmError(f"{option} expects {k} numbers separated by commas, got {text!r}") from None
    if len(v) != k:
        raise VjmError(f"{option} expects {k} numbers separated by commas, got {text!r}")
    return v


def _wrench_source(wrench, kc, fz, depth, width, diameter):
    from ..toolpath.wrench import Constant, Milling

    milling = [kc, fz, depth, width]
    if wrench is not None and any(v is not None for v in milling):
        raise VjmError("give either --wrench or the milling model (--kc, --feed-per-tooth, --depth, --width), "
                       "not both")
    if any(v is not None for v in milling):
        if any(v is None for v in milling):
            raise VjmError("the milling model needs all of --kc, --feed-per-tooth, --depth and --width")
        return Milling(kc, fz, depth, width, diameter)
    if wrench is not None:
        return Constant(tuple(_numbers(wrench, "--wrench", 6)))
    return None


def _long_run_progress():
    """Progress lines on stderr once ``vjm.path`` has announced a long run (its estimate line); a short run
    stays quiet, as ``vjm map`` does."""
    loud: list = []

    def say(msg: str) -> None:
        if msg.startswith("vjm path: "):
            loud.append(True)
        if loud:
            typer.echo(msg, err=True)

    return say


def path_cmd(model: Path = typer.Argument(..., help="model YAML (e.g. model_updated.yaml of vjm diagnose)"),
             toolpath: Path = typer.Argument(..., help="toolpath: CSV x,y,z[,rx,ry,rz][,Fx..Mz] or G-code"),
             out: Path = typer.Option(..., "--out", help="output folder (path.csv, deflection.png, plan.png, "
                                                         "summary.json, <toolpath>_compensated.<suffix>)"),
             tool: Optional[str] = typer.Option(None, "--tool", help="TCP dx,dy,dz in platform axes, mm (robots: in "
                                                                     "the tool frame's axes)"),
             seed: Optional[str] = typer.Option(None, "--seed", help="robots: the configuration q1,..,qn held along "
                                                                     "the path (default: home: of the model file)"),
             tool_frame: Optional[str] = typer.Option(None, "--tool-frame",
                                                      help="robots: the tool frame (default: the model's first)"),
             wrench: Optional[str] = typer.Option(None, "--wrench", help="constant wrench at the TCP Fx,Fy,Fz,Mx,My,Mz "
                                                                         "(N, N mm) on cutting moves"),
             kc: Optional[float] = typer.Option(None, "--kc", help="milling model: specific cutting force, N/mm^2"),
             fz: Optional[float] = typer.Option(None, "--feed-per-tooth", help="milling model: feed per tooth, mm"),
             depth: Optional[float] = typer.Option(None, "--depth", help="milling model: axial depth of cut, mm"),
             width: Optional[float] = typer.Option(None, "--width", help="milling model: radial width of cut, mm"),
             diameter: Optional[float] = typer.Option(None, "--diameter",
                                                      help="milling model: cutter diameter, mm (default: --width, "
                                                           "a full slot)"),
             method: str = typer.Option("nonlinear", "--method", help="deflection: nonlinear (with the model's "
                                                                      "effects) or linear (C w)"),
             tolerance: Optional[float] = typer.Option(None, "--tolerance", help="pass/fail tolerance, mm"),
             no_compensate: bool = typer.Option(False, "--no-compensate", help="skip the compensated toolpath"),
             linearize_arcs: bool = typer.Option(False, "--linearize-arcs",
                                                 help="write arcs of the compensated G-code as G1 chords"),
             split_moves: bool = typer.Option(False, "--split-moves",
                                              help="write feed moves of the compensated G-code as G1 pieces "
                                                   "of --step mm"),
             chord_tol: float = typer.Option(1e-3, "--chord-tol", help="arc sampling: chord error, mm"),
             step: float = typer.Option(1.0, "--step", help="straight moves: sample spacing, mm"),
             passed: str = typer.Option("MST", "--pass-through",
                                        help="G-code word letters kept verbatim (not interpreted)"),
             workers: int = typer.Option(1, "--workers", help="worker processes for the passes of a long path (threads for short ones)"),
             foot: Optional[Path] = typer.Option(None, "--foot", help="linkfea result JSON replacing the model's foot"),
             leg: Optional[Path] = typer.Option(None, "--leg", help="linkfea result JSON replacing the model's leg"),
             force: bool = typer.Option(False, "--force", help="write into a folder that also holds other files "
                                                               "(they are never overwritten or deleted)")):
    """Deflection of the tool along TOOLPATH under the process wrench, and the compensated toolpath."""
    from linkfea.files.outputs import refuse_inputs

    from ..toolpath.dispatch import path
    from ..toolpath.output import check_out, write_outputs

    try:
        if method not in ("linear", "nonlinear"):
            raise VjmError(f"--method must be linear or nonlinear, got {method!r}")
        if workers < 1:
            raise VjmError(f"--workers must be >= 1, got {workers}")
        if not passed.isalpha() and passed != "":
            raise VjmError(f"--pass-through expects word letters, e.g. MST, got {passed!r}")
        check_out(out, toolpath, force=force)
        refuse_inputs(out, None, (model, toolpath, foot, leg))
        src = _wrench_source(wrench, kc, fz, depth, width, diameter)
        res = path(model, toolpath, wrench=src, tool=_numbers(tool, "--tool", 3), method=method,
                   compensate=not no_compensate, tolerance=tolerance, linearize_arcs=linearize_arcs,
                   split_moves=split_moves,
                   chord_tol=chord_tol, step=step, passed=passed, workers=workers, foot=foot, leg=leg,
                   seed=None if seed is None else _numbers(seed, "--seed", seed.count(",") + 1),
                   tool_frame=tool_frame, progress=_long_run_progress())
        names = write_outputs(res, out)
    except user_errors() as exc:
        typer.echo(f"error: {one_line(exc)}", err=True)
        raise typer.Exit(2) from None
    typer.echo(res.summary())
    typer.echo(f"wrote {out}/" + ", ".join(names))
    if res.passed is False:
        raise typer.Exit(1)
