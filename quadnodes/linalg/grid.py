"""Diagonal storage for the normal matrix of an operator along the lines of a structured grid.

On a ``rows × cols`` grid whose every row of ``A`` couples four consecutive nodes
of one grid line, ``AᵀA + ωI`` has 13 diagonals (offsets 0, ±1, ±2, ±3, ±cols,
±2 cols, ±3 cols). A grid closed around (a cylinder or torus, whose lines are
closed and whose windows wrap across the seam) adds the periodic diagonals
``±(cols − d)`` (rows closed) and ``±(n − d·cols)`` (columns closed), ``d = 1, 2, 3``.
:class:`GridPattern` computes once where each entry goes;
:meth:`GridPattern.normal_matrix` then fills the diagonals for any coefficients,
with nodes outside the unknowns as identity rows.
"""

from __future__ import annotations

import numpy as np

__all__ = ["GridPattern"]


class GridPattern:
    """Where every entry of a grid's line operator ``AᵀA`` goes in diagonal storage (pattern only).

    The unknowns are the ``n`` nodes of a ``rows × cols`` grid in row-major order;
    every row of ``A`` couples four consecutive nodes of one grid line (a row: steps
    of 1, or a column: steps of ``cols``). ``ext`` lays every line out contiguously
    (one node sequence, all lines after one another), ``start`` lists the positions
    in ``ext`` where a 4-node row of ``A`` begins, in the order of ``A``'s rows.
    If some row of ``A`` is not along a grid line, :attr:`valid` is False.

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
        self.n, self.start, self.ext = n, start, ext
        # a closed line's walk repeats its first three nodes, so a pair near its start sits at two places
        # of the walk (each holding some of its windows): those entries are summed, not written
        self.summed = bool(seam)

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
