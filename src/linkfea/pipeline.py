"""The link stage end to end: CAD -> mesh -> P2 solve -> rigid fit -> checked compliance."""
from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from .mechanics.materials import DEFAULT_MATERIAL, get_material
from .options import ComputeOptions
from .result.linkresult import LinkResult
from .result.records import Diagnostics, MeshInfo
from .runtime.errors import LinkFeaWarning
from .runtime.progress import or_default

__all__ = ["ComputeOptions", "LinkResult", "compute"]
REFINE_GROWTH = 2.5
"""Largest DOF growth expected from one refinement step (for the budget check before meshing)."""


@dataclass(frozen=True)
class Run:
    """One mesh of the link through the solve, the fit and the error estimate."""

    mesh: Any
    """The :class:`~linkfea.mesh.linkmesh.LinkMesh`."""
    solution: Any
    """The :class:`~linkfea.fem.problem.FeaSolution`."""
    fit: Any
    """The :class:`~linkfea.fem.fit.FittedCompliance`."""
    timing: dict
    """Seconds per stage: mesh, assemble, factor, solve, fit, estimate."""
    estimate: Any
    """The :class:`~linkfea.fem.estimate.ErrorEstimate`."""


@dataclass(frozen=True)
class Refinement:
    """The refined run and the record of its steps (the result's ``diagnostics.refinement``)."""

    run: Run
    record: dict


def _solve_once(link, material, H, opts: ComputeOptions, cache_dir, progress, size_at=None) -> Run:
    from .fem.fit import compliance_from_solution
    from .fem.problem import solve_link
    from .mesh import DEFAULT_EPSILON, mesh_link

    mode, block_ratio = opts.mode, opts.block_ratio
    epsilon = DEFAULT_EPSILON if opts.envelope is None else opts.envelope
    t0 = time.perf_counter()
    mesh = mesh_link(link, H, with_block=(mode == "block"), epsilon=epsilon, cache_dir=cache_dir, progress=progress,
                     mesher=opts.mesher, size_at=size_at)
    t_mesh = time.perf_counter() - t0
    from .solvers.factorizers import factorizer_named

    sol = solve_link(mesh, material, mode=mode, block_ratio=block_ratio, progress=progress, assembler=opts.assembler,
                     solver=factorizer_named(opts.solver))
    progress("fit")
    t0 = time.perf_counter()
    comp = compliance_from_solution(sol)
    t_fit = time.perf_counter() - t0
    progress("error estimate")
    t0 = time.perf_counter()
    est = _estimate(sol, comp, material, mode, block_ratio, mesh)
    timing = {"mesh": t_mesh, **{k: float(sol.timing.get(k, 0.0)) for k in ("assemble", "factor", "solve")},
              "fit": t_fit, "estimate": time.perf_counter() - t0}
    return Run(mesh, sol, comp, timing, est)


def _estimate(sol, comp, material, mode, block_ratio, mesh):
    """The recovered-stress estimate of the compliance's discretization error (linkfea.fem.estimate)."""
    import numpy as np

    from .fem.estimate import estimate_error
    from .fem.p2 import lame

    lam, mu = lame(material)
    scale = np.where(np.asarray(mesh.block, dtype=bool), block_ratio, 1.0) if mode == "block" else None
    return estimate_error(sol, np.diag(comp.matrix), lam, mu, scale)


def _mesh_info(mesh, sol) -> MeshInfo:
    return MeshInfo(mesh.mesher, mesh.mesher_version, int(mesh.n_nodes), int(mesh.n_tets), int(sol.n_dofs),
                    int(len(sol.points)), float(mesh.edge_length), float(mesh.envelope),
                    "P2 tetrahedron (10 nodes)" + (", curved boundary edges" if mesh.curved_edges is not None else ""),
                    dict(mesh.quality), mesh.cache_key)


def _step(run: Run) -> dict:
    return {"n_dofs": int(run.solution.n_dofs), "error": float(run.estimate.matrix),
            "seconds": float(sum(run.timing.values()))}


