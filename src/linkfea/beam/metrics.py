"""Errors of a beam compliance against the FEA one (``linkfea compare``).

Error measures (:func:`compare_compliance`), all dimensionless
    * per entry: ``e_ij = (C_beam_ij - C_fea_ij) / sqrt(C_fea_ii C_fea_jj)``.
      On the diagonal this is the ordinary signed relative error; off the
      diagonal it is the error of the coupling measured against the geometric
      mean of the two direct compliances it couples (the error of the
      correlation coefficient), which stays meaningful where the FEA coupling
      itself is near zero and does not depend on the choice of units.
    * principal compliances: translation and rotation are not commensurable,
      so the 3x3 translational block (displacement of the frame origin under a
      pure force there) and the 3x3 rotational block (rotation under a pure
      couple) are eigen-decomposed separately.  Beam eigenpairs are matched to
      FEA ones by their directions; relative eigenvalue error
      ``|l_beam - l_fea| / l_fea``; direction error = angle between matched
      principal directions.  Eigenvalues closer than 2 % (in either model) form
      a cluster whose directions are not defined one by one: the angle is then
      the largest principal angle between the two clusters' subspaces.
    * summary: largest principal error of both blocks, largest direction angle,
      largest |diagonal error|, largest |coupling error|.
"""
from __future__ import annotations

import itertools

import numpy as np

from ..runtime.errors import LinkFeaError

CLUSTER_TOL = 0.02


def entry_errors(C_fea, C_beam) -> np.ndarray:
    """Signed ``(C_beam - C_fea) / sqrt(C_fea_ii C_fea_jj)``, 6x6."""
    C_fea, C_beam = np.asarray(C_fea, float), np.asarray(C_beam, float)
    d = np.diag(C_fea)
    if np.any(d <= 0):
        raise LinkFeaError("FEA compliance must have a positive diagonal")
    return (C_beam - C_fea) / np.sqrt(np.outer(d, d))


def principal_errors(A_fea, A_beam, tol: float = CLUSTER_TOL) -> dict:
    """Eigenvalue and direction errors of two symmetric 3x3 blocks (see module docstring)."""
    from scipy.linalg import subspace_angles

    lf, Vf = np.linalg.eigh(np.asarray(A_fea, float))
    lb, Vb = np.linalg.eigh(np.asarray(A_beam, float))
    overlap = np.abs(Vf.T @ Vb) ** 2
    perm = max(itertools.permutations(range(3)), key=lambda p: sum(overlap[i, p[i]] for i in range(3)))
    lb, Vb = lb[list(perm)], Vb[:, list(perm)]
    # Clusters of (nearly) equal eigenvalues in either model: union-find on 3 items.
    group = list(range(3))
    for i, j in itertools.combinations(range(3), 2):
        close = lambda l, i=i, j=j: abs(l[i] - l[j]) <= tol * max(abs(l[i]), abs(l[j]))  # noqa: E731
        if close(lf) or close(lb):
            gi, gj = group[i], group[j]
            group = [gi if g == gj else g for g in group]
    rel = np.empty(3)
    ang = np.empty(3)
    for g in set(group):
        idx = [k for k in range(3) if group[k] == g]
        rel[idx] = np.abs(np.sort(lb[idx]) - np.sort(lf[idx])) / np.sort(lf[idx])
        ang[idx] = np.rad2deg(np.max(subspace_angles(Vf[:, idx], Vb[:, idx])))
    return {"fea_eigenvalues": lf.tolist(), "beam_eigenvalues": lb.tolist(),
            "fea_directions": Vf.T.tolist(), "beam_directions": Vb.T.tolist(),
            "relative_error": rel.tolist(), "angle_deg": ang.tolist(),
            "max_relative_error": float(rel.max()), "max_angle_deg": float(ang.max())}


def compare_compliance(C_fea, C_beam) -> dict:
    """All error measures of a beam compliance against the FEA one (same frame)."""
    E = entry_errors(C_fea, C_beam)
    off = E[np.triu_indices(6, 1)]
    tr = principal_errors(np.asarray(C_fea)[:3, :3], np.asarray(C_beam)[:3, :3])
    ro = principal_errors(np.asarray(C_fea)[3:, 3:], np.asarray(C_beam)[3:, 3:])
    return {
        "entry_error": E.tolist(),
        "diagonal_error": np.diag(E).tolist(),
        "coupling_error": {"C26 (dy-Mz)": float(E[1, 5]), "C35 (dz-My)": float(E[2, 4])},
        "principal": {"translation": tr, "rotation": ro},
        "summary": {
            "max_principal_error": max(tr["max_relative_error"], ro["max_relative_error"]),
            "max_principal_error_translation": tr["max_relative_error"],
            "max_principal_error_rotation": ro["max_relative_error"],
            "max_angle_deg": max(tr["max_angle_deg"], ro["max_angle_deg"]),
            "max_abs_diagonal_error": float(np.max(np.abs(np.diag(E)))),
            "max_abs_coupling_error": float(np.max(np.abs(off))),
        },
    }
