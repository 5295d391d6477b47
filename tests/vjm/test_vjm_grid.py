"""The model owns its workspace: one grid, one reachability test, one-call maps, and runs planned
before they start (memory refused with the estimate and the limit, long runs announced with progress)."""
import numpy as np
import pytest
from typer.testing import CliRunner

import vjm
from vjm import VjmError
from vjm.cli import app
from vjm.discrepancy.simulate import axes_loads, design_loads, design_poses, grid_poses, random_poses
from vjm.effects import modelops as mo
from vjm.maps import grid
from vjm.maps.compute import compute_map, workspace_grid
from vjm.sweep.combine import workspace_points

PUU = "data/orthoglide/puu.yaml"


@pytest.fixture(scope="module")
def puu():
    return vjm.load_model(PUU)


def test_workspace_is_the_architecture_box_unless_the_geometry_gives_one(puu):
    lo, hi = (np.asarray(v) for v in puu.arch.workspace)
    assert np.array_equal(puu.workspace.lo, lo) and np.array_equal(puu.workspace.hi, hi)
    own = puu.replace(geometry={**puu.geometry, "workspace": [-10.0, 20.0]})
    assert np.array_equal(own.workspace.lo, [-10.0] * 3) and np.array_equal(own.workspace.hi, [20.0] * 3)
    # every user of the box honours it: the grid, the simulated designs and the discrepancy tools
    g = own.grid(4)
    assert g.points.min() == -10.0 and g.points.max() == 20.0
    assert np.array_equal(mo.workspace_box(own)[0], [-10.0] * 3)
    P = design_poses(own, "random:30", np.random.default_rng(1))
    assert P.min() >= -10.0 and P.max() <= 20.0


def test_grid_points_in_meshgrid_order_and_slice(puu):
    g = puu.grid(5, slice="z=0")
    assert g.shape == (5, 5, 1) and g.size == 25 and g.fixed == (2, 0.0)
    X, Y = np.meshgrid(g.axes[0], g.axes[1], indexing="ij")
    assert np.array_equal(g.points[:, 0], X.ravel()) and np.array_equal(g.points[:, 1], Y.ravel())
    assert np.all(g.points[:, 2] == 0.0)


def test_reachable_is_what_the_inverse_kinematics_accepts(puu):
    """Model.reachable against the inverse kinematics itself, point by point, on points across the boundary."""
    P = np.random.default_rng(3).uniform(-400.0, 400.0, (150, 3))
    ok = puu.reachable(P)
    assert 0 < ok.sum() < len(P)
    for p, r in zip(P, ok):
        try:
            puu.inverse_kinematics(p[None])
            ik = True
        except VjmError:
            ik = False
        assert ik == r, p


def test_one_call_map_is_the_three_call_map(puu):
    smap = puu.map(grid=7, slice="z=10")
    axes, G, fixed = workspace_grid(puu, 7, "z=10")
    old = compute_map(puu, G.reshape(-1, 3), axes, fixed)
    assert smap.shape == (7, 7, 1)
    for f in ("points", "K", "k_tran", "k_rot", "reachable"):
        assert np.array_equal(getattr(smap, f), getattr(old, f), equal_nan=True), f
    # each map entry is the single-pose stiffness (an independent call path)
    i = 17
    assert np.isclose(smap.k_tran[i], puu.stiffness(smap.points[i]).k_tran, rtol=1e-12)


def test_library_errors_name_no_command_line_flags(puu):
    for call in (lambda: puu.map(grid=1), lambda: puu.grid(0), lambda: puu.map(grid=5, slice="w=3"),
                 lambda: design_poses(puu, "sphere:3"), lambda: design_loads("axes", 3)):
        with pytest.raises(VjmError) as e:
            call()
        assert "--" not in str(e.value), str(e.value)


@pytest.mark.parametrize("call", [
    lambda m: m.map(grid=100000),
    lambda m: m.map(grid=100000, slice="z=0"),
    lambda m: grid_poses(m, 100000),
    lambda m: workspace_points(m, 100000),
    lambda m: random_poses(m, 10**12, np.random.default_rng(0)),
    lambda m: design_loads("random:1000000:10", 10**6, np.random.default_rng(0)),
])
def test_huge_runs_are_refused_before_any_allocation(puu, call):
    with pytest.raises(VjmError, match=r"would need about .* GB of memory for .*, more than the .* GB"):
        call(puu)


def test_plan_names_estimate_and_limit():
    with pytest.raises(VjmError, match=r"a test run would need about 0.001 GB of memory for 1e\+06 points, "
                                       r"more than the 0.0005 GB"):
        grid.plan("a test run", 10**6, 1.0, limit=5e5)
    p = grid.plan("a test run", 10**6, 1.0, seconds_per_item=1e-3, limit=2e6)
    assert p.memory == 1e6 and p.long and "17 min" in p.describe()


