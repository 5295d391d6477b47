"""``vjm design``: the lightest machine whose stiffness constraints hold, its links from their CAD by FEA."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from ..errors import VjmError, user_errors
from .common import FORCE, _fail, _progress


def _targets(text: Optional[str]):
    if text is None:
        return None
    try:
        return [float(t) for t in text.split(",")]
    except ValueError:
        raise VjmError(f"--targets expects k_tran_max limits (mm/N) separated by commas, got {text!r}") from None


def design_cmd(spec: Path = typer.Argument(..., help="design spec YAML (machine, free links, constraints, budget)"),
               out: Path = typer.Option(..., "--out", help="output folder (design.json ...; links/ is the FEA cache)"),
               targets: Optional[str] = typer.Option(None, "--targets",
                                                     help="k_tran_max limits (mm/N), e.g. 0.03,0.02,0.015: the "
                                                          "mass-stiffness front (front.csv, front.png)"),
               conservative: bool = typer.Option(False, "--conservative",
                                                 help="constraints hold at the top of the FEA error bar"),
               budget: Optional[int] = typer.Option(None, "--budget", help="FEA runs at most (default: the spec's)"),
               workers: Optional[int] = typer.Option(None, "--workers", help="local Dask workers (default: one per core)"),
               scheduler: Optional[str] = typer.Option(None, "--scheduler", help="address of a Dask scheduler"),
               seed: Optional[int] = typer.Option(None, "--seed", help="seed of the starting designs (default: the spec's)"),
               force: bool = FORCE):
    """Design synthesis: the lightest links (by CAD and FEA) whose machine meets the stiffness constraints."""
    from ..synthesis.run import design

    try:   # Ctrl-C: exit 130 (the command line's own handling); every finished FEA design is in the cache
        res = design(spec, out, budget=budget, workers=workers, scheduler=scheduler, seed=seed,
                     targets=_targets(targets), conservative=conservative or None, force=force, progress=_progress)
    except user_errors() as exc:
        _fail(exc)
    typer.echo(res.summary())
    typer.echo(f"wrote {out}/design.json, convergence.png, report.html"
               + (", front.csv, front.png" if res.front else "") + ", optimum_*")
