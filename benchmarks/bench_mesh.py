"""Benchmark of the meshers: gmsh (CAD faces) against pytetwild (fTetWild), side by side in one run.

1. Meshing time at equal size: pytetwild at the default edge length (no cache), then gmsh with its
   edge length set so its tet count matches (a few cheap gmsh runs), on the foot and on the
   filleted bracket of tests/brackets.py.  Interface-area errors of both.
2. The foot's 6x6 end to end (CAD to JSON through the pipeline) at the default gmsh mesh: (a) in a warm
   process (imports done), (b) as a cold CLI process with its imports itemized (``--only foot``).
   Its converged reference: Richardson over meshes refined along the concave edges, and the
   default's error per diagonal entry (``--only convergence``, a few minutes).
   The foot with machining radii (``fillet``, ``--only fillet``, about ten minutes): its default
   mesh, a refinement sequence and Richardson, and cheaper meshes against that reference.
3. A tube bar (cad/bar.py, section=tube) in block mode, end to end.

Usage::

    .venv/bin/python benchmarks/bench_mesh.py [--skip-pytetwild]

Heavy (a few minutes, mostly fTetWild): run it alone.
"""
from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from linkfea.options import ComputeOptions

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))  # the filleted bracket (tests/brackets.py)


def _mesh(link, H, mesher):
    from linkfea.mesh import mesh_link

    t0 = time.perf_counter()
    m = mesh_link(link, H, with_block=False, mesher=mesher, use_cache=False, area_gate=None)
    return m, time.perf_counter() - t0


def equal_size(label, link, skip_pytetwild):
    from linkfea.mesh import default_mesh_size

    H = default_mesh_size(link)
    print(f"\n## {label}: default edge {H:.3g} mm")
    if skip_pytetwild:
        m, t = _mesh(link, H, "gmsh")
        print(f"gmsh      {m.n_tets:7d} tets  {t:6.2f} s  areas base {m.quality['base_area_error']:+.2e} "
              f"tip {m.quality['tip_area_error']:+.2e}")
        return
    p, tp = _mesh(link, H, "pytetwild")
    h = H
    for _ in range(4):  # match the tet count: n ~ h^-3
        g, tg = _mesh(link, h, "gmsh")
        if abs(g.n_tets / p.n_tets - 1) < 0.05:
            break
        h *= (g.n_tets / p.n_tets) ** (1 / 3)
    for name, m, t, hh in (("pytetwild", p, tp, H), ("gmsh", g, tg, h)):
        print(f"{name:9s} edge {hh:5.3g} mm {m.n_tets:7d} tets {m.n_nodes:7d} vertices  {t:6.2f} s  "
              f"area errors base {m.quality['base_area_error']:+.2e} tip {m.quality['tip_area_error']:+.2e}")
    print(f"meshing speed ratio pytetwild / gmsh = {tp / tg:.1f}x (tets {g.n_tets / p.n_tets:.3f} of pytetwild's)")


IMPORTS = ("cadquery", "OCP", "vtk", "ezdxf", "numpy", "scipy.sparse", "skfem", "gmsh", "pypardiso", "linkfea")
"""Top-level imports itemized in the cold CLI process (cumulative times of ``python -X importtime``)."""


def _import_times(stderr: str) -> dict:
    """Cumulative import seconds of the first (outermost) import of each of :data:`IMPORTS`."""
    out: dict = {}
    for line in stderr.splitlines():
        if not line.startswith("import time:") or "|" not in line:
            continue
        _, cum, name = (x.strip() for x in line[len("import time:"):].split("|"))
        if name in IMPORTS and cum.isdigit():
            out[name] = max(out.get(name, 0.0), int(cum) / 1e6)
    return out


def _stages(t: dict) -> str:
    return ", ".join(f"{k} {v:.2f}" for k, v in t.items() if k != "total")


