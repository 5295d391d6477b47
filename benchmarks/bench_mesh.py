"""Benchmark of the meshers: gmsh (CAD faces) against pytetwild (fTetWild), side by side in one run.

1. Meshing time at equal size: pytetwild at the default edge length (no cache), then gmsh with its
   edge length set so its tet count matches (a few cheap gmsh runs), on the foot and on the
   filleted bracket of tests/brackets.py.  Interface-area errors of both.
2. The foot's 6x6 end to end (CAD to JSON through the pipeline) at the default gmsh mesh, and its
   distance to a finer reference (edge / 1.6): the largest relative difference on the diagonal.
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


def foot_end_to_end():
    from linkfea.cad import build_link
    from linkfea.mesh import default_mesh_size
    from linkfea.pipeline import compute

    print("\n## foot end to end (rigid, gmsh, default mesh)")
    H = default_mesh_size(build_link("orthoglide_foot", with_block=False))
    t0, c0 = time.perf_counter(), time.process_time()
    r = compute("orthoglide_foot")
    t_api, c_api = time.perf_counter() - t0, time.process_time() - c0
    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "foot.json"
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "linkfea", "compute", "orthoglide_foot", "--no-picture", "-q",
                        "--out", str(out)], check=True, env=dict(os.environ))
        t_cli = time.perf_counter() - t0
    print(f"{r.solution.n_dofs} DOF; pipeline total {r.timing['total']:.2f} s "
          f"({', '.join(f'{k} {v:.2f}' for k, v in r.timing.items() if k != 'total')}); "
          f"compute() call {t_api:.2f} s wall, {c_api:.2f} s CPU; CLI process to JSON (with Python and CadQuery imports) {t_cli:.2f} s")
    ref = compute("orthoglide_foot", mesh_size=H / 1.6)
    d = np.max(np.abs(np.diag(r.matrix) / np.diag(ref.matrix) - 1))
    print(f"reference at edge {H / 1.6:.3g} mm: {ref.solution.n_dofs} DOF; default vs reference, largest "
          f"relative difference on the diagonal: {d:.2e}")


def tube_block():
    from linkfea.pipeline import compute

    print("\n## tube bar in block mode (cad/bar.py section=tube, gmsh)")
    t0, c0 = time.perf_counter(), time.process_time()
    r = compute("bar", params={"section": "tube"}, mode="block")
    t, c = time.perf_counter() - t0, time.process_time() - c0
    print(f"{r.solution.n_dofs} DOF; total {t:.2f} s wall, {c:.2f} s CPU ({', '.join(f'{k} {v:.2f}' for k, v in r.timing.items())}); "
          f"tip area error {r.mesh.quality['tip_area_error']:+.2e}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--skip-pytetwild", action="store_true")
    ap.add_argument("--only", choices=["meshing", "foot", "tube"], help="run one part")
    args = ap.parse_args(argv)
    import gmsh
    import pytetwild

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
    if args.only in (None, "tube"):
        tube_block()
    print(f"\nload average at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
