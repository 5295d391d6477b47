"""Verdict, lack of fit, observability, confounding, robust fits and the suggested design.

References are independent of the code under test: scipy.stats (chi2 and
one-way ANOVA) for the tests, constructed signatures with a known null
direction or a known collinearity, the compliance matrices of the model
itself for what a data set can see, and terms written out here (not in the
effect library) for the out-of-library cases.
"""
import json

import numpy as np
import pytest
from scipy import stats
from typer.testing import CliRunner

import vjm
from vjm.discrepancy import observe
from vjm.discrepancy.data import Deflections, read_csv, write_deflections
from vjm.discrepancy.simulate import design_loads, simulate
from vjm.discrepancy.workflow import diagnose
from vjm.model.links import LinkSpring as Link
from vjm.stats.fit import FitResult, fit_terms, lack_of_fit
from vjm.stats.terms import Param, Problem, Term

PUU = "data/orthoglide/puu.yaml"
MODEL = vjm.load_model(PUU).replace(foot=Link.rigid())
_rng = np.random.default_rng(0)
_P0 = _rng.uniform(-60.0, 90.0, (14, 3))
_L = design_loads("axes:100", len(_P0), _rng)
P = np.repeat(_P0, _L.shape[1], axis=0)
W = _L.reshape(-1, 6)
NOISE = 1e-3
FEW = ["gravity", "clearance", "passive_joint_compliance", "actuator_travel_stiffness"]


# ---------------------------------------------------------------- statistics on constructed cases

def test_lack_of_fit_known_sigma_is_the_chi2_tail():
    """chi2 = 130 on 120 - 2 dof: p is scipy's chi2 survival function, chi2_red the ratio."""
    fr = FitResult(("a",), np.zeros(2), np.zeros(2), 130.0, 120, 2, True, True)
    lof = lack_of_fit(fr)
    assert lof["dof"] == 118
    assert lof["p_value"] == pytest.approx(stats.chi2.sf(130.0, 118), rel=1e-12)
    assert lof["chi2_red"] == pytest.approx(130.0 / 118)


def test_lack_of_fit_pure_error_equals_one_way_anova():
    """Unknown sigma, repeats: a one-mean model's lack-of-fit F against pure error is the one-way
    ANOVA F of the groups (scipy.stats.f_oneway), computed here from the raw groups."""
    rng = np.random.default_rng(5)
    groups = [rng.normal(mu, 1.0, 4) for mu in (0.0, 0.3, -0.2, 1.1, 0.5, 0.0)]
    y = np.concatenate(groups)
    g = np.repeat(np.arange(len(groups)), 4)
    terms = {"mean": Term("mean", (Param("m", 0.0, scale=1.0),))}
    prob = Problem(lambda names, th: y - (th[0] if names else 0.0), terms, g, False, ("mean",))
    fr = fit_terms(prob, ("mean",))
    ss_pe = float(sum(((x - x.mean()) ** 2).sum() for x in groups))
    lof = lack_of_fit(fr, (ss_pe, y.size - len(groups)))
    F, p = stats.f_oneway(*groups)
    assert lof["chi2_red"] == pytest.approx(F, rel=1e-6)
    assert lof["p_value"] == pytest.approx(p, rel=1e-6)
    assert lof["dof"] == len(groups) - 1


def test_lack_of_fit_cannot_be_judged_without_sigma_or_repeats():
    fr = FitResult(("a",), np.zeros(1), np.zeros(1), 3.0, 50, 1, False, True)
    lof = lack_of_fit(fr)
    assert lof["p_value"] is None and "cannot be judged" in lof["note"]


