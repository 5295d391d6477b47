"""Refinement driven by the error estimate: local sizes for gmsh from the per-element indicator.

One step (Dörfler marking): the elements with the largest indicators that together hold
:data:`MARK_FRACTION` of the estimated error are halved in size; the others keep theirs.  The
new sizes reach gmsh as a size callback (nearest element centroid of the previous mesh), so the
next mesh follows the CAD exactly and grades along the singular edges by itself.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

MARK_FRACTION = 0.5
"""Share of the estimated error (sum of the indicator) whose elements are refined per step."""
SIZE_FACTOR = 0.5
"""New edge length of a marked element, as a fraction of its present one."""


def element_sizes(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Mean edge length (mm) of each linear tet."""
    X = points[tets]
    pairs = [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)]
    return np.mean([np.linalg.norm(X[:, i] - X[:, j], axis=1) for i, j in pairs], axis=0)


def marked(indicator: np.ndarray, fraction: float = MARK_FRACTION) -> np.ndarray:
    """Boolean mask of the fewest elements whose indicators sum to ``fraction`` of the total."""
    ind = np.asarray(indicator, dtype=float)
    order = np.argsort(-ind)
    csum = np.cumsum(ind[order])
    n = int(np.searchsorted(csum, fraction * csum[-1])) + 1
    mask = np.zeros(len(ind), dtype=bool)
    mask[order[:n]] = True
    return mask


def size_function(points: np.ndarray, tets: np.ndarray, indicator: np.ndarray,
                  fraction: float = MARK_FRACTION) -> Callable[[float, float, float], float]:
    """``size_at(x, y, z)``: the refined local edge length for the next mesh (see the module)."""
    from scipy.spatial import cKDTree

    h = element_sizes(points, tets)
    h = np.where(marked(indicator, fraction), SIZE_FACTOR * h, h)
    tree = cKDTree(points[tets].mean(axis=1))

    def size_at(x: float, y: float, z: float) -> float:
        return float(h[tree.query((x, y, z))[1]])

    return size_at
