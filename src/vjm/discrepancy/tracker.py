"""A laser tracker's noise: standard deviations that grow with the distance and differ by axis.

A tracker measures a point by two angles and a range.  The angle encoders'
noise moves the point across the line of sight by an amount proportional to
the distance; the range meter's is nearly constant.  In the machine frame this
is modelled per axis as

    sigma_j(d) = sqrt(a_j^2 + (b_j d)^2),   j = dx, dy, dz,

with ``d`` the distance (mm) from the tracker's position to the measured
point (the commanded ``x,y,z``), ``a_j`` (mm) the floor and ``b_j`` (mm per
mm, e.g. 5e-6 = 5 um/m) the growth.  The sigmas so stated are used like
per-component sigma columns (``sigma_dx..sigma_dz``) of the file, and checked
against the residuals like them.  Rotations keep the file's ``sigma_r``
(or ``sigma_rx..sigma_rz``), or are estimated.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..errors import VjmError


@dataclass(frozen=True)
class TrackerNoise:
    """A tracker at ``origin`` (mm, machine frame) with noise floors ``a`` (mm) and growths ``b`` (mm/mm)
    per axis (dx, dy, dz)."""

    origin: tuple
    a: tuple
    b: tuple

    def __post_init__(self):
        for name, v in (("origin", self.origin), ("a", self.a), ("b", self.b)):
            if len(v) != 3 or not all(isinstance(x, (int, float)) and math.isfinite(x) for x in v):
                raise VjmError(f"tracker noise: {name} must be 3 finite numbers, got {v!r}")
        if any(x < 0 for x in self.a + self.b) or not any(x > 0 for x in self.a + self.b):
            raise VjmError(f"tracker noise: a {self.a} and b {self.b} must be >= 0, not all zero")

    @classmethod
    def parse(cls, position: str, noise: str) -> "TrackerNoise":
        """From the CLI: ``X,Y,Z`` and ``A,B`` (every axis) or ``AX,AY,AZ,BX,BY,BZ``."""
        def numbers(text, what):
            try:
                return [float(t) for t in str(text).split(",")]
            except ValueError:
                raise VjmError(f"{what}: {text!r} is not a comma-separated list of numbers") from None

        pos = numbers(position, "--tracker")
        ab = numbers(noise, "--tracker-noise")
        if len(pos) != 3:
            raise VjmError(f"--tracker: expected X,Y,Z (mm), got {position!r}")
        if len(ab) == 2:
            ab = [ab[0]] * 3 + [ab[1]] * 3
        if len(ab) != 6:
            raise VjmError(f"--tracker-noise: expected A,B or AX,AY,AZ,BX,BY,BZ (mm, mm/mm), got {noise!r}")
        return cls(tuple(pos), tuple(ab[:3]), tuple(ab[3:]))

    def sigmas(self, P) -> np.ndarray:
        """(n, 3) standard deviations of dx, dy, dz at the points P (n, 3)."""
        d = np.linalg.norm(np.asarray(P, float) - np.asarray(self.origin, float), axis=1)
        return np.sqrt(np.asarray(self.a) ** 2 + (np.asarray(self.b) * d[:, None]) ** 2)

    def apply(self, data):
        """Deflections with the translations' sigmas of this tracker (``sigma`` columns dx..dz); the file
        must not state them too."""
        stated = data.stated_sigmas()[:, :3]
        if np.isfinite(stated).any():
            col = "sigma_t" if data.sigma_t is not None else "sigma_dx..sigma_dz"
            raise VjmError(f"{data.source}: the file states the translations' sigmas ({col}) and a tracker noise "
                           "model was given: use one of them")
        sig = np.full((data.n, 6), np.nan) if data.sigma is None else data.sigma.copy()
        sig[:, :3] = self.sigmas(data.P)  # rotations: the file's sigma_rx..sigma_rz (here) or sigma_r (kept)
        return dataclasses.replace(data, sigma=sig)
