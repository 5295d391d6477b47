"""Self-validation of the independent truth generator (tests/truth.py).

Each term of the generator is checked against something it was not built
from: vjm's chains and statics, the nonlinear equilibrium, closed forms.
"""
import numpy as np
import pytest
import truth as tr

from vjm.discrepancy.data import read_csv

L = 310.0
BRACKET = {"beam": {"section": "rect", "width": 40.0, "height": 16.0, "length": 90.0, "material": "aluminium"}}
SLOPE = 5e-7  # (mm/N)/mm


def rich_model(slope=SLOPE, coupling=True):
    """Every model-file term at once: bracket foot with couplings, joint springs, travel-dependent actuator."""
    d = tr.nominal()
    return tr.variant(d, foot=tr.inline(tr.rect_beam_compliance(90, 40, 16, coupling=coupling)),
                      joints={"passive_stiffness": 2e7},
                      actuator={"stiffness": d["actuator"]["stiffness"], "compliance_slope": slope, "q_ref": 0.0})


@pytest.fixture(scope="module")
def rows():
    return tr.design(6, 12, seed=3)


def test_postures_and_loads():
    rng = np.random.default_rng(0)
    P = tr.postures(200, rng)
    assert P.shape == (200, 3) and np.all(P >= tr.WORKSPACE[0]) and np.all(P <= tr.WORKSPACE[1])
    W = tr.loads(12, rng)
    np.testing.assert_array_equal(W[0::2], -W[1::2])  # opposite pairs
    assert np.any((np.linalg.norm(W[:, :3], axis=1) > 0) & (np.linalg.norm(W[:, 3:], axis=1) > 0))
    assert np.any((np.linalg.norm(W[:, :3], axis=1) == 0) & (np.linalg.norm(W[:, 3:], axis=1) > 0))
    assert not np.any(tr.loads(12, rng, forces_only=True)[:, 3:])


def test_kinematics_match_vjm_chains(rows):
    """Closed-form inverse kinematics = vjm's; its Jacobian = central differences of it."""
    P, _ = rows
    m = tr.build(tr.nominal())
    np.testing.assert_allclose(tr.actuator_coordinates(P, L), m.inverse_kinematics(P), atol=1e-10)
    h = 1e-4
    fd = np.stack([(m.inverse_kinematics(P + h * e) - m.inverse_kinematics(P - h * e)) / (2 * h)
                   for e in np.eye(3)], axis=2)
    np.testing.assert_allclose(tr.actuator_jacobian(P, L), fd, atol=1e-7)


def test_actuator_forces_match_vjm_statics(rows):
    """J^-T F = vjm's load sharing (eq. 9, 12) on the richest model; moments load no actuator."""
    P, W = rows
    m = tr.build(rich_model())
    tau = m.joint_forces(P, W)["actuator"]
    np.testing.assert_allclose(tr.actuator_forces(P, W, L), tau, atol=1e-9 * np.abs(tau).max())
    Wm = W.copy()
    Wm[:, :3] = 0.0
    assert np.abs(m.joint_forces(P, Wm)["actuator"]).max() < 1e-9 * np.abs(tau).max()


def test_prpar_kinematics_and_statics_match_vjm(rows):
    """The 3-PRPaR (bar effects' truth): same closed-form inverse kinematics and actuator forces as
    the 3-PUU, checked against vjm's parallelogram chains; the acceptance design is reachable."""
    P, W = rows
    m = tr.build(tr.nominal(tr.PRPAR))
    assert m.architecture == "orthoglide-3PRPaR"
    np.testing.assert_allclose(tr.actuator_coordinates(P, L), m.inverse_kinematics(P), atol=1e-10)
    tau = m.joint_forces(P, W)["actuator"]
    np.testing.assert_allclose(tr.actuator_forces(P, W, L), tau, atol=1e-9 * np.abs(tau).max())
    Pa, Wa = tr.acceptance_rows("bar_axial")
    assert len(Pa) == 144 and np.all(m.arch.reachable(m, Pa)) and np.abs(Wa[:, 3:]).max() > 5000.0


