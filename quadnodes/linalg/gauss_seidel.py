"""Symmetric Gauss–Seidel preconditioning for conjugate gradients on a grid's diagonal storage or compressed rows.

For a symmetric positive definite ``M = L + D + U`` (``L`` strictly lower, ``U = Lᵀ`` in the sweeps'
order of the rows), one forward and one backward Gauss–Seidel sweep give ``P⁻¹ r = (D + U)⁻¹ D
(D + L)⁻¹ r``: ``P = (D + L) D⁻¹ (D + U)`` is symmetric positive definite whenever ``D`` is positive,
so CG may use it.

**Threads without lost couplings.** The rows are cut into one range per thread. The rows of a range
that couple to a later range are its *separator*; the rest are its *interior*. No interior couples to
another, so the sweeps order the rows interiors first (each thread sweeps its own, side by side) and
separators last (swept on one thread, a few grid rows each): a Gauss–Seidel sweep of the whole matrix
in that order, every coupling kept. (Sweeping each range alone and dropping the couplings between them
cost steps: at 1000², two threads, fair's system at ω = 0.3, 38 against 30 on broadband noise and 32
against 26 on zigzag noise, ``python benchmarks/studies/gauss_seidel.py --size 1000 --weights 0.3 --spacing fair``
against the previous engine; two and three threads now take the steps of one, ``tests/linalg/test_gauss_seidel.py``.)

CG runs in Eisenstat's form (:func:`gauss_seidel_cg`): with ``M`` scaled to a unit diagonal,
the preconditioned operator's product is one backward and one forward sweep, so a step costs
the two sweeps and no product with ``M``.

**A closed grid's seams kept out of the sweeps.** On a cylinder's diagonal storage the few couplings across its
seam (:attr:`~quadnodes.linalg.cg.SymmetricDiagonalBlocks.split`) would rule out the open grid's fast sweeps;
:class:`SymmetricGaussSeidel` sweeps ``M − S`` instead (``P`` built from its ``L`` and ``U``) and CG's product takes
``S`` in as a correction (:func:`gauss_seidel_cg`), so the solve is still of ``M``.

On a fairing matrix (a sum of per-line operators coupling four consecutive vertices, plus ω)
the sweeps damp the oscillating error that makes plain CG slow: on the bench sheets
(``benchmarks/_common.py``, all free, 300², two threads) 2.2–3.0× fewer steps than plain CG at every
weight from 0.003 to 3 and on both noises, up to 6.2× on eq. 32's own edge lengths
(``python benchmarks/studies/gauss_seidel.py``).

Examples
--------
>>> import numpy as np, scipy.sparse as sp
>>> from quadnodes.linalg.cg import SymmetricDiagonalBlocks, block_cg
>>> n = 40
>>> M = sp.diags([1.0, -4.0, 6.5, -4.0, 1.0], [-2, -1, 0, 1, 2], shape=(n, n)).todia()
>>> blocks = SymmetricDiagonalBlocks(M.offsets, M.data, threads=1)
>>> x, steps, res = block_cg(blocks, np.ones((n, 3)), np.zeros((n, 3)), rtol=1e-12, maxiter=500,
...                          precond=SymmetricGaussSeidel(blocks))
>>> bool(np.abs(M @ x - 1).max() < 1e-9)
True
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["SymmetricGaussSeidel", "CsrGaussSeidel", "gauss_seidel_cg", "sweep_scratch", "forward_solve",
           "backward_solve"]


def _fast(offsets: np.ndarray) -> bool:
    """Whether upper diagonals at ``offsets`` are an open grid's ``0, 1, 2, 3, g, 2g, 3g`` (the compiled sweeps)."""
    g = int(offsets[4]) if offsets.size == 7 else 0
    return g > 3 and np.array_equal(offsets, [0, 1, 2, 3, g, 2 * g, 3 * g])


