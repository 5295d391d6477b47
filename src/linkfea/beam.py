"""Closed-form beam compliances (seed eq. 14) with optional Timoshenko shear.

A cantilever of length ``L`` is clamped at its base and loaded at its tip.  The
compliance is expressed in the tip frame: origin at the tip centroid, x along
the beam (from base to tip), y and z the section's principal axes.  Order of
wrench and twist: Fx Fy Fz Mx My Mz / dx dy dz rx ry rz.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import LinkFeaError


@dataclass(frozen=True)
class Section:
    """Constants of a cross-section, in mm.

    Attributes
    ----------
    A : area (mm^2)
    Iy, Iz : second moments about the y and z axes (mm^4)
    J : Saint-Venant torsion constant (mm^4)
    Asy, Asz : shear areas for shear force along y and z (mm^2), i.e. kappa*A.
    """

    A: float
    Iy: float
    Iz: float
    J: float
    Asy: float
    Asz: float

    def __post_init__(self):
        for k in ("A", "Iy", "Iz", "J", "Asy", "Asz"):
            v = getattr(self, k)
            if not (np.isfinite(v) and v > 0):
                raise LinkFeaError(f"section constant {k} must be a positive number, got {v}")


def cowper_rect(nu: float) -> float:
    """Cowper's shear coefficient of a solid rectangle: 10(1+nu)/(12+11nu)."""
    return 10.0 * (1.0 + nu) / (12.0 + 11.0 * nu)


def cowper_circle(nu: float) -> float:
    """Cowper's shear coefficient of a solid circle: 6(1+nu)/(7+6nu)."""
    return 6.0 * (1.0 + nu) / (7.0 + 6.0 * nu)


def cowper_tube(nu: float, m: float) -> float:
    """Cowper's shear coefficient of a hollow circle, ``m`` = inner/outer radius."""
    m2 = m * m
    return 6.0 * (1.0 + nu) * (1.0 + m2) ** 2 / ((7.0 + 6.0 * nu) * (1.0 + m2) ** 2 + (20.0 + 12.0 * nu) * m2)


def rect_torsion_constant(width: float, height: float, terms: int = 50) -> float:
    """Saint-Venant J of a solid rectangle by its series solution (Timoshenko & Goodier).

    ``J = a b^3 / 3 * (1 - 192/pi^5 * b/a * sum_{n odd} tanh(n pi a / 2b) / n^5)``, ``a >= b``.
    """
    a, b = max(width, height), min(width, height)
    n = np.arange(1, 2 * terms, 2, dtype=float)
    s = np.sum(np.tanh(n * np.pi * a / (2.0 * b)) / n**5)
    return a * b**3 / 3.0 * (1.0 - 192.0 / np.pi**5 * (b / a) * s)


def rect_section(width: float, height: float, nu: float) -> Section:
    """Solid rectangle: ``width`` along y, ``height`` along z."""
    if not (width > 0 and height > 0):
        raise LinkFeaError(f"rectangle width and height must be > 0, got {width}, {height}")
    A = width * height
    k = cowper_rect(nu)
    return Section(A, width * height**3 / 12.0, height * width**3 / 12.0,
                   rect_torsion_constant(width, height), k * A, k * A)


def circle_section(diameter: float, nu: float) -> Section:
    """Solid circle."""
    if not diameter > 0:
        raise LinkFeaError(f"circle diameter must be > 0, got {diameter}")
    r = diameter / 2.0
    A = np.pi * r**2
    I = np.pi * r**4 / 4.0
    k = cowper_circle(nu)
    return Section(A, I, I, 2.0 * I, k * A, k * A)


def tube_section(diameter: float, inner_diameter: float, nu: float) -> Section:
    """Hollow circle."""
    if not (diameter > inner_diameter > 0):
        raise LinkFeaError(f"tube needs diameter > inner_diameter > 0, got {diameter}, {inner_diameter}")
    ro, ri = diameter / 2.0, inner_diameter / 2.0
    A = np.pi * (ro**2 - ri**2)
    I = np.pi * (ro**4 - ri**4) / 4.0
    k = cowper_tube(nu, ri / ro)
    return Section(A, I, I, 2.0 * I, k * A, k * A)


def cantilever_compliance(L: float, section: Section, E: float, nu: float, shear: bool = True) -> np.ndarray:
    """Tip compliance of a clamped beam in its tip frame (seed eq. 14).

    With ``shear=False`` this is exactly eq. 14 (Euler-Bernoulli); with
    ``shear=True`` the Timoshenko terms ``L/(G As)`` are added to the lateral
    translations.

    Examples
    --------
    >>> from linkfea.beam import rect_section, cantilever_compliance
    >>> C = cantilever_compliance(200.0, rect_section(20.0, 10.0, 0.3), 210e3, 0.3)
    >>> bool(C[1, 5] > 0 and C[2, 4] < 0)
    True
    """
    if not (L > 0 and E > 0):
        raise LinkFeaError(f"beam length and modulus must be > 0, got L={L}, E={E}")
    G = E / (2.0 * (1.0 + nu))
    s = section
    C = np.zeros((6, 6))
    C[0, 0] = L / (E * s.A)
    C[1, 1] = L**3 / (3 * E * s.Iz)
    C[2, 2] = L**3 / (3 * E * s.Iy)
    C[3, 3] = L / (G * s.J)
    C[4, 4] = L / (E * s.Iy)
    C[5, 5] = L / (E * s.Iz)
    C[1, 5] = C[5, 1] = L**2 / (2 * E * s.Iz)
    C[2, 4] = C[4, 2] = -(L**2) / (2 * E * s.Iy)
    if shear:
        C[1, 1] += L / (G * s.Asy)
        C[2, 2] += L / (G * s.Asz)
    return C