def test_signature_chi2_calibration_takes_a_scaled_model_whole(rows):
    """A true machine that is the model given with its actuator stiffness x 0.8 and its link
    compliances x 1.3 in extension and bending (beams of E / 1.3, torsion kept)
    differs from it far beyond the noise, and not at all once the calibration is refit; a softer
    torsion (which the calibration does not scale) stays."""
    P, W = rows
    given = tr.nominal()
    d = tr.variant(given, actuator={**given["actuator"], "stiffness": 0.8 * given["actuator"]["stiffness"]})
    for key, dims in (("foot", tr.FOOT), ("leg", tr.LEG)):
        C = 1.3 * tr.rect_beam_compliance(*dims)  # E and G / 1.3: every term, shear included ...
        C[3, 3] /= 1.3  # ... but torsion
        d[key] = tr.inline(C)
    raw, cal = tr.signature_chi2(given, tr.Truth(d), P, W)
    assert raw > 1e3 and cal < 1e-6 * raw, (raw, cal)
    raw_t, cal_t = tr.signature_chi2(given, tr.Truth(tr.variant(given, leg=tr.inline(
        tr.rect_beam_compliance(*tr.LEG, soft={"torsion": 1.05})))), P, W)
    assert cal_t > 0.1 * raw_t > 10.0


def test_nonlinear_truth_equals_linear_at_small_loads(rows):
    """vjm.stiffness.nonlinear on the rich model -> C w as the load goes to zero; visible at full load."""
    P, W = rows
    lin, nl = tr.Truth(rich_model()), tr.Truth(rich_model(), nonlinear=True)

    def rel(s):
        a, b = tr.deflections(lin, P, s * W), tr.deflections(nl, P, s * W)
        return np.max(np.abs(a - b) / np.abs(a).max(axis=0))

    r2, r3 = rel(1e-2), rel(1e-3)
    assert r3 < 1e-4
    assert 0.05 < r3 / r2 < 0.2  # the difference is the quadratic term: 10x less load, 10x less relative
    a, b = tr.deflections(lin, P, W), tr.deflections(nl, P, W)
    assert np.max(np.abs(a - b)[:, :3]) > 1e-4  # > 0.1 um: geometric nonlinearity at 100 N


def test_inline_foot_equals_beam_form(rows):
    """The foot written out here (Timoshenko, couplings) = vjm's beam: entry of the model file."""
    P, _ = rows
    beam = tr.build(tr.variant(tr.nominal(), foot=BRACKET))
    mine = tr.build(tr.variant(tr.nominal(), foot=tr.inline(tr.rect_beam_compliance(90, 40, 16))))
    # 1e-9: the torsion series is summed to 100 terms here, to 50 in linkfea.beam.closed_form
    np.testing.assert_allclose(mine.foot.compliance, beam.foot.compliance, rtol=1e-9, atol=1e-20)
    np.testing.assert_allclose(mine.stiffness_map(P).C, beam.stiffness_map(P).C, rtol=1e-9, atol=1e-18)
    C = tr.rect_beam_compliance(90, 40, 16)
    assert C[1, 5] > 0 and C[2, 4] < 0  # eq. 14 signs, right-handed
    Cn = tr.rect_beam_compliance(90, 40, 16, twist=False)
    assert Cn[3, 3] == pytest.approx(1e-4 * C[3, 3]) and np.all(np.delete(Cn.ravel(), 21) == np.delete(C.ravel(), 21))


def test_foot_coupling_shows_except_at_isotropic_posture():
    """Zeroing the foot's c26, c35 changes the 3-PUU compliance away from Q0 (the U axes line up there)."""
    P = np.array([[0.0, 0.0, 0.0], [-73.65] * 3, [50.0, -30.0, 20.0], [100.0, -60.0, 0.0]])
    C0 = tr.build(rich_model()).stiffness_map(P).C
    C1 = tr.build(rich_model(coupling=False)).stiffness_map(P).C
    d = np.sqrt(np.einsum("nii->ni", C0))
    rel = np.max(np.abs(C1 - C0) / (d[:, :, None] * d[:, None, :]), axis=(1, 2))
    assert rel[0] < 1e-12
    assert np.all(rel[1:] > 1e-3)


