"""A grid's line operator with constant coefficients, inverted by discrete cosine and Fourier transforms.

On a vertex grid the fairing matrix is a sum of per-line operators: every structure line's windows
of four consecutive nodes give ``c Dᵀ D`` (``D`` the line's third differences) with coefficients
``c`` that vary from window to window, plus ``ω`` on the diagonal. With one coefficient per family
(rows, columns) and the Neumann Laplacian ``L`` (``−1, 2, −1``; ``1, −1`` at a line's ends) in place of
the line's ``Dᵀ D`` through ``L³``, the operator is ``K = c_r (I ⊗ L³) + c_c (L³ ⊗ I) + ωI``,
which the two-dimensional discrete cosine transform (type II) diagonalizes; along an axis that closes
around (a cylinder or torus grid) the lines are periodic and the Fourier transform does the same with
the circulant ``L``. :class:`SpectralPreconditioner` applies ``K⁻¹`` in ``O(n log n)``, no set-up
but the eigenvalues.

``K`` and the fairing matrix agree up to the coefficients' spread and the lines' ends (``L³`` also
charges a line's first and last slopes and curvatures, which ``Dᵀ D`` leaves free), so preconditioned
conjugate gradients take steps that do not grow with the grid's size: on 300² sheets with broadband
noise 28 at the default weight against plain CG's 90 (``benchmarks/studies/cg_weights.py``). The
ends' mismatch grows as the weight falls, so the steps do too, more slowly than plain CG's.

Examples
--------
>>> P = SpectralPreconditioner((4, 5), (False, False), 1.0, 2.0, 0.5)
>>> R = np.zeros((1, 20)); R[0, 7] = 1.0
>>> Z = np.zeros_like(R)
>>> P.apply(R, Z, 0, 20, True)
>>> bool(np.allclose(P.operator() @ Z[0], R[0], atol=1e-6))  # (single precision)
True
"""

from __future__ import annotations

import sys
from types import ModuleType

import numpy as np
import scipy.sparse as sp

from . import threads as _threads

__all__ = ["SpectralPreconditioner", "line_laplacian", "loaded"]

#: Grids of at least this many nodes transform on the solver's threads (``workers``); below, one thread is
#: faster (300²: 1.5 against 2.3 ms a step, 1000²: 28 against 12 ms, a throwaway timing of ``dctn``/``idctn``).
PARALLEL_MIN_NODES = 250_000


def loaded() -> bool:
    """Whether SciPy's transforms (``scipy.fft``) are imported: using them then costs no import (about 40 ms).

    Returns
    -------
    bool

    Examples
    --------
    >>> import scipy.fft
    >>> loaded()
    True
    """
    return "scipy.fft" in sys.modules


def line_laplacian(n: int, closed: bool = False) -> sp.csr_matrix:
    """The line's Laplacian ``L``: ``−1, 2, −1`` in each row, ``1, −1`` at an open line's ends.

    Parameters
    ----------
    n : int
        Nodes on the line.
    closed : bool
        Whether the line closes around (then ``L`` is circulant).

    Returns
    -------
    (n, n) scipy.sparse.csr_matrix

    Raises
    ------
    ValueError
        If ``n < 1``.

    Examples
    --------
    >>> line_laplacian(3).toarray().tolist()
    [[1.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]]
    >>> line_laplacian(3, closed=True).toarray().tolist()
    [[2.0, -1.0, -1.0], [-1.0, 2.0, -1.0], [-1.0, -1.0, 2.0]]
    """
    if n < 1:
        raise ValueError(f"n: expected at least one node, got {n}")
    if n == 1:
        return sp.csr_matrix((1, 1))
    D = sp.diags([-np.ones(n), np.ones(n - 1)], [0, 1], shape=(n - 1 + closed, n), format="lil")
    if closed:
        D[n - 1, 0] = 1.0
    D = D.tocsr()
    return sp.csr_matrix(D.T @ D)


