"""Each effect of the library is found in data where it is hidden (issue 5).

Truth: data simulated by ``vjm.discrepancy.simulate`` from the 3-PUU model of
``data/orthoglide/puu.yaml`` with ONE hidden effect, 30 random reachable
postures x 6 axis loads of +-100 N (180 rows, translations only), Gaussian
noise of 1 um on deflections of ~36 um RMS.  The baseline handed to
``diagnose`` is that model with a rigid foot (so that ``foot_compliance``
is a candidate too); the workflow is not told the effect.  Truth values give
a 1-4 um RMS signal, a few noise sigmas.

For each effect, on one noise draw (seed 0; the same checks over more seeds, as rates:
benchmarks/bench_diagnose_repeats.py --only effects):
* exactly that effect is named;
* its fitted parameter is within 3 standard errors of the truth (the
  estimator is unbiased to first order, se from the Gauss-Newton covariance);
* reduced chi2 after <= 1.5 (expected 1 +- 0.06 for ~540 residuals);
* rms_after < rms_before.
``geometric_nonlinearity`` is hidden as the model's own nonlinear
equilibrium (scale 1): its truth is an independent Newton solve with
finite rotations, not the linear model.
"""
import numpy as np
import pytest

import vjm
from vjm import effects as fx
from vjm.discrepancy.simulate import design_loads, simulate
from vjm.discrepancy.workflow import diagnose
from vjm.model.links import LinkSpring as Link

MODEL = vjm.load_model("data/orthoglide/puu.yaml").replace(foot=Link.rigid())
_rng = np.random.default_rng(0)
_P0 = _rng.uniform(-60.0, 90.0, (30, 3))
_L = design_loads("axes:100", len(_P0), _rng)
P = np.repeat(_P0, _L.shape[1], axis=0)
W = _L.reshape(-1, 6)
NOISE = 1e-3  # mm

# effects the original library had (renamed or reshaped since): strict checks
TRUTH = {
    "leg_extension_torsion": {"kappa": 0.5},
    "foot_compliance": {"axial": 5e-5, "bending_y": 5e-4, "bending_z": 5e-4, "torsion": 1e-7, "length": 80.0},
    "passive_joint_compliance": {"compliance": 1e-7},
    "actuator_travel_stiffness": {"slope": 0.003},
    "gravity": {"weight": 10.0},
    "clearance": {"backlash": 0.002},
    "passive_clearance": {"backlash": 2e-5},
    "geometric_nonlinearity": {"scale": 1.0},
}

# per-link, per-mode effects: one seed each, on a model where they apply, loads with torques.
# Each must be named alone or in a group the report says this data cannot separate, or be
# reported not observable, in which case its true size must indeed be below the noise.
FULL = vjm.load_model("data/orthoglide/puu.yaml")
BARS = vjm.load_model("data/orthoglide/prpar.yaml")
MODES = {f"{lk}_{m}": (mdl, {"factor": f}) for lk, mdl in (("foot", FULL), ("leg", MODEL), ("bar", BARS))
         for m, f in (("axial", 3.0), ("bending_y", 3.0), ("bending_z", 3.0), ("torsion", 3.0))}
MODES.update({f"{lk}_bending_coupling": (mdl, {"kappa": 0.0}) for lk, mdl in (("foot", FULL), ("leg", MODEL), ("bar", BARS))})
MODES.update({f"{lk}_extension_torsion": (mdl, {"kappa": 0.5}) for lk, mdl in (("foot", FULL), ("bar", BARS))})
_LT = design_loads("axes:100:10000", 12, _rng)
PT = np.repeat(_P0[:12], _LT.shape[1], axis=0)
WT = _LT.reshape(-1, 6)


def test_every_registered_effect_is_tested():
    assert set(TRUTH) | set(MODES) == set(fx.REGISTRY)


def check_hidden_effect(name, seed):
    """``name`` hidden at its TRUTH size, noise draw ``seed``: named alone, fitted within 3 se, chi2 and RMS."""
    data = simulate(MODEL, [(name, TRUTH[name])], P, W, NOISE, None, seed)
    rep = diagnose(MODEL, data).report
    assert rep["named_effects"] == [name], (seed, rep["named_effects"], rep["summary"])
    assert rep["verdict"] == "explained", (seed, rep["summary"])
    for pname, truth in TRUTH[name].items():
        fit = rep["candidates"][name]["final_params"].get(pname)
        if fit is None:  # held fixed: not observable on this data
            assert pname in rep["candidates"][name].get("fixed", {}), (seed, pname)
            continue
        if name != "foot_compliance":  # a cantilever's section trades off against its length
            assert abs(fit["value"] - truth) <= 3 * fit["se"], (seed, pname, fit, truth)
    assert rep["chi2_after"] <= 1.5, (seed, rep["chi2_after"])
    assert rep["rms_after"] < rep["rms_before"], (seed, rep["rms_before"], rep["rms_after"])


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(TRUTH))
def test_hidden_effect_is_named_and_fitted(name):
    check_hidden_effect(name, seed=0)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(MODES))
def test_link_mode_effect_is_named_grouped_or_invisible(name):
    mdl, vals = MODES[name]
    data = simulate(mdl, [(name, vals)], PT, WT, NOISE, None, 0)
    # candidates: the link's own modes and couplings plus the effects they are most easily confused
    # with (keeps the CPU of 18 diagnoses small; the full library is exercised by the tests above)
    link = name.split("_")[0]
    own = [e for e in fx.REGISTRY if e.startswith(link + "_")]
    rep = diagnose(mdl, data, effects=own + ["passive_joint_compliance", "actuator_travel_stiffness", "gravity"]).report
    eff = fx.get(name)
    th = np.array([vals[p.name] for p in eff.param_specs(mdl)])
    t1 = np.einsum("nij,nj->ni", eff.apply(mdl, th).stiffness_map(PT).C, WT)
    t0 = np.einsum("nij,nj->ni", mdl.stiffness_map(PT).C, WT)
    signal = np.sqrt(np.sum((t1 - t0)[:, :3] ** 2)) / NOISE  # root chi-square of the true effect, no refit
    if name in rep["unobservable"]:
        # "not observable" checked independently: the true deflections differ from the nominal ones
        # by less than a few noise sigmas over the whole data set
        assert signal < 3.0, (name, signal)
        return
    assert rep["verdict"] in ("explained", "no_discrepancy"), (name, rep["summary"])
    grp = [g for g in rep["confounded"] if name in g]
    named_ok = rep["named_effects"] == [name] or bool(grp and rep["named_effects"]
                                                       and set(rep["named_effects"]) <= set(grp[0]))
    if rep["verdict"] == "no_discrepancy":
        # too small to detect at this noise, or absorbed by the calibration (then the report says so)
        mimic = "mimicked_by_calibration" in rep["candidates"][name]
        assert mimic or signal < 30.0, (name, signal, rep["summary"])
    else:
        assert named_ok, (name, rep["summary"])
