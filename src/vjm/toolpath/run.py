"""``vjm.path(...)``: deflection along a toolpath, its uncertainty, and the compensated toolpath.

The pipeline: read the toolpath, check it against the machine (orientations on
a 3-dof platform, reachability), the process wrench per point, the TCP's
deflection (linear or nonlinear), the calibration's band, the compensated
commands (nonlinear, with the model's effects), the compensated program in
the input's own format.  Nothing is written here (see :mod:`vjm.toolpath.output`).
"""
from __future__ import annotations

import functools
import os

import numpy as np

from linkfea.runtime.progress import or_quiet

from ..compensation import Compensation
from ..errors import VjmError
from . import gcode as gc
from . import uncertainty as unc
from .deflect import check_effects, platform_poses, tcp_deflection
from .equilibrium import RTOL
from .passes import deflect_and_compensate
from .points import Toolpath, csv_text, path_plan, write_csv
from .points import read as read_toolpath
from .result import PathResult
from .wrench import PerPoint


def _model(model, foot=None, leg=None):
    from .. import load_model

    if isinstance(model, (str, os.PathLike)):
        return load_model(model, foot=foot, leg=leg)
    return model


def check_machine(model, tp: Toolpath, tool) -> None:
    """Refuse a toolpath the machine cannot follow: orientations on a 3-dof platform, unreachable points."""
    if tp.has_orientation and model.dof == 3:
        raise VjmError(f"{tp.source}: the toolpath gives orientations (rx, ry, rz) but the machine's platform "
                       f"only translates (3 dof); drop the columns rx,ry,rz")
    P, _ = platform_poses(model, tp.poses, tool)
    ok = np.asarray(model.arch.reachable(model, P if model.dof == 6 else P[:, :3]), bool)
    if not ok.all():
        i = int(np.argmax(~ok))
        raise VjmError(f"{tp.where(i)}: the programmed point {np.round(tp.points[i], 6).tolist()} mm is outside "
                       f"the machine's workspace (or needs an actuator outside its limits)")


LARGE_DEFLECTION = 0.1
"""A wrench whose linear deflection passes this share of the workspace diagonal (or :data:`LARGE_ROTATION`)
is refused at once: the models are small-deflection models, and the nonlinear equilibrium spent 80 s failing on
``--wrench 1e300,...`` before saying so."""


LARGE_ROTATION = 1.0
"""Largest linear rotation of the platform (rad) accepted from a wrench (a test of large loads reaches 0.1)."""


def check_load(model, tp: Toolpath, W: np.ndarray, tool) -> None:
    """Refuse a wrench far beyond the model's range, from the linear deflection at its largest point."""
    from .deflect import linear

    if not W.size or not np.abs(W).max() > 0:
        return
    i = int(np.argmax(np.abs(W).max(axis=1)))
    with np.errstate(all="ignore"):  # 1e300 N: the products overflow, which is the answer
        d = linear(model, tp.poses[i:i + 1], W[i:i + 1], tool)[0]
        t, r = float(np.linalg.norm(d[:3])), float(np.linalg.norm(d[3:]))
    ws = model.workspace
    size = float(np.linalg.norm(np.asarray(ws.hi, float) - np.asarray(ws.lo, float)))
    if not (t <= LARGE_DEFLECTION * size and r <= LARGE_ROTATION):
        raise VjmError(f"{tp.where(i)}: the wrench {','.join(f'{v:g}' for v in W[i])} (N, N mm) "
                       f"deflects the tool by {t:.3g} mm and {r:.3g} rad in the linear model, beyond "
                       f"{LARGE_DEFLECTION:g} x the workspace ({size:.3g} mm) or {LARGE_ROTATION:g} rad, where the model "
                       "holds; "
                       "check the wrench and its units")


def _tool(tool) -> np.ndarray:
    t = np.zeros(3) if tool is None else np.asarray(tool, dtype=float)
    if t.shape != (3,) or not np.all(np.isfinite(t)):
        raise VjmError(f"tool must be three finite numbers dx,dy,dz (mm, platform axes), got {tool!r}")
    return t


def blend_after(tp: Toolpath, cmd: np.ndarray, residual_vec: np.ndarray) -> np.ndarray:
    """(n, 6) first-order error of the written program from the programmed path at every cutting sample
    (NaN on rapid moves).

    Between two written end points the program moves along the chord (or the kept arc) through
    the compensated end points, so a sample's command is the blend of their corrections; the
    error there is the blend's distance from the exact command plus the residual.
    """
    delta = cmd[:, :3] - tp.points
    s = tp.arc_length()
    vi = np.flatnonzero(tp.vertex)
    nxt = vi[np.minimum(np.searchsorted(vi, np.arange(tp.n)), len(vi) - 1)]
    prv = vi[np.maximum(np.searchsorted(vi, np.arange(tp.n), side="right") - 1, 0)]
    span = s[nxt] - s[prv]
    t = np.divide(s - s[prv], span, out=np.zeros(tp.n), where=span > 0)
    written = delta[prv] + t[:, None] * (delta[nxt] - delta[prv])
    out = np.zeros((tp.n, 6))
    out[:, :3] = (written - delta) + residual_vec
    out[~tp.cutting] = np.nan  # rapid moves cut nothing
    return out


