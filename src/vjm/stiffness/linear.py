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

import functools
import os
from dataclasses import dataclass, field

import numpy as np

from linkfea.mechanics.compliance import TWIST, WRENCH

from ..kinematics.chain import Chain, _frame_product, _jacobian_soa
from ..kinematics.transforms import ROTATION
from .linalg import (
    FAST_RTOL,
    cholesky,
    lower_inverse,
    psd_rank_inverse,
    psd_rank_inverse_soa,
    range_basis,
    spd_inverse,
    sym3_max_eig_soa,
    upper_inverse,
)

#: what a saved spread means (JSON results, map files)
SPREAD_NOTE = ("k +- spread: half-width of the range of k_tran (mm/N) and k_rot (rad/(N mm)) when every link's "
               "compliance moves within its FEA error bar (vjm.sweep.spread; links added in magnitude); links "
               "without an error estimate (analytic beams, inline matrices, rigid) contribute none")

#: poses per block of the batched kernels (a block's arrays stay in cache)
BLOCK = 2048
#: blocks of this many poses or more run the compiled kernels of :mod:`vjm.maps.map_kernel`; smaller
#: ones (a single ``vjm stiffness --at``) the numpy path, and do not import numba
KERNEL_FROM = 256
#: the environment switch of the map's path: ``numpy`` (the reference, at every size), ``numba``
#: (the kernels at every size) or ``auto`` (the default: the kernels from ``KERNEL_FROM`` poses)
KERNEL_ENV = "VJM_MAP_KERNEL"
KERNELS = ("auto", "numba", "numpy")


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

    ``J`` is the chain's full Jacobian (n, 6, n_vars) from :func:`vjm.kinematics.chain.jacobian`.
    Springs and passive joints together must span all six directions (a
    direction they leave out would be infinitely stiff).
    """
    n = J.shape[0]
    K = np.empty((n, 6, 6))
    rank = np.empty(n, dtype=int)
    for a in range(0, n, BLOCK):
        b = min(n, a + BLOCK)
        cb = {key: (c[a:b] if np.ndim(c) == 3 else c) for key, c in compliances.items()}
        Kb, rank[a:b] = chain_stiffness_soa(chain, np.ascontiguousarray(np.transpose(J[a:b], (2, 1, 0))), cb)
        K[a:b] = Kb.transpose(2, 0, 1)
    return K, rank


def _bordered(chain: Chain, J: np.ndarray, compliances: dict) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 11 through the whitened bordered system, any rank of ``J_q`` (poses first)."""
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


def chain_stiffness_soa(chain: Chain, Jt: np.ndarray, compliances: dict) -> tuple[np.ndarray, np.ndarray]:
    """:func:`chain_stiffness` with the pose axis last: ``Jt`` (n_vars, 6, n) -> K (6, 6, n), rank (n,).

    Where ``J_q`` has full column rank ``k``, eq. 11 reduces to
    ``K = N (N^T S N)^-1 N^T`` with ``N`` (6 x (6-k)) an orthonormal basis of
    the directions the passive joints cannot move (``N^T J_q = 0``): the
    wrench a chain can carry.  ``N`` comes from a Householder QR of ``J_q``
    (backward stable at any conditioning) and ``N^T S N`` is summed spring by
    spring as ``(N^T J_s) C_s (N^T J_s)^T``, so ``S`` is never formed.  A pose
    is sent to the rank-revealing bordered solve (:func:`_bordered`, SVD near
    rank loss) when a lower bound of ``sigma_min / sigma_max`` of ``J_q``
    falls below ``FAST_RTOL`` or when ``N^T S N`` is not clearly positive
    definite; elsewhere the rank is ``k``.
    """
    n = Jt.shape[2]
    passive = list(chain.passive)
    N, ok = _wrench_basis(Jt[passive] if passive else np.zeros((0, 6, n)))  # fancy index: a copy
    Z = {s.name: np.einsum("ain,cin->acn", N, Jt[list(s.vars)]) for s in chain.springs
         if compliances.get(s.name) is not None}
    K, ok = _reduced_stiffness(N, ok, Z, compliances)
    return _with_fallback(chain, K, ok, len(passive), compliances,
                          lambda bad: np.ascontiguousarray(Jt[:, :, bad].transpose(2, 1, 0)))


