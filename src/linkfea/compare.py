"""Beam or FEA?  N-beam equivalents of a CAD link and their errors against the FEA compliance.

The beam models are built in :mod:`linkfea.beammodel`, the error measures are defined in
:mod:`linkfea.metrics` and the outputs are rendered by :mod:`linkfea.report`; this module runs
the comparison and returns it as a :class:`Comparison`.
"""
from __future__ import annotations

import html
from dataclasses import dataclass

import numpy as np

from .beammodel import BeamModel, beam_frame, beam_model, link_beam_model, link_extent
from .checks import ArgumentError, integer
from .errors import LinkFeaError
from .materials import get_material
from .metrics import CLUSTER_TOL, compare_compliance, entry_errors, principal_errors
from .report import (
    COMPARE_FILES,
    ERROR_COLUMNS,
    LABELS,
    error_rows,
    figure_png,
    markdown_table,
    plot_error_vs_n,
    write_outputs,
)

__all__ = ["BeamModel", "Comparison", "ErrorTable", "CLUSTER_TOL", "DEFAULT_BEAMS", "LABELS", "UNITS", "beam_frame", "beam_model",
           "compare", "compare_compliance", "compare_link", "entry_errors", "fea_compliance", "fea_info",
           "figure_png", "link_beam_model", "link_extent", "markdown_table", "parse_beams",
           "principal_errors", "write_outputs"]

DEFAULT_BEAMS = (1, 2, 4, 8)
UNITS = {"compliance": "translations mm, rotations rad, forces N, moments N mm: blocks mm/N, rad/N, mm/(N mm), "
                       "rad/(N mm)", "errors": "dimensionless (fractions, not percent)", "angles": "deg"}


# --------------------------------------------------------------------------- the result object
@dataclass(frozen=True)
class ErrorTable:
    """The errors of every beam model against the FEA, one row per (model, N).

    Errors are fractions (not percent), angles in degrees; ``table["C22"]`` is a column as
    an array, ``table.rows`` the tuples, ``table.to_markdown()`` the table in percent.
    """

    columns: tuple
    rows: tuple

    def __len__(self) -> int:
        return len(self.rows)

    def __getitem__(self, column: str) -> np.ndarray:
        k = self.columns.index(column)
        return np.array([r[k] for r in self.rows])

    def records(self) -> list[dict]:
        return [dict(zip(self.columns, r)) for r in self.rows]

    def _cells(self, row) -> list[str]:
        return [c if isinstance(c, str) else str(c) if isinstance(c, (int, np.integer)) else
                (f"{c:.1f}" if name == "max angle (deg)" else f"{100 * c:+.1f}%")
                for name, c in zip(self.columns, row)]

    def to_markdown(self) -> str:
        lines = ["| " + " | ".join(self.columns) + " |", "|---" * len(self.columns) + "|"]
        lines += ["| " + " | ".join(self._cells(r)) + " |" for r in self.rows]
        return "\n".join(lines) + "\n"

    def __repr__(self) -> str:
        cells = [list(self.columns)] + [self._cells(r) for r in self.rows]
        w = [max(len(row[k]) for row in cells) for k in range(len(self.columns))]
        return "\n".join("  ".join(c.rjust(w[k]) for k, c in enumerate(row)) for row in cells)

    def _repr_html_(self) -> str:
        head = "".join(f"<th>{html.escape(c)}</th>" for c in self.columns)
        body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in self._cells(r)) + "</tr>"
                       for r in self.rows)
        return f"<table><tr>{head}</tr>{body}</table>"