def arc_centre(m, s, e, guess) -> np.ndarray:
    """The centre of the compensated arc from ``s`` to ``e``: the point of their perpendicular bisector
    (in the arc's plane) nearest ``guess``, so that both ends are on one circle; a full circle keeps ``guess``."""
    u, v, _ = gc.PLANE_AXES[m.plane]
    chord = (e - s)[[u, v]]
    L = np.linalg.norm(chord)
    if L < 1e-9:
        return guess
    nrm = np.array([-chord[1], chord[0]]) / L
    mid = 0.5 * (s + e)
    out = np.array(guess, dtype=float)
    out[[u, v]] = mid[[u, v]] + nrm * float(nrm @ (guess - mid)[[u, v]])
    return out


def compensated_text(tp: Toolpath, cmd: np.ndarray, linearize_arcs: bool = False, split: bool = False) -> str:
    """The compensated toolpath in the input's format (CSV, or the same G-code with new coordinates).

    ``linearize_arcs``: arcs become G1 chords through their compensated samples; ``split``: every
    feed move (G1, G2, G3) becomes G1 pieces through its compensated samples (``step`` apart).
    """
    if tp.kind == "csv":
        return csv_text(tp, cmd)
    return gc.write_text_of(compensated_program(tp, cmd, linearize_arcs, split))


def compensated_program(tp: Toolpath, cmd: np.ndarray, linearize_arcs: bool = False,
                        split: bool = False) -> gc.Program:
    """The compensated G-code program of :func:`compensated_text` (a G-code toolpath)."""
    prog = tp.program
    li = tp.line_index
    assert prog is not None and li is not None  # a G-code toolpath
    vi = np.flatnonzero(tp.vertex)
    new_end = {int(li[i]): cmd[i, :3] for i in vi}
    centres = {}
    pieces = {}
    for i, m in {m.line: m for m in gc.moves(prog)}.items():
        rows = np.flatnonzero(li == i)
        if split and m.kind != 0 and not np.isnan(m.start).any():
            pieces[i] = cmd[rows, :3]
        if m.centre is None:
            continue
        e = rows[-1]
        start = int(rows[0]) - 1  # the previous line's end point
        ds = cmd[start, :3] - tp.points[start] if start >= 0 else np.zeros(3)
        de = cmd[e, :3] - tp.points[e]
        centres[i] = arc_centre(m, cmd[start, :3] if start >= 0 else m.start, cmd[e, :3], m.centre + 0.5 * (ds + de))
        if linearize_arcs:
            pieces[i] = cmd[rows, :3]
    out = gc.rewrite(prog, new_end, centres)
    if pieces:
        out = gc.linearize(out, pieces)
    return out