def test_travel_slope_is_the_actuator_series_term(rows):
    """c(q) = c0 + s q adds exactly sum_i s q_i a_i a_i^T, a_i = J^-1 e_i (stress-free actuator motion)."""
    P, _ = rows
    C0 = tr.build(rich_model(slope=0.0)).stiffness_map(P).C
    C1 = tr.build(rich_model()).stiffness_map(P).C
    A = np.linalg.inv(tr.actuator_jacobian(P, L))
    q = tr.actuator_coordinates(P, L)
    dC = np.zeros_like(C0)
    dC[:, :3, :3] = np.einsum("ni,nji,nki->njk", SLOPE * q, A, A)
    np.testing.assert_allclose(C1 - C0, dC, atol=1e-9 * np.abs(C0).max())
    assert np.abs(dC).max() > 1e-2 * np.abs(C0[:, :3, :3]).max()


def test_backlash_is_odd_and_slips_each_actuator_by_b(rows):
    P, W = rows
    b = 5e-3
    t = tr.Truth(tr.nominal(), backlash=b)
    bw = tr.backlash_twist(t, P, W)
    np.testing.assert_allclose(tr.backlash_twist(t, P, -W), -bw, atol=1e-15)
    assert np.all(bw[:, 3:] == 0.0)
    slip = np.einsum("nij,nj->ni", tr.actuator_jacobian(P, L), bw[:, :3])  # actuator motion J dp
    has_force = np.linalg.norm(W[:, :3], axis=1) > 0
    np.testing.assert_allclose(np.abs(slip[has_force]), b, rtol=1e-9)
    tau = tr.actuator_forces(P, W, L)
    np.testing.assert_array_equal(np.sign(slip[has_force]), np.sign(tau[has_force]))
    assert np.all(np.abs(bw[~has_force]) == 0.0)  # pure moments: no actuator force, no slip
    assert np.all(np.einsum("ni,ni->n", W, bw) >= 0.0)  # the load does positive work on the slip
    # the total deflection is the elastic one plus the slip
    np.testing.assert_allclose(tr.deflections(t, P, W) - tr.deflections(tr.Truth(tr.nominal()), P, W), bw, atol=1e-14)


def test_joint_backlash_is_odd_linear_and_does_work_on_the_load(rows):
    """The U joints' clearance from two nonlinear equilibria: odd in the load (every moment
    changes sign), proportional to b (finite rotations add an even term ~5 b relative: 1e-3
    allows 10x that at b = 2e-5), never
    doing negative work, and the only change to the deflections."""
    P, W = rows[0][:48], rows[1][:48]
    b = 2e-5
    t = tr.Truth(tr.nominal(), joint_backlash=b)
    jw = tr.joint_slip_twist(t, P, W)
    assert np.abs(jw[:, 3:]).max() > 1e-5  # rad: the legs' tilts turn the platform
    np.testing.assert_allclose(tr.joint_slip_twist(t, P, -W), -jw, atol=1e-3 * np.abs(jw).max())
    half = tr.joint_slip_twist(tr.Truth(tr.nominal(), joint_backlash=b / 2), P, W)
    np.testing.assert_allclose(2 * half, jw, atol=1e-3 * np.abs(jw).max())
    assert np.all(np.einsum("ni,ni->n", W, jw) > 0.0)
    np.testing.assert_allclose(tr.deflections(t, P, W) - tr.deflections(tr.Truth(tr.nominal()), P, W), jw,
                               atol=1e-14)


