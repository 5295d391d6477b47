"""Throughput of `linkfea sweep` with 1 and 2 local worker processes, scheduler overhead per task,
and a projection to 100 workers on a 500-design sweep.

Usage: ``python benchmarks/bench_sweep.py [N_DESIGNS] [MESH_SIZE]`` (default 16 bar designs at 3 mm: with
2 workers the last round leaves one worker idle, so fewer designs measure that tail more than the
steady rate).

* Each configuration gets a fresh mesh cache and output folder, so every design runs the whole
  pipeline (CAD, meshing, FEA, fit) as in a first sweep.  The workers are started and warmed
  (imports) before the clock starts: throughput = designs / (first submit .. last result written).
* Both configurations run in the same invocation, one after the other (quote the ratio from one run).
* Scheduler overhead: wall time per trivial task for 2,000 tasks on the 2-worker cluster, and the
  gap between the sweep's wall time and the designs' own compute time.
* Projection: greedy list scheduling of 500 designs on 100 workers with design times drawn from
  the measured ones, plus the measured per-task overhead; the assumptions are printed.
"""
import os
import platform
import shutil
import sys
import tempfile
import time

import numpy as np


def load() -> str:
    return " ".join(f"{x:.1f}" for x in os.getloadavg())


def run(n_workers: int, n_designs: int, mesh_size: float, root: str) -> dict:
    from distributed import Client

    from linkfea.sweep import local_cluster, make_sweep, run_sweep

    cache = os.path.join(root, f"cache{n_workers}")
    out = os.path.join(root, f"out{n_workers}")
    os.environ["LINKFEA_CACHE_DIR"] = cache
    t0 = time.perf_counter()
    cluster = local_cluster(n_workers, memory_limit="auto")
    client = Client(cluster)
    client.run(lambda: __import__("linkfea.pipeline") and __import__("cadquery") and __import__("pypardiso"))
    t_start = time.perf_counter() - t0
    lengths = np.linspace(100.0, 200.0, n_designs)
    sw = make_sweep("bar", ["length=" + ",".join(f"{v:.4g}" for v in lengths)], {"mesh_size": mesh_size})
    load_before = load()
    t0 = time.perf_counter()
    rep = run_sweep(sw, out, client=client)
    wall = time.perf_counter() - t0
    assert len(rep.computed) == n_designs, rep
    task_s = np.array([r["t_total"] for r in rep.rows])
    # scheduler overhead: trivial tasks
    n_triv = 2000
    t0 = time.perf_counter()
    futs = client.map(lambda x: x, range(n_triv), pure=False)
    client.gather(futs)
    per_task = (time.perf_counter() - t0) / n_triv
    client.close()
    cluster.close()
    rows = rep.rows
    return {"workers": n_workers, "wall": wall, "startup": t_start, "rate": 60.0 * n_designs / wall,
            "task_s": task_s, "per_trivial_task": per_task, "load": f"{load_before} -> {load()}",
            "gap_per_design": (wall * n_workers - task_s.sum()) / n_designs, "rows": rows,
            "dofs": int(rows[0]["n_dofs"])}


def project(task_s: np.ndarray, per_task: float, n_designs=500, n_workers=100, startup=30.0, seed=0) -> dict:
    """Greedy list scheduling of n_designs tasks (times resampled from task_s) on n_workers."""
    rng = np.random.default_rng(seed)
    spans = []
    for _ in range(200):
        t = rng.choice(task_s, n_designs) + per_task
        free = np.zeros(n_workers)
        for x in t:
            k = np.argmin(free)
            free[k] += x
        spans.append(free.max())
    return {"makespan": float(np.median(spans)) + startup, "ideal": float(task_s.mean() * n_designs / n_workers),
            "startup": startup}


def main():
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 16
    h = float(sys.argv[2]) if len(sys.argv) > 2 else 3.0
    root = tempfile.mkdtemp(prefix="bench_sweep_")
    try:
        print(f"{platform.node()}: {os.cpu_count()} cores, Python {platform.python_version()}; "
              f"{n} bar designs (length 100..200 mm), mesh size {h} mm")
        res = [run(1, n, h, root), run(2, n, h, root)]
        for r in res:
            print(f"{r['workers']} worker(s): {r['wall']:.1f} s for {n} designs = {r['rate']:.2f} designs/min "
                  f"(cluster start + warm-up {r['startup']:.1f} s, not counted); design compute time "
                  f"{r['task_s'].mean():.2f} s mean ({r['task_s'].min():.2f}..{r['task_s'].max():.2f}), "
                  f"{r['dofs']} DOF for the first; wall x workers - compute = {r['gap_per_design']:.2f} s/design; "
                  f"trivial task {1e3 * r['per_trivial_task']:.2f} ms; load average {r['load']}")
        a, b = res
        print(f"2-worker / 1-worker throughput: {b['rate'] / a['rate']:.2f}x (target >= 1.7x)")
        same = all(np.allclose([x[c] for c in x if c.startswith("C_")], [y[c] for c in y if c.startswith("C_")],
                               rtol=0.05) for x, y in zip(a["rows"], b["rows"]))
        print(f"tables of the two runs agree to 5% (independent meshes): {same}")
        task_s = np.concatenate([a["task_s"]])  # single-worker times: least contention
        p = project(task_s, a["per_trivial_task"])
        print(f"projection, 500 designs on 100 workers (one core each, times as the 1-worker run here, "
              f"{1e3 * a['per_trivial_task']:.1f} ms scheduler cost per task, {p['startup']:.0f} s cluster start): "
              f"{p['makespan']:.0f} s ({p['makespan'] / 60:.1f} min); perfect division {p['ideal']:.0f} s; "
              f"one worker {task_s.mean() * 500 / 60:.0f} min")
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
