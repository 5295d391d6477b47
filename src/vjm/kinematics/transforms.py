"""Elementary homogeneous transforms Tx..Rz, batched over poses, and their generators.

Conventions: right-handed rotations, ``Rx(a) = [[1,0,0],[0,c,-s],[0,s,c]]``.
The generator of a factor ``V(a)`` is ``G = V(a)^-1 dV/da`` (independent of
``a``), so ``dV/da = V(a) G``.  For ``Rx`` it is the standard
``[[0,0,0],[0,0,-1],[0,1,0]]`` (the seed's eq. 4 prints its transpose).
"""
from __future__ import annotations

import numpy as np

KINDS = ("tx", "ty", "tz", "rx", "ry", "rz")
#: axis index (0, 1, 2) of each elementary kind
AXIS = {k: i % 3 for i, k in enumerate(KINDS)}
ROTATION = {k: k[0] == "r" for k in KINDS}


def elementary(kind: str, a) -> np.ndarray:
    """Stack of elementary transforms ``kind(a)`` for an array ``a`` of shape (n,).

    Returns an array of shape (n, 4, 4).  Works with complex ``a`` too (the
    nonlinear solver differentiates by complex step).
    """
    a = np.asarray(a)
    n = a.shape[0]
    T = np.zeros((n, 4, 4), dtype=np.result_type(a.dtype, float))
    T[:, 0, 0] = T[:, 1, 1] = T[:, 2, 2] = T[:, 3, 3] = 1.0
    ax = AXIS[kind]
    if not ROTATION[kind]:
        T[:, ax, 3] = a
        return T
    c, s = np.cos(a), np.sin(a)
    i, j = [(1, 2), (2, 0), (0, 1)][ax]  # plane of rotation, right-handed
    T[:, i, i] = c
    T[:, j, j] = c
    T[:, i, j] = -s
    T[:, j, i] = s
    return T


def generator(kind: str) -> np.ndarray:
    """4x4 generator ``G`` with ``dV/da = V(a) G`` for an elementary kind."""
    G = np.zeros((4, 4))
    ax = AXIS[kind]
    if not ROTATION[kind]:
        G[ax, 3] = 1.0
        return G
    i, j = [(1, 2), (2, 0), (0, 1)][ax]
    G[i, j] = -1.0
    G[j, i] = 1.0
    return G


def homogeneous(R=None, p=None) -> np.ndarray:
    """4x4 homogeneous matrix from a rotation and a translation."""
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    if p is not None:
        T[:3, 3] = p
    return T


def vee(W) -> np.ndarray:
    """Axial vector of the skew part of ``W`` (..., 3, 3): ``vee(skew(w)) == w``."""
    W = np.asarray(W)
    return 0.5 * np.stack([W[..., 2, 1] - W[..., 1, 2],
                           W[..., 0, 2] - W[..., 2, 0],
                           W[..., 1, 0] - W[..., 0, 1]], axis=-1)


def rotation_vector(R) -> np.ndarray:
    """Rotation vector (axis * angle) of rotation matrices (..., 3, 3), angle < pi."""
    R = np.asarray(R, dtype=float)
    w = vee(R)
    s = np.linalg.norm(w, axis=-1)
    c = 0.5 * (np.trace(R, axis1=-2, axis2=-1) - 1.0)
    ang = np.arctan2(s, c)
    scale = np.where(s > 1e-12, ang / np.where(s > 1e-12, s, 1.0), 1.0 + ang**2 / 6.0)
    return w * scale[..., None]
