"""Rigid-motion fit and compliance checks on synthetic data with known answers."""
import numpy as np
import pytest

from linkfea.fem.fit import check_compliance, fit_rigid_motion
from linkfea.runtime.errors import LinkFeaError


def _points(n=40, seed=0):
    return np.random.default_rng(seed).uniform(-10, 10, size=(n, 3))


def test_fit_recovers_exact_rigid_motion():
    """u = d + r x (x - o) is recovered exactly (residual at round-off)."""
    pts = _points()
    o = np.array([1.0, -2.0, 0.5])
    d, r = np.array([1e-3, -2e-3, 5e-4]), np.array([2e-4, -1e-4, 3e-4])
    u = d + np.cross(r, pts - o)
    twist, res = fit_rigid_motion(pts, u, o)
    assert np.allclose(twist, np.r_[d, r], rtol=0, atol=1e-15)
    assert res < 1e-12


def test_fit_in_rotated_axes_and_batches():
    """With axes given, the twist components are in those axes; (k, n, 3) input gives (k, 6)."""
    pts = _points()
    c, s = np.cos(0.4), np.sin(0.4)
    axes = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])  # rows = frame axes in CAD
    t_frame = np.array([1e-3, 0.0, -1e-3, 0.0, 2e-4, -1e-4])
    d, r = axes.T @ t_frame[:3], axes.T @ t_frame[3:]
    u = d + np.cross(r, pts)
    twists, res = fit_rigid_motion(pts, np.stack([u, 2 * u]), np.zeros(3), axes)
    assert np.allclose(twists, [t_frame, 2 * t_frame], atol=1e-15)
    assert np.all(res < 1e-12)


def test_fit_reports_non_rigid_misfit():
    """A stretch is not a rigid motion: the residual is of order one, not zero."""
    pts = _points()
    u = 1e-3 * pts * np.array([1.0, 0.0, 0.0])  # uniaxial strain 1e-3 along x
    _, res = fit_rigid_motion(pts, u, np.zeros(3))
    assert res > 0.1


def test_fit_rejects_collinear_nodes():
    pts = np.outer(np.linspace(0, 1, 5), [1.0, 2.0, 3.0])
    with pytest.raises(LinkFeaError, match="rigid motion"):
        fit_rigid_motion(pts, np.zeros_like(pts), np.zeros(3))


def test_check_compliance_measures_asymmetry_then_symmetrizes():
    A = np.random.default_rng(2).standard_normal((6, 6))
    C = A @ A.T + 6 * np.eye(6)
    E = np.zeros((6, 6))
    E[0, 1] = 1e-3
    C_sym, err, min_ev = check_compliance(C + E)
    assert np.allclose(C_sym, C_sym.T)
    assert 1e-5 < err < 1e-3
    assert min_ev == pytest.approx(np.linalg.eigvalsh(C_sym)[0])
    _, err0, _ = check_compliance(C)
    assert err0 < 1e-15


def test_check_compliance_rejects_non_positive_definite():
    """An indefinite (or singular) matrix is not a compliance: LinkFeaError with a clear message."""
    C = np.diag([1.0, 1.0, 1.0, 1.0, 1.0, 1.0])
    C[0, 1] = C[1, 0] = 1.5  # eigenvalue -0.5
    with pytest.raises(LinkFeaError, match="not positive definite"):
        check_compliance(C)
    with pytest.raises(LinkFeaError, match="not positive definite"):
        check_compliance(np.diag([1.0, 1.0, 1.0, 1.0, 1.0, -1.0]))
    with pytest.raises(LinkFeaError, match="6x6"):
        check_compliance(np.eye(5))
