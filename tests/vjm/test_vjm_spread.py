"""The machine's error bars from its links' FEA error bars (vjm.sweep.spread).

References that do not come from the spread code: a closed form (a machine whose only spring
is one link: its compliance, hence k_tran and k_rot, scale exactly with the link's), the bar's
ends evaluated as whole models (``spread_method="ends"``) against the linear sensitivity, and
invariants (zero bar -> zero spread, spread linear in the bar).
"""
import json

import numpy as np
import pytest
from typer.testing import CliRunner

import vjm
from linkfea.mechanics.compliance import UNITS
from linkfea.mechanics.frames import Frame
from vjm import LinkSpring
from vjm.cli import app
from vjm.model.machine import Actuator
from vjm.studies.table1 import report_lines, table1_rows

#: the foot's estimated relative errors at the default mesh (out/foot/result.json of `make demo`)
FOOT_BAR = np.array([0.018, 0.040, 0.017, 0.058, 0.020, 0.016])
LEG_BAR = np.array([0.03, 0.025, 0.03, 0.045, 0.02, 0.035])
POSES = np.array([[0.0, 0.0, 0.0], [50.0, 40.0, 30.0], [-60.0, 20.0, -40.0], [80.0, -70.0, 10.0],
                  [-30.0, -90.0, 60.0], [20.0, 100.0, -80.0]])


@pytest.fixture(scope="module")
def beams():
    return vjm.load_model("puu")


def with_bars(m, foot=FOOT_BAR, leg=LEG_BAR):
    return m.replace(foot=LinkSpring(m.foot.value, None, foot), leg=LinkSpring(m.leg.value, None, leg))


@pytest.fixture(scope="module")
def lin_ends(beams):
    m = with_bars(beams)
    return m.stiffness_map(POSES, spread=True), m.stiffness_map(POSES, spread=True, spread_method="ends")


def test_linear_sensitivity_agrees_with_the_bar_ends(lin_ends):
    """Linear spread vs half the range over the bars' ends: equal to the linearisation's error,
    O(e^2) relative (e = the largest bar, 5.8%), and each link's part too; and not zero."""
    lin, ends = lin_ends
    e = FOOT_BAR.max()
    for a, b in ((lin.k_tran_spread, ends.k_tran_spread), (lin.k_rot_spread, ends.k_rot_spread)):
        assert np.all(a > 0)
        assert np.max(np.abs(a - b) / b) < e**2
    for name in ("foot", "leg"):
        for a, b in zip(lin.spread_by_link[name], ends.spread_by_link[name]):
            assert np.max(np.abs(a - b) / b) < e**2
    # the spread is the links' parts added
    assert np.allclose(lin.k_tran_spread, sum(t for t, _ in lin.spread_by_link.values()), rtol=1e-14)
    # and a bar of a few percent gives a spread of that order
    assert np.all(lin.k_tran_spread / lin.k_tran < FOOT_BAR.max() + LEG_BAR.max())


def test_zero_bar_and_no_estimate_give_zero_spread(beams):
    """Beam links carry no estimate: spread zero, no link named; a link with a zero bar: zero."""
    r = beams.stiffness_map(POSES, spread=True)
    assert np.all(r.k_tran_spread == 0) and np.all(r.k_rot_spread == 0) and r.spread_by_link == {}
    r = with_bars(beams, foot=np.zeros(6), leg=np.zeros(6)).stiffness_map(POSES, spread=True)
    assert np.all(r.k_tran_spread == 0) and np.all(r.k_rot_spread == 0)
    # one link with a bar, the other with none: only the first contributes
    one = beams.replace(foot=LinkSpring(beams.foot.value, None, FOOT_BAR))
    r1 = one.stiffness_map(POSES, spread=True)
    assert set(r1.spread_by_link) == {"foot"} and np.all(r1.k_tran_spread > 0)


