"""Few postures, designs too weak to name an effect, and data at two load levels (tests/truth.py)."""
import csv

import numpy as np
import pytest
import truth as tr
from typer.testing import CliRunner

import vjm
from vjm.cli import app

NOMINAL = tr.NOMINAL
ALPHA = 0.01


def _diagnose(tmp, model, data, *extra):
    """report.json of `vjm diagnose` on a model mapping and tr.Measurements, and the exit code."""
    tmp.mkdir(parents=True, exist_ok=True)
    mp = tr.write_model(model, tmp / "model.yaml")
    dp = data.write(tmp / "data.csv")
    res = CliRunner().invoke(app, ["diagnose", mp, dp, "--out", str(tmp / "out"), *extra])
    import json
    with open(tmp / "out" / "report.json", encoding="utf-8") as fh:
        return json.load(fh), res


def _describe(rep):
    return f"{rep['verdict']} {rep['named_effects']} {rep['confounded']} {rep['flags']}"


# ------------------------------------------------------------------ few postures, weak designs

def test_six_random_postures_name_the_effect(tmp_path):
    """6 random postures x 12 loads (72 rows): the hidden clearance is named, verdict explained."""
    model, truth = tr.hide("clearance")
    P, W = tr.design(6, 12, seed=31)
    rep, res = _diagnose(tmp_path, model, tr.measure(truth, P, W, seed=32))
    assert res.exit_code == 0, res.output
    assert rep["verdict"] == "explained", _describe(rep)
    assert tr.names_exactly(rep, ["clearance"]), _describe(rep)


def test_weak_designs_are_insufficient_data_not_a_name(tmp_path):
    """A large clearance: on one posture x 6 loads, and on 2 postures x 2 loads (24 values for
    3 parameters), something fits, but the verdict is insufficient_data, with the reason, and
    the exit status says so."""
    model, truth = tr.hide(("clearance", 5e-3))
    P, W = tr.design(1, 6, seed=33)
    rep, res = _diagnose(tmp_path / "one", model, tr.measure(truth, P, W, seed=34))
    assert rep["named_effects"], _describe(rep)  # the selection did choose something ...
    assert rep["verdict"] == "insufficient_data", _describe(rep)  # ... that this design cannot name
    assert res.exit_code == 3, res.output
    assert any("1 posture" in f for f in rep["flags"]), rep["flags"]
    assert rep["summary"].startswith("Verdict: insufficient data"), rep["summary"]
    P, W = tr.design(2, 2, seed=35)
    rep, res = _diagnose(tmp_path / "two", model, tr.measure(truth, P, W, seed=36))
    assert rep["named_effects"] and rep["n_observations"] == 24, _describe(rep)
    assert rep["verdict"] == "insufficient_data", _describe(rep)
    assert res.exit_code == 3, res.output
    assert any("24 measured values for 3 fitted parameters" in f for f in rep["flags"]), rep["flags"]


# ------------------------------------------------------------------ two load levels

@pytest.fixture(scope="module")
def level_rows():
    """12 postures x 6 force directions, each at 50 N and 100 N (144 rows, translations only)."""
    return tr.level_design(12, 6, seed=5, levels=(0.5, 1.0), forces_only=True)


def test_level_design_repeats_each_direction_at_both_magnitudes(level_rows):
    P, W = level_rows
    f = np.linalg.norm(W[:, :3], axis=1)
    np.testing.assert_allclose(sorted(set(np.round(f, 9))), [50.0, 100.0])
    np.testing.assert_allclose(W[6:12], 2.0 * W[:6])  # same posture, same direction, twice the load
    assert np.all(P[:12] == P[0])