def chain_stiffness_frames(chain: Chain, vt: np.ndarray, compliances: dict, memo: dict | None = None):
    """Chain stiffness straight from the chain's frames, variable values ``vt`` (n_vars, n).

    Same result as ``chain_stiffness_soa(chain, _jacobian_soa(chain, vt)[1], ...)``
    without forming the full Jacobian: ``N^T J_s`` is read from each spring
    factor's frame (``N_t . e`` for a translation along ``e``,
    ``e . (d x N_t + N_r)`` for a rotation about ``e`` at distance ``d`` from the
    end point), with ``d x N_t + N_r`` computed once per frame origin.

    ``memo``: a dict kept with these frames (the same ``chain`` and ``vt`` on every call), where
    the geometric part (``N``, ``N^T J_s``, the end point) is stored per set of non-rigid springs;
    a fit that changes only compliances then redoes the spring part alone, with the same numbers.

    Returns
    -------
    K : (6, 6, n), rank : (n,), p_end : (3, n)
    """
    want = frozenset(s.name for s in chain.springs if compliances.get(s.name) is not None)
    geo = memo.get(want) if memo is not None else None
    if geo is None:
        geo = _frames_geometry(chain, vt, want)
        if memo is not None:
            memo[want] = geo
    N, ok, Z, pe = geo
    K, ok = _reduced_stiffness(N, ok, Z, compliances)
    K, rank = _with_fallback(chain, K, ok, len(chain.passive), compliances,
                             lambda bad: np.ascontiguousarray(_jacobian_soa(chain, vt[:, bad])[1].transpose(2, 1, 0)))
    return K, rank, pe


def _frames_geometry(chain: Chain, vt: np.ndarray, springs: frozenset):
    """``(N, ok, Z, p_end)`` of :func:`chain_stiffness_frames`: the wrench basis of the passive
    joints and ``Z_s = N^T J_s`` for the named ``springs``; geometry only, no compliance."""
    cols, recs = _frame_product(chain, vt)
    pe = cols[3]
    n = vt.shape[1]
    roles = chain.roles
    passive = list(chain.passive)
    k = len(passive)
    # J_q, column by column (a variable may appear in several factors)
    Aq = np.zeros((k, 6, n))
    slot = {v: i for i, v in enumerate(passive)}
    for var, kind, coef, e, o in recs:
        if roles[var] != "passive":
            continue
        col = Aq[slot[var]]
        if ROTATION[kind]:
            d = pe - o
            col[:3] += coef * _cross(e, d)
            col[3:] += coef * e
        else:
            col[:3] += coef * e
    N, ok = _wrench_basis(Aq)
    Nt, Nr = N[:, :3], N[:, 3:]
    # N^T J for the spring variables, grouped so that each einsum covers many factors
    want = set()
    for s in chain.springs:
        if s.name in springs:
            want.update(s.vars)
    groups = {}
    for r in recs:
        if r[0] in want:
            key = ("r", id(r[4])) if ROTATION[r[1]] else ("t",)
            groups.setdefault(key, []).append(r)
    zvar = {}
    for key, rs in groups.items():
        E = np.stack([r[3] for r in rs])
        if key[0] == "r":
            W = _cross(pe - rs[0][4], Nt) + Nr  # (m, 3, n)
        else:
            W = Nt
        Zg = np.einsum("rin,ain->ran", E, W)
        for r, z in zip(rs, Zg):
            z = z if r[2] == 1.0 else r[2] * z
            zvar[r[0]] = z if r[0] not in zvar else zvar[r[0]] + z
    Z = {s.name: np.stack([zvar[v] for v in s.vars], axis=1) for s in chain.springs if s.name in springs}
    return N, ok, Z, pe


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a x b`` over axis -2 (3 components), broadcasting: (..., 3, n)."""
    a0, a1, a2 = a[..., 0, :], a[..., 1, :], a[..., 2, :]
    b0, b1, b2 = b[..., 0, :], b[..., 1, :], b[..., 2, :]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-2)


def _wrench_basis(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal basis ``N`` (6-k, 6, n) of the complement of the columns ``A`` (k, 6, n).

    Householder QR without pivoting (backward stable; rank is not decided
    here); ``A`` is overwritten.  ``ok`` is False where the lower bound
    ``1 / (||R^-1||_F ||A||_F)`` of ``sigma_min / sigma_max`` is below
    ``FAST_RTOL`` (or not a number: a zero column).
    """
    k, _, n = A.shape
    m = 6 - k
    vs, betas = [], []
    Rm = np.zeros((k, k, n))
    for j in range(k):
        v = A[j, j:]  # becomes the Householder vector in place
        nx = np.sqrt(np.einsum("in,in->n", v, v))
        alpha = np.where(v[0] >= 0, -nx, nx)
        # beta = 2 / |v|^2; a zero column gives v = 0, so a huge beta is harmless
        beta = 1.0 / np.maximum(nx * (nx + np.abs(v[0])), 1e-300)
        v[0] -= alpha
        Rm[j, j] = alpha
        if j + 1 < k:
            sub = A[j + 1:, j:]
            w = np.einsum("lin,in->ln", sub, v) * beta
            sub -= w[:, None, :] * v
            Rm[j, j + 1:] = sub[:, 0]
        vs.append(v)
        betas.append(beta)
    # N = H_0 ... H_{k-1} [0; I]
    N = np.zeros((m, 6, n))
    for a in range(m):
        N[a, k + a] = 1.0
    for j in range(k - 1, -1, -1):
        sub = N[:, j:]
        w = np.einsum("ain,in->an", sub, vs[j]) * betas[j]
        sub -= w[:, None, :] * vs[j]
    ok = np.ones(n, dtype=bool)
    if k:
        # ||R^-1||_F >= 1/sigma_min and ||A||_F = ||R||_F >= sigma_max
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            Ri = upper_inverse(Rm)
            ok = 1.0 / np.sqrt(np.einsum("ijn,ijn->n", Ri, Ri) * np.einsum("ijn,ijn->n", Rm, Rm)) > FAST_RTOL
    return N, ok


