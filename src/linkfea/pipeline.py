"""The link stage end to end: CAD -> mesh -> P2 solve -> rigid fit -> checked compliance."""
from __future__ import annotations

import math
import time
import warnings
from pathlib import Path
from typing import Callable

from .mechanics.materials import get_material
from .options import BLOCK_RATIO as BLOCK_RATIO  # the options' ranges, also importable from here
from .options import ENVELOPE as ENVELOPE
from .options import MAX_DOFS, ComputeOptions
from .options import MESH_SIZE as MESH_SIZE
from .result.linkresult import LinkResult
from .runtime.errors import LinkFeaError, LinkFeaWarning
from .runtime.progress import or_quiet

__all__ = ["ComputeOptions", "LinkResult", "compute"]
REFINE_GROWTH = 2.5
"""Largest DOF growth expected from one refinement step (for the budget check before meshing)."""


def _solve_once(link, material, H, opts: ComputeOptions, cache_dir, progress, size_at=None):
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
    return mesh, sol, comp, timing, est


def _estimate(sol, comp, material, mode, block_ratio, mesh):
    """The recovered-stress estimate of the compliance's discretization error (linkfea.fem.estimate)."""
    import numpy as np

    from .fem.estimate import estimate_error
    from .fem.p2 import lame

    lam, mu = lame(material)
    scale = np.where(np.asarray(mesh.block, dtype=bool), block_ratio, 1.0) if mode == "block" else None
    return estimate_error(sol, np.diag(comp.matrix), lam, mu, scale)


def _mesh_info(mesh, sol) -> dict:
    return {"mesher": mesh.mesher, "mesher_version": mesh.mesher_version, "n_nodes": int(mesh.n_nodes),
            "n_tets": int(mesh.n_tets), "n_dofs": int(sol.n_dofs),
            "n_p2_nodes": int(len(sol.points)), "edge_length": float(mesh.edge_length),
            "envelope": float(mesh.envelope), "element": "P2 tetrahedron (10 nodes)" + (
                ", curved boundary edges" if getattr(mesh, "curved_edges", None) is not None else ""),
            "quality": dict(mesh.quality), "cache_key": mesh.cache_key}


def _refine(run, tolerance, max_dofs, solve_with, progress):
    """Refine by the error indicator until every diagonal estimate is below ``tolerance`` or the
    DOF budget would be passed; returns the last run and the record of the steps."""
    from .mesh.refine import size_function

    mesh, sol, comp, timing, est = run
    steps = [{"n_dofs": int(sol.n_dofs), "error": float(est.matrix), "seconds": float(sum(timing.values()))}]
    while est.matrix > tolerance and sol.n_dofs * REFINE_GROWTH <= max_dofs:
        progress(f"refining: estimated error {100 * est.matrix:.2g}% > {100 * tolerance:.2g}% at {sol.n_dofs} DOF")
        mesh, sol, comp, timing, est = solve_with(size_function(mesh.points, mesh.tets, est.indicator))
        steps.append({"n_dofs": int(sol.n_dofs), "error": float(est.matrix), "seconds": float(sum(timing.values()))})
    reached = bool(est.matrix <= tolerance)
    note = (f"estimated error {100 * est.matrix:.2g}% <= {100 * tolerance:.2g}% after {len(steps) - 1} refinements"
            if reached else f"stopped at {100 * est.matrix:.2g}% > {100 * tolerance:.2g}%: the next mesh would pass "
                            f"the budget of {max_dofs} DOF")
    record = {"tolerance": float(tolerance), "reached": reached, "steps": steps, "max_dofs": int(max_dofs),
              "seconds": float(sum(st["seconds"] for st in steps)), "note": note}
    if not reached:  # the result is usable, but not what was asked: say so beside the JSON's reached: false
        warnings.warn(f"tolerance {100 * tolerance:.2g}% not reached: {note} (max_dofs, --max-dofs); the result "
                      f"keeps its larger estimated error", LinkFeaWarning, stacklevel=3)
    return mesh, sol, comp, timing, est, record


