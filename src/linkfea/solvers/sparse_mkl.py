"""Products of a sparse matrix with blocks of vectors through MKL's sparse BLAS (inspector-executor).

The iterative solver's time is products of the stiffness with (n, 6) blocks.  scipy's CSR
product runs one scalar loop per stored entry; MKL's ``mkl_sparse_d_mm`` (row-major blocks) is
about 2x faster on one core (measured on a 78k-DOF P2 bar: 27 ms against 56-68 ms), and with a
symmetric descriptor it reads only the upper triangle, which the solve already has: no full
symmetric copy (half the matrix memory).  MKL comes with pypardiso (the direct solver); without
it, or for a matrix beyond 32-bit indices, :func:`operator` falls back to scipy.
"""
from __future__ import annotations

import ctypes
import logging
import os
from pathlib import Path
from typing import Optional

import numpy as np
import scipy.sparse as sp

log = logging.getLogger(__name__)

# MKL's enums (mkl_spblas.h).
_INDEX_BASE_ZERO = 0
_OPERATION_NON_TRANSPOSE = 10
_MATRIX_TYPE_GENERAL, _MATRIX_TYPE_SYMMETRIC = 20, 21
_FILL_MODE_UPPER = 41
_DIAG_NON_UNIT = 50
_LAYOUT_ROW_MAJOR = 101


class _Descr(ctypes.Structure):
    _fields_ = [("type", ctypes.c_int), ("mode", ctypes.c_int), ("diag", ctypes.c_int)]


def point_pypardiso_at_mkl() -> None:
    """Tell pypardiso where MKL's ``mkl_rt`` is (``PYPARDISO_MKL_RT``), from the ``mkl`` wheel's file list.

    Without it, importing pypardiso and creating each solver search the whole environment for
    the library (``glob('**/*mkl_rt*')``), about 0.6 s each on this venv; an explicit setting
    by the user is kept.
    """
    if os.environ.get("PYPARDISO_MKL_RT"):
        return
    try:
        from importlib.metadata import PackageNotFoundError, files
    except ImportError:  # pragma: no cover
        return
    try:
        found = [f for f in files("mkl") or () if f.name.startswith("libmkl_rt.so") or f.name == "mkl_rt.2.dll"]
    except PackageNotFoundError:
        return
    for f in found:
        path = Path(str(f.locate())).resolve()
        if path.is_file():
            os.environ["PYPARDISO_MKL_RT"] = str(path)
            return


_LIB: list = []


def _mkl() -> Optional[ctypes.CDLL]:
    """MKL's runtime library (the one pypardiso uses), or None."""
    if not _LIB:
        lib = None
        try:
            point_pypardiso_at_mkl()
            path = os.environ.get("PYPARDISO_MKL_RT")
            if path:
                lib = ctypes.CDLL(path)
                lib.mkl_sparse_d_mm.argtypes = [ctypes.c_int, ctypes.c_double, ctypes.c_void_p, _Descr, ctypes.c_int,
                                                ctypes.c_void_p, ctypes.c_int, ctypes.c_int, ctypes.c_double,
                                                ctypes.c_void_p, ctypes.c_int]
                lib.mkl_sparse_d_mv.argtypes = [ctypes.c_int, ctypes.c_double, ctypes.c_void_p, _Descr,
                                                ctypes.c_void_p, ctypes.c_double, ctypes.c_void_p]
                lib.mkl_sparse_d_create_csr.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_int, ctypes.c_int,
                                                        ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p,
                                                        ctypes.c_void_p]
                lib.mkl_sparse_destroy.argtypes = [ctypes.c_void_p]
                lib.mkl_sparse_set_mm_hint.argtypes = [ctypes.c_void_p, ctypes.c_int, _Descr, ctypes.c_int,
                                                       ctypes.c_int, ctypes.c_int]
                lib.mkl_sparse_optimize.argtypes = [ctypes.c_void_p]
        except (OSError, AttributeError) as exc:  # pragma: no cover (no MKL here)
            log.info("MKL sparse BLAS not available (%s); scipy's products", exc)
            lib = None
        _LIB.append(lib)
    return _LIB[0]


