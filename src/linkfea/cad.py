"""Links from CadQuery scripts or STEP files, and the interface selectors.

A :class:`Link` is the CAD-side value of the link stage: the body solid, an
optional pseudo-rigid reference block fused at the tip, the base (clamped) and
tip interface selectors, and the reference frame.

Selector syntax (command line, :func:`parse_selector`)
------------------------------------------------------
``plane:x=0``
    Faces lying on the plane x = 0 (also ``y=``/``z=``).
``plane:PX,PY,PZ,NX,NY,NZ``
    Faces lying on the plane through point P with normal N.
``box:XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX``
    Faces whose bounding box lies inside the box (``inf``/``-inf`` allowed).

Append ``,tol=T`` (mm) to either form to set the capture tolerance
(default :data:`DEFAULT_TOL`).  A plane selects planar faces whose normal is
parallel to N and which lie within ``tol`` of the plane; a box selects faces of
any type (a cylindrical bore, say) whose bounding box lies inside the box grown
by ``tol``.
"""
from __future__ import annotations

import importlib.util
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Union

import numpy as np

from .errors import LinkFeaError
from .frames import Frame
from .materials import get_material
from .resources import cad_dir

DEFAULT_TOL = 0.01
"""Default selector tolerance, mm (CAD faces are exact, so this only absorbs round-off)."""

CAD_DIR = cad_dir()
"""Folder of the bundled link scripts (``bar``, ``orthoglide_foot``, ...)."""


# --------------------------------------------------------------------------- selectors
@dataclass(frozen=True)
class Plane:
    """Planar faces on the plane through ``point`` with unit normal ``normal``."""

    point: tuple
    normal: tuple
    tol: float = DEFAULT_TOL

    def __post_init__(self):
        p = np.asarray(self.point, dtype=float).reshape(-1)
        n = np.asarray(self.normal, dtype=float).reshape(-1)
        if p.size != 3 or n.size != 3 or not (np.all(np.isfinite(p)) and np.all(np.isfinite(n))):
            raise LinkFeaError(f"plane selector needs a finite point and normal, got {self.point}, {self.normal}")
        if np.linalg.norm(n) == 0:
            raise LinkFeaError("plane selector normal must not be zero")
        if not (math.isfinite(self.tol) and self.tol > 0):
            raise LinkFeaError(f"selector tolerance must be > 0 mm, got {self.tol}")
        object.__setattr__(self, "point", tuple(p.tolist()))
        object.__setattr__(self, "normal", tuple((n / np.linalg.norm(n)).tolist()))

    def __str__(self):
        return "plane:" + ",".join(f"{v:g}" for v in self.point + self.normal) + f",tol={self.tol:g}"


@dataclass(frozen=True)
class Box:
    """Faces whose bounding box lies in the axis-aligned box ``[lo, hi]``."""

    lo: tuple
    hi: tuple
    tol: float = DEFAULT_TOL

    def __post_init__(self):
        lo = np.asarray(self.lo, dtype=float).reshape(-1)
        hi = np.asarray(self.hi, dtype=float).reshape(-1)
        if lo.size != 3 or hi.size != 3 or np.isnan(lo).any() or np.isnan(hi).any():
            raise LinkFeaError(f"box selector needs 3 lower and 3 upper bounds, got {self.lo}, {self.hi}")
        if np.any(hi <= lo):
            raise LinkFeaError(f"box selector upper bounds must exceed lower bounds, got {self.lo}, {self.hi}")
        if not (math.isfinite(self.tol) and self.tol > 0):
            raise LinkFeaError(f"selector tolerance must be > 0 mm, got {self.tol}")
        object.__setattr__(self, "lo", tuple(lo.tolist()))
        object.__setattr__(self, "hi", tuple(hi.tolist()))

    def __str__(self):
        return "box:" + ",".join(f"{v:g}" for v in self.lo + self.hi) + f",tol={self.tol:g}"


Selector = Union[Plane, Box]