def _eigenvalues(n: int, transform: str) -> np.ndarray:
    """``L``'s eigenvalues in the order of the transform along the axis (``"dct"``, ``"rfft"`` or ``"fft"``)."""
    if transform == "dct":
        return 2.0 - 2.0 * np.cos(np.pi * np.arange(n) / n)
    k = np.arange(n // 2 + 1 if transform == "rfft" else n)
    return 2.0 - 2.0 * np.cos(2.0 * np.pi * k / n)


class SpectralPreconditioner:
    """``P⁻¹ = S K⁻¹ S`` on a ``rows × cols`` grid in row-major order, by transforms (see the module).

    ``K = c_r (I ⊗ L_r³) + c_c (L_c³ ⊗ I) + ωI`` with ``L`` the Laplacian of a grid row (``cols`` nodes,
    coefficient ``c_r``) or column (``rows`` nodes, ``c_c``), periodic where the axis closes around;
    ``S`` selects the unknowns (fixed nodes' rows of ``Z`` are zero). Symmetric positive definite on
    the unknowns for any ``ω > 0``. Applied to all columns of the residual at once (``whole``), in
    single precision: it only steers the search directions, and halves the transforms' time.

    Parameters
    ----------
    shape : (int, int)
        ``(rows, cols)`` of the grid.
    wrap : (bool, bool)
        Whether the columns (the row index) and the rows (the column index) close around — as
        :attr:`quadnodes.linalg.grid.GridPattern.wrap`.
    row_coefficient, column_coefficient : float
        ``c_r``, ``c_c``: each family's window coefficient, ``≥ 0`` (the magnitude of the matrix's
        ``±3`` and ``±3·cols`` diagonals).
    weight : float
        ``ω > 0``.
    free : (rows · cols,) bool, optional
        The unknowns; default all.

    Raises
    ------
    ValueError
        If the shape, coefficients or weight are out of range.

    Examples
    --------
    On a closed 6 × 4 grid (rows periodic) ``P⁻¹`` inverts ``K``:

    >>> P = SpectralPreconditioner((6, 4), (True, False), 3.0, 1.0, 0.1)
    >>> x = np.random.default_rng(0).normal(size=(2, 24))
    >>> Z = np.zeros_like(x)
    >>> P.apply(x @ P.operator().toarray(), Z, 0, 24, True)
    >>> bool(np.allclose(Z, x, atol=1e-4))
    True
    """

    whole = True  # applied once per step to every row (block_cg)
    blas_free = True  # SciPy's transforms call no BLAS: nothing to pin

    def __init__(self, shape: tuple[int, int], wrap: tuple[bool, bool], row_coefficient: float,
                 column_coefficient: float, weight: float, free: np.ndarray | None = None) -> None:
        rows, cols = (int(s) for s in shape)
        if rows < 1 or cols < 1:
            raise ValueError(f"shape: expected positive sides, got {shape}")
        if not (np.isfinite(weight) and weight > 0):
            raise ValueError(f"weight: expected a positive finite number, got {weight}")
        for name, c in (("row_coefficient", row_coefficient), ("column_coefficient", column_coefficient)):
            if not (np.isfinite(c) and c >= 0):
                raise ValueError(f"{name}: expected a finite number >= 0, got {c}")
        self.shape = (rows, cols)
        self.wrap = (bool(wrap[0]), bool(wrap[1]))
        self.coefficients = (float(row_coefficient), float(column_coefficient))
        self.weight = float(weight)
        # the transform along each axis: orthonormal DCT-II along an open one; along a closed one the real
        # Fourier transform on the real data (done first), a full one on the other closed axis after it
        self._transforms = ["fft" if c else "dct" for c in self.wrap]
        if self.wrap[1]:
            self._transforms[1] = "rfft"
        elif self.wrap[0]:
            self._transforms[0] = "rfft"
        lam_c = _eigenvalues(rows, self._transforms[0])  # along a column (the row index)
        lam_r = _eigenvalues(cols, self._transforms[1])  # along a row (the column index)
        if free is not None and np.asarray(free).shape != (rows * cols,):
            raise ValueError(f"free: expected shape ({rows * cols},), got {np.asarray(free).shape}")
        self._fixed = np.empty(0, np.int64) if free is None else np.flatnonzero(~np.asarray(free, dtype=bool))
        eig = column_coefficient * lam_c[:, None] ** 3 + row_coefficient * lam_r[None, :] ** 3 + weight
        # 1/eig in single precision as ω/eig ∈ (0, 1] (no underflow whatever the units), 1/ω applied in double;
        # the unnormalized forward and inverse FFTs' scales cancel
        self._inverse = (weight / eig).astype(np.float32)

    def operator(self) -> sp.csr_matrix:
        """``K`` as a sparse matrix in the grid's row-major order (for tests and checks).

        Returns
        -------
        (rows · cols, rows · cols) scipy.sparse.csr_matrix

        Examples
        --------
        >>> SpectralPreconditioner((2, 3), (False, False), 1.0, 0.0, 0.5).operator()[0, :3].toarray().tolist()
        [[5.5, -9.0, 4.0]]
        """
        rows, cols = self.shape
        c_r, c_c = self.coefficients
        Lr, Lc = line_laplacian(cols, self.wrap[1]), line_laplacian(rows, self.wrap[0])
        K = (c_r * sp.kron(sp.eye(rows), Lr @ Lr @ Lr) + c_c * sp.kron(Lc @ Lc @ Lc, sp.eye(cols))
             + self.weight * sp.eye(rows * cols))
        return sp.csr_matrix(K)

    def apply(self, R: np.ndarray, Z: np.ndarray, lo: int, hi: int, columns: bool) -> None:
        """``Z = P⁻¹ R`` on every row (``lo``, ``hi`` are ignored: the transforms need the whole grid).

        ``R``, ``Z``: ``(c, k)`` arrays (``columns``) or ``(k, c)``, ``k ≥ rows · cols`` (rows past the
        grid, the CG vectors' padding, get zeros).
        """
        import scipy.fft as fft  # (here: importing it costs about 40 ms, paid only by a caller that uses it)

        rows, cols = self.shape
        n = rows * cols
        X = R[:, :n] if columns else R[:n].T  # (c, n)
        # each column scaled to at most 1 in single precision (no overflow or underflow whatever the units),
        # the scales and the eigenvalues' put back on the way out
        scale = np.maximum(X.max(axis=1), -X.min(axis=1))  # (two reductions: no |X| temporary)
        scale[~(np.isfinite(scale) & (scale > 0))] = 1.0
        G = np.empty(X.shape, dtype=np.float32)
        np.multiply(X, (1.0 / scale)[:, None], out=G, casting="same_kind")
        G[:, self._fixed] = 0.0  # (S on the way in too: P⁻¹ = S K⁻¹ S whatever R holds there)
        workers = _threads.thread_count() if n >= PARALLEL_MIN_NODES else 1
        G = self._forward(G.reshape(-1, rows, cols), fft, workers)
        G *= self._inverse
        G = self._backward(G, fft, workers).reshape(-1, n)
        out = Z[:, :n] if columns else Z[:n].T  # (c, n), a view of Z either way
        np.multiply(G, (scale / self.weight)[:, None], out=out)
        out[:, self._fixed] = 0.0
        (Z[:, n:] if columns else Z[n:])[...] = 0.0

    def _order(self) -> list[int]:
        """The axes in the forward transforms' order: a real Fourier transform first."""
        return [2, 1] if self._transforms[1] == "rfft" else [1, 2]

    def _forward(self, G: np.ndarray, _fft: ModuleType, workers: int) -> np.ndarray:
        for axis in self._order():
            kind = self._transforms[axis - 1]
            if kind == "dct":
                G = _fft.dct(G, type=2, axis=axis, norm="ortho", overwrite_x=True, workers=workers)
            else:
                G = (_fft.rfft if kind == "rfft" else _fft.fft)(G, axis=axis, overwrite_x=True, workers=workers)
        return G

    def _backward(self, G: np.ndarray, _fft: ModuleType, workers: int) -> np.ndarray:
        for axis in self._order()[::-1]:
            kind, size = self._transforms[axis - 1], self.shape[axis - 1]
            if kind == "dct":
                G = _fft.idct(G, type=2, axis=axis, norm="ortho", overwrite_x=True, workers=workers)
            elif kind == "rfft":
                G = _fft.irfft(G, n=size, axis=axis, overwrite_x=True, workers=workers)
            else:
                G = _fft.ifft(G, axis=axis, overwrite_x=True, workers=workers)
        return G