def path(model, toolpath, wrench=None, tool=None, method: str = "nonlinear", compensate: bool = True,
         tolerance: float | None = None, linearize_arcs: bool = False, split_moves: bool = False,
         chord_tol: float = 1e-3,
         step: float = 1.0, passed: str = gc.DEFAULT_PASS, uncertainty: bool = True, workers: int = 1,
         foot=None, leg=None, progress=None) -> PathResult:
    """Deflection of the tool along a toolpath and the compensated toolpath.  ``vjm path`` as a function.

    Parameters
    ----------
    model : a :class:`vjm.Model`, a model file (e.g. ``model_updated.yaml`` of ``vjm diagnose``) or a
        bundled name
    toolpath : a CSV or G-code file, or a :class:`vjm.toolpath.points.Toolpath`
    wrench : a :mod:`vjm.toolpath.wrench` source (``Constant``, ``Milling``, ``PerPoint``); default the
        CSV's Fx..Mz columns
    tool : TCP offset dx, dy, dz in platform axes, mm (default 0: the platform point)
    method : "nonlinear" (with the model's effects) or "linear" (``C(p) w``) for the deflection;
        the compensation is always nonlinear
    tolerance : mm; ``result.passed`` then says whether every point is within it
    linearize_arcs : write G2/G3 as G1 chords (within ``chord_tol``) in the compensated program
    split_moves : write every feed move (G1, G2, G3) as G1 pieces of at most ``step`` mm, each end
        compensated (the transition where the force turns then spans one piece)
    chord_tol, step : sampling of arcs (chord error, mm) and of straight moves (spacing, mm)
    uncertainty : propagate the calibration covariance of the model file, if it carries one
    workers : worker processes over the passes of a long path (:mod:`vjm.toolpath.passes`), threads over
        blocks of points otherwise
    progress : called with a line at each stage (deflection, uncertainty, compensation)
    """
    if tolerance is not None and not (np.isfinite(tolerance) and tolerance > 0):
        raise VjmError(f"--tolerance must be a number > 0 (mm), got {tolerance!r}")
    if not (np.isfinite(chord_tol) and chord_tol > 0) or not (np.isfinite(step) and step > 0):
        raise VjmError(f"--chord-tol and --step must be numbers > 0 (mm), got {chord_tol!r}, {step!r}")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise VjmError(f"workers must be an integer >= 1, got {workers!r}")
    if method not in ("linear", "nonlinear"):
        raise VjmError(f"--method must be linear or nonlinear, got {method!r}")
    m = _model(model, foot, leg)
    check_effects(m)
    t = _tool(tool)
    tp = toolpath if isinstance(toolpath, Toolpath) else read_toolpath(toolpath, chord_tol, step, passed)
    check_machine(m, tp, t)
    W = (wrench or PerPoint()).wrenches(tp)
    check_load(m, tp, W, t)
    plan = path_plan(len(tp.poses))  # a CSV's points, or a program's samples (checked before sampling)
    progress = or_quiet(progress)
    if plan.long:  # a run of more than a minute says so before it starts
        progress(f"{plan.describe()}; progress follows")
    notes = []
    if m.dof == 6 and not tp.has_orientation:
        notes.append("6-dof platform, toolpath without orientations: the platform keeps a zero rotation and "
                     "only positions are compensated")
    if method == "linear" and m.effects:
        notes.append(f"linear deflection: the model's effects ({', '.join(m.effects)}) are left out "
                     f"(they enter the nonlinear deflection and the compensation)")
    progress(f"{method} deflection at {len(tp.poses):,} points" + (" and compensation" if compensate else ""))
    d, d_nl, comp, cold = _deflect_and_compensate(m, tp, W, t, method, workers, compensate, progress)
    if d_nl is not None:
        notes.append(f"nonlinear equilibria warm-started from the neighbouring point, each checked to a residual "
                     f"of {RTOL:g} of its equations' scale: {cold:,} cold starts over {tp.n:,} points (the first "
                     f"point of each run of consecutive points, and warm starts that failed)")
    band = None
    cal = unc.read(m) if uncertainty else None
    if cal is not None:
        progress("uncertainty from the calibration covariance")
        G = unc.sensitivities(m, cal, lambda mm: tcp_deflection(mm, tp.poses, W, t, method, workers))
        band = unc.band(d, G, cal.cov)
        notes.append(f"uncertainty from the calibration covariance of {os.path.basename(m.path or '')} "
                     f"({', '.join(cal.names)})")
    after = text = None
    if comp is not None and d_nl is not None:
        after = blend_after(_all_vertices(tp, linearize_arcs, split_moves), comp.commanded, comp.residual_vector)
        cmd = comp.commanded
        text = (functools.partial(write_csv, tp=tp, poses=cmd) if tp.kind == "csv"  # written as it goes
                else functools.partial(gc.write_program, prog=compensated_program(tp, cmd, linearize_arcs,
                                                                                  split_moves)))
        worse = np.flatnonzero(np.linalg.norm(after[:, :3], axis=1) > np.linalg.norm(d_nl[:, :3], axis=1))
        if tp.kind == "gcode" and not split_moves and worse.size:
            notes.append(f"warning: along {worse.size} of {int(tp.cutting.sum())} cutting samples (first: "
                         f"{tp.where(int(worse[0]))}) the compensated program is farther from the path than the "
                         f"original; --split-moves fixes that")
        if tp.kind == "gcode" and not split_moves:
            notes.append("the written program is compensated at its end points; where the force turns at a "
                         "corner, the next move starts with the previous one's correction (see the 'compensated "
                         "program' curve): --split-moves writes feed moves in --step pieces")
    return PathResult(tp, W, d, method, tolerance, comp, band, after, tuple(notes), text)


def _deflect_and_compensate(m, tp: Toolpath, W, t, method: str, workers: int, compensate: bool, progress):
    """(deflection (n, 6) by ``method``, nonlinear deflection or None, Compensation or None, cold starts), in
    passes of :data:`~.passes.CHUNK` points (:mod:`vjm.toolpath.passes`: the compensation's check equilibria
    start from the deflection's at the same points; long paths over ``workers`` processes)."""
    n = len(tp.poses)
    d = tcp_deflection(m, tp.poses, W, t, "linear") if method == "linear" else np.empty((n, 6))
    if method == "linear" and not compensate:
        return d, None, None, 0
    d_nl, c, cold = deflect_and_compensate(m, tp, W, t, workers, compensate, progress)
    if method == "nonlinear":
        d = d_nl
    if c is None:
        return d, d_nl, None, cold
    cmd, res, resvec, iters, cold_c = c
    return d, d_nl, Compensation(cmd, res, residual_vector=resvec, equilibria=iters, cold=cold_c), cold + cold_c


def _all_vertices(tp: Toolpath, linearize_arcs: bool, split: bool) -> Toolpath:
    """The toolpath whose samples of linearized arcs or split moves are written end points too."""
    from dataclasses import replace

    v = np.array(tp.vertex)
    if tp.kind == "csv" or tp.program is None:
        v[:] = True
    elif split:
        v |= tp.cutting
    elif linearize_arcs:
        mv = {mm.line for mm in gc.moves(tp.program) if mm.centre is not None}
        v |= np.isin(tp.line_index, list(mv))
    return replace(tp, vertex=v)
