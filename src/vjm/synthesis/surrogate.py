"""A link's 6x6 compliance and mass as smooth functions of its free parameters, from its evaluated designs.

Why this form:

* **Log space.** A section's compliances go as powers of its dimensions (bending 1/(w h^3)), so the
  inputs are the parameters' logarithms scaled to [0, 1] (:meth:`~vjm.synthesis.spec.Param.to_unit`)
  and the outputs are logarithms: ``log C`` is then nearly linear, which the interpolant's linear
  part captures from a handful of designs.
* **The matrix logarithm.** The interpolated quantity is ``logm(S C S)`` (``S`` a fixed diagonal
  scaling that makes the blocks' units comparable), so the predicted ``C = S^-1 expm(.) S^-1`` is
  symmetric positive definite by construction, its couplings included, and equals the FEA's matrix
  at every evaluated design.
* **Radial basis functions** (:class:`scipy.interpolate.RBFInterpolator`, thin-plate spline with a
  linear polynomial): an interpolant that needs no hyper-parameters to be fitted, is deterministic and
  reproduces the evaluated designs exactly (the FEA is the truth there).

The mass (kg) is interpolated the same way, as its logarithm.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

_IU = np.triu_indices(6)


def _logm(A: np.ndarray) -> np.ndarray:
    w, V = np.linalg.eigh(A)
    return (V * np.log(w)[..., None, :]) @ np.swapaxes(V, -1, -2)


def _expm(L: np.ndarray) -> np.ndarray:
    w, V = np.linalg.eigh(L)
    return (V * np.exp(w)[..., None, :]) @ np.swapaxes(V, -1, -2)


@dataclass(frozen=True, eq=False)
class LinkSurrogate:
    """Fitted on designs at unit coordinates ``U`` (n, d); :meth:`predict` gives (C (m, 6, 6), mass (m,))."""

    scale: np.ndarray
    rbf: object

    @classmethod
    def fit(cls, U: np.ndarray, C: np.ndarray, mass: np.ndarray) -> "LinkSurrogate":
        from scipy.interpolate import RBFInterpolator

        U, C = np.atleast_2d(np.asarray(U, dtype=float)), np.asarray(C, dtype=float)
        d = np.einsum("nii->ni", C)
        scale = 1.0 / np.sqrt(np.exp(np.mean(np.log(d), axis=0)))
        L = _logm(scale[:, None] * C * scale[None, :])
        y = np.column_stack([L[:, _IU[0], _IU[1]], np.log(np.asarray(mass, dtype=float))])
        n, dim = U.shape
        # the linear part needs dim + 1 designs in general position; fewer get a constant
        degree = 1 if n >= dim + 1 else 0
        return cls(scale, RBFInterpolator(U, y, kernel="thin_plate_spline", degree=degree))

    def predict(self, U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        y = self.rbf(np.atleast_2d(np.asarray(U, dtype=float)))  # type: ignore[operator]
        L = np.zeros((len(y), 6, 6))
        L[:, _IU[0], _IU[1]] = y[:, :21]
        L = L + np.swapaxes(L, 1, 2) - np.einsum("nii->ni", L)[:, :, None] * np.eye(6)
        s = 1.0 / self.scale
        return s[:, None] * _expm(L) * s[None, :], np.exp(y[:, 21])
