"""How vjm's results show themselves: HTML tables for notebooks, matplotlib pictures, a JSON file.

Pure functions over arrays and plain values, used by the ``_repr_html_``, ``plot`` and ``save``
methods of :class:`vjm.stiffness.linear.StiffnessResult`, :class:`vjm.maps.compute.StiffnessMap` and
:class:`vjm.Model`.  This module imports none of them, so that each can call it.
"""
from __future__ import annotations

import html
import json
import os
import sys
from pathlib import Path

import numpy as np

from linkfea.mechanics.compliance import TWIST, WRENCH

from ..errors import VjmError

#: schema tag of a saved StiffnessResult (``StiffnessResult.save``)
STIFFNESS_SCHEMA = "vjm.stiffness/1"
#: units of the K and C blocks, as the tables state them
K_UNITS = "N/mm, N/rad, N, N mm/rad by block"
C_UNITS = "mm/N, mm/(N mm), rad/N, rad/(N mm) by block"


def pyplot():
    """``matplotlib.pyplot``, on the Agg backend unless a backend was chosen (``MPLBACKEND``,
    a notebook's inline backend, or pyplot already imported), so that pictures draw without X."""
    import matplotlib

    if "MPLBACKEND" not in os.environ and "matplotlib.pyplot" not in sys.modules:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def matrix_table(M, title: str, rows, cols) -> str:
    """A 6x6 matrix as an HTML table, entries as ``%.4e``."""
    head = "".join(f"<th>{c}</th>" for c in cols)
    body = "".join(f"<tr><th>{r}</th>" + "".join(f"<td>{v:.4e}</td>" for v in row) + "</tr>"
                   for r, row in zip(rows, np.asarray(M)))
    return f"<table><caption>{html.escape(title)}</caption><tr><th></th>{head}</tr>{body}</table>"


def rows_table(rows, title: str = "") -> str:
    """``[(label, value), ...]`` as a two-column HTML table (values escaped)."""
    cap = f"<caption>{html.escape(title)}</caption>" if title else ""
    body = "".join(f"<tr><th style='text-align:left'>{html.escape(str(k))}</th>"
                   f"<td style='text-align:left'>{html.escape(str(v))}</td></tr>" for k, v in rows)
    return f"<table>{cap}{body}</table>"


def stiffness_html(K, C, k_tran, k_rot, rank, points) -> str:
    """One pose: point, k values, rank, then K and C.  Several poses: one row per pose (first 20)."""
    K = np.asarray(K)
    if K.ndim == 2:
        p = np.round(np.asarray(points, dtype=float), 4).tolist()
        info = (f"<p><b>StiffnessResult</b> at {p} mm (world axes, origin at the end-effector point): "
                f"k_tran = {float(k_tran):.4e} mm/N, k_rot = {float(k_rot):.4e} rad/(N mm), "
                f"rank {int(rank)}</p>")
        return (info + matrix_table(K, f"stiffness K ({K_UNITS})", WRENCH, TWIST)
                + matrix_table(C, f"compliance C ({C_UNITS})", TWIST, WRENCH))
    n = len(K)
    shown = min(n, 20)
    head = "<tr><th>#</th><th>x, y, z [mm]</th><th>k_tran [mm/N]</th><th>k_rot [rad/(N mm)]</th><th>rank</th></tr>"
    body = "".join(f"<tr><td>{i}</td><td>{np.round(points[i], 4).tolist()}</td><td>{k_tran[i]:.4e}</td>"
                   f"<td>{k_rot[i]:.4e}</td><td>{int(rank[i])}</td></tr>" for i in range(shown))
    more = f"<p>... {n - shown} more poses</p>" if n > shown else ""
    return (f"<p><b>StiffnessResult</b>, {n} poses (world axes, origin at each end-effector point); "
            f"<code>.pose(i)</code> gives one with its K and C.</p><table>{head}{body}</table>{more}")


