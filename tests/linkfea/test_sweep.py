"""Design sweeps on a real Dask LocalCluster (2 worker processes) and the machine trade-offs built on them.

The bar is meshed coarsely (--mesh-size 6): these tests check the sweep's bookkeeping (same numbers as
`linkfea compute`, resume, failures, lost workers, worker count) and `vjm sweep` against `stiffness_map`
run per combination; the FEA itself is validated in test_fem_*.py.
"""
import json
import os

import numpy as np
import pytest
from typer.testing import CliRunner

from linkfea.cli import app as linkfea_app
from linkfea.mechanics.materials import get_material
from linkfea.runtime.errors import LinkFeaError
from linkfea.sweep import C_COLUMNS, make_sweep, parse_param_spec, run_sweep

pytestmark = pytest.mark.slow

MESH = ["--mesh-size", "6"]
GRID = ["--param", "length=100,140", "--param", "width=10:14:4"]
PUU = os.path.join(os.path.dirname(__file__), "..", "..", "data", "orthoglide", "puu.yaml")


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    """A fresh mesh cache shared by the test process and the workers (they inherit the environment)."""
    d = str(tmp_path_factory.mktemp("meshes"))
    old = os.environ.get("LINKFEA_CACHE_DIR")
    os.environ["LINKFEA_CACHE_DIR"] = d
    yield d
    if old is None:
        os.environ.pop("LINKFEA_CACHE_DIR", None)
    else:
        os.environ["LINKFEA_CACHE_DIR"] = old


@pytest.fixture(scope="module")
def client(cache):
    from distributed import Client

    from linkfea.sweep import local_cluster

    cluster = local_cluster(2, memory_limit="2GB")
    c = Client(cluster)
    assert len(c.scheduler_info()["workers"]) == 2
    yield c
    c.close()
    cluster.close()


def _table(out):
    import pyarrow.parquet as pq

    return pq.read_table(os.path.join(out, "sweep.parquet")).to_pylist()


def _C(row):
    return np.array([row[c] for c in C_COLUMNS]).reshape(6, 6)


@pytest.fixture(scope="module")
def grid_run(client, tmp_path_factory):
    """The 2x2 bar sweep through the CLI on the 2-worker cluster."""
    out = str(tmp_path_factory.mktemp("sweep") / "bar")
    r = CliRunner().invoke(linkfea_app, ["sweep", "bar", *GRID, *MESH, "--scheduler", client.scheduler.address,
                                         "--out", out, "-q"])
    assert r.exit_code == 0, r.output
    return out


def test_grid_equals_separate_compute_runs(grid_run, tmp_path):
    rows = _table(grid_run)
    assert [(r["param_length"], r["param_width"]) for r in rows] == [(100, 10), (100, 14), (140, 10), (140, 14)]
    assert {r["status"] for r in rows} == {"ok"} and len({r["worker"] for r in rows}) >= 1
    steel = get_material("steel")
    for row in rows:
        L, w = row["param_length"], row["param_width"]
        out = tmp_path / f"{L:g}_{w:g}.json"
        r = CliRunner().invoke(linkfea_app, ["compute", "bar", "--param", f"length={L:g}", "--param", f"width={w:g}",
                                             *MESH, "--no-picture", "-q", "--out", str(out)])
        assert r.exit_code == 0, r.output
        ref = json.loads(out.read_text())
        C_ref = np.array(ref["compliance"])
        # same pipeline, same (cached) mesh: equal to round-off of the solver, entry by entry on the diagonal scale
        scale = np.sqrt(np.outer(np.diag(C_ref), np.diag(C_ref)))
        assert np.max(np.abs(_C(row) - C_ref) / scale) < 1e-9
        doc = json.loads(open(os.path.join(grid_run, "results", row["key"] + ".json")).read())
        assert doc["schema"] == ref["schema"] and set(ref) <= set(doc)
        np.testing.assert_allclose(doc["compliance"], C_ref, rtol=1e-9, atol=1e-9 * np.max(np.abs(C_ref)))
        np.testing.assert_allclose([row[f"K_{t}"] for t in ("dx", "dy", "dz", "rx", "ry", "rz")],
                                   np.diag(np.linalg.inv(_C(row))), rtol=1e-8)
        # closed form: the bar body is L x w x 10 mm of steel (7850 kg/m^3)
        assert row["volume_mm3"] == pytest.approx(L * w * 10.0, rel=1e-9)
        assert row["mass_kg"] == pytest.approx(7.85e-9 * L * w * 10.0 * 1e3, rel=1e-9) == steel.mass_kg(L * w * 10)
        assert row["n_dofs"] > 0 and row["t_total"] > 0
    # Timoshenko sanity: the tip deflection under Fy scales like L^3 (shear adds a little at L/w = 10)
    by = {(r["param_length"], r["param_width"]): r for r in rows}
    ratio = by[(140, 10)]["C_dy_Fy"] / by[(100, 10)]["C_dy_Fy"]
    assert 0.9 * 1.4 ** 3 < ratio < 1.4 ** 3
    png = open(os.path.join(grid_run, "sweep.png"), "rb").read()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(open(os.path.join(grid_run, "sweep.csv")).read().splitlines()) == 5