def test_softening_truth_is_odd_and_quadratic_in_the_load(level_rows):
    """tests/truth.py's softening actuators: the extra twist is odd in the load and grows as its
    square (x4 at twice the load), and each actuator slips by s tau |tau| (J dp = slip)."""
    P, W = level_rows
    truth = tr.Truth(tr.variant(NOMINAL), softening=3e-7)
    lo, hi = tr.softening_twist(truth, P[:6], W[:6]), tr.softening_twist(truth, P[6:12], W[6:12])
    np.testing.assert_allclose(hi, 4.0 * lo, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(tr.softening_twist(truth, P[:6], -W[:6]), -lo, rtol=1e-12, atol=1e-15)
    tau = tr.actuator_forces(P[:6], W[:6], truth.L)
    J = tr.actuator_jacobian(P[:6], truth.L)
    np.testing.assert_allclose(np.einsum("nij,nj->ni", J, lo[:, :3]), 3e-7 * tau * np.abs(tau), rtol=1e-10)
    assert np.all(lo[:, 3:] == 0.0)


def test_softening_spring_at_two_levels_is_unexplained(tmp_path, level_rows):
    """Actuators that give way by s tau |tau| (a softening spring, out of the library): the
    overall lack of fit does not see it (the calibration takes a mean compliance), the
    load-level test does; the remaining gap is reported per load level."""
    P, W = level_rows
    truth = tr.Truth(tr.variant(NOMINAL), softening=3e-7)
    data = tr.measure(truth, P, W, seed=41, sigma_r=None)
    dg = vjm.diagnose(tr.write_model(NOMINAL, tmp_path / "m.yaml"), data.write(tmp_path / "d.csv"))
    rep = dg.report
    lof = rep["lack_of_fit"]
    assert lof["p_value"] > lof["alpha"], lof  # without the levels it would be calibrated away
    lv = lof["load_levels"]
    assert lv["levels_N"] == [50.0, 100.0] and lv["dof"] >= 1
    assert lv["significant"] and lv["p_value"] < lv["alpha"], lv
    assert rep["verdict"] == "unexplained", _describe(rep)
    levels = rep["localization"]["by_load_level"]
    assert [x["magnitude_N"] for x in levels] == [50.0, 100.0]
    # s tau |tau|: the data grow softer than the model with the load
    assert levels[1]["along_model"] > levels[0]["along_model"] + 0.005, levels
    assert "grow softer with the load" in rep["localization"]["summary"], rep["localization"]["summary"]
    assert "does not scale with the load" in dg.summary().as_text()


def test_linear_library_effect_at_two_levels_is_still_explained(tmp_path, level_rows):
    """A softer leg in extension (linear in the load) at the same two levels: named, and the
    load-level test does not fire (the same compliance at both levels)."""
    P, W = level_rows
    model, truth = tr.hide("leg_axial")
    rep, res = _diagnose(tmp_path, model, tr.measure(truth, P, W, seed=42, sigma_r=None), "--suggest", "12")
    assert rep["verdict"] == "explained", _describe(rep)
    assert tr.names_exactly(rep, ["leg_axial"]), _describe(rep)
    assert not rep["lack_of_fit"]["load_levels"]["significant"], rep["lack_of_fit"]["load_levels"]
    # the suggested rows keep the data's load levels
    Ps, Ws = tr.read_rows(tmp_path / "out" / "next_measurements.csv")
    assert len(Ps) == 12
    mag = np.hypot(np.linalg.norm(Ws[:, :3], axis=1), np.linalg.norm(Ws[:, 3:], axis=1) / 100.0)  # moment on 100 mm
    assert set(np.round(mag, 6)) <= {50.0, 100.0}, Ws


# ------------------------------------------------------------------ vjm simulate --loads with magnitudes

def _rows(path):
    with open(path, newline="", encoding="utf-8") as fh:
        rows = [r for r in csv.reader(fh) if r and not r[0].startswith("#")]
    hdr = rows[0]
    return np.array([[float(r[hdr.index(c)]) for c in ("Fx", "Fy", "Fz", "Mx", "My", "Mz")] for r in rows[1:]])


def test_simulate_writes_every_load_level(tmp_path):
    run = CliRunner().invoke
    out = tmp_path / "a.csv"
    res = run(app, ["simulate", tr.PUU, "--poses", "random:2", "--loads", "axes:50,100:5000", "--out", str(out)])
    assert res.exit_code == 0, res.output
    W = _rows(out)
    assert len(W) == 2 * 2 * 12  # 2 postures x (6 forces + 6 moments) x 2 levels
    per = W[:24]
    np.testing.assert_allclose(per[12:], 2.0 * per[:12])  # each direction at both levels, moment scaled
    assert set(np.abs(per[:, :3]).max(axis=1)) == {0.0, 50.0, 100.0}
    assert set(np.abs(per[:, 3:]).max(axis=1)) == {0.0, 2500.0, 5000.0}
    out2 = tmp_path / "b.csv"
    res = run(app, ["simulate", tr.PUU, "--poses", "random:2", "--loads", "random:3:40,80", "--out", str(out2),
                    "--seed", "3"])
    assert res.exit_code == 0, res.output
    W2 = _rows(out2)
    np.testing.assert_allclose(W2[3:6], 2.0 * W2[:3])  # each random direction at 40 N and 80 N
    np.testing.assert_allclose(np.linalg.norm(W2[:3, :3], axis=1), 40.0)
    bad = run(app, ["simulate", tr.PUU, "--loads", "axes:50,-1", "--out", str(tmp_path / "c.csv")])
    assert bad.exit_code == 2 and "must be a finite number > 0" in bad.output
    assert "Traceback" not in bad.output and not (tmp_path / "c.csv").exists()


# ------------------------------------------------------------------ --suggest: rows that separate a group

def test_rows_to_separate_is_the_first_prefix_that_separates_every_rival():
    """Greedy T-optimal rows on a constructed pair of rivals: ``rows_to_separate`` is the first
    number of rows (in their order) after which every rival's chi-square distance, recomputed
    from scratch by least squares, reaches T_SEPARATE."""
    from vjm.discrepancy import suggest as sg

    rng = np.random.default_rng(7)
    pairs_d, pairs_p = [], []
    for _ in range(2):  # two rivals B: imitation columns (kx = 2), A's signature s
        Xd = rng.standard_normal((5, 3, 2))
        pairs_d.append((Xd, Xd @ np.array([1.0, 0.5])))  # on the data A is B exactly: T = 0
        Xp = rng.standard_normal((40, 3, 2))
        pairs_p.append((Xp, Xp @ np.array([1.0, 0.5]) + 0.6 * rng.standard_normal((40, 3))))
    chosen, before, after, enough = sg._greedy_t(pairs_d, pairs_p, 30)
    assert before == pytest.approx(0.0, abs=1e-9) and after > sg.T_SEPARATE

    def t_after(k, pair_d, pair_p):  # |(I - P_X) s|^2 over the data and the first k chosen rows
        X = np.concatenate([pair_d[0], pair_p[0][chosen[:k]]]).reshape(-1, 2)
        s = np.concatenate([pair_d[1], pair_p[1][chosen[:k]]]).ravel()
        r = s - X @ np.linalg.lstsq(X, s, rcond=None)[0]
        return float(r @ r)

    t = [min(t_after(k, d, p) for d, p in zip(pairs_d, pairs_p)) for k in range(31)]
    assert enough is not None and 0 < enough <= 30
    assert t[enough] >= sg.T_SEPARATE and all(v < sg.T_SEPARATE for v in t[:enough]), (enough, t)
