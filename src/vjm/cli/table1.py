"""``vjm table1``: the seed's Table 1, our k_tran and k_rot at Q0, Q1, Q2 beside the paper's."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from ..errors import user_errors
from .common import FOOT, _fail, _load


def table1(model_puu: Path = typer.Argument(..., help="3-PUU model YAML"),
           model_prpar: Path = typer.Argument(..., help="3-PRPaR model YAML"),
           foot: Optional[Path] = FOOT,
           leg: Optional[Path] = typer.Option(None, "--leg", help="linkfea JSON for the 3-PUU leg"),
           bar: Optional[Path] = typer.Option(None, "--bar", help="linkfea JSON for one 3-PRPaR bar")):
    """Seed Table 1: our k_tran and k_rot at Q0, Q1, Q2 beside the paper's."""
    from ..studies.table1 import check_order, report_lines, table1_rows

    try:
        models = [_load(model_puu, foot, leg), _load(model_prpar, foot, bar)]
        check_order(models, (model_puu, model_prpar))
        rows = table1_rows(models)
    except user_errors() as exc:
        _fail(exc)
    for line in report_lines(rows, models):
        typer.echo(line)