def test_rerun_skips_everything_and_recomputes_only_a_deleted_result(grid_run, client):
    sw = make_sweep("bar", GRID[1::2], {"mesh_size": 6.0, "mode": "rigid"})
    before = {r["key"]: _C(r) for r in _table(grid_run)}
    rep = run_sweep(sw, grid_run, client=client)
    assert rep.computed == [] and sorted(rep.skipped) == sorted(before)
    victim = sw.designs[2].key
    mtimes = {k: os.stat(os.path.join(grid_run, "results", k + ".json")).st_mtime_ns for k in before}
    os.unlink(os.path.join(grid_run, "results", victim + ".json"))
    rep = run_sweep(sw, grid_run, client=client)
    assert rep.computed == [victim] and len(rep.skipped) == 3
    for k in before:
        if k != victim:
            assert os.stat(os.path.join(grid_run, "results", k + ".json")).st_mtime_ns == mtimes[k]
    after = {r["key"]: _C(r) for r in _table(grid_run)}
    for k in before:  # the recomputed design reads its mesh from the cache: the same matrix
        np.testing.assert_allclose(after[k], before[k], rtol=1e-9, atol=1e-9 * np.abs(before[k]).max())


def test_rerun_of_a_done_sweep_is_quick_and_starts_no_cluster(grid_run, monkeypatch):
    """All designs done: no Dask cluster or client, the table set left as it is, the same rows."""
    import time

    import distributed

    import linkfea.sweep.cluster

    def refuse(*args, **kwargs):
        raise AssertionError("a cluster was started for a sweep with nothing to do")

    monkeypatch.setattr(linkfea.sweep.cluster, "local_cluster", refuse)
    monkeypatch.setattr(distributed, "Client", refuse)
    sw = make_sweep("bar", GRID[1::2], {"mesh_size": 6.0})
    run_sweep(sw, grid_run)  # the table set of this plot choice, current from here on
    names = ("sweep.parquet", "sweep.csv", "sweep.json", "sweep.png")
    stamps = {n: os.stat(os.path.join(grid_run, n)).st_mtime_ns for n in names}
    before = _table(grid_run)
    t0 = time.perf_counter()
    rep = run_sweep(sw, grid_run, workers=2)
    seconds = time.perf_counter() - t0
    assert seconds < 5.0, seconds  # loose on a shared machine; about 0.1 s idle
    assert rep.computed == [] and rep.failed == [] and len(rep.skipped) == 4 and not rep.unfinished
    assert {n: os.stat(os.path.join(grid_run, n)).st_mtime_ns for n in names} == stamps
    assert [r["key"] for r in rep.rows] == [r["key"] for r in before]
    for r, b in zip(rep.rows, before):
        np.testing.assert_array_equal(_C(r), _C(b))
    # another plot choice is another table set: rebuilt, still without a cluster
    rep = run_sweep(sw, grid_run, plot=["dy_Fy"])
    assert os.stat(os.path.join(grid_run, "sweep.png")).st_mtime_ns != stamps["sweep.png"]
    assert json.load(open(os.path.join(grid_run, "sweep.json")))["plot"] == ["dy_Fy"]