def _linear_problem(cols, sigma_known=True):
    """Whitened residuals of y = 0 against sum_j theta_j cols[:, j] (terms 'base' + one per column)."""
    x = np.linspace(-1, 1, cols.shape[0])
    terms = {"base": Term("base", (Param("a", 1.0, scale=1.0, null=1.0),))}
    names = []
    for j in range(cols.shape[1]):
        terms[f"t{j}"] = Term(f"t{j}", (Param("c", 0.0, lower=-10, upper=10, scale=1.0),))
        names.append(f"t{j}")

    def res(nm, th):
        f = th[0] * x
        for k, n in enumerate(nm[1:], start=1):
            f = f + th[k] * cols[:, int(n[1:])]
        return x - f

    return Problem(res, terms, np.arange(x.size) // 4, sigma_known, ("base",)), x


def test_observability_finds_the_known_null_direction():
    """A two-parameter term whose second parameter never enters the residuals, and one whose two
    parameters enter only through their sum: one parameter held fixed in each; a term with
    no effect at all is not observable."""
    x = np.linspace(-1, 1, 80)
    terms = {"base": Term("base", (Param("a", 1.0, scale=1.0, null=1.0),)),
             "dead": Term("dead", (Param("u", 0.0, lower=-10, upper=10, scale=1.0),
                                   Param("v", 0.0, lower=-10, upper=10, scale=1.0))),
             "sum": Term("sum", (Param("u", 0.0, lower=-10, upper=10, scale=1.0),
                                 Param("v", 0.0, lower=-10, upper=10, scale=1.0))),
             "none": Term("none", (Param("u", 0.0, lower=-10, upper=10, scale=1.0),))}

    def res(names, th):
        f = th[0] * x
        if names[1:] == ("dead",):
            f = f + th[1] * x**2
        elif names[1:] == ("sum",):
            f = f + (th[1] + th[2]) * np.sin(3 * x)
        return (x - f) / 0.01

    prob = Problem(res, terms, np.arange(80) // 4, True, ("base",))
    base = fit_terms(prob, ("base",))
    dead = observe.term_sensitivity(prob, base.theta, "base", "dead")
    assert dead.free == (0,) and dead.fixed == (1,)
    s = observe.term_sensitivity(prob, base.theta, "base", "sum")
    assert len(s.free) == 1 and len(s.fixed) == 1
    none = observe.term_sensitivity(prob, base.theta, "base", "none")
    assert not none.observable


def test_confounding_of_constructed_collinear_signatures():
    """Signatures x^2 and x^2 + 0.001 sin(5x) are collinear (corr > 0.99); x^2 and x^3 are not;
    x and 2x + x^2 are collinear once the calibration column x is projected out only if the rest is."""
    x = np.linspace(-1, 1, 200)
    a, b, c = x**2, x**2 + 1e-3 * np.sin(5 * x), x**3
    assert observe.canonical_correlation(a[:, None], b[:, None]) > 0.99
    assert observe.canonical_correlation(a[:, None], c[:, None]) < 0.1
    cal = x[:, None]
    # raw correlation of x^3 and x is high (0.92), partial correlation with x projected out is not 1
    assert observe.canonical_correlation(c[:, None], cal) > 0.9
    assert observe.partial_correlation((x + x**2)[:, None], (2 * x + x**2)[:, None], cal) == pytest.approx(1.0)
    # a signature entirely in the calibration's span is mimicked by it, with the right coefficient
    R, coef = observe.mimicry((3 * x)[:, None], cal)
    assert R == pytest.approx(1.0) and coef[0, 0] == pytest.approx(3.0)


# ---------------------------------------------------------------- what the 3-PUU data can see

def test_leg_bending_coupling_unobservable_and_foot_coupling_observable_by_the_compliance():
    """Independent of the fit: the 3-PUU compliance does not change when the leg's c26/c35 are
    zeroed (U-U leg), but does when the foot's are zeroed, except at Q0 (seed: 0 at Q0, ~2 % at Q2)."""
    full = vjm.load_model(PUU)
    Q0, Q2 = np.zeros((1, 3)), np.full((1, 3), 73.65)

    def zero_coupling(m, key):
        C = getattr(m, key).compliance.copy()
        C[1, 5] = C[5, 1] = C[2, 4] = C[4, 2] = 0.0
        return m.replace(**{key: Link(C, None)})

    C = full.stiffness_map(np.vstack([Q0, Q2])).C
    Cl = zero_coupling(full, "leg").stiffness_map(np.vstack([Q0, Q2])).C
    Cf = zero_coupling(full, "foot").stiffness_map(np.vstack([Q0, Q2])).C
    rel = lambda A, B: np.abs(A - B).max() / np.abs(B).max()  # noqa: E731
    assert rel(Cl[1], C[1]) < 1e-9 and rel(Cl[0], C[0]) < 1e-9
    assert rel(Cf[0], C[0]) < 1e-9
    assert rel(Cf[1], C[1]) > 1e-3
    # and the diagnosis agrees: the leg's coupling is reported not observable, never fitted
    data = simulate(MODEL, [], P, W, NOISE, None, 0)
    rep = diagnose(MODEL, data, effects=["leg_bending_coupling", "gravity"]).report
    assert "leg_bending_coupling" in rep["unobservable"]
    assert rep["candidates"]["leg_bending_coupling"]["observable"] is False
    assert rep["candidates"]["leg_bending_coupling"]["p_value"] is None


# ---------------------------------------------------------------- verdicts on the 3-PUU

def test_clean_data_verdict_no_discrepancy_and_report_keys():
    data = simulate(MODEL, [], P, W, NOISE, None, 11)
    dg = vjm.diagnose(MODEL, data, effects=FEW)
    rep = dg.report
    assert dg.verdict == "no_discrepancy" and dg.named == []
    lof = rep["lack_of_fit"]
    assert set(lof) >= {"chi2_red", "dof", "p_value"} and lof["p_value"] > lof["alpha"]
    assert lof["alpha"] == pytest.approx(0.01 / (rep["n_tested"] + 1))
    assert isinstance(rep["confounded"], list)
    text = str(dg.summary())
    assert text.startswith("Verdict: no discrepancy")
    assert "<table" in dg._repr_html_()


def _upward(model, F):
    """An upward force F on the platform (not a weight), written here: C(p) (0, 0, +F, 0, 0, 0)."""
    C = model.stiffness_map(P).C
    return F * C[:, :, 2]


def test_out_of_library_effects_end_unexplained():
    """Two terms written here, not in the library: an upward force (gravity's fit stays at its
    bound W >= 0 and is not named), and a contact that stiffens with the load (deflection
    ~ |F|^(2/3) along F).  Both: verdict unexplained and the summary says where the gap is."""
    base = simulate(MODEL, [], P, W, NOISE, None, 3)
    for extra in (_upward(MODEL, 20.0),
                  np.hstack([3e-3 * (np.abs(W[:, :3]) / 100.0) ** (2 / 3) * np.sign(W[:, :3]), np.zeros((len(W), 3))])):
        T = base.T.copy()
        T[:, :3] += extra[:, :3]
        d = Deflections(base.P, base.W, T, base.sigma_t, None, base.rows, "x.csv")
        rep = diagnose(MODEL, d, effects=FEW).report
        assert rep["verdict"] == "unexplained", rep["summary"]
        assert rep["lack_of_fit"]["p_value"] < rep["lack_of_fit"]["alpha"]
        assert "no candidate of the library explains it" in rep["summary"]
        assert "Where the remaining gap is" in rep["summary"]
        if "gravity" in rep["candidates"] and rep["candidates"]["gravity"]["params"]:
            assert "gravity" not in rep["named_effects"]


def test_named_effect_with_remaining_gap_is_unexplained():
    """A library effect (weight, written here as C (0,0,-W)) plus an out-of-library contact term:
    gravity may be named, the verdict is still unexplained."""
    C = MODEL.stiffness_map(P).C
    base = simulate(MODEL, [], P, W, NOISE, None, 4)
    T = base.T.copy()
    T[:, :3] += -15.0 * C[:, :3, 2] + 4e-3 * (np.abs(W[:, :3]) / 100.0) ** 2 * np.sign(W[:, :3])
    rep = diagnose(MODEL, Deflections(base.P, base.W, T, base.sigma_t, None, base.rows, "y.csv"), effects=FEW).report
    assert rep["verdict"] == "unexplained", rep["summary"]
    assert "gravity" in rep["named_effects"]


def test_clipped_fit_is_never_named():
    """A leg 40x softer in torsion than the model (truth built here by editing c44), fitted by a
    candidate whose factor range ends at 20x: the fit ends on its bound, is flagged, is not named,
    and the verdict is not "explained"."""
    C = MODEL.leg.compliance.copy()
    C[3, 3] *= 40.0
    soft = MODEL.replace(leg=Link(C, None))
    data = simulate(soft, [], P, W, NOISE, None, 1)
    rep = diagnose(MODEL, data, effects=["leg_torsion"]).report
    c = rep["candidates"]["leg_torsion"]
    assert c["at_bound"] == ["factor"], c
    assert rep["named_effects"] == [] and rep["verdict"] == "unexplained", rep["summary"]
    assert any("on a bound" in f for f in rep["flags"]), rep["flags"]


# ---------------------------------------------------------------- suggested measurements

def _cli():
    from vjm.cli import app

    return app


def test_suggest_file_is_read_by_simulate(tmp_path):
    """diagnose --suggest 10 writes x,y,z,Fx..Mz rows with the data's load magnitudes; vjm simulate
    --poses F --loads F reads them as 10 paired measurements at exactly those rows."""
    data = simulate(MODEL, [], P, W, NOISE, None, 2)
    csv = tmp_path / "d.csv"
    write_deflections(csv, data)
    runner = CliRunner()
    out = tmp_path / "rep"
    r = runner.invoke(_cli(), ["diagnose", PUU, str(csv), "--out", str(out), "--suggest", "10",
                               "--effect", "gravity", "--effect", "clearance"])
    assert r.exit_code == 0, r.output
    nm = out / "next_measurements.csv"
    lines = [ln for ln in nm.read_text().splitlines() if not ln.startswith("#")]
    assert lines[0] == "x,y,z,Fx,Fy,Fz,Mx,My,Mz" and len(lines) == 11
    rows = np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]])
    f = np.linalg.norm(rows[:, 3:6], axis=1)
    m = np.linalg.norm(rows[:, 6:], axis=1)
    assert np.all((np.isclose(f, 100.0) & (m == 0)) | ((f == 0) & np.isclose(m, 100.0 * 100.0)))
    assert np.all(MODEL.arch.reachable(MODEL, rows[:, :3]))
    rep = json.loads((out / "report.json").read_text())
    assert rep["suggest"]["n"] == 10 and ("D-optimal" in rep["suggest"]["criterion"] or
                                         "T-optimal" in rep["suggest"]["criterion"])
    sim = tmp_path / "new.csv"
    r = runner.invoke(_cli(), ["simulate", PUU, "--poses", str(nm), "--loads", str(nm), "--noise-t", "0.001",
                               "--out", str(sim)])
    assert r.exit_code == 0, r.output
    d2 = read_csv(sim)
    assert d2.n == 10
    np.testing.assert_allclose(d2.P, rows[:, :3])
    np.testing.assert_allclose(d2.W, rows[:, 3:])


