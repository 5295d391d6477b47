"""The link stage end to end: CAD -> mesh -> P2 solve -> rigid fit -> checked compliance."""
from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Callable

from . import checks
from .errors import LinkFeaError
from .materials import get_material
from .result import LinkResult

__all__ = ["LinkResult", "compute"]

#: valid ranges of the numeric arguments of :func:`compute` (also ``linkfea sweep``'s options)
MESH_SIZE = checks.Bounds(0, lo_open=True, unit="mm")
BLOCK_RATIO = checks.Bounds(1, lo_open=True)
ENVELOPE = checks.Bounds(0, 0.1, lo_open=True, hi_open=True)


def _solve_once(link, material, H, mode, block_ratio, cache_dir, say, epsilon, mesher="gmsh", assembler="kernel"):
    from .fem import solve_link
    from .fit import compliance_from_solution
    from .mesh import mesh_link

    t0 = time.perf_counter()
    mesh = mesh_link(link, H, with_block=(mode == "block"), epsilon=epsilon, cache_dir=cache_dir, progress=say,
                     mesher=mesher)
    t_mesh = time.perf_counter() - t0
    sol = solve_link(mesh, material, mode=mode, block_ratio=block_ratio, progress=say, assembler=assembler)
    say("fit")
    t0 = time.perf_counter()
    comp = compliance_from_solution(sol)
    t_fit = time.perf_counter() - t0
    timing = {"mesh": t_mesh, **{k: float(sol.timing.get(k, 0.0)) for k in ("assemble", "factor", "solve")},
              "fit": t_fit}
    return mesh, sol, comp, timing


def _source_file(spec) -> Path:
    """The absolute path of the file ``spec`` names: a STEP or surface file, or a script (bare names
    resolved by :func:`linkfea.resources.find_script`)."""
    from .cad import is_step, resolve_script
    from .surface import is_surface

    if is_step(spec) or is_surface(spec):
        p = Path(str(spec))
        return p.resolve() if p.is_file() else p  # a missing file is reported by its loader
    return resolve_script(spec)


def compute(spec, params: dict | None = None, mesh_size: float | None = None, mode: str = "rigid",
            block_ratio: float = 1000.0, material: str | None = None, base=None, tip=None,
            convergence: bool = False, progress: Callable[[str], None] | None = None,
            cache_dir=None, epsilon: float | None = None, mesher: str | None = None,
            assembler: str = "kernel") -> LinkResult:
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
    epsilon : float, optional
        fTetWild envelope relative to the bounding-box diagonal (default
        :data:`linkfea.mesh.DEFAULT_EPSILON` = 1e-3).  Smaller follows small
        curved faces more closely (see ``mesh.quality``) but meshes much slower.
    mesher : {"gmsh", "pytetwild"}, optional
        gmsh meshes the CAD faces exactly (default for scripts and STEP); pytetwild meshes a
        tessellation (default for STL, OBJ and PLY surfaces).
    assembler : {"kernel", "skfem"}
        Stiffness assembly (see :func:`linkfea.fem.solve_link`); ``skfem`` is the slower
        reference path, equal to round-off.
    """
    from .cad import build_link
    from .fem import ASSEMBLERS, MODES
    from .mesh import DEFAULT_EPSILON, default_mesh_size
    from .resources import file_sha256

    mesh_size = checks.optional_number(mesh_size, "mesh_size", MESH_SIZE)
    block_ratio = checks.number(block_ratio, "block_ratio", BLOCK_RATIO)
    epsilon = DEFAULT_EPSILON if epsilon is None else checks.number(epsilon, "epsilon", ENVELOPE)

    say = progress or (lambda msg: None)
    if mode not in MODES:
        raise LinkFeaError(f"unknown mode {mode!r}; use rigid or block")
    if assembler not in ASSEMBLERS:
        raise LinkFeaError(f"unknown assembler {assembler!r}; use kernel or skfem")
    from .mesh import MESHERS
    from .surface import is_surface

    if mesher is None:
        mesher = "pytetwild" if is_surface(spec) else "gmsh"
    if mesher not in MESHERS:
        raise LinkFeaError(f"unknown mesher {mesher!r}; use gmsh or pytetwild")
    t_all = time.perf_counter()
    say("cad")
    t0 = time.perf_counter()
    source = _source_file(spec)  # before the CAD: a script is run from exactly this file
    link = build_link(source, params, material=material, base=base, tip=tip, with_block=(mode == "block"))
    mat = get_material(link.material)
    t_cad = time.perf_counter() - t0
    H = float(mesh_size) if mesh_size is not None else default_mesh_size(link)

    diagnostics: dict = {}
    if convergence:
        from .convergence import richardson

        sizes = [2.0 * H, math.sqrt(2.0) * H, H]
        runs = []
        for h in sizes:
            say(f"convergence: mesh size {h:.3g} mm")
            runs.append(_solve_once(link, mat, h, mode, block_ratio, cache_dir, say, epsilon, mesher, assembler))
        rich = richardson(sizes, [r[2].matrix for r in runs])
        mesh, sol, comp, timing = runs[-1]
        diagnostics["error_estimate"] = float(rich.error_diagonal)
        diagnostics["observed_order"] = float(rich.order_diagonal)
        diagnostics["convergence_sizes"] = sizes
        diagnostics["error_estimate_note"] = ("Richardson estimate of the relative error of the diagonal "
                                              "(largest entry) from 3 mesh sizes" + (f"; {rich.note}" if rich.note else ""))
    else:
        mesh, sol, comp, timing = _solve_once(link, mat, H, mode, block_ratio, cache_dir, say, epsilon, mesher,
                                              assembler)
        diagnostics["error_estimate"] = None
        diagnostics["error_estimate_note"] = "not computed: run with --convergence (3 mesh sizes, Richardson)"
    diagnostics.update(symmetry_error=float(comp.symmetry_error), fit_residual=float(comp.fit_residual),
                       min_eigenvalue=float(comp.min_eigenvalue))
    timing = {"cad": t_cad, **timing, "total": time.perf_counter() - t_all}
    from .io import versions

    mesh_info = {"mesher": mesh.mesher, "mesher_version": mesh.mesher_version, "n_nodes": int(mesh.n_nodes), "n_tets": int(mesh.n_tets), "n_dofs": int(sol.n_dofs),
                 "n_p2_nodes": int(len(sol.points)), "edge_length": float(mesh.edge_length),
                 "envelope": float(mesh.envelope), "element": "P2 tetrahedron (10 nodes)" + (
                     ", curved boundary edges" if getattr(mesh, "curved_edges", None) is not None else ""),
                 "quality": dict(mesh.quality), "cache_key": mesh.cache_key}
    return LinkResult(value=comp.compliance, name=link.name, source=str(source), source_sha256=file_sha256(source),
                      params=dict(link.params),
                      material=mat, mode=mode, block_ratio=float(block_ratio) if mode == "block" else None,
                      mesh_info=mesh_info, diagnostics=diagnostics, solver=dict(sol.solver), timing=timing,
                      versions=versions(), volume=float(link.body.Volume()), link=link, mesh=mesh, solution=sol,
                      fit=comp)
