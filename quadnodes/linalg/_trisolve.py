"""Compiled (Numba) sweeps of sparse triangular factors over a block of right-hand sides.

The block ``W`` is ``(n, w)`` C-contiguous: each factor entry updates one row of
``w`` contiguous numbers, a loop that vectorizes. Compiled on first use, cached on disk.
"""

from __future__ import annotations

import numba as nb
import numpy as np

__all__ = ["forward_sweep", "upper_sweep"]


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def forward_sweep(ptr: np.ndarray, idx: np.ndarray, val: np.ndarray, diag: np.ndarray | None,
                  W: np.ndarray) -> None:  # pragma: no cover
    """``W ← T⁻¹ W`` for a lower triangular ``T`` stored by columns: the CSC of ``L`` (``diag`` None: a unit
    diagonal) or the CSR of an upper ``U`` (``T = Uᵀ``, ``diag`` its diagonal); a stored diagonal entry is
    skipped (SuperLU's ``L`` keeps its ones). Rows still zero are skipped: unit right-hand sides reach only
    their elimination-tree ancestors."""
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
        if diag is not None:
            d = 1.0 / diag[j]
            for c in range(w):
                xj[c] *= d
        for q in range(ptr[j], ptr[j + 1]):
            i = idx[q]
            if i == j:
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
