"""The result of a compensation: what to command so that the loaded tool lands where it was asked to.

Two producers return it:

* :func:`vjm.robot.compensate.compensate` (:meth:`vjm.robot.RobotModel.compensate`, ``vjm compensate``): a
  serial robot's joint commands reaching target poses or points under its own weight;
* the compensation of a toolpath (:mod:`vjm.toolpath.compensate` for a parallel machine,
  :mod:`vjm.toolpath.robot` for a robot; ``vjm path``): the commanded TCP poses whose loaded TCP lands on the
  programmed ones.

Both fill ``commanded`` and ``residual``; the fields only one of them fills are None (or their default) in the
other's, as their comments say.  Units mm, rad.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class Compensation:
    """What to command, per target or path point, and how well the loaded tool lands.

    ``commanded``: robot targets: the joint commands (n, nq) (rad, mm prismatic; the last iterate where not
    converged); a toolpath: the commanded TCP poses (n, 3) or (n, 6) (mm, rotation vector rad).
    ``residual`` (n,): the loaded (deflected) tool's distance from the target at the commands, mm (robot
    targets given as poses: the rotation error times :data:`vjm.robot.ik.LENGTH` counts too)."""

    commanded: np.ndarray
    residual: np.ndarray
    # -- robot targets only (vjm.robot.compensate); None for a toolpath --
    #: (n, nq) the rigid IK's (uncompensated) commands
    plain: np.ndarray | None = None
    #: (n,) the deflected pose within ``tol``
    converged: np.ndarray | None = None
    #: (n,) False: the rigid IK does not reach the target (out of reach or the joint limits in the way)
    reached: np.ndarray | None = None
    #: (n,) the tool Jacobian (next to) rank deficient at the command
    singular: np.ndarray | None = None
    #: (n,) the plain commands' deflected position error, mm: the sag compensated (NaN: not reached)
    miss: np.ndarray | None = None
    #: (n, 6) the tool's deflection at the commands, mm and rad (NaN: not reached)
    sag: np.ndarray | None = None
    #: (n,) iterations of the compensation per target (0: not run)
    iterations: np.ndarray | None = None
    #: the tolerance of the deflected pose, mm
    tol: float | None = None
    #: the targets were points: only their positions count, the orientation free
    positions_only: bool | None = None
    # -- a toolpath only (vjm.toolpath); None for robot targets --
    #: (n, 3) loaded TCP minus programmed point at the commands, mm
    residual_vector: np.ndarray | None = None
    #: the nonlinear equilibria used (the most any point needed, besides the deflection's own)
    equilibria: int | None = None
    #: check equilibria that could not start from the deflection's (solved by the reference solver)
    cold: int = 0
