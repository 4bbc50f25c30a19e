"""Symmetric Gauss–Seidel preconditioning for conjugate gradients on a grid's diagonal storage.

For a symmetric positive definite ``M = L + D + Lᵀ`` (``L`` strictly lower), one forward and
one backward Gauss–Seidel sweep give ``P⁻¹ r = (D + Lᵀ)⁻¹ D (D + L)⁻¹ r``: ``P = (D + L) D⁻¹
(D + Lᵀ)`` is symmetric positive definite whenever ``D`` is positive, so CG may use it. Each
thread sweeps its own range of rows and leaves out the couplings to the other ranges (block
Jacobi over the ranges, Gauss–Seidel inside each): still SPD, and the ranges run side by side.

CG runs in Eisenstat's form (:func:`gauss_seidel_cg`): with ``M`` scaled to a unit diagonal,
the preconditioned operator's product is one backward and one forward sweep, so a step costs
the two sweeps and no product with ``M``.

On a fairing matrix (a sum of per-line operators coupling four consecutive vertices, plus ω)
the sweeps damp the oscillating error that makes plain CG slow: on the bench sheets
(``benchmarks/_common.py``, all free) 3–5× fewer steps than plain CG on one range of rows
(100²) and 1.7–4.8× fewer on two (300²: the couplings between the ranges are left out), at
every weight from 0.003 to 3 and on both noises (``python benchmarks/studies/gauss_seidel.py``).

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

import numpy as np

__all__ = ["SymmetricGaussSeidel", "gauss_seidel_cg"]


class SymmetricGaussSeidel:
    """The symmetric Gauss–Seidel preconditioner of a :class:`~quadnodes.linalg.cg.SymmetricDiagonalBlocks`, made once.

    Holds ``M̃ = D^{-1/2} M D^{-1/2}`` (unit diagonal) by its upper diagonals, and for an open
    grid (upper offsets ``0, 1, 2, 3, g, 2g, 3g``) the couplings along a grid row again at the
    row they act on (``F[d, i] = M̃[i, i − d]``) for the forward sweep's recurrence. Passed to
    :func:`~quadnodes.linalg.cg.block_cg` as ``precond``, it makes the solve
    :func:`gauss_seidel_cg`.

    Parameters
    ----------
    blocks : SymmetricDiagonalBlocks

    Raises
    ------
    numpy.linalg.LinAlgError
        When a diagonal entry is not positive (then ``M`` is not positive definite).
    """

    eisenstat = True  # (block_cg hands the whole solve to gauss_seidel_cg)

    def __init__(self, blocks: object) -> None:
        U = blocks.upper  # type: ignore[attr-defined]
        offsets = blocks.upper_offsets  # type: ignore[attr-defined]
        diagonal = U[0]
        bad = np.flatnonzero(~(diagonal > 0))
        if bad.size:
            raise np.linalg.LinAlgError(f"Gauss-Seidel: diagonal entry {bad[0]} is {diagonal[bad[0]]!r}, not positive")
        from ._kernels import unit_scaled
        from .threads import run_tasks

        n = U.shape[1]
        s = 1.0 / np.sqrt(diagonal)
        g = int(offsets[4]) if offsets.size == 7 else 0
        fast = g > 3 and np.array_equal(offsets, [0, 1, 2, 3, g, 2 * g, 3 * g])
        Us = np.empty_like(U)
        F = np.empty((4, n)) if fast else np.zeros((0, 0))
        self.row = g if fast else 1
        run_tasks(lambda lo, hi: unit_scaled(U, offsets, s, Us, F, lo, hi), blocks.ranges)  # type: ignore[attr-defined]
        self.upper, self.offsets, self.forward, self.scale = Us, offsets, F, s
        self.blocks = blocks


def gauss_seidel_cg(
    blocks: object,
    B: np.ndarray,
    X0: np.ndarray,
    *,
    rtol: float,
    maxiter: int,
    sweeps: SymmetricGaussSeidel | None = None,
) -> tuple[np.ndarray, int, float]:
    """Conjugate gradients preconditioned by one symmetric Gauss–Seidel sweep per thread's block, in Eisenstat's form.

    Solves ``M X = B`` (every column) for ``M`` in symmetric diagonal storage. With ``M``
    scaled to a unit diagonal and split inside each block of rows into ``I + L``, ``I``
    and ``I + Lᵀ`` (couplings between blocks: ``E``), CG runs on ``(I + L)⁻¹ M (I + Lᵀ)⁻¹``,
    whose product with ``p`` is ``t + (I + L)⁻¹ (p − t + E t)``, ``t = (I + Lᵀ)⁻¹ p``
    (Eisenstat 1981): the two sweeps of the preconditioner are the whole step, no product
    with ``M``. Stops when every column's preconditioned residual is at most ``rtol``
    times its preconditioned right-hand side and its true residual (one product to check)
    at most ``rtol`` times ``B``'s; else goes on.

    Parameters
    ----------
    blocks : SymmetricDiagonalBlocks
        ``M`` (symmetric positive definite) and its row ranges, one per thread.
    B : (k, c) float64
    X0 : (k, c) float64
        Starting guesses.
    rtol : float
    maxiter : int
        Cap on steps.
    sweeps : SymmetricGaussSeidel, optional
        The scaled matrix, made once for many solves.

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
    from ._kernels import unit_backward_sweep, unit_cg_update, unit_forward_sweep

    sw = SymmetricGaussSeidel(blocks) if sweeps is None else sweeps
    U, off, F, scale = sw.upper, sw.offsets, sw.forward, sw.scale
    k, c = B.shape
    if k != U.shape[1]:
        raise ValueError(f"B: expected {U.shape[1]} rows (the matrix's), got {k}")
    kp = -(-k // 64) * 64  # (padded as block_cg's vectors: the ranges end on multiples of 64)
    last = blocks.ranges[-1][1]  # type: ignore[attr-defined]
    # scratch per range (by its bounds: an empty range may share its start with the next)
    scratch = {(lo, kp if hi == last else hi): (np.empty((c, sw.row)), np.empty(c))
               for lo, hi in blocks.ranges}  # type: ignore[attr-defined]

    def run(fn) -> list:  # type: ignore[no-untyped-def]  # fn(lo, hi) on every range, the last to kp
        return blocks.run(lambda lo, hi: fn(lo, kp if hi == last else hi))  # type: ignore[attr-defined]

    def padded(a: np.ndarray | None = None) -> np.ndarray:
        out = np.zeros((c, kp))
        if a is not None:
            out[:, :k] = a.T
        return out

    Bp, X = padded(B), padded(X0)
    s = np.ones(kp)
    s[:k] = scale
    bnorm = np.maximum(np.sqrt(np.einsum("ij,ij->i", Bp, Bp)), 1e-300)
    Y, Rh, P, T, W, Xs = (padded() for _ in range(6))
    zero = np.zeros(c)

    def residual(lo: int, hi: int) -> np.ndarray:  # Y = B − M X on the range; its squared norms
        blocks.matvec(X, Y, lo, hi)  # type: ignore[attr-defined]
        y = Y[:, lo:hi]
        np.subtract(Bp[:, lo:hi], y, out=y)
        return np.einsum("ij,ij->i", y, y)

    nothing = padded()  # (never written: zero pages, read as T = 0 by the forward solves)

    def forward_solve(V: np.ndarray, out: np.ndarray) -> np.ndarray:  # out = (I + L)⁻¹ V; its squared norms
        def part(lo: int, hi: int) -> np.ndarray:
            S, _ = scratch[lo, hi]
            unit_forward_sweep(U, off, F, V, nothing, out, S, lo, hi, False, np.empty(c))
            v = out[:, lo:hi]
            return np.einsum("ij,ij->i", v, v)

        return sum(run(part))

    def backward(lo: int, hi: int) -> None:
        unit_backward_sweep(U, off, Rh, P, T, beta, scratch[lo, hi][0], lo, hi)

    def forward(lo: int, hi: int) -> np.ndarray:
        S, d = scratch[lo, hi]
        unit_forward_sweep(U, off, F, P, T, W, S, lo, hi, True, d)
        return d.copy()

    def update(lo: int, hi: int) -> np.ndarray:
        out = np.empty(c)
        unit_cg_update(Xs, Rh, T, W, alpha, lo, hi, out)
        return out

    bh = np.sqrt(forward_solve(Bp * s, W))  # ‖(I + L)⁻¹ D^{-1/2} B‖: the preconditioned residual's scale
    steps = 0
    inner = rtol  # the preconditioned residual's target, tightened when the true residual misses rtol
    while True:
        true = np.sqrt(sum(run(residual))) / bnorm
        if (true <= rtol).all() or steps >= maxiter or inner < 1e-17:
            return np.ascontiguousarray(X[:, :k].T), steps, float(true.max())
        Y *= s  # D^{-1/2} (B − M X), then CG's preconditioned residual
        rr = forward_solve(Y, Rh)
        tol2 = (inner * np.maximum(bh, 1e-300)) ** 2
        if steps:  # (a later round: the first starts from fresh zeros)
            Xs.fill(0.0)
            P.fill(0.0)
        beta = zero
        start = steps
        while steps < maxiter and (rr > tol2).any():
            run(backward)
            pq = sum(run(forward))
            if not (pq[rr > tol2] > 0).all():  # a breakdown (M not positive definite in floating point)
                return np.ascontiguousarray(X[:, :k].T), steps, float(np.inf)
            alpha = np.divide(rr, pq, out=np.zeros(c), where=pq > 0)
            rr_new = sum(run(update))
            beta = np.divide(rr_new, rr, out=np.zeros(c), where=rr > 0)
            rr = rr_new
            steps += 1
        Xs *= s
        X += Xs
        inner *= 0.1 if steps == start else 0.5
