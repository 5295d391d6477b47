"""The immutable machine model and its per-pose computations (pinocchio-style Model / Data).

A :class:`Model` holds parameters only (architecture, geometry, springs,
effects); every call such as :meth:`Model.stiffness_map` returns a fresh
:class:`~vjm.stiffness.StiffnessResult`.  ``dataclasses.replace(model, ...)``
(or :meth:`Model.replace`) gives a modified model, validated again.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from linkfea.compliance import check as check_compliance
from linkfea.errors import LinkFeaError

from .chain import jacobian
from .errors import VjmError
from .models import ARCHITECTURES
from .models.base import as_points
from .stiffness import StiffnessResult, assemble, assemble_soa, chain_stiffness, chain_stiffness_frames

#: poses per block in :meth:`Model.stiffness_map` (working set of a block stays in cache)
MAP_BLOCK = 2048


def validate_compliance(C, key: str) -> np.ndarray:
    """A 6x6 symmetric positive-definite compliance, or VjmError naming ``key``.

    The check and its tolerances are linkfea's, the one contract between the two packages
    (:func:`linkfea.compliance.check`).
    """
    try:
        return check_compliance(C, f"{key}: compliance")
    except LinkFeaError as exc:
        raise VjmError(str(exc)) from None


@dataclass(frozen=True)
class Actuator:
    """Actuator spring: ``c(q) = 1/stiffness + compliance_slope * (q - q_ref)``.

    ``stiffness`` in N/mm (prismatic) or N mm/rad (rotary); ``compliance_slope``
    in (mm/N)/mm, e.g. a ball screw whose compliance grows with the nut's
    distance from the fixed bearing; ``q_ref`` in mm (rad).
    """

    stiffness: float
    compliance_slope: float = 0.0
    q_ref: float = 0.0

    def __post_init__(self):
        for k in ("stiffness", "compliance_slope", "q_ref"):
            v = getattr(self, k)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) or not np.isfinite(v):
                raise VjmError(f"actuator.{k} must be a finite number, got {v!r}")
        if not self.stiffness > 0:
            raise VjmError(f"actuator.stiffness must be > 0, got {self.stiffness}")


@dataclass(frozen=True, eq=False)
class Link:
    """A link's 6-dof spring: ``compliance`` 6x6 in the spring frame, or None if rigid.

    ``source`` keeps what the model file said (``{"beam": ...}``,
    ``{"linkfea": path}`` ...) so that saving writes it back; None means
    "write the matrix inline".
    """

    compliance: np.ndarray | None
    source: dict | None = None

    @classmethod
    def rigid(cls) -> "Link":
        return cls(None, {"rigid": True})

    @classmethod
    def inline(cls, C) -> "Link":
        return cls(validate_compliance(C, "compliance"), None)


@dataclass(frozen=True)
class Joints:
    """Passive-joint elasticity: ``passive_stiffness`` N mm/rad about each joint's
    constrained rotation directions, or None for ideal joints."""

    passive_stiffness: float | None = None

    def __post_init__(self):
        k = self.passive_stiffness
        if k is not None and not (isinstance(k, (int, float, np.floating)) and np.isfinite(k) and k > 0):
            raise VjmError(f"joints.passive_stiffness must be a number > 0 (N mm/rad), got {k!r}")


@dataclass(frozen=True, eq=False)
class Model:
    """Immutable VJM model of a parallel machine.

    Attributes
    ----------
    architecture : one of ``vjm.models.ARCHITECTURES``
    geometry : dict of lengths in mm (``L``, ``r``, ``d`` ...; see the architecture)
    actuator : Actuator
    foot, leg : Link (spring frames: see the architecture's module)
    joints : Joints
    effects : dict, kept verbatim for the discrepancy workflow
    name : free text
    path : the file this model was read from (resolves relative paths), or None
    """

    architecture: str
    geometry: dict
    actuator: Actuator
    foot: Link
    leg: Link
    joints: Joints = field(default_factory=Joints)
    effects: dict = field(default_factory=dict)
    name: str = ""
    path: str | None = None

    def __post_init__(self):
        if self.architecture not in ARCHITECTURES:
            raise VjmError(f"architecture: unknown {self.architecture!r}; known: {', '.join(ARCHITECTURES)}")
        arch = ARCHITECTURES[self.architecture]
        if not isinstance(self.geometry, dict):
            raise VjmError("geometry must be a mapping of lengths in mm")
        for k in arch.geometry_keys:
            v = self.geometry.get(k)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) or not (np.isfinite(v) and v > 0):
                raise VjmError(f"geometry.{k} must be a length > 0 in mm for {self.architecture}, got {v!r}")
        for key in ("foot", "leg"):
            link = getattr(self, key)
            if not isinstance(link, Link):
                raise VjmError(f"{key} must be a vjm.model.Link")
            if link.compliance is not None:
                object.__setattr__(self, key, Link(validate_compliance(link.compliance, key), link.source))
        if self.foot.compliance is None and self.leg.compliance is None:
            raise VjmError("foot and leg are both rigid: the legs' constraint directions would be infinitely "
                           "stiff; give at least one of them a compliance")
        if not isinstance(self.effects, dict):
            raise VjmError("effects must be a mapping name -> parameters")

    # -- derived, computed once per model ---------------------------------
    @cached_property
    def arch(self):
        return ARCHITECTURES[self.architecture]

    @cached_property
    def chains(self):
        """The chains (eq. 1) of this model, built once."""
        return self.arch.chains(self)

    def replace(self, **changes) -> "Model":
        """A copy with some fields changed (validated), like ``dataclasses.replace``."""
        return dataclasses.replace(self, **changes)

    # -- per-pose computations --------------------------------------------
    def inverse_kinematics(self, P) -> np.ndarray:
        """Actuator coordinates (n, n_chains) (mm, or rad for rotary) of points P (n, 3).

        Raises VjmError for an unreachable point.
        """
        q, _ = self.arch.inverse_kinematics(self, as_points(P))
        return q

    def _chain_data(self, P):
        P = as_points(P)
        q, vals = self.arch.inverse_kinematics(self, P)
        comps = self.arch.compliances(self, P, vals, q)
        out = []
        for ch, v, c in zip(self.chains, vals, comps):
            T, J = jacobian(ch, v)
            err = np.max(np.abs(T[:, :3, 3] - P)) if len(P) else 0.0
            if err > 1e-6 * (1.0 + np.max(np.abs(P))):
                raise VjmError(f"internal: chain {ch.name} does not close on the pose (error {err:.3g} mm)")
            out.append((ch, v, J, c))
        return P, q, out

    def chain_stiffness(self, P) -> tuple[np.ndarray, np.ndarray]:
        """Each chain's stiffness K_i (n, n_chains, 6, 6) and J_q rank (n, n_chains)."""
        _, _, data = self._chain_data(P)
        Ks, ranks = zip(*(chain_stiffness(ch, J, c) for ch, _, J, c in data))
        return np.stack(Ks, axis=1), np.stack(ranks, axis=1)

    def stiffness_map(self, P) -> StiffnessResult:
        """Stiffness at every point of P (n, 3): batched, no loop over poses.

        The points are processed in blocks of ``MAP_BLOCK`` poses with the
        pose axis last, so that the intermediate arrays stay in cache; a bad
        point raises the same VjmError as the whole batch would.
        """
        P = as_points(P)
        n = P.shape[0]
        out = (np.empty((n, 6, 6)), np.empty((n, 6, 6)), np.empty(n), np.empty(n),
               np.empty(n, dtype=int), np.empty(n, dtype=bool), np.empty((n, len(self.chains)), dtype=int))
        tol = 1e-6 * (1.0 + (np.max(np.abs(P)) if n else 0.0))
        for a in range(0, n, MAP_BLOCK):
            self._map_block(P, a, out, tol)
        K, C, kt, kr, rank, inv, chain_rank = out
        return StiffnessResult(P, K, C, kt, kr, rank, inv, chain_rank)

    def _map_block(self, P, a, out, tol):
        """Poses ``a : a + MAP_BLOCK`` of :meth:`stiffness_map`, written into ``out``."""
        b = min(P.shape[0], a + MAP_BLOCK)
        K, C, kt, kr, rank, inv, chain_rank = out
        try:
            q, vals = self.arch.inverse_kinematics(self, P[a:b])
            comps = self.arch.compliances(self, P[a:b], vals, q)
        except VjmError:
            # report the error the whole batch gives (first offending point, first check)
            q, vals = self.arch.inverse_kinematics(self, P)
            self.arch.compliances(self, P, vals, q)
            raise
        Ksum = None
        for k, (ch, v, c) in enumerate(zip(self.chains, vals, comps)):
            Kc, chain_rank[a:b, k], pe = chain_stiffness_frames(ch, np.ascontiguousarray(v.T), c)
            err = np.max(np.abs(pe - P[a:b].T))
            if err > tol:
                raise VjmError(f"internal: chain {ch.name} does not close on the pose (error {err:.3g} mm)")
            Ksum = Kc if Ksum is None else Ksum + Kc
        Cb, rank[a:b], inv[a:b], kt[a:b], kr[a:b] = assemble_soa(Ksum)
        K[a:b] = Ksum.transpose(2, 0, 1)
        C[a:b] = Cb.transpose(2, 0, 1)

    def stiffness(self, p) -> StiffnessResult:
        """Stiffness at one point p (3,): K (6, 6), C, k_tran, k_rot, rank ..."""
        p = np.asarray(p, dtype=float)
        if p.shape != (3,):
            raise VjmError(f"a pose is a point (x, y, z) in mm, got shape {p.shape}")
        return self.stiffness_map(p[None, :]).pose(0)

    def deflection(self, P, wrench) -> np.ndarray:
        """Linear deflection twist ``C w`` (n, 6) (or (6,)) under wrench(es) (Fx..Mz, N and N mm)."""
        single = np.ndim(P) == 1
        res = self.stiffness_map(P)
        W = np.broadcast_to(np.asarray(wrench, dtype=float), (res.K.shape[0], 6))
        t = np.einsum("nij,nj->ni", res.C, W)
        return t[0] if single else t

    def joint_forces(self, P, wrench) -> dict:
        """Load sharing under an external wrench on the platform (eq. 9, 12).

        Returns a dict with

        * ``"chain_wrench"``: (n, n_chains, 6) wrench carried by each chain,
          ``f_i = K_i C w`` (world axes, at the end-effector point);
        * ``"actuator"``: (n, n_chains) generalised force of each actuator
          spring, ``tau_0 = J_theta0^T f_i`` (N, or N mm for rotary).  Positive
          when the load pushes the actuator towards increasing ``q0``.
        * ``"twist"``: (n, 6) the deflection ``C w``.

        For a single point (3,) the leading axis is dropped.
        """
        single = np.ndim(P) == 1
        P, _, data = self._chain_data(P)
        Ks, ranks = zip(*(chain_stiffness(ch, J, c) for ch, _, J, c in data))
        res = assemble(P, list(Ks), list(ranks))
        W = np.broadcast_to(np.asarray(wrench, dtype=float), (P.shape[0], 6))
        t = np.einsum("nij,nj->ni", res.C, W)
        f = np.stack([np.einsum("nij,nj->ni", K, t) for K in Ks], axis=1)
        tau = np.stack([np.einsum("ni,ni->n", J[:, :, ch.actuated[0]], f[:, k])
                        for k, (ch, _, J, _) in enumerate(data)], axis=1)
        out = {"chain_wrench": f, "actuator": tau, "twist": t}
        return {k: v[0] for k, v in out.items()} if single else out