def test_suggest_forces_only_has_no_moments():
    data = simulate(MODEL, [], P, W, NOISE, None, 2)
    dg = diagnose(MODEL, data, effects=["gravity", "clearance"], suggest=6, forces_only=True)
    assert dg.next_measurements.shape == (6, 9)
    assert np.all(dg.next_measurements[:, 6:] == 0)
    assert dg.report["suggest"]["forces_only"] is True


@pytest.mark.slow
def test_suggested_measurements_separate_a_confounded_pair():
    """8 postures near Q0 under forces only: a hidden elastic passive joint is reported in a group it
    cannot be separated from (the leg's torsion, the foot, ...).  Measuring the 24 suggested rows
    (T-optimal, torques allowed) and diagnosing old + new data resolves the group: the passive
    joints are named alone."""
    rng = np.random.default_rng(1)
    P0 = rng.uniform(-15.0, 15.0, (8, 3))
    L = design_loads("axes:100", len(P0), rng)
    Pq, Wq = np.repeat(P0, L.shape[1], axis=0), L.reshape(-1, 6)
    truth = [("passive_joint_compliance", {"compliance": 2e-7})]
    eff = ["passive_joint_compliance", "foot_compliance", "gravity"]
    d1 = simulate(MODEL, truth, Pq, Wq, NOISE, None, 1)
    dg = diagnose(MODEL, d1, effects=eff, suggest=24)
    grp = [g for g in dg.confounded if "passive_joint_compliance" in g]
    assert grp and "foot_compliance" in grp[0], dg.report["summary"]
    new = dg.next_measurements
    d2 = simulate(MODEL, truth, new[:, :3], new[:, 3:], NOISE, NOISE * 1e-2, 2)
    T2 = d2.T.copy()
    T2[:, 3:] = np.nan  # the same rig: translations only
    both = Deflections(np.vstack([d1.P, d2.P]), np.vstack([d1.W, d2.W]), np.vstack([d1.T, T2]),
                       np.r_[d1.sigma_t, d2.sigma_t], None)
    rep = diagnose(MODEL, both, effects=eff).report
    assert rep["named_effects"] == ["passive_joint_compliance"], rep["summary"]
    assert not any("passive_joint_compliance" in g and "foot_compliance" in g for g in rep["confounded"]), rep["summary"]


