"""The data set an effect predicts: postures, loads, and what every effect reads from the nominal model there.

Quantities that depend only on the nominal model (the actuator influence for ``clearance``, the passive
joints' for ``passive_clearance``, nonlinear-minus-linear deflection for ``geometric_nonlinearity``) are
computed once, lazily, per data set: by ``vjm diagnose`` on the measurements, by ``vjm simulate`` on the
simulated postures, by ``vjm path`` on the path's points.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import modelops as mo


def unique_postures(P, decimals=6):
    """Unique postures (m, 3) and the index (n,) of each row into them."""
    P = np.asarray(P, float)
    key = np.round(P, decimals)
    _, first, idx = np.unique(key, axis=0, return_index=True, return_inverse=True)
    # the first row of each group, unrounded: U[idx] reproduces P exactly for repeated postures
    return P[first], idx.reshape(-1)


def slip_signs(tau) -> np.ndarray:
    """The side each joint slips to under its forces ``tau``: their sign, 0 for forces below 1e-9 of the
    largest ("zero": no preferred side, no slip)."""
    tau = np.asarray(tau, float)
    return np.where(np.abs(tau) > 1e-9 * np.abs(tau).max(initial=1e-300), np.sign(tau), 0.0)


def slip_toward(A, W) -> np.ndarray:
    """(n, 6) ``sum_s a_s sign(a_s . w)``: every joint of influence ``A`` (n, k, 6) slipping by one unit
    toward the force it carries under ``W`` (n, 6); the work ``w . t`` is >= 0."""
    return np.einsum("nc,ncj->nj", slip_signs(np.einsum("ncj,nj->nc", A, W)), A)


@dataclass
class Context:
    """Per-data-set precomputations on the nominal model (cached lazily)."""

    model: object
    P: np.ndarray  # (m, 3) unique postures
    idx: np.ndarray  # (n,) measurement -> posture
    W: np.ndarray  # (n, 6) wrenches (zeros for stiffness observations)
    noise_t: float | None = None  # typical translation noise, mm (for screening candidates)
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def n(self) -> int:
        return int(self.idx.size)

    def compliance(self) -> np.ndarray:
        """(m, 6, 6) compliance of the nominal model at the unique postures."""
        if "C" not in self._cache:
            self._cache["C"] = mo.compliance_map(self.model, self.P)
        return self._cache["C"]

    def q(self) -> np.ndarray:
        """(m, n_chains) actuator coordinates of the unique postures (nominal geometry)."""
        if "q" not in self._cache:
            self._cache["q"] = mo.actuator_coords(self.model, self.P)
        return self._cache["q"]

    def clearance_unit(self) -> np.ndarray:
        """(n, 6) twist of a unit backlash in every actuator, each slipping in the direction of its force.

        By the unit-load theorem an imposed slip ``e`` of actuator i moves the
        end-effector by ``a_i e``, where ``a_i`` maps the applied wrench to that
        actuator's force (``tau_i = a_i . w``).  With the slip following the
        force sign, ``t = sum_i a_i sign(a_i . w)``, whose work ``w . t`` is >= 0.
        """
        if "clear" not in self._cache:
            self._cache["clear"] = slip_toward(mo.actuator_influence(self.model, self.P)[self.idx], self.W)
        return self._cache["clear"]

    def passive_clearance_unit(self, model=None, key=None) -> np.ndarray:
        """(n, 6) twist of a unit slip (1 rad) in every passive-joint spring, each toward its moment.

        As :meth:`clearance_unit`, with the moments ``tau_s = a_s . w`` the passive joints carry
        about their constrained directions (:func:`~vjm.effects.modelops.joint_spring_influence`).
        ``model``: the model being fitted (calibration and model-changing effects applied), whose
        load paths set the moments (a link's coupling changes how the load reaches the joints);
        ``key`` identifies it in the cache.  Default: the nominal model.
        """
        if model is None:
            model, key = self.model, "nominal"
        k = ("pclear", key)
        if k not in self._cache:
            if len(self._cache) > 64:
                self._cache = {n: v for n, v in self._cache.items() if not (isinstance(n, tuple) and n[0] == "pclear")}
            self._cache[k] = slip_toward(mo.joint_spring_influence(model, self.P)[self.idx], self.W)
        return self._cache[k]

    def nonlinear_delta(self) -> np.ndarray:
        """(n, 6) nonlinear-equilibrium deflection minus the linear ``C w`` of the nominal model."""
        if "nl" not in self._cache:
            self._cache["nl"] = mo.nonlinear_delta(self.model, self.P[self.idx], self.W)
        return self._cache["nl"]
