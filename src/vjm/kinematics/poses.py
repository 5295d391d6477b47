"""Per-pose kinematics of a model: pinocchio's Model / Data split.

A :class:`~vjm.model.machine.ParallelModel` is immutable and holds parameters only.
``model.kinematics(P)`` solves the inverse kinematics of a batch of platform
poses once and returns a :class:`Kinematics`: the platform frames, the
actuator coordinates, every chain's variable values and (on first use) the
chain Jacobians.  ``stiffness_map``, ``joint_forces``, ``vjm.stiffness.nonlinear`` and the
discrepancy predictions all start from it, so the pose sequence
IK -> compliances -> chain stiffness lives in one place.

Kinematics depend on the architecture, the geometry and the chain structure
only, never on a compliance: a model changed by ``replace`` in its springs
(as a calibration does) accepts the kinematics of the original one.

Poses
-----
A pose is the platform frame in world coordinates: a point ``(x, y, z)`` (mm)
for a translational platform, or ``(x, y, z, rx, ry, rz)`` with ``(rx, ry, rz)``
the rotation vector (axis times angle, rad) of the platform's orientation, or
a 4x4 homogeneous matrix.  :func:`as_poses` turns any of these, single or
batched, into (n, 4, 4) frames.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..errors import VjmError
from .chain import Chain, jacobian


def rotation_matrix(w) -> np.ndarray:
    """Rotation matrices (n, 3, 3) of rotation vectors w (n, 3) (Rodrigues; exact at w = 0)."""
    w = np.asarray(w, dtype=float)
    th = np.linalg.norm(w, axis=-1)
    small = th < 1e-8
    ths = np.where(small, 1.0, th)
    a = np.where(small, 1.0 - th**2 / 6.0, np.sin(ths) / ths)
    b = np.where(small, 0.5 - th**2 / 24.0, (1.0 - np.cos(ths)) / ths**2)
    W = np.zeros(w.shape[:-1] + (3, 3))
    W[..., 0, 1], W[..., 0, 2] = -w[..., 2], w[..., 1]
    W[..., 1, 0], W[..., 1, 2] = w[..., 2], -w[..., 0]
    W[..., 2, 0], W[..., 2, 1] = -w[..., 1], w[..., 0]
    return np.eye(3) + a[..., None, None] * W + b[..., None, None] * (W @ W)


def as_poses(P, dof: int = 3) -> np.ndarray:
    """Platform frames (n, 4, 4) from points (n, 3), poses (n, 6) or frames (n, 4, 4) (or one of them).

    ``dof`` is the platform's number of degrees of freedom: with 3 (translations
    only) the orientation must be the identity.  VjmError on anything else.
    """
    P = np.asarray(P, dtype=float)
    if P.shape in ((3,), (6,), (4, 4)):
        P = P[None]
    if P.ndim == 2 and P.shape[1] in (3, 6):
        if not np.all(np.isfinite(P)):
            raise VjmError("poses must be finite numbers")
        T = np.zeros((P.shape[0], 4, 4))
        T[:, :3, 3] = P[:, :3]
        T[:, 3, 3] = 1.0
        T[:, :3, :3] = rotation_matrix(P[:, 3:]) if P.shape[1] == 6 else np.eye(3)
    elif P.ndim == 3 and P.shape[1:] == (4, 4):
        if not np.all(np.isfinite(P)):
            raise VjmError("poses must be finite numbers")
        R = P[:, :3, :3]
        err = np.max(np.abs(R @ np.swapaxes(R, 1, 2) - np.eye(3)), initial=0.0)
        if err > 1e-9 or np.any(np.abs(P[:, 3] - [0, 0, 0, 1]) > 0) or np.any(np.linalg.det(R) < 0):
            raise VjmError("4x4 poses must be homogeneous frames with a proper rotation (R R^T = I, det R = 1)")
        T = np.array(P)
    else:
        raise VjmError(f"poses must have shape (n, 3) points, (n, 6) x,y,z,rx,ry,rz or (n, 4, 4) frames; "
                       f"got {np.shape(P)}")
    if dof == 3:
        tilt = np.max(np.abs(T[:, :3, :3] - np.eye(3)), initial=0.0)
        if tilt > 1e-12:
            raise VjmError("this platform has 3 dof (translations only): the pose's orientation must be zero")
    return T


@dataclass(frozen=True, eq=False)
class Kinematics:
    """Inverse kinematics of a batch of poses for one model (the per-pose "Data").

    Attributes
    ----------
    key : the kinematic identity of the model it belongs to (see ``Model.kinematic_key``)
    chains : the model's chains
    frames : (n, 4, 4) platform frames, world coordinates, mm
    q : (n, n_chains) actuator coordinates (mm, or rad for rotary actuators)
    values : per chain, (n, n_vars) values of every chain variable (springs at 0)
    """

    key: tuple
    chains: tuple[Chain, ...]
    frames: np.ndarray
    q: np.ndarray
    values: tuple[np.ndarray, ...]

    @property
    def n(self) -> int:
        return self.frames.shape[0]

    @property
    def points(self) -> np.ndarray:
        """(n, 3) end-effector points, mm."""
        return self.frames[:, :3, 3]

    @cached_property
    def jacobians(self) -> tuple[np.ndarray, ...]:
        """Per chain, the full Jacobian (n, 6, n_vars) (eq. 3-5): world axes at the end-effector point."""
        return tuple(jacobian(ch, v)[1] for ch, v in zip(self.chains, self.values))

    @cached_property
    def stiffness_memo(self) -> tuple[dict, ...]:
        """Per chain, a dict for the geometric part of the chain stiffness at these poses
        (:func:`vjm.stiffness.linear.chain_stiffness_frames`): kept here, since it depends on no
        compliance, so every model sharing these kinematics reuses it."""
        return tuple({} for _ in self.chains)

    def take(self, idx) -> Kinematics:
        """The kinematics of a subset (slice or index array) of the poses."""
        return Kinematics(self.key, self.chains, self.frames[idx], self.q[idx], tuple(v[idx] for v in self.values))
