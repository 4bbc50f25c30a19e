"""Compiled kernel (Numba) for :mod:`quadnodes.reference`: closest points on candidate triangles.

The same region test as :func:`quadnodes.reference._triangle_coordinates` (Ericson's, with each
triangle's own dot products computed once), one point at a time: only the branch that applies is
evaluated, nothing is allocated per candidate, and the points are split over threads (``nogil``).
IEEE arithmetic throughout (no ``fastmath``), with the formulas and the order of the candidates of
the NumPy path, so both give the same numbers to the bit.
"""

from __future__ import annotations

import numba as nb
import numpy as np

__all__ = ["closest_on_candidates"]


@nb.njit(cache=True, nogil=True, fastmath=False, boundscheck=False)
def closest_on_candidates(p: np.ndarray, a: np.ndarray, ab: np.ndarray, ac: np.ndarray, gram: np.ndarray,
                          cand: np.ndarray, m: int, out: np.ndarray, lo: int, hi: int) -> None:  # pragma: no cover
    """``out[i]`` = the closest point to ``p[i]`` over the triangles of its candidate quads, ``i`` in ``lo:hi``.

    ``cand[i]`` lists quad ids (-1: none); quad ``f`` is triangles ``f`` and ``f + m``. The
    candidates are visited as the NumPy path orders them (every first triangle, then every
    second one) and the first of equal distances wins, as ``np.argmin`` does.
    """
    nc = cand.shape[1]
    for i in range(lo, hi):
        px, py, pz = p[i, 0], p[i, 1], p[i, 2]
        best = np.inf
        bx, by, bz = np.nan, np.nan, np.nan
        for half in range(2):
            for j in range(nc):
                f = cand[i, j]
                if f < 0:
                    continue
                t = f + half * m
                ax, ay, az = a[t, 0], a[t, 1], a[t, 2]
                e1x, e1y, e1z = ab[t, 0], ab[t, 1], ab[t, 2]
                e2x, e2y, e2z = ac[t, 0], ac[t, 1], ac[t, 2]
                apx, apy, apz = px - ax, py - ay, pz - az
                # sums of three products in np.einsum's order on rows of 3 (first and third, then the
                # second): the NumPy path's numbers to the bit, so a result does not depend on which ran
                d1 = (e1x * apx + e1z * apz) + e1y * apy
                d2 = (e2x * apx + e2z * apz) + e2y * apy
                bb, bc, cc = gram[t, 0], gram[t, 1], gram[t, 2]
                d3, d4 = d1 - bb, d2 - bc
                d5, d6 = d1 - bc, d2 - cc
                va = d3 * d6 - d5 * d4
                vb = d5 * d2 - d1 * d6
                vc = d1 * d4 - d3 * d2
                if d1 <= 0 and d2 <= 0:
                    v, w = 0.0, 0.0
                elif d3 >= 0 and d4 <= d3:
                    v, w = 1.0, 0.0
                elif vc <= 0 and d1 >= 0 and d3 <= 0:
                    v, w = d1 / (d1 - d3), 0.0
                elif d6 >= 0 and d5 <= d6:
                    v, w = 0.0, 1.0
                elif vb <= 0 and d2 >= 0 and d6 <= 0:
                    v, w = 0.0, d2 / (d2 - d6)
                elif va <= 0 and d4 - d3 >= 0 and d5 - d6 >= 0:
                    tb = (d4 - d3) / ((d4 - d3) + (d5 - d6))
                    v, w = 1.0 - tb, tb
                else:
                    denom = va + vb + vc
                    v, w = vb / denom, vc / denom
                if not (np.isfinite(v) and np.isfinite(w)):  # a degenerate triangle: its corner a
                    v, w = 0.0, 0.0
                rx = apx - v * e1x - w * e2x
                ry = apy - v * e1y - w * e2y
                rz = apz - v * e1z - w * e2z
                d = (rx * rx + rz * rz) + ry * ry
                if d < best:
                    best = d
                    bx = ax + v * e1x + w * e2x
                    by = ay + v * e1y + w * e2y
                    bz = az + v * e1z + w * e2z
        out[i, 0], out[i, 1], out[i, 2] = bx, by, bz
