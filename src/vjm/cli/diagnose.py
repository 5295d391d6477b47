"""``vjm diagnose``, and :func:`run`, its body.

Errors (VjmError) become one line on stderr and exit status 2, like the other ``vjm`` commands.  ``vjm diagnose``
exits with status 3 when its verdict is ``insufficient_data`` or ``untrusted_data`` (the report
is written, but nothing may be taken as named: the design is too weak to name what fits, or more
than 10 % of the rows are gross outliers), 0 for the other verdicts.
"""
from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from ..errors import user_errors
from .common import _fail

#: exit status of ``vjm diagnose`` when the verdict is "insufficient_data" or "untrusted_data" (report
#: written, nothing named)
INSUFFICIENT_DATA_EXIT = 3
#: the verdicts under which nothing may be taken as named although the report is written
NOTHING_NAMED = ("insufficient_data", "untrusted_data")


def run(model_path, data_path, out_dir, force: bool = False, targets=None, kind=None,
        set_name: str = "vjm diagnose", **kw):
    """Check the arguments, load, ask the registry of data kinds (:mod:`vjm.discrepancy.kinds`; ``kind`` a
    name: that kind), check the output folder, diagnose and write: the body of ``vjm diagnose`` and
    ``vjm calibrate``; returns the Diagnosis.  ``targets`` (a robot's): also commands.csv, the compensation
    of these points on the calibrated model (:func:`vjm.calibration.write.calibrated_commands`)."""
    import dataclasses
    import os

    from linkfea.files.outputs import check_folder

    from ..calibration.write import calibrated_commands
    from ..discrepancy import kinds
    from ..discrepancy.workflow import check_arguments, diagnose
    from ..errors import VjmError
    from ..modelio.read import load_model
    from ..robot.compensate import check_targets

    check_arguments(**{k: v for k, v in kw.items() if k in ("alpha", "max_effects", "suggest") and v is not None})
    if kw.get("min_gain") is None:
        kw.pop("min_gain", None)
    if kw.get("same_setup") and not kw.get("validate"):
        raise VjmError("--same-setup says the --validate files were measured in the fitted data's set-up; give "
                       "--validate")
    # the kind from the model file, not the model: the output folder is checked before any work
    k = kinds.get(kind) if kind is not None else kinds.find(data_path, model_path, kw.get("columns"))
    if targets is not None and not k.commands:
        raise VjmError("--targets is for a serial or tree robot's absolute poses (the commands reaching them); a "
                       "parallel machine's commands are its inverse kinematics")
    check_folder(out_dir, k.output_files(targets is not None), force=force,
                 inputs=(model_path, data_path, kw.get("columns"), *(kw.get("validate") or ()), targets))
    model = load_model(model_path)
    seed = check_targets(model, targets) if targets is not None else None
    dg = diagnose(model, data_path, model_name=kw.pop("model_name", None) or os.path.basename(os.fspath(model_path)),
                  kind=k.name, **kw)
    if targets is not None:
        dg = dataclasses.replace(dg, commands=calibrated_commands(dg.calibration, targets, seed))
    dg.save(out_dir, force=force, set_name=set_name)
    return dg


def effect_names(effect, effects) -> list | None:
    """The effects of ``--effect`` (repeated) and ``--effects a,b`` (kept for the commands written with it), in
    order, ``-name`` an effect excluded (absolute poses: :func:`vjm.calibration.diagnosis.check_options`); None
    when neither is given."""
    names = list(effect or []) + [e.strip() for e in (effects or "").split(",") if e.strip()]
    return names or None


def _tracker(position, noise):
    """The TrackerNoise of --tracker and --tracker-noise (both or neither), or None."""
    from ..discrepancy.tracker import TrackerNoise
    from ..errors import VjmError

    if (position is None) != (noise is None):
        raise VjmError("--tracker and --tracker-noise go together (the tracker's position and its noise)")
    return None if position is None else TrackerNoise.parse(position, noise)