def parse_selector(text: str) -> Selector:
    """Parse a command-line selector (see the module docstring for the syntax).

    >>> parse_selector("plane:x=200").point
    (200.0, 0.0, 0.0)
    >>> parse_selector("box:-1,-50,-50,1,50,50,tol=0.1").tol
    0.1
    """
    if isinstance(text, (Plane, Box)):
        return text
    s = str(text).strip()
    kind, sep, rest = s.partition(":")
    kind = kind.strip().lower()
    if not sep or kind not in ("plane", "box"):
        raise LinkFeaError(f"selector {s!r}: expected 'plane:x=VALUE', 'plane:PX,PY,PZ,NX,NY,NZ' "
                           "or 'box:XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX' (optionally ',tol=T')")
    tol = DEFAULT_TOL
    nums: list[float] = []
    axis = None
    for tok in (t.strip() for t in rest.split(",") if t.strip()):
        key, eq, val = tok.partition("=")
        try:
            if eq and key.strip().lower() == "tol":
                tol = float(val)
            elif eq and kind == "plane" and key.strip().lower() in ("x", "y", "z") and axis is None:
                axis = ("x", "y", "z").index(key.strip().lower()), float(val)
            elif not eq:
                nums.append(float(tok))
            else:
                raise ValueError
        except ValueError:
            raise LinkFeaError(f"selector {s!r}: cannot read {tok!r}") from None
    if kind == "plane":
        if axis is not None and not nums:
            p = [0.0, 0.0, 0.0]
            n = [0.0, 0.0, 0.0]
            p[axis[0]] = axis[1]
            n[axis[0]] = 1.0
            return Plane(tuple(p), tuple(n), tol)
        if axis is None and len(nums) == 6:
            return Plane(tuple(nums[:3]), tuple(nums[3:]), tol)
        raise LinkFeaError(f"selector {s!r}: a plane is 'plane:x=VALUE' or 'plane:PX,PY,PZ,NX,NY,NZ'")
    if len(nums) != 6:
        raise LinkFeaError(f"selector {s!r}: a box needs 6 numbers XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX")
    return Box(tuple(nums[:3]), tuple(nums[3:]), tol)


def select_faces(shape, selector: Selector) -> list:
    """CAD faces of ``shape`` picked by ``selector`` (possibly empty)."""
    out = []
    if isinstance(selector, Plane):
        p, n = np.array(selector.point), np.array(selector.normal)
        for f in shape.Faces():
            if f.geomType() != "PLANE":
                continue
            fn = np.array(f.normalAt().toTuple())
            if abs(abs(fn @ n) - 1.0) > 1e-6:
                continue
            corners = _bbox_corners(f)
            if np.all(np.abs((corners - p) @ n) <= selector.tol):
                out.append(f)
    else:
        lo = np.array(selector.lo) - selector.tol
        hi = np.array(selector.hi) + selector.tol
        for f in shape.Faces():
            bb = f.BoundingBox()
            if np.all(np.array([bb.xmin, bb.ymin, bb.zmin]) >= lo) and np.all(np.array([bb.xmax, bb.ymax, bb.zmax]) <= hi):
                out.append(f)
    return out


def _bbox_corners(face) -> np.ndarray:
    bb = face.BoundingBox()
    return np.array([[x, y, z] for x in (bb.xmin, bb.xmax) for y in (bb.ymin, bb.ymax) for z in (bb.zmin, bb.zmax)])


def faces_area_centroid(faces) -> tuple[float, np.ndarray]:
    """Total area (mm^2) and area centroid (mm) of a list of CAD faces."""
    areas = np.array([f.Area() for f in faces])
    cents = np.array([f.Center().toTuple() for f in faces])  # OCC Center() is the area centroid
    A = float(areas.sum())
    return A, (areas @ cents) / A


def faces_mean_normal(faces) -> np.ndarray:
    """Area-weighted mean outward normal of planar faces (zero vector if they cancel)."""
    n = np.zeros(3)
    for f in faces:
        if f.geomType() == "PLANE":
            n += f.Area() * np.array(f.normalAt().toTuple())
    return n / max(sum(f.Area() for f in faces), 1e-300)