def test_independent_columns_drops_a_dependent_one():
    x = np.linspace(-1, 1, 50)
    J = np.stack([x, x**2, 2 * x + 1e-4 * x**3, np.zeros_like(x), x**3], axis=1)
    assert observe.independent_columns(J) == (0, 1, 4)


def test_calibration_factor_inseparable_on_the_data_is_held_at_nominal():
    """Postures within 2 mm of Q0 under forces only: leg axial compliance and actuator compliance act
    in series along the same axes, so link_scale cannot be told from actuator_scale; it is held at 1,
    flagged, and the actuator factor (truth 0.8, set here on the model) is still found."""
    rng = np.random.default_rng(3)
    P0 = rng.uniform(-2.0, 2.0, (6, 3))
    L = design_loads("axes:100", len(P0), rng)
    Pq, Wq = np.repeat(P0, L.shape[1], axis=0), L.reshape(-1, 6)
    a = MODEL.actuator
    data = simulate(MODEL.replace(actuator=type(a)(0.8 * a.stiffness, a.compliance_slope, a.q_ref)), [],
                    Pq, Wq, NOISE, None, 5)
    rep = diagnose(MODEL, data, effects=["gravity"]).report
    assert rep["calibration_held"] == {"link_scale": 1.0}
    assert any("link_scale held" in f for f in rep["flags"])
    act = rep["calibration"]["actuator_scale"]
    assert abs(act["value"] - 0.8) <= 3 * act["se"], act


