"""A rerun of a finished `linkfea sweep`: wall time against the first run, side by side in one invocation.

Usage: ``python benchmarks/bench_sweep_rerun.py [N_DESIGNS] [MESH_SIZE]`` (default 4 bar designs at 6 mm,
2 local workers).

* First run: ``linkfea sweep bar`` in a fresh output folder and mesh cache (a subprocess, as a user runs it:
  interpreter start, imports, the local Dask cluster, the designs, the table set).
* Rerun: the same command again; every design is done, so no cluster starts and the table set is current.
* In-process rerun: :func:`linkfea.sweep.run_sweep` on the same folder (no interpreter start or imports).
"""
import os
import subprocess
import sys
import tempfile
import time


def main(n_designs: int = 4, mesh_size: float = 6.0) -> None:
    import numpy as np

    from linkfea.sweep import make_sweep, run_sweep

    root = tempfile.mkdtemp(prefix="bench-rerun-")
    out = os.path.join(root, "out")
    env = {**os.environ, "LINKFEA_CACHE_DIR": os.path.join(root, "cache")}
    lengths = ",".join(f"{v:.4g}" for v in np.linspace(100.0, 200.0, n_designs))
    cmd = [sys.executable, "-m", "linkfea", "sweep", "bar", "--param", f"length={lengths}",
           "--mesh-size", str(mesh_size), "--workers", "2", "--out", out, "-q"]
    times = []
    for _ in range(3):
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, env=env)
        times.append(time.perf_counter() - t0)
    sw = make_sweep("bar", [f"length={lengths}"], {"mesh_size": mesh_size})
    t0 = time.perf_counter()
    rep = run_sweep(sw, out)
    t_api = time.perf_counter() - t0
    assert not rep.computed and len(rep.skipped) == n_designs
    print(f"{n_designs} bar designs at {mesh_size} mm, 2 workers, load {os.getloadavg()[0]:.1f}")
    print(f"first run (CLI)      {times[0]:7.2f} s")
    print(f"rerun (CLI)          {times[1]:7.2f} s, {times[2]:.2f} s  ({times[1] / times[0]:.3f} of the first run)")
    print(f"rerun (run_sweep)    {t_api:7.3f} s")


if __name__ == "__main__":
    args = sys.argv[1:]
    main(int(args[0]) if args else 4, float(args[1]) if len(args) > 1 else 6.0)