# --------------------------------------------------------------------------- links
@dataclass(frozen=True)
class Link:
    """A link ready for meshing.

    Attributes
    ----------
    name : str
    body : cadquery.Solid
        The deformable link, mm.
    block : cadquery.Solid or None
        Pseudo-rigid reference block fused to the body at the tip interface.
        ``None`` is allowed in rigid mode (the tip faces are then coupled directly).
    base, tip : Plane or Box
        Selectors of the clamped base interface and of the tip interface, both
        applied to the faces of ``body``.
    frame : Frame
        Reference frame: origin at the tip interface centroid, x along the link.
    params : dict
        Parameters the link was built with (mm unless stated).
    material : str
        Material name (see :func:`linkfea.materials.get_material`).
    source : str
        Script path or STEP path the link came from.
    """

    name: str
    body: Any
    block: Any
    base: Selector
    tip: Selector
    frame: Frame
    params: dict = field(default_factory=dict)
    material: str = "steel"
    source: str = ""

    @property
    def base_faces(self) -> list:
        return select_faces(self.body, self.base)

    @property
    def tip_faces(self) -> list:
        return select_faces(self.body, self.tip)


def resolve_params(defaults: dict, given: dict | None = None, positive=(), nonnegative=()) -> dict:
    """Merge ``given`` into a script's ``PARAMS`` with checks.

    Values are converted to the type of the default (so ``"200"`` from the
    command line becomes ``200.0``).  Unknown names, non-finite numbers,
    non-positive entries of ``positive`` and negative entries of
    ``nonnegative`` raise :class:`LinkFeaError`; so does an unknown material.
    """
    out = dict(defaults)
    for k, v in (given or {}).items():
        if k not in defaults:
            raise LinkFeaError(f"unknown parameter {k!r}; known parameters: {', '.join(sorted(defaults))}")
        d = defaults[k]
        try:
            if isinstance(d, bool):
                v = v if isinstance(v, bool) else str(v).strip().lower() in ("1", "true", "yes", "on")
            elif isinstance(d, (int, float)) and not isinstance(d, bool):
                v = float(v)
            else:
                v = str(v)
        except (TypeError, ValueError):
            raise LinkFeaError(f"parameter {k!r}: expected a number, got {v!r}") from None
        out[k] = v
    for k, v in out.items():
        if isinstance(v, float) and not math.isfinite(v):
            raise LinkFeaError(f"parameter {k!r} must be a finite number, got {v}")
    for k in positive:
        if not out[k] > 0:
            raise LinkFeaError(f"parameter {k!r} must be > 0 mm, got {out[k]}")
    for k in nonnegative:
        if not out[k] >= 0:
            raise LinkFeaError(f"parameter {k!r} must be >= 0, got {out[k]}")
    if "material" in out:
        get_material(out["material"])
    return out


def parse_param_args(items) -> dict:
    """``["length=200", "section=rect"]`` -> ``{"length": "200", "section": "rect"}``."""
    out = {}
    for it in items or ():
        k, eq, v = str(it).partition("=")
        if not eq or not k.strip():
            raise LinkFeaError(f"parameter {it!r}: expected NAME=VALUE")
        out[k.strip()] = v.strip()
    return out


def resolve_script(spec: str | Path) -> Path:
    """A cad/ script path, or a bare name like ``bar`` looked up in :data:`CAD_DIR`."""
    p = Path(spec)
    if p.suffix == ".py" and p.is_file():
        return p.resolve()
    for cand in (CAD_DIR / f"{p.name}.py", CAD_DIR / p.name, Path.cwd() / "cad" / f"{p.name}.py"):
        if cand.is_file():
            return cand.resolve()
    known = ", ".join(sorted(q.stem for q in CAD_DIR.glob("*.py"))) if CAD_DIR.is_dir() else "none"
    raise LinkFeaError(f"no link script or STEP file {str(spec)!r}; bundled scripts: {known}")


