"""``vjm map``: stiffness maps over a workspace grid (a robot's: over two joints or a Cartesian grid, :mod:`.robot_map`)."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import numpy as np
import typer

from ..errors import ArgumentError, VjmError, user_errors
from .common import FOOT, FORCE, LEG, _fail, _load, _point, _progress


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
            compare: Optional[Path] = typer.Option(None, "--compare", help="the --out folder of another map on the "
                                                   "same grid: also write this map's k_tran and k_rot over the "
                                                   "other's (ratio.npz, k_tran_ratio.png, k_rot_ratio.png); the "
                                                   "other folder is only read"),
            foot: Optional[Path] = FOOT, leg: Optional[Path] = LEG, force: bool = FORCE):
    """k_tran and k_rot over the workspace box: PNG maps and an .npz of K, k_tran, k_rot; robots: over two
    joints (--joints) or a Cartesian grid through the IK."""
    from linkfea.files.outputs import check_folder
    from linkfea.runtime.checks import integer

    from ..maps import compare as cmp
    from ..maps.compute import GRID, MAP_FILES

    robot_only = {"--joints": joints, "--q": q, "--box": box, "--tool": tool, "--self-weight": self_weight or None}
    try:
        grid = integer(grid, "grid", GRID, ArgumentError)
        if compare is not None:
            cmp.check_other(out, compare)
        other = None if compare is None else cmp.read_map(compare)
        check_folder(out, MAP_FILES + (cmp.RATIO_FILES if compare else ()), force=force,
                     inputs=(model, foot, leg, *([compare / "map.npz"] if compare else [])))  # before any work (a robot's set, a superset, checked again)
        m = _load(model, foot, leg)
        if m.kind == "serial":
            if spread:
                raise ArgumentError("spread", "is for parallel machines with FEA links; a robot map has none")
            if compare is not None:
                raise VjmError("--compare is for maps of parallel machines; compare a robot's map.csv files instead")
            from .robot_map import Request, run

            text = run(m, Request(grid, slice_, box, joints, q, orientation, tool, self_weight), out, force)
            typer.echo(f"{text}; wrote {out}/")
            return
        given = [k for k, v in robot_only.items() if v is not None]
        if given:
            raise VjmError(f"{given[0]} is for serial robots; {model} is a parallel machine")
        rot = _point(orientation or "0,0,0", "--orientation", (3,))
        smap = m.map(grid, slice_, orientation=rot, progress=_progress, spread=spread)
        ratio = None if other is None else cmp.ratios(smap, other)  # a grid that differs: refused before writing
        smap.save(out, force=force)
        if other is None:
            cmp.drop_ratio(out)
        else:
            cmp.save_ratio(smap, other, out, ratio)
    except user_errors() as exc:
        _fail(exc)
    wrote = "k_tran.png, k_rot.png, map.npz" + (", " + ", ".join(cmp.RATIO_FILES) if other else "")
    typer.echo(f"{smap.summary()}; wrote {out}/{wrote}")
    if ratio is not None:
        typer.echo(f"this map over {compare}: k_tran x{np.nanmin(ratio[0]):.3g}..{np.nanmax(ratio[0]):.3g}, "
                   f"k_rot x{np.nanmin(ratio[1]):.3g}..{np.nanmax(ratio[1]):.3g}")
