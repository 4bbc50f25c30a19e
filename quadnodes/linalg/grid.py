"""Diagonal storage for the normal matrix of an operator along the lines of a structured grid.

On a ``rows × cols`` grid whose every row of ``A`` couples four consecutive nodes
of one grid line, ``AᵀA + ωI`` has 13 diagonals (offsets 0, ±1, ±2, ±3, ±cols,
±2 cols, ±3 cols). A grid closed around (a cylinder or torus, whose lines are
closed and whose windows wrap across the seam) adds the periodic diagonals
``±(cols − d)`` (rows closed) and ``±(n − d·cols)`` (columns closed), ``d = 1, 2, 3``.
:class:`GridPattern` computes once where each entry goes;
:meth:`GridPattern.normal_matrix` then fills the diagonals for any coefficients,
with nodes outside the unknowns as identity rows.

An open grid whose operator rows come line by line in a known order
(:meth:`GridPattern.open_grid`) needs no walk at all: the diagonals are sums of
shifted products of the coefficients laid out per line, computed on grid-shaped
arrays (about 20 passes over the nodes, no gather, no scatter).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from . import compiled, threads

__all__ = ["GridPattern"]


class GridPattern:
    """Where every entry of a grid's line operator ``AᵀA`` goes in diagonal storage (pattern only).

    The unknowns are the ``n`` nodes of a ``rows × cols`` grid in row-major order;
    every row of ``A`` couples four consecutive nodes of one grid line (a row: steps
    of 1, or a column: steps of ``cols``). ``ext`` lays every line out contiguously
    (one node sequence, all lines after one another), ``start`` lists the positions
    in ``ext`` where a 4-node row of ``A`` begins, in the order of ``A``'s rows.
    If some row of ``A`` is not along a grid line, :attr:`valid` is False. On a grid closed around, the storage
    takes a shortcut (:attr:`repeats`) where ``ext`` and ``start`` are laid out as
    :attr:`~quadnodes.topology.Topology.window_walk` lays them out, and sums every entry otherwise.

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
        offsets = [-3 * cols, -2 * cols, -cols, -3, -2, -1, 0, 1, 2, 3, cols, 2 * cols, 3 * cols]
        # a pair d apart along a closed line, across its seam: (d, b - a, slot of M[a, b], slot of M[b, a])
        seam: list[tuple[int, int, int, int]] = []
        for closed, period, step in ((wrap_cols, cols, 1), (wrap_rows, n, cols)):
            if closed:
                for d in (1, 2, 3):
                    seam.append((d, d * step - period, len(offsets), len(offsets) + 1))
                    offsets += [d * step - period, period - d * step]
        if len(set(offsets)) != len(offsets):
            raise ValueError(f"GridPattern: a {n // cols} x {cols} grid closed around is too small for distinct "
                             "diagonals (at least 7 nodes along every closed direction)")
        idx = np.int32 if len(offsets) * n < 2**31 - 1 else np.int64  # (kept per mesh: half the memory of int64)
        starts = np.zeros(m, dtype=bool)
        starts[start] = True
        self.valid = True
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
        # a closed line's walk repeats its first three nodes, so a pair near its start sits at two places
        # of the walk (each holding some of its windows): those entries are summed, not written
        self.summed = bool(seam)
        self.blocks: tuple[tuple[int, int, int], ...] | None = None
        #: per ``d > 0``, where :attr:`summed`: ``(head, partner)`` indices into ``q[d]`` — the pairs in a closed
        #: line's repeated head and the same pairs at the line's start (one target, two places); None where the
        #: walk is not laid out so (then every pair's entry is summed by bincount)
        self.repeats: list[tuple[np.ndarray, np.ndarray]] | None = self._repeats() if seam else None

    def _repeats(self) -> list[tuple[np.ndarray, np.ndarray]] | None:
        """:attr:`repeats` from the walk: a line's windows start at consecutive places, and a closed line's last
        window reaches three places past its ``L`` nodes, which repeat its first three (``ext``). None unless the
        walk is :attr:`~quadnodes.topology.Topology.window_walk`'s layout — windows in the walk's order, every
        grid line once with all its windows, each closed line's three repeated nodes in place — so that these
        are the only pairs at two places."""
        ext, start, n = self.ext, self.start, self.n
        rows, cols = n // self.cols, self.cols
        if start.size == 0 or not (np.diff(start) > 0).all():
            return None
        wrap_rows, wrap_cols = self.wrap
        windows = rows * (cols if wrap_cols else max(cols - 3, 0)) + cols * (rows if wrap_rows else max(rows - 3, 0))
        if start.size != windows:
            return None
        cut = np.flatnonzero(np.diff(start) != 1)
        first, last = start[np.r_[0, cut + 1]], start[np.r_[cut, start.size - 1]]
        closed = ext[last + 1] == ext[first]
        if int(closed.sum()) != rows * wrap_cols + cols * wrap_rows:
            return None
        length = (last - first + 1)[closed]  # L: a closed line's windows, one per node
        head = last[closed] + 1  # the walk's places of its repeated nodes 0, 1, 2
        if not all(np.array_equal(ext[head + k], ext[first[closed] + k]) for k in range(3)):
            return None
        if np.unique(ext[first] * np.int64(n) + ext[first + 1]).size != first.size:  # (a line twice)
            return None
        out = []
        for d in (1, 2, 3):
            q = self.q[d]
            places = (head[:, None] + np.arange(3 - d)).reshape(-1)  # pairs (k, k + d) with both in the head
            partners = places - np.repeat(length, 3 - d)
            h, p = np.searchsorted(q, places), np.searchsorted(q, partners)
            if (h >= q.size).any() or (p >= q.size).any() or not (np.array_equal(q[h], places)
                                                                 and np.array_equal(q[p], partners)):
                return None
            t = self.target[d]
            if not all(np.array_equal(side[h], side[p]) for side in t):
                return None
            out.append((h, p))
        return out

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
        if cols < 4 or rows < 2:
            raise ValueError(f"GridPattern.open_grid: a {rows} x {cols} grid has no distinct diagonals")
        seen = [np.zeros(rows, dtype=np.int64), np.zeros(cols, dtype=np.int64)]
        for family, first, count in blocks:
            seen[family][first : first + count] += 1
        if not all((s == 1).all() for s in seen) or sum(c for _, _, c in blocks) != rows + cols:
            raise ValueError("GridPattern.open_grid: the blocks must cover every row and column once")
        self = cls.__new__(cls)
        self.offsets = np.array([-3 * cols, -2 * cols, -cols, -3, -2, -1, 0, 1, 2, 3, cols, 2 * cols, 3 * cols])
        self.n, self.rows, self.cols = rows * cols, rows, cols
        self.valid, self.summed = True, False
        self.wrap = (False, False)
        self.blocks = tuple((int(f), int(a), int(c)) for f, a, c in blocks)
        return self

    def _open_normal_matrix(self, coef: np.ndarray, free: np.ndarray, weight: float) -> np.ndarray:
        """:meth:`normal_matrix`'s data for :meth:`open_grid`: shifted products on grid-shaped arrays."""
        rows, cols, n = self.rows, self.cols, self.n
        expected = sum(count * max((cols if family == 0 else rows) - 3, 0) for family, _, count in self.blocks)
        if len(coef) != expected:
            raise ValueError(f"coef: expected {expected} rows for this grid, got {len(coef)}")
        if compiled.ready():  # one pass per family, the same numbers to the bit
            return self._compiled_open_normal_matrix(coef, free, weight)
        F = free.reshape(rows, cols).astype(np.float64)
        # upper[f][d][l, x]: entry (node x of line l, node x + d of line l) of family f's AᵀA, lines as rows
        upper = [np.zeros((4, rows, cols)), np.zeros((4, cols, rows))]
        lines_free = (F, F.T)
        pos = 0
        for family, first, count in self.blocks:
            length = cols if family == 0 else rows
            k = max(length - 3, 0)
            c = coef[pos : pos + count * k].reshape(count, k, 4)
            pos += count * k
            if k == 0:
                continue
            on = lines_free[family][first : first + count]
            c = np.stack([c[:, :, i] * on[:, i : i + k] for i in range(4)])  # a fixed node drops out
            u = upper[family][:, first : first + count]
            for d in range(4):
                for i in range(4 - d):
                    u[d][:, i : i + k] += c[i] * c[i + d]
        data = np.zeros((13, rows, cols))
        ur, uc = upper[0], upper[1].transpose(0, 2, 1)  # both as (4, rows, cols)
        data[6] = ur[0] + uc[0]
        data[6] += np.where(free, weight, 1.0).reshape(rows, cols)
        for d in (1, 2, 3):
            data[6 + d][:, d:] = ur[d][:, : cols - d]  # M[a, a + d] stored at column a + d
            data[6 - d][:, : cols - d] = ur[d][:, : cols - d]  # M[a + d, a] stored at column a
            data[9 + d][d:] = uc[d][: rows - d]
            data[3 - d][: rows - d] = uc[d][: rows - d]
        return data.reshape(13, n)

    def _compiled_open_normal_matrix(self, coef: np.ndarray, free: np.ndarray, weight: float) -> np.ndarray:
        """:meth:`_open_normal_matrix` by :func:`quadnodes.linalg._kernels.open_grid_family` (rows split over threads)."""
        from ._kernels import open_grid_family

        rows, cols, n = self.rows, self.cols, self.n
        first = [np.zeros(rows, dtype=np.int64), np.zeros(cols, dtype=np.int64)]
        pos = 0
        for family, line, count in self.blocks:
            k = max((cols if family == 0 else rows) - 3, 0)
            first[family][line : line + count] = pos + k * np.arange(count)
            pos += count * k
        coef = np.ascontiguousarray(coef, dtype=np.float64)
        F = free.astype(np.float64)
        data = np.zeros((13, n))
        t = min(threads.thread_count(), max(1, n // threads.PARALLEL_MIN_ROWS))  # (counted by nodes, cut by lines)
        for family in (0, 1):  # (family 1 adds to the main diagonal family 0 wrote)
            ranges = threads.split_ranges(rows if family == 0 else cols, parts=t, align=16)  # (its column tile)
            args = (coef, first[family], F, rows, cols, family, float(weight), data)
            threads.run_tasks(open_grid_family, [args + r for r in ranges])
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
            return self.offsets, self._open_normal_matrix(coef, free, weight)
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
            elif self.summed and self.repeats is None:
                flat += np.bincount(self.target[d][0], weights=v, minlength=flat.size)
                flat += np.bincount(self.target[d][1], weights=v, minlength=flat.size)
            else:
                flat[self.target[d][0]] = v
                flat[self.target[d][1]] = v
                if self.summed:  # a closed line's pairs at two places of the walk: their sum, written once
                    head, partner = self.repeats[d - 1]
                    both = v[head] + v[partner]
                    flat[self.target[d][0][head]] = both
                    flat[self.target[d][1][head]] = both
        data[6] += np.where(free, weight, 1.0)
        return self.offsets, data