@dataclass(frozen=True, eq=False)
class Comparison:
    """Beam models against the FEA compliance of one link (what ``linkfea compare`` writes).

    ``record`` is the JSON-ready record (``compare.json``); ``comparison["beams"]`` reads it
    directly.  :attr:`errors` is the error table, :meth:`plot` draws the error versus N on a
    matplotlib Axes, :meth:`save` writes compare.json, compare.md and compare.png.
    """

    record: dict

    def __getitem__(self, key):
        return self.record[key]

    @property
    def link(self) -> str:
        return self.record["link"]

    @property
    def fea(self) -> np.ndarray:
        """The FEA compliance in the link frame (6x6)."""
        return np.array(self.record["fea"]["compliance"])

    def beam(self, n: int, theory: str = "timoshenko") -> np.ndarray:
        """The ``n``-beam compliance (``theory`` timoshenko or euler_bernoulli) in the link frame."""
        for m in self.record["beams"]:
            if m["n"] == n:
                return np.array(m[f"compliance_{theory}"])
        raise LinkFeaError(f"no {n}-beam model in this comparison (N = {[m['n'] for m in self.record['beams']]})")

    @property
    def errors(self) -> ErrorTable:
        return ErrorTable(ERROR_COLUMNS, tuple(error_rows(self.record)))

    def plot(self, ax=None):
        """Largest principal error (%) of the translation and rotation blocks versus N; returns the Axes."""
        if ax is None:
            import matplotlib.pyplot as plt

            _, ax = plt.subplots(figsize=(5, 3.6))
        return plot_error_vs_n(self.record, ax)

    def save(self, out_dir, force: bool = False) -> dict:
        """Write compare.json, compare.md and compare.png into ``out_dir`` (one set; see
        :func:`linkfea.report.write_outputs`); their paths by name."""
        return write_outputs(self.record, out_dir, force=force)

    def __repr__(self) -> str:
        return f"Comparison({self.link!r}, N = {[m['n'] for m in self.record['beams']]})\n{self.errors!r}"

    def _repr_html_(self) -> str:
        return f"<p><b>{html.escape(self.link)}</b>: beam models vs FEA</p>" + self.errors._repr_html_()


# --------------------------------------------------------------------------- the comparison
def parse_beams(text) -> tuple:
    """``"1,2,4,8"`` (or a sequence) -> (1, 2, 4, 8); every N a whole number > 0."""
    items = [t.strip() for t in text.split(",")] if isinstance(text, str) else list(text)
    out = []
    for t in items:
        try:
            v = integer(int(t) if isinstance(t, str) else t, "beams")
        except (ValueError, ArgumentError):
            raise ArgumentError("beams", f"{t!r} is not an integer; give whole numbers > 0, e.g. 1,2,4,8") from None
        if v <= 0:
            raise ArgumentError("beams", f"must be > 0 (numbers of beams), got {v}")
        out.append(v)
    if not out:
        raise ArgumentError("beams", "must give at least one number of beams, e.g. 1,2,4,8")
    return tuple(sorted(set(out)))


def compare_link(link, C_fea, beams=DEFAULT_BEAMS, axis=None, fea_info: dict | None = None) -> dict:
    """The comparison record (JSON-ready) of a link's N-beam models against its FEA compliance.

    ``C_fea`` is the FEA compliance in ``link.frame``.
    """
    beams = parse_beams(beams)
    C_fea = np.asarray(C_fea, dtype=float)
    if C_fea.shape != (6, 6) or not np.all(np.isfinite(C_fea)):
        raise LinkFeaError(f"FEA compliance must be a finite 6x6 matrix, got shape {C_fea.shape}")
    mat = get_material(link.material)
    x_base, x_tip = link_extent(link, axis)
    models = []
    for n in beams:
        m = link_beam_model(link, n, axis)
        models.append({
            "n": n,
            "stations": m.stations.tolist(),
            "sections": [s.to_dict() for s in m.sections],
            "compliance_timoshenko": m.compliance.tolist(),
            "compliance_euler_bernoulli": m.compliance_eb.tolist(),
            "timoshenko": compare_compliance(C_fea, m.compliance),
            "euler_bernoulli": compare_compliance(C_fea, m.compliance_eb),
        })
    return {
        "link": link.name,
        "source": str(link.source),
        "params": {k: v for k, v in link.params.items()},
        "material": {"name": mat.name, "E": mat.E, "nu": mat.nu, "units": "MPa"},
        "frame": link.frame.to_dict(),
        "beam_axis": list(beam_frame(link.frame, axis).axes[0]),
        "beam_length": x_tip - x_base,
        "base_station": x_base,
        "tip_station": x_tip,
        "units": UNITS,
        "order": "wrench Fx Fy Fz Mx My Mz; twist dx dy dz rx ry rz; compliances at the link frame origin, "
                 "components in the link frame",
        "fea": {"compliance": C_fea.tolist(), **(fea_info or {})},
        "beams": models,
        "definitions": {
            "entry_error": "(C_beam_ij - C_fea_ij) / sqrt(C_fea_ii * C_fea_jj), signed",
            "principal": "eigen-decomposition of the 3x3 translational and rotational blocks separately; "
                         "relative_error = |l_beam - l_fea| / l_fea of direction-matched eigenvalues; "
                         f"angle between matched principal directions (subspace angle for eigenvalues within "
                         f"{CLUSTER_TOL:.0%})",
            "sections": "sectionproperties; shear areas geometric (nu = 0 shear function); J from warping",
        },
    }