def foot_end_to_end(warm_runs: int = 3):
    """(a) The pipeline in a warm process (imports done, a first call made: a notebook's second call,
    a sweep worker); (b) the cold CLI process, its wall time and its imports itemized."""
    from linkfea.pipeline import compute

    print("\n## foot end to end (rigid, gmsh, default mesh)")
    t0 = time.perf_counter()
    r = compute("orthoglide_foot")
    print(f"first call in this process (its cad stage includes importing cadquery): {time.perf_counter() - t0:.2f} s "
          f"({_stages(r.timing)})")
    runs = []
    for _ in range(warm_runs):
        t0 = time.perf_counter()
        r = compute("orthoglide_foot")
        runs.append((time.perf_counter() - t0, r.timing))
    wall, timing = sorted(runs, key=lambda x: x[0])[len(runs) // 2]
    print(f"(a) warm, median of {warm_runs}: {r.solution.n_dofs} DOF, compute() {wall:.2f} s wall, pipeline "
          f"total {timing['total']:.2f} s ({_stages(timing)})")
    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "foot.json"
        cmd = [sys.executable, "-m", "linkfea", "compute", "orthoglide_foot", "--no-picture", "-q", "--out", str(out)]
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, env=dict(os.environ))
        t_cli = time.perf_counter() - t0
        import json

        cold = json.loads(out.read_text())["timing"]
        p = subprocess.run([sys.executable, "-X", "importtime", *cmd[1:]], check=True, env=dict(os.environ),
                           capture_output=True, text=True)
    imp = _import_times(p.stderr)
    print(f"(b) cold CLI process to JSON: {t_cli:.2f} s wall; its pipeline {cold['total']:.2f} s "
          f"({_stages(cold)})")
    print("    imports (cumulative s, a second run under -X importtime): "
          + ", ".join(f"{k} {v:.2f}" for k, v in imp.items())
          + " (OCP and vtk and ezdxf are inside cadquery's figure)")


def foot_convergence():
    """The foot's converged compliance: meshes refined along the concave (re-entrant) edges, where the
    stress is singular, at corner sizes h_c = 1.4, 0.93, 0.70 mm (bulk edge 4.65 mm, grading 1 mm/mm),
    Richardson in h_c with the observed order; then the default mesh and uniform refinements against it."""
    import linkfea.mesh.gmsh as G
    from linkfea.cad import build_link
    from linkfea.mesh import default_mesh_size
    from linkfea.pipeline import compute

    print("\n## foot: converged reference (corner-refined meshes, Richardson) and the default's error")
    H = default_mesh_size(build_link("orthoglide_foot", with_block=False))
    saved = (G.CORNER_SIZE_FACTOR, G.FEATURE_GRADING)
    rows = []
    try:
        G.FEATURE_GRADING = 1.0
        for hc in (1.4, 0.93, 0.70):
            G.CORNER_SIZE_FACTOR = hc / H
            r = compute("orthoglide_foot")
            rows.append((hc, r.solution.n_dofs, np.diag(r.compliance)))
            print(f"corner {hc:.2f} mm: {r.solution.n_dofs} DOF, diagonal {np.array2string(rows[-1][2], precision=6)}")
    finally:
        G.CORNER_SIZE_FACTOR, G.FEATURE_GRADING = saved
    (h1, _, c1), (h2, _, c2), (h3, _, c3) = rows
    from linkfea.fem.convergence import richardson

    rich = richardson([h1, h2, h3], [c1, c2, c3])  # per diagonal entry, observed order solved for
    ref = rich.extrapolated
    print(f"observed orders {np.array2string(rich.order, precision=2)}{'; ' + rich.note if rich.note else ''}")
    print(f"reference (Richardson in the corner size): {np.array2string(ref, precision=6)}")
    print(f"corner 0.70 mm mesh vs reference: {np.array2string(100 * (c3 / ref - 1), precision=2)} %")
    for label, h in (("default", H), ("uniform edge / 1.6", H / 1.6)):
        r = compute("orthoglide_foot", ComputeOptions(mesh_size=h))
        e = 100 * (np.diag(r.compliance) / ref - 1)
        print(f"{label} ({h:.3g} mm, {r.solution.n_dofs} DOF) vs reference, % per diagonal entry: "
              f"{np.array2string(e, precision=2)}")


