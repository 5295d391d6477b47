"""Large links: the direct solver, the earlier iterative path and the P1-multigrid iterative path side by side.

Each solver runs in its own child process (its own peak RSS, VmHWM), one after the other, on the
same mesh: a structured bar (``--case bar``, deterministic, instant to mesh: ``--cells N`` gives
200 x 20 x 10 mm in 6N x 0.6N x 0.3N Kuhn-split cubes) or the sharp Orthoglide foot
(``--case foot --mesh-size H``, meshed once into the mesh cache, which the later children read).
Reported per solver: DOF, wall and CPU seconds (user + system, all threads), mesh / assembly /
factor-or-setup / solve seconds, CG iterations per load case, peak RSS, and the largest
difference of the 6x6 to the first solver's, relative to sqrt(C_ii C_jj).

    nice -n 10 .venv/bin/python benchmarks/bench_large.py --case bar --cells 16 --solvers direct,old,new
    nice -n 10 /usr/bin/time -v .venv/bin/python benchmarks/bench_large.py --case foot --mesh-size 1.4 --solvers new

Solvers: ``direct`` (PARDISO), ``old`` (scipy CG per load case, pyamg smoothed aggregation on the P2
matrix), ``new`` (``--solver iterative``: lockstep CG, P2 / P1 / aggregation V-cycle).
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


def _vm(key: str) -> float:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(key + ":"):
                return float(line.split()[1]) * 1024 / 1e9
    return float("nan")


def _mesh(args, say):
    if args.case == "bar":
        sys.path.append(os.path.join(ROOT, "tests"))
        from meshes import bar_link_mesh

        n = args.cells
        return bar_link_mesh(200.0, 20.0, 10.0, 6 * n, max(1, 6 * n // 10), max(1, 3 * n // 10)), "steel"
    from linkfea.cad import build_link
    from linkfea.mesh import mesh_link
    from linkfea.pipeline import _source_file

    link = build_link(_source_file(args.spec), None)
    return mesh_link(link, args.mesh_size, progress=say), link.material


def child(args) -> None:
    from linkfea.fem.fit import compliance_from_solution
    from linkfea.fem.problem import solve_link
    from linkfea.mechanics.materials import get_material
    from linkfea.solvers.factorizers import default_factorizer
    from linkfea.solvers.iterative import cg_amg_factorizer, cg_p1mg_factorizer

    t_start = time.perf_counter()

    def say(msg):
        print(f"[{time.perf_counter() - t_start:7.1f} s] {args.child}: {msg}", file=sys.stderr, flush=True)

    say("mesh")
    mesh, material = _mesh(args, say)
    t_mesh = time.perf_counter() - t_start
    factorizer = {"direct": default_factorizer, "old": cg_amg_factorizer, "new": cg_p1mg_factorizer}[args.child]
    sol = solve_link(mesh, get_material(material), solver=factorizer, progress=say)
    C = compliance_from_solution(sol).matrix
    ru = resource.getrusage(resource.RUSAGE_SELF)
    conv = sol.solver.convergence or {}
    out = {"solver": args.child, "factorizer": sol.solver.factorizer, "dofs": sol.n_dofs,
           "wall": time.perf_counter() - t_start, "cpu": ru.ru_utime + ru.ru_stime, "mesh": t_mesh,
           **{k: sol.timing.get(k) for k in ("assemble", "factor", "solve")},
           "iterations": conv.get("iterations"), "levels": conv.get("level_sizes", conv.get("levels")),
           "relative_residual": conv.get("relative_residual"), "peak_gb": _vm("VmHWM"), "C": C.tolist()}
    print("RESULT " + json.dumps(out), flush=True)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", choices=["bar", "foot"], default="bar")
    ap.add_argument("--cells", type=int, default=16, help="bar: 6N x 0.6N x 0.3N cubes (16: 98k DOF, 20: 190k)")
    ap.add_argument("--mesh-size", type=float, default=None, help="foot: edge length, mm")
    ap.add_argument("--spec", default="orthoglide_foot")
    ap.add_argument("--solvers", default="direct,old,new")
    ap.add_argument("--child", choices=["direct", "old", "new"], help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        child(args)
        return
    results = []
    for s in args.solvers.split(","):
        cmd = [sys.executable, os.path.abspath(__file__), "--case", args.case, "--cells", str(args.cells),
               "--spec", args.spec, "--child", s] + ([] if args.mesh_size is None else ["--mesh-size", str(args.mesh_size)])
        env = dict(os.environ, PYTHONPATH=os.path.join(ROOT, "src"))
        proc = subprocess.run(cmd, stdout=subprocess.PIPE, text=True, env=env, check=False)
        lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
        if proc.returncode or not lines:
            print(f"{s}: failed (exit {proc.returncode})", flush=True)
            continue
        r = json.loads(lines[-1][7:])
        results.append(r)
        C = np.array(r["C"])
        d = np.sqrt(np.diag(np.array(results[0]["C"])))
        agree = float(np.max(np.abs(C - np.array(results[0]["C"])) / np.outer(d, d)))
        print(f"{s:6s} {r['factorizer']:8s} {r['dofs']:>10,} DOF  wall {r['wall']:7.1f} s  cpu {r['cpu']:7.1f} s  "
              f"mesh {r['mesh']:6.1f}  assemble {r['assemble']:5.1f}  factor/setup {r['factor']:6.1f}  "
              f"solve {r['solve']:7.1f}  peak {r['peak_gb']:5.2f} GB  iterations {r['iterations']}  "
              f"levels {r['levels']}  6x6 vs {results[0]['solver']}: {agree:.1e}", flush=True)


if __name__ == "__main__":
    main()
