"""What an architecture provides to :class:`vjm.model.machine.ParallelModel`.

An architecture turns a model's parameters into chains (built once per
model) and, for a batch of end-effector points, into each chain's nominal
variable values (inverse kinematics) and spring compliances.
"""
from __future__ import annotations

import numpy as np

from ..errors import VjmError
from ..kinematics.chain import Chain

#: spring names shared by the chains and the compliances of every architecture (one string contract)
ACTUATOR = "actuator"
FOOT = "foot"
LEG = "leg"


class Architecture:
    """Base class; subclasses set ``name``, ``geometry_keys`` and implement the hooks.

    A new architecture is one module with a subclass and one line in
    ``vjm.architectures.ARCHITECTURES`` (see ``docs/add_architecture.md``).
    """

    name = ""
    #: poses per inverse-kinematics batch of a map (the stiffness runs in blocks of ``model.MAP_BLOCK``)
    ik_block = 2048
    #: the spring names its chains declare (``ChainBuilder`` names, keys of :meth:`compliances`)
    springs: tuple[str, ...] = (ACTUATOR, FOOT, LEG)
    geometry_keys: tuple[str, ...] = ()
    #: bars that make up one leg: 1, or 2 for a parallelogram leg (whose ``leg`` spring is one bar)
    leg_bars = 1
    #: unit of the actuator stiffness (prismatic N/mm, rotary N mm/rad)
    actuator_unit = "N/mm"

    #: named points marked on the maps, label -> (x, y, z) mm
    landmarks: dict[str, tuple[float, float, float]] = {}
    #: default workspace box ((xmin, ymin, zmin), (xmax, ymax, zmax)) in mm, for maps
    workspace = ((-100.0, -100.0, -100.0), (100.0, 100.0, 100.0))

    def chains(self, model) -> tuple[Chain, ...]:
        raise NotImplementedError

    def bind(self, model) -> "Architecture":
        """The architecture as one model sees it (a described machine carries its own workspace)."""
        return self

    def validate(self, model) -> None:
        """Checks of a model that depend on the architecture (VjmError)."""
        if model.foot.compliance is None and model.leg.compliance is None:
            raise VjmError("foot and leg are both rigid: the legs' constraint directions would be infinitely "
                           "stiff; give at least one of them a compliance")

    def platform_dof(self, model) -> int:
        """3 (a translational platform, the built-in architectures) or 6."""
        return 3

    def kinematic_key(self, model):
        """Anything besides architecture, geometry and joint springs that the chains depend on."""
        return None

    def solve(self, model, frames: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
        """Inverse kinematics of platform frames (n, 4, 4): actuator coordinates and chain values.

        Translational architectures answer from the points alone (their
        closed-form :meth:`inverse_kinematics`).
        """
        return self.inverse_kinematics(model, frames[:, :3, 3])

    def reachable(self, model, P: np.ndarray) -> np.ndarray:
        """Boolean mask (n,) of points the inverse kinematics accepts."""
        raise NotImplementedError

    def inverse_kinematics(self, model, P: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
        """Actuator coordinates (n, n_chains) and each chain's variable values (n, n_vars)."""
        raise NotImplementedError

    def compliances(self, model, P, chain_values, q_act) -> list[dict]:
        """Per chain, ``{spring name: compliance (k,k) or (n,k,k)}`` (rigid springs omitted)."""
        raise NotImplementedError


def actuator_compliance(model, q: np.ndarray) -> np.ndarray:
    """Actuator compliance (n, 1, 1) at actuator coordinates ``q`` (n,).

    ``c(q) = 1/k0 + slope * (q - q_ref)`` (e.g. a ball screw whose nut moves away
    from the bearing); constant when ``slope == 0``.
    """
    a = model.actuator
    c = 1.0 / a.stiffness + a.compliance_slope * (np.asarray(q, dtype=float) - a.q_ref)
    if np.any(c <= 0):
        bad = np.asarray(q)[c <= 0].ravel()[0]
        raise VjmError(f"actuator.compliance_slope gives a non-positive actuator compliance at q = {bad:.6g}; "
                       "reduce the slope or the travel")
    return c[:, None, None]


def joint_spring_compliance(model) -> np.ndarray | None:
    k = model.joints.passive_stiffness
    return None if k is None else np.array([[1.0 / k]])


def as_points(P) -> np.ndarray:
    P = np.asarray(P, dtype=float)
    if P.ndim == 1:
        P = P[None, :]
    if P.ndim != 2 or P.shape[1] != 3:
        raise VjmError(f"end-effector points must have shape (n, 3), got {np.shape(P)}")
    if not np.all(np.isfinite(P)):
        raise VjmError("end-effector points must be finite numbers")
    return P