def _layout(blocks: object) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray, np.ndarray] | None]:
    """``(U, offsets, entries)`` the sweeps take: every upper diagonal where they are an open grid's (or no grid's:
    the row-by-row sweeps), else the open grid's seven and the closed grid's periodic pairs as ``entries``, kept out
    of the sweeps."""
    offsets = blocks.upper_offsets  # type: ignore[attr-defined]
    if not _fast(offsets):
        U, dense, entries = blocks.split  # type: ignore[attr-defined]
        if entries is not None and _fast(dense):
            return U, dense, entries
    return blocks.upper, offsets, None  # type: ignore[attr-defined]


def _unit_scale(diagonal: np.ndarray) -> np.ndarray:
    """``D^{-1/2}``: the scaling to a unit diagonal (refused where an entry is not positive)."""
    bad = np.flatnonzero(~(diagonal > 0))
    if bad.size:
        raise np.linalg.LinAlgError(f"Gauss-Seidel: diagonal entry {bad[0]} is {diagonal[bad[0]]!r}, not positive")
    return 1.0 / np.sqrt(diagonal)


class SymmetricGaussSeidel:
    """The symmetric Gauss–Seidel preconditioner of a :class:`~quadnodes.linalg.cg.SymmetricDiagonalBlocks`, made once.

    Holds ``M̃ = D^{-1/2} M D^{-1/2}`` (unit diagonal) by its upper diagonals, and for an open
    grid (upper offsets ``0, 1, 2, 3, g, 2g, 3g``) the couplings along a grid row again at the
    row they act on (``F[d, i] = M̃[i, i − d]``) for the forward sweep's recurrence. A thread's
    separator is the last ``w`` rows of its range (``w`` the largest offset: three grid rows),
    so the numbering stays the grid's. On a closed grid whose periodic pairs the storage reads as entries
    (:attr:`~quadnodes.linalg.cg.SymmetricDiagonalBlocks.split`) the sweeps take the other seven diagonals and the
    pairs stay out of them (:attr:`seam`). Passed to :func:`~quadnodes.linalg.cg.block_cg` as
    ``precond``, it makes the solve :func:`gauss_seidel_cg`, on ``(c, m)`` vectors (``columns``).

    Parameters
    ----------
    blocks : SymmetricDiagonalBlocks

    Attributes
    ----------
    interiors, separators : list of tuple
        ``(lo, hi, below, above, before, after)`` of every part: its rows ``lo:hi``, and the
        fixed rows its backward sweep reads (``below:lo``, ``hi:above``: separators, later in the
        order) and its forward sweep reads (``before:lo``, ``hi:after``: interiors, earlier).

    Raises
    ------
    numpy.linalg.LinAlgError
        When a diagonal entry is not positive (then ``M`` is not positive definite).
    """

    eisenstat = True  # (block_cg hands the whole solve to gauss_seidel_cg)
    columns = True

    def __init__(self, blocks: object) -> None:
        from ._kernels import unit_scaled
        from .threads import RANGE_ALIGN, run_tasks, split_ranges

        U, offsets, entries = _layout(blocks)
        fast = _fast(offsets)
        g = int(offsets[4]) if fast else 0
        s = _unit_scale(U[0])
        Us = np.empty_like(U)
        F = np.empty((4, U.shape[1])) if fast else np.zeros((0, 0))
        self.row = g if fast else 1  # (the sweeps' scratch: one grid row per column)
        run_tasks(lambda lo, hi: unit_scaled(U, offsets, s, Us, F, lo, hi), blocks.ranges)  # type: ignore[attr-defined]
        self.upper, self.offsets, self.forward_rows, self.scale = Us, offsets, F, s
        #: a closed grid's periodic couplings, scaled to the unit diagonal, kept out of the sweeps (see
        #: :func:`gauss_seidel_cg`): ``(rows, first, columns, values)`` — each row once in ``rows``, its entries
        #: ``first[i]:first[i + 1]`` of ``columns`` and ``values`` — or None
        self.seam: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None
        if entries is not None:
            r, c, v = entries
            rows, first = np.unique(r, return_index=True)
            self.seam = (rows, np.r_[first, r.size], c, v * (s[r] * s[c]))  # (s_r s_c first: S̃ symmetric to the bit)
        self._blocks = blocks
        n, w = U.shape[1], int(offsets.max())
        ranges = list(blocks.ranges)  # type: ignore[attr-defined]
        while len(ranges) > 1 and min(hi - lo for lo, hi in ranges) <= 2 * w:  # separators must not touch
            ranges = split_ranges(n, parts=len(ranges) - 1, align=RANGE_ALIGN)
        last = len(ranges) - 1
        self.interiors = []
        for r, (lo, hi) in enumerate(ranges):
            top = hi - w if r < last else hi  # (the interior: lo:top; the separator: top:hi)
            self.interiors.append((lo, top, lo - w if r else lo, hi, lo, top))
        self.separators = [(hi - w, hi, hi - w, hi, hi - 2 * w, min(n, hi + w)) for _, hi in ranges[:-1]]

    @staticmethod
    def fits(blocks: object) -> bool:
        """Whether ``blocks`` (:class:`~quadnodes.linalg.cg.SymmetricDiagonalBlocks`) take the grid's compiled
        sweeps: an open grid's seven upper diagonals ``0, 1, 2, 3, g, 2g, 3g``, or a closed grid's once its periodic
        pairs are read as entries (:attr:`~quadnodes.linalg.cg.SymmetricDiagonalBlocks.split`)."""
        return _fast(blocks.upper_offsets) or _fast(blocks.split[1])  # type: ignore[attr-defined]

    def backward(self, R: np.ndarray, P: np.ndarray, T: np.ndarray, beta: np.ndarray, S: np.ndarray,
                 part: tuple) -> None:
        """``P = R + β P``, then ``T = (I + U)⁻¹ P`` on the part's rows (the later rows beside it fixed)."""
        from ._kernels import unit_backward_sweep

        lo, hi, below, above, _, _ = part
        unit_backward_sweep(self.upper, self.offsets, R, P, T, beta, S, lo, hi, below, above)

    def forward(self, P: np.ndarray, T: np.ndarray, W: np.ndarray, S: np.ndarray, part: tuple,
                dots: np.ndarray) -> None:
        """``W = (I + L)⁻¹ (P − T)`` on the part's rows (the earlier rows beside it fixed); ``dots = P·(T + W)`` there."""
        from ._kernels import unit_forward_sweep

        lo, hi, _, _, before, after = part
        unit_forward_sweep(self.upper, self.offsets, self.forward_rows, P, T, W, S, lo, hi, before, after, dots)

    def update(self, X: np.ndarray, R: np.ndarray, T: np.ndarray, W: np.ndarray, alpha: np.ndarray, lo: int,
               hi: int, rr: np.ndarray) -> None:
        """``x += α t``, ``r −= α (t + w)``, ``rr = r·r`` on rows ``lo:hi``."""
        from ._kernels import unit_cg_update

        unit_cg_update(X, R, T, W, alpha, lo, hi, rr)

    def product(self, X: np.ndarray, Y: np.ndarray) -> None:
        """``Y = M X`` (the unscaled matrix) on the rows of ``M``, on the blocks' threads."""
        b = self._blocks
        b.run(lambda lo, hi: b.matvec(X, Y, lo, hi))  # type: ignore[attr-defined]


