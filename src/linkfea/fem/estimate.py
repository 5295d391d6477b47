"""A posteriori discretization error of the 6x6 compliance: recovered-stress (Zienkiewicz-Zhu) estimate.

Why an energy estimate gives the compliance's error: the diagonal entry ``C_kk`` is the
energy of the unit load ``k`` (``w_k^T C w_k = a(u_k, u_k)``, with the exact rigid coupling of
the tip).  The P2 solution ``u_h`` is the Galerkin projection in the same constrained space,
so ``a(u_k - u_hk, u_hk) = 0`` and

    C_kk - C_h,kk = a(e_k, e_k) = ||e_k||_E^2 >= 0,        e_k = u_k - u_hk,

the discrete compliance is always too small, by exactly the squared energy norm of the
error; and ``C_ij - C_h,ij = a(e_i, e_j)``, so ``|dC_ij| <= sqrt(dC_ii dC_jj)`` (Cauchy-Schwarz).

The energy norm of the error is estimated by the Zienkiewicz-Zhu recovery: the P2 stress
``sigma_h`` (discontinuous between elements) is averaged at every P2 node (weighted by the
elements' volumes), the averages interpolated with the P2 shape functions give a continuous
``sigma*``, and

    eta_k^2 = sum_e int_e (sigma* - sigma_h) : D^-1 (sigma* - sigma_h) dV.

The relative error of ``C_kk`` is then ``SAFETY_FACTOR * eta_k^2 / (C_h,kk + SAFETY_FACTOR * eta_k^2)``
(the estimate of ``(C_kk - C_h,kk) / C_kk``).  The recovery smooths away part of the error
near singular edges (sharp re-entrant corners, the clamp's edges), where the error
concentrates: its raw effectivity on the compliance was 0.21-0.87 on the validation parts
(docs/benchmarks.md, "Discretization error estimate"), so the reported figure carries a
stated :data:`SAFETY_FACTOR`.

The per-element indicator (``eta_e^2 / C_h,kk``, largest over the 6 cases) says where the
error is, for refinement.

Units: N, mm, MPa.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np
import scipy.sparse as sp

from ..runtime.errors import LinkFeaError
from .p2 import TET_EDGES, _p2_reference_gradients

SAFETY_FACTOR = 3.0
"""Multiplier of the raw recovered-stress estimate of ``C_kk - C_h,kk``.  The raw effectivity
(raw estimate / true error of the compliance, each diagonal entry) measured on the validation
parts lies in [0.21, 0.87]: 0.21-0.42 on the slender bar (clamp and rigid-tip edges dominate;
reference: its converged sequence, whose limit matches Timoshenko), 0.46-0.70 on the filleted
bracket (reference: its own converged sequence), 0.56-0.87 on the sharp foot (reference: the
671k-DOF study); docs/benchmarks.md.  Rule: the smallest integer factor that takes the lowest
measured effectivity to at least 0.6 (a margin over the required 0.5), checked to keep the
highest below 3: ceil(0.6 / 0.21) = 3, giving 0.64-2.6."""

_CHUNK = 4096
_KEEP_BYTES = 512 * 2**20

# Reference coordinates of the 10 P2 nodes: the 4 vertices, then the midpoints of TET_EDGES.
_VERTS = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
_NODES_REF = np.vstack([_VERTS, 0.5 * (_VERTS[TET_EDGES[:, 0]] + _VERTS[TET_EDGES[:, 1]])])


def _p2_mass_reference() -> np.ndarray:
    """``M[a, b] = (1/V) int N_a N_b`` of the straight 10-node tet (scikit-fem's degree-4 rule: exact)."""
    from skfem.quadrature import get_quadrature
    from skfem.refdom import RefTet

    X, W = get_quadrature(RefTet, 4)
    lam = np.vstack([1.0 - X.sum(axis=0), X])  # (4, nq)
    N = np.vstack([lam * (2.0 * lam - 1.0), 4.0 * lam[TET_EDGES[:, 0]] * lam[TET_EDGES[:, 1]]])  # (10, nq)
    return 6.0 * (N * W) @ N.T


_MASS = _p2_mass_reference()
_DN_NODES = _p2_reference_gradients(_NODES_REF.T)  # (10 evaluation nodes, 10 shape functions, 3)


@dataclass(frozen=True)
class ErrorEstimate:
    """Estimated discretization error of a compliance from one P2 solution.

    Attributes
    ----------
    relative : ndarray (6,)
        Estimated relative error of each diagonal entry, ``(C_kk - C_h,kk) / C_kk`` (the
        computed value is too small by about this fraction), safety factor included.
    bound : ndarray (6, 6)
        Estimated ``|C_ij - C_h,ij|`` (same units as the compliance): ``sqrt(dC_ii dC_jj)``.
    matrix : float
        The whole matrix: the largest of :attr:`relative` (the convention of the Richardson
        estimate, :func:`linkfea.fem.convergence.richardson`); the off-diagonal entries' errors are
        bounded through :attr:`bound`.
    raw : ndarray (6,)
        ``eta_k^2 / C_h,kk`` before the safety factor.
    safety_factor : float
    indicator : ndarray (m,)
        Per element, the largest over the 6 cases of ``eta_e,k^2 / C_h,kk`` (relative
        contribution to the error of entry k); sums to about ``raw`` per case.
    """

    relative: np.ndarray
    bound: np.ndarray
    matrix: float
    raw: np.ndarray
    safety_factor: float
    indicator: np.ndarray

    def to_dict(self) -> dict:
        """The JSON summary (no per-element indicator)."""
        return {"method": "recovered stress (Zienkiewicz-Zhu), energy norm of each unit-load solution",
                "diagonal": [float(x) for x in self.relative], "matrix": float(self.matrix),
                "bound": self.bound.tolist(), "raw_diagonal": [float(x) for x in self.raw],
                "safety_factor": float(self.safety_factor),
                "note": ("estimated relative error of each diagonal entry: the computed compliance is too small "
                         "(too stiff) by about this fraction; bound: estimated |error| of every entry")}


def _element_stresses(X: np.ndarray, U: np.ndarray, lam: np.ndarray, mu: np.ndarray):
    """Stresses (m, 10, k, 6) (order xx yy zz yz xz xy) at the 10 nodes of tets with P2 nodes ``X``
    (m, 10, 3) and nodal displacements ``U`` (m, 10, k, 3), and the tets' volumes (m,).

    Isoparametric: the Jacobian is taken at each node, so curved cells are handled; on a
    straight cell it is the constant affine one.  A node where a curved cell's Jacobian is not
    positive (allowed between the quadrature points) takes the affine one.
    """
    m, _, k, _ = U.shape
    Xv = X[:, :4]
    Ja = (Xv[:, 1:] - Xv[:, :1]).transpose(0, 2, 1)  # affine dx_i / dxi_k
    vol = np.linalg.det(Ja) / 6.0
    # Reference gradients of u at the nodes: Ur[e, b, (c, i), kx] = sum_a DN[b, a, kx] U[e, a, c, i].
    Ur = np.matmul(_DN_NODES.transpose(0, 2, 1).reshape(1, 30, 10), U.reshape(m, 10, 3 * k))  # (m, 30, 3k)
    Ur = Ur.reshape(m, 10, 3, k * 3).transpose(0, 1, 3, 2)  # (m, b, (c, i), kx)
    mid = 0.5 * (X[:, TET_EDGES[:, 0]] + X[:, TET_EDGES[:, 1]])
    size = np.abs(Ja).max(axis=(1, 2))
    curved = np.abs(X[:, 4:] - mid).max(axis=(1, 2)) > 1e-9 * size
    Jinv = np.broadcast_to(np.linalg.inv(Ja)[:, None], (m, 10, 3, 3)).copy()
    if curved.any():
        Jn = np.einsum("mai,bak->mbik", X[curved], _DN_NODES)
        ok = np.linalg.det(Jn) > 0
        Jc = Jinv[curved]
        Jc[ok] = np.linalg.inv(Jn[ok])
        Jinv[curved] = Jc
    Du = np.matmul(Ur, Jinv).reshape(m, 10, k, 3, 3)  # du_i / dx_j
    tr = Du[..., 0, 0] + Du[..., 1, 1] + Du[..., 2, 2]
    s = np.empty((m, 10, k, 6))
    mu_, lt = mu[:, None, None], lam[:, None, None] * tr
    for c, (i, j) in enumerate(((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))):
        s[..., c] = mu_ * (Du[..., i, j] + Du[..., j, i]) + (lt if i == j else 0.0)
    return s, vol


def _energy(D: np.ndarray, vol: np.ndarray, lam: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """``int (sum_a N_a D_a) : C^-1 (sum_b N_b D_b)`` per element and case, (m, k), for nodal
    stress differences ``D`` (m, 10, k, 6) (straight-cell mass matrix)."""
    # sigma : C^-1 sigma = (sigma:sigma - lam/(3 lam + 2 mu) tr^2) / (2 mu), sigma:sigma with 2x the shears.
    m, _, k, _ = D.shape
    MD = np.matmul(_MASS[None], D.reshape(m, 10, k * 6)).reshape(D.shape)
    dd = (D * MD).sum(axis=1)
    full = dd[..., 0] + dd[..., 1] + dd[..., 2] + 2.0 * (dd[..., 3] + dd[..., 4] + dd[..., 5])
    trD, trMD = D[..., :3].sum(axis=-1), MD[..., :3].sum(axis=-1)
    trtr = (trD * trMD).sum(axis=1)
    w = (lam / (3.0 * lam + 2.0 * mu))[:, None]
    return vol[:, None] * (full - w * trtr) / (2.0 * mu[:, None])


def estimate_error(sol, compliance_diagonal: np.ndarray, lam: float, mu: float,
                   scale: Optional[np.ndarray] = None, safety_factor: float = SAFETY_FACTOR) -> ErrorEstimate:
    """Recovered-stress estimate of the compliance's discretization error.

    Parameters
    ----------
    sol : linkfea.fem.problem.FeaSolution
        The 6 unit-load solutions (P2 nodes, cells, displacements).
    compliance_diagonal : array (6,)
        ``C_h,kk`` of the computed compliance (the energies of the unit loads).
    lam, mu : float
        Lame constants, MPa; ``scale`` (m,) multiplies both per element (the block mode's block).
    safety_factor : float
        See :data:`SAFETY_FACTOR`.
    """
    pts = np.asarray(sol.points, dtype=float)
    cells = np.asarray(sol.cells, dtype=np.int64)
    disp = np.asarray(sol.displacements, dtype=float)  # (k, N, 3)
    k = disp.shape[0]
    m, N = len(cells), len(pts)
    s = np.ones(m) if scale is None else np.asarray(scale, dtype=float)
    lam_e, mu_e = lam * s, mu * s
    Cd = np.asarray(compliance_diagonal, dtype=float)
    if Cd.shape != (k,) or np.any(~(Cd > 0)):
        raise LinkFeaError("error estimate: the compliance diagonal must be positive")
    dispT = np.ascontiguousarray(disp.transpose(1, 0, 2))  # (N, k, 3)

    # Pass 1: volume-weighted nodal averages of the element stresses (kept for pass 2 when they fit
    # in _KEEP_BYTES, else computed again).
    acc = np.zeros((N, k * 6))
    wsum = np.zeros(N)
    keep = m * 10 * k * 6 * 8 <= _KEEP_BYTES
    kept = []
    for s0 in range(0, m, _CHUNK):
        sl = slice(s0, min(s0 + _CHUNK, m))
        S, vol = _element_stresses(pts[cells[sl]], dispT[cells[sl]], lam_e[sl], mu_e[sl])
        nodes = cells[sl].ravel()
        P = sp.csr_matrix((np.repeat(vol, 10), (nodes, np.arange(len(nodes)))), shape=(N, len(nodes)))
        acc += P @ S.reshape(-1, k * 6)
        wsum += np.bincount(nodes, weights=np.repeat(vol, 10), minlength=N)
        if keep:
            kept.append((S, vol))
    star = (acc / wsum[:, None]).reshape(N, k, 6)

    # Pass 2: energy of the difference, per element and case.
    eta2 = np.empty((m, k))
    for n_chunk, s0 in enumerate(range(0, m, _CHUNK)):
        sl = slice(s0, min(s0 + _CHUNK, m))
        S, vol = kept[n_chunk] if keep else _element_stresses(pts[cells[sl]], dispT[cells[sl]], lam_e[sl], mu_e[sl])
        eta2[sl] = _energy(star[cells[sl]] - S, vol, lam_e[sl], mu_e[sl])

    raw = eta2.sum(axis=0) / Cd
    dC = safety_factor * raw * Cd
    rel = dC / (Cd + dC)
    return ErrorEstimate(relative=rel, bound=np.sqrt(np.outer(dC, dC)), matrix=float(rel.max()), raw=raw,
                         safety_factor=float(safety_factor), indicator=(eta2 / Cd[None, :]).max(axis=1))
