"""Compiled kernels (Numba) for the solver: a symmetric diagonal-storage product, banded solves
along grid lines, and symmetric Gauss–Seidel sweeps (a grid's diagonal storage and compressed rows).

Every kernel works on a range of rows (or lines) so that the solver's own thread pool
can run ranges side by side (``nogil``); inner loops run over contiguous memory so
that they vectorize. Compiled on first use and cached on disk.
"""

from __future__ import annotations

import numba as nb
import numpy as np

__all__ = ["LANES", "symmetric_diagonal_product", "entries_product", "strided_line_solve", "row_line_solve",
           "blocked_lines", "cg_update", "cg_direction", "row_dots", "strided_band_cholesky", "grid_family",
           "unit_backward_sweep", "unit_forward_sweep", "unit_cg_update", "unit_scaled", "csr_backward_sweep",
           "csr_forward_sweep", "rows_cg_update", "csr_separators", "csr_split_counts", "csr_split_fill"]

#: Rows of the product computed per chunk (the chunk's slices of every diagonal stay in cache).
_CHUNK = 1024


# The loops below index 1-D slices from 0: Numba then knows no index is negative and
# LLVM vectorizes them (with ``range(a, b)`` on the whole array it does not).


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def _axpy_into(y: np.ndarray, u: np.ndarray, x: np.ndarray) -> None:  # pragma: no cover - compiled
    """``y += u · x`` elementwise (equal lengths)."""
    for i in range(y.size):
        y[i] += u[i] * x[i]


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def _axmy_into(y: np.ndarray, u: np.ndarray, x: np.ndarray) -> None:  # pragma: no cover - compiled
    """``y -= u · x`` elementwise (equal lengths)."""
    for i in range(y.size):
        y[i] -= u[i] * x[i]


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def _seven_diagonal_rows(y: np.ndarray, u0: np.ndarray, u1: np.ndarray, u2: np.ndarray, u3: np.ndarray,
                         u4: np.ndarray, u5: np.ndarray, u6: np.ndarray, v1: np.ndarray, v2: np.ndarray,
                         v3: np.ndarray, v4: np.ndarray, v5: np.ndarray, v6: np.ndarray, x: np.ndarray,
                         p1: np.ndarray, p2: np.ndarray, p3: np.ndarray, p4: np.ndarray, p5: np.ndarray,
                         p6: np.ndarray, m1: np.ndarray, m2: np.ndarray, m3: np.ndarray, m4: np.ndarray,
                         m5: np.ndarray, m6: np.ndarray) -> None:  # pragma: no cover - compiled
    """``y = u0 x + Σ_d (u_d p_d + v_d m_d)`` elementwise: the 13 terms of a row of a symmetric
    matrix with 7 upper diagonals, every operand a slice aligned with ``y``. Four partial sums
    (no chain of 13 dependent multiply-adds: the loop is latency-bound otherwise)."""
    for j in range(y.size):
        s0 = u0[j] * x[j] + u1[j] * p1[j] + v1[j] * m1[j]
        s1 = u2[j] * p2[j] + v2[j] * m2[j] + u3[j] * p3[j]
        s2 = v3[j] * m3[j] + u4[j] * p4[j] + v4[j] * m4[j]
        s3 = u5[j] * p5[j] + v5[j] * m5[j] + u6[j] * p6[j] + v6[j] * m6[j]
        y[j] = (s0 + s1) + (s2 + s3)


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def _seven_diagonal_product(U: np.ndarray, offsets: np.ndarray, X: np.ndarray, Y: np.ndarray,
                            lo: int, hi: int) -> None:  # pragma: no cover - compiled
    """:func:`symmetric_diagonal_product` with exactly 7 upper diagonals on rows ``lo:hi`` where every
    offset stays inside the matrix (``offsets[6] ≤ lo``, ``hi + offsets[6] ≤ n``): one pass per row
    chunk and column, each row's 13 terms summed in registers (a grid's fairing matrix)."""
    o1, o2, o3, o4, o5, o6 = offsets[1], offsets[2], offsets[3], offsets[4], offsets[5], offsets[6]
    for a in range(lo, hi, _CHUNK):
        b = min(a + _CHUNK, hi)
        u0, u1, u2, u3, u4, u5, u6 = U[0, a:b], U[1, a:b], U[2, a:b], U[3, a:b], U[4, a:b], U[5, a:b], U[6, a:b]
        v1, v2, v3 = U[1, a - o1 : b - o1], U[2, a - o2 : b - o2], U[3, a - o3 : b - o3]
        v4, v5, v6 = U[4, a - o4 : b - o4], U[5, a - o5 : b - o5], U[6, a - o6 : b - o6]
        for q in range(X.shape[0]):
            x = X[q]
            _seven_diagonal_rows(Y[q, a:b], u0, u1, u2, u3, u4, u5, u6, v1, v2, v3, v4, v5, v6, x[a:b],
                                 x[a + o1 : b + o1], x[a + o2 : b + o2], x[a + o3 : b + o3], x[a + o4 : b + o4],
                                 x[a + o5 : b + o5], x[a + o6 : b + o6], x[a - o1 : b - o1], x[a - o2 : b - o2],
                                 x[a - o3 : b - o3], x[a - o4 : b - o4], x[a - o5 : b - o5], x[a - o6 : b - o6])


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def symmetric_diagonal_product(U: np.ndarray, offsets: np.ndarray, X: np.ndarray, Y: np.ndarray,
                               lo: int, hi: int) -> None:  # pragma: no cover - compiled
    """``Y[:, lo:hi] = (M X)[:, lo:hi]`` for a symmetric ``M`` stored by its upper diagonals.

    ``U[d, i] = M[i, i + offsets[d]]`` (``(d, n)``, entries past the end zero) with
    ``offsets[0] = 0`` and positive offsets after it, in any order (a closed grid's periodic pairs follow
    its first 13); ``X``, ``Y`` are C-contiguous ``(c, m)`` with ``m ≥ n`` (columns past ``n`` are neither read nor written). With 7
    upper diagonals (an open grid's fairing matrix) the rows away from both ends take
    :func:`_seven_diagonal_product`.
    """
    n = U.shape[1]
    if offsets.size == 7:
        top = offsets.max()
        a = max(lo, top)
        b = min(hi, n - top)
        if b > a:
            _diagonal_product_rows(U, offsets, X, Y, lo, a)
            _seven_diagonal_product(U, offsets, X, Y, a, b)
            _diagonal_product_rows(U, offsets, X, Y, b, hi)
            return
    _diagonal_product_rows(U, offsets, X, Y, lo, hi)


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def entries_product(rows: np.ndarray, cols: np.ndarray, vals: np.ndarray, X: np.ndarray, Y: np.ndarray, a: int,
                    b: int) -> None:  # pragma: no cover - compiled
    """``Y[:, rows[e]] += vals[e] X[:, cols[e]]`` for the entries ``a:b`` (a list of matrix entries by row) on
    ``(c, m)`` vectors: the few entries of :class:`~quadnodes.linalg.cg.SymmetricDiagonalBlocks`' sparse diagonals."""
    for q in range(X.shape[0]):
        x = X[q]
        y = Y[q]
        for e in range(a, b):
            y[rows[e]] += vals[e] * x[cols[e]]


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def _diagonal_product_rows(U: np.ndarray, offsets: np.ndarray, X: np.ndarray, Y: np.ndarray,
                           lo: int, hi: int) -> None:  # pragma: no cover - compiled
    """:func:`symmetric_diagonal_product` on rows ``lo:hi`` (any number of diagonals): per row chunk,
    one pass over the chunk for each diagonal and side."""
    n = U.shape[1]
    c = X.shape[0]
    nd = offsets.size
    for a in range(lo, hi, _CHUNK):
        b = min(a + _CHUNK, hi)
        for q in range(c):
            x = X[q]
            y = Y[q]
            ys = y[a:b]
            u0 = U[0, a:b]
            xs = x[a:b]
            for i in range(b - a):
                ys[i] = u0[i] * xs[i]
            for d in range(1, nd):
                o = offsets[d]
                s = min(b, n - o)  # above the diagonal: i + o < n
                if s > a:
                    _axpy_into(y[a:s], U[d, a:s], x[a + o : s + o])
                t = max(a, o)  # below: i - o ≥ 0
                if b > t:
                    _axpy_into(y[t:b], U[d, t - o : b - o], x[t - o : b - o])


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def strided_line_solve(F: np.ndarray, dinv: np.ndarray, stride: int, R: np.ndarray, Y: np.ndarray,
                       Z: np.ndarray, first: int, last: int, add: bool) -> None:  # pragma: no cover - compiled
    """Banded solves along the strided lines ``first:last`` of a grid: ``Z (+)= B⁻¹ R``.

    The nodes are ``n = rows · stride`` in row-major order; line ``s`` is the column
    ``s, s + stride, s + 2·stride, …``. ``F[kd - k, i] = U[i - k·stride, i]`` is the
    upper Cholesky factor of the lines' band ``B = UᵀU`` in the nodes' own order,
    ``dinv`` the reciprocals of its diagonal. ``R``, ``Z`` and the scratch space
    ``Y`` are C-contiguous ``(c, m)``, ``m ≥ n``; ``add`` adds the solution to ``Z``
    instead of writing it (without ``add``, ``Y`` may be ``Z`` itself). The inner loops run across lines (contiguous nodes,
    independent of one another).
    """
    kd = F.shape[0] - 1
    c = R.shape[0]
    rows = F.shape[1] // stride
    w = last - first
    for j in range(rows):  # Uᵀ y = r, one grid row of all lines at a time (F's slices stay in cache)
        a = j * stride + first
        b = a + w
        ds = dinv[a:b]
        for q in range(c):
            ys = Y[q, a:b]
            rs = R[q, a:b]
            for i in range(w):
                ys[i] = rs[i]
            for k in range(1, min(kd, j) + 1):
                o = k * stride
                _axmy_into(ys, F[kd - k, a:b], Y[q, a - o : b - o])
            for i in range(w):
                ys[i] *= ds[i]
    for j in range(rows - 1, -1, -1):  # U z = y
        a = j * stride + first
        b = a + w
        ds = dinv[a:b]
        for q in range(c):
            ys = Y[q, a:b]
            for k in range(1, min(kd, rows - 1 - j) + 1):
                o = k * stride
                _axmy_into(ys, F[kd - k, a + o : b + o], Y[q, a + o : b + o])
            zs = Z[q, a:b]
            if add:
                for i in range(w):
                    ys[i] *= ds[i]
                    zs[i] += ys[i]
            else:
                for i in range(w):
                    ys[i] *= ds[i]
                    zs[i] = ys[i]


