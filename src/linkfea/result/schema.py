"""The link result JSON: schema, writing a JSON document atomically, and the validated read.

Schema (``"schema": "linkfea.result/1"``)::

    name, source, params, material {name, E, nu, density (t/mm^3)}, mode, block_ratio,
    volume_mm3   the link body's CAD volume, mm^3 (reference block excluded)
    mass_kg      volume * density, kg (null if the material has no density)
    compliance   6x6 nested lists, t = C w
    stiffness    6x6 nested lists, inverse of compliance
    order        {"wrench": [Fx..Mz], "twist": [dx..rz]}
    units        compliance / stiffness blocks, lengths, forces, stresses
    frame        Frame.to_dict(): origin, x_axis, y_axis, z_axis in CAD coordinates (mm)
    mesh         mesher, mesher_version, n_nodes, n_tets, n_dofs, edge_length, envelope, quality {...}
    diagnostics  symmetry_error, fit_residual, min_eigenvalue, error_estimate (null unless --convergence),
                 discretization_error (the recovered-stress estimate: diagonal, matrix, bound, raw_diagonal,
                 safety_factor, method, note), sharp_edges (count, note), refinement (with --tolerance)
    solver       factorizer that ran (pardiso | superlu | cg+p1mg | cg+amg), fallback_reason (null unless PARDISO
                 failed), choice (with --solver auto), convergence (CG: levels, iterations, residuals)
    timing       seconds per stage: cad, mesh, assemble, factor, solve, fit, total
    versions     python and package versions
"""
from __future__ import annotations

import json
import platform
from importlib import metadata
from pathlib import Path

import numpy as np

from ..files.atomic import plain, write_text
from ..files.outputs import roll_forward_file
from ..mechanics.compliance import check
from ..mechanics.frames import Frame
from ..runtime.errors import LinkFeaError

SCHEMA = "linkfea.result/1"
__all__ = ["SCHEMA", "read_result", "versions", "write_json_atomic"]


def versions() -> dict:
    out = {"python": platform.python_version()}
    for pkg in ("linkfea-vjm", "numpy", "scipy", "scikit-fem", "gmsh", "pytetwild", "cadquery", "pypardiso", "pyvista"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = None
    return out


def write_json_atomic(path, doc: dict) -> Path:
    """Write JSON to a temporary file beside ``path``, then ``os.replace`` it."""
    path = Path(path)
    write_text(path, json.dumps(plain(doc), indent=2) + "\n")
    return path


#: largest |C K - I| of a result's compliance C and stiffness K (both written at full precision)
INVERSE_TOL = 1e-6


def check_stiffness(K, C: np.ndarray, where: str) -> None:
    """A stored stiffness ``K`` must be the inverse of the compliance ``C`` it is stored with."""
    try:
        K = np.asarray(K, dtype=float)
    except (TypeError, ValueError):
        raise LinkFeaError(f"{where} is not a 6x6 matrix of numbers") from None
    if K.shape != (6, 6) or not np.all(np.isfinite(K)):
        raise LinkFeaError(f"{where} is not a finite 6x6 matrix")
    err = float(np.max(np.abs(C @ K - np.eye(6))))
    if not err <= INVERSE_TOL:
        raise LinkFeaError(f"{where} contradicts the compliance: |C K - I| = {err:.2g} (> {INVERSE_TOL:g}); "
                           f"the file was edited or damaged")


def read_result(path) -> dict:
    """Read and validate a link result JSON.

    Returns the document with ``compliance`` and ``stiffness`` as 6x6 arrays
    and ``frame`` as a :class:`Frame` (under ``frame_obj``).

    Raises
    ------
    LinkFeaError
        Missing file or keys (``schema`` included), a compliance that is not a
        finite, symmetric, positive-definite 6x6 matrix, a stored stiffness
        that is not its inverse.
    """
    path = Path(path)
    roll_forward_file(path)  # a write killed after its commit point is completed first
    try:
        doc = json.loads(path.read_text())
    except FileNotFoundError:
        raise LinkFeaError(f"link result {str(path)!r} not found") from None
    except (OSError, ValueError) as exc:
        raise LinkFeaError(f"cannot read link result {str(path)!r}: {exc}") from None
    if not isinstance(doc, dict):
        raise LinkFeaError(f"{path}: not a linkfea result (expected a JSON object)")
    missing = [k for k in ("schema", "compliance", "frame", "units") if k not in doc]
    if missing:
        raise LinkFeaError(f"{path}: not a linkfea result, missing {', '.join(missing)}")
    if doc["schema"] != SCHEMA:
        raise LinkFeaError(f"{path}: schema {doc['schema']!r} is not {SCHEMA!r} (not a result of this linkfea)")
    C = check(doc["compliance"], f"{path}: compliance")
    doc["compliance"] = C
    K = np.linalg.inv(C)
    if "stiffness" in doc:
        check_stiffness(doc["stiffness"], C, f"{path}: stiffness")
    doc["stiffness"] = K
    doc["frame_obj"] = Frame.from_dict(doc["frame"])
    return doc
