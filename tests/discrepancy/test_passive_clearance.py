"""Clearance in the passive joints: the moments the joints carry and the twist of their slip.

``passive_clearance`` (vjm.effects.library) predicts, by the unit-load theorem, that a
joint slipping by ``e`` about its constrained direction moves the end-effector by
``a_s e``, where ``tau_s = a_s . w`` is the moment that joint carries under a wrench w
(``modelops.joint_spring_influence``: linear Jacobians and the bordered solve).  The
references here come from :mod:`vjm.stiffness.nonlinear`, which shares neither: it minimises the
spring energy over all joint coordinates with finite rotations, the slip imposed as the
rest value of the joint's spring (``offsets``) and the moment read off the spring's rotation.
"""
import numpy as np
import pytest

import vjm
from vjm import effects as fx
from vjm.effects import modelops as mo
from vjm.errors import VjmError
from vjm.stiffness import nonlinear

PUU = vjm.load_model("data/orthoglide/puu.yaml")
PRPAR = vjm.load_model("data/orthoglide/prpar.yaml")
RNG = np.random.default_rng(7)
P = RNG.uniform(-60.0, 100.0, (4, 3))
#: stiff passive-joint springs for the nonlinear reference (N mm/rad): the joints are ideal to ~1e-8
K_STIFF = 1e13


@pytest.mark.parametrize("model", [PUU, PRPAR], ids=["3-PUU", "3-PRPaR"])
def test_slip_twist_equals_nonlinear_equilibrium_with_imposed_slip(model):
    """A slip of 1e-7 rad imposed in one joint of one chain: the nonlinear equilibrium (energy
    minimum of the whole overconstrained machine, no load) moves the platform by ``a_s e`` to
    O(e) relative (second-order terms of finite rotations): 1e-5 allows 100x that."""
    names = mo.joint_spring_names(model)
    A = mo.joint_spring_influence(model, P)
    assert A.shape == (len(P), 3 * len(names), 6)
    stiff = model.replace(joints=vjm.model.machine.Joints(K_STIFF))
    e = 1e-7
    for ci in range(3):
        for si, name in enumerate(names):
            th = np.zeros((3, 1))
            th[ci, 0] = e
            t = nonlinear.deflection_map(stiff, P, np.zeros(6), offsets={name: th})
            ref = e * A[:, ci * len(names) + si]
            assert np.abs(t).max() > 0
            assert np.abs(t - ref).max() <= 1e-5 * np.abs(ref).max(), (ci, name)


def test_joint_moments_equal_nonlinear_spring_rotation():
    """Elastic U joints (1e7 N mm/rad): under a small wrench (0.1 N, 10 N mm) each joint's moment
    ``a_s . w`` equals its spring's stiffness times the rotation it takes in the nonlinear
    equilibrium (1e-4: the linear limit; the loads keep the cubic terms far below)."""
    k = 1e7
    model = PUU.replace(joints=vjm.model.machine.Joints(k))
    W = np.array([[0.1, -0.05, 0.08, 10.0, -6.0, 4.0]] * len(P))
    A = mo.joint_spring_influence(model, P)
    tau = np.einsum("nsj,nj->ns", A, W)
    _, info = nonlinear.deflection_map(model, P, W, return_info=True)
    names = mo.joint_spring_names(model)
    ref = np.stack([k * info["springs"][c][nm][:, 0] for c in range(3) for nm in names], axis=1)
    assert np.abs(tau - ref).max() <= 1e-4 * np.abs(ref).max()


def test_slip_does_work_along_the_load():
    """Each joint slips toward its moment, so the slip twist does non-negative work on the load."""
    from vjm.effects.context import Context

    W = RNG.normal(size=(len(P), 6)) * np.array([100, 100, 100, 5000, 5000, 5000])
    ctx = Context(PUU, P, np.arange(len(P)), W)
    t = ctx.passive_clearance_unit()
    assert np.all(np.einsum("ni,ni->n", t, W) > 0)