# ---------------------------------------------------------------- an effect hidden inside a named one

def test_hiding_share_closed_form():
    """e1, e2, e3 orthonormal; the model holds span(e1, e2) and explains s = 40 e1 + 30 e2; a term
    along u = cos t e1 + sin t e3 has canonical correlation cos t with the model, and the model can
    stand in for r u at a chi-square cost (r sin t)^2, so the term carries z / sin t unseen, out of
    |<s, u>| = 40 cos t: share z / (40 sin t cos t)."""
    rng = np.random.default_rng(3)
    E, _ = np.linalg.qr(rng.standard_normal((60, 3)))
    e1, e2, e3 = E.T
    z = 2.5758293035489
    for t in (0.01, 0.05, 0.3):
        B = 7.0 * (np.cos(t) * e1 + np.sin(t) * e3)
        R, share = observe.hiding_share(B[:, None], np.column_stack([e1 + e2, e1 - e2]), 40 * e1 + 30 * e2, z)
        assert R == pytest.approx(np.cos(t), abs=1e-12)
        assert share == pytest.approx(z / (40 * np.sin(t) * np.cos(t)), rel=1e-9)
    # a second column of B that the model cannot imitate changes nothing: the closest direction counts
    B2 = np.column_stack([np.cos(0.05) * e1 + np.sin(0.05) * e3, rng.standard_normal(60)])
    B2[:, 1] -= E @ (E.T @ B2[:, 1])
    R2, share2 = observe.hiding_share(B2, np.column_stack([e1, e2]), 40 * e1 + 30 * e2, z)
    assert R2 == pytest.approx(np.cos(0.05), abs=1e-9)
    assert share2 == pytest.approx(z / (40 * np.sin(0.05) * np.cos(0.05)), rel=1e-6)


