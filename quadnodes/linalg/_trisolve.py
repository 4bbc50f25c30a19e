"""Compiled (Numba) sweeps of sparse triangular factors over a block of right-hand sides.

The block ``W`` is ``(n, w)`` C-contiguous: each factor entry updates one row of
``w`` contiguous numbers, a loop that vectorizes. Compiled on first use, cached on disk.
"""

from __future__ import annotations

import numba as nb
import numpy as np

__all__ = ["lower_unit_sweep", "upper_sweep", "upper_transposed_sweep"]


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def lower_unit_sweep(ptr: np.ndarray, idx: np.ndarray, val: np.ndarray, W: np.ndarray) -> None:  # pragma: no cover
    """``W ← L⁻¹ W`` for a unit lower triangular ``L`` in CSC (a stored diagonal is skipped)."""
    n, w = W.shape
    for j in range(n):
        xj = W[j]
        zero = True  # unit right-hand sides reach only their elimination-tree ancestors: skip the zero rows
        for c in range(w):
            if xj[c] != 0.0:
                zero = False
                break
        if zero:
            continue
        for q in range(ptr[j], ptr[j + 1]):
            i = idx[q]
            if i == j:  # a stored diagonal entry (SuperLU's L keeps its ones)
                continue
            v = val[q]
            xi = W[i]
            for c in range(w):
                xi[c] -= v * xj[c]


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def upper_sweep(ptr: np.ndarray, idx: np.ndarray, val: np.ndarray, diag: np.ndarray,
                W: np.ndarray) -> None:  # pragma: no cover
    """``W ← U⁻¹ W`` for an upper triangular ``U`` given by its strictly upper part in CSC and its diagonal."""
    n, w = W.shape
    for j in range(n - 1, -1, -1):
        xj = W[j]
        d = 1.0 / diag[j]
        for c in range(w):
            xj[c] *= d
        for q in range(ptr[j], ptr[j + 1]):
            v = val[q]
            xi = W[idx[q]]
            for c in range(w):
                xi[c] -= v * xj[c]


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def upper_transposed_sweep(ptr: np.ndarray, idx: np.ndarray, val: np.ndarray, diag: np.ndarray,
                           W: np.ndarray) -> None:  # pragma: no cover
    """``W ← U⁻ᵀ W`` for an upper triangular ``U`` in CSR (a stored diagonal is skipped) and its diagonal
    (``Uᵀ`` is lower triangular: a forward sweep, which skips the rows a unit right-hand side does not reach)."""
    n, w = W.shape
    for j in range(n):
        xj = W[j]
        zero = True
        for c in range(w):
            if xj[c] != 0.0:
                zero = False
                break
        if zero:
            continue
        d = 1.0 / diag[j]
        for c in range(w):
            xj[c] *= d
        for q in range(ptr[j], ptr[j + 1]):
            i = idx[q]
            if i == j:  # a stored diagonal entry (SuperLU's L keeps its ones)
                continue
            v = val[q]
            xi = W[i]
            for c in range(w):
                xi[c] -= v * xj[c]
