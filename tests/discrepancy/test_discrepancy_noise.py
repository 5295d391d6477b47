"""The noise of the measurements: estimated, stated wrongly, per component, growing with distance.

Every data set comes from tests/truth.py (the defects of the noise are made there, never with
vjm.discrepancy code): 16 random postures x 12 loads of the 3-PUU, 1 um / 10 urad unless said.
Rates over many sets: benchmarks/bench_diagnose_noise.py.
"""
import numpy as np
import pytest
import truth as tr
from scipy import stats
from typer.testing import CliRunner

from vjm.cli import app
from vjm.discrepancy.data import read_csv
from vjm.discrepancy.stages.kinds import kind_of
from vjm.discrepancy.stages.problem import build_problem
from vjm.discrepancy.tracker import TrackerNoise
from vjm.discrepancy.workflow import diagnose
from vjm.errors import VjmError
from vjm.stats.fit import compare, fit_terms
from vjm.stats.terms import Param, Problem, Term

HDR = "x,y,z,Fx,Fy,Fz,Mx,My,Mz,dx,dy,dz,rx,ry,rz"
#: a tracker 300 mm from the workspace's centre along -x, its angle noise 6 um/m across the line of
#: sight (y, z) and its range noise 1 um/m along it (x), 0.5 um floor
TRACKER = ((-330.0, 26.35, 26.35), (5e-4, 5e-4, 5e-4), (1e-6, 6e-6, 6e-6))


def _diagnose(tmp_path, given, data, name, **kw):
    mp = tr.write_model(given, tmp_path / f"{name}.yaml")
    return diagnose(mp, data.write(tmp_path / f"{name}.csv"), **kw).report


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    return tmp_path_factory.mktemp("noise")


@pytest.fixture(scope="module")
def backlash():
    return tr.hide(("clearance", 3e-3))


@pytest.fixture(scope="module")
def no_sigma_backlash(work, backlash):
    """Design seed 7: the common-variance F test with weights from the nominal residuals named
    leg_bending_z (factor 1.13) beside the clearance on this set."""
    given, truth = backlash
    P, W = tr.design(16, 12, seed=7)
    return _diagnose(work, given, tr.measure(truth, P, W, seed=8, known_sigmas=False), "nosig")


def test_sigma_columns_dropped_hidden_clearance_named_alone(no_sigma_backlash):
    rep = no_sigma_backlash
    assert not rep["sigma_known"]
    assert rep["verdict"] == "explained" and rep["named_effects"] == ["clearance"], rep["summary"]
    b = rep["final_params"]["clearance"]["backlash"]
    assert abs(b["value"] - 3e-3) <= 3 * b["se"]
    # the variances of translations and rotations fitted apart: each near the truth's noise
    est = rep["noise"]["groups"]
    assert 0.9 < est["t"]["estimated_sigma"] < 1.1 and 9.0 < est["r"]["estimated_sigma"] < 11.0, est
    # a sign-bound effect never fits against its physics
    gnl = rep["candidates"].get("geometric_nonlinearity", {}).get("params", {})
    assert all(v["value"] >= 0 for v in gnl.values()), gnl


def test_clean_without_sigmas_no_discrepancy(work):
    P, W = tr.design(16, 12, seed=3)
    rep = _diagnose(work, tr.NOMINAL, tr.measure(tr.Truth(tr.variant(tr.NOMINAL)), P, W, seed=4,
                                                 known_sigmas=False), "clean")
    assert rep["verdict"] == "no_discrepancy", rep["summary"]


def test_stated_sigma_half_the_real_one(work, backlash):
    """The file states 0.5 um / 5 urad where the noise is 1 um / 10 urad: the clearance alone is named
    and both stated sigmas are flagged about 2x too small."""
    given, truth = backlash
    P, W = tr.design(16, 12, seed=5)
    rep = _diagnose(work, given, tr.measure(truth, P, W, seed=6, stated_factor=0.5), "half")
    assert rep["verdict"] == "explained" and rep["named_effects"] == ["clearance"], rep["summary"]
    for key, name in (("t", "sigma_t"), ("r", "sigma_r")):
        g = rep["noise"]["groups"][key]
        assert g["stated"] == "too_small" and 1.8 < g["ratio"] < 2.2, g
        assert any(f.startswith(f"stated {name} looks 2.0x too small") for f in rep["flags"]), rep["flags"]


def test_hysteresis_excess_is_structure_not_noise(work):
    """Known, right sigmas and an out-of-library hysteresis: the excess of the residuals depends on the
    previous load, so the stated sigmas stand and the verdict stays unexplained."""
    P, W = tr.design(16, 12, seed=9)
    rep = _diagnose(work, tr.NOMINAL, tr.measure(tr.Truth(tr.variant(tr.NOMINAL), hysteresis=0.05), P, W,
                                                 seed=10), "hyst")
    assert rep["verdict"] == "unexplained", rep["summary"]
    g = rep["noise"]["groups"]["t"]
    assert g["stated"] == "too_small" and not g["taken_as_noise"], g
    assert rep["noise"]["scale_used"] == [1.0, 1.0]


@pytest.fixture(scope="module")
def dz_noisy(work):
    """Noise 5x larger on dz, stated in sigma_dz (per-component columns)."""
    P, W = tr.design(16, 12, seed=11)
    m = tr.measure(tr.Truth(tr.variant(tr.NOMINAL)), P, W, seed=12, axis_factor=(1, 1, 5, 1, 1, 1))
    return m, m.write(work / "dz.csv")


