"""The physical domain of the calibration's parameters and the practical threshold of an effect's gain
(:mod:`vjm.stats.staged`, :mod:`vjm.effects.absolute`): the bounded fit against scipy's non-negative least
squares, a stage that fits only below its bound against the textbook least squares, a significant but
negligible stage against held-out errors refitted fold by fold, the held-out error of one Gauss-Newton step
against the refit, and the payload's bound from the model file's rated load."""
import numpy as np
import pytest
from nested import linear
from scipy.optimize import nnls

from vjm.effects import absolute
from vjm.stats.fit import interleaved_folds
from vjm.stats.staged import Practical, fold_errors, least_squares_fit, select_stages

N = 400
T = np.linspace(-1.0, 1.0, N)


def noise(seed, n=N):
    return np.random.default_rng(seed).standard_normal(n)


def test_the_bounded_fit_is_the_non_negative_least_squares():
    X = np.column_stack([np.ones(N), T, T ** 2, np.sin(3 * T)])
    y = X @ np.array([1.0, -0.5, 0.3, -0.2]) + 0.05 * noise(1)
    x, _, rss = least_squares_fit(lambda b: X @ b - y, lambda b: X, np.full(4, 0.1), (np.zeros(4), np.full(4, np.inf)))
    ref, res = nnls(X, y)
    assert x == pytest.approx(ref, abs=1e-7)
    assert rss == pytest.approx(res ** 2, rel=1e-9)


def test_a_stage_that_fits_only_below_its_bound_stands_in_and_is_not_named():
    X = np.column_stack([np.ones(N), T ** 3, np.cos(4 * T)])
    y = 1.0 - 0.4 * T ** 3 + 0.3 * np.cos(4 * T) + 0.02 * noise(2)   # "a" wants -0.4, "b" +0.3
    nf = linear(X, y, ["nuis", "a", "b"], lower=[-np.inf, 0.0, 0.0])
    stages, best, _ = select_stages(nf, ["a", "b"], 1e-3, 1e-6)
    a, b = stages[1], stages[2]
    assert not a.kept and a.category == "stands_in" and a.note.startswith("stands in for something else")
    ols = np.linalg.lstsq(X[:, :2], y, rcond=None)[0]   # the textbook fit of the stage a wanted
    assert a.wanted[0]["parameter"] == "c1" and a.wanted[0]["value"] == pytest.approx(ols[1], rel=1e-6)
    assert a.wanted[0]["value"] < -2 * a.wanted[0]["std"]
    assert b.kept and best.idx == [0, 2] and best.x[1] > 0


def test_a_significant_but_negligible_stage_is_not_named_and_its_gain_is_the_held_out_drop():
    n = 100_000
    t = np.linspace(-1.0, 1.0, n)
    X = np.column_stack([np.ones(n), np.sin(5 * t)])
    y = 1.0 + 0.17 * np.sin(5 * t) + noise(3, n)    # F test passes, the held-out RMS drops by ~0.7 %
    stages, best, _ = select_stages(linear(X, y, ["nuis", "a"], folds=5), ["a"], 1e-3, 1e-6)
    a = stages[1]
    assert a.p_value < 1e-6 and not a.kept and a.category == "negligible"

    def cv_rms(cols):
        sq = 0.0
        for test in interleaved_folds(n, 5):
            b = np.linalg.lstsq(X[~test][:, cols], y[~test], rcond=None)[0]
            sq += float(np.sum((X[test][:, cols] @ b - y[test]) ** 2))
        return np.sqrt(sq / n)

    before, after = cv_rms([0]), cv_rms([0, 1])
    assert a.gain == pytest.approx(before - after, rel=1e-6) and 0.005 * before < a.gain < 0.01 * before
    assert a.threshold == pytest.approx(0.01 * before, rel=1e-9)
    # a threshold the user sets below the gain: named (the gain exceeds its fold-to-fold standard error)
    named, _, _ = select_stages(linear(X, y, ["nuis", "a"], folds=5, practical=Practical(0.0)), ["a"], 1e-3, 1e-6)
    assert named[1].kept and named[1].gain > named[1].gain_se
    # a gain on the fitted rows below half the threshold: not worth the folds, that gain reported
    small = 1.0 + 0.03 * np.sin(5 * t) + noise(3, n)
    st, _, _ = select_stages(linear(X, small, ["nuis", "a"], folds=5), ["a"], 1e-3, 1e-6)
    rss = [float(np.sum((small - X[:, c] @ np.linalg.lstsq(X[:, c], small, rcond=None)[0]) ** 2)) for c in ([0], [0, 1])]
    assert st[1].p_value < 1e-6 and st[1].category == "negligible" and np.isnan(st[1].cv_rms)
    assert st[1].gain == pytest.approx(np.sqrt(rss[0] / n) - np.sqrt(rss[1] / n), rel=1e-6)


