"""The staged selection of vjm.stats (the absolute-pose calibration's statistics) on ordinary linear least
squares, where every number has a textbook closed form computed here independently: the F test's p-value
from projections and the regularised incomplete beta function, the leave-one-out error from the hat
matrix (PRESS), the standard errors from ``s^2 (X^T X)^-1``."""
import numpy as np
import pytest
from nested import linear
from scipy.special import betainc

from vjm.stats.fit import cross_validated, f_test, interleaved_folds
from vjm.stats.staged import Nested, forward_stages, identifiable, least_squares_fit, select_stages

N = 90
T = np.linspace(-1.0, 1.0, N)


def noise(seed):
    return np.random.default_rng(seed).standard_normal(N)


def projector(X):
    return X @ np.linalg.pinv(X)


def textbook_p(y, X0, X1):
    """p-value of the F test of the nested linear models X0 within X1: the sums of squares from projections,
    the upper tail of F(q, d) as the regularised incomplete beta I_{d/(d+qF)}(d/2, q/2)."""
    n, k0, k1 = len(y), np.linalg.matrix_rank(X0), np.linalg.matrix_rank(X1)
    q, d = k1 - k0, n - k1
    extra = (projector(X1) - projector(X0)) @ y
    resid = y - projector(X1) @ y
    F = (extra @ extra / q) / (resid @ resid / d)
    return float(betainc(d / 2, q / 2, d / (d + q * F)))


def ols_rss(y, X):
    r = y - projector(X) @ y
    return float(r @ r)


@pytest.mark.parametrize("effect", [0.0, 0.02, 0.3])
def test_f_test_is_the_textbook_f_test_of_nested_linear_fits(effect):
    X1 = np.column_stack([np.ones(N), T, T ** 2, np.sin(3 * T)])
    X0 = X1[:, :2]
    y = 0.5 + T + effect * np.sin(3 * T) + 0.05 * noise(1)
    p = f_test(ols_rss(y, X0), 2, ols_rss(y, X1), 4, N)
    assert p == pytest.approx(textbook_p(y, X0, X1), rel=1e-9, abs=1e-300)
    if effect == 0.3:
        assert p < 1e-10


def test_f_test_makes_no_test_where_none_can_be_made():
    assert f_test(2.0, 3, 1.0, 3, 50) == 1.0        # nothing added
    assert f_test(2.0, 3, 0.0, 4, 50) == 1.0        # a perfect fit
    assert f_test(2.0, 3, 1.0, 4, 4) == 1.0         # no residual degree of freedom
    assert f_test(1.0, 3, 2.0, 4, 50) == 1.0        # the larger fit worse (a local minimum)


def test_least_squares_fit_gives_the_ols_estimate_and_standard_errors():
    X = np.column_stack([np.ones(N), T, 1e-6 * T ** 3])   # a column 1e6 smaller: the scaling of the covariance
    y = X @ np.array([0.3, -1.2, 4e5]) + 0.01 * noise(2)
    x, sd, rss = least_squares_fit(lambda b: X @ b - y, lambda b: X, np.zeros(3))
    b, *_ = np.linalg.lstsq(X, y, rcond=None)
    s2 = ols_rss(y, X) / (N - 3)
    assert x == pytest.approx(b, rel=1e-7)
    assert rss == pytest.approx(ols_rss(y, X), rel=1e-9)
    assert sd == pytest.approx(np.sqrt(s2 * np.diag(np.linalg.inv(X.T @ X))), rel=1e-6)


def test_leave_one_out_rms_is_press_of_the_hat_matrix():
    X = np.column_stack([np.ones(N), T, T ** 2])
    y = 1.0 + T - 0.5 * T ** 2 + 0.1 * noise(3)

    def fit(train):
        return np.linalg.lstsq(X[train], y[train], rcond=None)[0]

    def held_out(test, b):
        r = y[test] - X[test] @ b
        return float(r @ r), len(r)

    rms = cross_validated(fit, held_out, interleaved_folds(N, N))
    e = y - projector(X) @ y
    h = np.diag(projector(X))
    assert rms == pytest.approx(np.sqrt(np.mean((e / (1 - h)) ** 2)), rel=1e-9)