def test_per_component_sigma_columns_read_and_used(work, dz_noisy):
    m, path = dz_noisy
    d = read_csv(path)
    assert d.sigma_t is None and d.sigma is not None
    np.testing.assert_allclose(d.sigma[:, 2], 5e-3)
    np.testing.assert_allclose(d.sigma[:, [0, 1]], 1e-3)
    # closed form: the residual problem whitens each component by its own column
    model = tr.build(tr.NOMINAL)
    s = build_problem(model, d, kind_of(d))
    r = s.prob.residuals((), np.zeros(0))
    expect = ((d.T - s.pred.twists((), np.zeros(0))) / d.sigma)[d.mask]
    np.testing.assert_allclose(r, expect, rtol=1e-12)
    rep = diagnose(model, d).report
    assert rep["sigma_known"] and rep["verdict"] == "no_discrepancy", rep["summary"]
    # with the 5x on dz, the translations' residuals are what the file states
    assert rep["noise"]["groups"]["t"]["stated"] == "consistent", rep["noise"]


def test_per_component_sigma_columns_refused_when_inconsistent(tmp_path):
    row = "0,0,0,100,0,0,0,0,0,1e-3,0,0,,,"
    bad = {"sigma_t,sigma_dx,sigma_dy,sigma_dz": (",1e-3,1e-3,1e-3,1e-3", r"sigma_t and sigma_dx both given"),
           "sigma_dx,sigma_dy": (",1e-3,1e-3", r"sigma_dx, sigma_dy without sigma_dz"),
           "sigma_dx,sigma_dy,sigma_dz": (",1e-3,1e-3,", r"column 'sigma_dz': value is missing: dz is measured")}
    for cols, (vals, msg) in bad.items():
        p = tmp_path / "bad.csv"
        p.write_text(f"{HDR},{cols}\n{row}{vals}\n")
        with pytest.raises(VjmError, match=msg):
            read_csv(p)


def test_distance_proportional_noise(work, backlash):
    """A laser tracker's noise (truth.tracker_sigma), the file stating only the rotations' sigma: the
    tracker model given to diagnose makes the translations' sigmas; the clearance alone is named and
    the stated noise is consistent with the residuals."""
    given, truth = backlash
    P, W = tr.design(16, 12, seed=13)
    m = tr.measure(truth, P, W, seed=14, tracker=TRACKER)
    sig = m.sigma.copy()
    sig[:, :3] = np.nan  # the file states the rotations' sigmas only
    path = tr.Measurements(m.P, m.W, m.T, None, None, sig).write(work / "tracker.csv")
    noise = TrackerNoise(*TRACKER)
    np.testing.assert_allclose(noise.sigmas(m.P), m.sigma[:, :3], rtol=1e-12)
    rep = diagnose(tr.write_model(given, work / "tracker.yaml"), path, noise=noise).report
    assert rep["sigma_known"] and rep["verdict"] == "explained", rep["summary"]
    assert rep["named_effects"] == ["clearance"], rep["summary"]
    assert rep["noise"]["groups"]["t"]["stated"] == "consistent", rep["noise"]


def test_tracker_options_refused_alone(tmp_path):
    res = CliRunner().invoke(app, ["diagnose", "m.yaml", "d.csv", "--out", str(tmp_path / "o"), "--tracker", "0,0,0"])
    assert res.exit_code == 2 and "--tracker and --tracker-noise go together" in res.output
    with pytest.raises(VjmError, match="--tracker-noise: expected A,B"):
        TrackerNoise.parse("0,0,0", "1,2,3")


def test_profiled_likelihood_ratio_closed_form():
    """A linear model with two variance components (sd 1 and 10): the fit is the weighted least squares
    with each component's own ML variance (a fixed point checked by numpy), and the test statistic is
    sum_g n_g ln(RSS_g0 / RSS_g1)."""
    rng = np.random.default_rng(0)
    n = 400
    comp = np.repeat([0, 1], n // 2)
    x = rng.standard_normal(n)
    z = rng.standard_normal(n)
    y = 2.0 * x + 0.15 * z + np.where(comp == 0, 1.0, 10.0) * rng.standard_normal(n)
    terms = {"a": Term("a", (Param("a", 0.0),)), "b": Term("b", (Param("b", 0.0),))}

    def residuals(names, theta):
        cols = {"a": x, "b": z}
        return y - sum(t * cols[nm] for nm, t in zip(names, theta))

    prob = Problem(residuals, terms, np.arange(n) % 20, False, ("a",), comp)
    small, big = fit_terms(prob, ("a",)), fit_terms(prob, ("a", "b"))
    var = np.array(big.group_var)
    w = 1.0 / np.sqrt(var[comp])
    coef, *_ = np.linalg.lstsq(np.column_stack([x, z]) * w[:, None], y * w, rcond=None)
    np.testing.assert_allclose(big.theta, coef, rtol=1e-4)
    r = y - np.column_stack([x, z]) @ big.theta
    np.testing.assert_allclose(var, [np.mean(r[comp == g] ** 2) for g in (0, 1)], rtol=1e-6)
    lr = sum(m * np.log(a / b) for m, a, b in zip(big.group_n, small.group_rss, big.group_rss))
    assert compare(prob, small, big)[1] == pytest.approx(stats.chi2.sf(lr, 1), rel=1e-9)
