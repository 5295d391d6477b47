"""Numeric arguments of the Python API: type, finiteness and range, named by their Python name (the CLI
names the flag: see tests/bad_inputs.py); plausibility of a data set against its model (units, workspace)."""
import json
import time

import numpy as np
import pytest
from bad_inputs import DEGREES, GOOD, MICRONS, PLACES

import vjm
from linkfea.runtime import checks
from linkfea.runtime.errors import LinkFeaError
from vjm.discrepancy.data import Deflections, StiffnessObs, read_csv
from vjm.errors import VjmError

PUU = vjm.load_model(PLACES["puu"])


def test_bounds_and_types():
    b = checks.Bounds(0, 1, lo_open=True, hi_open=True)
    assert str(b) == "in (0, 1)" and str(checks.Bounds(2)) == ">= 2" and str(checks.Bounds(0, lo_open=True,
                                                                                          unit="mm")) == "> 0 mm"
    assert checks.number(np.float64(0.5), "alpha", b) == 0.5 and checks.integer(np.int64(3), "grid") == 3
    for bad in ("0.5", True, None, [0.5], float("inf")):
        with pytest.raises(checks.ArgumentError, match=r"^alpha must be a (finite )?number in \(0, 1\)"):
            checks.number(bad, "alpha", b)
    for bad in (2.5, 3.0, "3", False):
        with pytest.raises(checks.ArgumentError, match=r"^grid must be a whole number >= 2"):
            checks.integer(bad, "grid", checks.Bounds(2))
    e = checks.ArgumentError("noise_t", "must be >= 0 mm, got -1")
    assert checks.cli_message(e) == "--noise-t must be >= 0 mm, got -1"
    assert checks.cli_message(checks.ArgumentError("epsilon", "must be ..."), {"epsilon": "--envelope"}) == \
        "--envelope must be ..."
    assert checks.cli_message(LinkFeaError("a\nb")) == "a b"


@pytest.mark.parametrize("bounds", [checks.Bounds(), checks.Bounds(0), checks.Bounds(hi=1.0), checks.POSITIVE,
                                    checks.Bounds(0, 1, lo_open=True, hi_open=True), checks.Bounds(0, 1)])
def test_no_bounds_contain_nan(bounds):
    """Every comparison with NaN is false: a range test written as "below lo or above hi" lets it through."""
    assert not bounds.contains(float("nan")) and not bounds.contains(np.float64("nan"))
    assert bounds.contains(0.5)


@pytest.mark.parametrize("call, message", [
    (lambda: vjm.discrepancy.workflow.diagnose(PUU, None, alpha=0.0), r"^alpha must be in \(0, 1\), got 0$"),
    (lambda: vjm.discrepancy.workflow.diagnose(PUU, None, alpha=float("nan")), r"^alpha must be a finite number"),
    (lambda: vjm.discrepancy.workflow.diagnose(PUU, None, alpha="0.05"), r"^alpha must be a number in \(0, 1\)"),
    (lambda: vjm.discrepancy.workflow.diagnose(PUU, None, folds=1), r"^folds must be a whole number in \[2, 50\], got 1$"),
    (lambda: vjm.discrepancy.workflow.diagnose(PUU, None, suggest=2.5), r"^suggest must be a whole number >= 0"),
    (lambda: vjm.discrepancy.simulate.simulate(PUU, [], np.zeros((1, 3)), np.eye(6)[:1], -1.0, None, 0),
     r"^noise_t must be >= 0 mm, got -1$"),
    (lambda: vjm.discrepancy.simulate.simulate(PUU, [], np.zeros((1, 3)), np.eye(6)[:1], 1e-3, float("nan"), 0),
     r"^noise_r must be a finite number >= 0 rad"),
    (lambda: vjm.maps.compute.workspace_grid(PUU, 1), r"^grid must be a whole number >= 2, got 1$"),
    (lambda: vjm.maps.compute.workspace_grid(PUU, 2.5), r"^grid must be a whole number >= 2, got 2.5$"),
    (lambda: vjm.maps.grid.parse_slice("z=inf"), r"^slice expects axis=value"),
])
def test_vjm_api_names_the_argument(call, message):
    import vjm.discrepancy.simulate
    import vjm.discrepancy.workflow
    import vjm.maps.compute  # noqa: F401

    with pytest.raises(VjmError, match=message) as info:
        call()
    assert "--" not in str(info.value)


@pytest.mark.parametrize("kw, message", [
    ({"mesh_size": -1.0}, r"^mesh_size must be > 0 mm, got -1$"),
    ({"mesh_size": float("nan")}, r"^mesh_size must be a finite number > 0 mm"),
    ({"block_ratio": 1.0, "mode": "block"}, r"^block_ratio must be > 1, got 1$"),
    ({"envelope": 0.5}, r"^envelope must be in \(0, 0.1\), got 0.5$"),
    ({"tolerance": float("nan")}, r"^tolerance must be a finite number in \(0, 1\)"),
    ({"tolerance": 2.0}, r"^tolerance must be in \(0, 1\) \(a fraction: 0.01 = 1%\), got 2$"),
])
def test_linkfea_api_names_the_argument_before_any_work(kw, message):
    import linkfea

    t0 = time.perf_counter()
    with pytest.raises(LinkFeaError, match=message):
        linkfea.compute("bar", linkfea.ComputeOptions(**kw))
    assert time.perf_counter() - t0 < 5.0  # refused before the CAD is built


