"""Conjugate gradients on several right-hand sides at once, threaded over row ranges.

:func:`block_cg` runs one CG per column of ``B`` sharing every operator product;
the operator is a :class:`~quadnodes.linalg.threads.RowBlocks` (CSR) or a
:class:`DiagonalBlocks` (diagonal storage, for matrices of a structured grid);
:class:`BlockJacobi` and :class:`LinePreconditioner` are its preconditioners.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.linalg.blas import daxpy as _daxpy, ddot as _ddot, dscal as _dscal

from . import threads as _threads
from .threads import RANGE_ALIGN, RowBlocks, blas_pinned

try:  # SciPy's diagonal-storage kernel (y += A x, one contiguous pass per diagonal)
    from scipy.sparse._sparsetools import dia_matvec as _dia_matvec
except ImportError:  # pragma: no cover - then callers use CSR
    _dia_matvec = None

__all__ = ["HAS_DIAGONAL_KERNEL", "DiagonalBlocks", "SymmetricDiagonalBlocks", "BlockJacobi", "LinePreconditioner",
           "PathLinePreconditioner", "strongest_lines", "block_cg", "permuted"]

#: Whether SciPy's diagonal-storage kernel is available (else use :class:`RowBlocks`).
HAS_DIAGONAL_KERNEL = _dia_matvec is not None


class DiagonalBlocks(RowBlocks):
    """A matrix in diagonal storage (``data[d, j] = M[j - offsets[d], j]``), cut into row ranges.

    The same interface as :class:`RowBlocks` for :func:`block_cg`, with ``(c, n)``
    vectors; a row range is the sub-matrix with offsets shifted by its first row.
    """

    def __init__(self, offsets: np.ndarray, data: np.ndarray, *, threads: int | None = None) -> None:
        n = data.shape[1]
        t = _threads.thread_count() if threads is None else max(1, int(threads))
        t = max(1, min(t, n // _threads.PARALLEL_MIN_ROWS))
        cuts = (np.arange(1, t) * n // t) // RANGE_ALIGN * RANGE_ALIGN  # every row costs the same
        self.ranges = list(zip(np.r_[0, cuts].tolist(), np.r_[cuts, n].tolist()))
        self.offsets = offsets.astype(np.int32 if n < 2**31 - 1 else np.int64)
        self.data = data
        self.M = sp.dia_matrix((data, self.offsets), shape=(n, n))
        self.columns = True

    def matvec(self, X: np.ndarray, Y: np.ndarray, lo: int, hi: int, *, data: np.ndarray | None = None,
               accumulate: bool = False) -> None:
        n = self.data.shape[1]
        hi = min(hi, n)
        split = self._split if data is None and not accumulate else None
        if split is None and data is None and not accumulate:
            split = self._split = self._main_and_rest()
        if split is not None and split[0] is not None:
            # y = diag · x first, the diagonals before and after it added by SciPy's kernel: no pass to zero y
            main, parts = split
            for x, y in zip(X, Y):
                y = y[lo:hi]
                np.multiply(main[lo:hi], x[lo:hi], out=y)
                for offsets, rest in parts:
                    _dia_matvec(hi - lo, n, offsets.size, n, offsets + offsets.dtype.type(lo), rest, x, y)
            return
        off = self.offsets + self.offsets.dtype.type(lo)
        for x, y in zip(X, Y):
            y = y[lo:hi]
            if not accumulate:
                y.fill(0.0)
            _dia_matvec(hi - lo, n, off.size, n, off, self.data if data is None else data, x, y)

    _split: tuple | None = None

    def _main_and_rest(self) -> tuple:
        """``(main diagonal, [(offsets, diagonals), …])``: the storage's rows before and after the main diagonal as
        views (contiguous rows of ``data``: no copy of the storage), or ``(None,)`` without a main diagonal."""
        zero = np.flatnonzero(self.offsets == 0)
        if zero.size != 1 or not self.data.flags.c_contiguous:
            return (None,)
        z = int(zero[0])
        parts = [(self.offsets[a:b], self.data[a:b]) for a, b in ((0, z), (z + 1, self.offsets.size)) if b > a]
        return (self.data[z], parts)




def permuted(M: sp.csr_matrix, order: np.ndarray) -> sp.csr_matrix:
    """``M[order][:, order]`` for a CSR matrix in one pass (column indices left unsorted)."""
    k = M.shape[0]
    idx = M.indices.dtype
    rank = np.empty(k, dtype=idx)
    rank[order] = np.arange(k, dtype=idx)
    counts = np.diff(M.indptr)[order]
    indptr = np.zeros(k + 1, dtype=M.indptr.dtype)
    np.cumsum(counts, out=indptr[1:])
    # source position of every entry: its row's old start plus its place in the row
    src = np.repeat(M.indptr[:-1][order] - indptr[:-1], counts) + np.arange(indptr[-1], dtype=indptr.dtype)
    return sp.csr_matrix((M.data[src], rank[M.indices[src]], indptr), shape=M.shape)




class BlockJacobi:
    """Block-diagonal preconditioner: exact inverses of the diagonal ``b × b`` blocks of ``M``.

    The unknowns are ordered by :func:`_patch_order`, so a block is a compact patch
    of about 4 × 4 vertices. On such a patch the fairing energy of a smooth (slowly
    varying) motion is small next to ω, so the local solves capture most of the
    stiff, oscillating part and leave the smooth part to CG.
    """

    def __init__(self, M: sp.csr_matrix, size: int) -> None:
        k = M.shape[0]
        kp = -(-k // RANGE_ALIGN) * RANGE_ALIGN  # as the CG vectors (size divides RANGE_ALIGN)
        counts = np.diff(M.indptr)
        row = np.repeat(np.arange(k, dtype=np.int64), counts)
        col = M.indices.astype(np.int64)
        same = np.flatnonzero((row ^ col) < size) if size & (size - 1) == 0 else \
            np.flatnonzero(row // size == col // size)  # same block (power of 2: equal high bits)
        D = np.zeros(kp * size)
        D[row[same] * size + (col[same] % size)] = M.data[same]
        D = D.reshape(kp // size, size, size)
        pad = np.arange(k, kp)
        D[pad // size, pad % size, pad % size] = 1.0
        inv = np.linalg.inv(D)
        inv += inv.transpose(0, 2, 1)  # exactly symmetric, so a row vector can multiply it
        inv *= 0.5
        self.inv = inv
        self.size = size

    def apply(self, R: np.ndarray, Z: np.ndarray, lo: int, hi: int, columns: bool) -> None:
        """``Z = P⁻¹ R`` on rows ``lo:hi`` (at block boundaries) of ``(c, n)`` or ``(n, c)`` arrays."""
        b = self.size
        inv = self.inv[lo // b : hi // b]
        if columns:
            c = R.shape[0]
            r = R[:, lo:hi].reshape(c, -1, b).transpose(1, 0, 2)  # (blocks, c, b) views
            z = Z[:, lo:hi].reshape(c, -1, b).transpose(1, 0, 2)
            np.matmul(r, inv, out=z)
        else:
            c = R.shape[1]
            np.matmul(inv, R[lo:hi].reshape(-1, b, c), out=Z[lo:hi].reshape(-1, b, c))




def _run_cg(
    blocks: RowBlocks,
    B: np.ndarray,
    X0: np.ndarray,
    *,
    rtol: float,
    maxiter: int,
    precond: object | None = None,
) -> tuple[np.ndarray, int, float]:
    """(Preconditioned) conjugate gradients on the columns of ``B`` at once.

    Each column is an independent CG run; they share the operator products, and
    every vector update runs on the row ranges of ``blocks`` in parallel. Stops
    when every column's residual is at most ``rtol`` times its right-hand side.
    Returns the solution, the number of steps and the worst relative residual.

    The vectors are zero-padded to a multiple of :data:`RANGE_ALIGN` rows and
    stored as ``(c, k)`` arrays for small systems (``blocks.columns``), else as
    ``(k, c)`` arrays updated through ``(k / RANGE_ALIGN, RANGE_ALIGN·c)`` views:
    either way per-column scalars broadcast along long rows (NumPy is several
    times slower on an inner dimension of 3).
    """
    k, c = B.shape
    kp = -(-k // RANGE_ALIGN) * RANGE_ALIGN
    columns = blocks.columns
    width = RANGE_ALIGN * c

    def padded(a: np.ndarray | None) -> np.ndarray:
        return _threads.padded(a, kp, c, columns=columns)

    X, B, R, P, Q = padded(X0), padded(B), padded(None), padded(None), padded(None)
    Z = R if precond is None else padded(None)

    if columns:
        def part(V: np.ndarray, lo: int, hi: int) -> np.ndarray:
            return V[:, lo : kp if hi == k else hi]

        def dot(U: np.ndarray, V: np.ndarray) -> np.ndarray:
            return np.einsum("ij,ij->i", U, V)

        alpha, beta = np.zeros((c, 1)), np.zeros((c, 1))  # per-column scalars
        scalars = alpha[:, 0], beta[:, 0]
    else:
        def part(V: np.ndarray, lo: int, hi: int) -> np.ndarray:
            return V.reshape(-1, width)[lo // RANGE_ALIGN : (kp if hi == k else hi) // RANGE_ALIGN]

        def dot(U: np.ndarray, V: np.ndarray) -> np.ndarray:
            return np.einsum("ij,ij->j", U, V).reshape(RANGE_ALIGN, c).sum(axis=0)

        alpha, beta = np.zeros(width), np.zeros(width)  # per-column scalars, repeated along a row
        scalars = alpha.reshape(RANGE_ALIGN, c), beta.reshape(RANGE_ALIGN, c)

    whole = getattr(precond, "whole", False)  # applied to all rows at once, after the ranges

    def precondition(lo: int, hi: int) -> None:
        if precond is not None and not whole:
            precond.apply(R, Z, lo, kp if hi == k else hi, columns)

    def start(lo: int, hi: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        blocks.matvec(X, R, lo, hi)
        r, b = part(R, lo, hi), part(B, lo, hi)
        np.subtract(b, r, out=r)
        precondition(lo, hi)
        if whole:
            return dot(r, r), dot(b, b), None
        z = part(Z, lo, hi)
        part(P, lo, hi)[...] = z
        return dot(r, r), dot(b, b), dot(r, z)

    parts = blocks.run(start)
    rr = sum(p[0] for p in parts)
    bnorm = np.maximum(np.sqrt(sum(p[1] for p in parts)), 1e-300)
    if whole:
        precond.apply(R, Z, 0, kp, columns)  # type: ignore[union-attr]
        P[...] = Z
        rz = dot(part(R, 0, k), part(Z, 0, k))  # (the layout of the ranges)
    else:
        rz = sum(p[2] for p in parts)
    tol2 = (rtol * bnorm) ** 2

    if columns and len(blocks.ranges) == 1:
        # one thread, one contiguous vector per coordinate: a plain loop with BLAS level 1
        # in place (one pass per update; NumPy's α·p then x += t makes three and a
        # temporary) and Python floats for the per-coordinate scalars. Not on threads:
        # OpenBLAS's own threads would spin against the pool's.
        rows = [(X[i], R[i], P[i], Q[i], Z[i]) for i in range(c)]
        rr_, rz_, tol_ = rr.tolist(), rz.tolist(), tol2.tolist()
        step = [0.0] * c
        it = 0
        while it < maxiter and any(rr_[i] > tol_[i] for i in range(c)):
            blocks.matvec(P, Q, 0, kp)
            for i, (x, r, p, q, _) in enumerate(rows):
                pq = _ddot(p, q)
                a = rz_[i] / pq if pq > 0 else 0.0
                _daxpy(p, x, a=a)
                _daxpy(q, r, a=-a)
            if whole:
                precond.apply(R, Z, 0, kp, columns)  # type: ignore[union-attr]
            else:
                precondition(0, kp)
            for i, (_, r, _, _, z) in enumerate(rows):
                rr_i = _ddot(r, r)
                rz_i = rr_i if precond is None else _ddot(r, z)
                step[i] = rz_i / rz_[i] if rz_[i] > 0 else 0.0
                rr_[i], rz_[i] = rr_i, rz_i
            it += 1
            if it < maxiter and any(rr_[i] > tol_[i] for i in range(c)):
                for i, (_, _, p, _, z) in enumerate(rows):
                    _dscal(step[i], p)
                    _daxpy(z, p)
        x = np.ascontiguousarray(X[:, :k].T)
        return x, it, float(np.max(np.sqrt(np.array(rr_)) / bnorm))

    T = padded(None)  # (threaded runs: NumPy updates through a temporary)

    def product(lo: int, hi: int) -> np.ndarray:
        blocks.matvec(P, Q, lo, hi)
        return dot(part(P, lo, hi), part(Q, lo, hi))

    def update(lo: int, hi: int) -> tuple[np.ndarray, np.ndarray | None]:
        t, r = part(T, lo, hi), part(R, lo, hi)
        np.multiply(part(P, lo, hi), alpha, out=t)
        part(X, lo, hi)[...] += t
        np.multiply(part(Q, lo, hi), alpha, out=t)
        r -= t
        precondition(lo, hi)
        return dot(r, r), (None if precond is None or whole else dot(r, part(Z, lo, hi)))

    def direction(lo: int, hi: int) -> None:
        p = part(P, lo, hi)
        p *= beta
        p += part(Z, lo, hi)

    if columns and isinstance(blocks, SymmetricDiagonalBlocks):  # compiled passes: one read of each vector
        from ._kernels import cg_direction, cg_update, row_dots

        def product(lo: int, hi: int) -> np.ndarray:
            blocks.matvec(P, Q, lo, hi)
            out = np.empty(c)
            row_dots(P, Q, lo, kp if hi == k else hi, out)
            return out

        def update(lo: int, hi: int) -> tuple[np.ndarray, np.ndarray | None]:
            hi = kp if hi == k else hi
            rr = np.empty(c)
            cg_update(X, R, P, Q, alpha[:, 0], lo, hi, rr)
            precondition(lo, hi)
            if precond is None or whole:
                return rr, None
            rz = np.empty(c)
            row_dots(R, Z, lo, hi, rz)
            return rr, rz

        def direction(lo: int, hi: int) -> None:
            cg_direction(P, Z, beta[:, 0], lo, kp if hi == k else hi)

        def dot(U: np.ndarray, V: np.ndarray) -> np.ndarray:  # type: ignore[no-redef]
            return sum(blocks.run(lambda lo, hi: _row_dots(U, V, lo, kp if hi == k else hi)))

        def _row_dots(U: np.ndarray, V: np.ndarray, lo: int, hi: int) -> np.ndarray:
            out = np.empty(c)
            row_dots(U, V, lo, hi, out)
            return out

    it = 0
    while it < maxiter and (rr > tol2).any():
        pq = sum(blocks.run(product))
        scalars[0][...] = np.divide(rz, pq, out=np.zeros_like(rz), where=pq > 0)
        parts = blocks.run(update)
        rr_new = sum(p[0] for p in parts)
        if whole:
            precond.apply(R, Z, 0, kp, columns)  # type: ignore[union-attr]
            rz_new = dot(part(R, 0, k), part(Z, 0, k))
        else:
            rz_new = rr_new if precond is None else sum(p[1] for p in parts)
        scalars[1][...] = np.divide(rz_new, rz, out=np.zeros_like(rz), where=rz > 0)
        rr, rz = rr_new, rz_new
        it += 1
        if it < maxiter and (rr > tol2).any():
            blocks.run(direction)
    x = np.ascontiguousarray(X[:, :k].T) if columns else X[:k]
    return x, it, float(np.max(np.sqrt(rr) / bnorm))


def block_cg(
    blocks: RowBlocks,
    B: np.ndarray,
    X0: np.ndarray,
    *,
    rtol: float,
    maxiter: int,
    precond: object | None = None,
) -> tuple[np.ndarray, int, float]:
    """(Preconditioned) conjugate gradients on the columns of ``B`` at once, BLAS held to one thread.

    Parameters
    ----------
    blocks : RowBlocks or DiagonalBlocks
        The symmetric positive definite operator ``M`` cut into row ranges.
    B : (k, c) float64
        Right-hand sides.
    X0 : (k, c) float64
        Starting guesses.
    rtol : float
        Stop when every column's residual is at most ``rtol`` times its right-hand side.
    maxiter : int
        Cap on steps.
    precond : BlockJacobi, LinePreconditioner or SymmetricGaussSeidel, optional
        ``apply(R, Z, lo, hi, columns)`` writing ``Z = P⁻¹ R`` on rows ``lo:hi``
        (a preconditioner with ``whole = True`` is applied to all rows at once);
        :class:`~quadnodes.linalg.gauss_seidel.SymmetricGaussSeidel` runs
        :func:`~quadnodes.linalg.gauss_seidel.gauss_seidel_cg` instead.

    Returns
    -------
    x : (k, c) float64
    steps : int
    residual : float
        The worst column's relative residual.

    Examples
    --------
    >>> M = sp.diags([-1.0, 2.5, -1.0], [-1, 0, 1], shape=(50, 50)).tocsr()
    >>> b = np.ones((50, 2))
    >>> x, steps, res = block_cg(RowBlocks(M), b, np.zeros((50, 2)), rtol=1e-12, maxiter=500)
    >>> bool(np.abs(M @ x - b).max() < 1e-9), res <= 1e-12
    (True, True)
    """
    if getattr(precond, "eisenstat", False):  # symmetric Gauss–Seidel: the sweeps are the whole step
        from .gauss_seidel import gauss_seidel_cg

        return gauss_seidel_cg(blocks, B, X0, rtol=rtol, maxiter=maxiter, sweeps=precond)  # type: ignore[arg-type]
    if len(blocks.ranges) > 1 and (precond is None or getattr(precond, "blas_free", False)):
        # threaded passes that call no BLAS (SciPy's sparse and diagonal kernels, NumPy's array loops,
        # the compiled kernels): nothing to pin (the pin's first library scan costs about 20 ms)
        return _run_cg(blocks, B, X0, rtol=rtol, maxiter=maxiter, precond=precond)
    with blas_pinned():  # (one range: BLAS level-1 calls; block Jacobi: batched matmul)
        return _run_cg(blocks, B, X0, rtol=rtol, maxiter=maxiter, precond=precond)


#: :class:`SymmetricDiagonalBlocks` reads an upper diagonal holding fewer than one entry in this many (but the main
#: one) as a list of entries, not as a pass of its own: a closed grid's periodic pairs.
SPARSE_DIAGONAL_FRACTION = 16


class SymmetricDiagonalBlocks(DiagonalBlocks):
    """A symmetric matrix in diagonal storage, applied by a compiled kernel from its upper diagonals.

    Same interface and input as :class:`DiagonalBlocks` (``data[d, j] = M[j - offsets[d], j]``,
    offsets symmetric about 0); the product reads each of the ``(d + 1) / 2`` upper
    diagonals once for all columns' passes from cache, about half the memory
    traffic of the full storage (:func:`~quadnodes.linalg._kernels.symmetric_diagonal_product`). Upper
    diagonals that hold few entries (:data:`SPARSE_DIAGONAL_FRACTION`: a closed grid's periodic pairs, a handful per
    line) after the others are read as a list of entries instead, so a torus's product is an open grid's seven
    diagonals (the kernel's fast rows) and a few thousand entries.
    """

    def __init__(self, offsets: np.ndarray, data: np.ndarray, *, threads: int | None = None) -> None:
        super().__init__(offsets, data, threads=threads)
        n = data.shape[1]
        offsets = np.asarray(offsets)
        up = np.flatnonzero(offsets >= 0)
        if offsets[up[0]] != 0 or not np.array_equal(np.sort(-offsets[offsets < 0]), np.sort(offsets[up[1:]])):
            raise ValueError("offsets: expected a main diagonal and symmetric pairs")
        self.upper_offsets = offsets[up].astype(np.int64)
        self._n, self._rows = n, up  # (the storage's rows of the upper diagonals)
        # diagonals that hold a few entries (a closed grid's periodic pairs: a handful per line, at its seam) cost a
        # full pass each in the product: the product reads the others from U, and those entries from a list by row,
        # both triangles (their rows of U are not kept: :attr:`upper` makes the whole on request)
        held = np.array([np.count_nonzero(data[r]) for r in up])
        sparse = held * SPARSE_DIAGONAL_FRACTION < n
        sparse[0] = False
        k = up.size  # (the sparse ones taken apart where they follow all the others)
        if sparse.any() and sparse[int(np.argmax(sparse)):].all():
            k = int(np.argmax(sparse))
        U = self._upper_rows(data, k)
        self._dense = (U, self.upper_offsets[:k])
        self._upper = U if k == up.size else None
        #: the few entries' ``(rows, columns, values)``, by row (both triangles), or None
        self._seam: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        if k < up.size:
            parts = []
            for d in range(k, up.size):
                o = int(self.upper_offsets[d])
                j = np.flatnonzero(data[up[d]])  # (M[i, i + o] is stored at column j = i + o)
                j = j[j >= o]
                parts += [(j - o, j, data[up[d], j]), (j, j - o, data[up[d], j])]
            r, c, v = (np.concatenate(p) for p in zip(*parts))
            order = np.argsort(r, kind="stable")
            self._seam = (r[order], c[order], v[order])

    def _upper_rows(self, data: np.ndarray, k: int) -> np.ndarray:
        """The first ``k`` upper diagonals as ``(k, n)`` rows: ``U[d, i] = M[i, i + o_d]`` (zero past the end)."""
        n = self._n
        U = np.zeros((k, n))
        for d, o in zip(range(k), self.upper_offsets[:k]):  # M[i, i + o] = data[d, i + o]
            if o < n:  # (an offset past the matrix, e.g. 3 columns on a grid of 2 rows, stays zero)
                U[d, : n - o] = data[self._rows[d], o:]
        return U

    @property
    def split(self) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray, np.ndarray] | None]:
        """``(U, offsets, entries)``: the upper diagonals the product reads as diagonals (``U[d, i] = M[i, i +
        offsets[d]]``) and the few it reads as a list, ``(rows, columns, values)`` by row, both triangles (a closed
        grid's periodic pairs; None where there are none)."""
        return self._dense[0], self._dense[1], self._seam

    @property
    def upper(self) -> np.ndarray:
        """``(d, n)``: every upper diagonal, ``U[d, i] = M[i, i + upper_offsets[d]]`` (made on first use where the
        product keeps only some of them: a closed grid's)."""
        if self._upper is None:
            self._upper = self._upper_rows(self.data, self.upper_offsets.size)
        return self._upper

    def matvec(self, X: np.ndarray, Y: np.ndarray, lo: int, hi: int, *, data: np.ndarray | None = None,
               accumulate: bool = False) -> None:
        if data is not None or accumulate:  # (not used by block_cg; the general kernel)
            return super().matvec(X, Y, lo, hi, data=data, accumulate=accumulate)
        from ._kernels import entries_product, symmetric_diagonal_product

        n = self._n
        if X.flags.c_contiguous and Y.flags.c_contiguous:
            symmetric_diagonal_product(*self._dense, X, Y, lo, min(hi, n))
            if self._seam is not None:
                rows = self._seam[0]
                a, b = np.searchsorted(rows, (lo, min(hi, n)))
                entries_product(*self._seam, X, Y, int(a), int(b))
        else:  # pragma: no cover - block_cg's vectors are contiguous
            return super().matvec(X, Y, lo, hi)


class _PathEntries:
    """``M``'s entries looked up by pairs of unknowns: ``M`` in compressed rows, sorted, and its entries' keys."""

    def __init__(self, M: sp.spmatrix) -> None:
        M = sp.csr_matrix(M)
        M.sort_indices()
        self.M = M
        k = M.shape[0]
        self.keys = np.repeat(np.arange(k, dtype=np.int64), np.diff(M.indptr)) * k + M.indices

    def __call__(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """``M[a, b]`` entry by entry (0 where not stored)."""
        keys, k = self.keys, self.M.shape[0]
        key = a * k + b
        pos = np.minimum(np.searchsorted(keys, key), keys.size - 1)
        return np.where(keys[pos] == key, self.M.data[pos], 0.0)

    def along(self, path: np.ndarray, segment: np.ndarray, d: int) -> tuple[np.ndarray, np.ndarray]:
        """``(same, M[path[j], path[j + d]])`` for every ``j`` below ``len(path) − d``: whether both lie on one path
        (``segment``, each entry's path), and the entry there (0 across paths)."""
        same = segment[:-d] == segment[d:]
        return same, np.where(same, self(path[:-d], path[d:]), 0.0)


class PathLinePreconditioner:
    """Additive line-block preconditioner for any mesh: exact banded solves along paths of unknowns.

    The unknowns of a sparse SPD matrix ``M`` lie on paths (a mesh's structure lines,
    broken where a fixed vertex drops out), and ``M`` couples unknowns up to ``kd``
    steps apart along a path through that line's terms. Every path gets the band
    ``B_p`` of ``M``'s entries between its unknowns up to ``kd`` steps apart, with
    ``M``'s whole diagonal; ``P⁻¹ = Σ_p E_p B_p⁻¹ E_pᵀ`` (unknowns on no path: ``1/M_ii``).
    On a grid this is :class:`LinePreconditioner` (rows and columns); here the paths
    are laid end to end in one band, factorized once (LAPACK ``pbtrf``), and solved
    by a compiled sweep each way (:func:`~quadnodes.linalg._kernels.path_band_solve`;
    LAPACK's ``pbtrs`` runs its recurrence through level-2 BLAS calls, about 10× slower
    here). A coupling of a closed path across its seam (its last and first unknowns) is
    moved onto the diagonal as its absolute value, so the band stays positive definite
    where ``M`` is diagonally dominant along it. Applied to all rows at once (``whole``).

    Parameters
    ----------
    M : (k, k) sparse, symmetric positive definite
    path : (S,) int64
        The paths' unknowns, one path after another.
    starts : (S,) bool
        True where a new path begins.
    closed : (S,) bool, optional
        True at the start of a closed path (its last unknowns are coupled to its first
        ones around a seam); default: every path open.
    kd : int
        Half-bandwidth along a path (3 for windows of four vertices).

    Raises
    ------
    numpy.linalg.LinAlgError
        When a band is not positive definite (then use plain CG).
    """

    whole = True
    blas_free = True  # (compiled sweeps: block_cg need not pin BLAS)

    def __init__(self, M: sp.spmatrix, path: np.ndarray, starts: np.ndarray, closed: np.ndarray | None = None,
                 kd: int = 3) -> None:
        from scipy.linalg import cholesky_banded

        entries = _PathEntries(M)
        M = entries.M
        k = M.shape[0]
        path = np.asarray(path, dtype=np.int64)
        S = path.size
        diag = M.diagonal()
        band = np.zeros((kd + 1, S))
        band[kd] = diag[path]
        starts = np.asarray(starts, dtype=bool)
        seg = np.cumsum(starts) - 1
        first = np.flatnonzero(starts)
        last = np.r_[first[1:], S] - 1
        if closed is not None:
            ring = np.asarray(closed, dtype=bool)[first]
            first, last = first[ring], last[ring]
        else:
            first = last = first[:0]
        for d in range(1, kd + 1):
            band[kd - d, d:] = entries.along(path, seg, d)[1]
            # a closed path: its last unknowns coupled to its first ones across the seam, d steps
            # around (last - a with first + b, a + b = d - 1), moved onto both diagonals
            for b in range(d):
                i = last - (d - 1 - b)
                j = first + b
                ok = i - j > kd  # (nearer pairs are inside the band already)
                if ok.any():
                    v = np.abs(entries(path[i[ok]], path[j[ok]]))
                    np.add.at(band[kd], i[ok], v)
                    np.add.at(band[kd], j[ok], v)
        self.factor = cholesky_banded(band, lower=False, check_finite=False)
        self._dinv = 1.0 / self.factor[kd]
        self.path = path
        self.k = k
        covered = np.zeros(k, dtype=bool)
        covered[path] = True
        self._lone = np.flatnonzero(~covered)
        self._lone_inv = 1.0 / diag[self._lone]
        self._work: np.ndarray | None = None
        self._second: np.ndarray | None = None
        # from LINES_PARALLEL_MIN_ROWS unknowns: the paths in two stretches of whole paths on two threads
        # (each unknown lies on two paths, so the second stretch adds into its own Z, summed after)
        inner = np.flatnonzero(starts)[1:]  # the starts of all paths but the first: where a stretch may end
        half = int(inner[np.argmin(np.abs(2 * inner - S))]) if inner.size else S
        self._cut = half if (k >= LINES_PARALLEL_MIN_ROWS and _threads.thread_count() > 1) else S

    def apply(self, R: np.ndarray, Z: np.ndarray, lo: int, hi: int, columns: bool) -> None:
        """``Z = P⁻¹ R`` for ``(c, n)`` (``columns``) or ``(n, c)`` arrays (all rows; ``whole``)."""
        from ._kernels import path_band_solve, path_band_solve_xyz

        k = self.k
        Rr = np.ascontiguousarray(R[:, :k].T) if columns else R  # (n, c): one cache line per unknown
        solve = path_band_solve_xyz if self.factor.shape[0] == 4 and Rr.shape[1] == 3 else path_band_solve
        Zr = np.zeros((k, Rr.shape[1])) if columns else Z
        if not columns:
            Zr[:k] = 0.0
        work = self._work
        if work is None or work.shape[1] != Rr.shape[1]:
            work = self._work = np.empty((self.path.size, Rr.shape[1]))
        S, cut = self.path.size, self._cut
        if cut < S:
            second = self._second
            if second is None or second.shape != Zr.shape:
                second = self._second = np.empty(Zr.shape)
            second.fill(0.0)
            job = _threads.pool().submit(solve, self.factor, self._dinv, self.path, Rr, second, work,
                                         cut, S)
            solve(self.factor, self._dinv, self.path, Rr, Zr, work, 0, cut)
            job.result()
            Zr += second
        else:
            solve(self.factor, self._dinv, self.path, Rr, Zr, work, 0, S)
        if self._lone.size:
            Zr[self._lone] = Rr[self._lone] * self._lone_inv[:, None]
        if columns:
            Z[:, :k] = Zr.T


def strongest_lines(M: sp.spmatrix, path: np.ndarray, starts: np.ndarray, kd: int = 3
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Which of its paths ties each unknown most strongly, and how much more strongly than its weakest.

    An entry's tie to its path is the mean of ``|M|`` between it and the entries up to ``kd`` steps along it. On a
    quad mesh's structure lines an unknown lies on two paths, one each way; where faces are long and thin the line
    along their short edges ties it far more strongly, and a point smoother is slow there.

    Parameters
    ----------
    M : (k, k) sparse
        Symmetric.
    path : (S,) int64
        The paths' unknowns, one path after another (as :class:`PathLinePreconditioner` takes them).
    starts : (S,) bool
        True where a new path begins.
    kd : int
        Steps along a path counted in an entry's tie (≥ 1).

    Returns
    -------
    ratio : (k,) float64
        Each unknown's strongest tie over its weakest, where it has two path entries or more, each at least ``kd``
        steps from its path's ends (near an end it is tied by fewer terms of the energy, whatever the faces'
        shape); ∞ there where one entry's tie is 0; 1 elsewhere, and where no entry ties it at all.
    strongest : (S,) bool
        One entry per unknown on a path: its first of the most strongly tied.

    Examples
    --------
    >>> M = sp.lil_matrix((5, 5))
    >>> M.setdiag(4.0)
    >>> M[0, 1] = M[1, 0] = M[0, 2] = M[2, 0] = -1.0  # unknown 0 tied 1.0 along 1, 0, 2
    >>> M[0, 3] = M[3, 0] = M[0, 4] = M[4, 0] = -0.1  # and 0.1 along 3, 0, 4
    >>> ratio, strongest = strongest_lines(M, np.array([1, 0, 2, 3, 0, 4]), np.arange(6) % 3 == 0, kd=1)
    >>> ratio.round(6).tolist(), strongest.tolist()
    ([10.0, 1.0, 1.0, 1.0, 1.0], [True, True, True, True, False, True])
    """
    entries = _PathEntries(M)
    k = entries.M.shape[0]
    path = np.asarray(path, dtype=np.int64)
    S = path.size
    seg = np.cumsum(np.asarray(starts, dtype=bool)) - 1
    tie = np.zeros(S)
    near = np.zeros(S)  # (the entries counted: fewer near a path's ends)
    for d in range(1, max(1, kd) + 1):
        same, v = entries.along(path, seg, d)
        v = np.abs(v)
        tie[d:] += v
        tie[:-d] += v
        near[d:] += same
        near[:-d] += same
    tie /= np.maximum(near, 1.0)
    inner = near == 2 * max(1, kd)  # (an entry with a whole neighbourhood on its path)
    high = np.zeros(k)
    low = np.full(k, np.inf)
    np.maximum.at(high, path, tie)
    np.minimum.at(low, path, tie)
    ratio = np.ones(k)
    two = (np.bincount(path, minlength=k) >= 2) & (np.bincount(path, weights=~inner, minlength=k) == 0) & (high > 0)
    with np.errstate(divide="ignore"):
        ratio[two] = high[two] / low[two]  # (∞ where one path does not tie it at all)
    top = np.flatnonzero(tie == high[path])
    first = np.unique(path[top], return_index=True)[1]  # (the first of equals: one entry per unknown)
    strongest = np.zeros(S, dtype=bool)
    strongest[top[first]] = True
    return ratio, strongest


#: The line solves run on the pool's threads from this many nodes on (below, handing the lines
#: to a second thread costs more than it saves: 300² 5.3 ms on two threads against 4.3 ms on one;
#: 1000² 35 ms against 54 ms).
LINES_PARALLEL_MIN_ROWS = 200_000


class LinePreconditioner:
    """Additive line-block preconditioner on a ``rows × cols`` grid: exact solves along its rows
    and along its columns, added.

    ``M``'s entries that couple nodes of the same grid row (offsets ±1 … ±b) form a
    band ``B₁`` (with ``M``'s whole diagonal), those of the same grid column
    (offsets ±cols … ±b·cols) a band ``B₂``; every line is an independent block of
    its band. ``P⁻¹ = B₁⁻¹ + B₂⁻¹`` — a sum of SPD inverses, so SPD by construction.
    Both are factorized once by banded Cholesky and applied to all columns of the
    residual at once (``whole = True``: :func:`block_cg` calls it once per step on
    every row), by compiled kernels (:mod:`quadnodes.linalg._kernels`) whose inner
    loops run across lines — the column lines across the columns in the nodes' own
    row-major order, the row lines :data:`~quadnodes.linalg._kernels.LANES` at a time
    in a blocked copy — on the solver's threads from :data:`LINES_PARALLEL_MIN_ROWS` nodes.

    Parameters
    ----------
    row_band : (b + 1, n) float64
        ``row_band[b - k, j] = M[j − k, j]`` (zero where ``j − k`` is in another row);
        ``row_band[b]`` is ``M``'s diagonal.
    column_band : (b + 1, n) float64
        ``column_band[b - k, j] = M[j − k·cols, j]`` (zero for ``j < k·cols``), the same diagonal.
    cols : int
        Nodes per grid row (the nodes are in row-major order).

    Raises
    ------
    numpy.linalg.LinAlgError
        If a block is not positive definite.
    ValueError
        If the bands' shapes do not make a grid of ``cols`` columns.

    Examples
    --------
    Two families on a 4 × 4 grid: rows and columns of a Laplacian-like matrix.

    >>> T = sp.diags([-1.0, 2.2, -1.0], [-1, 0, 1], shape=(4, 4))
    >>> M = sp.kronsum(T, T).tocsr()
    >>> rows = np.vstack([np.r_[0, M.diagonal(1)], M.diagonal()])
    >>> cols = np.vstack([np.r_[np.zeros(4), M.diagonal(4)], M.diagonal()])
    >>> P = LinePreconditioner(rows, cols, 4)
    >>> R = np.zeros((1, 64)); R[0, :16] = 1.0; Z = np.empty_like(R)
    >>> P.apply(R, Z, 0, 64, True)
    >>> bool(np.all(Z[0, :16] > 0)), bool(np.all(Z[0, 16:] == 0))
    (True, True)
    """

    whole = True
    blas_free = True  # (compiled sweeps: block_cg need not pin BLAS)

    def __init__(self, row_band: np.ndarray, column_band: np.ndarray, cols: int) -> None:
        from ._kernels import LANES, blocked_lines, strided_band_cholesky

        self.n = n = row_band.shape[1]
        self.cols = cols = int(cols)
        if cols < 1 or n % cols or column_band.shape != row_band.shape:
            raise ValueError(f"bands of shapes {row_band.shape} and {column_band.shape} do not make rows of {cols}")
        self.rows = rows = n // cols
        kd = row_band.shape[0] - 1
        # the row lines in blocks of LANES lines side by side (padded with identity lines)
        A1 = np.concatenate([blocked_lines(row_band[:kd], cols, 0.0), blocked_lines(row_band[kd:], cols, 1.0)])
        F1 = np.empty_like(A1)
        per_block = cols * LANES
        for blk in range(A1.shape[1] // per_block):
            bad = strided_band_cholesky(A1, F1, LANES, cols, blk * per_block, 0, LANES)
            if bad >= 0:
                raise np.linalg.LinAlgError(f"the row lines' block is not positive definite (blocked node {bad})")
        F2 = np.empty_like(column_band)
        bad = strided_band_cholesky(np.ascontiguousarray(column_band), F2, cols, rows, 0, 0, cols)
        if bad >= 0:
            raise np.linalg.LinAlgError(f"the column lines' block is not positive definite (node {bad})")
        self._first, self._dinv1 = F1, 1.0 / F1[kd]
        self._second, self._dinv2 = F2, 1.0 / F2[kd]
        self._scratch: np.ndarray | None = None
        t = _threads.thread_count() if n >= LINES_PARALLEL_MIN_ROWS else 1
        self._row_ranges = [(a * LANES, b * LANES) for a, b in _threads.split_ranges(-(-rows // LANES), parts=t)]
        self._col_ranges = _threads.split_ranges(cols, parts=t)

    def apply(self, R: np.ndarray, Z: np.ndarray, lo: int, hi: int, columns: bool) -> None:
        """``Z = P⁻¹ R`` on every row (``lo``, ``hi`` are ignored: the solves run along whole lines)."""
        from ._kernels import LANES, row_line_solve, strided_line_solve

        n, rows, cols = self.n, self.rows, self.cols
        if not columns or not (R.flags.c_contiguous and Z.flags.c_contiguous):
            Rc = np.ascontiguousarray(R[:n].T if not columns else R[:, :n])
            Zc = np.empty(Rc.shape)
        else:
            Rc, Zc = R, Z  # (c, kp): the kernels use the first n of every row
        c = Rc.shape[0]
        size = len(self._row_ranges) * c * cols * LANES
        if self._scratch is None or self._scratch.size != size:
            self._scratch = np.empty(size)
        F1, d1, F2, d2 = self._first, self._dinv1, self._second, self._dinv2
        blocks = [self._scratch[i * c * cols * LANES : (i + 1) * c * cols * LANES].reshape(c, cols, LANES)
                  for i in range(len(self._row_ranges))]
        # the column lines first, solved in place in Z; then the row lines, added block by block
        _threads.run_tasks(lambda ab, _: strided_line_solve(F2, d2, cols, Rc, Zc, Zc, ab[0], ab[1], False),
                           [((a, b), None) for a, b in self._col_ranges])
        _threads.run_tasks(lambda ab, B: row_line_solve(F1, d1, cols, rows, Rc, B, Zc, ab[0], ab[1], True),
                           list(zip(self._row_ranges, blocks)))
        if Zc is Z:
            Z[:, n:] = 0.0
        elif columns:
            Z[:, :n] = Zc
            Z[:, n:] = 0.0
        else:
            Z[:n] = Zc.T
            Z[n:] = 0.0