def _reduced_stiffness(N, ok, Z: dict, compliances: dict):
    """``K = N (sum_s Z_s C_s Z_s^T)^-1 N^T`` with ``Z_s = N^T J_s`` (m, dof_s, n)."""
    m, _, n = N.shape
    M = np.zeros((m, m, n))
    for name, Zs in Z.items():
        C = np.asarray(compliances[name], dtype=float)
        if C.ndim == 2:
            Y = np.matmul(C.T, Zs)  # one small BLAS product per row of N (blocks keep it single-threaded)
        elif C.shape[1] == 1:
            Y = Zs * C[:, 0, 0]
        else:
            Y = np.einsum("acn,ncd->adn", Zs, C)
        M += np.einsum("acn,bcn->abn", Y, Zs)
    Mi, piv = spd_inverse(M)
    ok = ok & (piv > FAST_RTOL)
    W = np.einsum("abn,ain->bin", Mi, N)
    K = np.einsum("bin,bjn->ijn", W, N)
    K += K.transpose(1, 0, 2)
    K *= 0.5
    return K, ok


def _with_fallback(chain, K, ok, k, compliances, J_of):
    """Rank ``k`` where ``ok``; elsewhere K and rank from :func:`_bordered` on ``J_of(bad)`` (poses first)."""
    rank = np.full(K.shape[2], k)
    bad = np.nonzero(~ok)[0]
    if bad.size:
        cb = {key: (c[bad] if np.ndim(c) == 3 else c) for key, c in compliances.items() if c is not None}
        Kb, rank[bad] = _bordered(chain, J_of(bad), cb)
        K[:, :, bad] = Kb.transpose(1, 2, 0)
    return K, rank


