"""Closed-form beam compliances (seed eq. 14) with optional Timoshenko shear.

A cantilever of length ``L`` is clamped at its base and loaded at its tip.  The
compliance is expressed in the tip frame: origin at the tip centroid, x along
the beam (from base to tip), y and z the section's principal axes.  Order of
wrench and twist: Fx Fy Fz Mx My Mz / dx dy dz rx ry rz.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mechanics.frames import twist_transform
from ..runtime.errors import LinkFeaError


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
    >>> from linkfea.beam.closed_form import rect_section, cantilever_compliance
    >>> C = cantilever_compliance(200.0, rect_section(20.0, 10.0, 0.3), 210e3, 0.3)
    >>> bool(C[1, 5] > 0 and C[2, 4] < 0)
    True
    """
    if not (L > 0 and E > 0):
        raise LinkFeaError(f"beam length and modulus must be > 0, got L={L}, E={E}")
    G = E / (2.0 * (1.0 + nu))
    s = section
    C = eq14(L, E, G, s.A, s.Iy, s.Iz, s.J)
    if shear:
        C[1, 1] += L / (G * s.Asy)
        C[2, 2] += L / (G * s.Asz)
    return C


def eq14(L: float, E: float, G: float, A: float, Iy: float, Iz: float, J: float) -> np.ndarray:
    """The seed's eq. 14: tip compliance (tip frame, x along the beam) of an Euler-Bernoulli
    cantilever of length L, moduli E, G and section A, Iy, Iz, J; the one home of the formula.

    Fy turns the tip by +rz (``c26 = L^2/2EIz``), Fz by -ry (``c35 = -L^2/2EIy``).
    """
    C = np.zeros((6, 6))
    C[0, 0] = L / (E * A)
    C[1, 1] = L**3 / (3 * E * Iz)
    C[2, 2] = L**3 / (3 * E * Iy)
    C[3, 3] = L / (G * J)
    C[4, 4] = L / (E * Iy)
    C[5, 5] = L / (E * Iz)
    C[1, 5] = C[5, 1] = L**2 / (2 * E * Iz)
    C[2, 4] = C[4, 2] = -(L**2) / (2 * E * Iy)
    return C


# --- Beams in series -------------------------------------------------------------------------


@dataclass(frozen=True)
class BeamSegment:
    """A straight prismatic segment of a beam model, in the beam frame.

    The beam frame has x along the beam and its origin at the point where the
    model's compliance is wanted (the link tip).  The segment runs from
    ``x_start`` to ``x_end`` (``x_start < x_end``) along a line parallel to x
    through ``centroid`` = (y, z); its section's principal axes are the beam
    frame's y and z rotated by ``angle`` (rad, right-handed about x).

    Attributes
    ----------
    x_start, x_end : float
        Ends of the segment along x, mm.
    section : Section
        Constants in the principal axes (``Iy`` about principal axis 1).
    centroid : tuple of float
        (y, z) of the section centroid, mm.
    angle : float
        Principal angle, rad.
    """

    x_start: float
    x_end: float
    section: Section
    centroid: tuple = (0.0, 0.0)
    angle: float = 0.0

    def __post_init__(self):
        vals = (self.x_start, self.x_end, self.angle, *self.centroid)
        if not np.all(np.isfinite(vals)):
            raise LinkFeaError(f"beam segment: ends, centroid and angle must be finite, got {vals}")
        if not self.x_end > self.x_start:
            raise LinkFeaError(f"beam segment: x_end must exceed x_start, got {self.x_start}..{self.x_end}")
        object.__setattr__(self, "centroid", (float(self.centroid[0]), float(self.centroid[1])))

    @property
    def length(self) -> float:
        return self.x_end - self.x_start

    def tip_axes(self) -> np.ndarray:
        """Rows: the segment's x, principal y and principal z axes in beam-frame components."""
        c, s = np.cos(self.angle), np.sin(self.angle)
        return np.array([[1.0, 0.0, 0.0], [0.0, c, s], [0.0, -s, c]])

    def tip_origin(self) -> np.ndarray:
        return np.array([self.x_end, self.centroid[0], self.centroid[1]])


def series_compliance(segments, E: float, nu: float, shear: bool = True) -> np.ndarray:
    """Compliance of beam segments clamped end to end, at the beam frame's origin.

    A serial chain of 6-dof springs: the tip wrench reaches every segment
    unchanged (moved to that segment's tip), and the segments' elastic twists
    add up once moved rigidly to the origin, so ``C = sum_i X_i C_i X_i^T`` with
    ``X_i`` the twist map from segment ``i``'s tip frame to the beam frame
    (:func:`linkfea.mechanics.frames.twist_transform`).  Jumps of the centroid line
    between segments are rigid.

    Parameters
    ----------
    segments : sequence of BeamSegment
    E, nu : float
        Young's modulus (MPa) and Poisson's ratio.
    shear : bool
        Timoshenko shear terms (True) or exactly seed eq. 14 (False).

    Returns
    -------
    ndarray (6, 6)
        Compliance at the origin, axes of the beam frame (mm/N, rad/(N mm)).
    """
    segments = list(segments)
    if not segments:
        raise LinkFeaError("a beam model needs at least one segment")
    Cs = np.stack([cantilever_compliance(s.length, s.section, E, nu, shear) for s in segments])
    # Beam frame (origin 0, identity axes) seen from each segment tip frame.
    Xs = np.stack([_twist_to_origin(s.tip_axes(), s.tip_origin()) for s in segments])
    return np.einsum("nij,njk,nlk->il", Xs, Cs, Xs)


def _twist_to_origin(axes: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """Twist map from a frame (rows ``axes``, ``origin``, in beam coords) to the beam frame."""
    # transform_compliance(C, R, p): R = target axes in source components, p = target origin in source.
    return twist_transform(axes, axes @ (-origin))
