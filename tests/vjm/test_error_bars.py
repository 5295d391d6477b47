"""Standard deviations that account for what the model misses (vjm.stats.uncertainty): the linearised
delete-one-block jackknife against refits and against the spread of correlated data, the lack-of-fit scaling
against its closed form, the blocks, and the calibration's reported standard deviations against pinocchio's
truth (tests/truth_serial.py)."""
import os
import warnings

import numpy as np
import pytest

from vjm.stats.uncertainty import jackknife_std, parameter_std, pose_blocks, residual_blocks

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(__file__)))
Z95 = 1.959963984540054


def _clustered(rng, clusters=16, size=25):
    """A straight line y = a + b x whose x and errors share a part per cluster (correlated residuals)."""
    c = np.repeat(np.arange(clusters), size)
    x = rng.normal(size=clusters)[c] + 0.3 * rng.normal(size=c.size)
    e = rng.normal(size=clusters)[c] + 0.3 * rng.normal(size=c.size)
    J = np.column_stack([np.ones_like(x), x])
    return J, 1.0 + 2.0 * x + e, [np.flatnonzero(c == k) for k in range(clusters)]


def test_linearised_jackknife_is_the_refitted_one_on_a_linear_model():
    J, y, blocks = _clustered(np.random.default_rng(0))
    J = J * np.array([1.0, 1e-6])   # columns of very different scales, as the calibration's
    beta = np.linalg.lstsq(J, y, rcond=None)[0]
    r = J @ beta - y
    d = np.array([np.linalg.lstsq(np.delete(J, b, 0), np.delete(y, b), rcond=None)[0] for b in blocks])
    G = len(blocks)
    refit = np.sqrt((G - 1) / G * np.sum((d - d.mean(axis=0)) ** 2, axis=0))
    assert np.allclose(jackknife_std(J, r, blocks), refit, rtol=1e-8)


def test_jackknife_covers_correlated_errors_where_the_formal_one_does_not():
    rng = np.random.default_rng(1)
    hit = {"formal": 0, "std": 0}
    for _ in range(300):
        J, y, blocks = _clustered(rng)
        beta = np.linalg.lstsq(J, y, rcond=None)[0]
        u = parameter_std(J, J @ beta - y, [(blocks, "clusters")])
        hit["formal"] += abs(beta[1] - 2.0) <= Z95 * u.formal[1]
        hit["std"] += abs(beta[1] - 2.0) <= Z95 * u.std[1]
    assert hit["formal"] < 0.6 * 300    # errors shared within a cluster: the formal interval far too narrow
    assert hit["std"] >= 0.85 * 300     # 16 clusters: under 95 % with the normal quantile (90 % here)


def test_stated_sigmas_scaled_by_the_lack_of_fit():
    rng = np.random.default_rng(2)
    x = rng.uniform(-1, 1, 200)
    J = np.column_stack([np.ones_like(x), x])
    sigma = np.full(200, 0.1)
    bare = 0.1 * np.sqrt(np.diag(np.linalg.inv(J.T @ J)))   # the stated sigmas' closed form
    for noise, scale in ((0.01, 1.0), (0.5, None)):   # residuals below the sigmas: no narrower than them
        r = noise * rng.normal(size=200)
        r -= J @ np.linalg.lstsq(J, r, rcond=None)[0]   # a least-squares optimum's residuals
        u = parameter_std(J, r, [], sigma)
        want = scale if scale is not None else np.sqrt(np.sum((r / 0.1) ** 2) / 198)
        assert u.scale == pytest.approx(want, rel=1e-12)
        assert np.allclose(u.formal, bare * want, rtol=1e-10) and np.array_equal(u.std, u.formal)
    u = parameter_std(J, r, [])   # no sigmas: s^2 (J^T J)^-1
    assert np.allclose(u.formal, np.sqrt(np.diag(np.linalg.inv(J.T @ J)) * (r @ r) / 198), rtol=1e-10)


def test_blocks_partition_the_rows_into_neighbourhoods():
    gx, gy = np.meshgrid(np.arange(16.0), np.arange(16.0) * 100)   # a grid, one column 100 times the other's units
    x = np.column_stack([gx.ravel(), gy.ravel()])
    (near, what), (order, _) = pose_blocks(x, np.zeros(len(x)))
    assert len(near) == 16 == len(order) and "neighbouring" in what
    for blocks in (near, order):
        assert np.array_equal(np.sort(np.concatenate(blocks)), np.arange(len(x)))
    # squares of 4 x 4 poses: no block's box holds another block's point
    assert all(len(b) == 16 and np.ptp(x[b, 0]) == 3 and np.ptp(x[b, 1]) == 300 for b in near)
    boxes = [(x[b].min(axis=0), x[b].max(axis=0)) for b in near]
    for i, b in enumerate(near):
        for j, (lo, hi) in enumerate(boxes):
            assert i == j or not np.any(np.all((x[b] >= lo) & (x[b] <= hi), axis=1))
    groups = np.repeat([f"g{k}" for k in range(20)], 5)
    [(blocks, what)] = pose_blocks(np.zeros((100, 2)), groups)
    assert len(blocks) == 20 and what == "20 registration groups"
    r = residual_blocks([np.array([1])], 4, k=2)
    assert sorted(r[0].tolist()) == [3, 4, 5, 15, 16, 17]


def test_calibration_reports_error_bars_that_cover_the_truth():
    truth = pytest.importorskip("truth_serial")
    import vjm
    from vjm.calibration.engine import calibrate
    from vjm.calibration.poses import AbsolutePoses

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = vjm.load_model(os.path.join(ROOT, "data", "robots", "ur10", "ur10.urdf"))   # no nominal springs
    c = 4e-6   # rad/(N m)
    v, s = [], []
    for seed in range(10):
        rng = np.random.default_rng(seed)
        q = rng.uniform(-np.pi, np.pi, (80, 6))
        q[:, 1] = rng.uniform(-np.pi, 0.0, 80)
        h = truth.Hidden(compliance={"shoulder_lift_joint": c}, marker=np.array([10.0, -20.0, 110.0]), sigma=0.01)
        pts = truth.measure(os.path.join(ROOT, "data", "robots", "ur10", "ur10.urdf"), "tool0", model.q_names, q,
                            h, rng)
        data = AbsolutePoses(tuple(model.q_names), q, {"tool0": pts}, group=np.full(80, "A", dtype=object))
        cal = calibrate(model, data, "tool0", effects=("compliance",))
        v.append(cal.values["shoulder_lift_joint.compliance"] * 1000)
        s.append(cal.std["shoulder_lift_joint.compliance"] * 1000)
    assert "jackknife over" in cal.std_method and "neighbouring poses" in cal.std_method
    from vjm.calibration import report as cr
    from vjm.calibration.diagnosis import pose_report
    from vjm.discrepancy.summary import pose_text

    rep = pose_report(cr.report(cal, cr.Options("tool0", ("compliance",)), "ur10.urdf", data, [], 0.0), cal, data,
                      1e-3)
    assert f"Standard deviations: {cal.std_method}." in pose_text(rep) and rep["std_method"] == cal.std_method
    v, s = np.array(v), np.array(s)
    assert np.sum(np.abs(v - c) <= Z95 * s) >= 8
    # honest, not wide: the mean reported std within a factor 1.6 of the spread over the seeds (10 seeds: the
    # spread itself is known to about 25 %)
    assert 1 / 1.6 < np.mean(s) / np.std(v, ddof=1) < 1.6
