"""The link result JSON: schema, atomic write and validated read.

Schema (``"schema": "linkfea.result/1"``)::

    name, source, params, material {name, E, nu}, mode, block_ratio,
    compliance   6x6 nested lists, t = C w
    stiffness    6x6 nested lists, inverse of compliance
    order        {"wrench": [Fx..Mz], "twist": [dx..rz]}
    units        compliance / stiffness blocks, lengths, forces, stresses
    frame        Frame.to_dict(): origin, x_axis, y_axis, z_axis in CAD coordinates (mm)
    mesh         mesher, mesher_version, n_nodes, n_tets, n_dofs, edge_length, envelope, quality {...}
    diagnostics  symmetry_error, fit_residual, min_eigenvalue, error_estimate (null unless --convergence)
    timing       seconds per stage: cad, mesh, assemble, factor, solve, fit, total
    versions     python and package versions
"""
from __future__ import annotations

import json
import platform
from importlib import metadata
from pathlib import Path

import numpy as np

from .atomic import plain, write_text
from .errors import LinkFeaError
from .frames import Frame

SCHEMA = "linkfea.result/1"
WRENCH = ["Fx", "Fy", "Fz", "Mx", "My", "Mz"]
TWIST = ["dx", "dy", "dz", "rx", "ry", "rz"]
UNITS = {
    "compliance": {"force->translation": "mm/N", "moment->rotation": "rad/(N*mm)",
                   "moment->translation": "mm/(N*mm) = 1/N", "force->rotation": "rad/N"},
    "stiffness": {"translation->force": "N/mm", "rotation->moment": "N*mm/rad",
                  "rotation->force": "N/rad", "translation->moment": "N*mm/mm = N"},
    "length": "mm", "force": "N", "moment": "N*mm", "stress": "MPa", "time": "s",
}
SYMMETRY_RTOL = 1e-6


def versions() -> dict:
    out = {"python": platform.python_version()}
    for pkg in ("linkfea-vjm", "numpy", "scipy", "scikit-fem", "gmsh", "pytetwild", "cadquery", "pypardiso", "pyvista"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = None
    return out


def result_dict(res) -> dict:
    """The JSON document of a :class:`linkfea.pipeline.LinkResult`."""
    link, mesh, sol, comp = res.link, res.mesh, res.solution, res.compliance
    return plain({
        "schema": SCHEMA,
        "name": link.name,
        "source": str(link.source),
        "params": dict(link.params),
        "material": {"name": res.material.name, "E": res.material.E, "nu": res.material.nu},
        "mode": res.mode,
        "block_ratio": res.block_ratio,
        "compliance": comp.matrix,
        "stiffness": comp.stiffness,
        "order": {"wrench": WRENCH, "twist": TWIST},
        "units": UNITS,
        "frame": comp.frame.to_dict(),
        "mesh": {"mesher": mesh.mesher, "mesher_version": mesh.mesher_version, "n_nodes": int(mesh.n_nodes), "n_tets": int(mesh.n_tets), "n_dofs": int(sol.n_dofs),
                 "n_p2_nodes": int(len(sol.points)), "edge_length": float(mesh.edge_length),
                 "envelope": float(mesh.envelope), "element": "P2 tetrahedron (10 nodes)",
                 "quality": dict(mesh.quality), "cache_key": mesh.cache_key},
        "diagnostics": dict(res.diagnostics),
        "timing": dict(res.timing),
        "versions": versions(),
    })


def write_json_atomic(path, doc: dict) -> Path:
    """Write JSON to a temporary file beside ``path``, then ``os.replace`` it."""
    path = Path(path)
    write_text(path, json.dumps(plain(doc), indent=2) + "\n")
    return path


def write_result(path, res) -> Path:
    """Write a link result as JSON (atomic)."""
    return write_json_atomic(path, result_dict(res))


def read_result(path) -> dict:
    """Read and validate a link result JSON.

    Returns the document with ``compliance`` and ``stiffness`` as 6x6 arrays
    and ``frame`` as a :class:`Frame` (under ``frame_obj``).

    Raises
    ------
    LinkFeaError
        Missing file or keys, a compliance that is not a finite, symmetric,
        positive-definite 6x6 matrix.
    """
    path = Path(path)
    try:
        doc = json.loads(path.read_text())
    except FileNotFoundError:
        raise LinkFeaError(f"link result {str(path)!r} not found") from None
    except (OSError, ValueError) as exc:
        raise LinkFeaError(f"cannot read link result {str(path)!r}: {exc}") from None
    if not isinstance(doc, dict):
        raise LinkFeaError(f"{path}: not a linkfea result (expected a JSON object)")
    missing = [k for k in ("compliance", "frame", "units") if k not in doc]
    if missing:
        raise LinkFeaError(f"{path}: not a linkfea result, missing {', '.join(missing)}")
    try:
        C = np.asarray(doc["compliance"], dtype=float)
    except (TypeError, ValueError):
        raise LinkFeaError(f"{path}: compliance is not a numeric matrix") from None
    if C.shape != (6, 6) or not np.all(np.isfinite(C)):
        raise LinkFeaError(f"{path}: compliance must be a finite 6x6 matrix, got shape {C.shape}")
    scale = np.sqrt(np.abs(np.outer(np.diag(C), np.diag(C)))) + np.finfo(float).tiny
    if np.max(np.abs(C - C.T) / scale) > SYMMETRY_RTOL:
        raise LinkFeaError(f"{path}: compliance is not symmetric")
    d = np.diag(C)
    if np.any(d <= 0) or np.linalg.eigvalsh(C / np.sqrt(np.outer(d, d)))[0] <= 0:
        raise LinkFeaError(f"{path}: compliance is not positive definite")
    doc["compliance"] = C
    doc["stiffness"] = np.linalg.inv(C)
    doc["frame_obj"] = Frame.from_dict(doc["frame"])
    return doc
