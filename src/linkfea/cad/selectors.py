"""Interface selectors: which CAD faces are the base and the tip of a link.

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

import math
from dataclasses import dataclass
from typing import Union

import numpy as np

from ..runtime.errors import LinkFeaError

DEFAULT_TOL = 0.01
"""Default selector tolerance, mm (CAD faces are exact, so this only absorbs round-off)."""


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