def test_sweep_api_names_the_argument():
    from linkfea.sweep import make_sweep

    with pytest.raises(LinkFeaError, match=r"^sample must be a whole number >= 1, got 0$"):
        make_sweep("bar", ["length=100:120"], sample=0)
    with pytest.raises(LinkFeaError, match=r"^seed must be a whole number >= 0, got -3$"):
        make_sweep("bar", ["length=100:120"], sample=2, seed=-3)
    with pytest.raises(LinkFeaError, match=r"^mesh_size must be > 0 mm, got 0$"):
        make_sweep("bar", ["length=100,120"], {"mesh_size": 0.0})


def test_result_json_schema_and_stiffness_checked(tmp_path):
    from linkfea.result.schema import read_result

    C = np.diag([1e-4, 1e-4, 2e-4, 1e-7, 1e-7, 2e-7])
    doc = {"schema": "linkfea.result/1", "compliance": C.tolist(), "stiffness": np.linalg.inv(C).tolist(),
           "frame": {"origin": [0, 0, 0], "x_axis": [1, 0, 0], "y_axis": [0, 1, 0], "z_axis": [0, 0, 1]},
           "units": {}}
    p = tmp_path / "r.json"
    p.write_text(json.dumps(doc))
    np.testing.assert_array_equal(read_result(p)["compliance"], C)
    p.write_text(json.dumps(dict(doc, stiffness=(1.01 * np.linalg.inv(C)).tolist())))
    with pytest.raises(LinkFeaError, match=r"stiffness contradicts the compliance: \|C K - I\| = 0.01"):
        read_result(p)
    p.write_text(json.dumps({k: v for k, v in doc.items() if k != "schema"}))
    with pytest.raises(LinkFeaError, match="missing schema"):
        read_result(p)


def test_units_far_beyond_any_effect_refused(tmp_path):
    """Translations in µm, rotations in degrees, compliances in µm/N: one hint about units; the data in mm
    and rad pass."""
    from vjm.discrepancy.plausible import check_units
    from vjm.effects.context import unique_postures

    for text, fragment in ((MICRONS, r"translations are 1e\+03 x"), (DEGREES, "rotations are 57.3 x"),
                           (GOOD, None)):
        (tmp_path / "m.csv").write_text(text)
        d = read_csv(tmp_path / "m.csv")
        U, idx = unique_postures(d.P)
        if fragment is None:
            check_units(PUU, d, U, idx)
            continue
        with pytest.raises(VjmError, match=fragment + r".*check the units \((mm|rad) for"):
            check_units(PUU, d, U, idx)
    k = PUU.stiffness([0.0, 0.0, 0.0])
    obs = StiffnessObs(np.zeros((2, 3)), np.array([0, 1]), np.array([k.k_tran, k.k_rot]) * 1e3)
    U, idx = unique_postures(obs.P)
    with pytest.raises(VjmError, match=r"observed compliances are 1e\+03 x the model's.*k_tran in mm/N"):
        check_units(PUU, obs, U, idx)
    check_units(PUU, StiffnessObs(obs.P, obs.quantity, obs.value / 1e3 * 1.3), U, idx)


def test_reachable_posture_outside_the_workspace_box_is_a_warning():
    from vjm.discrepancy.plausible import workspace_flags
    from vjm.effects import modelops as mo

    lo, hi = mo.workspace_box(PUU)
    P = np.array([[0.0, 0.0, 0.0], [lo[0] - 10.0, 0.0, 0.0]])
    mo.actuator_coords(PUU, P)  # reachable (raises otherwise)
    d = Deflections(P, np.eye(6)[:2] * 100, np.full((2, 6), 1e-3), rows=np.array([2, 3]), source="m.csv")
    (flag,) = workspace_flags(PUU, d)
    assert flag.startswith(f"m.csv: row 3: posture ({lo[0] - 10:g}, 0, 0) mm is outside the model's workspace box")
    assert workspace_flags(PUU, Deflections(P[:1], d.W[:1], d.T[:1])) == []


def test_diagnosis_warns_of_a_posture_outside_the_workspace_box(tmp_path):
    """End to end: the warning is in the report's flags and in the printed summary."""
    from vjm.discrepancy.workflow import diagnose
    from vjm.effects import modelops as mo

    lo, _ = mo.workspace_box(PUU)
    rng = np.random.default_rng(7)
    P = np.repeat(np.array([[0.0, 0.0, 0.0], [20.0, -10.0, 5.0], [lo[0] - 10.0, 0.0, 0.0]]), 3, axis=0)
    W = np.tile(100.0 * np.eye(6)[:3], (3, 1))
    T = np.full((len(P), 6), np.nan)
    T[:, :3] = np.einsum("nij,nj->ni", mo.compliance_map(PUU, P)[:, :3], W) + 1e-4 * rng.standard_normal((9, 3))
    d = Deflections(P, W, T, np.full(9, 1e-4), None, np.arange(2, 11), "m.csv")
    rep = diagnose(PUU, d).report
    assert any("row 8 and 2 more: posture" in f and "outside the model's workspace box" in f for f in rep["flags"])
    assert "outside the model's workspace box" in rep["summary"]
