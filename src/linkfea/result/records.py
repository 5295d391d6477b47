"""The typed parts of a link result: what the mesh was (:class:`MeshInfo`) and how good the
compliance is (:class:`Diagnostics`).  Each writes its object of the result JSON (``to_dict``, the
keys in the order the JSON has always had) and reads it back (``from_dict``)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Optional


@dataclass(frozen=True)
class MeshInfo:
    """The mesh a compliance was computed on (the result JSON's ``mesh``)."""

    mesher: Optional[str]
    mesher_version: Optional[str]
    n_nodes: int
    n_tets: int
    n_dofs: int
    n_p2_nodes: int
    edge_length: float
    envelope: float
    element: str
    quality: dict = field(default_factory=dict)
    """The meshers' quality report (radius ratios, edge lengths, volume and interface-area errors)."""
    cache_key: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {"mesher": self.mesher, "mesher_version": self.mesher_version, "n_nodes": self.n_nodes,
                "n_tets": self.n_tets, "n_dofs": self.n_dofs, "n_p2_nodes": self.n_p2_nodes,
                "edge_length": self.edge_length, "envelope": self.envelope, "element": self.element,
                "quality": dict(self.quality), "cache_key": self.cache_key}

    @classmethod
    def from_dict(cls, d: dict) -> "MeshInfo":
        return cls(d.get("mesher"), d.get("mesher_version"), int(d["n_nodes"]), int(d["n_tets"]), int(d["n_dofs"]),
                   int(d.get("n_p2_nodes", 0)), float(d["edge_length"]), float(d.get("envelope", 0.0)),
                   str(d.get("element", "")), dict(d.get("quality") or {}), str(d.get("cache_key") or ""))


@dataclass(frozen=True)
class Diagnostics:
    """How far the compliance can be trusted (the result JSON's ``diagnostics``)."""

    symmetry_error: float
    fit_residual: float
    min_eigenvalue: float
    error_estimate: Optional[float]
    """Richardson estimate of the diagonal's relative error (None unless ``convergence`` ran)."""
    error_estimate_note: str
    discretization_error: Optional[dict] = None
    """The recovered-stress estimate (:meth:`linkfea.fem.estimate.ErrorEstimate.to_dict`)."""
    sharp_edges: Optional[dict] = None
    """Count of sharp re-entrant CAD edges and what it means."""
    refinement: Optional[dict] = None
    """With a tolerance: reached or not, and each refinement step's DOF and error."""
    observed_order: Optional[float] = None
    convergence_sizes: Optional[list] = None

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {} if self.refinement is None else {"refinement": self.refinement}
        d["error_estimate"] = self.error_estimate
        if self.observed_order is not None:
            d.update(observed_order=self.observed_order, convergence_sizes=self.convergence_sizes)
        d["error_estimate_note"] = self.error_estimate_note
        d.update({k: v for k, v in (("discretization_error", self.discretization_error),
                                    ("sharp_edges", self.sharp_edges)) if v is not None})
        d.update(symmetry_error=self.symmetry_error, fit_residual=self.fit_residual,
                 min_eigenvalue=self.min_eigenvalue)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "Diagnostics":
        return cls(float(d["symmetry_error"]), float(d["fit_residual"]), float(d["min_eigenvalue"]),
                   d.get("error_estimate"), str(d.get("error_estimate_note", "")), d.get("discretization_error"),
                   d.get("sharp_edges"), d.get("refinement"), d.get("observed_order"), d.get("convergence_sizes"))