@dataclass(frozen=True, eq=False)
class StiffnessResult:
    """Per-pose output of the stiffness model (the model itself stays immutable).

    Arrays carry a leading pose axis for :meth:`vjm.model.machine.ParallelModel.stiffness_map`
    and none for :meth:`vjm.model.machine.ParallelModel.stiffness`.

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
    rotation : (n, 3) platform orientation (rotation vector, rad) of 6-dof platforms, else None
    k_tran_spread, k_rot_spread : (n,) the spread of k_tran (mm/N) and k_rot (rad/(N mm)) when
        every link's compliance moves within its FEA error bar (:mod:`vjm.sweep.spread`): read
        ``k_tran +- k_tran_spread``.  Zero where no link carries an error estimate (analytic
        beams, inline matrices); NaN where K is singular; None unless asked for
        (``Model.stiffness_map(P, spread=True)``).
    spread_by_link : ``{link name: (k_tran part, k_rot part)}``, each (n,): what each link's
        bar contributes to the spread (the spread is their sum); None unless asked for
    """

    points: np.ndarray
    K: np.ndarray
    C: np.ndarray
    k_tran: np.ndarray
    k_rot: np.ndarray
    rank: np.ndarray
    invertible: np.ndarray
    chain_rank: np.ndarray = field(default=None)
    rotation: np.ndarray | None = None
    k_tran_spread: np.ndarray | None = None
    k_rot_spread: np.ndarray | None = None
    spread_by_link: dict | None = None

    def pose(self, i: int) -> "StiffnessResult":
        """The result of pose ``i`` alone (no leading axis)."""
        fields = ("points", "K", "C", "k_tran", "k_rot", "rank", "invertible", "chain_rank")
        opt = {f: None if getattr(self, f) is None else getattr(self, f)[i]
               for f in ("rotation", "k_tran_spread", "k_rot_spread")}
        by = None if self.spread_by_link is None else {k: (t[i], r[i]) for k, (t, r) in self.spread_by_link.items()}
        return StiffnessResult(**{f: getattr(self, f)[i] for f in fields}, **opt, spread_by_link=by)

    def to_dict(self) -> dict:
        """JSON-ready dict (single pose or map), frames and units stated."""
        out = {
            "point_mm": np.asarray(self.points).tolist(),
            "K": np.asarray(self.K).tolist(),
            "C": np.asarray(self.C).tolist(),
            "k_tran_mm_per_N": np.asarray(self.k_tran).tolist(),
            "k_rot_rad_per_Nmm": np.asarray(self.k_rot).tolist(),
            "rank": np.asarray(self.rank).tolist(),
            "invertible": np.asarray(self.invertible).tolist(),
            "chain_rank": np.asarray(self.chain_rank).tolist(),
            "frame": "world axes, origin at the end-effector point",
            "order": f"{' '.join(TWIST)} / {' '.join(WRENCH)}",
            "units": {"K": "N/mm, N/rad, N mm/rad", "C": "mm/N, mm/(N mm), rad/(N mm)"},
        }
        if self.rotation is not None:
            out["rotation_vector_rad"] = np.asarray(self.rotation).tolist()
        if self.k_tran_spread is not None:
            out["k_tran_spread_mm_per_N"] = np.asarray(self.k_tran_spread).tolist()
            out["k_rot_spread_rad_per_Nmm"] = np.asarray(self.k_rot_spread).tolist()
            out["spread_by_link"] = {k: {"k_tran_mm_per_N": np.asarray(t).tolist(),
                                         "k_rot_rad_per_Nmm": np.asarray(r).tolist()}
                                     for k, (t, r) in (self.spread_by_link or {}).items()}
            out["spread_note"] = SPREAD_NOTE
        return out

    def save(self, path):
        """Write :meth:`to_dict` as JSON (schema ``vjm.stiffness/1``, frame, order and units stated),
        atomically; a file at ``path`` that is not such a file is refused.  Returns the path.

        >>> import json, tempfile, pathlib, vjm
        >>> r = vjm.load_model("puu").stiffness([0.0, 0.0, 0.0])
        >>> p = r.save(pathlib.Path(tempfile.mkdtemp()) / "K.json")
        >>> json.loads(p.read_text())["frame"]
        'world axes, origin at the end-effector point'
        """
        from ..maps.views import STIFFNESS_SCHEMA, save_json

        return save_json(path, self.to_dict(), STIFFNESS_SCHEMA)

    def plot(self, ax=None, kind: str = "principal", pose: int = 0):
        """Draw one pose on ``ax`` (a new figure if None) and return the Axes.

        ``kind="principal"``: bars of the principal compliances, the eigenvalues of
        ``C[:3, :3]`` (mm/N) and ``C[3:, 3:]`` (rad/(N mm)) on two log axes -- how soft the
        machine is in its weakest and stiffest directions.  ``kind="matrix"``: the 6x6 ``C``
        as an image of log10 |C_ij|.  ``pose`` picks the pose of a multi-pose result.

        >>> import vjm
        >>> ax = vjm.load_model("puu").stiffness([0.0, 0.0, 0.0]).plot()
        >>> len(ax.patches)
        3
        """
        from ..maps.views import plot_matrix, plot_principal

        r = self.pose(pose) if np.ndim(self.K) == 3 else self
        title = f"at {np.round(np.asarray(r.points, dtype=float), 3).tolist()} mm"
        if kind == "principal":
            return plot_principal(r.C, ax=ax, title=f"principal compliances {title}")
        if kind == "matrix":
            return plot_matrix(r.C, ax=ax, title=f"C {title}")
        raise ValueError(f"kind must be 'principal' or 'matrix', got {kind!r}")

    def __repr__(self) -> str:
        """A few lines: the point (or the number of poses), k_tran, k_rot, rank; K and C are in the fields."""
        from ..maps.views import stiffness_text

        return stiffness_text(self.k_tran, self.k_rot, self.rank, self.points)

    def _repr_html_(self) -> str:
        from ..maps.views import stiffness_html

        return stiffness_html(self.K, self.C, self.k_tran, self.k_rot, self.rank, self.points)