def test_parameter_names_read_without_running_the_script(tmp_path):
    """The names read from the source are those of the imported script; a PARAMS that is not a
    literal is read by running the script."""
    from pathlib import Path

    from linkfea.cad import load_script
    from linkfea.sweep.designs import script_param_names

    cad = Path(__file__).resolve().parents[1] / "cad"
    for script in sorted(cad.glob("*.py")):
        assert script_param_names(script) == set(load_script(script).PARAMS), script.name
    odd = tmp_path / "odd.py"
    odd.write_text("PARAMS = {'a': 1.0}\nPARAMS.update(b=2.0)\n\n\ndef build(**p):\n    return None\n")
    assert script_param_names(odd) is None
    with pytest.raises(LinkFeaError, match="unknown parameter 'c'; known parameters: a, b"):
        make_sweep(odd, ["c=1,2"])


def test_invalid_design_fails_alone(client, tmp_path):
    sw = make_sweep("bar", ["width=12,-3", "length=100"], {"mesh_size": 6.0})
    rep = run_sweep(sw, tmp_path, client=client)
    rows = _table(tmp_path)
    assert [r["status"] for r in rows] == ["ok", "failed"]
    assert "'width' must be > 0" in rows[1]["error"] and "\n" not in rows[1]["error"]
    assert np.isnan(rows[1]["C_dy_Fy"]) and rows[0]["C_dy_Fy"] > 0
    assert rep.failed == [sw.designs[1].key]
    # the failure is recorded: a rerun does not retry it unless asked
    assert run_sweep(sw, tmp_path, client=client).computed == []
    assert run_sweep(sw, tmp_path, client=client, retry_failed=True).failed == [sw.designs[1].key]


def test_local_workers_run_without_the_dashboard_sampler(client):
    """The local cluster's workers received its lean settings (the 10 ms stack sampler off), so
    one worker per core leaves the designs the CPU."""
    import dask

    from linkfea.sweep import LEAN_CLUSTER_CONFIG

    def settings():
        return {k: dask.config.get(k) for k in LEAN_CLUSTER_CONFIG}

    got = client.run(settings)
    assert len(got) == 2 and all(v == LEAN_CLUSTER_CONFIG for v in got.values()), got
    assert dask.config.get("distributed.worker.profile.enabled") is True  # the caller's own config untouched


def test_local_workers_import_the_callers_package_and_leave_its_pythonpath(monkeypatch, tmp_path):
    """A local cluster does not touch the caller's PYTHONPATH, and its workers still import the very
    linkfea the caller imported, even when PYTHONPATH names another package of that name first."""
    from distributed import Client

    import linkfea
    from linkfea.sweep import local_cluster

    decoy = tmp_path / "decoy" / "linkfea"
    decoy.mkdir(parents=True)
    (decoy / "__init__.py").write_text("raise ImportError('the decoy linkfea, not the caller's')\n")
    monkeypatch.setenv("PYTHONPATH", str(decoy.parent))
    cluster = local_cluster(1, memory_limit="1GB")
    try:
        assert os.environ["PYTHONPATH"] == str(decoy.parent)
        with Client(cluster) as c:
            got = c.run(lambda: (__import__("linkfea").__file__, os.environ.get("OMP_NUM_THREADS")))
    finally:
        cluster.close()
    assert list(got.values()) == [(linkfea.__file__, "1")]


def test_lost_workers_keep_finished_results_and_rerun_completes(client, tmp_path):
    sw = make_sweep("bar", ["length=90,110,130,150"], {"mesh_size": 6.0})
    written = {}

    def kill_all_workers(doc):
        if not written:  # after the first result: every worker process is killed and restarted
            written[doc["sweep"]["key"]] = None
            client.restart()

    rep = run_sweep(sw, tmp_path, client=client, on_result=kill_all_workers)
    assert rep.unfinished, "the restart should have cancelled running designs"
    done = rep.computed
    assert done and set(done) | set(rep.unfinished) == {d.key for d in sw.designs}
    files = {k: (tmp_path / "results" / f"{k}.json") for k in done}
    snap = {k: (f.read_bytes(), f.stat().st_mtime_ns) for k, f in files.items()}
    assert [r["status"] for r in _table(tmp_path)].count("not_run") == len(rep.unfinished)
    rep2 = run_sweep(sw, tmp_path, client=client)
    assert sorted(rep2.computed) == sorted(rep.unfinished) and sorted(rep2.skipped) == sorted(done)
    assert {k: (f.read_bytes(), f.stat().st_mtime_ns) for k, f in files.items()} == snap
    assert [r["status"] for r in _table(tmp_path)] == ["ok"] * 4


