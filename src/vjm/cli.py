"""``vjm`` command line: stiffness at a point, stiffness maps, the seed's Table 1.

Every command turns a VjmError into one line on stderr and exit status 2.
New commands register on ``app`` (see the end of this file).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Optional

import numpy as np
import typer

from .errors import ArgumentError, VjmError, one_line, user_errors

app = typer.Typer(add_completion=False, help="Virtual-joint-method stiffness of parallel machines.")


@app.callback()
def _root():
    """Virtual-joint-method stiffness of parallel machines."""
    from linkfea.runtime.errors import LinkFeaWarning, warnings_as_lines

    from .errors import VjmWarning

    warnings_as_lines(VjmWarning, LinkFeaWarning)


def _fail(exc: Exception):
    typer.echo(f"error: {one_line(exc)}", err=True)
    raise typer.Exit(2)


def _load(model: Path, foot: Optional[Path], leg: Optional[Path]):
    from .modelio.read import load_model
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


@app.command()
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
        from .sweep.spread import bars

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


@app.command("map")
def map_cmd(model: Path = typer.Argument(..., help="model YAML"),
            grid: int = typer.Option(30, "--grid", help="points per axis (robots: also per joint of --joints)"),
            slice_: Optional[str] = typer.Option(None, "--slice", help="fix one axis, e.g. z=0"),
            orientation: Optional[str] = typer.Option(None, "--orientation",
                                                      help="6-dof platforms: the fixed platform rotation vector "
                                                           "rx,ry,rz (rad) of the map (default 0,0,0); robots: the "
                                                           "tool's (default: as at --q)"),
            out: Path = typer.Option(..., "--out", help="output directory (k_tran.png, k_rot.png, map.npz; "
                                                        "robots also map.csv, summary.json)"),
            spread: bool = typer.Option(False, "--spread",
                                        help="also save k_tran_spread and k_rot_spread (map.npz), the spread from "
                                             "the links' FEA error bars; costs one more spring evaluation per FEA "
                                             "link (1.4-3x the map's time); zero if no link has an error estimate"),
            joints: Optional[str] = typer.Option(None, "--joints", help="robots: a joint-space map of two joints, "
                                                                        "name=lo:hi[:n] each, e.g. q2=-2:0:41,q3=0:2.5:41"),
            q: Optional[str] = typer.Option(None, "--q", help="robots: the other joints' values (joint map) or the "
                                                              "IK's seed configuration (default: the file's home:)"),
            box: Optional[str] = typer.Option(None, "--box", help="robots: the Cartesian grid's box x0:x1,y0:y1,z0:z1 "
                                                                  "mm (default: the tool's reach)"),
            tool: Optional[str] = typer.Option(None, "--tool", help="robots: the tool frame (default: the first)"),
            self_weight: bool = typer.Option(False, "--self-weight", help="robots: also the sag under the robot's "
                                                                          "own weight (sag.png)"),
            foot: Optional[Path] = FOOT, leg: Optional[Path] = LEG, force: bool = FORCE):
    """k_tran and k_rot over the workspace box: PNG maps and an .npz of K, k_tran, k_rot; robots: over two
    joints (--joints) or a Cartesian grid through the IK."""
    from linkfea.files.outputs import check_folder
    from linkfea.runtime.checks import integer

    from .maps.compute import GRID, MAP_FILES

    robot_only = {"--joints": joints, "--q": q, "--box": box, "--tool": tool, "--self-weight": self_weight or None}
    try:
        grid = integer(grid, "grid", GRID, ArgumentError)
        check_folder(out, MAP_FILES, force=force)  # before any work (a robot's set, a superset, checked again)
        m = _load(model, foot, leg)
        if m.kind == "serial":
            if spread:
                raise ArgumentError("spread", "is for parallel machines with FEA links; a robot map has none")
            from .robot.mapcmd import Request, run

            text = run(m, Request(grid, slice_, box, joints, q, orientation, tool, self_weight), out, force)
            typer.echo(f"{text}; wrote {out}/")
            return
        given = [k for k, v in robot_only.items() if v is not None]
        if given:
            raise VjmError(f"{given[0]} is for serial robots; {model} is a parallel machine")
        rot = _point(orientation or "0,0,0", "--orientation", (3,))
        smap = m.map(grid, slice_, orientation=rot, progress=_progress, spread=spread)
        smap.save(out, force=force)
    except user_errors() as exc:
        _fail(exc)
    typer.echo(f"{smap.summary()}; wrote {out}/k_tran.png, k_rot.png, map.npz")


@app.command()
def table1(model_puu: Path = typer.Argument(..., help="3-PUU model YAML"),
           model_prpar: Path = typer.Argument(..., help="3-PRPaR model YAML"),
           foot: Optional[Path] = FOOT,
           leg: Optional[Path] = typer.Option(None, "--leg", help="linkfea JSON for the 3-PUU leg"),
           bar: Optional[Path] = typer.Option(None, "--bar", help="linkfea JSON for one 3-PRPaR bar")):
    """Seed Table 1: our k_tran and k_rot at Q0, Q1, Q2 beside the paper's."""
    from .studies.table1 import check_order, report_lines, table1_rows

    try:
        models = [_load(model_puu, foot, leg), _load(model_prpar, foot, bar)]
        check_order(models, (model_puu, model_prpar))
        rows = table1_rows(models)
    except user_errors() as exc:
        _fail(exc)
    for line in report_lines(rows, models):
        typer.echo(line)


