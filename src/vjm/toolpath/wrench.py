"""The process wrench at the tool centre point along a toolpath: per point, constant, or a milling model.

Each source is a small strategy object with ``wrenches(toolpath) -> (n, 6)``: Fx Fy Fz Mx My Mz
(N, N mm), world axes, acting on the tool at the TCP.

:class:`Milling` is a **model**, not a measurement: a mechanistic cutting force
``F = kc * h_m * a_p`` opposing the feed, with ``h_m = f_z * a_e / D`` a mean
chip thickness (``f_z`` feed per tooth, ``a_e`` radial width of cut, ``D`` the
cutter diameter, ``D = a_e`` for a full slot) and ``a_p`` the axial depth.  It
ignores the radial and axial components, run-out and the tooth-passing
variation; it gives the order of magnitude and the direction a path sees, and
a measured wrench (CSV columns Fx..Mz) replaces it where one is known.
Rapid moves (G0) carry no cutting force.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import VjmError


@dataclass(frozen=True)
class PerPoint:
    """The wrench columns Fx..Mz of a CSV toolpath."""

    def wrenches(self, tp) -> np.ndarray:
        if tp.wrench is None:
            raise VjmError(f"{tp.source}: no wrench columns Fx..Mz; give --wrench or --milling options")
        return np.asarray(tp.wrench, dtype=float)


@dataclass(frozen=True)
class Constant:
    """One wrench (6,) at every cutting point (rapid moves: none)."""

    wrench: tuple

    def __post_init__(self):
        w = np.asarray(self.wrench, dtype=float)
        if w.shape != (6,) or not np.all(np.isfinite(w)):
            raise VjmError(f"--wrench expects six finite numbers Fx,Fy,Fz,Mx,My,Mz (N, N mm), got {self.wrench!r}")

    def wrenches(self, tp) -> np.ndarray:
        return np.where(tp.cutting[:, None], np.asarray(self.wrench, dtype=float)[None], 0.0)


@dataclass(frozen=True)
class Milling:
    """The mechanistic milling force of the module docstring (a model), opposing the feed direction.

    kc : specific cutting force, N/mm^2 (e.g. ~700 for aluminium alloys, ~2000 for steel)
    feed_per_tooth : f_z, mm;  depth : axial depth of cut a_p, mm;  width : radial width a_e, mm
    diameter : cutter diameter D, mm (None: a full slot, D = a_e)
    """

    kc: float
    feed_per_tooth: float
    depth: float
    width: float
    diameter: float | None = None

    def __post_init__(self):
        for k in ("kc", "feed_per_tooth", "depth", "width") + (("diameter",) if self.diameter is not None else ()):
            v = getattr(self, k)
            if not (isinstance(v, (int, float)) and np.isfinite(v) and v > 0):
                raise VjmError(f"--{k.replace('_', '-')} must be a number > 0, got {v!r}")
        if self.diameter is not None and self.width > self.diameter:
            raise VjmError(f"--width {self.width:g} mm exceeds the cutter --diameter {self.diameter:g} mm")

    @property
    def force(self) -> float:
        """Magnitude of the cutting force, N."""
        D = self.width if self.diameter is None else self.diameter
        return self.kc * self.feed_per_tooth * self.width / D * self.depth

    def wrenches(self, tp) -> np.ndarray:
        W = np.zeros((tp.n, 6))
        W[:, :3] = -self.force * tp.directions()
        W[~tp.cutting] = 0.0
        return W


def at_platform(W_tcp, lever) -> np.ndarray:
    """The wrench (n, 6) at the platform point of a wrench ``W_tcp`` (n, 6) at the TCP, ``lever`` (n, 3)
    the TCP's position from the platform point in world axes: ``M += lever x F``."""
    W = np.array(W_tcp, dtype=float)
    W[:, 3:] += np.cross(lever, W[:, :3])
    return W