def test_weight_is_the_even_part(rows):
    """t(w) + t(-w) = 2 C(p) (0, 0, -m g) for the linear truth; the weight's own work is positive."""
    P, W = rows
    t = tr.Truth(rich_model(), weight=20.0)
    even = 0.5 * (tr.deflections(t, P, W) + tr.deflections(t, P, -W))
    C = tr.build(rich_model()).stiffness_map(P).C
    g = np.array([0.0, 0.0, -20.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(even, C @ g, atol=1e-12)
    assert np.all((C @ g)[:, 2] < 0)  # sags downwards
    # the weight rides with the load through the nonlinear solve too
    tn = tr.Truth(rich_model(), nonlinear=True, weight=20.0)
    np.testing.assert_allclose(tr.deflections(tn, P, 1e-3 * W), tr.deflections(t, P, 1e-3 * W),
                               atol=1e-2 * np.abs(C @ g).max())  # 20 N: nonlinear by ~0.1%


def test_out_of_library_terms(rows):
    P, W = rows
    d = tr.nominal()
    c = tr.Truth(d, contact=1e-3)
    ct = tr.contact_twist(c, W)
    np.testing.assert_allclose(tr.contact_twist(c, 8 * W), 4 * ct, rtol=1e-12)  # |F|^(2/3)
    F = W[:, :3]
    assert np.all(np.einsum("ni,ni->n", ct[:, :3], F) >= 0) and np.all(ct[:, 3:] == 0)
    np.testing.assert_allclose(np.linalg.norm(ct[:, :3], axis=1), 1e-3 * np.linalg.norm(F, axis=1) ** (2 / 3))
    h = tr.Truth(d, hysteresis=0.05)
    base = tr.deflections(tr.Truth(d), P, W)
    extra = tr.deflections(h, P, W) - base
    first = np.r_[True, np.any(P[1:] != P[:-1], axis=1)]
    assert np.all(extra[first] == 0.0)
    np.testing.assert_allclose(extra[~first], 0.05 * base[np.flatnonzero(~first) - 1], atol=1e-15)


def test_measurements_csv_and_noise(tmp_path, rows):
    P, W = rows
    t = tr.Truth(tr.nominal())
    m = tr.measure(t, P, W, seed=5)
    path = m.write(tmp_path / "m.csv")
    back = read_csv(path)  # the README's format, read by vjm diagnose's own reader
    np.testing.assert_array_equal(back.P, P)
    np.testing.assert_array_equal(back.W, W)
    np.testing.assert_array_equal(back.T, m.T)
    assert np.all(back.sigma_t == 1e-3) and np.all(back.sigma_r == 1e-5)
    z = (m.T - tr.deflections(t, P, W)) / np.r_[[1e-3] * 3, [1e-5] * 3]
    n = z.size  # chi-square of the normalized noise within +-5 sd of its mean
    assert abs(np.sum(z**2) - n) < 5 * np.sqrt(2 * n)
    # unknown sigmas: no sigma columns, each row repeated in a row, rotations blank
    u = tr.measure(t, P, W, seed=6, sigma_r=None, known_sigmas=False, repeats=3)
    back = read_csv(u.write(tmp_path / "u.csv"))
    assert back.sigma_t is None and back.sigma_r is None and back.n == 3 * len(P)
    assert np.all(np.isnan(back.T[:, 3:]))
    np.testing.assert_array_equal(back.P[0::3], back.P[2::3])
    assert np.all(back.T[0::3, :3] != back.T[1::3, :3])
    # known translation sigma, rotations not measured: no sigma_r column
    back = read_csv(tr.measure(t, P, W, seed=7, sigma_r=None).write(tmp_path / "t.csv"))
    assert np.all(back.sigma_t == 1e-3) and back.sigma_r is None and np.all(np.isnan(back.T[:, 3:]))
    Pr, Wr = tr.read_rows(path)
    np.testing.assert_array_equal(Pr, P)
    np.testing.assert_array_equal(Wr, W)


def test_soft_modes_scale_one_rigidity():
    C, E, nu = tr.rect_beam_compliance(50, 60, 10), 70_000.0, 0.33
    S = tr.rect_beam_compliance(50, 60, 10, soft={"bending_y": 2.0})
    shear = 50 / (E / (2 * (1 + nu)) * 10 * (1 + nu) / (12 + 11 * nu) * 600)
    assert S[4, 4] == pytest.approx(2 * C[4, 4]) and S[2, 4] == pytest.approx(2 * C[2, 4])
    assert S[2, 2] - shear == pytest.approx(2 * (C[2, 2] - shear))
    keep = np.ones((6, 6), bool)
    keep[[2, 2, 4, 4], [2, 4, 2, 4]] = False
    np.testing.assert_array_equal(S[keep], C[keep])
    T = tr.rect_beam_compliance(50, 60, 10, soft={"torsion": 1.5})
    assert T[3, 3] == pytest.approx(1.5 * C[3, 3])


@pytest.mark.parametrize("name", sorted(n for n, h in tr.LIBRARY.items() if h.seen))
def test_hidden_library_effects_show_above_noise(name):
    """Each effect hidden at its test size moves the data (the acceptance tests' design) beyond the noise."""
    P, W = tr.acceptance_rows(name)  # the 3-PUU's: 24 postures x 12 loads, seed 11
    given, truth = tr.hide(name)
    d = tr.deflections(truth, P, W) - tr.deflections(tr.Truth(given), P, W)
    chi2 = np.sum((d[:, :3] / 1e-3) ** 2) + np.sum((d[:, 3:] / 1e-5) ** 2)
    assert chi2 > 100.0  # 288 rows, 1 um and 10 urad
    with pytest.raises(ValueError):
        tr.hide("foot_compliance", "foot_bending_coupling")  # different model files given
    with pytest.raises(ValueError):
        tr.hide("foot_torsion", "foot_bending_coupling")  # both change the true foot
    given, truth = tr.hide("foot_compliance", "clearance")
    assert given["foot"] == {"rigid": True} and truth.backlash > 0 and "compliance" in truth.model["foot"]
    with pytest.raises(ValueError):
        tr.hide("bar_axial", "foot_compliance")  # the 3-PRPaR and a 3-PUU with a rigid foot
    given, truth = tr.hide("bar_axial", "gravity")  # the weight on the 3-PRPaR
    assert given == tr.MODELS["prpar"] and truth.model["architecture"] == "orthoglide-3PRPaR"
    # 210 pairs of the 21 seen effects, less the 66 that need two model files (rigid, uncoupled or
    # slender foot, prpar.yaml) or change one part twice (two foot modes, two leg or bar modes)
    assert len(tr.pairs()) == 144


def test_what_one_effect_shows_besides_the_other():
    """``on_top_chi2`` against ``signature_chi2``: with the other effect at size 0 (no other), an
    effect shows besides it exactly what it shows alone, and the empty one shows nothing; two
    extension-torsion couplings of the 3-PUU, foot and leg, are one signature (each ~0 besides the
    other), the joint springs and the foot's coupling are not."""
    P, W = tr.design(8, 6, seed=3)
    given, truth = tr.hide("gravity")
    alone = tr.signature_chi2(given, truth, P, W)[1]
    got = tr.on_top_chi2(["gravity", ("clearance", 0.0)], P, W)
    assert got["gravity"] == pytest.approx(alone, rel=1e-4) and alone > 100
    assert got["clearance"] < 1e-6 * alone
    ext = tr.on_top_chi2(["foot_extension_torsion", "leg_extension_torsion"], P, W)
    springs = tr.on_top_chi2(["passive_joint_compliance", "foot_extension_torsion"], P, W)
    assert max(ext.values()) < 1.0 and min(springs.values()) > 30.0


def test_report_reading_accepts_groups_and_nothing_else():
    rep = {"named_effects": ["leg_torsion", "gravity"], "confounded": [["passive_joint_compliance", "leg_torsion"]]}
    assert tr.names_exactly(rep, ["passive_joint_compliance", "gravity"])  # "leg torsion or joint springs"
    assert tr.names_exactly(rep, ["leg_torsion", "gravity"])
    assert not tr.names_exactly(rep, ["foot_torsion", "gravity"])  # leg_torsion does not stand for it
    assert not tr.names_exactly(rep, ["gravity"])  # one effect too many named
    assert not tr.names_exactly({"named_effects": ["gravity"], "confounded": []}, ["gravity", "clearance"])
    # an explanation the report offers besides the named one (within Occam's window) counts as well
    alt = {**rep, "alternatives": [{"named_effects": ["foot_torsion", "gravity"], "delta_bic": 1.0}]}
    assert tr.names_exactly(alt, ["foot_torsion", "gravity"])
    assert not tr.names_exactly(alt, ["foot_torsion"])
    # at group level one named effect may stand for a group holding both hidden ones, no more
    grp = {"named_effects": ["leg_torsion"], "confounded": [["passive_joint_compliance", "leg_torsion"]]}
    assert not tr.names_exactly(grp, ["passive_joint_compliance", "leg_torsion"])
    assert tr.names_at_group_level(grp, ["passive_joint_compliance", "leg_torsion"])
    assert not tr.names_at_group_level(grp, ["passive_joint_compliance", "gravity"])
    assert not tr.names_at_group_level(rep, ["leg_torsion"])  # gravity named besides
    assert not tr.names_at_group_level({"named_effects": [], "confounded": []}, ["gravity"])
