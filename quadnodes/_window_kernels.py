"""Compiled kernels (Numba) for the windows of :mod:`quadnodes.zigzag` and :mod:`quadnodes.fairing`.

:func:`window_geometry` computes what ``zigzag._window_geometry`` computes along the
topology's window walk — each window's deviation (eq. 30), the inverse lengths of its
three edges, and optionally the alternating turning and ``line_spacing="fair"``'s mean
length and energy — reading the window's four vertices once, instead of some twenty
NumPy passes over the whole walk. IEEE arithmetic throughout (no ``fastmath``; NumPy's
division by zero gives ``inf``, not an exception), with NumPy's formulas and order of
operations, so both paths give the same numbers to the bit: detection and fairing do
not depend on whether the kernel was loaded in time. :func:`window_coefficients` writes eq. 32's
coefficients row by row (NumPy writes the columns of a ``(w, 4)`` array with a stride).
"""

from __future__ import annotations

import numba as nb
import numpy as np

__all__ = ["window_geometry", "window_coefficients"]


@nb.njit(cache=True, nogil=True, fastmath=False, boundscheck=False, error_model="numpy")
def window_geometry(V: np.ndarray, ext: np.ndarray, start: np.ndarray, dev: np.ndarray, inverse: np.ndarray,
                    alt: np.ndarray, mean: np.ndarray, energy: np.ndarray, alternation: bool, even: bool,
                    lo: int, hi: int) -> None:  # pragma: no cover - compiled
    """Windows ``lo:hi`` of the walk: ``dev[w]``, ``inverse[:, w]`` ``(3, W)``; with ``alternation``
    ``alt[w]``; with ``even`` ``mean[w, :]`` ``(W, 3)`` and ``energy[w]``.

    Window ``w`` is the walk's vertices ``ext[start[w]:start[w] + 4]`` of ``V`` ``(n, 3)``.
    """
    for w in range(lo, hi):
        s = start[w]
        i0, i1, i2, i3 = ext[s], ext[s + 1], ext[s + 2], ext[s + 3]
        # the three edges, as zigzag._walk_edges: (x² + y²) + z², 1 / sqrt
        ax, ay, az = V[i1, 0] - V[i0, 0], V[i1, 1] - V[i0, 1], V[i1, 2] - V[i0, 2]
        bx, by, bz = V[i2, 0] - V[i1, 0], V[i2, 1] - V[i1, 1], V[i2, 2] - V[i1, 2]
        cx, cy, cz = V[i3, 0] - V[i2, 0], V[i3, 1] - V[i2, 1], V[i3, 2] - V[i2, 2]
        ia = 1.0 / np.sqrt((ax * ax + ay * ay) + az * az)
        ib = 1.0 / np.sqrt((bx * bx + by * by) + bz * bz)
        ic = 1.0 / np.sqrt((cx * cx + cy * cy) + cz * cz)
        inverse[0, w], inverse[1, w], inverse[2, w] = ia, ib, ic
        if even:
            m = 3.0 / ((1.0 / ia + 1.0 / ib) + 1.0 / ic)
            h = 0.5 * m
            fx = (ax * h + cx * h) - bx * m
            fy = (ay * h + cy * h) - by * m
            fz = (az * h + cz * h) - bz * m
            energy[w] = (fx * fx + fy * fy) + fz * fz
            mean[w, 0], mean[w, 1], mean[w, 2] = m, m, m
        # unit directions, then the deviation ((u0 + u2) / 2 - u1)²
        ax, ay, az = ax * ia, ay * ia, az * ia
        bx, by, bz = bx * ib, by * ib, bz * ib
        cx, cy, cz = cx * ic, cy * ic, cz * ic
        rx = (ax + cx) * 0.5 - bx
        ry = (ay + cy) * 0.5 - by
        rz = (az + cz) * 0.5 - bz
        dev[w] = (rx * rx + ry * ry) + rz * rz
        if alternation:
            # -(u1 - u0)·(u2 - u1), clipped at 0 as np.maximum(0, ·) (NaN stays NaN)
            px = (bx - ax) * (cx - bx)
            py = (by - ay) * (cy - by)
            pz = (bz - az) * (cz - bz)
            a = -((px + py) + pz)
            alt[w] = a if (a > 0.0 or a != a) else 0.0


@nb.njit(cache=True, nogil=True, fastmath=False, boundscheck=False)
def window_coefficients(i0: np.ndarray, i1: np.ndarray, i2: np.ndarray, out: np.ndarray, lo: int,
                        hi: int) -> None:  # pragma: no cover - compiled
    """Rows ``lo:hi`` of ``out`` ``(w, 4)``: eq. 32's coefficients from the inverse lengths of the three edges
    (``quadnodes.fairing._coefficients``'s formulas)."""
    for w in range(lo, hi):
        a, b, c = i0[w], i1[w], i2[w]
        out[w, 0] = -0.5 * a
        out[w, 1] = 0.5 * a + b
        out[w, 2] = -b - 0.5 * c
        out[w, 3] = 0.5 * c
