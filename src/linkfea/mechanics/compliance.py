"""The 6x6 compliance that linkfea hands to vjm: matrix, frame, units, the one check, and the
shared conventions (wrench and twist labels, units) both packages import from here.

One validator and one tolerance policy for every place a compliance enters the programs
(the FEA fit, a saved result JSON, a vjm model file or link):

* a finite 6x6 matrix of numbers, order ``Fx Fy Fz Mx My Mz`` -> ``dx dy dz rx ry rz``;
* a positive diagonal;
* symmetric: ``|C_ij - C_ji| <= SYMMETRY_RTOL * sqrt(C_ii C_jj)`` (scaled by the diagonal,
  since the blocks mix mm/N and rad/(N mm), so an absolute tolerance would be meaningless);
* positive definite: the smallest eigenvalue of the diagonally scaled symmetric part
  ``D^-1/2 C D^-1/2`` above ``PD_RTOL`` times its largest.

The FEA fit measures the asymmetry of its raw matrix (a diagnostic) and symmetrizes it
before this check (:func:`linkfea.fem.fit.check_compliance`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..runtime.errors import LinkFeaError
from .frames import Frame

__all__ = ["Compliance", "PD_RTOL", "SYMMETRY_RTOL", "TWIST", "UNITS", "UNITS_SHORT", "WRENCH", "check"]

# The conventions linkfea and vjm share, in one place (vjm's models, measurement files and
# results import them from here): wrench and twist order, units.  Units: N, mm, MPa, rad.

#: wrench order (N, N mm)
WRENCH = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")
#: twist order (mm, rad)
TWIST = ("dx", "dy", "dz", "rx", "ry", "rz")
#: units of a saved compliance and stiffness, by block, and of the base quantities
UNITS = {
    "compliance": {"force->translation": "mm/N", "moment->rotation": "rad/(N*mm)",
                   "moment->translation": "mm/(N*mm) = 1/N", "force->rotation": "rad/N"},
    "stiffness": {"translation->force": "N/mm", "rotation->moment": "N*mm/rad",
                  "rotation->force": "N/rad", "translation->moment": "N*mm/mm = N"},
    "length": "mm", "force": "N", "moment": "N*mm", "stress": "MPa", "time": "s",
}
#: the same in one line, for matrices printed to a terminal
UNITS_SHORT = "t = C w; mm/N, rad/N, mm/(N mm), rad/(N mm) by block"

SYMMETRY_RTOL = 1e-6
"""Largest accepted ``|C_ij - C_ji| / sqrt(C_ii C_jj)``."""
PD_RTOL = 1e-12
"""Smallest accepted eigenvalue of the diagonally scaled matrix, relative to its largest."""


def check(C, what: str = "compliance") -> np.ndarray:
    """The symmetrized float copy of a valid compliance, or :class:`LinkFeaError` naming ``what``."""
    try:
        C = np.array(C, dtype=float)
    except (TypeError, ValueError):
        raise LinkFeaError(f"{what} must be a 6x6 matrix of numbers") from None
    if C.shape != (6, 6):
        raise LinkFeaError(f"{what} must be a finite 6x6 matrix (order Fx Fy Fz Mx My Mz), got shape {C.shape}")
    if not np.all(np.isfinite(C)):
        raise LinkFeaError(f"{what} must be a finite 6x6 matrix, it has non-finite entries")
    d = np.diag(C)
    if np.any(d <= 0):
        k = int(np.argmin(d))
        raise LinkFeaError(f"{what} is not positive definite: diagonal entry {k} ({TWIST[k]}/{WRENCH[k]}) "
                           f"is {d[k]:.3e} <= 0")
    scale = np.sqrt(np.outer(d, d))
    asym = float(np.max(np.abs(C - C.T) / scale))
    if asym > SYMMETRY_RTOL:
        raise LinkFeaError(f"{what} is not symmetric: max |C_ij - C_ji| / sqrt(C_ii C_jj) = {asym:.3g} "
                           f"> {SYMMETRY_RTOL:g}")
    C = 0.5 * (C + C.T)
    ev = np.linalg.eigvalsh(C / scale)
    if ev[0] <= PD_RTOL * ev[-1]:
        raise LinkFeaError(f"{what} is not positive definite (smallest eigenvalue of the diagonally scaled "
                           f"matrix {ev[0]:.3e})")
    return C


@dataclass(frozen=True, eq=False)
class Compliance:
    """A checked 6x6 compliance in a stated frame.

    ``matrix`` maps a wrench ``(Fx Fy Fz Mx My Mz)`` (N, N mm) at the frame origin, in frame
    axes, to the twist ``(dx dy dz rx ry rz)`` (mm, rad) there: ``t = C w``.  The matrix is
    checked (:func:`check`), symmetrized and made read-only at construction.

    >>> import numpy as np
    >>> c = Compliance(np.diag([1e-3, 2e-3, 2e-3, 1e-6, 1e-6, 1e-6]))
    >>> float(c.stiffness[0, 0])
    1000.0
    """

    matrix: np.ndarray
    frame: Frame | None = None
    units: dict = field(default_factory=lambda: UNITS)
    what: str = field(default="compliance", repr=False)

    def __post_init__(self):
        C = check(self.matrix, self.what)
        C.setflags(write=False)
        object.__setattr__(self, "matrix", C)

    def congruence(self, d) -> "Compliance":
        """``D C D`` with ``D = diag(d)``, ``d`` six positive numbers (a section's moduli scaled mode by
        mode), frame None.  Not checked again: a diagonal congruence leaves the symmetry and the
        diagonally scaled matrix the check reads exactly as they were (a fit calls this thousands of times)."""
        d = np.asarray(d, dtype=float)
        if d.shape != (6,) or not np.all(np.isfinite(d)) or np.any(d <= 0):
            raise LinkFeaError(f"a congruence takes six positive finite factors, got {d!r}")
        C = self.matrix * np.outer(d, d)
        C.setflags(write=False)
        out = object.__new__(Compliance)
        for name, value in (("matrix", C), ("frame", None), ("units", self.units), ("what", self.what)):
            object.__setattr__(out, name, value)
        return out

    @property
    def stiffness(self) -> np.ndarray:
        """``K = C^-1`` (N/mm, N mm/rad by block)."""
        return np.linalg.inv(self.matrix)

    def to_frame(self, frame: Frame) -> "Compliance":
        """The same spring seen at another frame (adjoint map ``C_B = X C_A X^T``)."""
        if self.frame is None:
            raise LinkFeaError("this compliance states no frame; it cannot be moved to another one")
        return Compliance(self.frame.compliance_to(self.matrix, frame), frame, self.units, self.what)

    def __eq__(self, other):
        if not isinstance(other, Compliance):
            return NotImplemented
        same_frame = (self.frame is None and other.frame is None) or (
            self.frame is not None and other.frame is not None
            and np.array_equal(self.frame.origin, other.frame.origin)
            and np.array_equal(self.frame.axes, other.frame.axes))
        return bool(np.array_equal(self.matrix, other.matrix) and same_frame and self.units == other.units)

    __hash__ = None
