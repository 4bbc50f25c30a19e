"""Columns and blocks of the inverse of a factorized sparse matrix, many at a time.

SciPy's SuperLU ``solve`` treats a block of right-hand sides one column after
another (at 300² a column costs 35–90 ms whatever the block's width), so
``P⁻¹[:, cols]`` for hundreds of columns is slow through it. Here the
triangular factors are swept once per block of :data:`BLOCK` columns by a
compiled kernel (Numba, as :mod:`quadnodes.linalg._kernels`): every entry of
``L`` and ``U`` is read once per block and applied to a row of the block, so the
cost per column falls with the block's width. CHOLMOD (when
:mod:`quadnodes.linalg.direct` used it) solves blocks well by itself and is
called directly.

:class:`InverseBlock` keeps ``M⁻¹[S][:, S]`` for a growing index set ``S``
without whole columns: with ``Pr A Pc = L U`` (SuperLU),
``A⁻¹[i, j] = (U⁻ᵀ e_{pc[i]})ᵀ (L⁻¹ e_{pr[j]})``, and both factors are *forward*
sweeps of unit vectors, which reach only the elimination-tree ancestors of their
index (on a 300² grid in nested-dissection order a few thousand of 90,000 rows).
The two sparse vectors of every index are kept, so adding indices costs their
sweeps and one sparse product.

Examples
--------
>>> import scipy.sparse as sp
>>> from quadnodes.linalg import factorize
>>> M = sp.csc_matrix(np.array([[4.0, 1.0, 0.0], [1.0, 3.0, 1.0], [0.0, 1.0, 2.0]]))
>>> C = inverse_columns(factorize(M, kind="spd"), np.array([0, 2]))
>>> np.allclose(C, np.linalg.inv(M.toarray())[:, [0, 2]])
True
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import InputError
from .direct import Factorization

__all__ = ["inverse_columns", "InverseBlock", "BLOCK", "COMPILED_MIN", "SWEEP_MIN"]

#: Columns swept together through the triangular factors.
BLOCK = 16
#: Below this many entries of the result (rows × columns) SciPy's own solve is used (no compiled kernel loaded).
COMPILED_MIN = 2_000_000
#: :class:`InverseBlock` sweeps the factors (compiled) from this many unknowns, or when the compiled kernels are
#: loaded already; below, plain solves (at 100² about 2 ms per column, against a second to load Numba).
SWEEP_MIN = 40_000


def inverse_columns(f: Factorization, cols: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
    """``M⁻¹[rows][:, cols]`` of a factorized ``(n, n)`` matrix ``M``.

    Parameters
    ----------
    f : Factorization
        From :func:`~quadnodes.linalg.factorize`.
    cols : (c,) int
        Columns of ``M⁻¹`` wanted.
    rows : (r,) int, optional
        Rows kept of each column (default: all ``n``).

    Returns
    -------
    (r, c) float64

    Raises
    ------
    InputError
        If an index is out of range or the result is not finite.
    """
    n = f.shape[0]
    cols = np.asarray(cols, dtype=np.int64)
    rows = np.arange(n) if rows is None else np.asarray(rows, dtype=np.int64)
    for name, idx in (("cols", cols), ("rows", rows)):
        if idx.ndim != 1 or (idx.size and (idx.min() < 0 or idx.max() >= n)):
            raise InputError(f"{f.what}: {name} must be indices in range({n})")
    out = np.empty((rows.size, cols.size))
    lu = f._lu
    compiled = (f.backend == "superlu" and n * cols.size >= COMPILED_MIN and _kernel() is not None)
    width = BLOCK if compiled or f.backend == "cholmod" else 3  # SciPy: 3 per call was cheapest per column
    factors = _superlu_factors(f) if compiled else None
    for a in range(0, cols.size, width):
        c = cols[a:a + width]
        if factors is not None:
            out[:, a:a + c.size] = _sweep(factors, c, n)[rows]
        else:
            e = np.zeros((n, c.size))
            e[c, np.arange(c.size)] = 1.0
            out[:, a:a + c.size] = f.solve(e)[rows]
    if not np.isfinite(out).all():
        raise InputError(f"{f.what}: the linear system is numerically singular (the solution is not finite)")
    return out


def _compiled_ready() -> bool:
    from . import compiled

    return compiled.ready()


def _kernel() -> Any:
    try:
        from . import _trisolve
    except ImportError:  # pragma: no cover - Numba missing: SciPy's solve remains
        return None
    return _trisolve


def _superlu_factors(f: Factorization) -> tuple:
    """``L`` (strictly lower, CSC), ``U`` (strictly upper, CSC), ``U``'s diagonal and the permutations that map
    a right-hand side of ``M`` onto the factors' rows (``r``) and their solution back (``q``)."""
    import scipy.sparse as sp

    lu = f._lu
    L = sp.tril(lu.L, k=-1, format="csc")
    U = lu.U.tocsc()
    diag = U.diagonal().copy()
    U = sp.triu(U, k=1, format="csc")
    n = f.shape[0]
    # SuperLU: Pr A Pc = L U with Pr[perm_r[i], i] = 1 and Pc[i, perm_c[i]] = 1, A = M[p][:, p] (p: f's order)
    p = np.arange(n) if f._perm is None else f._perm
    r = np.empty(n, dtype=np.int64)
    r[lu.perm_r] = np.arange(n)  # (Pr b)[k] = b[r[k]]
    pc = np.asarray(lu.perm_c, dtype=np.int64)
    # b of M maps to b[p] of A; A's solution x_A = Pc w, i.e. x_A[j] = w[pc[j]]; M's solution x[p] = x_A
    return (L.indptr.astype(np.int64), L.indices.astype(np.int64), L.data, U.indptr.astype(np.int64),
            U.indices.astype(np.int64), U.data, diag, p[r], p, pc)


