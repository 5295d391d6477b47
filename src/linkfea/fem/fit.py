"""From unit-load displacements to a checked 6x6 compliance.

The twist of the reference block is fitted to all of its nodal displacements
by linear least squares (SVD): these are redundant data, as recommended in
the seed paper (Pashkevich, Chablat & Wenger, sec. 3.3).  Column ``k`` of the
compliance is the fitted twist under unit wrench ``k``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mechanics.compliance import Compliance, check
from ..mechanics.frames import Frame, rigid_motion_matrix, twist_transform
from ..runtime.errors import LinkFeaError


def _rigid_basis(points, origin, axes) -> np.ndarray:
    return rigid_motion_matrix(points, origin, axes).reshape(-1, 6)


def _lstsq_svd(A: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """Least-squares solution of ``A X = Y`` through the SVD of ``A``; rank-deficient ``A`` is an error."""
    Uu, s, Vt = np.linalg.svd(A, full_matrices=False)
    if s.size < 6 or s[-1] <= 1e-10 * s[0]:
        raise LinkFeaError("the reference nodes do not determine a rigid motion "
                           "(fewer than 3 non-collinear nodes)")
    return Vt.T @ ((Uu.T @ Y) / s[:, None])


def fit_rigid_motion(points, displacements, origin, axes=None):
    """Small rigid motion best fitting nodal displacements, by SVD least squares.

    Parameters
    ----------
    points : array (n, 3)
        Node coordinates.
    displacements : array (n, 3) or (k, n, 3)
        Nodal displacements, one or ``k`` load cases.
    origin : array (3,)
        Point where the twist's translation is taken.
    axes : array (3, 3), optional
        Rows are the axes in which the twist components are expressed
        (default: the coordinate axes of ``points``).

    Returns
    -------
    twist : ndarray (6,) or (k, 6)
        ``(dx, dy, dz, rx, ry, rz)``; ``u(x) = d + r x (x - origin)``.
    residual : float or ndarray (k,)
        Relative RMS misfit ``||u - u_fit|| / ||u||`` (0 for an exact rigid motion).
    """
    pts = np.asarray(points, dtype=float)
    u = np.asarray(displacements, dtype=float)
    single = u.ndim == 2
    u = u[None] if single else u
    if pts.ndim != 2 or pts.shape[1] != 3 or u.shape[1:] != pts.shape:
        raise LinkFeaError(f"fit_rigid_motion: points {pts.shape} and displacements {u.shape} do not match")
    A = _rigid_basis(pts, origin, np.eye(3) if axes is None else axes)
    Y = u.reshape(len(u), -1).T  # (3n, k)
    T = _lstsq_svd(A, Y)
    res = np.linalg.norm(A @ T - Y, axis=0) / np.maximum(np.linalg.norm(Y, axis=0), np.finfo(float).tiny)
    return (T[:, 0], float(res[0])) if single else (T.T, res)


def fit_compliance(sol, frame: Frame | None = None):
    """Raw 6x6 compliance from the 6 unit-load solutions, by rigid fit of the reference nodes.

    Parameters
    ----------
    sol : linkfea.fem.problem.FeaSolution
    frame : Frame, optional
        Frame of the result (default ``sol.frame``, the frame of the loads).

    Returns
    -------
    C_raw : ndarray (6, 6)
        Column ``k`` is the twist (frame axes, at frame origin) under unit wrench ``k``.
    residuals : ndarray (6,)
        Relative fit residual of each load case.
    """
    frame = sol.frame if frame is None else frame
    idx = np.asarray(sol.ref_nodes)
    twists, res = fit_rigid_motion(sol.points[idx], sol.displacements[:, idx, :], frame.origin, frame.axes)
    C = twists.T
    if frame is not sol.frame:
        # Loads were unit wrenches in sol.frame; express them in `frame` too: C_B = X C_A X^T,
        # and here the fitted twists are already in B, so only the wrench side moves: w_A = X^T w_B.
        R_rel = sol.frame.axes @ frame.axes.T
        p_rel = sol.frame.axes @ (frame.origin - sol.frame.origin)
        C = C @ twist_transform(R_rel, p_rel).T
    return C, res


def check_compliance(C_raw):
    """Measure the asymmetry of a raw FEA compliance, symmetrize it and check it.

    The symmetry error is a diagnostic of the fit, measured on the diagonally scaled matrix
    ``S = D^-1/2 C D^-1/2`` (units mix mm/N and rad/(N mm)): ``||S - S^T||_F / ||S + S^T||_F``.
    The symmetrized matrix then goes through the one compliance check,
    :func:`linkfea.mechanics.compliance.check`.

    Returns
    -------
    C_sym : ndarray (6, 6)
    symmetry_error : float
    min_eigenvalue : float
        Smallest eigenvalue of ``C_sym`` (in its mixed units).

    Raises
    ------
    LinkFeaError
        If the matrix is not finite, not 6x6 or not positive definite.
    """
    C = np.asarray(C_raw, dtype=float)
    try:
        C_sym = check(0.5 * (C + C.T) if C.shape == (6, 6) else C)
    except LinkFeaError as exc:
        raise LinkFeaError(f"{exc}; check the mesh, the clamp and the reference interfaces "
                           "(is the link clamped, and is the reference block attached?)") from None
    s = 1.0 / np.sqrt(np.diag(C))
    S = C * s[:, None] * s[None, :]
    sym_err = float(np.linalg.norm(S - S.T) / np.linalg.norm(S + S.T))
    return C_sym, sym_err, float(np.linalg.eigvalsh(C_sym)[0])


@dataclass(frozen=True)
class FittedCompliance:
    """The compliance fitted from an FEA solution, with the fit's diagnostics.

    Attributes
    ----------
    matrix : ndarray (6, 6)
        Symmetrized compliance, order Fx Fy Fz Mx My Mz -> dx dy dz rx ry rz;
        units mm/N, rad/(N mm) and mixed mm/(N mm) = rad/N.
    raw : ndarray (6, 6)
        Before symmetrization.
    frame : Frame
        Frame of the wrench and twist components and of the reference point.
    symmetry_error : float
    fit_residual : float
        Largest relative residual of the 6 rigid fits.
    min_eigenvalue : float
    fit_residuals : ndarray (6,)
    """

    matrix: np.ndarray
    raw: np.ndarray
    frame: Frame
    symmetry_error: float
    fit_residual: float
    min_eigenvalue: float
    fit_residuals: np.ndarray = None

    @property
    def stiffness(self) -> np.ndarray:
        """Inverse of the compliance (N/mm, N mm/rad)."""
        return np.linalg.inv(self.matrix)

    @property
    def compliance(self) -> Compliance:
        """The checked value (matrix, frame, units) handed on to results and vjm."""
        return Compliance(self.matrix, self.frame)

    def to_frame(self, frame: Frame) -> "FittedCompliance":
        """The same compliance expressed at another frame (adjoint map)."""
        return FittedCompliance(self.frame.compliance_to(self.matrix, frame), self.frame.compliance_to(self.raw, frame),
                                frame, self.symmetry_error, self.fit_residual, self.min_eigenvalue, self.fit_residuals)


def compliance_from_solution(sol, frame: Frame | None = None) -> FittedCompliance:
    """Fit, check and wrap the compliance of a :class:`linkfea.fem.problem.FeaSolution`."""
    C_raw, res = fit_compliance(sol, frame)
    C, sym_err, min_ev = check_compliance(C_raw)
    return FittedCompliance(C, C_raw, sol.frame if frame is None else frame, sym_err, float(np.max(res)), min_ev,
                            np.asarray(res))