def _hidden_problem(sigma, b, seed=1):
    """y = calibration (offset 1) + A (2 parameters: u + v) + B (b (u + 0.02 w)) + noise sigma, u, v, w
    orthogonal to each other and to the offset, norm sqrt(m) = K sigma.  B's signature lies in A's
    span up to 0.02 w: canonical correlation 1/sqrt(1 + 0.02^2) = 0.9998."""
    m = 240
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(np.column_stack([np.ones(m), rng.standard_normal((m, 4))]))
    one, u, v, w, o = (np.sqrt(m) * Q[:, k] for k in range(5))
    cols = {"A": (u, v), "B": (u + 0.02 * w,), "C": (o,)}
    y = 1.0 * one + u + v + b * cols["B"][0] + sigma * rng.standard_normal(m)
    terms = {"calibration": Term("calibration", (Param("offset", 1.0, lower=0.0, upper=10.0, scale=1.0, null=1.0),))}
    for n, cs in cols.items():
        terms[n] = Term(n, tuple(Param(f"p{k}", 0.0, lower=-10.0, upper=10.0, scale=0.1) for k in range(len(cs))))

    def res(names, th):
        f, i = th[0] * one, 1
        for n in names[1:]:
            for c in cols[n]:
                f, i = f + th[i] * c, i + 1
        return (y - f) / sigma

    return Problem(res, terms, np.arange(m) // 4, True, ("calibration",))


def _select_and_group(prob, names, alpha=0.01):
    from vjm.discrepancy.stages.confounding import confounding
    from vjm.discrepancy.stages.rivals import rival_check
    from vjm.stats.selection import backward_eliminate, forward_select

    base = fit_terms(prob, ("calibration",))
    cal_cols = observe.calibration_columns(prob, base.theta, "calibration")
    sens = {n: observe.term_sensitivity(prob, base.theta, "calibration", n) for n in names}
    sel = forward_select(prob, names, alpha=alpha, extra_tests=1)
    sel, rivals = rival_check(prob, sel, names, sens, cal_cols, alpha)
    sel = backward_eliminate(prob, sel)
    first = sel.rounds[0]
    cand_rep = {n: {"p_value": first[n]["p_value"], "params": first[n]["fit"].values(prob)[n]} for n in names}
    conf = confounding(prob, sel, sens, cal_cols, cand_rep, alpha, rivals)
    return sel, {"groups": conf.groups, "details": conf.details}


def test_effect_hidden_inside_a_named_one_is_grouped_with_it():
    """A (two parameters) and B hidden, B's signature inside A's span up to 0.02 w.  A absorbs B
    (fits (1 + b) u + v) and B cannot replace A (v), so the swap test separates them; whether part of
    A's u is B, the data can tell only when B's 0.02 w part shows.  Along u' = (u + 0.02 w)/|.| the
    model can stand in for r u' at a chi-square cost (0.02 r)^2 / (1 + 0.02^2), so B can carry
    z sqrt(1 + 0.02^2) / 0.02 unseen out of A's (1 + b) K / sqrt(1 + 0.02^2) along it (K = sqrt(240) / sigma):

    * sigma 0.1, b = 0.5: B's w part is 1.5 sigma in all (not significant): A named, B grouped with it,
      share z (1 + 0.02^2) / (0.02 x 1.5 K) = 0.55;
    * sigma 0.1, b = 0 (B absent): the same design cannot exclude it: share 0.83, grouped;
    * sigma 0.001, b = 0: it could carry only 0.8 % of A: no group;
    * sigma 0.001, b = 0.5: its w part is 155 sigma: named besides A."""
    z = 2.5758293035489
    for sigma, b in ((0.1, 0.5), (0.1, 0.0)):
        sel, conf = _select_and_group(_hidden_problem(sigma, b), ["A", "B", "C"])
        assert sel.selected == ("A",)
        assert any({"A", "B"} <= set(g) for g in conf["groups"]), conf
        d = next(d for d in conf["details"] if d["names"] == ["A", "B"])
        assert d["correlation"] == pytest.approx(1 / np.sqrt(1 + 0.02**2), abs=1e-6)
        assert d["share"] == pytest.approx(z * (1 + 0.02**2) / (0.02 * (1 + b) * np.sqrt(240) / sigma), rel=0.05)
        assert not any("C" in g for g in conf["groups"])
    sel, conf = _select_and_group(_hidden_problem(0.001, 0.0), ["A", "B", "C"])
    assert sel.selected == ("A",)
    assert not any("B" in g for g in conf["groups"]), conf
    sel, conf = _select_and_group(_hidden_problem(0.001, 0.5), ["A", "B", "C"])
    assert set(sel.selected) == {"A", "B"}
