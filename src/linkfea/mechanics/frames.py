"""Reference frames and the adjoint map that moves 6x6 compliances between them.

Conventions (used by linkfea and vjm alike):

* twist ``t = (dx, dy, dz, rx, ry, rz)``: translation of the frame origin and
  small right-handed rotation (omega = vee(dR R^T));
* wrench ``w = (Fx, Fy, Fz, Mx, My, Mz)``: force and moment about the frame
  origin, so that ``w . t`` is work;
* compliance ``C`` maps a wrench to a twist, ``t = C w`` (mm/N, rad/(N mm)).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..runtime.errors import LinkFeaError


def skew(v) -> np.ndarray:
    """Cross-product matrices: ``skew(a) @ b == np.cross(a, b)``.

    ``v`` (..., 3) gives (..., 3, 3); a complex ``v`` stays complex (vjm.stiffness.nonlinear
    differentiates by complex step), anything else becomes float.
    """
    v = np.asarray(v)
    if not np.iscomplexobj(v):
        v = v.astype(float)
    S = np.zeros(v.shape[:-1] + (3, 3), dtype=v.dtype)
    S[..., 0, 1], S[..., 0, 2] = -v[..., 2], v[..., 1]
    S[..., 1, 0], S[..., 1, 2] = v[..., 2], -v[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -v[..., 1], v[..., 0]
    return S


def rigid_motion_matrix(points: np.ndarray, origin: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """Nodal displacements (n, 3, 6) of a small rigid motion per unit twist component.

    Twist components are in the frame with rows ``axes``: ``u = R t + (R r) x (x - o)``
    with ``R = axes.T``.
    """
    R = np.asarray(axes, dtype=float).T
    d = np.asarray(points, dtype=float) - np.asarray(origin, dtype=float)
    out = np.empty((len(d), 3, 6))
    out[:, :, :3] = R
    # (R r) x d = -skew(d) R r
    out[:, :, 3:] = -skew(d) @ R
    return out


def twist_transform(R, p) -> np.ndarray:
    """6x6 map of twists from frame A to frame B.

    Frame B has origin ``p`` and axes given by the columns of ``R``, both
    expressed in frame A.  A rigid motion with twist ``t_A`` at A's origin
    (components in A) has twist ``X @ t_A`` at B's origin (components in B).
    Wrenches go the other way: ``w_A = X.T @ w_B``.
    """
    R = np.asarray(R, dtype=float)
    p = np.asarray(p, dtype=float)
    X = np.zeros((6, 6))
    X[:3, :3] = R.T
    X[:3, 3:] = -R.T @ skew(p)
    X[3:, 3:] = R.T
    return X


def transform_compliance(C, R, p) -> np.ndarray:
    """Compliance at frame A moved to frame B (origin ``p``, axes ``R`` in A).

    ``C_B = X C_A X^T`` with ``X = twist_transform(R, p)``.
    """
    X = twist_transform(R, p)
    return X @ np.asarray(C, dtype=float) @ X.T


def transform_stiffness(K, R, p) -> np.ndarray:
    """Stiffness at frame A moved to frame B: ``K_B = X^-T K_A X^-1``."""
    Xi = np.linalg.inv(twist_transform(R, p))
    return Xi.T @ np.asarray(K, dtype=float) @ Xi


@dataclass(frozen=True)
class Frame:
    """A right-handed frame in CAD coordinates (mm).

    Attributes
    ----------
    origin : ndarray, shape (3,)
    axes : ndarray, shape (3, 3)
        Rows are the unit x, y and z axes of the frame in CAD coordinates.
    """

    origin: np.ndarray
    axes: np.ndarray

    def __post_init__(self):
        o = np.asarray(self.origin, dtype=float).reshape(3)
        a = np.asarray(self.axes, dtype=float).reshape(3, 3)
        if not (np.all(np.isfinite(o)) and np.all(np.isfinite(a))):
            raise LinkFeaError("frame origin and axes must be finite numbers")
        if not np.allclose(a @ a.T, np.eye(3), atol=1e-9) or np.linalg.det(a) < 0:
            raise LinkFeaError("frame axes must be orthonormal and right-handed")
        object.__setattr__(self, "origin", o)
        object.__setattr__(self, "axes", a)

    @classmethod
    def from_x(cls, origin, x_axis, y_hint=(0.0, 1.0, 0.0)) -> "Frame":
        """Frame with its x axis along ``x_axis`` and y as close as possible to ``y_hint``."""
        x = np.asarray(x_axis, dtype=float)
        x = x / np.linalg.norm(x)
        y = np.asarray(y_hint, dtype=float)
        y = y - x * (x @ y)
        if np.linalg.norm(y) < 1e-9:
            y = np.array([0.0, 0.0, 1.0]) - x * x[2]
        y = y / np.linalg.norm(y)
        return cls(origin, np.vstack([x, y, np.cross(x, y)]))

    @property
    def R(self) -> np.ndarray:
        """Rotation whose columns are the frame axes (CAD <- frame)."""
        return self.axes.T

    def compliance_to(self, C, other: "Frame") -> np.ndarray:
        """Move compliance ``C`` given in this frame to frame ``other``."""
        R_rel = self.axes @ other.axes.T  # other's axes in this frame's components
        p_rel = self.axes @ (other.origin - self.origin)
        return transform_compliance(C, R_rel, p_rel)

    def to_dict(self) -> dict:
        return {
            "origin": self.origin.tolist(),
            "x_axis": self.axes[0].tolist(),
            "y_axis": self.axes[1].tolist(),
            "z_axis": self.axes[2].tolist(),
            "units": "mm",
            "note": "origin and axes in CAD coordinates",
        }

    @classmethod
    def from_dict(cls, d: dict) -> "Frame":
        try:
            return cls(d["origin"], np.vstack([d["x_axis"], d["y_axis"], d["z_axis"]]))
        except (KeyError, TypeError, ValueError) as exc:
            raise LinkFeaError(f"frame: expected keys origin, x_axis, y_axis, z_axis ({exc})") from None