WRENCH_OF = dict(zip(("dx", "dy", "dz", "rx", "ry", "rz"), ("Fx", "Fy", "Fz", "Mx", "My", "Mz")))
TWIST_OF = {w: t for t, w in WRENCH_OF.items()}


def test_same_table_whatever_the_number_of_workers(grid_run, tmp_path):
    """One in-process worker thread against the 2-process run: same rows in the same order."""
    from distributed import Client, LocalCluster

    sw = make_sweep("bar", GRID[1::2], {"mesh_size": 6.0, "mode": "rigid"})
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0") as lc, \
            Client(lc) as c:
        run_sweep(sw, tmp_path, client=c)
    a, b = _table(grid_run), _table(tmp_path)
    volatile = {c for c in a[0] if c.startswith("t_")} | {"worker"}
    assert [r["key"] for r in a] == [r["key"] for r in b] and list(a[0]) == list(b[0])
    for ra, rb in zip(a, b):
        for c in ra:
            if c in volatile:
                continue
            if c.startswith("C_"):
                # same mesh; the in-process worker's solver may use several threads: round-off only, judged
                # on the entry's scale sqrt(C_ii C_jj) (near-zero couplings carry no relative digits)
                t, w = c[2:].split("_")
                scale = np.sqrt(ra[f"C_{t}_{WRENCH_OF[t]}"] * ra[f"C_{TWIST_OF[w]}_{w}"])
                assert abs(rb[c] - ra[c]) <= 1e-9 * scale, c
            elif c in ("symmetry_error", "fit_residual"):
                # dimensionless round-off measures themselves: equal to round-off, not to relative digits
                assert abs(rb[c] - ra[c]) <= 1e-9, c
            elif isinstance(ra[c], float):
                assert rb[c] == pytest.approx(ra[c], rel=1e-9), c
            else:
                assert ra[c] == rb[c], c


def test_param_specs_and_latin_hypercube():
    assert parse_param_spec("h=10:30:5").grid_values() == (10.0, 15.0, 20.0, 25.0, 30.0)
    assert parse_param_spec("h=0.1:0.3:0.1").grid_values() == (0.1, 0.2, 0.3)
    for bad in ("h", "h=", "h=3:1:1", "h=1:3:0", "h=1:x", "h=1,,2"):
        with pytest.raises(LinkFeaError):
            parse_param_spec(bad)
    with pytest.raises(LinkFeaError, match="needs a step"):
        make_sweep("bar", ["length=100:200"])
    sw = make_sweep("bar", ["length=100:200", "width=8:16"], sample=8, seed=3)
    assert len(sw.designs) == 8 and sw.sampling["method"] == "latin-hypercube"
    # Latin hypercube: each of the 8 equal strata of each range holds exactly one design
    for name, lo, hi in (("length", 100, 200), ("width", 8, 16)):
        x = np.array([d.params[name] for d in sw.designs])
        assert sorted(np.floor((x - lo) / (hi - lo) * 8).astype(int).tolist()) == list(range(8))
    again = make_sweep("bar", ["length=100:200", "width=8:16"], sample=8, seed=3)
    assert [d.key for d in again.designs] == [d.key for d in sw.designs]
    assert make_sweep("bar", ["length=100:200", "width=8:16"], sample=8, seed=4).designs[0].key != sw.designs[0].key
    # the key follows the options and the script's content, not the spelling of the numbers
    k = make_sweep("bar", ["length=100"]).designs[0].key
    assert make_sweep("bar", ["length=100.0"]).designs[0].key == k
    assert make_sweep("bar", ["length=100"], {"mesh_size": 5.0}).designs[0].key != k


