"""Beam or FEA?  N-beam equivalents of a CAD link and their errors against the FEA compliance.

The beam models are built in :mod:`linkfea.beam.equivalents`, the error measures are defined in
:mod:`linkfea.beam.metrics`, the outputs are rendered by :mod:`linkfea.beam.report`, and the result is
the typed :class:`~linkfea.beam.comparison.Comparison`; this module runs the comparison.
"""
from __future__ import annotations

import numpy as np

from ..mechanics.materials import get_material
from ..runtime.checks import ArgumentError, integer
from ..runtime.errors import LinkFeaError
from .comparison import BeamFit, Comparison, ErrorTable
from .equivalents import BeamModel, beam_frame, beam_model, link_beam_model, link_extent
from .metrics import CLUSTER_TOL, compare_compliance, entry_errors, principal_errors
from .report import COMPARE_FILES, LABELS, figure_png, markdown_table, write_outputs

__all__ = ["BeamFit", "BeamModel", "Comparison", "ErrorTable", "CLUSTER_TOL", "DEFAULT_BEAMS", "LABELS", "UNITS",
           "beam_frame", "beam_model", "build_comparison", "compare", "compare_compliance", "compare_link",
           "entry_errors", "fea_compliance", "fea_info", "figure_png", "link_beam_model", "link_extent",
           "markdown_table", "parse_beams", "principal_errors", "write_outputs"]

DEFAULT_BEAMS = (1, 2, 4, 8)
UNITS = {"compliance": "translations mm, rotations rad, forces N, moments N mm: blocks mm/N, rad/N, mm/(N mm), "
                       "rad/(N mm)", "errors": "dimensionless (fractions, not percent)", "angles": "deg"}


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


def build_comparison(link, C_fea, beams=DEFAULT_BEAMS, axis=None, fea_info: dict | None = None) -> Comparison:
    """The comparison of a link's N-beam models against its FEA compliance ``C_fea`` (in ``link.frame``)."""
    beams = parse_beams(beams)
    C_fea = np.asarray(C_fea, dtype=float)
    if C_fea.shape != (6, 6) or not np.all(np.isfinite(C_fea)):
        raise LinkFeaError(f"FEA compliance must be a finite 6x6 matrix, got shape {C_fea.shape}")
    mat = get_material(link.material)
    x_base, x_tip = link_extent(link, axis)
    models = []
    for n in beams:
        m = link_beam_model(link, n, axis)
        models.append(BeamFit(
            n=n,
            stations=m.stations.tolist(),
            sections=[s.to_dict() for s in m.sections],
            compliance_timoshenko=m.compliance.tolist(),
            compliance_euler_bernoulli=m.compliance_eb.tolist(),
            timoshenko=compare_compliance(C_fea, m.compliance),
            euler_bernoulli=compare_compliance(C_fea, m.compliance_eb),
        ))
    return Comparison(
        link=link.name,
        source=str(link.source),
        params={k: v for k, v in link.params.items()},
        material={"name": mat.name, "E": mat.E, "nu": mat.nu, "units": "MPa"},
        frame=link.frame.to_dict(),
        beam_axis=list(beam_frame(link.frame, axis).axes[0]),
        beam_length=x_tip - x_base,
        base_station=x_base,
        tip_station=x_tip,
        units=UNITS,
        order="wrench Fx Fy Fz Mx My Mz; twist dx dy dz rx ry rz; compliances at the link frame origin, "
              "components in the link frame",
        fea_run={"compliance": C_fea.tolist(), **(fea_info or {})},
        beams=tuple(models),
        definitions={
            "entry_error": "(C_beam_ij - C_fea_ij) / sqrt(C_fea_ii * C_fea_jj), signed",
            "principal": "eigen-decomposition of the 3x3 translational and rotational blocks separately; "
                         "relative_error = |l_beam - l_fea| / l_fea of direction-matched eigenvalues; "
                         f"angle between matched principal directions (subspace angle for eigenvalues within "
                         f"{CLUSTER_TOL:.0%})",
            "sections": "sectionproperties; shear areas geometric (nu = 0 shear function); J from warping",
        },
    )


def compare_link(link, C_fea, beams=DEFAULT_BEAMS, axis=None, fea_info: dict | None = None) -> dict:
    """The comparison record (JSON-ready, what compare.json holds) of a link's N-beam models against
    its FEA compliance: :func:`build_comparison` as a dictionary.

    ``C_fea`` is the FEA compliance in ``link.frame``.
    """
    return build_comparison(link, C_fea, beams, axis, fea_info).to_dict()


def fea_compliance(spec, params=None, mesh_size=None, mode="rigid", material=None, base=None, tip=None,
                   progress=None):
    """FEA compliance of a link spec in its frame, and the link: ``(C, link, info)``.

    Runs :func:`linkfea.pipeline.compute` (the one home of CAD -> mesh -> P2
    solve -> rigid fit) and keeps what the comparison record needs.
    """
    from ..options import ComputeOptions
    from ..pipeline import compute as run

    opts = ComputeOptions(mesh_size=mesh_size, mode=mode, material=material, base=base, tip=tip)
    res = run(spec, opts, params=params, progress=progress)
    return fea_info(res)


def fea_info(res) -> tuple:
    """``(C, link, info)`` of a :class:`linkfea.result.linkresult.LinkResult`: C in ``res.link.frame``."""
    link, mesh, comp = res.link, res.mesh, res.value
    # The pipeline fits at the mesh frame, which is the link frame; the adjoint map makes that explicit.
    C = comp.to_frame(link.frame).matrix
    d = res.diagnostics
    info = {"mode": res.mode, "block_ratio": res.block_ratio,
            "mesh": {"n_nodes": int(mesh.n_nodes), "n_tets": int(mesh.n_tets), "n_dofs": int(res.solution.n_dofs),
                     "edge_length": float(mesh.edge_length), "element": "P2 tetrahedron (10 nodes)"},
            "diagnostics": {k: getattr(d, k) for k in ("symmetry_error", "fit_residual", "min_eigenvalue",
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
        Output folder, checked before the FEA (:func:`linkfea.files.outputs.check_folder`).
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
        The comparison (typed); its ``to_dict()`` is what compare.json holds.
    """
    beams = parse_beams(beams)  # fail before the (slow) FEA
    if out is not None:
        from ..files.outputs import check_folder  # here: `import linkfea` stays light

        check_folder(out, COMPARE_FILES, force=force)
    C, link, info = fea_compliance(spec, params, mesh_size, mode, material, base, tip, progress)
    cmp = build_comparison(link, C, beams, axis, info)
    if out is not None:
        cmp.save(out, force=force)
    return cmp