def _sweep(factors: tuple, cols: np.ndarray, n: int) -> np.ndarray:
    """The columns ``cols`` of ``M⁻¹`` (all rows) by one forward and one backward sweep over the factors."""
    from . import _trisolve

    lp, li, lv, up, ui, uv, diag, into, p, pc = factors
    # right-hand side e_c of M, in the factors' row order: row k holds b[into[k]]
    pos = np.empty(n, dtype=np.int64)
    pos[into] = np.arange(n)
    w = np.zeros((n, cols.size))
    w[pos[cols], np.arange(cols.size)] = 1.0
    _trisolve.forward_sweep(lp, li, lv, None, w)
    _trisolve.upper_sweep(up, ui, uv, diag, w)
    x = np.empty_like(w)
    x[p] = w[pc]
    return x


class InverseBlock:
    """``M⁻¹[S][:, S]`` of a factorized matrix for an index set ``S`` that grows (:meth:`extend`).

    Attributes
    ----------
    index : (s,) int
        ``S`` in the order of :attr:`block`'s rows and columns.
    block : (s, s) float64
        ``M⁻¹[S][:, S]`` (for a symmetric ``M`` symmetric up to rounding).

    Examples
    --------
    >>> import scipy.sparse as sp
    >>> from quadnodes.linalg import factorize
    >>> M = sp.csc_matrix(np.array([[4.0, 1.0, 0.0], [1.0, 3.0, 1.0], [0.0, 1.0, 2.0]]))
    >>> inv = InverseBlock(factorize(M, kind="spd"))
    >>> inv.extend(np.array([2])); inv.extend(np.array([0]))
    >>> np.allclose(inv.block, np.linalg.inv(M.toarray())[np.ix_([2, 0], [2, 0])])
    True
    """

    def __init__(self, f: Factorization) -> None:
        self._f = f
        n = f.shape[0]
        self.index = np.zeros(0, dtype=np.int64)
        self.block = np.zeros((0, 0))
        # loading Numba costs about a second per process: below SWEEP_MIN unknowns plain solves are cheaper
        self._sweeps = f.backend == "superlu" and (n >= SWEEP_MIN or _compiled_ready()) and _kernel() is not None
        if self._sweeps:
            import scipy.sparse as sp

            lu = f._lu
            L = lu.L  # CSC with its unit diagonal stored (the sweeps skip diagonal entries)
            self._L = (L.indptr.astype(np.int64), L.indices.astype(np.int64), L.data)
            U = lu.U
            self._diag = U.diagonal()
            U = U.tocsr()
            self._Ut = (U.indptr.astype(np.int64), U.indices.astype(np.int64), U.data)
            p = np.arange(n) if f._perm is None else f._perm
            pinv = np.empty(n, dtype=np.int64)
            pinv[p] = np.arange(n)  # M index i is row pinv[i] of A = M[p][:, p]
            self._row = np.asarray(lu.perm_c, dtype=np.int64)[pinv]  # A⁻¹[i, j] = B⁻¹[pc[i], pr[j]]
            self._col = np.asarray(lu.perm_r, dtype=np.int64)[pinv]
            self._Z: Any = sp.csc_matrix((n, 0))
            self._Y: Any = sp.csc_matrix((n, 0))

    def extend(self, idx: np.ndarray) -> None:
        """Add the indices ``idx`` (not yet in :attr:`index`) to ``S``; :attr:`block` grows by their rows and columns.

        Raises
        ------
        InputError
            If an index is out of range or the result is not finite.
        """
        idx = np.asarray(idx, dtype=np.int64)
        n = self._f.shape[0]
        if idx.ndim != 1 or (idx.size and (idx.min() < 0 or idx.max() >= n)):
            raise InputError(f"{self._f.what}: indices must be in range({n})")
        old = self.index.size
        S2 = np.concatenate([self.index, idx])
        if self._sweeps:
            import scipy.sparse as sp

            from . import _trisolve

            Zs, Ys = [], []
            for a in range(0, idx.size, BLOCK):
                c = idx[a:a + BLOCK]
                W = np.zeros((n, c.size))
                W[self._row[c], np.arange(c.size)] = 1.0
                _trisolve.forward_sweep(*self._Ut, self._diag, W)
                Zs.append(_sparse(W))
                W = np.zeros((n, c.size))
                W[self._col[c], np.arange(c.size)] = 1.0
                _trisolve.forward_sweep(*self._L, None, W)
                Ys.append(_sparse(W))
            Zn, Yn = sp.hstack(Zs, format="csc"), sp.hstack(Ys, format="csc")
            Z2 = sp.hstack([self._Z, Zn], format="csc")
            right = (Z2.T @ Yn).toarray()  # M⁻¹[S2, new]
            lower = (Zn.T @ self._Y).toarray()  # M⁻¹[new, old]
            self._Z, self._Y = Z2, sp.hstack([self._Y, Yn], format="csc")
        else:
            right = inverse_columns(self._f, idx, S2)
            lower = right[:old].T  # a symmetric M (CHOLMOD serves SPD matrices only)
        G = np.empty((S2.size, S2.size))
        G[:old, :old] = self.block
        G[:, old:] = right
        G[old:, :old] = lower
        if not np.isfinite(G).all():
            raise InputError(f"{self._f.what}: the linear system is numerically singular (the solution is not finite)")
        self.index, self.block = S2, G


def _sparse(W: np.ndarray) -> Any:
    """A swept block as a CSC matrix, read only on the rows it reached (``csc_matrix(W)`` scans every entry)."""
    import scipy.sparse as sp

    r = np.flatnonzero(W.any(axis=1))
    i, j = np.nonzero(W[r])
    return sp.csc_matrix((W[r[i], j], (r[i], j)), shape=W.shape)