class CsrGaussSeidel:
    """The symmetric Gauss–Seidel preconditioner of a :class:`~quadnodes.linalg.threads.RowBlocks` (CSR), made once.

    Holds ``M̃ = D^{-1/2} M D^{-1/2}`` (unit diagonal) in compressed rows, each row's couplings split
    into those inside its block (lower and upper) and those outside it. A thread's block is its range's
    interior; all separator rows form one more block, swept after the interiors on one thread. The
    sweeps go row by row, in the matrix's own numbering within a block, on ``(m, c)`` vectors. Where
    the separators would hold more than a quarter of the rows (a numbering without locality), the
    sweeps run on one thread instead. Passed to :func:`~quadnodes.linalg.cg.block_cg` as ``precond``,
    it makes the solve :func:`gauss_seidel_cg`.

    Parameters
    ----------
    blocks : RowBlocks or DiagonalBlocks
        The operator CG multiplies by (its matrix, in CSR here) and its row ranges.

    Attributes
    ----------
    interiors, separators : list of tuple
        ``(rows, couple_backward, couple_forward)`` of every block: its rows (ascending), and whether
        each sweep reads its couplings outside the block (the interiors' backward sweeps read the
        separators' ``T``; the separators' forward sweep reads the interiors' ``W``).

    Raises
    ------
    numpy.linalg.LinAlgError
        When a diagonal entry is not positive (then ``M`` is not positive definite).
    """

    eisenstat = True  # (block_cg hands the whole solve to gauss_seidel_cg)
    columns = False
    row = 1

    def __init__(self, blocks: object) -> None:
        from ._kernels import csr_separators, csr_split_counts, csr_split_fill
        from .cg import DiagonalBlocks
        from .threads import RowBlocks, run_tasks

        M = blocks.M.tocsr()  # type: ignore[attr-defined]  # (diagonal storage too: a closed grid's seams)
        s = _unit_scale(M.diagonal())
        n = M.shape[0]
        ranges = self._ranges = list(blocks.ranges)  # type: ignore[attr-defined]  # (the product's)
        separator = np.zeros(n, dtype=np.bool_)
        if len(ranges) > 1:  # (the last range reaches no later one)
            run_tasks(lambda lo, hi: csr_separators(M.indptr, M.indices, lo, hi, separator), ranges[:-1])
            if np.count_nonzero(separator) > n // 4:
                separator[:] = False
                ranges = [(0, n)]
        # each row's strictly lower and upper parts inside its block, and its couplings outside it, as three
        # CSR matrices scaled to a unit diagonal (the sweeps then never branch), split on the pool
        counts = np.zeros((3, n), dtype=np.int64)
        run_tasks(lambda lo, hi: csr_split_counts(M.indptr, M.indices, separator, lo, hi, counts), ranges)
        ptr = np.zeros((3, n + 1), dtype=np.int64)
        np.cumsum(counts, axis=1, out=ptr[:, 1:])
        total = ptr[:, -1]
        split = [(np.empty(total[p], dtype=M.indices.dtype), np.empty(total[p])) for p in range(3)]
        run_tasks(lambda lo, hi: csr_split_fill(M.indptr, M.indices, M.data, s, separator, lo, hi, ptr,
                                                *split[0], *split[1], *split[2]), ranges)
        self.lower, self.upper_part, self.coupling = ((ptr[p], *split[p]) for p in range(3))
        idx = M.indices.dtype
        self.interiors = [(lo + np.flatnonzero(~separator[lo:hi]).astype(idx), True, False) for lo, hi in ranges]
        self.separators = [(np.flatnonzero(separator).astype(idx), False, True)] if len(ranges) > 1 else []
        if isinstance(blocks, DiagonalBlocks):  # (the residual's product from its own storage: no CSR copy kept)
            self._diagonal: DiagonalBlocks | None = blocks
            self._product = None
        else:
            self._diagonal = None
            self._product = RowBlocks(M, threads=1, columns=False)  # (the residual's product on (m, c) vectors)
        self.scale = s

    def backward(self, R: np.ndarray, P: np.ndarray, T: np.ndarray, beta: np.ndarray, S: np.ndarray,
                 part: tuple) -> None:
        """As :meth:`SymmetricGaussSeidel.backward`, row by row."""
        from ._kernels import csr_backward_sweep

        rows, couple, _ = part
        csr_backward_sweep(*self.upper_part, *self.coupling, R, P, T, beta, rows, couple)

    def forward(self, P: np.ndarray, T: np.ndarray, W: np.ndarray, S: np.ndarray, part: tuple,
                dots: np.ndarray) -> None:
        """As :meth:`SymmetricGaussSeidel.forward`, row by row."""
        from ._kernels import csr_forward_sweep

        rows, _, couple = part
        csr_forward_sweep(*self.lower, *self.coupling, P, T, W, rows, couple, dots)

    def update(self, X: np.ndarray, R: np.ndarray, T: np.ndarray, W: np.ndarray, alpha: np.ndarray, lo: int,
               hi: int, rr: np.ndarray) -> None:
        """As :meth:`SymmetricGaussSeidel.update`, on ``(m, c)`` vectors."""
        from ._kernels import rows_cg_update

        rows_cg_update(X, R, T, W, alpha, lo, hi, rr)

    def product(self, X: np.ndarray, Y: np.ndarray) -> None:
        """``Y = M X`` on the rows of ``M`` (SciPy's multi-vector kernel, on the ranges' threads; a grid's own
        diagonal storage on transposed copies — a few products a solve — where the blocks are one)."""
        from .threads import run_tasks

        if self._diagonal is not None:
            b = self._diagonal
            Xt = np.ascontiguousarray(X.T)
            Yt = np.zeros_like(Xt)  # (padding rows past the matrix's stay zero)
            b.run(lambda lo, hi: b.matvec(Xt, Yt, lo, hi))
            Y[...] = Yt.T
            return
        prod = self._product
        run_tasks(lambda lo, hi: prod.matvec(X, Y, lo, hi), self._ranges)


