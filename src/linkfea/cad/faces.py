"""The faces of a part a selector can pick, each with a ready selector; the nearest ones to a selector
that finds nothing; a preview picture of the chosen base and tip with the link's frame.

``linkfea faces part.step`` prints :func:`face_groups`; the interface check names
:func:`nearest_selectors` when a ``--base`` or ``--tip`` finds no face; ``--preview`` draws
:func:`write_preview`.  A group is what one selector picks: the planar faces on one plane
(``plane:x=0``, or ``plane:PX,PY,PZ,NX,NY,NZ`` for an oblique plane) or the cylindrical faces of one
cylinder (a ``box:`` around them, checked to pick nothing else).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .selectors import Box, Plane, faces_area_centroid, parse_selector, select_faces

#: pixel colours of the preview (RGB 0-255): base, tip, the rest of the part
BASE_RGB, TIP_RGB, BODY_RGB = (200, 0, 200), (255, 150, 0), (190, 190, 190)


@dataclass(frozen=True)
class FaceGroup:
    """The faces one selector picks: ``kind`` ``"plane"`` or ``"cylinder"``, their number, area (mm^2)
    and area centroid (mm); the plane's unit normal or the cylinder's axis, and its radius (mm)."""

    selector: str
    kind: str
    n_faces: int
    area: float
    centroid: tuple
    direction: tuple
    radius: float | None = None

    def line(self) -> str:
        c = ", ".join(f"{v:.4g}" for v in self.centroid)
        d = ", ".join(f"{v:.3g}" for v in self.direction)
        what = (f"normal ({d})" if self.kind == "plane" else f"radius {self.radius:.4g} mm, axis ({d})")
        return (f"{self.selector:<44} {self.kind:<8} {self.n_faces:>3} face{'s' if self.n_faces > 1 else ' '} "
                f"{self.area:>10.4g} mm^2  centroid ({c})  {what}")


def _g(v: float) -> str:
    """A coordinate as a selector writes it: round-off below 1e-9 mm dropped."""
    v = 0.0 if abs(v) < 1e-9 else v
    return f"{v:.10g}"


def _box(lo, hi) -> str:
    """A box selector around ``lo``..``hi`` rounded outward to 0.01 mm (short, and still around the faces)."""
    lo = np.floor(np.asarray(lo) * 100.0 - 1e-6) / 100.0
    hi = np.ceil(np.asarray(hi) * 100.0 + 1e-6) / 100.0
    return "box:" + ",".join(_g(round(float(v), 2)) for v in (*lo, *hi))


def plane_selector(point, normal) -> str:
    """``plane:x=V`` for a plane normal to an axis, else ``plane:PX,PY,PZ,NX,NY,NZ``."""
    n = np.asarray(normal, dtype=float)
    k = int(np.argmax(np.abs(n)))
    if abs(abs(n[k]) - 1.0) <= 1e-9:
        return f"plane:{'xyz'[k]}={_g(float(point[k]))}"
    return "plane:" + ",".join(_g(float(v)) for v in (*point, *n))


def _group(faces, sel: str, kind: str, direction, radius=None) -> FaceGroup:
    area, cen = faces_area_centroid(faces)
    def clean(v):
        return tuple(0.0 if abs(float(x)) < 1e-9 else float(x) for x in v)

    return FaceGroup(sel, kind, len(faces), float(area), clean(cen), clean(direction), radius)


def face_groups(body) -> list[FaceGroup]:
    """The planar and cylindrical faces of ``body`` grouped by the selector that picks them, largest first."""
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.GeomAbs import GeomAbs_Cylinder

    faces = body.Faces()
    done: set = set()
    out = []
    for f in faces:
        if f.hashCode() in done or f.geomType() != "PLANE":
            continue
        n = np.array(f.normalAt().toTuple())
        sel = plane_selector(np.array(f.Center().toTuple()), n)
        picked = select_faces(body, parse_selector(sel))
        done |= {g.hashCode() for g in picked}
        out.append(_group(picked or [f], sel, "plane", n))
    cylinders: dict = {}
    for f in faces:
        a = BRepAdaptor_Surface(f.wrapped)
        if a.GetType() != GeomAbs_Cylinder:
            continue
        c = a.Cylinder()
        ax, loc = c.Axis().Direction(), c.Location()
        d = np.array([ax.X(), ax.Y(), ax.Z()])
        d = d * np.sign(d[np.argmax(np.abs(d))])
        p = np.array([loc.X(), loc.Y(), loc.Z()])
        p = p - (p @ d) * d  # the axis's point nearest the origin: one key per cylinder
        key = (tuple(np.round(p, 6)), tuple(np.round(d, 6)), round(c.Radius(), 6))
        cylinders.setdefault(key, (d, c.Radius(), []))[2].append(f)
    for d, r, fs in cylinders.values():
        lo = np.min([[f.BoundingBox().xmin, f.BoundingBox().ymin, f.BoundingBox().zmin] for f in fs], axis=0)
        hi = np.max([[f.BoundingBox().xmax, f.BoundingBox().ymax, f.BoundingBox().zmax] for f in fs], axis=0)
        sel = _box(lo, hi)
        picked = select_faces(body, parse_selector(sel))
        if {g.hashCode() for g in picked} != {f.hashCode() for f in fs}:
            sel += "  (also picks other faces)"
        out.append(_group(fs, sel, "cylinder", d, float(r)))
    return sorted(out, key=lambda g: -g.area)


def _distance(group: FaceGroup, selector) -> float:
    """How far a group is from what ``selector`` asks, mm (a plane's tilt counts as distance too)."""
    c = np.array(group.centroid)
    if isinstance(selector, Plane):
        n, p = np.array(selector.normal), np.array(selector.point)
        tilt = 0.0 if group.kind == "plane" and abs(abs(n @ np.array(group.direction)) - 1) < 1e-6 else 1e6
        return float(abs((c - p) @ n)) + tilt
    assert isinstance(selector, Box)
    lo, hi = np.array(selector.lo), np.array(selector.hi)
    return float(np.linalg.norm(np.maximum(0.0, np.maximum(lo - c, c - hi))))


def nearest_selectors(body, selector, n: int = 3) -> list[str]:
    """The selectors of the ``n`` face groups nearest to what ``selector`` asks, each with its area and
    distance: what to write instead of a selector that finds no face."""
    sel = parse_selector(selector)
    ranked = sorted(face_groups(body), key=lambda g: _distance(g, sel))[:n]
    out = []
    for g in ranked:
        d = _distance(g, sel)
        far = f"{d:.3g} mm away" if d < 1e5 else "not parallel"
        out.append(f"{g.selector.split('  ')[0]} ({g.kind}, {g.area:.4g} mm^2, {far})")
    return out


def check_preview(path):
    """The preview's path, checked before any work: a file there that linkfea did not write is refused."""
    from pathlib import Path

    from ..files.outputs import check_file, owned

    return check_file(Path(path), lambda p: p.name in owned(p.parent), "a preview linkfea wrote", option="--preview")


def write_preview(link, path, window_size=(900, 700)):
    """A picture of the part with its base and tip faces coloured (:data:`BASE_RGB`, :data:`TIP_RGB`) and
    the link's frame as a triad of arrows (x red, y green, z blue) at its origin; off-screen, atomic."""

    import cadquery as cq
    import pyvista as pv
    from vtkmodules.vtkCommonCore import vtkLogger

    from ..files.outputs import OutputSet

    path = check_preview(path)

    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
    diag = float(link.body.BoundingBox().DiagonalLength)
    tol = 1e-3 * diag

    def poly(shape):
        v, f = shape.tessellate(tol, 0.2)
        V = np.array([p.toTuple() for p in v], dtype=float).reshape(-1, 3)
        F = np.array(f, dtype=np.int64).reshape(-1, 3)
        return pv.PolyData(V, np.hstack([np.full((len(F), 1), 3), F]).astype(np.int64).ravel())

    pl = pv.Plotter(off_screen=True, window_size=list(window_size))
    pl.set_background("white")
    pl.add_mesh(poly(link.body), color=[c / 255 for c in BODY_RGB], opacity=0.45)
    for faces, rgb, label in ((link.base_faces, BASE_RGB, "base"), (link.tip_faces, TIP_RGB, "tip")):
        if faces:
            pl.add_mesh(poly(cq.Compound.makeCompound(faces)), color=[c / 255 for c in rgb], lighting=False,
                        label=label)
    f = link.frame
    for axis, colour in zip(f.axes, ("red", "green", "blue")):
        pl.add_mesh(pv.Arrow(start=f.origin, direction=axis, scale=0.2 * diag), color=colour, lighting=False)
    _look_at_both(pl, link, diag)
    pl.add_text(f"{link.name}: base {link.base} (magenta), tip {link.tip} (orange); frame x red, y green, z blue",
                font_size=9, color="black")
    try:
        with OutputSet(path.parent, f"linkfea faces {path.name}") as out:
            pl.screenshot(out.path(path.name))
    finally:
        pl.close()
    return path


def _look_at_both(pl, link, diag: float) -> None:
    """A camera from the side both interfaces face (their mean outward normal, tilted off any axis)."""
    from .selectors import faces_mean_normal

    n = faces_mean_normal(link.base_faces) + faces_mean_normal(link.tip_faces)
    if np.linalg.norm(n) < 0.3:  # opposite faces (a straight bar): look from the side
        n = n + np.array([0.3, -1.0, 0.6])
    d = n / np.linalg.norm(n) + np.array([0.25, -0.35, 0.2])
    d /= np.linalg.norm(d)
    bb = link.body.BoundingBox()
    c = np.array([bb.center.x, bb.center.y, bb.center.z])
    up = np.array([0.0, 0.0, 1.0]) if abs(d[2]) < 0.9 else np.array([0.0, 1.0, 0.0])
    pl.camera_position = [tuple(c + 2.5 * diag * d), tuple(c), tuple(up)]