def _error_diagnostics(diagnostics: dict, est, link, mode: str) -> float:
    """Put the error estimate and the sharp-edge note into ``diagnostics``; the seconds the edges took."""
    diagnostics["discretization_error"] = est.to_dict()
    if mode == "block":
        diagnostics["discretization_error"]["note"] += ("; block mode: the loads are nodal forces on the block, "
                                                        "so the estimate is approximate there")
    t0 = time.perf_counter()
    diagnostics["sharp_edges"] = sharp_edges_note(link)
    return time.perf_counter() - t0


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


def _source_file(spec) -> Path:
    """The absolute path of the file ``spec`` names: a STEP or surface file, or a script (bare names
    resolved by :func:`linkfea.runtime.resources.find_script`)."""
    from .cad import is_step, resolve_script
    from .cad.surface import is_surface

    if is_step(spec) or is_surface(spec):
        p = Path(str(spec))
        return p.resolve() if p.is_file() else p  # a missing file is reported by its loader
    return resolve_script(spec)


def compute(spec, params: dict | None = None, mesh_size: float | None = None, mode: str = "rigid",
            block_ratio: float = 1000.0, material: str | None = None, base=None, tip=None,
            convergence: bool = False, progress: Callable[[str], None] | None = None,
            cache_dir=None, epsilon: float | None = None, mesher: str | None = None,
            assembler: str = "kernel", solver: str = "auto", tolerance: float | None = None,
            max_dofs: int = MAX_DOFS, envelope: float | None = None,
            options: ComputeOptions | None = None) -> LinkResult:
    """Compute a link's 6x6 compliance at its reference frame.

    Parameters
    ----------
    spec : str or Path
        A cad/ script (path or bare name such as ``"bar"``) or a STEP file.
    params : dict, optional
        Script parameters (strings are converted to the defaults' types).
    mesh_size : float, optional
        Target edge length, mm (default :func:`linkfea.mesh.default_mesh_size`).
    mode : {"rigid", "block"}
        Rigid coupling of the tip interface, or the pseudo-rigid block with
        ``E * block_ratio``.
    material : str, optional
        Overrides the script's material (STEP default: steel).
    base, tip : str or selector, optional
        Interface selectors (required for STEP, optional overrides for scripts).
    convergence : bool
        Also solve at ``2h`` and ``sqrt(2) h`` and put the Richardson error
        estimate of the finest compliance into ``diagnostics["error_estimate"]``.
    progress : callable, optional
        Called with a short message at each stage.
    cache_dir : path, optional
        Mesh cache folder.
    envelope : float, optional
        fTetWild envelope relative to the bounding-box diagonal (default
        :data:`linkfea.mesh.DEFAULT_EPSILON` = 1e-3).  Smaller follows small
        curved faces more closely (see ``mesh.quality``) but meshes much slower.
    mesher : {"gmsh", "pytetwild"}, optional
        gmsh meshes the CAD faces exactly (default for scripts and STEP); pytetwild meshes a
        tessellation (default for STL, OBJ and PLY surfaces).
    assembler : {"kernel", "skfem"}
        Stiffness assembly (see :func:`linkfea.fem.problem.solve_link`); ``skfem`` is the slower
        reference path, equal to round-off.
    solver : {"auto", "direct", "iterative"}
        PARDISO (``direct``), CG with pyamg multigrid (``iterative``, :mod:`linkfea.solvers.iterative`), or
        ``auto``: direct unless its peak memory, estimated before the solve, exceeds the memory at
        hand.  ``result.solver`` records the choice and CG's convergence.
    tolerance : float, optional
        Refine (gmsh, local sizes from the error indicator, :mod:`linkfea.mesh.refine`) until the
        estimated error of every diagonal entry is below it (0.01 = 1%), or the next mesh would
        pass ``max_dofs``; ``diagnostics["refinement"]`` says which, with each step's DOF and error.
    options : ComputeOptions, optional
        All of the options above as one value (then none of them may be given alone).
    epsilon : float, optional
        Deprecated name of ``envelope``.
    """
    from .cad import build_link
    from .files.atomic import file_sha256
    from .mesh import default_mesh_size

    if epsilon is not None:
        warnings.warn("compute(epsilon=...) is deprecated: use envelope=...", DeprecationWarning, stacklevel=2)
        if envelope is not None:
            raise LinkFeaError("give envelope or its deprecated name epsilon, not both")
        envelope = epsilon
    given = ComputeOptions(mesh_size=mesh_size, mode=mode, block_ratio=block_ratio, material=material, base=base,
                           tip=tip, envelope=envelope, convergence=convergence, mesher=mesher, assembler=assembler,
                           solver=solver, tolerance=tolerance, max_dofs=max_dofs)
    if options is not None:
        if given != ComputeOptions():
            raise LinkFeaError("give compute options as options=ComputeOptions(...) or as keywords, not both")
        given = options
    opts = given.for_input(spec)
    progress = or_quiet(progress)
    t_all = time.perf_counter()
    progress("cad")
    t0 = time.perf_counter()
    source = _source_file(spec)  # before the CAD: a script is run from exactly this file
    link = build_link(source, params, material=opts.material, base=opts.base, tip=opts.tip,
                      with_block=(opts.mode == "block"))
    mat = get_material(link.material)
    t_cad = time.perf_counter() - t0
    H = opts.mesh_size if opts.mesh_size is not None else default_mesh_size(link)

    diagnostics: dict = {}
    if opts.convergence:
        from .fem.convergence import richardson

        sizes = [2.0 * H, math.sqrt(2.0) * H, H]
        runs = []
        for h in sizes:
            progress(f"convergence: mesh size {h:.3g} mm")
            runs.append(_solve_once(link, mat, h, opts, cache_dir, progress))
        rich = richardson(sizes, [r[2].matrix for r in runs])
        mesh, sol, comp, timing, est = runs[-1]
        diagnostics["error_estimate"] = float(rich.error_diagonal)
        diagnostics["observed_order"] = float(rich.order_diagonal)
        diagnostics["convergence_sizes"] = sizes
        diagnostics["error_estimate_note"] = ("Richardson estimate of the relative error of the diagonal "
                                              "(largest entry) from 3 mesh sizes" + (f"; {rich.note}" if rich.note else ""))
    else:
        mesh, sol, comp, timing, est = _solve_once(link, mat, H, opts, cache_dir, progress)
        if opts.tolerance is not None:
            mesh, sol, comp, timing, est, diagnostics["refinement"] = _refine(
                (mesh, sol, comp, timing, est), opts.tolerance, opts.max_dofs,
                lambda size_at: _solve_once(link, mat, H, opts, cache_dir, progress, size_at), progress)
        diagnostics["error_estimate"] = None
        diagnostics["error_estimate_note"] = "not computed: run with --convergence (3 mesh sizes, Richardson)"
    timing["edges"] = _error_diagnostics(diagnostics, est, link, opts.mode)
    diagnostics.update(symmetry_error=float(comp.symmetry_error), fit_residual=float(comp.fit_residual),
                       min_eigenvalue=float(comp.min_eigenvalue))
    timing = {"cad": t_cad, **timing, "total": time.perf_counter() - t_all}
    from .result.schema import versions

    mesh_info = _mesh_info(mesh, sol)
    return LinkResult(value=comp.compliance, name=link.name, source=str(source), source_sha256=file_sha256(source),
                      params=dict(link.params),
                      material=mat, mode=opts.mode, block_ratio=opts.block_ratio if opts.mode == "block" else None,
                      mesh_info=mesh_info, diagnostics=diagnostics, solver=dict(sol.solver), timing=timing,
                      versions=versions(), volume=float(link.body.Volume()), link=link, mesh=mesh, solution=sol,
                      fit=comp, estimate=est)