def foot_fillet(r: float = 2.5):
    """The foot with its concave edges rounded (radius ``r``): no singular edge, so the compliance
    converges fast.  gmsh's curvature rule (SEGMENTS_PER_CIRCLE elements per turn) sets the size on
    the fillets, the edge length H elsewhere: the sequence scales both together, (2H, 8), (sqrt2 H,
    8 sqrt2), (H, 16) = the default mesh, and Richardson over it gives the reference.  Then meshes
    that resolve the fillets more coarsely (fewer elements per turn at the default H)."""
    import linkfea.mesh.gmsh as G
    from linkfea.cad import build_link
    from linkfea.fem.convergence import richardson
    from linkfea.mesh import default_mesh_size
    from linkfea.pipeline import compute

    print(f"\n## foot with fillet = {r:g} mm: refinement sequence, Richardson, cheaper meshes")
    params = {"fillet": r}
    H = default_mesh_size(build_link("orthoglide_foot", params=params, with_block=False))
    saved = G.SEGMENTS_PER_CIRCLE
    rows = []

    def run(k, n):
        G.SEGMENTS_PER_CIRCLE = n
        t0 = time.perf_counter()
        res = compute("orthoglide_foot", ComputeOptions(mesh_size=k * H), params=params)
        t = time.perf_counter() - t0
        print(f"edge {k * H:.3g} mm, {n:.3g} per turn: {res.solution.n_dofs} DOF, compute() {t:.1f} s "
              f"({_stages(res.timing)}); diagonal {np.array2string(np.diag(res.compliance), precision=6)}", flush=True)
        return res.solution.n_dofs, np.diag(res.compliance)

    try:
        for k in (2.0, 2 ** 0.5, 1.0):
            rows.append((k, *run(k, saved / k)))
        rich = richardson([k for k, _, _ in rows], [c for _, _, c in rows])
        ref = rich.extrapolated
        print(f"observed orders {np.array2string(rich.order, precision=2)}{'; ' + rich.note if rich.note else ''}")
        print(f"reference: {np.array2string(ref, precision=6)}")
        for k, n_dof, c in rows:
            print(f"  edge {k * H:.3g} mm ({n_dof} DOF) vs reference: {np.array2string(100 * (c / ref - 1), precision=2)} %")
        for n in (4.0, 6.0, 8.0):
            n_dof, c = run(1.0, n)
            print(f"  edge {H:.3g} mm, {n:g} per turn ({n_dof} DOF) vs reference: "
                  f"{np.array2string(100 * (c / ref - 1), precision=2)} %")
    finally:
        G.SEGMENTS_PER_CIRCLE = saved


def tube_block():
    from linkfea.pipeline import compute

    print("\n## tube bar in block mode (cad/bar.py section=tube, gmsh)")
    t0, c0 = time.perf_counter(), time.process_time()
    r = compute("bar", ComputeOptions(mode="block"), params={"section": "tube"})
    t, c = time.perf_counter() - t0, time.process_time() - c0
    print(f"{r.solution.n_dofs} DOF; total {t:.2f} s wall, {c:.2f} s CPU ({', '.join(f'{k} {v:.2f}' for k, v in r.timing.items())}); "
          f"tip area error {r.mesh.quality['tip_area_error']:+.2e}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--skip-pytetwild", action="store_true")
    ap.add_argument("--only", choices=["meshing", "foot", "convergence", "fillet", "tube"], help="run one part")
    args = ap.parse_args(argv)
    import gmsh
    import pytetwild

    from linkfea.solvers.factorizers import _point_pypardiso_at_mkl

    _point_pypardiso_at_mkl()  # the cold CLI child measures pypardiso's import as the CLI does it
    print(f"python {platform.python_version()}, gmsh {gmsh.__version__}, pytetwild "
          f"{getattr(pytetwild, '__version__', '?')}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}")
    from brackets import BASE, TIP, bracket_step

    from linkfea.cad import build_link

    if args.only in (None, "meshing"):
        with tempfile.TemporaryDirectory() as d:
            equal_size("foot", build_link("orthoglide_foot", with_block=False), args.skip_pytetwild)
            equal_size("filleted bracket", build_link(str(bracket_step(d)), base=BASE, tip=TIP, with_block=False),
                       args.skip_pytetwild)
    if args.only in (None, "foot"):
        foot_end_to_end()
    if args.only in (None, "convergence"):
        foot_convergence()
    if args.only in (None, "fillet"):
        foot_fillet()
    if args.only in (None, "tube"):
        tube_block()
    print(f"\nload average at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