def test_the_held_out_error_of_one_gauss_newton_step_is_the_refit():
    """The engine's held-out folds: one step from the fit on all rows against a fit on each fold's others
    (the UR10's series A, every 30th row); the folds blocks of neighbouring rows of each group."""
    from vjm.calibration import engine
    from vjm.calibration.poses import read_column_map, read_poses
    from vjm.modelio.read import load_model

    d = "data/realdata/ur10_ipa"
    m = load_model("data/robots/ur10/ur10.yaml")
    data = read_poses(f"{d}/Series_A/measurements_grid.csv", read_column_map(f"{d}/columns.yaml"), m.q_names)
    data = data.with_group("A").subset(np.arange(0, data.n, 30))
    eff = ("geometry", "compliance")
    cal = engine.calibrate(m, data, "tool0", effects=eff)
    frames, ps = engine._initial(m, data, ("tool0",), None)
    measured = (("tool0", ps[0]),)
    prob = engine._problems(m, data, measured, frames)
    meas = engine._measurements(data, measured)
    full = engine._layout(m, measured, prob.groups, eff)
    idx = [full.names.index(k) for k in cal.values]
    x = np.array(list(cal.values.values()))
    lay = full.pick(idx)

    def held(test, xx):
        r = engine._predict(engine._rows(prob, test), lay, xx) - meas[test]
        return float(np.sum(r * r)), len(r)

    refit = fold_errors(lambda tr: engine.fit(engine._rows(prob, tr), lay, meas[tr], x)[0], held,
                        engine.block_folds(np.zeros(data.n), 5))
    step = engine._held_out(prob, full, meas, 5)(idx, x)
    masks = engine.block_folds(np.array([0, 0, 1, 0, 1, 1, 1]), 2)
    assert [list(np.flatnonzero(m)) for m in masks] == [[0, 1, 2, 4], [3, 5, 6]]
    assert step[:, 1] == pytest.approx(refit[:, 1])
    # 4e-4 on 400 rows (the folds' fits differ more than on the 11,911): far below a named effect's gain, 1 %
    assert step[:, 0] == pytest.approx(refit[:, 0], rel=1e-3)


def test_the_payload_is_bounded_by_the_rated_load_and_the_compliances_by_zero(tmp_path):
    import shutil

    from vjm.errors import VjmError
    from vjm.modelio.read import load_model

    shutil.copy("data/robots/ur10/ur10.urdf", tmp_path / "ur10.urdf")
    text = open("data/robots/ur10/ur10.yaml").read()
    (tmp_path / "r.yaml").write_text(text + "\npayload_limit: 10\n")
    m = load_model(tmp_path / "r.yaml")
    assert m.payload_limit == 10.0
    names = ["payload.mass", "elbow_joint.compliance", "elbow_joint.lateral", "elbow_joint.backlash",
             "elbow_joint.offset", "reg[A].tx"]
    lo, hi, op = absolute.domain(names, m, {"payload.mass": 4.0, "elbow_joint.compliance": 2e-9})
    assert list(lo) == [-4.0, -2e-9, 0.0, 0.0, -np.inf, -np.inf]
    assert list(hi) == [6.0, np.inf, np.inf, np.inf, np.inf, np.inf]
    assert not op.any()
    (tmp_path / "bad.yaml").write_text(text + "\npayload_limit: -5\n")
    with pytest.raises(VjmError, match="payload_limit must be > 0"):
        load_model(tmp_path / "bad.yaml")


def test_a_stage_whose_gauss_newton_step_buys_little_is_not_fitted():
    """The pre-screen (:func:`vjm.stats.staged.linear_gain`): on a linear model one Gauss-Newton step from the
    fit before a stage is its fit, so the skipped stage's RSS is that of the full fit; a stage buying less
    than half the threshold is recorded unfitted, one buying more (or any, the threshold 0) is fitted."""
    import dataclasses

    from vjm.stats.staged import forward_stages

    X = np.column_stack([np.ones(N), T, T ** 2, np.sin(3 * T)])
    y = 0.5 + 2.0 * T + 1e-3 * T ** 2 + 0.3 * np.sin(3 * T) + 0.01 * noise(7)
    kinds = ("nuis", "a", "small", "big")
    nf = linear(X, y, kinds, practical=Practical(0.002))
    calls = []

    def fit(idx, x0, bounds=None):
        calls.append(list(idx))
        return least_squares_fit(lambda b: X[:, idx] @ b - y, lambda b: X[:, idx], x0, bounds)

    nf = dataclasses.replace(nf, residual=lambda x: X @ x - y, fit=fit)
    stages, _, _ = forward_stages(nf, ("a", "small", "big"), 1e-3, 1e-6)
    by = {s.name: s for s in stages}
    exact = least_squares_fit(lambda b: X[:, :3] @ b - y, lambda b: X[:, :3], np.zeros(3))[2]
    assert [0, 1, 2] not in calls and not by["small"].kept   # not fitted
    assert by["small"].rss == pytest.approx(exact, rel=1e-9) and by["small"].gain < 0.5 * 0.002
    assert by["big"].kept and [0, 1, 3] in calls
    calls.clear()
    forward_stages(dataclasses.replace(nf, practical=Practical(0.0)), ("a", "small", "big"), 1e-3, 1e-6)
    assert [0, 1, 2] in calls
