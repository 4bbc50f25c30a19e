"""Array helpers: sorted unique values and rows of integer arrays by sorting, and cross products and
lengths of vectors stored coordinates-as-rows.

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

__all__ = ["unique_values", "unique_rows", "cross_rows", "norm_rows"]


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


def cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross products of ``(3, m)`` vectors (coordinates as rows), as ``np.cross`` computes them.

    NumPy's cross product and norms of ``(m, 3)`` arrays run over an inner dimension of 3,
    several times slower than these contiguous passes; the operations and their order are
    ``np.cross``'s, so the results are the same to the bit.

    Examples
    --------
    >>> cross_rows(np.array([[1.0], [0.0], [0.0]]), np.array([[0.0], [1.0], [0.0]])).ravel().tolist()
    [0.0, 0.0, 1.0]
    """
    out = np.empty_like(a)
    np.multiply(a[1], b[2], out=out[0])
    out[0] -= a[2] * b[1]
    np.multiply(a[2], b[0], out=out[1])
    out[1] -= a[0] * b[2]
    np.multiply(a[0], b[1], out=out[2])
    out[2] -= a[1] * b[0]
    return out


def norm_rows(a: np.ndarray) -> np.ndarray:
    """Euclidean lengths ``(m,)`` of ``(3, m)`` vectors, summed in ``np.linalg.norm``'s order (same bits).

    Examples
    --------
    >>> norm_rows(np.array([[3.0], [4.0], [0.0]])).tolist()
    [5.0]
    """
    s = a[0] * a[0]
    s += a[1] * a[1]
    s += a[2] * a[2]
    return np.sqrt(s, out=s)
