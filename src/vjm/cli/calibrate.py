"""``vjm calibrate``: a robot calibrated on absolute poses, held out, written back as one set."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from ..errors import user_errors
from .common import FORCE, _fail

#: memory (B) and time (s) per row of a calibration at the default effects and folds, for the estimate before
#: the work: 6 kB measured (UR10, 20,000 rows); 1.5 ms (200,000 rows on one machine) to 10 ms (20,000 rows on a
#: shared 2-core one)
ROW_COST = (8e3, 5e-3)


def calibrate_cmd(model: Path = typer.Argument(..., help="robot model YAML (urdf: ...)"),
                  data: Path = typer.Argument(..., help="absolute poses: joint values and measured points per row"),
                  columns: Optional[Path] = typer.Option(None, "--columns", help="column map YAML: the files' own "
                                                         "names, units, separator, decimal mark"),
                  validate: Optional[list[Path]] = typer.Option(None, "--validate", help="held-out file (a new "
                                                                "instrument set-up; repeatable)"),
                  register_on: int = typer.Option(30, "--register", help="poses of each --validate file that "
                                                  "register its instrument frame (the robot frozen)"),
                  folds: Optional[int] = typer.Option(None, "--folds", help="k-fold cross-validation in the choice "
                                                      "of effects (0: none; default 5, or 0 with --validate)"),
                  effects: Optional[str] = typer.Option(None, "--effects",
                                                        help="stages tried, in this order (default geometry,"
                                                             "compliance,payload; also: coupling, lateral, bending, "
                                                             "varying, thermal, tilt, backlash)"),
                  frame: Optional[list[str]] = typer.Option(None, "--frame", help="a measured point (repeatable; "
                                                            "default: every point of the data)"),
                  alpha: float = typer.Option(1e-3, "--alpha", help="F test level of an effect"),
                  targets: Optional[Path] = typer.Option(None, "--targets", help="also commands.csv: the joint values "
                                                         "reaching these points x,y,z[,rx,ry,rz] (mm, rad, base frame) "
                                                         "under self-weight on the calibrated model (seed: home:)"),
                  out: Path = typer.Option(..., "--out", help="output folder"),
                  force: bool = FORCE):
    """Calibrate a robot on absolute poses (laser tracker, camera): registration, geometry, joint compliance
    under self-weight; held out; the calibrated URDF and robot file written back."""
    import time

    try:
        from linkfea.files.outputs import check_folder

        from ..calibration import report as cr
        from ..calibration.write import calibrated_commands
        from ..maps.grid import plan
        from ..robot.compensate import check_targets

        asked = tuple(e.strip() for e in effects.split(",") if e.strip()) if effects is not None else None
        opt = cr.Options(tuple(frame or ()), asked or cr.default_effects(), alpha,
                         (0 if validate else 5) if folds is None else folds, register_on)
        cr.check_options(opt)
        files = cr.FILES + (("commands.csv",) if targets is not None else ())
        check_folder(out, files, force=force, inputs=(model, data, columns, *(validate or ()), targets))
        m, d, vals, opt = cr.inputs(model, data, columns, validate or [], opt, asked is not None)
        plan("vjm calibrate", d.n, *ROW_COST, unit="rows", hint="calibrate on a subset of the rows (postures "
             "spread over the workspace, not repeats)", progress=lambda line: typer.echo(line, err=True))
        seed = check_targets(m, targets) if targets is not None else None
        t0 = time.perf_counter()
        cal, held = cr.run(m, d, vals, opt)
        rep = cr.report(cal, opt, model, d, held, time.perf_counter() - t0)
        extra = {"commands.csv": calibrated_commands(cal, targets, seed)} if targets is not None else None
        cr.write_set(out, cal, rep, force, extra=extra)
    except user_errors() as exc:
        _fail(exc)
    typer.echo(cr.summary(rep), nl=False)
    typer.echo(f"wrote {out}/" + ", ".join(files))