class MklMatrix:
    """``M @ X`` for a CSR matrix (``symmetric_upper``: the upper triangle of a symmetric one) and
    ``X`` an (n,) vector or (n, k) block; the product is MKL's, the result a new array."""

    def __init__(self, M: sp.csr_matrix, symmetric_upper: bool, lib: ctypes.CDLL, block_columns: int = 6,
                 expected_calls: int = 500):
        M = sp.csr_matrix(M)
        M.sort_indices()
        self.shape = M.shape
        self.nnz = M.nnz
        self._indptr = np.ascontiguousarray(M.indptr, dtype=np.int32)
        self._indices = np.ascontiguousarray(M.indices, dtype=np.int32)
        self._data = np.ascontiguousarray(M.data, dtype=np.float64)
        self._diag = np.asarray(M.diagonal(), dtype=float)
        self._lib = lib
        self._handle = ctypes.c_void_p()
        p = self._indptr.ctypes.data
        status = lib.mkl_sparse_d_create_csr(ctypes.byref(self._handle), _INDEX_BASE_ZERO, M.shape[0], M.shape[1],
                                             p, p + 4, self._indices.ctypes.data, self._data.ctypes.data)
        if status != 0:
            raise RuntimeError(f"mkl_sparse_d_create_csr failed (status {status})")
        self._descr = (_Descr(_MATRIX_TYPE_SYMMETRIC, _FILL_MODE_UPPER, _DIAG_NON_UNIT) if symmetric_upper
                       else _Descr(_MATRIX_TYPE_GENERAL, _FILL_MODE_UPPER, _DIAG_NON_UNIT))
        # MKL's inspector: with the hint of many products with 6-column blocks, it lays the matrix out
        # for them (for a symmetric one, a full copy inside MKL: 3x faster than the triangle as given).
        lib.mkl_sparse_set_mm_hint(self._handle, _OPERATION_NON_TRANSPOSE, self._descr, _LAYOUT_ROW_MAJOR,
                                   block_columns, expected_calls)
        lib.mkl_sparse_optimize(self._handle)

    def diagonal(self) -> np.ndarray:
        return self._diag

    def __matmul__(self, X):
        X = np.ascontiguousarray(X, dtype=np.float64)
        if X.ndim == 1:
            Y = np.empty(self.shape[0])
            status = self._lib.mkl_sparse_d_mv(_OPERATION_NON_TRANSPOSE, 1.0, self._handle, self._descr,
                                               X.ctypes.data, 0.0, Y.ctypes.data)
        else:
            k = X.shape[1]
            Y = np.empty((self.shape[0], k))
            status = self._lib.mkl_sparse_d_mm(_OPERATION_NON_TRANSPOSE, 1.0, self._handle, self._descr,
                                               _LAYOUT_ROW_MAJOR, X.ctypes.data, k, k, 0.0, Y.ctypes.data, k)
        if status != 0:
            raise RuntimeError(f"MKL sparse product failed (status {status})")
        return Y

    def __del__(self):
        if getattr(self, "_handle", None):
            self._lib.mkl_sparse_destroy(self._handle)
            self._handle = None


def operator(M: sp.spmatrix, symmetric_upper: bool = False):
    """A matrix-product operator for ``M`` (its upper triangle if ``symmetric_upper``): MKL's if
    available, else the scipy matrix itself (made full symmetric if given as a triangle)."""
    lib = _mkl()
    if lib is not None and M.nnz < 2**31 - 1 and max(M.shape) < 2**31 - 1:
        try:
            return MklMatrix(sp.csr_matrix(M), symmetric_upper, lib)
        except RuntimeError as exc:  # pragma: no cover
            log.warning("MKL sparse products unavailable (%s); scipy's", exc)
    if symmetric_upper:
        from .sparse import symmetric_from_upper

        return symmetric_from_upper(M).tocsr()
    return sp.csr_matrix(M)
