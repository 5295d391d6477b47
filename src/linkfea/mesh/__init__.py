"""Tetrahedral meshing of a link: gmsh for CAD solids (default), pytetwild on request.

:func:`mesh_link` dispatches on ``mesher``: ``"gmsh"`` meshes the CAD itself
(:mod:`linkfea.mesh.gmsh`: exact interface faces, conforming block by an OCC
fragment, deterministic, fast); ``"pytetwild"`` meshes a tessellation with
fTetWild (:mod:`linkfea.mesh.pytetwild`).  Both end in :func:`linkfea.mesh.linkmesh.finish_mesh`: the quality
report and the interface-area gate (a base or tip area more than
:data:`AREA_GATE` off its CAD faces is an error, never a silent number).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable

from ..cad.link import interface_faces
from ..options import ENVELOPE, MESH_SIZE, MESHERS
from ..runtime import checks
from ..runtime.child import run_in_child
from ..runtime.errors import LinkFeaError
from ..runtime.progress import or_quiet
from . import gmsh as mesh_gmsh
from .linkmesh import AREA_GATE, LinkMesh, finish_mesh
from .pytetwild import mesh_with_pytetwild

DEFAULT_EPSILON = 1e-3
"""fTetWild envelope relative to the bounding-box diagonal (its own default)."""

CURVED = True
"""gmsh meshes are second order in geometry: the P2 node of a boundary edge lies on the CAD
surface, not on the chord (isoparametric P2; docs/benchmarks.md measures the gain)."""

DEFAULT_MESHER = "gmsh"


def default_mesh_size(link) -> float:
    """Default target edge length, mm: 0.6 x the mean wall thickness 2V/A, at most diag/20.

    P2 tets bend well with one to two elements through a wall, so the
    thinnest walls set the size; 2V/A is the thickness of a plate and a
    generous estimate for compact parts, hence the cap.
    """
    s = link.body
    t = 2.0 * s.Volume() / s.Area()
    return float(min(0.6 * t, s.BoundingBox().DiagonalLength / 20.0))


TETS_PER_CUBE = 5.5
"""Tets per ``H^3`` of volume in a gmsh mesh of target edge ``H``: measured 5.5-5.7 on the bar (H = 3 mm,
rigid and block), 6.4 on the parallelogram bar and 9.6 on the sharp foot (their default sizes: the
corner and interface refinement adds to it); coarse meshes have more (the surface dominates).  The
smallest measured value, so the estimate below is at the low end."""

DOFS_PER_TET = 4.0
"""P2 unknowns per tet of a large mesh: ``3 (n_vertices + n_edges)`` with ``n_edges ~ n_vertices +
n_tets`` (Euler) and ``n_vertices ~ n_tets / 5.5`` gives 4.1; coarse meshes have more (5.8 at 8k DOF)."""


@dataclass(frozen=True)
class MeshEstimate:
    """Size of a mesh before it is made: tets, P2 unknowns and the memory of solving them."""

    mesh_size: float
    n_tets: float
    n_dofs: float
    memory: float

    def check(self, budget: float | None = None) -> None:
        """Refuse a mesh whose solve cannot fit in ``budget`` bytes (default: what the solver may use now)."""
        from ..runtime.memory import human_bytes
        from ..solvers.iterative import available_bytes

        budget = available_bytes() if budget is None else budget
        if self.memory > budget:
            raise LinkFeaError(f"a mesh of edge {self.mesh_size:.3g} mm would have about {self.n_tets:.2g} tets "
                               f"({self.n_dofs:.2g} DOF) and need about {human_bytes(self.memory)} of memory to "
                               f"solve, more than the {human_bytes(budget)} available; use a larger --mesh-size "
                               "(or check the link's dimensions)")


def mesh_estimate(volume: float, mesh_size: float) -> MeshEstimate:
    """The mesh of ``volume`` mm^3 at edge ``mesh_size`` mm, estimated from the size field before meshing:
    :data:`TETS_PER_CUBE` tets per ``H^3``, :data:`DOFS_PER_TET` unknowns each, and the iterative solver's
    measured memory per unknown (the lighter path: :func:`linkfea.solvers.iterative.iterative_peak_bytes`)."""
    from ..solvers.iterative import iterative_peak_bytes

    cube = float(mesh_size) ** 3
    n_tets = TETS_PER_CUBE * float(volume) / cube if cube > 0.0 else math.inf  # 1e-200 mm: H^3 underflows
    n_dofs = DOFS_PER_TET * n_tets
    return MeshEstimate(float(mesh_size), n_tets, n_dofs, iterative_peak_bytes(n_dofs))


def link_volume(link, with_block: bool) -> float:
    """The volume to mesh, mm^3: the body, and the block in block mode."""
    return float(link.body.Volume()) + (float(link.block.Volume()) if with_block and link.block is not None else 0.0)


def mesh_link(link, mesh_size: float | None = None, with_block: bool = True, epsilon: float = DEFAULT_EPSILON,
              cache_dir: str | Path | None = None, use_cache: bool = True, sizing: bool = True,
              progress: Callable[[str], None] | None = None, mesher: str = DEFAULT_MESHER,
              area_gate: float | None = AREA_GATE, size_at: Callable | None = None) -> LinkMesh:
    """Mesh a :class:`linkfea.cad.link.Link` into a :class:`LinkMesh`.

    Parameters
    ----------
    link : Link
    mesh_size : float, optional
        Absolute target edge length, mm (default :func:`default_mesh_size`).
    with_block : bool
        Mesh the reference block too (block mode); in rigid mode it is left out
        and the tip faces are coupled directly.
    epsilon : float
        fTetWild envelope relative to the bounding-box diagonal (pytetwild only).
    cache_dir : path, optional
        Mesh cache folder (default ``$LINKFEA_CACHE_DIR``, else the platform's cache folder; pytetwild only,
        gmsh is deterministic and fast).
    use_cache : bool
        Read and write the cache.
    sizing : bool
        Refine near curved faces too small for ``mesh_size`` (:func:`linkfea.mesh.pytetwild.sizing_field`; pytetwild only,
        gmsh refines by curvature).
    progress : callable, optional
        Called with a short message at each stage.
    mesher : {"gmsh", "pytetwild"}
    area_gate : float or None
        Largest allowed relative interface-area error (None: report only).
    size_at : callable, optional
        ``size_at(x, y, z)``: a local edge length (mm) below ``mesh_size`` where the mesh must be
        finer (gmsh only; the error-driven refinement, :mod:`linkfea.mesh.refine`).

    Raises
    ------
    LinkFeaError
        Bad size, a selector matching no mesh facet, overlapping interfaces,
        inverted or missing cells.
    """
    progress = or_quiet(progress)
    # the ranges of linkfea.options (a ComputeOptions is already checked; a direct call is checked here)
    H = default_mesh_size(link) if mesh_size is None else checks.number(mesh_size, "mesh_size", MESH_SIZE)
    epsilon = checks.number(epsilon, "envelope", ENVELOPE)
    block_solid = link.block if with_block else None
    if with_block and block_solid is None:
        raise LinkFeaError(f"{link.name}: block mode needs a reference block; use --mode rigid")

    if mesher not in MESHERS:
        raise LinkFeaError(f"unknown mesher {mesher!r}; use gmsh or pytetwild")
    mesh_estimate(link_volume(link, with_block), H).check()  # before the mesher: it cannot be stopped midway
    if size_at is not None and mesher != "gmsh":
        raise LinkFeaError("refinement by the error estimate (--tolerance) needs the gmsh mesher")
    if mesher == "gmsh":
        return _mesh_with_gmsh(link, H, block_solid, progress, area_gate, size_at)

    return mesh_with_pytetwild(link, H, block_solid, epsilon, cache_dir, use_cache, sizing, progress, area_gate)


def _mesh_with_gmsh(link, H, block_solid, progress, area_gate, size_at=None) -> LinkMesh:
    diag = link.body.BoundingBox().DiagonalLength
    if H > diag:
        raise LinkFeaError(f"mesh size {H:g} mm exceeds the part size ({diag:.3g} mm bounding-box diagonal)")
    base_faces, tip_faces = interface_faces(link)
    progress(f"meshing with gmsh (edge {H:.3g} mm)")
    # In a child process: gmsh does not return to Python until done, and Ctrl-C must stop it now.
    g = run_in_child(mesh_gmsh.mesh_gmsh, link.name, link.body, block_solid, base_faces, tip_faces, H,
                     curved=CURVED, size_at=size_at)
    progress("checking interfaces")
    m = finish_mesh(link, g.points, g.tets, g.block, g.base_facets, g.tip_facets, block_solid, H, 0.0, "",
                    "gmsh", mesh_gmsh.version(), area_gate)
    if g.curved_edges is None:
        return m
    m.quality["n_curved_edges"] = int(len(g.curved_edges))
    return replace(m, curved_edges=g.curved_edges, curved_points=g.curved_points)
