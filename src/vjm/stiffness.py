"""Chain stiffness from the bordered system (seed eq. 10-12) and the machine sum (eq. 13).

For one chain, with ``S = J_theta K_theta^-1 J_theta^T`` (the springs'
compliance seen at the end effector), eq. 11 reads::

    [ S     J_q ] [ f  ]   [ dt ]
    [ J_q^T  0  ] [ dq ] = [ 0  ]

Writing ``S = L L^T`` and ``A = L^-1 J_q``, its solution is
``f = K dt`` with ``K = L^-T (I - P_A) L^-1`` where ``P_A`` is the orthogonal
projector onto the column space of ``A``.  That projector comes from a
rank-revealing factorisation (pivoted QR, and SVD near rank loss), so
``J_q`` may be rank deficient (singular postures, redundant passive joints):
the solution is still unique in ``f`` and finite, and the rank is
reported.  The machine stiffness is the sum of the chains' ``K`` (eq. 13),
all in the world frame at the end-effector point.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .chain import Chain
from .linalg import cholesky, lower_inverse, psd_rank_inverse, range_basis, sym3_max_eig


def spring_compliance(chain: Chain, J: np.ndarray, compliances: dict) -> np.ndarray:
    """``S = sum_s J_s C_s J_s^T`` over the chain's springs, shape (n, 6, 6).

    ``compliances[name]`` is the spring's compliance, (k, k) or per pose (n, k, k).
    Springs missing from the dict are rigid (omitted).
    """
    n = J.shape[0]
    S = np.zeros((n, 6, 6))
    for s in chain.springs:
        C = compliances.get(s.name)
        if C is None:
            continue
        Js = J[:, :, list(s.vars)]
        S += Js @ C @ np.swapaxes(Js, 1, 2)
    return 0.5 * (S + np.swapaxes(S, 1, 2))


def chain_stiffness(chain: Chain, J: np.ndarray, compliances: dict) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness ``K_i`` (n, 6, 6) of one chain and the rank of its ``J_q`` (n,).

    ``J`` is the chain's full Jacobian (n, 6, n_vars) from :func:`vjm.chain.jacobian`.
    Springs and passive joints together must span all six directions (a
    direction they leave out would be infinitely stiff).
    """
    S = spring_compliance(chain, J, compliances)
    Jq = J[:, :, list(chain.passive)]
    # S + a Jq Jq^T gives the same K (J_q^T f = 0 kills the added term) and is
    # positive definite as soon as springs and passive joints together span
    # all six directions (e.g. a rank-5 parallelogram spring next to its joint).
    JJ = Jq @ np.swapaxes(Jq, 1, 2)
    a = np.trace(S, axis1=1, axis2=2) / np.maximum(np.trace(JJ, axis1=1, axis2=2), 1e-300)
    B = lower_inverse(cholesky(S + a[:, None, None] * JJ))  # B = L^-1
    Q, rank = range_basis(B @ Jq)
    BQ = np.swapaxes(B, 1, 2) @ Q
    K = np.swapaxes(B, 1, 2) @ B - BQ @ np.swapaxes(BQ, 1, 2)
    return 0.5 * (K + np.swapaxes(K, 1, 2)), rank


@dataclass(frozen=True, eq=False)
class StiffnessResult:
    """Per-pose output of the stiffness model (the model itself stays immutable).

    Arrays carry a leading pose axis for :meth:`vjm.model.Model.stiffness_map`
    and none for :meth:`vjm.model.Model.stiffness`.

    Attributes
    ----------
    points : (n, 3) end-effector positions, mm, world frame
    K : (n, 6, 6) Cartesian stiffness, world axes, at the end-effector point;
        order dx dy dz rx ry rz, units N/mm, N/rad, N mm/rad
    C : (n, 6, 6) compliance ``K^-1`` where ``invertible``; where K is singular
        (a direction the platform can move in with no resistance), the
        Moore-Penrose pseudo-inverse, and ``invertible`` is False
    k_tran : (n,) mm/N, largest eigenvalue of ``C[:3, :3]``: the largest
        deflection per unit force over all force directions (``inf`` where
        K is singular)
    k_rot : (n,) rad/(N mm), largest eigenvalue of ``C[3:, 3:]``: the largest
        rotation per unit torque (``inf`` where K is singular)
    rank : (n,) numerical rank of K (6 at regular postures)
    invertible : (n,) bool
    chain_rank : (n, n_chains) rank of each chain's passive-joint Jacobian ``J_q``
    """

    points: np.ndarray
    K: np.ndarray
    C: np.ndarray
    k_tran: np.ndarray
    k_rot: np.ndarray
    rank: np.ndarray
    invertible: np.ndarray
    chain_rank: np.ndarray = field(default=None)

    def pose(self, i: int) -> "StiffnessResult":
        """The result of pose ``i`` alone (no leading axis)."""
        return StiffnessResult(*(getattr(self, f)[i] for f in
                                 ("points", "K", "C", "k_tran", "k_rot", "rank", "invertible", "chain_rank")))

    def to_dict(self) -> dict:
        """JSON-ready dict (single pose or map), frames and units stated."""
        return {
            "point_mm": np.asarray(self.points).tolist(),
            "K": np.asarray(self.K).tolist(),
            "C": np.asarray(self.C).tolist(),
            "k_tran_mm_per_N": np.asarray(self.k_tran).tolist(),
            "k_rot_rad_per_Nmm": np.asarray(self.k_rot).tolist(),
            "rank": np.asarray(self.rank).tolist(),
            "invertible": np.asarray(self.invertible).tolist(),
            "chain_rank": np.asarray(self.chain_rank).tolist(),
            "frame": "world axes, origin at the end-effector point",
            "order": "dx dy dz rx ry rz / Fx Fy Fz Mx My Mz",
            "units": {"K": "N/mm, N/rad, N mm/rad", "C": "mm/N, mm/(N mm), rad/(N mm)"},
        }


def assemble(points: np.ndarray, chain_K: list, chain_ranks: list) -> StiffnessResult:
    """Machine stiffness: sum of the chains' K (eq. 13) and the derived compliances."""
    K = np.sum(chain_K, axis=0)
    C, rank, inv = psd_rank_inverse(K)
    kt = np.where(inv, sym3_max_eig(C[:, :3, :3]), np.inf)
    kr = np.where(inv, sym3_max_eig(C[:, 3:, 3:]), np.inf)
    return StiffnessResult(points, K, C, kt, kr, rank, inv, np.stack(chain_ranks, axis=1))