def sweep_scratch(sweeps: SymmetricGaussSeidel | CsrGaussSeidel, c: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """One ``(S, dots)`` scratch pair per part of ``sweeps`` (interiors, then separators) for ``c`` vectors."""
    return [(np.empty((c, sweeps.row)), np.empty(c)) for _ in range(len(sweeps.interiors) + len(sweeps.separators))]


def forward_solve(sweeps: SymmetricGaussSeidel | CsrGaussSeidel, V: np.ndarray, T: np.ndarray, W: np.ndarray,
                  scratch: list) -> None:
    """``W = (I + L̃)⁻¹ (V − T)`` on every row, in the sweeps' order: the interiors side by side, then the separators.

    Vectors in the sweeps' layout (``(c, kp)`` with ``columns``, else ``(kp, c)``); ``scratch`` from
    :func:`sweep_scratch` (each part's ``dots`` gets ``V·(T + W)`` on its rows).
    """
    from .threads import run_tasks

    def part(i: int, p: tuple) -> None:
        sweeps.forward(V, T, W, scratch[i][0], p, scratch[i][1])

    run_tasks(part, list(enumerate(sweeps.interiors)))
    for i, p in enumerate(sweeps.separators, len(sweeps.interiors)):
        part(i, p)


def backward_solve(sweeps: SymmetricGaussSeidel | CsrGaussSeidel, R: np.ndarray, P: np.ndarray, T: np.ndarray,
                   scratch: list) -> None:
    """``P = R``, then ``T = (I + Ũ)⁻¹ P`` on every row, in the sweeps' order: the separators, then the interiors.

    As :func:`forward_solve`.
    """
    from .threads import run_tasks

    zero = np.zeros(scratch[0][1].size)

    def part(i: int, p: tuple) -> None:
        sweeps.backward(R, P, T, zero, scratch[i][0], p)

    for i, p in enumerate(sweeps.separators, len(sweeps.interiors)):
        part(i, p)
    run_tasks(part, list(enumerate(sweeps.interiors)))


def gauss_seidel_cg(
    blocks: object,
    B: np.ndarray,
    X0: np.ndarray,
    *,
    rtol: float,
    maxiter: int,
    sweeps: SymmetricGaussSeidel | CsrGaussSeidel | None = None,
    monitor: Callable[[int, float], bool] | None = None,
) -> tuple[np.ndarray, int, float]:
    """Conjugate gradients preconditioned by one symmetric Gauss–Seidel sweep, in Eisenstat's form, on threads.

    Solves ``M X = B`` (every column). With ``M`` scaled to a unit diagonal and split in the
    sweeps' order (the threads' interiors, then the separators between their ranges; see the
    module) into ``I + L``, ``I`` and ``I + U``, CG runs on ``(I + L)⁻¹ M (I + U)⁻¹``, whose
    product with ``p`` is ``t + (I + L)⁻¹ (p − t)``, ``t = (I + U)⁻¹ p`` (Eisenstat 1981): the
    two sweeps of the preconditioner are the whole step, no product with ``M``. A step sweeps the
    separators backward, then each thread its interior backward and forward, then the separators
    forward. Stops when every column's preconditioned residual is at most ``rtol`` times its
    preconditioned right-hand side and its true residual (one product to check) at most ``rtol``
    times ``B``'s; else goes on.

    Parameters
    ----------
    blocks : SymmetricDiagonalBlocks or RowBlocks
        ``M`` (symmetric positive definite) and its row ranges, one per thread: diagonal
        storage (an open grid's fast sweeps; a closed grid's with its seam's couplings ``S̃`` kept out of them and
        the product taken as ``t + (I + L)⁻¹ (p − t + S̃ t)``) or compressed rows (row by row).
    B : (k, c) float64
    X0 : (k, c) float64
        Starting guesses.
    rtol : float
    maxiter : int
        Cap on steps.
    sweeps : SymmetricGaussSeidel or CsrGaussSeidel, optional
        The scaled matrix, made once for many solves (default: made here for ``blocks``).
    monitor : callable, optional
        Called after every step with the step count and the worst column's preconditioned residual
        relative to its preconditioned right-hand side (what the stop compares with ``rtol``);
        returning True ends the solve there, with the iterate reached.

    Returns
    -------
    x : (k, c) float64
    steps : int
    residual : float
        The worst column's true relative residual (inf after a breakdown: a step whose
        ``p·Âp`` is not positive, so ``M`` is not positive definite in floating point).

    Raises
    ------
    numpy.linalg.LinAlgError
        When a diagonal entry of ``M`` is not positive.
    """
    from .threads import RANGE_ALIGN, padded as _padded, run_tasks

    if sweeps is None:
        sweeps = SymmetricGaussSeidel(blocks) if hasattr(blocks, "upper") else CsrGaussSeidel(blocks)
    sw = sweeps
    columns = sw.columns  # (c, m) vectors for the grid's sweeps, (m, c) for compressed rows
    k, c = B.shape
    if k != sw.scale.size:
        raise ValueError(f"B: expected {sw.scale.size} rows (the matrix's), got {k}")
    kp = -(-k // RANGE_ALIGN) * RANGE_ALIGN  # (padded as block_cg's vectors)

    interiors, separators = sw.interiors, sw.separators  # (the padding rows stay zero: no sweep touches them)
    scratch = sweep_scratch(sw, c)
    tasks = list(enumerate(interiors))

    def run(fn) -> list:  # type: ignore[no-untyped-def]  # fn(lo, hi) on every range, the last to kp
        return blocks.run(lambda lo, hi: fn(lo, kp if hi == k else hi))  # type: ignore[attr-defined]

    def padded(a: np.ndarray | None = None) -> np.ndarray:
        return _padded(a, kp, c, columns=columns)

    def norms2(V: np.ndarray) -> np.ndarray:
        return np.einsum("ij,ij->i", V, V) if columns else np.einsum("ij,ij->j", V, V)

    def result(residual: float) -> tuple[np.ndarray, int, float]:
        return (np.ascontiguousarray(X[:, :k].T) if columns else X[:k].copy()), steps, residual

    Bp, X = padded(B), padded(X0)
    s = np.ones(kp)
    s[:k] = sw.scale
    s = s if columns else s[:, None]
    bnorm = np.maximum(np.sqrt(norms2(Bp)), 1e-300)
    Y, Rh, P, T, W, Xs = (padded() for _ in range(6))
    zero = np.zeros(c)
    nothing = padded()  # (never written: zero pages, read as T = 0 by the forward solves)

    def lower_norms(V: np.ndarray, out: np.ndarray) -> np.ndarray:  # out = (I + L)⁻¹ V; its squared norms
        forward_solve(sw, V, nothing, out, scratch)
        return norms2(out)

    def interior(i: int, p: tuple) -> np.ndarray:  # both sweeps of a thread's interior; its dots
        S, d = scratch[i]
        sw.backward(Rh, P, T, beta, S, p)
        sw.forward(P, T, W, S, p, d)
        return d.copy()

    seam = getattr(sw, "seam", None)

    def interiors_with_seam() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Both sweeps of the interiors where the couplings ``S̃`` across a closed grid's seam are kept out of them:
        with ``M̃ = (I + L) + (I + U) − I + S̃``, ``Âp = t + (I + L)⁻¹ (p − t + S̃ t)`` — the backward sweeps whole,
        then ``S̃ t`` added to ``p`` on the seam's rows for the forward sweeps (the separators' too: the caller
        restores ``p`` after them). Returns the interiors' dots, ``S̃ t`` and ``p``'s kept rows."""
        rows, first, cols, vals = seam  # type: ignore[misc]
        run_tasks(lambda i, p: sw.backward(Rh, P, T, beta, scratch[i][0], p), tasks)
        ST = np.add.reduceat(T[:, cols] * vals, first[:-1], axis=1)
        kept = P[:, rows]  # (a copy: P is restored exactly after)
        P[:, rows] = kept + ST
        run_tasks(lambda i, p: sw.forward(P, T, W, scratch[i][0], p, scratch[i][1]), tasks)
        return sum(scratch[i][1] for i in range(len(interiors))), ST, kept

    def update(lo: int, hi: int) -> np.ndarray:
        out = np.empty(c)
        sw.update(Xs, Rh, T, W, alpha, lo, hi, out)
        return out

    bh = np.sqrt(lower_norms(Bp * s, W))  # ‖(I + L)⁻¹ D^{-1/2} B‖: the preconditioned residual's scale
    bh2 = np.maximum(bh, 1e-300) ** 2
    steps = 0
    inner = rtol  # the preconditioned residual's target, tightened when the true residual misses rtol
    stopped = False  # (by the monitor)
    while True:
        sw.product(X, Y)  # Y = B − M X, the true residual
        np.subtract(Bp, Y, out=Y)
        true = np.sqrt(norms2(Y)) / bnorm
        if (true <= rtol).all() or steps >= maxiter or inner < 1e-17 or stopped:
            return result(float(true.max()))
        Y *= s  # D^{-1/2} (B − M X), then CG's preconditioned residual
        rr = lower_norms(Y, Rh)
        tol2 = (inner * np.maximum(bh, 1e-300)) ** 2
        if steps:  # (a later round: the first starts from fresh zeros)
            Xs.fill(0.0)
            P.fill(0.0)
        beta = zero
        start = steps
        while steps < maxiter and (rr > tol2).any():
            for i, p in enumerate(separators, len(interiors)):
                sw.backward(Rh, P, T, beta, scratch[i][0], p)
            if seam is None:
                pq = sum(run_tasks(interior, tasks))
            else:
                pq, ST, kept = interiors_with_seam()
            for i, p in enumerate(separators, len(interiors)):
                sw.forward(P, T, W, scratch[i][0], p, scratch[i][1])
                pq = pq + scratch[i][1]
            if seam is not None:  # p restored; p·Âp from the dots the sweeps took with p + S̃ t
                P[:, seam[0]] = kept
                pq = pq - np.einsum("ij,ij->i", ST, T[:, seam[0]] + W[:, seam[0]])
            if not (pq[rr > tol2] > 0).all():  # a breakdown (M not positive definite in floating point)
                return result(float(np.inf))
            alpha = np.divide(rr, pq, out=np.zeros(c), where=pq > 0)
            rr_new = sum(run(update))
            beta = np.divide(rr_new, rr, out=np.zeros(c), where=rr > 0)
            rr = rr_new
            steps += 1
            if monitor is not None and monitor(steps, float(np.sqrt((rr / bh2).max()))):
                stopped = True
                break
        Xs *= s
        X += Xs
        inner *= 0.1 if steps == start else 0.5
