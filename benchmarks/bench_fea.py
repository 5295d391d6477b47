"""Benchmark of the linkfea FEA stage against CalculiX on the same P2 mesh.

Prints DOFs, the time of every stage (CAD, mesh, assemble, factor, solve, fit),
peak memory, and runs CalculiX (C3D10 + *RIGID BODY) on the same mesh in the
same run, printing the time ratio and the agreement of the two compliances.

Usage::

    .venv/bin/python benchmarks/bench_fea.py                      # CAD bar via the pipeline if present
    .venv/bin/python benchmarks/bench_fea.py --source structured  # 200x20x10 bar, structured tets
    .venv/bin/python benchmarks/bench_fea.py --mesh-size 2.5 --no-ccx

Heavy (about a minute at 100k DOF): run it alone.
"""
from __future__ import annotations

import argparse
import os
import platform
import resource
import shutil
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))  # structured meshes (tests/meshes.py)


def _rss_mb(who=resource.RUSAGE_SELF) -> float:
    return resource.getrusage(who).ru_maxrss / 1024.0  # Linux: KiB


def _pipeline_mesh(mesh_size, mode, timing):
    """CAD + mesh stages of the pipeline (linkfea.cad / linkfea.mesh) for cad/bar.py."""
    from linkfea.cad import build_link
    from linkfea.mesh import mesh_link

    t0 = time.perf_counter()
    link = build_link("bar", {"length": 200.0, "width": 20.0, "height": 10.0}, with_block=(mode == "block"))
    timing["cad"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    mesh = mesh_link(link, mesh_size=mesh_size, with_block=(mode == "block"), use_cache=False)
    timing["mesh"] = time.perf_counter() - t0
    return mesh, "cad/bar.py 200x20x10 (pipeline CAD + gmsh)"


def _structured_mesh(n, timing):
    from meshes import bar_link_mesh

    t0 = time.perf_counter()
    mesh = bar_link_mesh(200.0, 20.0, 10.0, *n)
    timing["mesh"] = time.perf_counter() - t0
    return mesh, f"200x20x10 bar, structured {n[0]}x{n[1]}x{n[2]} hexes x 6 tets"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--source", choices=["auto", "cad", "structured"], default="auto")
    ap.add_argument("--mesh-size", type=float, default=3.0, help="pipeline target edge length, mm")
    ap.add_argument("--grid", type=int, nargs=3, default=[60, 12, 6], help="structured hex grid (nx ny nz)")
    ap.add_argument("--mode", choices=["rigid", "block"], default="rigid")
    ap.add_argument("--no-ccx", action="store_true")
    ap.add_argument("--threads", type=int, default=os.cpu_count())
    args = ap.parse_args(argv)

    from linkfea.fem.fit import compliance_from_solution
    from linkfea.fem.problem import solve_link
    from linkfea.mechanics.materials import get_material
    from linkfea.solvers.factorizers import pardiso_factorizer

    steel = get_material("steel")
    timing = {}
    mesh = None
    if args.source in ("auto", "cad"):
        try:
            mesh, label = _pipeline_mesh(args.mesh_size, args.mode, timing)
        except Exception as exc:  # pipeline stages not in the tree yet
            if args.source == "cad":
                raise
            print(f"[pipeline CAD/mesh unavailable: {type(exc).__name__}: {exc}] -> structured mesh")
            timing.clear()
    if mesh is None:
        mesh, label = _structured_mesh(tuple(args.grid), timing)

    # Load the PARDISO library once outside the timed stages (a one-off disk search for MKL).
    try:
        import scipy.sparse as sp
        pardiso_factorizer(sp.identity(3, format="csr"))
    except Exception:
        pass

    rss_before = _rss_mb()
    tracemalloc.start()
    t_fea = time.perf_counter()
    sol = solve_link(mesh, steel, mode=args.mode)
    t0 = time.perf_counter()
    comp = compliance_from_solution(sol)
    timing["fit"] = time.perf_counter() - t0
    fea_total = time.perf_counter() - t_fea
    numpy_peak = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    timing.update(sol.timing)
    rss_fea = _rss_mb()

    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores; threads {args.threads}")
    print(f"mesh: {label}: {mesh.n_nodes} vertices, {mesh.n_tets} tets, P2 nodes {len(sol.points)}, "
          f"solved DOFs {sol.n_dofs}, mode {args.mode}")
    for k in ("cad", "mesh", "assemble", "factor", "solve", "fit"):
        if k in timing:
            print(f"  {k:9s} {timing[k]:8.3f} s")
    fea_core = sum(sol.timing.values())
    print(f"  FEA total (assemble+factor+solve+fit) {fea_total:.3f} s; assembly share "
          f"{sol.timing['assemble'] / fea_core:.1%} of assemble+factor+solve")
    print(f"  peak memory: numpy arrays of the FEA stage {numpy_peak:.0f} MB (tracemalloc); process peak RSS "
          f"{rss_fea:.0f} MB (before FEA {rss_before:.0f} MB; PARDISO's own memory is only in the RSS)")
    print(f"  symmetry error {comp.symmetry_error:.2e}, fit residual {comp.fit_residual:.2e}")

    if not args.no_ccx and shutil.which("ccx"):
        from calculix import solve_calculix

        t0 = time.perf_counter()
        res = solve_calculix(mesh, steel, mode=args.mode, threads=args.threads)
        ccx_total = time.perf_counter() - t0
        rel = np.linalg.norm(res.compliance - comp.raw) / np.linalg.norm(comp.raw)
        print(f"CalculiX: ccx run {res.wall_time:.3f} s, with deck writing and parsing {ccx_total:.3f} s, "
              f"peak RSS (ccx) {res.peak_memory_mb:.0f} MB")
        print(f"  ratio CalculiX / linkfea FEA = {ccx_total / fea_total:.2f}x "
              f"(ccx run alone {res.wall_time / fea_total:.2f}x)")
        print(f"  compliance agreement |C_ccx - C| / |C| = {rel:.2e}")
    elif not args.no_ccx:
        print("CalculiX (ccx) not installed: install Debian package calculix-ccx")


if __name__ == "__main__":
    main()
