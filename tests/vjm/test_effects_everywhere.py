"""Every registered effect works in the three commands that read effects: ``simulate``, ``diagnose``
(its predictor) and ``path`` (the ``model_updated.yaml`` that carries it).

For each effect of the library, on a model where it applies, at a size that shows:
* ``vjm simulate`` with the effect hidden gives, noise-free, what ``vjm diagnose``'s predictor says
  the effect adds (calibration at its null);
* the model file ``diagnose`` writes for it (:meth:`Effect.save`, then :func:`vjm.save_model`) reads
  back, and ``vjm path``'s nonlinear deflection with it is that prediction plus the loads' own
  nonlinearity (measured on the nominal model), to a small part of the effect's change;
* where an independent computation exists, the path's deflection equals it: the nonlinear equilibrium
  (:func:`vjm.stiffness.nonlinear.deflection_map`, the reference solver, not the path's kernel) of
  the modified model for a model-changing effect, under the process load plus the weight for
  ``gravity``, ``C w + s (nonlinear - C w)`` for ``geometric_nonlinearity``.

An effect written the documented way (an ``extra`` only) is accepted by ``vjm path`` too, and adds
its twist there.
"""
import numpy as np
import pytest

import vjm
from vjm import effects as fx
from vjm.discrepancy.predict import Predictor
from vjm.discrepancy.simulate import simulate
from vjm.effects.context import Context, unique_postures
from vjm.model.links import LinkSpring
from vjm.stats.terms import Term
from vjm.stiffness.nonlinear import deflection_map
from vjm.toolpath.deflect import tcp_deflection

PUU = vjm.load_model("data/orthoglide/puu.yaml")
RIGID_FOOT = PUU.replace(foot=LinkSpring.rigid())
PRPAR = vjm.load_model("data/orthoglide/prpar.yaml")
#: the built-in effects (a test may register more: they are not the library's)
BUILT_IN = sorted(n for n, e in fx.REGISTRY.items() if type(e).__module__.startswith("vjm.effects"))

#: a size that shows (a change of a few percent of the deflections at least)
SIZES = {"factor": 3.0, "kappa": 0.5, "compliance": 1e-7, "slope": 0.003, "weight": 50.0, "backlash": 0.003,
         "scale": 3.0}
FOOT = {"axial": 5e-5, "bending_y": 5e-4, "bending_z": 5e-4, "torsion": 1e-7, "length": 80.0}
SPECIAL = {"passive_clearance": {"backlash": 1e-4}, "foot_compliance": FOOT}
#: link modes the passive joints of their test machine release: no change at the end-effector, to first order
SILENT = {"bar_bending_y", "leg_bending_y", "leg_bending_coupling"}

_rng = np.random.default_rng(4)
P = _rng.uniform(-40.0, 60.0, (8, 3))
#: small loads, so that the load's own nonlinearity is well below the effects' changes (it grows as the
#: square of the load); a weight or a slip does not shrink with them
W = np.hstack([_rng.normal(0.0, 5.0, (8, 3)), _rng.normal(0.0, 150.0, (8, 3))])


def _model_for(eff):
    for m in (PUU, RIGID_FOOT, PRPAR):
        if eff.applies_to(m, "deflection") is None:
            return m
    raise AssertionError(f"{eff.name} applies to none of the test machines")


def _values(eff, model):
    vals = SPECIAL.get(eff.name) or {p.name: SIZES[p.name] for p in eff.param_specs(model)
                                     if p.name not in eff.optional}
    return vals, np.array([float(vals.get(p.name, p.null)) for p in eff.param_specs(model)])


def _predicted(model, eff, theta):
    """What diagnose's predictor says the data are, nominal and with the effect."""
    U, idx = unique_postures(P)
    ctx = Context(model, U, idx, W)
    terms = {eff.name: Term(eff.name, eff.param_specs(model, ctx), eff.description)}
    pred = Predictor(model, ctx, terms)
    null = np.array([p.null for p in eff.param_specs(model, ctx)], float)
    return pred.twists([eff.name], null), pred.twists([eff.name], theta)


def _path(model):
    return tcp_deflection(model, P, W, [0.0, 0.0, 0.0], "nonlinear")


