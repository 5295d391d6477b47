"""N-beam equivalents of a CAD link (the beam side of ``linkfea compare``).

Beam equivalent (:func:`link_beam_model`)
    The body is cut by N planes normal to the beam axis (default: the link
    frame's x) at the mid-stations of N equal segments between the base and
    the tip interface centroids (projected on the axis).  Each cut gives a
    section (sectionproperties, :mod:`linkfea.beam.sections`); segment i is a
    prismatic Timoshenko (or eq. 14 Euler-Bernoulli) beam along a line parallel
    to the axis through that section's centroid, bending about its principal
    axes.  The segments are clamped end to end (rigid jumps between centroid
    lines) and summed as a serial chain at the link frame
    (:func:`linkfea.beam.closed_form.series_compliance`).  Not modelled: shear-centre
    offsets, taper within a segment, warping restraint, the flexibility of the
    clamp region beyond the base centroid.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..cad.link import interface_faces
from ..mechanics.frames import Frame
from ..mechanics.materials import Material, get_material
from ..runtime.errors import LinkFeaError
from .closed_form import BeamSegment, series_compliance
from .sections import cut_section, section_constants


@dataclass(frozen=True)
class BeamModel:
    """An N-beam equivalent of a link, compliances in the link frame.

    Attributes
    ----------
    n : int
    stations : ndarray (n,)
        Cut positions along the beam axis, mm from the link frame origin.
    segments : tuple of BeamSegment
        In the beam frame (x = beam axis, origin = link frame origin).
    sections : tuple of SectionConstants
        Section constants at the stations, beam-frame y-z axes.
    compliance : ndarray (6, 6)
        Timoshenko N-beam compliance in the link frame.
    compliance_eb : ndarray (6, 6)
        Euler-Bernoulli (seed eq. 14) N-beam compliance in the link frame.
    """

    n: int
    stations: np.ndarray
    segments: tuple
    sections: tuple
    compliance: np.ndarray
    compliance_eb: np.ndarray


def beam_frame(frame: Frame, axis=None) -> Frame:
    """The beam frame: the link frame's origin, x along ``axis`` (link-frame components)."""
    if axis is None:
        return frame
    a = np.asarray(axis, dtype=float).reshape(-1)
    if a.size != 3 or not np.all(np.isfinite(a)) or np.linalg.norm(a) == 0:
        raise LinkFeaError(f"beam axis must be a non-zero 3-vector, got {axis}")
    a_cad = frame.axes.T @ (a / np.linalg.norm(a))
    return Frame.from_x(frame.origin, a_cad, y_hint=frame.axes[1] if abs(a_cad @ frame.axes[1]) < 0.9
                        else frame.axes[2])


def beam_model(body, frame: Frame, x_base: float, x_tip: float, n: int, material: Material,
               axis=None) -> BeamModel:
    """N-beam model of a solid between ``x_base`` and ``x_tip`` along the beam axis.

    Parameters
    ----------
    body : cadquery.Shape
    frame : Frame
        The link frame (CAD coordinates); the result is expressed there.
    x_base, x_tip : float
        Ends of the beam along the beam axis, mm from the frame origin (``x_base < x_tip``).
    n : int
        Number of segments (> 0).
    material : Material
    axis : 3-vector, optional
        Beam axis in link-frame components (default x).

    Raises
    ------
    LinkFeaError
        ``n <= 0``, ends in the wrong order, a station that cuts no material or a
        section sectionproperties cannot analyse.
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n <= 0:
        raise LinkFeaError(f"number of beams must be a positive integer, got {n!r}")
    if not (np.isfinite(x_base) and np.isfinite(x_tip) and x_base < x_tip):
        raise LinkFeaError(f"beam ends must satisfy x_base < x_tip along the axis, got {x_base:g}, {x_tip:g} mm")
    bf = beam_frame(frame, axis)
    edges = np.linspace(x_base, x_tip, n + 1)
    stations = 0.5 * (edges[:-1] + edges[1:])
    secs = []
    for x in stations:
        try:
            secs.append(section_constants(cut_section(body, bf, float(x))))
        except LinkFeaError as exc:
            raise LinkFeaError(f"beam model with {n} segments, station x = {x:g} mm: {exc}") from None
    segs = tuple(BeamSegment(float(a), float(b), s.principal_section(), s.centroid, s.angle)
                 for a, b, s in zip(edges[:-1], edges[1:], secs))
    C_t = series_compliance(segs, material.E, material.nu, shear=True)
    C_e = series_compliance(segs, material.E, material.nu, shear=False)
    if bf is not frame:
        C_t, C_e = bf.compliance_to(C_t, frame), bf.compliance_to(C_e, frame)
    return BeamModel(n, stations, segs, tuple(secs), C_t, C_e)


def link_extent(link, axis=None) -> tuple[float, float]:
    """Base and tip interface centroids projected on the beam axis, mm from the frame origin."""
    from ..cad.selectors import faces_area_centroid

    bf = beam_frame(link.frame, axis)
    out = []
    for faces in interface_faces(link):
        _, c = faces_area_centroid(faces)
        out.append(float((c - bf.origin) @ bf.axes[0]))
    return out[0], out[1]


def link_beam_model(link, n: int, axis=None) -> BeamModel:
    """N-beam equivalent of a :class:`linkfea.cad.link.Link` (see the module docstring)."""
    x_base, x_tip = link_extent(link, axis)
    if not x_base < x_tip:
        raise LinkFeaError(f"{link.name}: along the beam axis the base ({x_base:g} mm) is not behind the tip "
                           f"({x_tip:g} mm); choose another axis")
    return beam_model(link.body, link.frame, x_base, x_tip, n, get_material(link.material), axis)