@app.command("sweep")
def sweep_cmd(model: Path = typer.Argument(..., help="model YAML"),
              foot: Optional[Path] = typer.Option(None, "--foot", help="`linkfea sweep` folder or result JSON"),
              leg: Optional[Path] = typer.Option(None, "--leg", help="`linkfea sweep` folder or result JSON"),
              bar: Optional[Path] = typer.Option(None, "--bar", help="parallelogram legs: the bar's sweep or JSON"),
              grid: int = typer.Option(9, "--grid", help="points per axis of the workspace grid"),
              out: Path = typer.Option(..., "--out", help="output folder (tradeoffs.csv/.parquet, pareto.*)"),
              force: bool = FORCE):
    """Machine trade-offs: every combination of link designs, worst/mean k_tran and k_rot, mass, Pareto set."""
    from .sweep.combine import sweep

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


@app.command("calibrate")
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

        from .robot import calibreport as cr
        from .robot import compcmd as cc

        asked = tuple(e.strip() for e in effects.split(",") if e.strip()) if effects is not None else None
        opt = cr.Options(tuple(frame or ()), asked or cr.DEFAULT_EFFECTS, alpha,
                         (0 if validate else 5) if folds is None else folds, register_on)
        cr.check_options(opt)
        files = cr.FILES + (("commands.csv",) if targets is not None else ())
        check_folder(out, files, force=force)
        m, d, vals, opt = cr.inputs(model, data, columns, validate or [], opt, asked is not None)
        seed = cc.check_targets(m, targets) if targets is not None else None
        t0 = time.perf_counter()
        cal, held = cr.run(m, d, vals, opt)
        rep = cr.report(cal, opt, model, d, held, time.perf_counter() - t0)
        extra = {"commands.csv": cc.calibrated_commands(cal, targets, seed)} if targets is not None else None
        cr.write_set(out, cal, rep, force, extra=extra)
    except user_errors() as exc:
        _fail(exc)
    typer.echo(cr.summary(rep), nl=False)
    typer.echo(f"wrote {out}/" + ", ".join(files))


@app.command("compensate")
def compensate_cmd(model: Path = typer.Argument(..., help="robot model YAML (urdf: or dh:)"),
                   targets: Path = typer.Argument(..., help="targets CSV: x,y,z[,rx,ry,rz] (mm, rad; the robot's base "
                                                            "frame); without rx,ry,rz the orientation is free"),
                   seed: Optional[str] = typer.Option(None, "--seed", help="the configuration: joint values q1,... "
                                                      "(rad, mm prismatic) or home (default: the file's home:)"),
                   tool: Optional[str] = typer.Option(None, "--tool", help="the tool frame (default: the first)"),
                   payload: Optional[str] = typer.Option(None, "--payload", help="KG[@x,y,z]: a point mass at a point "
                                                         "(mm) of the tool frame"),
                   tol: float = typer.Option(1e-6, "--tol", help="tolerance of the deflected tool pose, mm"),
                   out: Path = typer.Option(..., "--out", help="commands CSV (joint values, residual_mm, converged)")):
    """The joint values to command so that the tool, sagging under the robot's weight, reaches each target."""
    try:
        from .robot.compcmd import Request, run

        m = _load(model, None, None)
        text = run(m, Request(str(targets), seed, tool, payload, tol), out)
    except user_errors() as exc:
        _fail(exc)
    typer.echo(f"{text}; wrote {out}")


def _register_extensions():
    try:
        from .discrepancy.cli import register
    except ModuleNotFoundError:
        return
    register(app)
    from .toolpath.cli import register as register_path

    register_path(app)


_register_extensions()


def main(argv=None) -> int:
    """Console entry point (``vjm``): the exit status; a usage error is one ``error:`` line."""
    from linkfea.runtime.clirun import run

    return run(app, argv, "vjm")


if __name__ == "__main__":
    sys.exit(main())