def test_spread_scales_linearly_with_the_bar(beams, lin_ends):
    lin, _ = lin_ends
    half = with_bars(beams, FOOT_BAR / 2, LEG_BAR / 2).stiffness_map(POSES, spread=True)
    assert np.allclose(half.k_tran_spread, lin.k_tran_spread / 2, rtol=1e-3, atol=0)
    assert np.allclose(half.k_rot_spread, lin.k_rot_spread / 2, rtol=1e-3, atol=0)


@pytest.mark.parametrize("method", ["linear", "ends"])
def test_closed_form_one_link_in_series_with_rigid_parts(beams, method):
    """Rigid foot, a practically rigid actuator (1e12 N/mm), ideal joints: the leg is the only spring,
    so with a uniform bar e the machine compliance is exactly (1 + t e) times the nominal one, and
    k_tran +- e k_tran, k_rot +- e k_rot."""
    e = 0.02
    m = beams.replace(foot=LinkSpring.rigid(), leg=LinkSpring(beams.leg.value, None, np.full(6, e)),
                      actuator=Actuator(1e12))
    r = m.stiffness_map(POSES, spread=True, spread_method=method)
    assert np.allclose(r.k_tran_spread, e * r.k_tran, rtol=2e-6, atol=0)
    assert np.allclose(r.k_rot_spread, e * r.k_rot, rtol=2e-6, atol=0)


def test_bar_read_from_a_result_json_reaches_map_table_and_json(beams, tmp_path):
    """A result JSON's discretization_error.diagonal becomes the link's bar (model file route); the
    map's .npz, the JSON of a pose and Table 1's text carry the spread."""
    doc = {"schema": "linkfea.result/1", "compliance": np.asarray(beams.foot.compliance).tolist(),
           "frame": Frame(np.zeros(3), np.eye(3)).to_dict(), "units": UNITS,
           "diagnostics": {"discretization_error": {"diagonal": FOOT_BAR.tolist()}}}
    path = tmp_path / "foot.json"
    path.write_text(json.dumps(doc))
    m = vjm.load_model("puu", foot=path)
    assert np.array_equal(m.foot.error, FOOT_BAR) and m.leg.error is None

    smap = m.map(grid=4, slice="z=0", spread=True)
    smap.save(tmp_path / "map")
    z = np.load(tmp_path / "map" / "map.npz")
    ok = z["reachable"]
    ref = m.stiffness_map(z["points"][ok], spread=True)
    assert np.allclose(z["k_tran_spread"][ok], ref.k_tran_spread, rtol=1e-12)
    assert np.allclose(z["k_rot_spread"][ok], ref.k_rot_spread, rtol=1e-12)
    assert "mm/N" in str(z["spread_note"])
    assert json.loads(json.dumps(m.stiffness([0, 0, 0], spread=True).to_dict()))["k_tran_spread_mm_per_N"] > 0

    prpar = vjm.load_model("prpar", foot=path)
    rows = table1_rows([m, prpar])
    lines = report_lines(rows, [m, prpar])
    q0 = next(ln.split() for ln in lines if ln.startswith("orthoglide-3PUU") and " Q0 " in ln)
    val, spr = q0[2].split("+-")
    assert float(val) == pytest.approx(rows[0]["k_tran"] * 1e4, rel=5e-3)
    assert float(spr) == pytest.approx(rows[0]["k_tran_spread"] * 1e4, rel=5e-2)
    assert rows[0]["k_tran_spread"] > 0 and rows[3]["k_tran_spread"] > 0  # the 3-PRPaR shares the foot

    # the command line: `vjm map --spread` saves the spread, `vjm table1 --foot` prints it
    runner = CliRunner()
    r = runner.invoke(app, ["map", "puu", "--grid", "3", "--slice", "z=0", "--spread", "--foot", str(path),
                            "--out", str(tmp_path / "cli")])
    assert r.exit_code == 0, r.output
    z = np.load(tmp_path / "cli" / "map.npz")
    assert np.all(z["k_tran_spread"][z["reachable"]] > 0)
    r = runner.invoke(app, ["table1", "puu", "prpar", "--foot", str(path)])
    assert r.exit_code == 0 and r.output.count("+-") >= 12, r.output
