"""Sparse-matrix helpers of the solvers: the stiffness is assembled as its upper triangle."""
from __future__ import annotations

import scipy.sparse as sp


def symmetric_from_upper(U: sp.spmatrix) -> sp.csr_matrix:
    """Full symmetric matrix from its upper triangle with diagonal."""
    U = sp.csr_matrix(U)
    return (U + sp.triu(U, k=1, format="csr").T).tocsr()