#: Lines solved side by side by :func:`row_line_solve` (two AVX2 vectors of float64).
LANES = 8


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def row_line_solve(F: np.ndarray, dinv: np.ndarray, length: int, nlines: int, R: np.ndarray, B: np.ndarray,
                   Z: np.ndarray, first: int, last: int, add: bool) -> None:  # pragma: no cover - compiled
    """Banded solves along the contiguous lines (grid rows) ``first:last``: ``Z (+)= B⁻¹ R``.

    Line ``s`` holds the nodes ``s·length … (s + 1)·length − 1``. The lines are taken
    :data:`LANES` at a time (``first`` a multiple of it): their ``R`` goes into the
    scratch block ``B`` (``(c, length, LANES)``, transposed, so the recurrence runs
    along ``length`` with the lanes as a vector), is solved there and written back.
    ``F`` and ``dinv`` are the factor and reciprocal diagonal in that blocked layout
    (:func:`blocked_lines`): entry ``(s − s % LANES)·length + j·LANES + s % LANES`` belongs to
    node ``j`` of line ``s``, for ``nlines`` lines padded to a multiple of :data:`LANES`.
    """
    kd = F.shape[0] - 1
    c = R.shape[0]
    L = LANES
    for s0 in range(first, last, L):
        t = min(L, nlines - s0)
        base = s0 * length
        for q in range(c):
            r = R[q]
            bq = B[q]
            if t < L:
                bq[:, t:] = 0.0
            for u in range(t):  # gather: node j of line s0 + u -> bq[j, u]
                src = r[base + u * length : base + (u + 1) * length]
                for j in range(length):
                    bq[j, u] = src[j]
            for j in range(length):  # Uᵀ y = r
                bj = bq[j]
                for k in range(1, min(kd, j) + 1):
                    fk = F[kd - k, base + j * L : base + j * L + L]
                    bk = bq[j - k]
                    for u in range(L):
                        bj[u] -= fk[u] * bk[u]
                dj = dinv[base + j * L : base + j * L + L]
                for u in range(L):
                    bj[u] *= dj[u]
            for j in range(length - 1, -1, -1):  # U z = y
                bj = bq[j]
                for k in range(1, min(kd, length - 1 - j) + 1):
                    fk = F[kd - k, base + (j + k) * L : base + (j + k) * L + L]
                    bk = bq[j + k]
                    for u in range(L):
                        bj[u] -= fk[u] * bk[u]
                dj = dinv[base + j * L : base + j * L + L]
                for u in range(L):
                    bj[u] *= dj[u]
            z = Z[q]
            for u in range(t):  # scatter back
                dst = z[base + u * length : base + (u + 1) * length]
                if add:
                    for j in range(length):
                        dst[j] += bq[j, u]
                else:
                    for j in range(length):
                        dst[j] = bq[j, u]