def fea_compliance(spec, params=None, mesh_size=None, mode="rigid", material=None, base=None, tip=None,
                   progress=None):
    """FEA compliance of a link spec in its frame, and the link: ``(C, link, info)``.

    Runs :func:`linkfea.pipeline.compute` (the one home of CAD -> mesh -> P2
    solve -> rigid fit) and keeps what the comparison record needs.
    """
    from .pipeline import compute as run

    res = run(spec, params=params, mesh_size=mesh_size, mode=mode, material=material, base=base, tip=tip,
              progress=progress)
    return fea_info(res)


def fea_info(res) -> tuple:
    """``(C, link, info)`` of a :class:`linkfea.result.LinkResult`: C in ``res.link.frame``."""
    link, mesh, comp = res.link, res.mesh, res.value
    # The pipeline fits at the mesh frame, which is the link frame; the adjoint map makes that explicit.
    C = comp.to_frame(link.frame).matrix
    d = res.diagnostics
    info = {"mode": res.mode, "block_ratio": res.block_ratio,
            "mesh": {"n_nodes": int(mesh.n_nodes), "n_tets": int(mesh.n_tets), "n_dofs": int(res.solution.n_dofs),
                     "edge_length": float(mesh.edge_length), "element": "P2 tetrahedron (10 nodes)"},
            "diagnostics": {k: d.get(k) for k in ("symmetry_error", "fit_residual", "min_eigenvalue",
                                                  "error_estimate")},
            "timing_s": {k: float(v) for k, v in res.timing.items()}}
    return np.asarray(C, dtype=float), link, info


def compare(spec, beams=DEFAULT_BEAMS, params=None, mesh_size=None, mode="rigid", out=None, axis=None,
            material=None, base=None, tip=None, progress=None, force=False) -> Comparison:
    """FEA versus N-beam models of a link; optionally write ``out``/compare.{json,md,png}.

    Parameters
    ----------
    spec : str or Path
        A cad/ script (name or path) or a STEP file.
    beams : sequence of int or str
        Numbers of beams N, e.g. ``"1,2,4,8"``.
    params : dict, optional
        Script parameters.
    mesh_size : float, optional
        FEA target edge length, mm.
    mode : {"rigid", "block"}
    out : path, optional
        Output folder, checked before the FEA (:func:`linkfea.outputs.check_folder`).
    force : bool
        Write into ``out`` even if it holds files of other origin (they are never touched).
    axis : 3-vector, optional
        Beam axis in link-frame components (default x).
    material, base, tip : str, optional
        Material override and interface selectors (required for a STEP file),
        as in :func:`linkfea.pipeline.compute`.
    progress : callable, optional
        Called with a short message at each FEA stage.

    Returns
    -------
    Comparison
        The comparison; its ``record`` is what compare.json holds.
    """
    beams = parse_beams(beams)  # fail before the (slow) FEA
    if out is not None:
        from .outputs import check_folder  # here: `import linkfea` stays light

        check_folder(out, COMPARE_FILES, force=force)
    C, link, info = fea_compliance(spec, params, mesh_size, mode, material, base, tip, progress)
    record = compare_link(link, C, beams, axis, info)
    if out is not None:
        write_outputs(record, out, force=force)
    return Comparison(record)