def assemble(points: np.ndarray, chain_K: list, chain_ranks: list) -> StiffnessResult:
    """Machine stiffness: sum of the chains' K (eq. 13) and the derived compliances."""
    K = np.sum(chain_K, axis=0)
    C, rank, inv, kt, kr = assemble_soa(np.ascontiguousarray(K.transpose(1, 2, 0)))
    return StiffnessResult(points, K, np.ascontiguousarray(C.transpose(2, 0, 1)), kt, kr, rank, inv,
                           np.stack(chain_ranks, axis=1))


def assemble_soa(K: np.ndarray):
    """Compliance, rank and k values of machine stiffnesses K (6, 6, n) (pose axis last).

    Returns ``C`` (6, 6, n), ``rank``, ``invertible``, ``k_tran``, ``k_rot`` (n,),
    as :class:`StiffnessResult` defines them (see :func:`vjm.stiffness.linalg.psd_rank_inverse_soa`).
    """
    C, rank, inv = psd_rank_inverse_soa(K)
    kt = np.where(inv, sym3_max_eig_soa(C[:3, :3]), np.inf)
    kr = np.where(inv, sym3_max_eig_soa(C[3:, 3:]), np.inf)
    return C, rank, inv, kt, kr


# -- the compiled path (vjm.maps.map_kernel): the same arithmetic pose by pose ----------------------

@functools.cache
def _map_kernel():
    """The compiled kernels (:mod:`vjm.maps.map_kernel`), or None where numba is not installed."""
    try:
        from ..maps import map_kernel
    except ImportError:
        return None
    return map_kernel


def kernels_compiled() -> bool:
    """Whether the map kernels are compiled already: loaded in this process, or in numba's cache beside the
    source (``python -m vjm.kernels``, ``make install``, an earlier run); a stale cache (a source changed) is
    compiled again on first use.  False where numba is not installed."""
    mk = _map_kernel()
    if mk is None:
        return False
    entry = mk.machine_block
    if entry.signatures:
        return True
    try:   # numba's cache index of the entry point (a private attribute: any failure reads "not compiled")
        return os.path.exists(entry._cache._cache_file._index_path)
    except Exception:
        return False


def use_kernel(n: int, kernel: str | None = None) -> bool:
    """Whether a block of ``n`` poses runs the compiled kernels: ``kernel`` (or, if None, the
    environment variable ``VJM_MAP_KERNEL``) is ``auto`` (from ``KERNEL_FROM`` poses), ``numba``
    or ``numpy``."""
    choice = kernel if kernel is not None else (os.environ.get(KERNEL_ENV) or "auto")
    if choice not in KERNELS:
        raise ValueError(f"kernel must be one of {', '.join(KERNELS)}, got {choice!r}"
                         + ("" if kernel is not None else f" (environment variable {KERNEL_ENV})"))
    if choice == "numpy" or (choice == "auto" and n < KERNEL_FROM):
        return False
    return _map_kernel() is not None


#: machines (tuples of chains) as arrays for the kernel, by the chains' ids (the chains are kept in
#: the entry, so the ids stay their own)
_ENCODED: dict = {}


def _encoded(chains):
    """The chains' factors concatenated (code, var, coef, T and the offsets of each chain's), the
    offsets of their variables, and their passive variables (chain-local numbers) with offsets."""
    key = tuple(id(ch) for ch in chains)
    hit = _ENCODED.get(key)
    if hit is None or any(a is not b for a, b in zip(hit[0], chains)):
        from ..kinematics.ik import encode

        if len(_ENCODED) >= 64:
            _ENCODED.clear()
        enc = [encode(ch) for ch in chains]
        fo, vo, po = (np.cumsum([0] + [len(x) for x in xs]).astype(np.int64) for xs in
                      ([e[0] for e in enc], [range(ch.n_vars) for ch in chains], [ch.passive for ch in chains]))
        arrays = tuple(np.concatenate([e[i] for e in enc]) for i in range(4))
        passive = np.array([v for ch in chains for v in ch.passive], dtype=np.int64)
        hit = _ENCODED[key] = (tuple(chains), (*arrays, fo), vo, (passive, po))
    return hit[1], hit[2], hit[3]