def blocked_lines(F: np.ndarray, length: int, pad: float) -> np.ndarray:
    """``F`` (``(k, n)``, rows of the lines ``s·length …`` one after another) in the blocked
    layout of :func:`row_line_solve`, the lines padded to a multiple of :data:`LANES` with ``pad``.

    Examples
    --------
    >>> blocked_lines(np.arange(6.0)[None], 3, -1.0)[0, :8].tolist()  # two lines of 3
    [0.0, 3.0, -1.0, -1.0, -1.0, -1.0, -1.0, -1.0]
    """
    k, n = F.shape
    lines = n // length
    padded = -(-lines // LANES) * LANES
    out = np.full((k, padded, length), pad)
    out[:, :lines] = F.reshape(k, lines, length)
    return np.ascontiguousarray(out.reshape(k, padded // LANES, LANES, length).transpose(0, 1, 3, 2)).reshape(k, -1)


@nb.njit(cache=True, nogil=True, fastmath=False, boundscheck=False)
def path_band_solve(F: np.ndarray, dinv: np.ndarray, path: np.ndarray, R: np.ndarray, Z: np.ndarray,
                    work: np.ndarray, a: int, b: int) -> None:  # pragma: no cover - compiled
    """``Z[path] += B⁻¹ R[path]`` for a band ``B = Uᵀ U`` laid out along ``path`` (repeats allowed).

    ``F`` is ``U`` in LAPACK's upper band layout (``F[kd - t, j] = U[j - t, j]``, as
    :func:`scipy.linalg.cholesky_banded` returns it), ``dinv`` ``1 / F[kd]``; ``R``, ``Z`` are ``(m, c)`` row-major
    (all columns of an unknown in one cache line: a path jumps through memory) with ``m``
    above every index of ``path``; ``work`` is ``(len(path), c)`` scratch. A zero band
    entry between two stretches of the path decouples them, so many lines laid end to
    end are solved in one sweep each way. Only positions ``a:b`` are solved (a stretch that
    starts and ends with whole paths: another thread may solve the rest, into another ``Z``).
    """
    kd = F.shape[0] - 1
    c = R.shape[1]
    y = work
    for j in range(a, b):  # Uᵀ y = r along the path
        r = R[path[j]]
        yj = y[j]
        for q in range(c):
            yj[q] = r[q]
        for t in range(1, min(kd, j - a) + 1):
            f = F[kd - t, j]
            yt = y[j - t]
            for q in range(c):
                yj[q] -= f * yt[q]
        d = dinv[j]
        for q in range(c):
            yj[q] *= d
    for i in range(b - 1, a - 1, -1):  # U x = y, scattered back
        yi = y[i]
        for t in range(1, min(kd, b - 1 - i) + 1):
            f = F[kd - t, i + t]
            yt = y[i + t]
            for q in range(c):
                yi[q] -= f * yt[q]
        d = dinv[i]
        z = Z[path[i]]
        for q in range(c):
            yi[q] *= d
            z[q] += yi[q]


@nb.njit(cache=True, nogil=True, fastmath=False, boundscheck=False)
def path_band_solve_xyz(F: np.ndarray, dinv: np.ndarray, path: np.ndarray, R: np.ndarray, Z: np.ndarray,
                        work: np.ndarray, a: int, b: int) -> None:  # pragma: no cover - compiled
    """:func:`path_band_solve` for half-bandwidth 3 and three columns (x, y, z: the fairing's lines), unrolled.

    The last three solutions ride in registers, so each step waits on one multiply-add chain instead of
    reloading them: 2–4× faster than the general loop on 111,000 unknowns, as the path's jumps through memory
    allow. The same arithmetic in the same order (no fused multiply-adds: ``fastmath`` off), so the same results
    to the last bit — given that ``F``'s entries that would reach before ``a`` (``F[3 - t, a + s]``, ``s < t``) are
    zero, as :func:`scipy.linalg.cholesky_banded` leaves them for a band with no coupling across stretches: the
    general loop skips them, this one multiplies them by zero.
    """
    y = work
    y1x = y1y = y1z = y2x = y2y = y2z = y3x = y3y = y3z = 0.0
    for j in range(a, b):  # Uᵀ y = r along the path (at a, no earlier entries: the zeros above)
        p = path[j]
        f1 = F[2, j]
        f2 = F[1, j]
        f3 = F[0, j]
        d = dinv[j]
        yx = (R[p, 0] - f1 * y1x - f2 * y2x - f3 * y3x) * d
        yy = (R[p, 1] - f1 * y1y - f2 * y2y - f3 * y3y) * d
        yz = (R[p, 2] - f1 * y1z - f2 * y2z - f3 * y3z) * d
        y[j, 0] = yx
        y[j, 1] = yy
        y[j, 2] = yz
        y3x, y3y, y3z = y2x, y2y, y2z
        y2x, y2y, y2z = y1x, y1y, y1z
        y1x, y1y, y1z = yx, yy, yz
    y1x = y1y = y1z = y2x = y2y = y2z = y3x = y3y = y3z = 0.0
    for i in range(b - 1, a - 1, -1):  # U x = y, scattered back
        p = path[i]
        g1 = F[2, i + 1] if i + 1 < b else 0.0
        g2 = F[1, i + 2] if i + 2 < b else 0.0
        g3 = F[0, i + 3] if i + 3 < b else 0.0
        d = dinv[i]
        yx = (y[i, 0] - g1 * y1x - g2 * y2x - g3 * y3x) * d
        yy = (y[i, 1] - g1 * y1y - g2 * y2y - g3 * y3y) * d
        yz = (y[i, 2] - g1 * y1z - g2 * y2z - g3 * y3z) * d
        Z[p, 0] += yx
        Z[p, 1] += yy
        Z[p, 2] += yz
        y3x, y3y, y3z = y2x, y2y, y2z
        y2x, y2y, y2z = y1x, y1y, y1z
        y1x, y1y, y1z = yx, yy, yz


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def cg_update(X: np.ndarray, R: np.ndarray, P: np.ndarray, Q: np.ndarray, alpha: np.ndarray, lo: int,
              hi: int, rr: np.ndarray) -> None:  # pragma: no cover - compiled
    """One pass of a CG step on columns ``lo:hi`` of ``(c, m)`` arrays: ``x += α p``, ``r −= α q``,
    and ``rr[q] = r·r`` over the range."""
    for q in range(X.shape[0]):
        a = alpha[q]
        x = X[q, lo:hi]
        r = R[q, lo:hi]
        p = P[q, lo:hi]
        v = Q[q, lo:hi]
        acc = 0.0
        for i in range(hi - lo):
            x[i] += a * p[i]
            t = r[i] - a * v[i]
            r[i] = t
            acc += t * t
        rr[q] = acc


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def cg_direction(P: np.ndarray, Z: np.ndarray, beta: np.ndarray, lo: int, hi: int) -> None:  # pragma: no cover - compiled
    """``p = z + β p`` on columns ``lo:hi`` of ``(c, m)`` arrays."""
    for q in range(P.shape[0]):
        b = beta[q]
        p = P[q, lo:hi]
        z = Z[q, lo:hi]
        for i in range(hi - lo):
            p[i] = z[i] + b * p[i]


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def row_dots(U: np.ndarray, V: np.ndarray, lo: int, hi: int, out: np.ndarray) -> None:  # pragma: no cover - compiled
    """``out[q] = U[q, lo:hi] · V[q, lo:hi]``."""
    for q in range(U.shape[0]):
        u = U[q, lo:hi]
        v = V[q, lo:hi]
        acc = 0.0
        for i in range(hi - lo):
            acc += u[i] * v[i]
        out[q] = acc


@nb.njit(cache=True, nogil=True, fastmath=False, boundscheck=False)
def strided_band_cholesky(A: np.ndarray, F: np.ndarray, stride: int, length: int, base: int, first: int,
                          last: int) -> int:  # pragma: no cover - compiled
    """Upper banded Cholesky factors (LAPACK ``pbtrf`` 'U' layout) of strided lines, side by side.

    Line ``s`` (``first ≤ s < last``) holds the nodes ``base + s + j·stride``, ``j < length``;
    ``A[kd - k, i]`` is the band entry coupling node ``i`` with ``i − k·stride`` (zero
    across line starts is implied: entries before a line's start are never read).
    Writes ``F`` (same layout, ``F[kd - k, i] = U[i − k·stride, i]``) for those nodes.
    Returns −1, or the first node whose pivot is not positive (the block is not
    positive definite).
    """
    kd = A.shape[0] - 1
    w = last - first
    for j in range(length):
        a = base + j * stride + first
        b = a + w
        top = min(kd, j)
        for m in range(top, 0, -1):  # U[j - m, j], nearest row last
            f = F[kd - m, a:b]
            src = A[kd - m, a:b]
            for i in range(w):
                f[i] = src[i]
            o = m * stride
            for p in range(m + 1, top + 1):
                g1 = F[kd - p, a:b]
                g2 = F[kd - p + m, a - o : b - o]
                for i in range(w):
                    f[i] -= g1[i] * g2[i]
            d = F[kd, a - o : b - o]
            for i in range(w):
                f[i] /= d[i]
        for m in range(top + 1, kd + 1):
            f = F[kd - m, a:b]
            for i in range(w):
                f[i] = 0.0
        f = F[kd, a:b]
        src = A[kd, a:b]
        for i in range(w):
            f[i] = src[i]
        for p in range(1, top + 1):
            g = F[kd - p, a:b]
            for i in range(w):
                f[i] -= g[i] * g[i]
        for i in range(w):
            if not f[i] > 0.0:
                return a + i
            f[i] = np.sqrt(f[i])
    return -1


@nb.njit(cache=True, nogil=True, fastmath=False, boundscheck=False)
def grid_family(coef: np.ndarray, first: np.ndarray, F: np.ndarray, rows: int, cols: int, family: int,
                closed: bool, seam: int, weight: float, data: np.ndarray, lo: int,
                hi: int) -> None:  # pragma: no cover - compiled
    """One family's share of a grid's ``AᵀA + ωI`` in diagonal storage, its lines ``lo:hi``.

    ``coef`` ``(w, 4)``: the rows of ``A``; the windows of line ``l`` of ``family`` (0: grid rows,
    1: grid columns) are ``coef[first[l] : first[l] + k]`` in order along it (``k = L − 3``, or ``L`` on a
    ``closed`` line, window ``j`` holding its nodes ``j … j + 3`` mod ``L``). ``F`` ``(n,)``:
    1.0 on the unknowns, 0.0 elsewhere (a fixed node drops out of every window). ``data`` ``(13 + …, n)``
    as ``GridPattern.normal_matrix``: family 0 writes its diagonals and sets the main diagonal,
    family 1 (after it) writes its own, adds to the main diagonal and then ``ω`` (1 off the
    unknowns); a closed family's pairs across the seam go to its periodic slots ``seam + 2(d − 1)`` (``M[a, b]``
    at column ``b``) and the next (``M[b, a]`` at column ``a``). Sums in ``GridPattern._laid_out_normal_matrix``'s
    order, so the numbers are its to the bit. Columns are taken 16 side by side, row by row, so that reads and
    writes stay near each other.
    """
    length = cols if family == 0 else rows
    k = length if closed else length - 3
    step = 1 if family == 0 else cols
    tile = 1 if family == 0 else 16
    for t0 in range(lo, hi, tile):
        t1 = min(t0 + tile, hi)
        for x in range(length):
            for line in range(t0, t1):
                node = line * cols + x if family == 0 else x * cols + line
                p = first[line]
                for d in range(4):
                    partner = node + d * step if x + d < length else node + (d - length) * step
                    s = 0.0
                    for i in range(4 - d):
                        j = x - i  # the window whose slot i is this node (slot i + d is d steps on)
                        if closed and j < 0:
                            j += length
                        if 0 <= j and j < k:
                            s += (coef[p + j, i] * F[node]) * (coef[p + j, i + d] * F[partner])
                    if d == 0:
                        if family == 0:
                            data[6, node] = s
                        else:
                            s = data[6, node] + s
                            data[6, node] = s + (weight if F[node] != 0.0 else 1.0)
                    elif x + d < length:
                        if family == 0:
                            data[6 + d, node + d] = s  # M[a, a + d] at column a + d
                            data[6 - d, node] = s  # M[a + d, a] at column a
                        else:
                            data[9 + d, node + d * cols] = s
                            data[3 - d, node] = s
                    elif closed:  # across the seam: the partner is d − L steps on
                        data[seam + 2 * (d - 1), partner] = s
                        data[seam + 2 * (d - 1) + 1, node] = s


# Symmetric Gauss–Seidel sweeps (quadnodes.linalg.gauss_seidel). Each row depends on the rows
# before it (forward) or after it (backward), so a sweep is a recurrence: per grid row, the
# couplings to the three grid rows before (or after) it are summed first in a loop that
# vectorizes, and only the couplings along the row (offsets 1, 2, 3) run as the recurrence,
# three columns side by side, the last three values kept in registers. The recurrence
# contracts multiply-adds but keeps its order (``fastmath={"contract"}``): with reassociation
# LLVM put the newest value first, and the chain of dependent operations grew from one
# multiply-add per row to three (0.44 against 0.19 ms per 90,000 rows).


@nb.njit(cache=True, nogil=True, fastmath={"contract"}, boundscheck=False)
def _chain3(t0: np.ndarray, t1: np.ndarray, t2: np.ndarray, l1: np.ndarray, l2: np.ndarray, l3: np.ndarray,
            z0: np.ndarray, z1: np.ndarray, z2: np.ndarray, h0: np.ndarray, h1: np.ndarray, h2: np.ndarray,
            down: bool) -> None:  # pragma: no cover - compiled
    """``z[k] = t[k] − l1[k] z[k∓1] − l2[k] z[k∓2] − l3[k] z[k∓3]`` along equal-length slices, from the first
    entry up (or with ``down`` from the last down), three columns side by side; ``h`` holds each column's
    three values before the first one computed (``z[−1], z[−2], z[−3]``, or ``z[w], z[w+1], z[w+2]``).
    (Reversed views instead of ``down`` were about 1.5× slower.)"""
    a0, b0, c0 = h0[0], h0[1], h0[2]
    a1, b1, c1 = h1[0], h1[1], h1[2]
    a2, b2, c2 = h2[0], h2[1], h2[2]
    w = z0.size
    for j in range(w):
        k = w - 1 - j if down else j
        f1, f2, f3 = l1[k], l2[k], l3[k]
        s0 = t0[k] - f3 * c0 - f2 * b0 - f1 * a0
        s1 = t1[k] - f3 * c1 - f2 * b1 - f1 * a1
        s2 = t2[k] - f3 * c2 - f2 * b2 - f1 * a2
        z0[k] = s0
        z1[k] = s1
        z2[k] = s2
        c0, c1, c2 = b0, b1, b2
        b0, b1, b2 = a0, a1, a2
        a0, a1, a2 = s0, s1, s2


@nb.njit(cache=True, nogil=True, fastmath={"contract"}, boundscheck=False)
def _chain1(t: np.ndarray, l1: np.ndarray, l2: np.ndarray, l3: np.ndarray, z: np.ndarray,
            h: np.ndarray, down: bool) -> None:  # pragma: no cover - compiled
    """:func:`_chain3` for one column."""
    a, b, c = h[0], h[1], h[2]
    w = z.size
    for j in range(w):
        k = w - 1 - j if down else j
        v = t[k] - l3[k] * c - l2[k] * b - l1[k] * a
        z[k] = v
        c, b, a = b, a, v


@nb.njit(cache=True, nogil=True, boundscheck=False)
def _recurrence(T: np.ndarray, L1: np.ndarray, L2: np.ndarray, L3: np.ndarray, Z: np.ndarray, a: int, b: int,
                forward: bool, H: np.ndarray) -> None:  # pragma: no cover - compiled
    """The recurrence of a sweep on the rows ``a:b`` (from ``a`` up, or from ``b − 1`` down):
    ``z_i = T[q, i − a] − l1_i z_{i∓1} − l2_i z_{i∓2} − l3_i z_{i∓3}``, the earlier values read from
    ``Z`` (rows ``a−3:a`` or ``b:b+3``); ``H`` is ``(c, 3)`` scratch."""
    c = Z.shape[0]
    w = b - a
    for q in range(c):
        for j in range(3):
            H[q, j] = Z[q, a - 1 - j] if forward else Z[q, b + j]
    if c == 3:
        _chain3(T[0, :w], T[1, :w], T[2, :w], L1[a:b], L2[a:b], L3[a:b], Z[0, a:b], Z[1, a:b], Z[2, a:b],
                H[0], H[1], H[2], not forward)
    else:
        for q in range(c):
            _chain1(T[q, :w], L1[a:b], L2[a:b], L3[a:b], Z[q, a:b], H[q], not forward)


# Conjugate gradients on the symmetrically Gauss–Seidel-preconditioned system in Eisenstat's form
# (quadnodes.linalg.gauss_seidel.gauss_seidel_cg): with M scaled to a unit diagonal, M = (I + L) +
# (I + U) − I in the sweeps' order of the rows (every thread's interior rows first, the separator rows
# between the threads' ranges last), the preconditioned operator (I + L)⁻¹ M (I + U)⁻¹ applied to p is
# t + (I + L)⁻¹ (p − t) with t = (I + U)⁻¹ p: one backward and one forward sweep, no product. A block's
# sweep reads the rows beside it that come later (backward) or earlier (forward) in that order as fixed
# values: the rows ``below:lo`` and ``hi:above``.


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def _beyond(U: np.ndarray, offsets: np.ndarray, V: np.ndarray, q: int, i: int, lo: int, hi: int, below: int,
            above: int) -> float:  # pragma: no cover - compiled
    """``Σ_j M_ij V[q, j]`` over the fixed rows ``j`` beside the block ``lo:hi`` (``below:lo`` and ``hi:above``)."""
    s = 0.0
    for d in range(1, offsets.size):
        o = offsets[d]
        j = i - o
        if below <= j < lo:
            s += U[d, j] * V[q, j]
        j = i + o
        if hi <= j < above:
            s += U[d, i] * V[q, j]
    return s


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def _unit_rows(U: np.ndarray, offsets: np.ndarray, V: np.ndarray, Z: np.ndarray, lo: int, hi: int, a: int, b: int,
               forward: bool, below: int, above: int) -> None:  # pragma: no cover - compiled
    """Rows ``a:b`` of a unit triangular solve on the block ``lo:hi``, row by row (any offsets):
    forward ``z_i = v_i − Σ_{j<i} M_ij z_j``, backward ``z_i = v_i − Σ_{j>i} M_ij z_j`` (``j`` in the
    block), each less its couplings to the fixed rows ``below:lo`` and ``hi:above`` of ``Z``; ``V``
    already holds the right-hand side's rows (may be ``Z``)."""
    nd = offsets.size
    for k in range(b - a):
        i = a + k if forward else b - 1 - k
        for q in range(Z.shape[0]):
            s = V[q, i] - _beyond(U, offsets, Z, q, i, lo, hi, below, above)
            for d in range(1, nd):
                o = offsets[d]
                if forward:
                    j = i - o
                    if j >= lo:
                        s -= U[d, j] * Z[q, j]
                else:
                    j = i + o
                    if j < hi:
                        s -= U[d, i] * Z[q, j]
            Z[q, i] = s


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def _difference_into(v: np.ndarray, p: np.ndarray, t: np.ndarray) -> None:  # pragma: no cover - compiled
    """``v = p − t`` elementwise."""
    for k in range(v.size):
        v[k] = p[k] - t[k]


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def _backward_terms(R: np.ndarray, P: np.ndarray, T: np.ndarray, U: np.ndarray, beta: np.ndarray, S: np.ndarray,
                    a: int, b: int, g: int) -> None:  # pragma: no cover - compiled
    """Rows ``a:b`` of the backward sweep before its recurrence: ``P = R + β P``, then
    ``S[q, k] = P[q, i] − Σ_j U[3 + j, i] T[q, i + j·g]`` (``i = a + k``, ``j = 1, 2, 3``)."""
    w = b - a
    m1, m2, m3 = U[4, a:b], U[5, a:b], U[6, a:b]
    cg_direction(P, R, beta, a, b)  # (its own pass: with P written beside S, LLVM did not vectorize)
    if P.shape[0] == 3:  # the three coordinates in one pass: each coefficient read once
        p0, p1, p2 = P[0, a:b], P[1, a:b], P[2, a:b]
        s0, s1, s2 = S[0, :w], S[1, :w], S[2, :w]
        x10, x11, x12 = T[0, a + g : b + g], T[1, a + g : b + g], T[2, a + g : b + g]
        x20, x21, x22 = T[0, a + 2 * g : b + 2 * g], T[1, a + 2 * g : b + 2 * g], T[2, a + 2 * g : b + 2 * g]
        x30, x31, x32 = T[0, a + 3 * g : b + 3 * g], T[1, a + 3 * g : b + 3 * g], T[2, a + 3 * g : b + 3 * g]
        for k in range(w):
            f1, f2, f3 = m1[k], m2[k], m3[k]
            s0[k] = p0[k] - f1 * x10[k] - f2 * x20[k] - f3 * x30[k]
            s1[k] = p1[k] - f1 * x11[k] - f2 * x21[k] - f3 * x31[k]
            s2[k] = p2[k] - f1 * x12[k] - f2 * x22[k] - f3 * x32[k]
        return
    for q in range(P.shape[0]):
        p, sq = P[q, a:b], S[q, :w]
        x1, x2, x3 = T[q, a + g : b + g], T[q, a + 2 * g : b + 2 * g], T[q, a + 3 * g : b + 3 * g]
        for k in range(w):
            sq[k] = p[k] - m1[k] * x1[k] - m2[k] * x2[k] - m3[k] * x3[k]


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def _forward_terms(P: np.ndarray, T: np.ndarray, W: np.ndarray, U: np.ndarray, S: np.ndarray, a: int, b: int,
                   g: int) -> None:  # pragma: no cover - compiled
    """Rows ``a:b`` (``a ≥ 3g``) of the forward sweep before its recurrence:
    ``S[q, k] = P[q, i] − T[q, i] − Σ_j U[3 + j, i − j·g] W[q, i − j·g]`` (``i = a + k``)."""
    w = b - a
    m1, m2, m3 = U[4, a - g : b - g], U[5, a - 2 * g : b - 2 * g], U[6, a - 3 * g : b - 3 * g]
    if P.shape[0] == 3:
        p0, p1, p2 = P[0, a:b], P[1, a:b], P[2, a:b]
        t0, t1, t2 = T[0, a:b], T[1, a:b], T[2, a:b]
        s0, s1, s2 = S[0, :w], S[1, :w], S[2, :w]
        x10, x11, x12 = W[0, a - g : b - g], W[1, a - g : b - g], W[2, a - g : b - g]
        x20, x21, x22 = W[0, a - 2 * g : b - 2 * g], W[1, a - 2 * g : b - 2 * g], W[2, a - 2 * g : b - 2 * g]
        x30, x31, x32 = W[0, a - 3 * g : b - 3 * g], W[1, a - 3 * g : b - 3 * g], W[2, a - 3 * g : b - 3 * g]
        for k in range(w):
            f1, f2, f3 = m1[k], m2[k], m3[k]
            s0[k] = p0[k] - t0[k] - f1 * x10[k] - f2 * x20[k] - f3 * x30[k]
            s1[k] = p1[k] - t1[k] - f1 * x11[k] - f2 * x21[k] - f3 * x31[k]
            s2[k] = p2[k] - t2[k] - f1 * x12[k] - f2 * x22[k] - f3 * x32[k]
        return
    for q in range(P.shape[0]):
        p, t, sq = P[q, a:b], T[q, a:b], S[q, :w]
        x1, x2, x3 = W[q, a - g : b - g], W[q, a - 2 * g : b - 2 * g], W[q, a - 3 * g : b - 3 * g]
        for k in range(w):
            sq[k] = p[k] - t[k] - m1[k] * x1[k] - m2[k] * x2[k] - m3[k] * x3[k]


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def unit_backward_sweep(U: np.ndarray, offsets: np.ndarray, R: np.ndarray, P: np.ndarray, T: np.ndarray,
                        beta: np.ndarray, S: np.ndarray, lo: int, hi: int, below: int,
                        above: int) -> None:  # pragma: no cover - compiled
    """On the block ``lo:hi``: ``P = R + β P`` (per column), then ``T = (I + U)⁻¹ P``, the rows ``below:lo``
    and ``hi:above`` of ``T`` read as fixed (they come later in the sweeps' order).

    ``U[d, i] = M[i, i + offsets[d]]`` of a unit-diagonal symmetric ``M`` (``U[0]`` unused);
    ``(c, m)`` C-contiguous vectors (``hi ≤ U.shape[1]``). With the open grid's
    offsets ``0, 1, 2, 3, g, 2g, 3g`` and ``S`` of shape ``(c, g)`` the couplings to later grid
    rows are summed vectorized and only those along the row run as the recurrence.
    """
    c = P.shape[0]
    g = offsets[4] if offsets.size == 7 and S.shape[1] == offsets[4] else 0
    fast = g > 0 and hi - lo > 6 * g
    b0 = hi - 3 * g if fast else lo  # (the fast rows' direction is updated with their terms)
    cg_direction(P, R, beta, b0, hi)
    if hi <= lo:
        return
    if not fast:
        _unit_rows(U, offsets, P, T, lo, hi, lo, hi, False, below, above)
        return
    _unit_rows(U, offsets, P, T, lo, hi, b0, hi, False, below, above)
    u1, u2, u3 = U[1], U[2], U[3]
    H = np.empty((c, 3))
    for b in range(b0, lo, -g):
        a = max(b - g, lo)
        _backward_terms(R, P, T, U, beta, S, a, b, g)
        if a < lo + 3 * g and below < lo:  # the couplings to the fixed rows before the block
            for q in range(c):
                for i in range(a, min(b, lo + 3 * g)):
                    S[q, i - a] -= _beyond(U, offsets, T, q, i, lo, hi, below, lo)
        _recurrence(S, u1, u2, u3, T, a, b, False, H)


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def unit_forward_sweep(U: np.ndarray, offsets: np.ndarray, F: np.ndarray, P: np.ndarray, T: np.ndarray,
                       W: np.ndarray, S: np.ndarray, lo: int, hi: int, below: int, above: int,
                       dots: np.ndarray) -> None:  # pragma: no cover - compiled
    """On the block ``lo:hi``: ``W = (I + L)⁻¹ (P − T)``, the rows ``below:lo`` and ``hi:above`` of ``W``
    read as fixed (they come earlier in the sweeps' order), and ``dots[q] = P·(T + W)`` over the block.

    ``F[d, i] = M[i, i − d]`` (``d = 1, 2, 3``, the open grid's fast path; else empty); ``hi ≤ U.shape[1]``.
    ``T`` zero: a plain forward solve of ``P``. (The fast path reads no fixed rows after the block; a
    block with them, a separator, is short and goes row by row.)
    """
    c = P.shape[0]
    for q in range(c):
        dots[q] = 0.0
    if hi <= lo:
        return
    g = offsets[4] if offsets.size == 7 and F.shape[0] == 4 and S.shape[1] == offsets[4] else 0
    fast = g > 0 and hi - lo > 6 * g and above == hi
    a0 = lo + 3 * g if fast else hi  # (the rows swept one by one; the others with their chunk's terms)
    for q in range(c):
        _difference_into(W[q, lo:a0], P[q, lo:a0], T[q, lo:a0])
    _unit_rows(U, offsets, W, W, lo, hi, lo, a0, True, below, above)
    if fast:
        f1, f2, f3 = F[1], F[2], F[3]
        H = np.empty((c, 3))
        for a in range(a0, hi, g):
            b = min(a + g, hi)
            _forward_terms(P, T, W, U, S, a, b, g)
            _recurrence(S, f1, f2, f3, W, a, b, True, H)
            _add_dots(P, T, W, a, b, dots)  # (while the chunk is in cache)
    _add_dots(P, T, W, lo, a0, dots)


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def _add_dots(P: np.ndarray, T: np.ndarray, W: np.ndarray, a: int, b: int, dots: np.ndarray) -> None:  # pragma: no cover - compiled
    """``dots[q] += P[q]·(T[q] + W[q])`` over the rows ``a:b``."""
    for q in range(P.shape[0]):
        p, t, v = P[q, a:b], T[q, a:b], W[q, a:b]
        acc = 0.0
        for k in range(b - a):
            acc += p[k] * (t[k] + v[k])
        dots[q] += acc


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def unit_cg_update(X: np.ndarray, R: np.ndarray, T: np.ndarray, W: np.ndarray, alpha: np.ndarray, lo: int, hi: int,
                   rr: np.ndarray) -> None:  # pragma: no cover - compiled
    """``x += α t``, ``r −= α (t + w)`` and ``rr[q] = r·r`` on columns ``lo:hi`` of ``(c, m)`` arrays."""
    for q in range(X.shape[0]):
        a = alpha[q]
        x, r, t, w = X[q, lo:hi], R[q, lo:hi], T[q, lo:hi], W[q, lo:hi]
        acc = 0.0
        for i in range(hi - lo):
            x[i] += a * t[i]
            v = r[i] - a * (t[i] + w[i])
            r[i] = v
            acc += v * v
        rr[q] = acc


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def unit_scaled(U: np.ndarray, offsets: np.ndarray, s: np.ndarray, Us: np.ndarray, F: np.ndarray, lo: int,
                hi: int) -> None:  # pragma: no cover - compiled
    """Rows ``lo:hi`` of ``D^{-1/2} M D^{-1/2}`` by its upper diagonals (``Us[d, i] = U[d, i] s_i s_{i+o}``,
    ``Us[0] = 1``, zero past the end) and, with ``F`` of shape ``(4, n)``, ``F[d, i] = Us[d, i − d]``
    (``d = 1, 2, 3``; zero before the start)."""
    n = U.shape[1]
    for i in range(lo, hi):
        Us[0, i] = 1.0
    for d in range(1, offsets.size):
        o = offsets[d]
        u, v = U[d], Us[d]
        for i in range(lo, hi):
            v[i] = u[i] * s[i] * s[i + o] if i + o < n else 0.0
    if F.shape[0] == 4:
        for d in range(1, 4):
            u, f = U[d], F[d]
            for i in range(lo, hi):
                f[i] = u[i - d] * s[i - d] * s[i] if i >= d else 0.0


# The same sweeps for a matrix in compressed rows (a mesh that is no open grid), row by row on ``(m, c)``
# vectors (a row's c values side by side: one cache line per neighbour).


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False, inline="always")
def _minus_row3(ptr: np.ndarray, idx: np.ndarray, val: np.ndarray, V: np.ndarray, i: int, a0: float, a1: float,
                a2: float) -> tuple[float, float, float]:  # pragma: no cover - compiled
    """``a − Σ_e val[e] V[idx[e]]`` over CSR row ``i``, three columns in registers."""
    for e in range(ptr[i], ptr[i + 1]):
        j = idx[e]
        a = val[e]
        a0 -= a * V[j, 0]
        a1 -= a * V[j, 1]
        a2 -= a * V[j, 2]
    return a0, a1, a2


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False, inline="always")
def _minus_row(ptr: np.ndarray, idx: np.ndarray, val: np.ndarray, V: np.ndarray, i: int,
               acc: np.ndarray) -> None:  # pragma: no cover - compiled
    """``acc −= Σ_e val[e] V[idx[e]]`` over CSR row ``i``, any number of columns."""
    for e in range(ptr[i], ptr[i + 1]):
        j = idx[e]
        a = val[e]
        for q in range(acc.size):
            acc[q] -= a * V[j, q]


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def csr_backward_sweep(up_ptr: np.ndarray, up_idx: np.ndarray, up: np.ndarray, out_ptr: np.ndarray,
                       out_idx: np.ndarray, out: np.ndarray, R: np.ndarray, P: np.ndarray, T: np.ndarray,
                       beta: np.ndarray, rows: np.ndarray, couple: bool) -> None:  # pragma: no cover - compiled
    """:func:`unit_backward_sweep` on ``(m, c)`` vectors over the block's ``rows`` (ascending; swept from the
    last), with the unit-diagonal matrix's strictly upper part inside each block (``up_*``) and its
    couplings outside the block (``out_*``) in CSR: ``P = R + β P``, then ``T = (I + U)⁻¹ (P − E T)``,
    ``E`` the couplings (with ``couple``; the rows they reach hold their final ``T``)."""
    c = P.shape[1]
    if c == 3:  # (x, y, z in registers: the general loop keeps them in a scratch array, 1.6× slower)
        b0, b1, b2 = beta[0], beta[1], beta[2]
        for k in range(rows.size - 1, -1, -1):
            i = rows[k]
            a0 = R[i, 0] + b0 * P[i, 0]
            a1 = R[i, 1] + b1 * P[i, 1]
            a2 = R[i, 2] + b2 * P[i, 2]
            P[i, 0], P[i, 1], P[i, 2] = a0, a1, a2
            if couple:
                a0, a1, a2 = _minus_row3(out_ptr, out_idx, out, T, i, a0, a1, a2)
            a0, a1, a2 = _minus_row3(up_ptr, up_idx, up, T, i, a0, a1, a2)
            T[i, 0], T[i, 1], T[i, 2] = a0, a1, a2
        return
    acc = np.empty(c)
    for k in range(rows.size - 1, -1, -1):
        i = rows[k]
        for q in range(c):
            acc[q] = R[i, q] + beta[q] * P[i, q]
            P[i, q] = acc[q]
        if couple:
            _minus_row(out_ptr, out_idx, out, T, i, acc)
        _minus_row(up_ptr, up_idx, up, T, i, acc)
        for q in range(c):
            T[i, q] = acc[q]


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def csr_forward_sweep(low_ptr: np.ndarray, low_idx: np.ndarray, low: np.ndarray, out_ptr: np.ndarray,
                      out_idx: np.ndarray, out: np.ndarray, P: np.ndarray, T: np.ndarray, W: np.ndarray,
                      rows: np.ndarray, couple: bool, dots: np.ndarray) -> None:  # pragma: no cover - compiled
    """:func:`unit_forward_sweep` on ``(m, c)`` vectors over the block's ``rows`` (ascending), with the
    strictly lower part inside each block (``low_*``) and the couplings outside it (``out_*``) in CSR:
    ``W = (I + L)⁻¹ (P − T − E W)`` on the block, ``E`` the couplings (with ``couple``; the rows they
    reach hold their final ``W``), and ``dots[q] = P·(T + W)`` over it."""
    c = P.shape[1]
    if c == 3:  # (x, y, z in registers, as in csr_backward_sweep)
        d0 = d1 = d2 = 0.0
        for k in range(rows.size):
            i = rows[k]
            a0 = P[i, 0] - T[i, 0]
            a1 = P[i, 1] - T[i, 1]
            a2 = P[i, 2] - T[i, 2]
            if couple:
                a0, a1, a2 = _minus_row3(out_ptr, out_idx, out, W, i, a0, a1, a2)
            a0, a1, a2 = _minus_row3(low_ptr, low_idx, low, W, i, a0, a1, a2)
            W[i, 0], W[i, 1], W[i, 2] = a0, a1, a2
            d0 += P[i, 0] * (T[i, 0] + a0)
            d1 += P[i, 1] * (T[i, 1] + a1)
            d2 += P[i, 2] * (T[i, 2] + a2)
        dots[0], dots[1], dots[2] = d0, d1, d2
        return
    acc = np.empty(c)
    for q in range(c):
        dots[q] = 0.0
    for k in range(rows.size):
        i = rows[k]
        for q in range(c):
            acc[q] = P[i, q] - T[i, q]
        if couple:
            _minus_row(out_ptr, out_idx, out, W, i, acc)
        _minus_row(low_ptr, low_idx, low, W, i, acc)
        for q in range(c):
            W[i, q] = acc[q]
            dots[q] += P[i, q] * (T[i, q] + acc[q])


@nb.njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def rows_cg_update(X: np.ndarray, R: np.ndarray, T: np.ndarray, W: np.ndarray, alpha: np.ndarray, lo: int, hi: int,
                   rr: np.ndarray) -> None:  # pragma: no cover - compiled
    """:func:`unit_cg_update` on ``(m, c)`` vectors: ``x += α t``, ``r −= α (t + w)``, ``rr[q] = r·r`` over ``lo:hi``."""
    c = X.shape[1]
    for q in range(c):
        rr[q] = 0.0
    for i in range(lo, hi):
        for q in range(c):
            a = alpha[q]
            X[i, q] += a * T[i, q]
            v = R[i, q] - a * (T[i, q] + W[i, q])
            R[i, q] = v
            rr[q] += v * v


@nb.njit(cache=True, nogil=True, boundscheck=False)
def csr_separators(indptr: np.ndarray, indices: np.ndarray, lo: int, hi: int,
                   separator: np.ndarray) -> None:  # pragma: no cover - compiled
    """Rows ``lo:hi`` (a thread's range): ``separator[i]`` where row ``i`` couples to a row from ``hi`` on."""
    for i in range(lo, hi):
        reach = False
        for e in range(indptr[i], indptr[i + 1]):
            if indices[e] >= hi:
                reach = True
        separator[i] = reach


@nb.njit(cache=True, nogil=True, boundscheck=False)
def _same_block(separator: np.ndarray, i: int, j: int, lo: int, hi: int) -> bool:  # pragma: no cover - compiled
    """Whether rows ``i`` (of the range ``lo:hi``) and ``j`` share a block: both separators, or both in the
    range's interior."""
    if separator[i]:
        return separator[j]
    return not separator[j] and lo <= j < hi


@nb.njit(cache=True, nogil=True, boundscheck=False)
def csr_split_counts(indptr: np.ndarray, indices: np.ndarray, separator: np.ndarray, lo: int, hi: int,
                     counts: np.ndarray) -> None:  # pragma: no cover - compiled
    """Per row of the range ``lo:hi``: its entries strictly below the diagonal inside its block (the
    range's interior, or all separator rows), strictly above it inside its block, and outside it
    (``counts[0..2, i]``; the diagonal in none)."""
    for i in range(lo, hi):
        a = b = o = 0
        for e in range(indptr[i], indptr[i + 1]):
            j = indices[e]
            if not _same_block(separator, i, j, lo, hi):
                o += 1
            elif j < i:
                a += 1
            elif j > i:
                b += 1
        counts[0, i], counts[1, i], counts[2, i] = a, b, o


@nb.njit(cache=True, nogil=True, boundscheck=False)
def csr_split_fill(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, s: np.ndarray,
                   separator: np.ndarray, lo: int, hi: int, ptr: np.ndarray, idx0: np.ndarray, val0: np.ndarray,
                   idx1: np.ndarray, val1: np.ndarray, idx2: np.ndarray,
                   val2: np.ndarray) -> None:  # pragma: no cover - compiled
    """Rows ``lo:hi`` of the three parts of :func:`csr_split_counts` (lower, upper, outside the block),
    scaled to a unit diagonal (``data · s_i · s_j``): part ``p``'s row ``i`` starts at ``ptr[p, i]``."""
    for i in range(lo, hi):
        f0, f1, f2 = ptr[0, i], ptr[1, i], ptr[2, i]
        si = s[i]
        for e in range(indptr[i], indptr[i + 1]):
            j = indices[e]
            v = data[e] * si * s[j]
            if not _same_block(separator, i, j, lo, hi):
                idx2[f2] = j
                val2[f2] = v
                f2 += 1
            elif j < i:
                idx0[f0] = j
                val0[f0] = v
                f0 += 1
            elif j > i:
                idx1[f1] = j
                val1[f1] = v
                f1 += 1
