"""The sweep's table set (``sweep.parquet``, ``sweep.csv``, ``sweep.json``, ``sweep.png``), rebuilt from ``results/``."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Sequence

import numpy as np

from ..files.atomic import plain
from ..files.outputs import OutputSet
from ..mechanics.compliance import TWIST, WRENCH
from .designs import Design, Sweep
from .plot import C_COLUMNS, DIAGONAL, plot_sweep
from .store import read_design_result, result_path

K_COLUMNS = [f"K_{t}" for t in TWIST]
UNITS = {
    "C_d*_F*": "mm/N", "C_r*_M*": "rad/(N*mm)", "C_d*_M*": "1/N", "C_r*_F*": "rad/N",
    "K_dx..K_dz": "N/mm", "K_rx..K_rz": "N*mm/rad",
    "volume_mm3": "mm^3", "mass_kg": "kg", "edge_length": "mm", "t_*": "s",
    "frame": "each design's link reference frame (results/<key>.json 'frame')",
}


def design_row(design: Design, doc: dict | None) -> dict:
    """One table row: the design's parameters, status, compliance, stiffness diagonal, mass, mesh, timing."""
    row = {"index": design.index, "key": design.key}
    row.update({f"param_{k}": v for k, v in design.params.items()})
    sw = (doc or {}).get("sweep", {})
    row["status"] = sw.get("status", "not_run")
    row["error"] = sw.get("error")
    ok = row["status"] == "ok"
    C = np.asarray(doc["compliance"], dtype=float) if ok else np.full((6, 6), np.nan)
    K = np.asarray(doc["stiffness"], dtype=float) if ok else np.full((6, 6), np.nan)
    row.update(dict(zip(C_COLUMNS, C.ravel().tolist())))
    row.update(dict(zip(K_COLUMNS, np.diag(K).tolist())))
    g = (lambda *ks: _get(doc, ks)) if ok else (lambda *ks: None)
    row.update(volume_mm3=g("volume_mm3"), mass_kg=g("mass_kg"), material=g("material", "name"),
               n_nodes=g("mesh", "n_nodes"), n_tets=g("mesh", "n_tets"), n_dofs=g("mesh", "n_dofs"),
               edge_length=g("mesh", "edge_length"), radius_ratio_min=g("mesh", "quality", "radius_ratio_min"),
               volume_error=g("mesh", "quality", "volume_error"),
               symmetry_error=g("diagnostics", "symmetry_error"), fit_residual=g("diagnostics", "fit_residual"))
    for k in ("cad", "mesh", "assemble", "factor", "solve", "fit", "total"):
        row[f"t_{k}"] = g("timing", k)
    row["worker"] = sw.get("worker")
    return row


def _get(doc, keys):
    for k in keys:
        if not isinstance(doc, dict):
            return None
        doc = doc.get(k)
    return doc


def _column(values: list):
    """A pyarrow array: float64 if every non-null value is a number, else string."""
    import pyarrow as pa

    nonnull = [v for v in values if v is not None]
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in nonnull):
        if all(isinstance(v, int) for v in nonnull) and nonnull:
            return pa.array(values, type=pa.int64())
        return pa.array([None if v is None else float(v) for v in values], type=pa.float64())
    return pa.array([None if v is None else str(v) for v in values], type=pa.string())


#: the files of the table set, written together by :func:`write_table`
TABLE_FILES = ("sweep.parquet", "sweep.csv", "sweep.json", "sweep.png")


def table_rows(sweep: Sweep, out) -> list[dict]:
    """One row per design of the sweep, in enumeration order, from ``results/``."""
    return [design_row(d, read_design_result(out, d.key)) for d in sweep.designs]


def _meta(sweep: Sweep, plot: Sequence[str] | None) -> dict:
    return {"schema": "linkfea.sweep-table/1", "spec": sweep.spec, "source_sha256": sweep.source_sha,
            "options": sweep.options, "params": list(sweep.names), "sampling": sweep.sampling, "units": UNITS,
            "order": {"wrench": WRENCH, "twist": TWIST, "compliance": "t = C w, C_<twist>_<wrench>"},
            "plot": list(plot or DIAGONAL)}


def _summary(sweep: Sweep, rows: list[dict], plot: Sequence[str] | None) -> str:
    """The text of ``sweep.json``: the table's metadata, the status counts and the designs."""
    counts = {s: sum(r["status"] == s for r in rows) for s in ("ok", "failed", "not_run")}
    return json.dumps(plain({**_meta(sweep, plot), "counts": counts,
                             "designs": [{"index": d.index, "key": d.key, "params": d.params}
                                         for d in sweep.designs]}), indent=1) + "\n"


def table_is_current(sweep: Sweep, out, rows: list[dict], plot: Sequence[str] | None = None) -> bool:
    """Whether the table set in ``out`` is the one :func:`write_table` would write now.

    It is when its ``sweep.json`` says the same (source, options, designs, status counts, plotted
    entries) and no result of the sweep's designs is as new as the oldest file of the set.  A rerun
    whose designs are all done then leaves the set as it is, without loading pyarrow or matplotlib.
    """
    out = Path(out)
    try:
        oldest = min((out / n).stat().st_mtime_ns for n in TABLE_FILES)
        if (out / "sweep.json").read_text(encoding="utf-8") != _summary(sweep, rows, plot):
            return False
    except (OSError, UnicodeDecodeError):
        return False
    for d in sweep.designs:
        try:
            if result_path(out, d.key).stat().st_mtime_ns >= oldest:
                return False
        except FileNotFoundError:
            continue  # not run, and counted so in sweep.json
    return True


def write_table(sweep: Sweep, out, plot: Sequence[str] | None = None, rows: list[dict] | None = None) -> list[dict]:
    """Rebuild ``sweep.parquet``, ``sweep.csv``, ``sweep.json`` and ``sweep.png`` from ``results/``.

    One row per design of the sweep, in enumeration order (grid or sample
    order), with status ``ok``, ``failed`` (and its error) or ``not_run``
    (``rows``: those of :func:`table_rows`, if already read).
    """
    import pyarrow as pa
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    out = Path(out)
    rows = table_rows(sweep, out) if rows is None else rows
    cols = list(rows[0]) if rows else ["index", "key", "status", "error"]
    table = pa.table({c: _column([r.get(c) for r in rows]) for c in cols})
    table = table.replace_schema_metadata({"linkfea.sweep": json.dumps(plain(_meta(sweep, plot)))})
    with OutputSet(out, "linkfea sweep") as s:  # the four files are one set: all from this run, or the old ones
        pq.write_table(table, s.path("sweep.parquet"))
        pacsv.write_csv(table, s.path("sweep.csv"))
        Path(s.path("sweep.json")).write_text(_summary(sweep, rows, plot), encoding="utf-8")
        plot_sweep(rows, sweep.names, plot or DIAGONAL, s.path("sweep.png"))
    return rows
