"""Tetrahedral meshing of a link with pytetwild, cached by content hash.

(Skeleton: the LinkMesh contract is fixed here; meshing is filled in.)
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .frames import Frame


@dataclass(frozen=True)
class LinkMesh:
    """A linear tetrahedral mesh of a link, ready for P2 analysis.

    Attributes
    ----------
    points : ndarray (n, 3)
        Vertex coordinates in CAD coordinates, mm.
    tets : ndarray (m, 4) int
        Positively oriented tetrahedra.
    block : ndarray (m,) bool
        True for cells of the pseudo-rigid reference block.
    base_facets : ndarray (k, 3) int
        Boundary triangles of the clamped base interface.
    tip_facets : ndarray (k2, 3) int
        Boundary (or body/block interface) triangles of the tip interface.
    frame : Frame
        The link's reference frame (origin at the tip interface centroid, x along the link).
    edge_length : float
        Target edge length used for meshing, mm.
    envelope : float
        Surface envelope of the mesher, mm: how far boundary vertices may sit from the CAD.
    quality : dict
        Mesh quality report (e.g. min/mean scaled Jacobian or aspect ratio).
    """

    points: np.ndarray
    tets: np.ndarray
    block: np.ndarray
    base_facets: np.ndarray
    tip_facets: np.ndarray
    frame: Frame
    edge_length: float
    envelope: float = 0.0
    quality: dict = field(default_factory=dict)

    @property
    def n_nodes(self) -> int:
        return len(self.points)

    @property
    def n_tets(self) -> int:
        return len(self.tets)
