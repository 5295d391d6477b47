"""Writing the outputs of ``vjm path``: one function, every file of the set through linkfea's atomic writes.

Files (in ``out``): ``path.csv`` (along the path), ``deflection.png`` (error against arc length,
before/after), ``plan.png`` (the path in plan coloured by the error), ``summary.json`` (worst points,
pass/fail, residual, band) and the compensated toolpath ``<input stem>_compensated<suffix>``.
Each file goes to a temporary name beside its target and all are renamed only once every one of
them was written, so an error leaves the folder as it was.
"""
from __future__ import annotations

import json
import os
from contextlib import ExitStack

import numpy as np

from linkfea.atomic import atomic_path, plain

from ..errors import VjmError


def output_names(toolpath_name: str) -> dict:
    """The file names ``vjm path`` writes, by role."""
    stem, suffix = os.path.splitext(os.path.basename(os.fspath(toolpath_name)))
    return {"table": "path.csv", "deflection": "deflection.png", "plan": "plan.png", "summary": "summary.json",
            "compensated": f"{stem}_compensated{suffix}"}


#: what summary.json says of its writer: a folder holding our file names without it is not ours
WRITER = "vjm path"


def check_out(out, toolpath_name) -> None:
    """Refuse an output folder that is a file, one where the compensated program would replace the input,
    or one holding files of our names that an earlier ``vjm path`` did not write."""
    out = os.path.abspath(os.fspath(out))
    if os.path.exists(out) and not os.path.isdir(out):
        raise VjmError(f"--out {out} is a file, not a folder")
    names = output_names(toolpath_name)
    target = os.path.join(out, names["compensated"])
    if os.path.exists(toolpath_name) and os.path.abspath(os.fspath(toolpath_name)) == target:
        raise VjmError(f"--out {out}: the compensated program would replace the input {toolpath_name}")
    present = [n for n in names.values() if os.path.exists(os.path.join(out, n))]
    if present and not _ours(os.path.join(out, names["summary"])):
        raise VjmError(f"--out {out} holds {', '.join(present)}, not written by {WRITER}; choose another folder")


def _ours(summary) -> bool:
    try:
        with open(summary, encoding="utf-8") as fh:
            return json.load(fh).get("written_by") == WRITER
    except (OSError, ValueError, AttributeError):
        return False


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
    if res.compensated_text is None:
        names.pop("compensated")
    with ExitStack() as stack:
        tmp = {k: stack.enter_context(atomic_path(os.path.join(os.fspath(out), v))) for k, v in names.items()}
        with open(tmp["table"], "w", encoding="utf-8", newline="") as fh:
            fh.write(res.table())
        with open(tmp["summary"], "w", encoding="utf-8") as fh:
            json.dump(summary_dict(res), fh, indent=1)
        if "compensated" in tmp:
            with open(tmp["compensated"], "w", encoding="utf-8", newline="") as fh:
                fh.write(res.compensated_text)
        for key, draw, size in (("deflection", res.plot_deflection, (7, 3.5)), ("plan", res.plot_plan, (5.5, 4.5))):
            fig, ax = plt.subplots(figsize=size)
            draw(ax=ax)
            fig.tight_layout()
            fig.savefig(tmp[key], dpi=110)
            plt.close(fig)
    return list(names.values())
