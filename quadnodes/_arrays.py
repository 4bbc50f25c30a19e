"""Sorted unique values and rows of integer arrays, by sorting.

NumPy 2.3+ finds ``np.unique``'s values of an integer array with a hash table, which is far
slower than a sort here: a million int64 keys take 4.7 s against 0.07 s sorted, a million
index pairs (``axis=0``) 4.5 s against 0.15 s (NumPy 2.4, ``benchmarks/studies/unique_sort.py``).
Meshes call it on every edge or
face, so the package uses these instead; the results are ``np.unique``'s exactly (sorted).

Examples
--------
>>> unique_values(np.array([3, 1, 3, 2])).tolist()
[1, 2, 3]
>>> unique_rows(np.array([[2, 1], [0, 5], [2, 1]])).tolist()
[[0, 5], [2, 1]]
"""

from __future__ import annotations

import numpy as np

__all__ = ["unique_values", "unique_rows"]


def unique_values(a: np.ndarray) -> np.ndarray:
    """The sorted distinct values of ``a`` (flattened), as ``np.unique(a)``.

    Parameters
    ----------
    a : (...) integer or float array

    Returns
    -------
    (u,) array of ``a``'s dtype
    """
    s = np.sort(np.asarray(a).reshape(-1))
    if s.size == 0:
        return s
    keep = np.empty(s.size, dtype=bool)
    keep[0] = True
    np.not_equal(s[1:], s[:-1], out=keep[1:])
    return s[keep]


def unique_rows(a: np.ndarray) -> np.ndarray:
    """The distinct rows of the integer array ``a`` in lexicographic order, as ``np.unique(a, axis=0)``.

    Rows of two non-negative columns below 2³¹ are packed into one int64 key and sorted
    once; other shapes are ordered by ``np.lexsort``.

    Parameters
    ----------
    a : (m, k) integer array

    Returns
    -------
    (u, k) array of ``a``'s dtype
    """
    a = np.asarray(a)
    if a.ndim != 2:
        raise ValueError(f"unique_rows: expected a 2-D array, got shape {a.shape}")
    if len(a) == 0:
        return a.copy()
    if a.shape[1] == 2 and a.min() >= 0 and a.max() < 2**31:
        key = unique_values(a[:, 0].astype(np.int64) << 32 | a[:, 1].astype(np.int64))
        out = np.empty((key.size, 2), dtype=a.dtype)
        out[:, 0] = key >> 32
        out[:, 1] = key & 0xFFFFFFFF
        return out
    s = a[np.lexsort(a.T[::-1])]
    keep = np.empty(len(s), dtype=bool)
    keep[0] = True
    np.any(s[1:] != s[:-1], axis=1, out=keep[1:])
    return s[keep]
