"""A linear least-squares model as the staged selection sees it (:class:`vjm.stats.staged.Nested`): the
closed forms of the selection's tests (linear fits are their own Gauss-Newton steps and their own folds)."""
import numpy as np

from vjm.stats.fit import interleaved_folds
from vjm.stats.staged import Nested, Practical, fold_errors, least_squares_fit


def linear(X, y, kinds, folds=0, lower=None, practical=Practical()):
    """The :class:`Nested` of the linear model y ~ X, its columns in the blocks ``kinds`` (``nuis`` first),
    ``lower`` bounds of its parameters (None: unbounded), ``folds`` interleaved folds (0: none)."""
    def fit(idx, x0, bounds=None):
        return least_squares_fit(lambda b: X[:, idx] @ b - y, lambda b: X[:, idx], x0, bounds)

    def cv(idx, x, bounds=None):
        return fold_errors(lambda tr: np.linalg.lstsq(X[tr][:, idx], y[tr], rcond=None)[0],
                           lambda te, b: (float(np.sum((X[te][:, idx] @ b - y[te]) ** 2)), int(te.sum())),
                           interleaved_folds(len(y), folds))

    p = X.shape[1]
    bounds = None if lower is None else (np.asarray(lower, dtype=float), np.full(p, np.inf), np.zeros(p, dtype=bool))
    return Nested(tuple(f"c{i}" for i in range(p)), tuple(kinds), fit, lambda x, cols: X[:, cols],
                  lambda idx, x: {}, y.size, y.size, "base", ("nuis",), cv=cv if folds else None, bounds=bounds,
                  practical=practical)