def _refine(run: Run, tolerance, max_dofs, solve_with, progress) -> Refinement:
    """Refine by the error indicator until every diagonal estimate is below ``tolerance`` or the
    DOF budget would be passed; the last run and the record of the steps."""
    from .mesh.refine import size_function

    steps = [_step(run)]
    while run.estimate.matrix > tolerance and run.solution.n_dofs * REFINE_GROWTH <= max_dofs:
        progress(f"refining: estimated error {100 * run.estimate.matrix:.2g}% > {100 * tolerance:.2g}% at "
                 f"{run.solution.n_dofs} DOF")
        run = solve_with(size_function(run.mesh.points, run.mesh.tets, run.estimate.indicator))
        steps.append(_step(run))
    est = run.estimate
    reached = bool(est.matrix <= tolerance)
    note = (f"estimated error {100 * est.matrix:.2g}% <= {100 * tolerance:.2g}% after {len(steps) - 1} refinements"
            if reached else f"stopped at {100 * est.matrix:.2g}% > {100 * tolerance:.2g}%: the next mesh would pass "
                            f"the budget of {max_dofs} DOF")
    record = {"tolerance": float(tolerance), "reached": reached, "steps": steps, "max_dofs": int(max_dofs),
              "seconds": float(sum(st["seconds"] for st in steps)), "note": note}
    if not reached:  # the result is usable, but not what was asked: say so beside the JSON's reached: false
        warnings.warn(f"tolerance {100 * tolerance:.2g}% not reached: {note} (max_dofs, --max-dofs); the result "
                      f"keeps its larger estimated error", LinkFeaWarning, stacklevel=3)
    return Refinement(run, record)


def _discretization_error(est, mode: str) -> dict:
    """The recovered-stress estimate as the result records it."""
    d = est.to_dict()
    if mode == "block":
        d["note"] += "; block mode: the loads are nodal forces on the block, so the estimate is approximate there"
    return d


def sharp_edges_note(link) -> dict:
    """The link body's sharp re-entrant (concave) edges and what they mean for the result."""
    from .mesh.gmsh import concave_edges

    try:
        n = len(concave_edges(link.body))
    except Exception:  # a body OpenCASCADE cannot classify (e.g. a surface mesh): say nothing rather than guess
        return {"count": None, "note": "not checked (the body could not be classified)"}
    if n == 0:
        return {"count": 0, "note": "no sharp re-entrant edges"}
    return {"count": n, "note": (f"{n} sharp re-entrant edge{'s' if n > 1 else ''}: the stress is singular there, "
                                 "and the compliance converges slowly; a machining radius removes this")}


def default_material_note(spec, material: str | None) -> str:
    """One line saying that a STEP or surface file was computed in the default material, or ''."""
    from .cad import is_step
    from .cad.surface import is_surface

    if material is not None or not (is_step(spec) or is_surface(spec)):
        return ""
    m = get_material(DEFAULT_MATERIAL)
    return (f"material: {m.name} (E = {m.E:g} MPa, nu = {m.nu:g}) by default, the file names none; choose "
            "another with --material (material= in Python)")


def _source_file(spec) -> Path:
    """The absolute path of the file ``spec`` names: a STEP or surface file, or a script (bare names
    resolved by :func:`linkfea.runtime.resources.find_script`)."""
    from .cad import is_step, resolve_script
    from .cad.surface import is_surface

    if is_step(spec) or is_surface(spec):
        p = Path(str(spec))
        return p.resolve() if p.is_file() else p  # a missing file is reported by its loader
    return resolve_script(spec)


