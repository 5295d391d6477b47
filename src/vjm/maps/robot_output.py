"""A robot's map as files and text: the one output set of ``vjm map robot.yaml``, its summary, its HTML.

Used by :class:`vjm.maps.robot_joint.JointMap` and :class:`vjm.maps.robot_cartesian.CartesianMap` (their
``save``, ``summary``, ``summary_dict`` and ``_repr_html_``); it imports neither.  Files (one set,
:class:`linkfea.files.outputs.OutputSet`): ``map.npz`` (every array), ``map.csv`` (one row a point),
``k_tran.png``, ``k_rot.png``, ``sag.png`` (a map with the self-weight sag) and ``summary.json``.
"""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from linkfea.files.atomic import file_sha256, plain
from linkfea.files.outputs import OutputSet, check_folder

from ..modelio.csvtext import header

#: the output set's name in the folder's manifest, and summary.json's writer
WRITER = "vjm map"
FILES = ("map.npz", "map.csv", "k_tran.png", "k_rot.png", "summary.json")
SAG_FILE = "sag.png"
UNITS = ("k_tran mm/N, k_rot rad/(N mm) (largest eigenvalues of the compliance blocks); K world axes at the tool "
         "point; sag mm and rad; joints rad (mm prismatic); NaN: not evaluated")


def label(res) -> str:
    """The robot and the tool a map is of, as its pictures' titles name them."""
    import os

    name = os.path.basename(res.model_path) if res.model_path else (res.model_name or "robot")
    return f"{name}; tool {res.tool}" if res.tool else name


def files(self_weight: bool) -> tuple[str, ...]:
    """The files of a map's set (``sag.png`` with the self-weight sag)."""
    return FILES + ((SAG_FILE,) if self_weight else ())


def summary_dict(res, doc: dict) -> dict:
    """summary.json of a robot map ``res``: the model, the tool, ``doc`` (what the map covers), the ranges of
    k_tran and k_rot (and the largest sag), the model file's checksum."""
    kt, kr = res.k_tran, res.k_rot
    out = {"written_by": WRITER, "model": res.model_name, "tool": res.tool, "joint_names": list(res.q_names),
           "units": UNITS, **doc,
           "k_tran_min": float(np.nanmin(kt)) if np.isfinite(kt).any() else None,
           "k_tran_max": float(np.nanmax(kt)) if np.isfinite(kt).any() else None,
           "k_rot_min": float(np.nanmin(kr)) if np.isfinite(kr).any() else None,
           "k_rot_max": float(np.nanmax(kr)) if np.isfinite(kr).any() else None}
    if res.sag is not None:
        s = np.linalg.norm(res.sag[..., :3], axis=-1)
        out["sag_max_mm"] = float(np.nanmax(s)) if np.isfinite(s).any() else None
    if res.model_path:
        out["model_file"] = {"path": str(res.model_path), "sha256": file_sha256(res.model_path)}
    return plain(out)


def line(s: dict) -> str:
    """The one-line summary of a map's summary dict."""
    where = (f"{s['joints'][0]} x {s['joints'][1]} ({s['n'][0]} x {s['n'][1]} configurations)"
             if s["kind"] == "joint space" else
             f"{s['evaluated']} of {s['points']} grid points evaluated ({s['unreachable']} unreachable, "
             f"{s['singular']} singular)")
    if s["k_tran_min"] is None:
        return f"{where}; no stiffness"
    text = (f"{where}; k_tran {s['k_tran_min']:.3g}..{s['k_tran_max']:.3g} mm/N, "
            f"k_rot {s['k_rot_min']:.3g}..{s['k_rot_max']:.3g} rad/(N mm)")
    return text + (f"; sag up to {s['sag_max_mm']:.3g} mm" if s.get("sag_max_mm") is not None else "")


def html(title: str, s: dict) -> str:
    """A map's summary as an HTML table (a notebook's view)."""
    from .views import rows_table

    skip = ("written_by", "units", "model_file", "joint_names")
    return rows_table([(k, v) for k, v in s.items() if k not in skip], f"{title}: {line(s)}")


def table(res, names, columns) -> tuple[list, list]:
    """The CSV's header and rows: one per point (a joint map: per configuration); ``columns`` the arrays and
    the leading header of the map's kind."""
    sag_cols = ["sag_dx_mm", "sag_dy_mm", "sag_dz_mm", "sag_rx_rad", "sag_ry_rad", "sag_rz_rad"]
    lead, cols = columns
    head = lead + list(names) + ["k_tran_mm_per_N", "k_rot_rad_per_Nmm"] + (sag_cols if res.sag is not None else [])
    if res.sag is not None:
        cols = cols + [res.sag.reshape(-1, 6)]
    rows = [[*(c[i] for c in cols)] for i in range(len(cols[0]))]
    return head, [[v if isinstance(v, str) else f"{float(v):.10g}" for r in row for v in np.atleast_1d(r)]
                  for row in rows]


def write_set(out, res, arrays: dict, summary: dict, force: bool = False) -> Path:
    """map.npz (``arrays``), map.csv, the pictures and summary.json as one set (all new, or the old ones);
    returns the folder."""
    from .views import pyplot

    plt = pyplot()
    names = files(res.sag is not None)
    check_folder(out, names, force=force)
    with OutputSet(out, WRITER) as s:
        tmp = {n: s.path(n) for n in names}
        np.savez_compressed(tmp["map.npz"], **arrays, note=np.array(summary["units"]))
        head, rows = table(res, summary["joint_names"], res.csv_columns())
        with open(tmp["map.csv"], "w", encoding="utf-8", newline="") as fh:
            w = csv.writer(fh)
            fh.write(header(head) + "\r\n")  # the csv module's line end, as the rows'
            w.writerows(rows)
        with open(tmp["summary.json"], "w", encoding="utf-8") as fh:
            json.dump(summary, fh, indent=1)
        for name in ("k_tran", "k_rot", "sag"):
            if f"{name}.png" in tmp:
                fig, ax = plt.subplots(figsize=(5.5, 4.5))
                res.plot(name, ax=ax)
                fig.tight_layout()
                fig.savefig(tmp[f"{name}.png"], dpi=110)
                plt.close(fig)
    return Path(out)
