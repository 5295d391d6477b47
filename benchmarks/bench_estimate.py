"""Effectivity and cost of the discretization error estimate (linkfea.fem.estimate); the iterative solver.

Effectivity = estimated / true relative error of each diagonal entry.  True errors come from
references the estimate plays no part in:

* ``bar``: the 200 x 20 x 10 steel bar on structured meshes of 10, 5, 3.33 and 2.5 mm cells
  (tests/meshes.py); the true value is the Richardson limit of the three finest, which is also
  compared with Timoshenko's cantilever and Saint-Venant's torsion.
* ``bracket``: the filleted L-bracket of tests/brackets.py (gmsh) on four meshes, edge length and
  elements per turn of the curvature rule scaled together by sqrt(2) (18k to 187k DOF); the true
  value is the Richardson limit of the three finest, in h = DOF^(-1/3).
* ``foot``: the sharp Orthoglide foot at its default mesh and at uniform 3.5 and 2.9 mm, against
  the 671k-DOF study of docs/benchmarks.md (finest mesh, a lower bound of the converged value,
  plus its own Richardson extrapolation for C22 and C44).

``--only iterative``: the direct and the iterative solver side by side on one link (the 6x6 to
1e-6, time, peak memory of the process).

Usage::

    nice -n 10 .venv/bin/python benchmarks/bench_estimate.py --only bar|bracket|foot|iterative [--mesh-size H]

Heavy parts (bracket, the finest bar): run alone, one at a time.
"""
from __future__ import annotations

import argparse
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

# The foot study of docs/benchmarks.md: default mesh against the 0.70 mm corner mesh (671,121 DOF),
# % per diagonal entry, and the Richardson extrapolation above that mesh (C22 0.42%, C44 0.79%;
# the others have no reliable extrapolation, so their true error is at least the lower bound).
FOOT_LOWER_BOUND = {  # mesh size: (DOF, % below the 671k mesh)
    None: (62_865, [0.87, 2.05, 0.96, 2.80, 0.85, 0.61]),
    3.5: (105_645, [0.69, 1.64, 0.71, 2.24, 0.68, 0.48]),
    2.9: (170_589, [0.43, 0.80, 0.45, 1.00, 0.44, 0.36]),
}
FOOT_BEYOND = [0.0, 0.42, 0.0, 0.79, 0.0, 0.0]


def _row(label, dofs, values, fmt="{:.2f}"):
    print(f"| {label} | {dofs:,} | " + " | ".join(fmt.format(v) for v in values) + " |", flush=True)


def _cost(timing):
    plain = sum(timing[k] for k in ("assemble", "factor", "solve"))
    return timing["estimate"], plain


def bar():
    from meshes import bar_link_mesh

    from linkfea.beam.closed_form import cantilever_compliance, rect_section, rect_torsion_constant
    from linkfea.fem.convergence import richardson
    from linkfea.fem.estimate import estimate_error
    from linkfea.fem.fit import compliance_from_solution
    from linkfea.fem.p2 import lame
    from linkfea.fem.problem import solve_link
    from linkfea.mechanics.materials import get_material

    steel = get_material("steel")
    lam, mu = lame(steel)
    runs = []
    for n in [(20, 4, 2), (40, 8, 4), (60, 12, 6), (80, 16, 8)]:
        mesh = bar_link_mesh(200.0, 20.0, 10.0, *n)
        t0 = time.perf_counter()
        sol = solve_link(mesh, steel)
        C = compliance_from_solution(sol).matrix
        t1 = time.perf_counter()
        est = estimate_error(sol, np.diag(C), lam, mu)
        t2 = time.perf_counter()
        runs.append((mesh.edge_length, sol.n_dofs, np.diag(C), est, t2 - t1, t1 - t0))
        print(f"bar {mesh.edge_length:.3g} mm, {sol.n_dofs} DOF: solve {t1 - t0:.2f} s, estimate {t2 - t1:.2f} s",
              flush=True)
    rich = richardson([r[0] for r in runs[1:]], [r[2] for r in runs[1:]])
    C0 = cantilever_compliance(200.0, rect_section(20.0, 10.0, steel.nu), steel.E, steel.nu, shear=True)
    C0[3, 3] = 200.0 / (steel.G * rect_torsion_constant(20.0, 10.0))
    print("observed orders", np.round(rich.order, 2), "; limit against Timoshenko / Saint-Venant, %",
          np.round(100 * (rich.extrapolated / np.diag(C0) - 1), 2))
    for h, n, d, est, *_ in runs[:3]:
        true = (rich.extrapolated - d) / rich.extrapolated
        _row(f"bar {h:.3g} mm: true %", n, 100 * true, "{:.3f}")
        _row(f"bar {h:.3g} mm: effectivity", n, est.relative / true)


