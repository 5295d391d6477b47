"""The lightest Orthoglide 3-PUU with k_tran_max <= 0.015 mm/N: `vjm design` against the grid, side by side.

Usage: ``python benchmarks/design_orthoglide.py [ROOT]`` (default: a temporary folder).

Targets (data/design/orthoglide_light.yaml): the optimizer's verified design is no heavier than the
grid's best feasible combination, with at most 33 FEA runs (a third of the grid's 100), in at most
10 min on 2 cores.

1. The grid: `linkfea sweep orthoglide_foot` over arm_width 24:56:8, arm_height 20:44:6, wall 3:9:3
   (5 x 5 x 3 = 75 designs) and `linkfea sweep parallelogram_bar` with boss_height 20 over width
   8:24:4, height 8:20:3 (5 x 5 = 25), the defaults of `linkfea compute`; then every combination on
   the 11 x 11 x 11 workspace grid as `vjm sweep` reports it, and the lightest with k_tran_max <= 0.015.
2. `vjm design data/design/orthoglide_light.yaml` (its own output folder and mesh cache: no design of
   the grid is reused).

Both run in this one invocation on 2 local workers; the table printed is the one docs/design.md quotes.
"""
import json
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT_DIR = Path(__file__).resolve().parents[1]
SPEC = ROOT_DIR / "data" / "design" / "orthoglide_light.yaml"
LIMIT = 0.015


def grid(root: Path) -> dict:
    from distributed import Client

    from linkfea.sweep import local_cluster, make_sweep, run_sweep
    from vjm.modelio.read import load_model
    from vjm.sweep.combine import load_designs, trade_offs

    os.environ["LINKFEA_CACHE_DIR"] = str(root / "cache_grid")
    t0 = time.perf_counter()
    cluster = local_cluster(2, memory_limit="auto")
    client = Client(cluster)
    try:
        foot = make_sweep("orthoglide_foot", ["arm_width=24:56:8", "arm_height=20:44:6", "wall=3:9:3"])
        leg = make_sweep("parallelogram_bar", ["boss_height=20", "width=8:24:4", "height=8:20:3"])
        r1 = run_sweep(foot, root / "grid_foot", client=client)
        r2 = run_sweep(leg, root / "grid_leg", client=client)
    finally:
        client.close()
        cluster.close()
    runs = len(r1.computed) + len(r2.computed)
    model = load_model(str(ROOT_DIR / "data" / "orthoglide" / "puu.yaml"))
    res = trade_offs(model, {"foot": load_designs(root / "grid_foot", "foot"),
                             "leg": load_designs(root / "grid_leg", "leg")}, 11)
    seconds = time.perf_counter() - t0
    ok = [r for r in res.rows if r["k_tran_max"] <= LIMIT]
    best = min(ok, key=lambda r: r["moving_mass_kg"])
    return {"runs": runs, "seconds": seconds, "mass": best["moving_mass_kg"], "k_tran_max": best["k_tran_max"],
            "combinations": len(res.rows),
            "parameters": {k: v for k, v in best.items() if k.startswith(("foot_", "leg_")) and "result" not in k}}


def optimizer(root: Path) -> dict:
    import vjm

    os.environ["LINKFEA_CACHE_DIR"] = str(root / "cache_design")
    t0 = time.perf_counter()
    res = vjm.design(SPEC, root / "design", workers=2, progress=lambda line: print(line, file=sys.stderr))
    seconds = time.perf_counter() - t0
    return {"runs": res.fea_runs, "computed": res.fea_computed, "seconds": seconds, "mass": res.moving_mass_kg,
            "k_tran_max": res.k_tran_max, "error_bar": res.constraints[0].error_bar, "parameters": res.parameters,
            "stop": res.stop, "feasible": res.feasible}


def main() -> None:
    root = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="design-bench-"))
    g = grid(root)
    o = optimizer(root)
    print(json.dumps({"grid": g, "design": o}, indent=1, default=str))
    print("\n| | FEA runs | time | moving mass | k_tran_max by FEA |\n|---|---|---|---|---|")
    print(f"| grid (5x5x3 foot, 5x5 leg) | {g['runs']} | {g['seconds'] / 60:.1f} min | {g['mass']:.4f} kg "
          f"| {g['k_tran_max']:.5f} mm/N |")
    print(f"| vjm design | {o['runs']} | {o['seconds'] / 60:.1f} min | {o['mass']:.4f} kg "
          f"| {o['k_tran_max']:.5f} mm/N (+{o['error_bar']:.5f}) |")
    ok = o["feasible"] and o["mass"] <= g["mass"] and o["runs"] <= 33 and o["seconds"] <= 600
    print(f"\ntargets (no heavier than the grid, <= 33 runs, <= 10 min): {'met' if ok else 'NOT met'}")


if __name__ == "__main__":
    main()
