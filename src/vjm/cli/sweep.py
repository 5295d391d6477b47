"""``vjm sweep``: machine trade-offs over every combination of link designs, with the Pareto set."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from ..errors import VjmError, user_errors
from .common import FORCE, _fail, _progress


def sweep_cmd(model: Path = typer.Argument(..., help="model YAML"),
              foot: Optional[Path] = typer.Option(None, "--foot", help="`linkfea sweep` folder or result JSON"),
              leg: Optional[Path] = typer.Option(None, "--leg", help="`linkfea sweep` folder or result JSON"),
              bar: Optional[Path] = typer.Option(None, "--bar", help="parallelogram legs: the bar's sweep or JSON"),
              grid: int = typer.Option(9, "--grid", help="points per axis of the workspace grid"),
              out: Path = typer.Option(..., "--out", help="output folder (tradeoffs.csv/.parquet, pareto.*)"),
              force: bool = FORCE):
    """Machine trade-offs: every combination of link designs, worst/mean k_tran and k_rot, mass, Pareto set."""
    from ..sweep.combine import sweep

    try:
        if foot is None and leg is None and bar is None:
            raise VjmError("give link designs with --foot, --leg or --bar (a `linkfea sweep` folder or a result JSON)")
        res = sweep(model, out, grid, foot=foot, leg=leg, bar=bar, force=force, progress=_progress)
    except user_errors() as exc:
        _fail(exc)
    front = sorted((r for r in res.rows if r["pareto"]), key=lambda r: r["moving_mass_kg"])
    roles = [k for k in ("foot", "leg") if k in res.rows[0]]
    typer.echo(f"{len(res.rows)} combinations on {res.n_points} reachable points; non-dominated "
               f"(moving mass kg, worst k_tran mm/N):")
    for r in front:
        typer.echo("  " + " ".join(f"{k}={r[k]}" for k in roles)
                   + f"  {r['moving_mass_kg']:.4g} kg  {r['k_tran_max']:.4g} mm/N")
    typer.echo(f"wrote {out}/tradeoffs.csv, tradeoffs.parquet, pareto.csv, pareto.json, pareto.png")