def compute(spec, options: ComputeOptions | None = None, *, params: dict | None = None,
            progress: Callable[[str], None] | bool | None = None, cache_dir=None) -> LinkResult:
    """Compute a link's 6x6 compliance at its reference frame.

    Parameters
    ----------
    spec : str or Path
        A cad/ script (path or bare name such as ``"bar"``), a STEP file or a triangle surface
        (STL, OBJ, PLY).
    options : ComputeOptions, optional
        How the link is computed (default ``ComputeOptions()``), checked when made:

        - ``mesh_size``: target edge length, mm (default :func:`linkfea.mesh.default_mesh_size`);
        - ``mode``: ``"rigid"`` coupling of the tip interface, or the pseudo-rigid ``"block"`` with
          ``E * block_ratio``;
        - ``material``: overrides the script's material (STEP default: steel);
        - ``base``, ``tip``: interface selectors (required for STEP, optional overrides for scripts);
        - ``convergence``: also solve at ``2h`` and ``sqrt(2) h`` and put the Richardson error
          estimate of the finest compliance into ``diagnostics.error_estimate``;
        - ``envelope``: fTetWild envelope relative to the bounding-box diagonal (default
          :data:`linkfea.mesh.DEFAULT_EPSILON` = 1e-3); smaller follows small curved faces more
          closely (see ``mesh_info.quality``) but meshes much slower;
        - ``mesher``: gmsh meshes the CAD faces exactly (default for scripts and STEP); pytetwild
          meshes a tessellation (default for STL, OBJ and PLY surfaces);
        - ``assembler``: ``"kernel"`` or ``"skfem"``, the slower reference path, equal to round-off
          (see :func:`linkfea.fem.problem.solve_link`);
        - ``solver``: PARDISO (``"direct"``), CG with multigrid (``"iterative"``,
          :mod:`linkfea.solvers.iterative`), or ``"auto"``: direct unless its peak memory, estimated
          before the solve, exceeds the memory at hand; ``result.solver`` records the choice and CG's
          convergence;
        - ``tolerance``, ``max_dofs``: refine (gmsh, local sizes from the error indicator,
          :mod:`linkfea.mesh.refine`) until the estimated error of every diagonal entry is below
          ``tolerance`` (0.01 = 1%), or the next mesh would pass ``max_dofs``;
          ``diagnostics.refinement`` says which, with each step's DOF and error.
    params : dict, optional
        Script parameters (strings are converted to the defaults' types).
    progress : callable, None or False
        Called with a short message at each stage; None (the default) prints each stage as a line on
        stderr (:class:`linkfea.runtime.progress.StderrLines`), False says nothing.
    cache_dir : path, optional
        Mesh cache folder.
    """
    from .cad import build_link
    from .files.atomic import file_sha256
    from .mesh import default_mesh_size

    opts = (ComputeOptions() if options is None else options).for_input(spec)
    progress = or_default(progress)
    t_all = time.perf_counter()
    progress("cad")
    t0 = time.perf_counter()
    source = _source_file(spec)  # before the CAD: a script is run from exactly this file
    link = build_link(source, params, material=opts.material, base=opts.base, tip=opts.tip,
                      with_block=(opts.mode == "block"))
    mat = get_material(link.material)
    note = default_material_note(spec, opts.material)
    if note:
        progress(note)
    t_cad = time.perf_counter() - t0
    H = opts.mesh_size if opts.mesh_size is not None else default_mesh_size(link)

    richardson_fields: dict = {}
    refinement = None
    if opts.convergence:
        from .fem.convergence import richardson

        sizes = [2.0 * H, math.sqrt(2.0) * H, H]
        runs = []
        for h in sizes:
            progress(f"convergence: mesh size {h:.3g} mm")
            runs.append(_solve_once(link, mat, h, opts, cache_dir, progress))
        rich = richardson(sizes, [r.fit.matrix for r in runs])
        run = runs[-1]
        richardson_fields = dict(
            error_estimate=float(rich.error_diagonal), observed_order=float(rich.order_diagonal),
            convergence_sizes=sizes,
            error_estimate_note=("Richardson estimate of the relative error of the diagonal (largest entry) from "
                                 "3 mesh sizes" + (f"; {rich.note}" if rich.note else "")))
    else:
        run = _solve_once(link, mat, H, opts, cache_dir, progress)
        if opts.tolerance is not None:
            refined = _refine(run, opts.tolerance, opts.max_dofs,
                              lambda size_at: _solve_once(link, mat, H, opts, cache_dir, progress, size_at), progress)
            run, refinement = refined.run, refined.record
        richardson_fields = dict(error_estimate=None, error_estimate_note="not computed: run with --convergence "
                                                                          "(3 mesh sizes, Richardson)")
    from .mesh.linkmesh import sliver_warning

    slivers = sliver_warning(link.name, run.mesh.quality, run.mesh.n_tets, run.mesh.mesher)
    if slivers:
        warnings.warn(slivers, LinkFeaWarning, stacklevel=2)
    t0 = time.perf_counter()
    sharp = sharp_edges_note(link)
    timing = {**run.timing, "edges": time.perf_counter() - t0}
    comp = run.fit
    diagnostics = Diagnostics(symmetry_error=float(comp.symmetry_error), fit_residual=float(comp.fit_residual),
                              min_eigenvalue=float(comp.min_eigenvalue),
                              discretization_error=_discretization_error(run.estimate, opts.mode),
                              sharp_edges=sharp, refinement=refinement, **richardson_fields)
    timing = {"cad": t_cad, **timing, "total": time.perf_counter() - t_all}
    from .result.schema import versions

    return LinkResult(value=comp.compliance, name=link.name, source=str(source), source_sha256=file_sha256(source),
                      params=dict(link.params),
                      material=mat, mode=opts.mode, block_ratio=opts.block_ratio if opts.mode == "block" else None,
                      mesh_info=_mesh_info(run.mesh, run.solution), diagnostics=diagnostics,
                      solver=run.solution.solver, timing=timing, versions=versions(),
                      volume=float(link.body.Volume()), link=link, mesh=run.mesh, solution=run.solution,
                      fit=comp, estimate=run.estimate)
