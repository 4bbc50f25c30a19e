"""Diagonal storage for the normal matrix of an operator along the lines of a structured grid.

On a ``rows × cols`` grid whose every row of ``A`` couples four consecutive nodes
of one grid line, ``AᵀA + ωI`` has 13 diagonals (offsets 0, ±1, ±2, ±3, ±cols,
±2 cols, ±3 cols). A grid closed around (a cylinder or torus, whose lines are
closed and whose windows wrap across the seam) adds the periodic diagonals
``±(cols − d)`` (rows closed) and ``±(n − d·cols)`` (columns closed), ``d = 1, 2, 3``.
:class:`GridPattern` computes once where each entry goes;
:meth:`GridPattern.normal_matrix` then fills the diagonals for any coefficients,
with nodes outside the unknowns as identity rows.

An open or closed grid whose operator rows come line by line in a known order
(:meth:`GridPattern.open_grid`, :meth:`GridPattern.closed_grid`) needs no walk at all: the diagonals are sums of
shifted products of the coefficients laid out per line, computed on grid-shaped
arrays (about 20 passes over the nodes, no gather, no scatter).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from . import compiled, threads

__all__ = ["GridPattern"]


def _diagonals(n: int, cols: int, wrap_rows: bool, wrap_cols: bool) -> tuple[list[int], list[tuple[int, int, int, int]]]:
    """The storage's offsets, and per pair ``d`` apart across a closed line's seam ``(d, b − a, slot of M[a, b],
    slot of M[b, a])``: the rows' (``wrap_cols``) periodic slots first, then the columns'.

    Raises
    ------
    ValueError
        When two diagonals would share an offset (fewer than 7 nodes along a closed direction).
    """
    offsets = [-3 * cols, -2 * cols, -cols, -3, -2, -1, 0, 1, 2, 3, cols, 2 * cols, 3 * cols]
    seam: list[tuple[int, int, int, int]] = []
    for closed, period, step in ((wrap_cols, cols, 1), (wrap_rows, n, cols)):
        if closed:
            for d in (1, 2, 3):
                seam.append((d, d * step - period, len(offsets), len(offsets) + 1))
                offsets += [d * step - period, period - d * step]
    if len(set(offsets)) != len(offsets):
        raise ValueError(f"GridPattern: a {n // cols} x {cols} grid closed around is too small for distinct "
                         "diagonals (at least 7 nodes along every closed direction)")
    return offsets, seam


class GridPattern:
    """Where every entry of a grid's line operator ``AᵀA`` goes in diagonal storage (pattern only).

    The unknowns are the ``n`` nodes of a ``rows × cols`` grid in row-major order;
    every row of ``A`` couples four consecutive nodes of one grid line (a row: steps
    of 1, or a column: steps of ``cols``). ``ext`` lays every line out contiguously
    (one node sequence, all lines after one another), ``start`` lists the positions
    in ``ext`` where a 4-node row of ``A`` begins, in the order of ``A``'s rows.
    If some row of ``A`` is not along a grid line, :attr:`valid` is False. (A grid whose rows of ``A`` come whole
    lines at a time in a known order needs no walk: :meth:`open_grid`, :meth:`closed_grid`.)

    Entry ``(ext[q], ext[q+d])`` of the window walk ``ext`` sums ``c_i c_{i+d}`` over
    the (up to ``4 - d``) windows that hold both positions; ``q[d]`` lists those
    positions and ``target[d]`` their places in the flattened ``(13, n)`` diagonals
    (for ``d > 0`` the entry above and its mirror below the main diagonal; for ``d = 0``
    the vertex, whose diagonal entries are summed). Made once
    per mesh and reused by every iteration and every weight.
    """

    def __init__(self, ext: np.ndarray, start: np.ndarray, n: int, cols: int, *, wrap_rows: bool = False,
                 wrap_cols: bool = False) -> None:
        m = ext.size
        #: ``(wrap_rows, wrap_cols)``: whether the grid's columns (row index) and rows (column index) close around.
        self.wrap = (bool(wrap_rows), bool(wrap_cols))
        offsets, seam = _diagonals(n, cols, *self.wrap)
        idx = np.int32 if len(offsets) * n < 2**31 - 1 else np.int64  # (kept per mesh: half the memory of int64)
        starts = np.zeros(m, dtype=bool)
        starts[start] = True
        self.valid = True
        # a closed line's walk repeats its first three nodes, so a pair near its start sits at two places
        # of the walk (each holding some of its windows): those entries are summed, not written
        self.summed = bool(seam)
        self.blocks: tuple[tuple[int, int, int], ...] | None = None
        self.q: list[np.ndarray] = []
        self.target: list[tuple[np.ndarray, ...]] = []
        for d in range(4):
            held = np.zeros(m, dtype=bool)  # a window holds positions q and q + d
            for i in range(4 - d):
                held[i:] |= starts[: m - i]
            q = np.flatnonzero(held[: m - d]).astype(idx)
            a, b = ext[q].astype(idx), ext[q + d].astype(idx)
            if d == 0:
                self.q.append(q)
                self.target.append((a,))
                continue
            row = b - a == d
            col = b - a == d * cols
            up = np.where(row, 6 + d, 9 + d)  # M[a, b] at column b in slot up
            down = 12 - up  # M[b, a] at column a
            ok = row | col
            for sd, delta, s_up, s_down in seam:
                if sd == d:
                    across = b - a == delta
                    up = np.where(across, s_up, up)
                    down = np.where(across, s_down, down)
                    ok |= across
            if not ok.all():  # not along rows (+1), columns (+cols) or across a seam
                self.valid = False
                return
            self.q.append(q)
            up, down = up.astype(idx), down.astype(idx)
            self.target.append((up * idx(n) + b, down * idx(n) + a))
        self.offsets = np.array(offsets)
        self.n, self.start, self.ext, self.cols = n, start, ext, cols

    @classmethod
    def open_grid(cls, rows: int, cols: int, blocks: Sequence[tuple[int, int, int]]) -> GridPattern:
        """The pattern of an open ``rows × cols`` grid whose operator rows come whole lines at a time.

        ``blocks`` lists ``A``'s rows in order as ``(family, first, count)``: ``count``
        consecutive grid rows (``family`` 0, nodes ``i*cols … i*cols + cols-1``) or grid
        columns (``family`` 1, nodes ``j, j + cols, …``) from line ``first`` on, each line
        giving its ``L - 3`` windows in order along it (``L`` its number of nodes). The
        blocks must cover every row and every column once (``cols ≥ 4``).

        Raises
        ------
        ValueError
            When the blocks do not cover each line of both families exactly once, or ``cols < 4``.

        Examples
        --------
        >>> p = GridPattern.open_grid(4, 5, [(0, 0, 1), (1, 0, 5), (0, 1, 3)])
        >>> p.offsets.tolist()
        [-15, -10, -5, -3, -2, -1, 0, 1, 2, 3, 5, 10, 15]
        """
        return cls._laid_out(rows, cols, blocks, False, False)

    @classmethod
    def closed_grid(cls, rows: int, cols: int, blocks: Sequence[tuple[int, int, int]], *, wrap_rows: bool = False,
                    wrap_cols: bool = False) -> GridPattern:
        """The pattern of a cylinder or torus grid whose operator rows come whole lines at a time.

        As :meth:`open_grid`, but the grid's rows are closed where ``wrap_cols`` (node ``i*cols + cols-1`` joins
        ``i*cols``) and its columns where ``wrap_rows``: a closed line of ``L`` nodes gives ``L`` windows in order
        along it, window ``j`` holding its nodes ``j, j+1, j+2, j+3`` (mod ``L``) — the layout of
        :attr:`~quadnodes.topology.Topology.window_walk` on such a grid. The storage gets the periodic diagonals
        ``±(cols − d)`` and ``±(n − d·cols)`` (``d = 1, 2, 3``) for the entries across a seam; as on an open grid it
        is computed on grid-shaped arrays (shifted products, no walk, no gather).

        Raises
        ------
        ValueError
            As :meth:`open_grid`, and when a closed direction has fewer than 7 nodes (the periodic diagonals would
            share offsets with the others).

        Examples
        --------
        >>> p = GridPattern.closed_grid(4, 8, [(0, 0, 1), (1, 0, 8), (0, 1, 3)], wrap_cols=True)  # rings of 8
        >>> p.offsets[13:].tolist(), p.wrap
        ([-7, 7, -6, 6, -5, 5], (False, True))
        """
        return cls._laid_out(rows, cols, blocks, bool(wrap_rows), bool(wrap_cols))

    @classmethod
    def _laid_out(cls, rows: int, cols: int, blocks: Sequence[tuple[int, int, int]], wrap_rows: bool,
                  wrap_cols: bool) -> GridPattern:
        """:meth:`open_grid` and :meth:`closed_grid`."""
        name = "closed_grid" if wrap_rows or wrap_cols else "open_grid"
        if cols < 4 or rows < 2:
            raise ValueError(f"GridPattern.{name}: a {rows} x {cols} grid has no distinct diagonals")
        seen = [np.zeros(rows, dtype=np.int64), np.zeros(cols, dtype=np.int64)]
        for family, first, count in blocks:
            seen[family][first : first + count] += 1
        if not all((s == 1).all() for s in seen) or sum(c for _, _, c in blocks) != rows + cols:
            raise ValueError(f"GridPattern.{name}: the blocks must cover every row and column once")
        self = cls.__new__(cls)
        offsets, _ = _diagonals(rows * cols, cols, wrap_rows, wrap_cols)
        self.offsets = np.array(offsets)
        self.n, self.rows, self.cols = rows * cols, rows, cols
        self.valid, self.summed = True, False
        self.wrap = (wrap_rows, wrap_cols)
        self.blocks = tuple((int(f), int(a), int(c)) for f, a, c in blocks)
        return self

    def _line_windows(self, family: int) -> tuple[int, int, bool]:
        """``(L, k, closed)`` of a line of ``family`` (0: grid rows, 1: grid columns): its nodes, its windows and
        whether it closes around."""
        length = self.cols if family == 0 else self.rows
        closed = self.wrap[1] if family == 0 else self.wrap[0]
        return length, (length if closed else max(length - 3, 0)), closed

    def _laid_out_normal_matrix(self, coef: np.ndarray, free: np.ndarray, weight: float) -> np.ndarray:
        """:meth:`normal_matrix`'s data for :meth:`open_grid` and :meth:`closed_grid`: shifted products on
        grid-shaped arrays."""
        rows, cols, n = self.rows, self.cols, self.n
        expected = sum(count * self._line_windows(family)[1] for family, _, count in self.blocks)
        if len(coef) != expected:
            raise ValueError(f"coef: expected {expected} rows for this grid, got {len(coef)}")
        if compiled.ready():  # one pass per family, the same numbers to the bit
            return self._compiled_laid_out_normal_matrix(coef, free, weight)
        F = free.reshape(rows, cols).astype(np.float64)
        # upper[f][d][l, x]: entry (node x of line l, node x + d of line l — mod L on a closed line) of family f's
        # AᵀA, lines as rows
        upper = [np.zeros((4, rows, cols)), np.zeros((4, cols, rows))]
        lines_free = (F, F.T)
        pos = 0
        for family, first, count in self.blocks:
            _, k, closed = self._line_windows(family)
            c = coef[pos : pos + count * k].reshape(count, k, 4)
            pos += count * k
            if k == 0:
                continue
            on = lines_free[family][first : first + count]
            u = upper[family][:, first : first + count]
            if closed:  # window j's slot i is node j + i (mod L): a fixed node drops out
                c = np.stack([c[:, :, i] * np.roll(on, -i, axis=1) for i in range(4)])
                for d in range(4):
                    for i in range(4 - d):
                        u[d] += np.roll(c[i] * c[i + d], i, axis=1)
                continue
            c = np.stack([c[:, :, i] * on[:, i : i + k] for i in range(4)])  # a fixed node drops out
            for d in range(4):
                for i in range(4 - d):
                    u[d][:, i : i + k] += c[i] * c[i + d]
        data = np.zeros((self.offsets.size, rows, cols))
        ur, uc = upper[0], upper[1].transpose(0, 2, 1)  # both as (4, rows, cols)
        data[6] = ur[0] + uc[0]
        data[6] += np.where(free, weight, 1.0).reshape(rows, cols)
        for d in (1, 2, 3):
            data[6 + d][:, d:] = ur[d][:, : cols - d]  # M[a, a + d] stored at column a + d
            data[6 - d][:, : cols - d] = ur[d][:, : cols - d]  # M[a + d, a] stored at column a
            data[9 + d][d:] = uc[d][: rows - d]
            data[3 - d][: rows - d] = uc[d][: rows - d]
        seam = 13
        for d in (1, 2, 3):  # across a seam: node a near a line's end, b = a + d − L near its start
            if self.wrap[1]:
                up = seam + 2 * (d - 1)
                data[up][:, :d] = ur[d][:, cols - d :]  # M[a, b] at column b
                data[up + 1][:, cols - d :] = ur[d][:, cols - d :]  # M[b, a] at column a
            if self.wrap[0]:
                up = seam + 6 * self.wrap[1] + 2 * (d - 1)
                data[up][:d] = uc[d][rows - d :]
                data[up + 1][rows - d :] = uc[d][rows - d :]
        return data.reshape(-1, n)

    def _compiled_laid_out_normal_matrix(self, coef: np.ndarray, free: np.ndarray, weight: float) -> np.ndarray:
        """:meth:`_laid_out_normal_matrix` by :func:`quadnodes.linalg._kernels.grid_family` (lines split over
        threads)."""
        from ._kernels import grid_family

        rows, cols, n = self.rows, self.cols, self.n
        first = [np.zeros(rows, dtype=np.int64), np.zeros(cols, dtype=np.int64)]
        pos = 0
        for family, line, count in self.blocks:
            k = self._line_windows(family)[1]
            first[family][line : line + count] = pos + k * np.arange(count)
            pos += count * k
        coef = np.ascontiguousarray(coef, dtype=np.float64)
        F = free.astype(np.float64)
        data = np.zeros((self.offsets.size, n))
        t = min(threads.thread_count(), max(1, n // threads.PARALLEL_MIN_ROWS))  # (counted by nodes, cut by lines)
        seams = (13, 13 + 6 * self.wrap[1])  # each family's first periodic slot (used where its lines close)
        for family in (0, 1):  # (family 1 adds to the main diagonal family 0 wrote)
            closed = self._line_windows(family)[2]
            ranges = threads.split_ranges(rows if family == 0 else cols, parts=t, align=16)  # (its column tile)
            args = (coef, first[family], F, rows, cols, family, closed, seams[family], float(weight), data)
            threads.run_tasks(grid_family, [args + r for r in ranges])
        return data

    def normal_matrix(self, coef: np.ndarray, free: np.ndarray, weight: float) -> tuple[np.ndarray, np.ndarray]:
        """``AᵀA + ωI`` in the grid's numbering as ``(offsets, data)``; other rows and columns are the identity's.

        A node outside the unknowns drops out of every row of ``A``, so the block
        of the unknowns is exactly their system. Shifted products along the
        walk: no sparse product and no sort.

        Parameters
        ----------
        coef : (w, 4) float64
            Coefficients of every row of ``A`` (its nodes ``ext[start[i] : start[i] + 4]``).
        free : (n,) bool
            The unknowns; the other nodes get identity rows and columns.
        weight : float
            ``ω``, added on the unknowns' diagonal.

        Returns
        -------
        offsets : (13,) int64, or (19,) / (25,) on a grid closed in one / both directions
        data : (len(offsets), n) float64
            ``data[d, j] = M[j - offsets[d], j]`` (SciPy's ``dia_matrix`` layout).

        Examples
        --------
        >>> ext = np.arange(12); start = np.array([0, 4, 8])  # a 3 × 4 grid: three rows of 4
        >>> p = GridPattern(ext, start, 12, 4)
        >>> off, data = p.normal_matrix(np.tile([-1.0, 3, -3, 1], (3, 1)), np.ones(12, bool), 0.5)
        >>> import scipy.sparse as sp
        >>> M = sp.dia_matrix((data, off), shape=(12, 12)).toarray()
        >>> float(M[0, 0]), float(M[1, 1]), float(M[0, 3]), bool((M == M.T).all())
        (1.5, 9.5, -1.0, True)
        """
        if self.blocks is not None:
            return self.offsets, self._laid_out_normal_matrix(coef, free, weight)
        n, m, start = self.n, self.ext.size, self.start
        on = free[self.ext]
        C = np.zeros((4, m))
        C[:, start] = coef.T
        for i in range(4):
            C[i, : m - i] *= on[i:]  # slot i of the window at s is ext[s + i]
        data = np.zeros((self.offsets.size, n))
        flat = data.reshape(-1)
        val = np.empty(m)
        for d in range(4):
            np.multiply(C[0], C[d], out=val)
            for i in range(1, 4 - d):
                val[i:] += C[i, : m - i] * C[i + d, : m - i]
            v = np.take(val, self.q[d])
            if d == 0:
                data[6] = np.bincount(self.target[0][0], weights=v, minlength=n)
            elif self.summed:
                flat += np.bincount(self.target[d][0], weights=v, minlength=flat.size)
                flat += np.bincount(self.target[d][1], weights=v, minlength=flat.size)
            else:
                flat[self.target[d][0]] = v
                flat[self.target[d][1]] = v
        data[6] += np.where(free, weight, 1.0)
        return self.offsets, data
