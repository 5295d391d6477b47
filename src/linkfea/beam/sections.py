"""Cross-section constants of any planar section, by the ``sectionproperties`` package.

A section is a shapely (Multi)Polygon in the y-z plane of a beam frame (x
along the beam, mm).  Its constants come from sectionproperties' finite
element analysis of the section: area, centroid, second moments, principal
angle, the Saint-Venant torsion constant J from the warping function (never
``Iy + Iz``, which is right for circles only) and the shear areas.

Shear areas are sectionproperties' *geometric* ones (no material, so its shear
function is solved with nu = 0).  For a rectangle and a circle they equal
Cowper's ``kappa A`` at nu = 0 (5/6 A and 6/7 A).  Cowper's mild nu dependence
(+2 to +3 % in kappa at nu = 0.3) is not carried over to arbitrary sections,
and sectionproperties' nu-dependent energy coefficient is not used either: for
wide sections it collapses (kappa = 0.18 for a 10:1 rectangle at nu = 0.3)
because of anticlastic Poisson stresses of the free Saint-Venant beam, which a
clamped link does not have.

The shear centre offset from the centroid (bending-torsion coupling of open
or unsymmetric sections) is not modelled: beam segments bend about their
centroid line and twist about it.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from ..mechanics.frames import Frame
from ..runtime.errors import LinkFeaError
from .closed_form import Section

#: Triangles per section mesh, roughly: max triangle area = A / this.
DEFAULT_MESH_DIVISIONS = 400


@dataclass(frozen=True)
class SectionConstants:
    """Constants of a planar section in the y-z axes it was given in (mm).

    Attributes
    ----------
    area : float
    centroid : tuple (y, z)
    Iyy, Izz, Iyz : float
        Centroidal second moments in the given axes: ``Iyy = int z^2``,
        ``Izz = int y^2``, ``Iyz = int y z`` (mm^4).
    J : float
        Saint-Venant torsion constant from the warping function (mm^4).
    Asy, Asz : float
        Shear areas for a shear force along y and along z (mm^2).
    angle : float
        Principal angle (rad): principal axis 1 is y rotated by ``angle``
        right-handedly about x (towards z).
    I1, I2 : float
        Principal second moments about axes 1 and 2 (mm^4).
    As1, As2 : float
        Shear areas for shear forces along principal axes 1 and 2 (mm^2).
    """

    area: float
    centroid: tuple
    Iyy: float
    Izz: float
    Iyz: float
    J: float
    Asy: float
    Asz: float
    angle: float
    I1: float
    I2: float
    As1: float
    As2: float

    def principal_section(self) -> Section:
        """A :class:`linkfea.beam.closed_form.Section` in the principal axes (y' = axis 1, z' = axis 2).

        ``Iy`` of a Section is the moment about its y axis, ``int z'^2``; about
        principal axis 1 that is ``I1``.  The shear area along y' is ``As1``.
        """
        return Section(self.area, self.I1, self.I2, self.J, self.As1, self.As2)

    def to_dict(self) -> dict:
        d: dict = {k: float(getattr(self, k)) for k in
             ("area", "Iyy", "Izz", "Iyz", "J", "Asy", "Asz", "angle", "I1", "I2", "As1", "As2")}
        d["centroid"] = [float(self.centroid[0]), float(self.centroid[1])]
        d["units"] = "mm, mm^2, mm^4, rad"
        return d


def _as_geometry(polygon):
    """Validate a shapely polygon and wrap it as a sectionproperties geometry."""
    from sectionproperties.pre.geometry import CompoundGeometry, Geometry
    from shapely.geometry import MultiPolygon, Polygon

    if not isinstance(polygon, (Polygon, MultiPolygon)):
        raise LinkFeaError(f"section must be a shapely Polygon or MultiPolygon, got {type(polygon).__name__}")
    if polygon.is_empty or not polygon.is_valid or not polygon.area > 0:
        from shapely.validation import explain_validity

        why = "empty" if polygon.is_empty else explain_validity(polygon)
        raise LinkFeaError(f"section polygon cannot be meshed by sectionproperties: {why} (area {polygon.area:g} mm^2)")
    if isinstance(polygon, MultiPolygon):
        return CompoundGeometry([Geometry(p) for p in polygon.geoms])
    return Geometry(polygon)


def section_constants(polygon, mesh_divisions: int = DEFAULT_MESH_DIVISIONS) -> SectionConstants:
    """Constants of a planar section by sectionproperties (geometric and warping analyses).

    Parameters
    ----------
    polygon : shapely.geometry.Polygon or MultiPolygon
        The section in the y-z plane (shapely x = y, shapely y = z), mm, holes allowed.
        Disjoint parts are analysed as one section (J is then the sum of the parts').
    mesh_divisions : int
        Largest triangle area is ``area / mesh_divisions``.

    Returns
    -------
    SectionConstants

    Raises
    ------
    LinkFeaError
        If the polygon is invalid or empty, or sectionproperties cannot mesh or analyse it.

    Examples
    --------
    >>> from shapely.geometry import box
    >>> c = section_constants(box(0, 0, 20, 10))
    >>> round(c.area, 6), round(c.Iyy, 3)   # 20 x 10: Iyy = 20 * 10^3 / 12
    (200.0, 1666.667)
    """
    from sectionproperties.analysis.section import Section as SpSection

    geom = _as_geometry(polygon)
    area = float(polygon.area)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            geom = geom.create_mesh(mesh_sizes=area / float(mesh_divisions))
            sec = SpSection(geom)
            sec.calculate_geometric_properties()
            sec.calculate_warping_properties()
            cy, cz = sec.get_c()
            ixx, iyy, ixy = sec.get_ic()
            i11, i22 = sec.get_ip()
            asx, asy = sec.get_as()
            as11, as22 = sec.get_as_p()
            J = sec.get_j()
            phi = sec.get_phi()
            A = sec.get_area()
    except LinkFeaError:
        raise
    except Exception as exc:  # sectionproperties/triangle raise assorted types
        raise LinkFeaError(f"sectionproperties cannot mesh or analyse this section "
                           f"(area {area:g} mm^2): {type(exc).__name__}: {exc}") from None
    vals = np.array([A, ixx, iyy, J, asx, asy, i11, i22, as11, as22], dtype=float)
    if not (np.all(np.isfinite(vals)) and np.all(vals > 0)):
        raise LinkFeaError(f"sectionproperties returned non-positive section constants for a section of "
                           f"area {area:g} mm^2: {vals.tolist()}")
    # Principal axes closest to the given y, z (|angle| <= 45 deg): a quarter turn swaps axes 1 and 2.
    phi = np.deg2rad(phi)
    quarter = np.round(phi / (np.pi / 2.0))
    phi -= quarter * np.pi / 2.0
    if int(quarter) % 2:
        i11, i22, as11, as22 = i22, i11, as22, as11
    # sectionproperties' (x, y) are our (y, z): its ixx = int y_sp^2 = int z^2 = our Iyy.
    return SectionConstants(
        area=float(A), centroid=(float(cy), float(cz)),
        Iyy=float(ixx), Izz=float(iyy), Iyz=float(ixy), J=float(J),
        Asy=float(asx), Asz=float(asy), angle=float(phi),
        I1=float(i11), I2=float(i22), As1=float(as11), As2=float(as22),
    )


def cut_section(solid, frame: Frame, x: float, tolerance: float | None = None):
    """The section of a CadQuery solid by the plane ``x = const`` of a frame.

    Parameters
    ----------
    solid : cadquery.Shape
        The body (a Solid or a Compound of solids), CAD coordinates in mm.
    frame : Frame
        Beam frame in CAD coordinates; the cutting plane is normal to its x axis.
    x : float
        Position of the plane along the frame's x axis, mm from its origin.
    tolerance : float, optional
        Chordal deflection used to discretise curved edges, mm
        (default 2e-5 of the solid's bounding-box diagonal).

    Returns
    -------
    shapely Polygon or MultiPolygon
        In the frame's (y, z) coordinates, holes included.

    Raises
    ------
    LinkFeaError
        If the plane cuts no material.
    """
    import cadquery as cq
    from shapely.geometry import Polygon
    from shapely.ops import unary_union

    bb = solid.BoundingBox()
    diag = float(bb.DiagonalLength)
    tol = tolerance if tolerance is not None else 2e-5 * diag
    centre = frame.origin + float(x) * frame.axes[0]
    plane = cq.Face.makePlane(4.0 * diag, 4.0 * diag, cq.Vector(*centre), cq.Vector(*frame.axes[0]))
    try:
        cut = solid.intersect(plane)
        faces = cut.Faces()
    except Exception as exc:
        raise LinkFeaError(f"cutting the link at x = {x:g} mm failed: {exc}") from None

    def to_yz(wire):
        pts, _ = wire.sample(float(tol))
        P = np.array([p.toTuple() for p in pts]) - frame.origin
        return P @ frame.axes[1:].T

    polys = []
    for f in faces:
        shell = Polygon(to_yz(f.outerWire()), [to_yz(w) for w in f.innerWires()])
        polys.append(shell.buffer(0) if not shell.is_valid else shell)
    sec = unary_union(polys) if polys else Polygon()
    if sec.is_empty or sec.area <= 1e-12 * diag**2:
        raise LinkFeaError(f"the plane x = {x:g} mm of the beam frame cuts no material of the link "
                           f"(choose stations between base and tip, or another axis)")
    return sec