@pytest.mark.parametrize("name", BUILT_IN)
def test_every_effect_in_simulate_diagnose_and_path(name, tmp_path):
    eff = fx.get(name)
    model = _model_for(eff)
    vals, theta = _values(eff, model)
    nominal, predicted = _predicted(model, eff, theta)
    change = predicted - nominal
    # some link modes do not show at the end-effector of some machines (the 3-PRPaR's pivots release a
    # bar's bending about y): there the path must not move either, to first order
    size = float(np.abs(change[:, :3]).max())
    assert (size < 1e-12) == (name in SILENT), f"{name} at {vals} moves the prediction by {size:.2g} mm"

    # simulate: the hidden effect, noise-free, is what the predictor says
    sim = simulate(model, [(name, vals)], P, W, noise_t=0.0, noise_r=0.0, seed=0)
    assert np.allclose(sim.T, predicted, rtol=0, atol=1e-9 * np.abs(predicted).max())

    # path: the model file diagnose writes for the effect, read back
    vjm.save_model(eff.save(model, theta), tmp_path / "model_updated.yaml")
    updated = vjm.load_model(tmp_path / "model_updated.yaml")
    base, moved = _path(model), _path(updated)
    assert np.all(np.isfinite(moved))
    # the path is the predictor plus the loads' own nonlinearity (the predictor is linear but for
    # geometric_nonlinearity, whose prediction already holds it), to a small part of either
    lin = np.einsum("nij,nj->ni", model.stiffness_map(P).C, W)
    nl = float(np.abs(base - lin)[:, :3].max())
    expect = predicted if name == "geometric_nonlinearity" else predicted + (base - lin)
    assert np.abs(moved - expect)[:, :3].max() <= 0.02 * size + 0.05 * nl + 1e-9 * np.abs(base).max()
    if eff.kind == "model":
        truth = deflection_map(eff.apply(model, theta), P, W)
    elif name == "gravity":
        truth = deflection_map(model, P, W + np.r_[vals["weight"] * np.array([0.0, 0.0, -1.0]), np.zeros(3)])
    elif name == "geometric_nonlinearity":
        truth = lin + vals["scale"] * (deflection_map(model, P, W) - lin)
    else:
        return  # the slips: no other computation than the effect's own
    assert np.allclose(moved, truth, rtol=0, atol=1e-7 * np.abs(truth).max())


class _Drift(fx.Effect):
    """An effect written the documented way: an ``extra`` only."""

    name = "test_drift"
    description = "a constant offset of the end-effector along z"
    kind = "additive"
    data_kinds = ("deflection",)
    params = (fx.Param("dz", start=0.0, scale=1e-3, null=0.0, unit="mm"),)

    def extra(self, ctx, theta, C):
        out = np.zeros((ctx.n, 6))
        out[:, 2] = theta[0]
        return out


def test_an_effect_added_the_documented_way_works_in_path(monkeypatch, tmp_path):
    monkeypatch.setitem(fx.REGISTRY, _Drift.name, _Drift())
    eff = fx.get("test_drift")
    vjm.save_model(eff.save(PUU, np.array([0.01])), tmp_path / "model_updated.yaml")
    updated = vjm.load_model(tmp_path / "model_updated.yaml")
    assert updated.effects == {"test_drift": {"dz": 0.01}}
    moved, base = _path(updated), _path(PUU)
    expected = base.copy()
    expected[:, 2] += 0.01
    assert np.allclose(moved, expected, rtol=0, atol=1e-12)


def test_an_effect_added_the_documented_way_goes_from_diagnose_to_path(monkeypatch, tmp_path):
    """The whole way: a drift hidden in simulated data is named by vjm diagnose, written into
    model_updated.yaml, and vjm path applies it (its deflection moves by the fitted drift)."""
    from vjm.discrepancy.simulate import design_loads
    from vjm.discrepancy.workflow import diagnose

    monkeypatch.setitem(fx.REGISTRY, _Drift.name, _Drift())
    rng = np.random.default_rng(2)
    P0 = rng.uniform(-40.0, 60.0, (12, 3))
    L = design_loads("axes:100", len(P0), rng)
    Pm, Wm = np.repeat(P0, L.shape[1], axis=0), L.reshape(-1, 6)
    data = simulate(PUU, [("test_drift", {"dz": 0.01})], Pm, Wm, noise_t=1e-3, noise_r=None, seed=3)
    d = diagnose(PUU, data, effects=["test_drift", "clearance"], folds=2)
    assert d.report.named_effects == ("test_drift",)
    d.save(tmp_path / "report")
    updated = vjm.load_model(tmp_path / "report" / "model_updated.yaml")
    dz = updated.effects["test_drift"]["dz"]
    assert abs(dz - 0.01) < 1e-3  # 10 noise sigmas of drift, fitted from 72 rows
    moved, base = _path(updated), _path(updated.replace(effects={}))
    assert np.allclose(moved[:, 2] - base[:, 2], dz, rtol=0, atol=1e-12)
