"""``vjm calibrate``: a robot calibrated on absolute poses, held out, written back as one set.

The calibration-only form of ``vjm diagnose``: the same body (:func:`vjm.cli.diagnose.run`), the data kind
fixed to a robot's absolute poses (:class:`vjm.discrepancy.kinds.RobotPoseData`), the same flags for what
they share and the same report files (report.json, report.html, summary.txt, calibrated.urdf,
calibrated.yaml; commands.csv with ``--targets``).
"""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from ..errors import user_errors
from .common import FORCE, _fail


def calibrate_cmd(model: Path = typer.Argument(..., help="robot model YAML (urdf: ...)"),
                  data: Path = typer.Argument(..., help="absolute poses: joint values and measured points per row"),
                  columns: Optional[Path] = typer.Option(None, "--columns", help="column map YAML: the files' own "
                                                         "names, units, separator, decimal mark"),
                  validate: Optional[list[Path]] = typer.Option(None, "--validate", help="held-out file (a new "
                                                                "instrument set-up; repeatable)"),
                  register_on: int = typer.Option(30, "--register", help="poses of each --validate file that "
                                                  "register its instrument frame (the robot frozen)"),
                  same_setup: bool = typer.Option(False, "--same-setup", help="the --validate files without a group "
                                                  "column were measured in the fitted data's set-up: every row "
                                                  "held out on its registration"),
                  folds: Optional[int] = typer.Option(None, "--folds", help="k-fold cross-validation in the choice "
                                                      "of effects (0: none, else 2 to 50 and at most the rows; "
                                                      "default 5, or 0 with --validate)"),
                  effect: Optional[list[str]] = typer.Option(None, "--effect", help="an effect tried (repeatable, "
                                                             "in this order; default: every effect that applies to "
                                                             "the robot and the data: geometry, compliance, "
                                                             "coupling, lateral, bending, varying, thermal, tilt, "
                                                             "backlash, payload, guide_tilt, column_tilt, link_scale; "
                                                             "-name: all "
                                                             "but that one)"),
                  min_gain: Optional[float] = typer.Option(None, "--min-gain", help="what an effect must buy held "
                                                           "out to be named, mm (default 1 %% of the error it starts "
                                                           "from, at least 10 %% of the stated sigma)"),
                  effects: Optional[str] = typer.Option(None, "--effects", help="the same as --effect, "
                                                        "comma-separated: a,b"),
                  frame: Optional[list[str]] = typer.Option(None, "--frame", help="a measured point (repeatable; "
                                                            "default: every point of the data)"),
                  alpha: Optional[float] = typer.Option(None, "--alpha", help="F test level of an effect "
                                                        "(default 0.001)"),
                  targets: Optional[Path] = typer.Option(None, "--targets", help="also commands.csv: the joint values "
                                                         "reaching these points x,y,z[,rx,ry,rz] (mm, rad, base frame) "
                                                         "under self-weight on the calibrated model (seed: home:)"),
                  outliers: bool = typer.Option(True, "--outliers/--no-outliers", help="set aside the rows no "
                                                "effect explains"),
                  verbose: bool = typer.Option(False, "--verbose", "-v", help="print each stage"),
                  out: Path = typer.Option(..., "--out", help="output folder"),
                  force: bool = FORCE):
    """Calibrate a robot on absolute poses (laser tracker, camera): registration, geometry, joint compliance
    under self-weight; held out; the calibrated URDF and robot file written back."""
    from .diagnose import effect_names, run

    try:
        from ..discrepancy.kinds import get

        files = get("absolute").output_files(targets is not None)
        dg = run(model, data, out, force=force, targets=targets, kind="absolute", set_name="vjm calibrate",
                 model_name=str(model), alpha=alpha, effects=effect_names(effect, effects), folds=folds,
                 frame=frame or None, columns=columns, validate=validate or (), register=register_on,
                 same_setup=same_setup, outliers=outliers, min_gain=min_gain,
                 progress=(lambda s: typer.echo(s, err=True)) if verbose else None)
    except user_errors() as exc:
        _fail(exc)
    typer.echo(dg.summary().brief(), nl=False)
    typer.echo(f"wrote {out}/" + ", ".join(files))
