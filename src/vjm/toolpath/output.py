"""Writing the outputs of ``vjm path``: one function, every file of the set through linkfea's atomic writes.

Files (in ``out``): ``path.csv`` (along the path), ``deflection.png`` (error against arc length,
before/after), ``plan.png`` (the path in plan coloured by the error), ``summary.json`` (worst points,
pass/fail, residual, band) and the compensated toolpath ``<input stem>_compensated<suffix>``.
The files are one output set (:class:`linkfea.files.outputs.OutputSet`): all old or all new, even if the
process is killed, and nothing in the folder that the tools did not write is touched.
"""
from __future__ import annotations

import json
import os

import numpy as np

from linkfea.files.atomic import plain
from linkfea.files.outputs import OutputSet, check_folder

from ..errors import VjmError


def output_names(toolpath_name: str) -> dict:
    """The file names ``vjm path`` writes, by role."""
    stem, suffix = os.path.splitext(os.path.basename(os.fspath(toolpath_name)))
    return {"table": "path.csv", "deflection": "deflection.png", "plan": "plan.png", "summary": "summary.json",
            "compensated": f"{stem}_compensated{suffix}"}


#: what summary.json says of its writer, and the name of the output set in the folder's manifest
WRITER = "vjm path"


def check_out(out, toolpath_name, force: bool = False) -> None:
    """Before any work: refuse a folder where the compensated program would replace the input, and
    whatever :func:`linkfea.files.outputs.check_folder` refuses (a file, an unwritable place, files of other
    origin without ``force``, and a file of other origin at one of our names even with it)."""
    names = output_names(toolpath_name)
    target = os.path.join(os.path.abspath(os.fspath(out)), names["compensated"])
    if os.path.exists(toolpath_name) and os.path.abspath(os.fspath(toolpath_name)) == target:
        raise VjmError(f"--out {out}: the compensated program would replace the input {toolpath_name}")
    check_folder(out, names.values(), force=force)


def summary_dict(res) -> dict:
    c = res.compensation
    return plain({
        "written_by": WRITER, "toolpath": res.toolpath.source, "points": res.toolpath.n, "method": res.method,
        "units": "mm, rad; TCP deflection in world axes", "max_error_mm": float(res.error.max()),
        "mean_error_mm": float(res.error.mean()), "worst": res.worst(10),
        "tolerance_mm": res.tolerance, "passed": res.passed,
        "band_max_mm": None if res.band is None else float(res.band.norm.max()),
        "band_z": None if res.band is None else res.band.z,
        "compensated_residual_max_mm": None if c is None else float(c.residual.max()),
        "compensated_program_max_error_mm": None if res.after is None
        else float(np.nanmax(np.linalg.norm(res.after[:, :3], axis=1))),
        "notes": list(res.notes),
    })


def write_outputs(res, out) -> list:
    """Write the whole output set of ``res`` into folder ``out``; returns the file names written.

    Call :func:`check_out` first (before any work): this function replaces files of its names."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = output_names(res.toolpath.source)
    if res.compensated is None:
        names.pop("compensated")
    with OutputSet(out, WRITER) as s:
        tmp = {k: s.path(v) for k, v in names.items()}
        with open(tmp["table"], "w", encoding="utf-8", newline="") as fh:
            res.write_table(fh)
        with open(tmp["summary"], "w", encoding="utf-8") as fh:
            json.dump(summary_dict(res), fh, indent=1)
        if "compensated" in tmp:
            with open(tmp["compensated"], "w", encoding="utf-8", newline="") as fh:
                res.write_compensated(fh)
        for key, draw, size in (("deflection", res.plot_deflection, (7, 3.5)), ("plan", res.plot_plan, (5.5, 4.5))):
            fig, ax = plt.subplots(figsize=size)
            draw(ax=ax)
            fig.tight_layout()
            fig.savefig(tmp[key], dpi=110)
            plt.close(fig)
    return list(names.values())