def _packed_springs(chains, compliances: list, n: int):
    """The chains' non-rigid springs for :func:`vjm.maps.map_kernel.machine_block`: their variables
    (chain-local), each spring's bounds in them, each chain's range of springs, and the compliances
    row-major: each spring's offset in one buffer of the constant ones followed by the per-pose ones
    (n, ...)."""
    svar: list = []
    sb, sr, fix, pose, where = [0], [0], [], [], []
    for ch, comp in zip(chains, compliances):
        for s in ch.springs:
            c = comp.get(s.name)
            if c is None:
                continue
            c = np.asarray(c, dtype=float)
            svar += s.vars
            sb.append(len(svar))
            if c.ndim == 3:
                where.append((True, sum(x.shape[1] for x in pose)))
                pose.append(c.reshape(n, -1))
            else:
                where.append((False, sum(x.size for x in fix)))
                fix.append(c.ravel())
        sr.append(len(sb) - 1)
    nfix = sum(x.size for x in fix)
    off = np.array([o + (nfix if per else 0) for per, o in where], dtype=np.int64)
    return (np.array(svar, dtype=np.int64), np.array(sb, dtype=np.int64), np.array(sr, dtype=np.int64), off,
            np.concatenate(fix) if fix else np.zeros(0),
            np.concatenate(pose, axis=1) if pose else np.zeros((n, 0)))


def machine_block_compiled(chains, values, compliances, points, out, closed) -> None:
    """The machine stiffness at a block of poses by the compiled kernel, with the numpy path's
    decisions, written into ``out`` = (K, C (n, 6, 6), k_tran, k_rot, rank, invertible (n,),
    chain ranks (n, n_chains)).

    ``values`` per chain (n, n_vars), ``compliances`` per chain as :func:`chain_stiffness`,
    ``points`` (n, 3) the poses' points; ``closed(k, gap)`` checks chain k's largest closure gap
    (mm).  Poses a chain's fast closed form flags are redone by :func:`chain_stiffness_frames`
    (bordered solve near rank loss) and :func:`assemble_soa`, poses whose K is not invertible by
    :func:`vjm.stiffness.linalg.psd_rank_inverse` (pseudo-inverse, rank).
    """
    kern = _map_kernel()
    K, C, kt, kr, rank, inv, chain_rank = out
    n = K.shape[0]
    flag = np.zeros(n, dtype=np.bool_)
    gaps = np.zeros(len(chains))
    factors, vo, (passive, po) = _encoded(chains)
    vals = np.concatenate([np.asarray(v, dtype=float) for v in values], axis=1) if len(values) > 1 else \
        np.ascontiguousarray(values[0], dtype=float)
    kern.machine_block(*factors, vals, vo, passive, po, *_packed_springs(chains, compliances, n),
                       np.ascontiguousarray(points, dtype=float), FAST_RTOL, 1e-10,  # psd_rank_inverse_soa's rtol
                       K, C, rank, inv, kt, kr, flag, gaps)
    for k, ch in enumerate(chains):
        closed(k, gaps[k])
        chain_rank[:, k] = len(ch.passive)
    bad = np.flatnonzero(flag)
    if bad.size:
        Kb = np.zeros((6, 6, bad.size))
        for k, (ch, v, c) in enumerate(zip(chains, values, compliances)):
            cb = {key: (x[bad] if np.ndim(x) == 3 else x) for key, x in c.items()}
            Kc, chain_rank[bad, k], _ = chain_stiffness_frames(ch, np.ascontiguousarray(v[bad].T), cb)
            Kb += Kc
        Cb, rank[bad], inv[bad], kt[bad], kr[bad] = assemble_soa(Kb)
        K[bad] = np.transpose(Kb, (2, 0, 1))
        C[bad] = np.transpose(Cb, (2, 0, 1))
    sing = np.flatnonzero(~inv)
    if sing.size:
        C[sing], rank[sing], _ = psd_rank_inverse(K[sing])