def load_script(path: str | Path):
    """Import a cad/ script as a module (it must define ``PARAMS`` and ``build``)."""
    path = resolve_script(path)
    modname = f"linkfea_cad_{path.stem}"
    spec = importlib.util.spec_from_file_location(modname, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    if not (hasattr(mod, "PARAMS") and callable(getattr(mod, "build", None))):
        raise LinkFeaError(f"{path}: a link script must define PARAMS and build(**params)")
    return mod


def is_step(spec) -> bool:
    return Path(str(spec)).suffix.lower() in (".step", ".stp")


def build_link(spec, params: dict | None = None, material: str | None = None,
               base=None, tip=None, with_block: bool = True, block_length: float | None = None) -> Link:
    """Build a :class:`Link` from a cad/ script (name or path) or a STEP file.

    For scripts, ``base``/``tip`` override the script's selectors and
    ``material`` the script's material; a new ``tip`` also rebuilds the frame
    and the block from the selected faces, as for STEP files.  For STEP files ``base`` and ``tip``
    are required and ``params`` must be empty.
    """
    if material is not None:
        get_material(material)
    if is_step(spec):
        if params:
            raise LinkFeaError("--param applies to cad/ scripts, not to STEP files")
        if base is None or tip is None:
            raise LinkFeaError("a STEP file needs --base and --tip selectors")
        return load_step(spec, parse_selector(base), parse_selector(tip), material or "steel",
                         with_block=with_block, block_length=block_length)
    mod = load_script(spec)
    p = dict(params or {})
    if material is not None:
        if "material" not in mod.PARAMS:
            raise LinkFeaError(f"{spec}: this script has no material parameter")
        p["material"] = material
    link = mod.build(**p)
    if not isinstance(link, Link):
        raise LinkFeaError(f"{spec}: build() must return a linkfea.cad.Link")
    changes: dict = {}
    if base is not None:
        changes["base"] = parse_selector(base)
    if tip is not None:
        changes["tip"] = parse_selector(tip)
    if changes:
        from dataclasses import replace
        link = replace(link, **changes)
    check_link(link)
    if tip is not None:
        # A new tip interface: the script's frame and block belong to the old one, so both are
        # rebuilt from the selected faces by the STEP rule.
        frame, block, _ = interface_frame_and_block(link.body, link.base_faces, link.tip_faces, with_block,
                                                    block_length, link.name)
        from dataclasses import replace
        link = replace(link, frame=frame, block=block)
    return link


def check_link(link: Link) -> None:
    """Selectors find faces, base and tip do not overlap, solids are valid."""
    for nm, s in (("body", link.body), ("block", link.block)):
        if s is not None and not s.isValid():
            raise LinkFeaError(f"{link.name}: the {nm} solid is not valid")
    bf, tf = link.base_faces, link.tip_faces
    if not bf:
        raise LinkFeaError(f"{link.name}: base selector {link.base} finds no face")
    if not tf:
        raise LinkFeaError(f"{link.name}: tip selector {link.tip} finds no face")
    if {f.hashCode() for f in bf} & {f.hashCode() for f in tf} or _faces_touch(bf, tf):
        raise LinkFeaError(f"{link.name}: base and tip interfaces overlap ({link.base} / {link.tip})")
    get_material(link.material)


def _faces_touch(fa, fb, tol=1e-6) -> bool:
    """True where a base face and a tip face share a point (an edge or a vertex)."""
    import cadquery as cq
    a = cq.Compound.makeCompound(fa)
    b = cq.Compound.makeCompound(fb)
    return a.distance(b) <= tol


# --------------------------------------------------------------------------- STEP input
def load_step(path, base: Selector, tip: Selector, material: str = "steel",
              with_block: bool = True, block_length: float | None = None) -> Link:
    """Load and validate a STEP link and build its frame and (optional) block.

    Checks: exactly one solid, a valid BRep (``BRepCheck``), no
    self-intersection (``BOPAlgo_ArgumentAnalyzer``), a watertight
    tessellation (trimesh).  The frame's origin is the area centroid of the
    tip faces; its x axis is their mean outward normal when they are planar
    and coplanar, otherwise the direction from the base centroid to the tip
    centroid (a bore, say).  With ``with_block`` the block is the tip faces
    extruded outward by ``block_length`` (default half the square root of the
    tip area); this needs planar tip faces.
    """
    import cadquery as cq

    path = Path(path)
    if not path.is_file():
        raise LinkFeaError(f"STEP file {str(path)!r} not found")
    try:
        shape = cq.importers.importStep(str(path)).val()
    except Exception as exc:  # OCC raises bare exceptions on unreadable files
        raise LinkFeaError(f"cannot read STEP file {str(path)!r}: {exc}") from None
    solids = shape.Solids() if hasattr(shape, "Solids") else []
    if not solids:
        raise LinkFeaError(f"{path.name}: no closed solid in the STEP file (an open shell is not watertight)")
    if len(solids) > 1:
        raise LinkFeaError(f"{path.name}: expected one solid, found {len(solids)} "
                           "(several bodies, or a self-intersecting solid split on import)")
    body = solids[0]
    validate_solid(body, path.name)
    get_material(material)
    link = Link(name=path.stem, body=body, block=None, base=base, tip=tip,
                frame=Frame(np.zeros(3), np.eye(3)), params={}, material=material, source=str(path))
    check_link(link)
    frame, block, h = interface_frame_and_block(body, link.base_faces, link.tip_faces, with_block,
                                                block_length, path.name)
    return Link(name=path.stem, body=body, block=block, base=base, tip=tip, frame=frame,
                params={"block_length": h} if with_block else {},
                material=material, source=str(path))


def interface_frame_and_block(body, base_faces, tip_faces, with_block: bool, block_length, label: str):
    """Frame from the tip faces and, with ``with_block``, the block extruded from them.

    Origin: area centroid of the tip faces.  x: their mean outward normal
    when they are planar and coplanar, otherwise the direction from the base
    centroid to the tip centroid (a bore).  Block: the tip faces extruded
    outward by ``block_length`` (default half the square root of their area).

    Returns
    -------
    frame, block (or None), block length used (or None)
    """
    import cadquery as cq

    A, c_tip = faces_area_centroid(tip_faces)
    _, c_base = faces_area_centroid(base_faces)
    n = faces_mean_normal(tip_faces)
    planar = all(f.geomType() == "PLANE" for f in tip_faces) and np.linalg.norm(n) > 1 - 1e-6
    x = n if planar else c_tip - c_base
    if np.linalg.norm(x) < 1e-9:
        raise LinkFeaError(f"{label}: cannot orient the frame (tip and base centroids coincide)")
    frame = Frame.from_x(c_tip, x)
    if not with_block:
        return frame, None, None
    if not planar:
        raise LinkFeaError(f"{label}: block mode needs planar, coplanar tip faces; use --mode rigid")
    h = block_length if block_length is not None else 0.5 * math.sqrt(A)
    if not (math.isfinite(h) and h > 0):
        raise LinkFeaError(f"block length must be > 0 mm, got {h}")
    v = cq.Vector(*(frame.axes[0] * h))
    parts = [cq.Solid.extrudeLinear(f, v) for f in tip_faces]
    block = parts[0] if len(parts) == 1 else cq.Compound.makeCompound(parts).fuse().clean()
    if hasattr(block, "Solids") and len(block.Solids()) == 1:
        block = block.Solids()[0]
    if block.intersect(body).Volume() > 1e-6 * block.Volume():
        raise LinkFeaError(f"{label}: the block extruded from the tip faces runs into the body")
    return frame, block, h


def validate_solid(solid, label: str = "solid") -> None:
    """Raise :class:`LinkFeaError` unless ``solid`` is a valid, closed, non-self-intersecting solid."""
    import trimesh
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Check

    if not solid.isValid():
        raise LinkFeaError(f"{label}: the solid is not valid (BRepCheck failed: open shell or bad geometry)")
    if not BRepAlgoAPI_Check(solid.wrapped, True, True).IsValid():
        raise LinkFeaError(f"{label}: the solid intersects itself or has degenerate edges")
    if not solid.Volume() > 0:
        raise LinkFeaError(f"{label}: the solid has no volume (open or inside-out shell)")
    v, f = tessellate(solid, 1e-3 * _size(solid))
    tm = trimesh.Trimesh(v, f, process=True)
    if not tm.is_watertight:
        raise LinkFeaError(f"{label}: the surface is not watertight (open shell or gaps between faces)")


def _size(shape) -> float:
    """Bounding-box diagonal, mm."""
    return float(shape.BoundingBox().DiagonalLength)


def tessellate(shape, tol: float, angular_tol: float = 0.2) -> tuple[np.ndarray, np.ndarray]:
    """Triangulate a shape's surface: vertices (n, 3) float64 and triangles (m, 3) int64."""
    v, f = shape.tessellate(tol, angular_tol)
    V = np.array([p.toTuple() for p in v], dtype=float).reshape(-1, 3)
    F = np.array(f, dtype=np.int64).reshape(-1, 3)
    return V, F