def test_k_fold_rms_is_that_of_an_explicit_loop_over_every_kth_row():
    X = np.column_stack([np.ones(N), np.cos(2 * T)])
    y = X @ np.array([0.2, 0.7]) + 0.1 * noise(4)
    k = 4
    masks = interleaved_folds(N, k)
    assert sorted(np.flatnonzero(masks[1])) == list(range(1, N, k))
    rms = cross_validated(lambda tr: np.linalg.lstsq(X[tr], y[tr], rcond=None)[0],
                          lambda te, b: (float(np.sum((y[te] - X[te] @ b) ** 2)), int(te.sum())), masks)
    sq = 0.0
    for f in range(k):
        test = [i for i in range(N) if i % k == f]
        train = [i for i in range(N) if i % k != f]
        b = np.linalg.solve(X[train].T @ X[train], X[train].T @ y[train])
        sq += sum((y[i] - X[i] @ b) ** 2 for i in test)
    assert rms == pytest.approx(np.sqrt(sq / N), rel=1e-9)
    assert np.isnan(cross_validated(None, None, []))


def test_stages_are_kept_by_their_f_test_and_combinations_removed():
    u, v = np.cos(3 * T), T ** 3   # u orthogonal to v beside the nuisance (even against odd)
    X = np.column_stack([np.ones(N), T, u, 2 * T - 0.5 * np.ones(N), v])
    y = 1.0 + 0.8 * v + 0.01 * noise(5)
    nf = linear(X, y, ["nuis", "nuis", "a", "b", "c"])
    stages, best, removed = forward_stages(nf, ["a", "b", "c"], 1e-3, 1e-6)
    assert [s.name for s in stages] == ["base", "a", "b", "c"]
    assert [s.kept for s in stages] == [True, False, False, True]
    assert stages[1].p_value == pytest.approx(textbook_p(y, X[:, :2], X[:, :3]), rel=1e-6)
    assert stages[3].p_value == pytest.approx(textbook_p(y, X[:, :2], X[:, [0, 1, 4]]), rel=1e-6)
    assert stages[3].rss == pytest.approx(ols_rss(y, X[:, [0, 1, 4]]), rel=1e-9)
    assert stages[3].rms == pytest.approx(np.sqrt(stages[3].rss / N))
    assert best.idx == [0, 1, 4]
    # the column 2 T - 1/2 is one of the nuisance block's span: removed, naming the columns it combines
    assert removed == [(3, "not identifiable: a combination of c1, c0")]


def test_identifiable_keeps_the_first_of_two_collinear_candidates():
    J = np.column_stack([np.ones(N), T, 3 * T, T ** 2])
    kept, removed = identifiable(J, ["one", "t", "3t", "t2"], [0], [1, 2, 3], 1e-6)
    assert kept == [1, 3]
    assert removed == [(2, "not identifiable: a combination of t")]


def test_a_stage_the_later_one_explains_is_dropped_and_the_rest_refitted():
    z, w = T ** 3, np.cos(5 * T)
    X = np.column_stack([np.ones(N), z + 0.3 * w, z])   # the stage "a" correlated with the true "b"
    y = 2.0 * z + 0.01 * noise(6)
    stages, best, _ = select_stages(linear(X, y, ["nuis", "a", "b"]), ["a", "b"], 1e-3, 1e-6)
    assert not stages[1].kept and stages[1].note.startswith("explained by the effects named after it")
    assert stages[2].kept and best.idx == [0, 2]
    # b's record refitted beside the base alone: its F test the textbook one of that pair
    assert stages[2].n_params == 2
    assert stages[2].p_value == pytest.approx(textbook_p(y, X[:, :1], X[:, [0, 2]]), rel=1e-6, abs=1e-300)
    assert best.rss == pytest.approx(ols_rss(y, X[:, [0, 2]]), rel=1e-9)


def test_with_folds_a_stage_is_kept_only_if_its_held_out_error_drops():
    X = np.column_stack([np.ones(N), T, np.sin(4 * T)])
    y = 1.0 + 0.5 * T + 0.3 * np.sin(4 * T) + 0.05 * noise(7)
    stages, best, _ = forward_stages(linear(X, y, ["nuis", "a", "b"], folds=5), ["a", "b"], 1e-3, 1e-6)
    assert [s.kept for s in stages] == [True, True, True]
    assert stages[2].cv_rms < stages[1].cv_rms < stages[0].cv_rms
    # a p-value that passes with a held-out error that does not drop: a model whose cv is never lower
    nf = linear(X, y, ["nuis", "a", "b"], folds=5)
    worse = Nested(nf.names, nf.kinds, nf.fit, nf.jacobian, nf.summary, nf.m, nf.points, nf.first, nf.nuisance,
                   cv=lambda idx, x: np.full((5, 2), [float(len(idx)) ** 2, 1.0]))
    stages, best, _ = forward_stages(worse, ["a", "b"], 1e-3, 1e-6)
    assert [s.kept for s in stages] == [True, False, False] and stages[1].p_value < 1e-3