def test_cli_sweep_bad_input_one_line(tmp_path):
    out = tmp_path / "o"
    for args, msg in ((["--param", "length=1:2:0"], "step > 0"), (["--param", "nope=1,2"], "unknown parameter 'nope'"),
                      (["--param", "length=100", "--plot", "zz_Fy"], "unknown compliance entries"),
                      (["--param", "length=100", "--workers", "0"], "--workers")):
        r = CliRunner().invoke(linkfea_app, ["sweep", "bar", *args, "--out", str(out), "-q"])
        assert r.exit_code == 2 and r.output.count("\n") == 1 and msg in r.output, r.output
        assert not out.exists()


# --------------------------------------------------------------------------- vjm sweep
def test_vjm_sweep_equals_stiffness_map_per_combination(grid_run, tmp_path):
    import pyarrow.parquet as pq

    import vjm
    from vjm.cli import app as vjm_app
    from vjm.sweep.combine import pareto_mask, workspace_points

    out = tmp_path / "machine"
    r = CliRunner().invoke(vjm_app, ["sweep", PUU, "--foot", grid_run, "--leg", grid_run, "--grid", "5",
                                     "--out", str(out)])
    assert r.exit_code == 0, r.output
    rows = pq.read_table(out / "tradeoffs.parquet").to_pylist()
    assert len(rows) == 16
    keys = [x["key"] for x in _table(grid_run)]
    P = workspace_points(vjm.load_model(PUU), 5)
    for row in rows:
        # independent path: the model file reader with the two result JSONs, then stiffness_map
        m = vjm.load_model(PUU, foot=row["foot_result"], leg=row["leg_result"])
        res = m.stiffness_map(P)
        assert row["k_tran_max"] == pytest.approx(np.max(res.k_tran), rel=1e-12)
        assert row["k_tran_mean"] == pytest.approx(np.mean(res.k_tran), rel=1e-12)
        assert row["k_rot_max"] == pytest.approx(np.max(res.k_rot), rel=1e-12)
        assert row["k_rot_mean"] == pytest.approx(np.mean(res.k_rot), rel=1e-12)
        assert row["foot"] in keys and row["leg"] in keys
        # 3 chains, each one foot and one leg (3-PUU)
        mf, ml = (json.loads(open(row[f"{k}_result"]).read())["mass_kg"] for k in ("foot", "leg"))
        assert row["moving_mass_kg"] == pytest.approx(3 * (mf + ml), rel=1e-12)
    # brute force dominance: a Pareto row is dominated by none, every other row by some row
    mass = np.array([x["moving_mass_kg"] for x in rows])
    kt = np.array([x["k_tran_max"] for x in rows])
    dominated = [bool(np.any((mass <= mass[i]) & (kt <= kt[i]) & ((mass < mass[i]) | (kt < kt[i]))))
                 for i in range(len(rows))]
    assert [x["pareto"] for x in rows] == [not d for d in dominated]
    assert any(x["pareto"] for x in rows)
    assert len(open(out / "pareto.csv").read().splitlines()) == 1 + sum(x["pareto"] for x in rows)
    assert (out / "pareto.png").read_bytes()[:4] == b"\x89PNG"
    rng = np.random.default_rng(0)
    for _ in range(20):  # the O(n log n) front against brute force on random clouds with ties
        a, b = rng.integers(0, 6, 40).astype(float), rng.integers(0, 6, 40).astype(float)
        brute = [not np.any((a <= a[i]) & (b <= b[i]) & ((a < a[i]) | (b < b[i]))) for i in range(40)]
        assert pareto_mask(a, b).tolist() == brute


def test_vjm_sweep_bad_input(grid_run, tmp_path):
    from vjm.cli import app as vjm_app

    for args, msg in ((["--bar", grid_run], "one-piece leg"), (["--leg", str(tmp_path)], "without sweep.parquet"),
                      (["--leg", grid_run, "--grid", "1"], "--grid")):
        r = CliRunner().invoke(vjm_app, ["sweep", PUU, *args, "--out", str(tmp_path / "o")])
        assert r.exit_code == 2 and msg in r.output, r.output
        assert not (tmp_path / "o").exists()