def diagnose_cmd(
    model: Path = typer.Argument(..., help="model YAML (e.g. data/orthoglide/puu.yaml)"),
    data: Path = typer.Argument(..., help="measurements CSV: x,y,z[,ox,oy,oz],Fx..Mz,dx..rz[,sigma_t,sigma_r | ,sigma_dx..sigma_rz] or x,y,z,quantity,value; a robot's: absolute poses (joint values, <frame>.x,.y,.z)"),
    out: Path = typer.Option(..., "--out", help="output directory (report.json, report.html, PNGs, model_updated.yaml; "
                                                "a robot's: report.json, report.html, summary.txt, calibrated.urdf, "
                                                "calibrated.yaml)"),
    alpha: Optional[float] = typer.Option(None, "--alpha", help="family-wise significance level of each selection "
                                                                "round (default 0.01; a robot's: F test level of an "
                                                                "effect, default 0.001)"),
    effect: Optional[List[str]] = typer.Option(None, "--effect", help="restrict the candidates (repeatable); a "
                                                                      "robot's: the effects tried, in this order; "
                                                                      "-name: the default ones but that one "
                                                                      "(absolute poses)"),
    effects: Optional[str] = typer.Option(None, "--effects", help="the same as --effect, comma-separated: a,b"),
    folds: Optional[int] = typer.Option(None, "--folds", help="k-fold cross-validation, 2 to 50 and at most the "
                                                              "postures (default 5; absolute poses: 0 none, at most "
                                                              "the rows, and 0 with --validate)"),
    frame: Optional[List[str]] = typer.Option(None, "--frame", help="a robot's: a measured point fitted "
                                                                    "(repeatable; default: every point of the data)"),
    columns: Optional[Path] = typer.Option(None, "--columns", help="absolute poses (a robot's or a parallel "
                                                                   "machine's): column map YAML (the file's own names, "
                                                                   "units, separator)"),
    validate: Optional[List[Path]] = typer.Option(None, "--validate", help="absolute poses: held-out file (a new "
                                                                           "instrument set-up; repeatable)"),
    register_on: int = typer.Option(30, "--register", help="poses of each --validate file that register its "
                                                           "instrument frame (the robot or machine frozen)"),
    same_setup: bool = typer.Option(False, "--same-setup", help="absolute poses: the --validate files without a "
                                                                "group column were measured in the fitted data's "
                                                                "set-up: every row held out on its registration"),
    targets: Optional[Path] = typer.Option(None, "--targets", help="a robot's: also commands.csv, the joint values "
                                                                  "reaching these points x,y,z[,rx,ry,rz] (mm, rad, "
                                                                  "base frame) under self-weight, calibrated model"),
    min_gain: Optional[float] = typer.Option(None, "--min-gain", help="absolute poses: what an effect must buy "
                                                                     "held out to be named, mm (default 1 %% of the "
                                                                     "error it starts from, at least 10 %% of the "
                                                                     "stated sigma)"),
    verbose: bool = typer.Option(False, "--verbose", "-v", help="print each selection round"),
    suggest: int = typer.Option(0, "--suggest", min=0,
                                help="write DIR/next_measurements.csv: N (posture, load) rows to measure next"),
    forces_only: bool = typer.Option(False, "--forces-only", help="suggest force loads only (no torques)"),
    outliers: bool = typer.Option(True, "--outliers/--no-outliers",
                                  help="set aside rows holding a gross outlier (|z| > 5 robust sigmas) and diagnose "
                                       "the others; more than 10 %% of such rows: verdict untrusted_data"),
    force: bool = typer.Option(False, "--force", help="write into a folder that also holds other files (they are "
                                                      "never overwritten or deleted)"),
    tracker: Optional[str] = typer.Option(None, "--tracker", help="X,Y,Z: position (mm) of the laser tracker that "
                                                                 "measured the translations (with --tracker-noise)"),
    tracker_noise: Optional[str] = typer.Option(None, "--tracker-noise",
                                                help="A,B or AX,AY,AZ,BX,BY,BZ: translation sigma "
                                                     "sqrt(A^2 + (B d)^2) per axis, A mm, B mm/mm, d the distance "
                                                     "from --tracker"),
):
    """Name the physical effect missing from MODEL that the measurements in DATA reveal."""
    try:
        noise = _tracker(tracker, tracker_noise)
        dg = run(model, data, out, alpha=alpha, effects=effect_names(effect, effects), folds=folds, frame=frame or None,
                 progress=(lambda s: typer.echo(s, err=True)) if verbose else None,
                 suggest=suggest, forces_only=forces_only, force=force, outliers=outliers, noise=noise,
                 columns=columns, validate=validate or (), register=register_on, targets=targets,
                 same_setup=same_setup, min_gain=min_gain)
    except user_errors() as exc:
        _fail(exc)
    typer.echo(dg.summary().brief().rstrip("\n"))
    typer.echo(f"Report: {Path(out) / 'report.html'}")
    if suggest:
        typer.echo(f"Next measurements: {Path(out) / 'next_measurements.csv'}")
    if dg.verdict in NOTHING_NAMED:  # the report is written, but nothing may be taken as named
        raise typer.Exit(INSUFFICIENT_DATA_EXIT)
