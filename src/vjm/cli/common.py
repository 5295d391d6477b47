"""What the ``vjm`` commands share: one ``error:`` line for a user error, model loading, point parsing,
progress lines, common options."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import numpy as np
import typer

from ..errors import VjmError, one_line


def _fail(exc: Exception):
    typer.echo(f"error: {one_line(exc)}", err=True)
    raise typer.Exit(2)


def _load(model: Path, foot: Optional[Path], leg: Optional[Path]):
    from ..modelio.read import load_model
    return load_model(model, foot=foot, leg=leg)


def _point(text: str, option: str = "--at", sizes=(3, 6)) -> np.ndarray:
    """x,y,z (mm) or x,y,z,rx,ry,rz (rotation vector, rad) from the command line."""
    try:
        p = np.array([float(v) for v in text.split(",")])
    except ValueError:
        raise VjmError(f"{option} expects numbers x,y,z[,rx,ry,rz] (mm, rad), got {text!r}") from None
    if not np.all(np.isfinite(p)):
        raise VjmError(f"{option} expects finite numbers x,y,z[,rx,ry,rz] (mm, rad), got {text!r}")
    if p.shape[0] not in sizes:
        raise VjmError(f"{option} expects {' or '.join(map(str, sizes))} numbers "
                       f"({'x,y,z' if 3 in sizes else ''}{'[,rx,ry,rz]' if 6 in sizes else 'rx,ry,rz'}), "
                       f"got {text!r}")
    return p


def _progress(line: str) -> None:
    """Progress of a long run, one line each on stderr."""
    typer.echo(line, err=True)


FOOT = typer.Option(None, "--foot", help="linkfea result JSON replacing the model's foot")
FORCE = typer.Option(False, "--force", help="write into a folder that also holds other files (they are never "
                                            "overwritten or deleted)")
LEG = typer.Option(None, "--leg", help="linkfea result JSON replacing the model's leg (one bar for parallelograms)")