def principal_compliances(C) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues of ``C[:3, :3]`` (mm/N) and of ``C[3:, 3:]`` (rad/(N mm)), largest first."""
    C = np.asarray(C, dtype=float)
    return np.linalg.eigvalsh(C[:3, :3])[::-1], np.linalg.eigvalsh(C[3:, 3:])[::-1]


def log_limits(values) -> tuple[float, float] | None:
    """Limits of a log axis showing ``values``: whole decades around the positive finite ones, at least one
    decade wide (equal values, as the three principal compliances of an isotropic point, would otherwise
    collapse the axis); None if no value is positive and finite.

    >>> log_limits([2.78e-4, 2.78e-4, 2.78e-4])
    (0.0001, 0.001)
    """
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v) & (v > 0)]
    if not v.size:
        return None
    lo, hi = np.floor(np.log10(v.min())), np.ceil(np.log10(v.max()))
    return float(10.0 ** lo), float(10.0 ** max(hi, lo + 1))


def plot_principal(C, ax=None, title: str = ""):
    """Bar chart of the principal compliances (translation and rotation, each on its own log axis).

    A new figure lays itself out (constrained layout: both axis labels and the title inside it); each
    axis spans whole decades around its bars (:func:`log_limits`).
    """
    plt = pyplot()
    if ax is None:
        _, ax = plt.subplots(figsize=(6.4, 3.6), layout="constrained")
    t, r = principal_compliances(C)
    ax.bar(range(3), t, color="tab:blue", label="translation [mm/N]")
    ax2 = ax.twinx()
    ax2.bar(range(4, 7), r, color="tab:orange", label="rotation [rad/(N mm)]")
    for a, v, label, colour in ((ax, t, "translation [mm/N]", "tab:blue"),
                                (ax2, r, "rotation [rad/(N mm)]", "tab:orange")):
        lim = log_limits(v)
        if lim is not None:
            a.set_yscale("log")
            a.set_ylim(*lim)
        a.set_ylabel(label, color=colour)
    ax.set_xticks([0, 1, 2, 4, 5, 6], ["t1", "t2", "t3", "r1", "r2", "r3"])
    ax.set_xlim(-0.7, 6.7)
    ax.set_title(title or "principal compliances (eigenvalues of the C blocks)", fontsize=10)
    return ax


def plot_matrix(C, ax=None, title: str = ""):
    """The 6x6 compliance as an image of log10 |C_ij| with a colourbar."""
    plt = pyplot()
    if ax is None:
        _, ax = plt.subplots(figsize=(5, 4.2))
    A = np.abs(np.asarray(C, dtype=float))
    tiny = np.max(A) * 1e-12 if np.max(A) > 0 else 1e-300
    im = ax.imshow(np.log10(np.maximum(A, tiny)), cmap="viridis")
    ax.figure.colorbar(im, ax=ax, label="log10 |C_ij|")
    ax.set_xticks(range(6), WRENCH)
    ax.set_yticks(range(6), TWIST)
    ax.set_title(title or f"compliance C ({C_UNITS})", fontsize=9)
    return ax


def save_json(path, doc: dict, schema: str) -> Path:
    """Write ``doc`` with its ``schema`` tag as JSON, atomically.  A file already at ``path`` is
    replaced only if it carries the same schema (this tool wrote it); anything else is refused."""
    from linkfea.files.atomic import plain, write_text

    path = Path(path)
    if path.exists():
        try:
            old = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            old = None
        if not (isinstance(old, dict) and old.get("schema") == schema):
            raise VjmError(f"{path}: exists and is not a {schema} file; not overwritten")
    write_text(path, json.dumps(plain({"schema": schema, **doc}), indent=1) + "\n")
    return path


def map_html(architecture: str, shape, axes, fixed, points, reachable, k_tran, k_rot) -> str:
    """Grid, reachable count, and min / max of k_tran and k_rot with the points where they occur."""
    rows = [("architecture", architecture),
            ("grid", " x ".join(str(s) for s in shape) + " points; " + ", ".join(
                f"{'xyz'[i]} {float(a[0]):.4g}..{float(a[-1]):.4g} mm" for i, a in enumerate(axes))),
            ("slice", "none (3-D grid)" if fixed is None else f"{'xyz'[fixed[0]]} = {float(fixed[1]):.4g} mm"),
            ("reachable", f"{int(np.sum(reachable))} of {len(points)}")]
    for name, unit in (("k_tran", "mm/N"), ("k_rot", "rad/(N mm)")):
        v = np.asarray(k_tran if name == "k_tran" else k_rot, dtype=float)
        ok = np.isfinite(v)
        if not ok.any():
            rows.append((name, "no reachable point"))
            continue
        idx = np.flatnonzero(ok)
        lo, hi = idx[np.argmin(v[ok])], idx[np.argmax(v[ok])]
        for what, i in (("min", lo), ("max", hi)):
            rows.append((f"{name} {what} [{unit}]",
                         f"{v[i]:.4e} at {np.round(points[i], 4).tolist()} mm"))
    return "<p><b>StiffnessMap</b> (K in world axes at the end-effector point; NaN = unreachable)</p>" + \
        rows_table(rows)


def _link_row(link) -> str:
    if link.compliance is None:
        return "rigid"
    src = link.source or {}
    kind = next(iter(src), "inline")
    f = link.frame
    where = ("in the architecture's spring frame (no CAD frame stated)" if f is None else
             f"CAD frame origin {np.round(f.origin, 4).tolist()} mm, x axis {np.round(f.axes[0], 4).tolist()}")
    d = np.diag(np.asarray(link.compliance))
    return f"{kind}; {where}; diag C = [{', '.join(f'{x:.3e}' for x in d)}]"


def _effect(name, params) -> str:
    if isinstance(params, dict) and params:
        return f"{name} (" + ", ".join(f"{k} = {v}" for k, v in params.items()) + ")"
    return str(name)


def model_html(model) -> str:
    """Architecture, geometry, links with their frames, actuator, joints and effects of a vjm Model."""
    a = model.actuator
    rows = [("architecture", model.architecture), ("name", model.name or "-"),
            ("geometry [mm]", ", ".join(f"{k} = {v}" for k, v in model.geometry.items()))]
    rows += [(f"link {k}", _link_row(v)) for k, v in model.links.items()]
    rows += [("actuator", f"stiffness {a.stiffness:g} N/mm, compliance slope {a.compliance_slope:g} (mm/N)/mm, "
                          f"q_ref {a.q_ref:g} mm"),
             ("joints", "ideal" if model.joints.passive_stiffness is None
              else f"passive stiffness {model.joints.passive_stiffness:g} N mm/rad"),
             ("effects", "; ".join(_effect(k, v) for k, v in model.effects.items()) or "none")]
    if model.path:
        rows.append(("file", model.path))
    return "<p><b>vjm Model</b></p>" + rows_table(rows)


def _names(names, shown: int = 6) -> str:
    """``a, b, c`` or ``a, b, ... (9)``: a short list in one line."""
    names = [str(n) for n in names]
    if len(names) <= shown:
        return ", ".join(names) or "none"
    return ", ".join(names[:shown - 1]) + f", ... ({len(names)})"


def model_text(model) -> str:
    """A parallel machine in three lines (the repr; ``_repr_html_`` has the whole table)."""
    a = model.actuator
    links = [f"{k} ({'rigid' if v.compliance is None else next(iter(v.source or {}), 'inline')})"
             for k, v in model.links.items()]
    head = f"<vjm Model {model.name or '(unnamed)'!r}: {model.architecture}, parallel machine"
    return (f"{head}{f', from {model.path}' if model.path else ''}\n"
            f" links: {_names(links)}; actuator {a.stiffness:g} N/mm; joints "
            f"{'ideal' if model.joints.passive_stiffness is None else f'{model.joints.passive_stiffness:g} N mm/rad'}"
            f"; effects: {_names(model.effects)}\n"
            " .stiffness(x), .map(grid=...), .save(path); every field: ._repr_html_()>")


def robot_rows(model) -> list:
    """A robot model's facts as (label, value) rows: its repr's lines and its HTML table."""
    p = model.payload
    return [("name", model.name or "(unnamed)"), ("file", model.path or "-"),
            ("joints", f"{model.nq} ({_names(model.q_names)})"),
            ("tools", _names(model.tools)),
            ("springs", f"{len(model.joint_springs)} joint, {len(model.joint6)} 6x6 joint, {len(model.links)} link"),
            ("payload", "none" if p is None else f"{p.mass:g} kg at {p.frame}"),
            ("gravity [m/s^2]", ", ".join(f"{float(g):g}" for g in model.gravity))]


def robot_text(model) -> str:
    """A serial or tree robot in a few lines (the repr)."""
    r = dict(robot_rows(model))
    return (f"<vjm RobotModel {r['name']!r}: {model.nq} joints ({_names(model.q_names)})"
            f"{'' if model.path is None else f', from {model.path}'}\n"
            f" tools: {r['tools']}; springs: {r['springs']}; payload {r['payload']}; gravity ({r['gravity [m/s^2]']}) "
            f"m/s^2\n .stiffness(q), .self_weight(q), .joint_map(...), .save(path)>")


def stiffness_text(k_tran, k_rot, rank, points) -> str:
    """A StiffnessResult in a few lines: one pose's point, k_tran, k_rot and rank; several poses' ranges."""
    k_tran, k_rot, rank = np.asarray(k_tran, dtype=float), np.asarray(k_rot, dtype=float), np.asarray(rank)
    if k_tran.ndim == 0:
        p = np.round(np.asarray(points, dtype=float), 4).tolist()
        return (f"<StiffnessResult at {p} mm: k_tran = {float(k_tran):.4g} mm/N, k_rot = {float(k_rot):.4g} "
                f"rad/(N mm), rank {int(rank)}\n .K, .C: 6x6, world axes at the end-effector point; .plot(), "
                ".save(path)>")
    return (f"<StiffnessResult, {len(k_tran)} poses: k_tran {np.nanmin(k_tran):.4g}..{np.nanmax(k_tran):.4g} "
            f"mm/N, k_rot {np.nanmin(k_rot):.4g}..{np.nanmax(k_rot):.4g} rad/(N mm), rank "
            f"{int(rank.min()) if rank.size else '-'}..{int(rank.max()) if rank.size else '-'}\n"
            " .K, .C: (n, 6, 6), world axes at each end-effector point; .pose(i) gives one>")