def test_long_runs_announce_their_time_and_report_progress(puu, monkeypatch):
    """With the 'long' threshold at zero, a map says how long it takes and reports each chunk;
    its values are those of the one-block evaluation."""
    lines = []
    monkeypatch.setattr(grid, "LONG_SECONDS", 0.0)
    monkeypatch.setattr(grid, "CHUNK", 10)
    smap = puu.map(grid=6, slice="z=0", progress=lines.append)
    assert lines[0].startswith("the stiffness map (6 per axis, z=0): 36 points, about")  # the estimate, first
    assert lines[1].startswith("36 reachable points: this will take about")  # then the measured time
    assert any("%" in x and "left" in x for x in lines) and lines[-1].startswith("100%")
    monkeypatch.setattr(grid, "LONG_SECONDS", 60.0)
    quiet = []
    again = puu.map(grid=6, slice="z=0", progress=quiet.append)
    assert quiet == [] and np.array_equal(smap.K, again.K)


@pytest.mark.parametrize("args", [
    ["map", PUU, "--grid", "100000"],
    ["map", PUU, "--grid", "100000", "--slice", "z=0"],
    ["simulate", PUU, "--poses", "grid:100000"],
    ["simulate", PUU, "--poses", "random:1000000000000"],
    ["simulate", PUU, "--poses", "grid:3", "--loads", "random:100000000000:10"],
])
def test_cli_refuses_huge_grids_in_one_line(args, tmp_path):
    out = tmp_path / "o"
    r = CliRunner().invoke(app, [*args, "--out", str(out)])
    assert r.exit_code == 2, r.output
    assert r.output.startswith("error: ") and "GB of memory" in r.output and "Traceback" not in r.output
    assert len(r.output.strip().splitlines()) == 1 and not out.exists()


def test_cli_map_reports_progress_of_a_long_run(tmp_path, monkeypatch):
    monkeypatch.setattr(grid, "LONG_SECONDS", 0.0)
    monkeypatch.setattr(grid, "CHUNK", 8)
    r = CliRunner().invoke(app, ["map", PUU, "--grid", "5", "--slice", "z=0", "--out", str(tmp_path / "m")])
    assert r.exit_code == 0, r.output
    assert "this will take about" in r.output and "100%" in r.output


def test_array_forms_of_the_designs_match_the_strings(puu):
    rng = lambda: np.random.default_rng(7)  # noqa: E731
    assert np.array_equal(design_poses(puu, "random:12", rng()), random_poses(puu, 12, rng()))
    G = design_poses(puu, "grid:3")
    assert np.array_equal(G, grid_poses(puu, 3)) and np.array_equal(design_poses(puu, G), G)
    assert np.array_equal(design_loads("axes:100:5000", 4), design_loads(axes_loads(100.0, 5000.0), 4))
    L = design_loads(axes_loads(100.0), 2)
    assert L.shape == (2, 6, 6) and np.array_equal(L[1, 2], [0, 100.0, 0, 0, 0, 0])
    with pytest.raises(VjmError, match="unreachable"):
        design_poses(puu, [[0.0, 0.0, 0.0], [900.0, 0.0, 0.0]])


def test_parallelogram_links_are_named_from_the_architecture():
    """modelops reads the architecture's leg_bars, not a list of architecture names."""
    assert mo.link_label(vjm.load_model("data/orthoglide/prpar.yaml"), "leg") == "bar"
    assert mo.link_label(vjm.load_model(PUU), "leg") == "leg"
    assert mo.link_label(vjm.load_model("data/orthoglide/delta.yaml"), "leg") == "bar"


def test_simulate_reports_progress_and_keeps_its_numbers(puu, monkeypatch):
    from vjm.discrepancy.simulate import simulate

    P0 = design_poses(puu, "grid:3")
    L = design_loads("axes:100", len(P0))
    P, W = np.repeat(P0, L.shape[1], axis=0), L.reshape(-1, 6)
    ref = simulate(puu, [], P, W, 1e-3, None, seed=2)
    lines = []
    monkeypatch.setattr(grid, "LONG_SECONDS", 0.0)
    monkeypatch.setattr(grid, "CHUNK", 4)
    got = simulate(puu, [], P, W, 1e-3, None, seed=2, progress=lines.append)
    assert np.array_equal(got.T, ref.T, equal_nan=True)
    assert "this will take about" in lines[0] and lines[-1].startswith("100%")