def _bracket_run(step, H, seg):
    import brackets

    import linkfea
    import linkfea.mesh.gmsh as G

    saved = G.SEGMENTS_PER_CIRCLE
    G.SEGMENTS_PER_CIRCLE = seg
    try:
        return linkfea.compute(step, linkfea.ComputeOptions(mesh_size=H, base=brackets.BASE, tip=brackets.TIP), cache_dir=None)
    finally:
        G.SEGMENTS_PER_CIRCLE = saved


def bracket():
    import brackets

    from linkfea.cad import build_link
    from linkfea.fem.convergence import richardson
    from linkfea.mesh import default_mesh_size
    from linkfea.mesh.gmsh import SEGMENTS_PER_CIRCLE

    with tempfile.TemporaryDirectory() as tmp:
        step = brackets.bracket_step(tmp)
        H = default_mesh_size(build_link(step, base=brackets.BASE, tip=brackets.TIP))
        runs = []
        for f in (np.sqrt(2.0), 1.0, 1 / np.sqrt(2.0), 0.5):
            r = _bracket_run(step, H * f, SEGMENTS_PER_CIRCLE / f)
            e, plain = _cost(r.timing)
            print(f"bracket {H * f:.3g} mm, {r.mesh_info.n_dofs} DOF: solve {plain:.2f} s, estimate {e:.2f} s "
                  f"({100 * e / plain:.0f}%)", flush=True)
            runs.append((r.mesh_info.n_dofs, np.diag(r.compliance), r.error_diagonal))
    rich = richardson([n ** (-1 / 3) for n, *_ in runs[1:]], [d for _, d, _ in runs[1:]])
    print("observed orders (in DOF^-1/3)", np.round(rich.order, 2))
    for n, d, est in runs[:3]:
        true = (rich.extrapolated - d) / rich.extrapolated
        _row("bracket: true %", n, 100 * true, "{:.3f}")
        _row("bracket: effectivity", n, est / true)


def foot(mesh_size=None):
    import linkfea

    r = linkfea.compute("orthoglide_foot", linkfea.ComputeOptions(mesh_size=mesh_size))
    dofs, lower = FOOT_LOWER_BOUND[mesh_size]
    if r.mesh_info.n_dofs != dofs:
        print(f"warning: {r.mesh_info.n_dofs} DOF, the study's mesh had {dofs}")
    e, plain = _cost(r.timing)
    print(f"foot {r.mesh_info.edge_length:.3g} mm: solve {plain:.2f} s, estimate {e:.2f} s ({100 * e / plain:.0f}%), "
          f"sharp edges {r.diagnostics.sharp_edges['count']} ({r.timing['edges']:.2f} s)")
    true = np.array(lower) + np.array(FOOT_BEYOND)
    _row("foot: estimate %", dofs, 100 * r.error_diagonal)
    _row("foot: effectivity (at most, against the lower bound)", dofs, 100 * r.error_diagonal / true)


def iterative(mesh_size=None, spec="orthoglide_foot", both=True):
    import linkfea

    out = {}
    for kind in (("direct", "iterative") if both else ("iterative",)):
        t0 = time.perf_counter()
        r = linkfea.compute(spec, linkfea.ComputeOptions(mesh_size=mesh_size, solver=kind))
        wall = time.perf_counter() - t0
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
        out[kind] = r
        conv = r.solver.convergence or {}
        print(f"{kind}: {r.mesh_info.n_dofs:,} DOF, {wall:.1f} s (factor {r.timing['factor']:.1f}, solve "
              f"{r.timing['solve']:.1f}), process peak so far {peak:.2f} GB, CG iterations "
              f"{conv.get('iterations')}", flush=True)
    if both:
        a, b = out["direct"].compliance, out["iterative"].compliance
        d = np.sqrt(np.diag(a))
        print(f"6x6 direct vs iterative: {np.max(np.abs(a - b) / np.outer(d, d)):.2e} (scaled)")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", choices=["bar", "bracket", "foot", "iterative"], required=True)
    ap.add_argument("--mesh-size", type=float, default=None)
    ap.add_argument("--spec", default="orthoglide_foot")
    ap.add_argument("--iterative-only", action="store_true", help="skip the direct solve (a link too large for it)")
    a = ap.parse_args(argv)
    if a.only == "bar":
        bar()
    elif a.only == "bracket":
        bracket()
    elif a.only == "foot":
        foot(a.mesh_size)
    else:
        iterative(a.mesh_size, a.spec, both=not a.iterative_only)


if __name__ == "__main__":
    main()
