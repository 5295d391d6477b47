"""``vjm simulate``: synthetic measurements of a model with hidden effects (a robot's: absolute poses)."""
from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from ..errors import user_errors
from .common import _fail


def simulate_cmd(
    model: Path = typer.Argument(..., help="model YAML"),
    effect: Optional[List[str]] = typer.Option(None, "--effect", help="hidden effect NAME[:param=value,...] (repeatable)"),
    poses: Optional[str] = typer.Option(None, "--poses", help="grid:N | random:N | CSV with x,y,z[,ox,oy,oz] "
                                                               "(default grid:4); robots: random:N (default "
                                                               "random:100) | CSV of joint values"),
    loads: str = typer.Option("axes:100", "--loads", help="axes:F[:M] | random:N:F | CSV with Fx..Mz; several "
                                                           "magnitudes (load levels): axes:50,100, random:N:50,100"),
    noise_t: float = typer.Option(0.001, "--noise-t", help="translation noise sigma, mm"),
    noise_r: Optional[float] = typer.Option(None, "--noise-r", help="rotation noise sigma, rad (omit: rotations not measured)"),
    seed: int = typer.Option(0, "--seed"),
    out: Path = typer.Option(..., "--out", help="output CSV"),
    tilt: float = typer.Option(0.0, "--tilt", help="6-dof platform: random orientations of grid/random poses, "
                                                   "each rotation-vector component within +-TILT rad"),
):
    """Write synthetic measurements of MODEL with hidden effects (a robot: absolute poses for vjm calibrate or diagnose)."""
    from ..discrepancy.simulate import run

    try:
        from linkfea.files.outputs import refuse_inputs

        from ..calibration.simulate import simulate_robot

        refuse_inputs(out, (), (model, poses, loads))
        n = simulate_robot(model, effect or [], poses, loads, noise_t, noise_r, seed, out, tilt)
        if n is not None:
            typer.echo(f"wrote {n} absolute poses to {out}")
            return
        d = run(model, effect or [], poses or "grid:4", loads, noise_t, noise_r, seed, out,
                progress=lambda line: typer.echo(line, err=True), tilt=tilt)
    except user_errors() as exc:
        _fail(exc)
    typer.echo(f"wrote {d.n} measurements to {out}")