def test_offsets_bad_input_is_one_clear_error():
    stiff = PUU.replace(joints=vjm.model.machine.Joints(K_STIFF))
    with pytest.raises(VjmError, match="springs the model does not have"):
        nonlinear.deflection_map(stiff, P, np.zeros(6), offsets={"nope": np.zeros((3, 1))})
    with pytest.raises(VjmError, match="one row per chain"):
        nonlinear.deflection_map(stiff, P, np.zeros(6), offsets={"u1": np.zeros(1)})
    with pytest.raises(VjmError, match="rigid"):  # the ideal-joint model has no u1 spring; the foot is given
        nonlinear.deflection_map(PUU.replace(foot=vjm.LinkSpring.rigid()), P, np.zeros(6),
                                 offsets={"foot": np.zeros((3, 6))})


def test_not_a_candidate_without_constrained_joint_directions():
    """The 6-UPS hexapod's spherical and universal joints constrain no rotation a leg carries."""
    hexa = vjm.load_model("data/machines/hexapod_6ups.yaml")
    assert "no constrained directions" in fx.get("passive_clearance").applies_to(hexa, "deflection")
    assert fx.get("passive_clearance").applies_to(PUU, "deflection") is None


def test_slips_follow_the_moments_of_the_model_being_fitted():
    """A 3-PRPaR whose bars have an extension-torsion coupling (kappa 0.6) carries other moments in
    its pivots than the model given: the slip twist computed on the coupled model (as the fit does,
    with the coupling and calibration applied) equals the independent truth's two nonlinear
    equilibria (tests/truth.py: moments read off stiff pivot springs, then the slips imposed) on
    that machine, and the nominal model's slip twist does not."""
    import truth as tr

    from vjm.effects.context import Context

    given, true = tr.hide(("passive_clearance", 1e-7), "bar_extension_torsion")
    P, W = tr.design(**tr.DESIGNS["prpar"])
    P, W = P[:36], W[:36]
    ref = tr.joint_slip_twist(true, P, W)
    ctx = Context(tr.build(given), P, np.arange(len(P)), W)
    fitted = 1e-7 * ctx.passive_clearance_unit(tr.build(true.model), key="coupled")
    nominal = 1e-7 * ctx.passive_clearance_unit()
    scale = np.abs(ref).max()
    assert np.abs(fitted - ref).max() <= 1e-4 * scale
    assert np.abs(nominal - ref).max() >= 1e-2 * scale


@pytest.mark.parametrize("model, free", [(PUU, True), (PRPAR, False)], ids=["3-PUU", "3-PRPaR"])
def test_fit_reads_the_uncalibrated_moments_only_where_the_calibration_leaves_them(model, free):
    """The fit computes the slips once for every calibration it tries where the calibration does not
    change the joints' moments: on the 3-PUU (statically determinate load paths) its predictions equal,
    to round-off, those of the calibrated model (C w of the calibrated model plus the slip twist of
    that model's moments); on the 3-PRPaR (parallelograms) the calibrated model is used."""
    from vjm.discrepancy.predict import CALIBRATION, Predictor, apply_calibration, calibration_term
    from vjm.discrepancy.simulate import design_loads
    from vjm.effects.context import Context, slip_toward, unique_postures
    from vjm.stats.terms import Term

    rng = np.random.default_rng(3)
    L = design_loads("axes:100:10000", len(P), rng)
    Pn, W = np.repeat(P, L.shape[1], axis=0), L.reshape(-1, 6)
    U, idx = unique_postures(Pn)
    ctx = Context(model, U, idx, W)
    eff = fx.get("passive_clearance")
    pred = Predictor(model, ctx, {CALIBRATION: calibration_term(model),
                                  eff.name: Term(eff.name, tuple(eff.param_specs(model, ctx)))})
    for cal in ((0.8, 1.3), (1.9, 0.4)):
        theta = np.array([*cal, 3e-5])
        t = pred.twists((CALIBRATION, eff.name), theta)
        m = apply_calibration(model, np.array(cal))
        elastic = np.einsum("nij,nj->ni", m.stiffness_map(U).C[idx], W)
        slip = 3e-5 * slip_toward(mo.joint_spring_influence(m, U)[idx], W)
        assert np.abs(slip).max() > 1e-3 * np.abs(elastic).max()  # the slips are not lost in C w
        assert np.abs(t - elastic - slip).max() <= 1e-12 * np.abs(slip).max()
    assert pred._calibration_free[(eff.name, ())] is free
