"""The symmetric Gauss–Seidel–transforms–Gauss–Seidel cycle as a preconditioner, fused: built and measured for
``spectral_smoothing.py`` (docs/fairing.md "Tried: Gauss–Seidel around the transforms"), not part of the package.

An approximate inverse ``K⁻¹`` that follows ``M`` globally but not its local variation (the spectral
preconditioner of a grid with one coefficient per family where the windows' coefficients vary at random) leaves
CG the steps that the variation costs; symmetric Gauss–Seidel sweeps damp that error locally. The cycle

    ``x₁ = (D + L)⁻¹ r``,  ``x₂ = x₁ + K⁻¹ (r − M x₁)``,  ``z = x₂ + (D + U)⁻¹ (r − M x₂)``

is symmetric positive definite (the sweeps alone are). Written out it costs two sweeps and three products a
step besides ``K⁻¹``; fused, the sweeps and one product. With ``M`` scaled to a unit diagonal, ``M = I + L + U``:

- ``r − M x₁ = −U x₁``: the forward sweep scatters ``U x₁`` as it goes (each row's lower entries, read for
  ``x₁``, add the row's value to the earlier rows: :func:`csr_forward_scatter`);
- ``r − M x₂ = M u − U x₁`` with ``u = K⁻¹ U x₁``: the one product;
- ``M z = r + L y`` with ``y = (I + U)⁻¹ (r − M x₂)``: the backward sweep scatters ``L y``
  (:func:`csr_backward_scatter`), so CG's own product is not needed (``q = M z + β q`` as ``p = z + β p``).

The sweeps run in :class:`~quadnodes.linalg.gauss_seidel.CsrGaussSeidel`'s order and blocks (each thread's
interior side by side, then the separators between their ranges), so every coupling is kept; the interiors'
scatter stays inside their own block, and the separators' share of ``L y`` is gathered after them. The kernels
compile when the study runs (no disk cache: a few seconds).
"""

from __future__ import annotations

import sys
from collections.abc import Callable

import numba as nb
import numpy as np

from quadnodes.linalg.gauss_seidel import CsrGaussSeidel


class SmoothedInverse:
    """The symmetric cycle of a forward Gauss–Seidel sweep, ``inverse`` and a backward sweep, made once.

    :func:`smoothed_cg` runs CG with it.

    Parameters
    ----------
    blocks : DiagonalBlocks or SymmetricDiagonalBlocks
        ``M`` (symmetric positive definite) in diagonal storage and its row ranges, one per thread: the product's
        (on ``(c, n)`` vectors); the sweeps take its compressed rows (:class:`CsrGaussSeidel`).
    inverse : object
        ``K⁻¹``, symmetric positive semi-definite: ``apply(R, Z, lo, hi, columns)`` writing ``Z = K⁻¹ R`` on every
        row of ``(c, k)`` arrays (``columns=True``; e.g. a
        :class:`~quadnodes.linalg.spectral.SpectralPreconditioner`), applied to all rows at once.

    Raises
    ------
    numpy.linalg.LinAlgError
        When a diagonal entry of ``M`` is not positive (then ``M`` is not positive definite).
    """

    def __init__(self, blocks: object, inverse: object) -> None:
        self.sweeps = CsrGaussSeidel(blocks)
        self.inverse = inverse
        self.blocks = blocks
        self.scale = self.sweeps.scale  # D^{-1/2}
        self.root = 1.0 / self.scale  # D^{1/2}


def smoothed_cg(
    blocks: object,
    B: np.ndarray,
    X0: np.ndarray,
    *,
    rtol: float,
    maxiter: int,
    cycle: SmoothedInverse,
    monitor: Callable[[int, float], bool] | None = None,
) -> tuple[np.ndarray, int, float]:
    """Conjugate gradients preconditioned by :class:`SmoothedInverse`'s cycle, fused (see the module), on threads.

    Solves ``M X = B`` (every column) in the unit-diagonal scaling ``D^{-1/2} M D^{-1/2}``. Stops when every
    column's scaled residual is at most ``rtol`` times its scaled right-hand side and its true residual (one
    product to check) at most ``rtol`` times ``B``'s; else goes on from there with a tighter inner target.

    Parameters
    ----------
    blocks : DiagonalBlocks
        ``M`` and its row ranges (the cycle's).
    B : (k, c) float64
    X0 : (k, c) float64
        Starting guesses.
    rtol : float
    maxiter : int
        Cap on steps.
    cycle : SmoothedInverse
    monitor : callable, optional
        Called after every step with the step count and the worst column's scaled residual relative to its
        scaled right-hand side; returning True ends the solve there, with the iterate reached.

    Returns
    -------
    x : (k, c) float64
    steps : int
    residual : float
        The worst column's true relative residual (inf after a breakdown: a step whose ``p·Mp`` is not
        positive, so ``M`` is not positive definite in floating point).
    """
    from quadnodes.linalg._kernels import cg_update
    from quadnodes.linalg.threads import RANGE_ALIGN, padded as _padded, run_tasks

    kern = sys.modules[__name__]  # (this module's kernels, below)

    sw = cycle.sweeps
    k, c = B.shape
    if k != sw.scale.size:
        raise ValueError(f"B: expected {sw.scale.size} rows (the matrix's), got {k}")
    kp = -(-k // RANGE_ALIGN) * RANGE_ALIGN
    s = np.zeros(kp)
    s[:k] = cycle.scale
    d = np.zeros(kp)
    d[:k] = cycle.root
    lower, upper, coupling = sw.lower, sw.upper_part, sw.coupling
    interiors = [rows for rows, _, _ in sw.interiors]
    separators = [rows for rows, _, _ in sw.separators]

    def run(fn: Callable[[int, int], object]) -> list:  # fn(lo, hi) on every range, the last to kp
        return blocks.run(lambda lo, hi: fn(lo, kp if hi == k else hi))  # type: ignore[attr-defined]

    def padded(a: np.ndarray | None = None) -> np.ndarray:
        return _padded(a, kp, c, columns=True)

    def norms2(V: np.ndarray) -> np.ndarray:
        return np.einsum("ij,ij->i", V, V)

    def product(X: np.ndarray, Y: np.ndarray) -> None:
        blocks.run(lambda lo, hi: blocks.matvec(X, Y, lo, hi))  # type: ignore[attr-defined]

    Bp, X = padded(B), padded(X0)
    bnorm = np.maximum(np.sqrt(norms2(Bp)), 1e-300)
    R, X1, V, T, U, W, P, Q, Xs = (padded() for _ in range(9))

    def forward(rows: np.ndarray, couple: bool) -> None:
        kern.csr_forward_scatter(*lower, *coupling, R, X1, V, rows, couple)

    def backward(rows: np.ndarray, couple: bool) -> None:
        kern.csr_backward_scatter(*upper, *coupling, T, V, W, rows, couple)

    def precondition() -> np.ndarray:
        """``z`` into ``X1`` and ``M z`` into ``W`` from ``R`` (the other buffers scratch); ``r·z`` per column."""
        run_tasks(lambda rows: forward(rows, False), [(rows,) for rows in interiors])  # x₁, U x₁ → X1, V
        for rows in separators:
            forward(rows, True)
        run(lambda lo, hi: kern.smoothed_scale(d, V, T, lo, hi))  # D^{1/2} U x₁
        cycle.inverse.apply(T, U, 0, kp, True)  # u' = K⁻¹ D^{1/2} U x₁ (u = D^{1/2} u')
        product(U, T)  # M u'
        run(lambda lo, hi: kern.smoothed_residual(s, T, V, lo, hi))  # r − M̃ x₂ = D^{-1/2} M u' − U x₁ → T
        for rows in separators:  # y → V, L y → W (V's U x₁ is spent)
            backward(rows, False)
        run_tasks(lambda rows: backward(rows, True), [(rows,) for rows in interiors])
        for rows in separators:
            kern.csr_gather_add(*coupling, V, W, rows)
        dots = run(lambda lo, hi: _direction(lo, hi, True))
        return sum(dots)

    beta = np.zeros(c)

    def _direction(lo: int, hi: int, first: bool) -> np.ndarray:
        out = np.empty(c)
        kern.smoothed_direction(X1, U, V, W, R, P, Q, d, out, beta, lo, hi, first)
        return out

    def update(lo: int, hi: int) -> np.ndarray:
        out = np.empty(c)
        cg_update(Xs, R, P, Q, alpha, lo, hi, out)
        return out

    def result(residual: float) -> tuple[np.ndarray, int, float]:
        return np.ascontiguousarray(X[:, :k].T), steps, residual

    steps = 0
    inner = rtol
    stopped = False
    alpha = np.zeros(c)
    while True:
        product(X, T)  # B − M X, the true residual
        np.subtract(Bp, T, out=T)
        true = np.sqrt(norms2(T)) / bnorm
        if (true <= rtol).all() or steps >= maxiter or inner < 1e-17 or stopped:
            return result(float(true.max()))
        np.multiply(T, s, out=R)  # D^{-1/2} (B − M X)
        rr = norms2(R)
        bh2 = np.maximum(norms2(Bp * s), 1e-300)  # the scaled right-hand side's squared norms
        tol2 = inner**2 * bh2
        Xs.fill(0.0)
        rz_old = None
        start = steps
        while steps < maxiter and (rr > tol2).any():
            rz = precondition()
            if rz_old is None:
                beta[:] = 0.0
            else:
                np.divide(rz, rz_old, out=beta, where=rz_old != 0)
                beta[rz_old == 0] = 0.0
            rz_old = rz
            pq = sum(run(lambda lo, hi: _direction(lo, hi, False)))
            if not (pq[rr > tol2] > 0).all():  # a breakdown (M not positive definite in floating point)
                return result(float(np.inf))
            np.divide(rz, pq, out=alpha, where=pq > 0)
            alpha[~(pq > 0)] = 0.0
            rr = sum(run(update))
            steps += 1
            if monitor is not None and monitor(steps, float(np.sqrt((rr / bh2).max()))):
                stopped = True
                break
        X += Xs * s
        inner *= 0.1 if steps == start else 0.5


# --- the cycle's kernels: compressed-row sweeps with scatter, and its vector passes, on (c, m) vectors -----------


@nb.njit(cache=False, nogil=True, fastmath=True, boundscheck=False)
def csr_forward_scatter(low_ptr: np.ndarray, low_idx: np.ndarray, low: np.ndarray, out_ptr: np.ndarray,
                        out_idx: np.ndarray, out: np.ndarray, R: np.ndarray, X: np.ndarray, V: np.ndarray,
                        rows: np.ndarray, couple: bool) -> None:
    """``X = (I + L)⁻¹ (R − E X)`` over the block's ``rows`` (ascending) on ``(c, m)`` vectors, and ``V = U X``
    by scatter: a row's strictly lower entries inside the block (``low_*``) and, with ``couple``, its couplings
    outside it (``out_*``, whose rows hold their final ``X`` and come earlier) are read for ``x_i`` and then
    add ``L_ij x_i`` to ``V_j`` (``U = Lᵀ``). ``V_i`` is zeroed when row ``i`` is reached: every row adding to it
    comes later in the sweeps' order."""
    c = R.shape[0]
    if c == 3:
        for k in range(rows.size):
            i = rows[k]
            a0, a1, a2 = R[0, i], R[1, i], R[2, i]
            if couple:
                for e in range(out_ptr[i], out_ptr[i + 1]):
                    j = out_idx[e]
                    v = out[e]
                    a0 -= v * X[0, j]
                    a1 -= v * X[1, j]
                    a2 -= v * X[2, j]
            for e in range(low_ptr[i], low_ptr[i + 1]):
                j = low_idx[e]
                v = low[e]
                a0 -= v * X[0, j]
                a1 -= v * X[1, j]
                a2 -= v * X[2, j]
            X[0, i], X[1, i], X[2, i] = a0, a1, a2
            V[0, i] = V[1, i] = V[2, i] = 0.0
            for e in range(low_ptr[i], low_ptr[i + 1]):
                j = low_idx[e]
                v = low[e]
                V[0, j] += v * a0
                V[1, j] += v * a1
                V[2, j] += v * a2
            if couple:
                for e in range(out_ptr[i], out_ptr[i + 1]):
                    j = out_idx[e]
                    v = out[e]
                    V[0, j] += v * a0
                    V[1, j] += v * a1
                    V[2, j] += v * a2
        return
    for k in range(rows.size):
        i = rows[k]
        for q in range(c):
            a = R[q, i]
            if couple:
                for e in range(out_ptr[i], out_ptr[i + 1]):
                    a -= out[e] * X[q, out_idx[e]]
            for e in range(low_ptr[i], low_ptr[i + 1]):
                a -= low[e] * X[q, low_idx[e]]
            X[q, i] = a
            V[q, i] = 0.0
            for e in range(low_ptr[i], low_ptr[i + 1]):
                V[q, low_idx[e]] += low[e] * a
            if couple:
                for e in range(out_ptr[i], out_ptr[i + 1]):
                    V[q, out_idx[e]] += out[e] * a


@nb.njit(cache=False, nogil=True, fastmath=True, boundscheck=False)
def csr_backward_scatter(up_ptr: np.ndarray, up_idx: np.ndarray, up: np.ndarray, out_ptr: np.ndarray,
                         out_idx: np.ndarray, out: np.ndarray, S: np.ndarray, Y: np.ndarray, V: np.ndarray,
                         rows: np.ndarray, couple: bool) -> None:
    """``Y = (I + U)⁻¹ (S − E Y)`` over the block's ``rows`` (from the last) on ``(c, m)`` vectors, and ``V = L Y``
    inside the block by scatter: a row's strictly upper entries inside the block add ``U_ij y_i`` to ``V_j``
    (``V_i`` zeroed when row ``i`` is reached). With ``couple`` the couplings outside the block (later rows,
    holding their final ``Y``) are read but not scattered — two threads' interiors may reach one separator
    row: :func:`csr_gather_add` adds them to the separators' ``V`` afterwards."""
    c = S.shape[0]
    if c == 3:
        for k in range(rows.size - 1, -1, -1):
            i = rows[k]
            a0, a1, a2 = S[0, i], S[1, i], S[2, i]
            if couple:
                for e in range(out_ptr[i], out_ptr[i + 1]):
                    j = out_idx[e]
                    v = out[e]
                    a0 -= v * Y[0, j]
                    a1 -= v * Y[1, j]
                    a2 -= v * Y[2, j]
            for e in range(up_ptr[i], up_ptr[i + 1]):
                j = up_idx[e]
                v = up[e]
                a0 -= v * Y[0, j]
                a1 -= v * Y[1, j]
                a2 -= v * Y[2, j]
            Y[0, i], Y[1, i], Y[2, i] = a0, a1, a2
            V[0, i] = V[1, i] = V[2, i] = 0.0
            for e in range(up_ptr[i], up_ptr[i + 1]):
                j = up_idx[e]
                v = up[e]
                V[0, j] += v * a0
                V[1, j] += v * a1
                V[2, j] += v * a2
        return
    for k in range(rows.size - 1, -1, -1):
        i = rows[k]
        for q in range(c):
            a = S[q, i]
            if couple:
                for e in range(out_ptr[i], out_ptr[i + 1]):
                    a -= out[e] * Y[q, out_idx[e]]
            for e in range(up_ptr[i], up_ptr[i + 1]):
                a -= up[e] * Y[q, up_idx[e]]
            Y[q, i] = a
            V[q, i] = 0.0
            for e in range(up_ptr[i], up_ptr[i + 1]):
                V[q, up_idx[e]] += up[e] * a


@nb.njit(cache=False, nogil=True, fastmath=True, boundscheck=False)
def csr_gather_add(ptr: np.ndarray, idx: np.ndarray, val: np.ndarray, Y: np.ndarray, V: np.ndarray,
                   rows: np.ndarray) -> None:
    """``V_i += Σ_e val[e] Y[:, idx[e]]`` over CSR row ``i`` for every ``i`` in ``rows``, on ``(c, m)`` vectors."""
    for k in range(rows.size):
        i = rows[k]
        for q in range(Y.shape[0]):
            a = V[q, i]
            for e in range(ptr[i], ptr[i + 1]):
                a += val[e] * Y[q, idx[e]]
            V[q, i] = a


@nb.njit(cache=False, nogil=True, fastmath=True, boundscheck=False)
def smoothed_residual(s: np.ndarray, MU: np.ndarray, V: np.ndarray, lo: int, hi: int) -> None:
    """``MU = s ⊙ MU − V`` on columns ``lo:hi`` of ``(c, m)`` arrays (the cycle's residual after the inverse)."""
    for q in range(MU.shape[0]):
        m = MU[q, lo:hi]
        v = V[q, lo:hi]
        t = s[lo:hi]
        for i in range(hi - lo):
            m[i] = t[i] * m[i] - v[i]


@nb.njit(cache=False, nogil=True, fastmath=True, boundscheck=False)
def smoothed_scale(d: np.ndarray, V: np.ndarray, T: np.ndarray, lo: int, hi: int) -> None:
    """``T = d ⊙ V`` on columns ``lo:hi`` of ``(c, m)`` arrays."""
    for q in range(V.shape[0]):
        v = V[q, lo:hi]
        o = T[q, lo:hi]
        t = d[lo:hi]
        for i in range(hi - lo):
            o[i] = t[i] * v[i]


@nb.njit(cache=False, nogil=True, fastmath=True, boundscheck=False)
def smoothed_direction(X1: np.ndarray, U: np.ndarray, Y: np.ndarray, W: np.ndarray, R: np.ndarray,
                       P: np.ndarray, Q: np.ndarray, d: np.ndarray, rz: np.ndarray, beta: np.ndarray, lo: int,
                       hi: int, first: bool) -> None:
    """On columns ``lo:hi`` of ``(c, m)`` arrays: the cycle's ``z = x₁ − d ⊙ u + y`` and ``M z = r + w``; then
    with ``first`` only ``rz[q] = r·z`` (``z`` kept in ``X1``, ``M z`` in ``W``); else ``p = z + β p``,
    ``q = M z + β q`` from the ``z``, ``M z`` that ``X1`` and ``W`` hold (a second pass, after ``β`` is known),
    and ``rz[q] = p·q``."""
    c = R.shape[0]
    if first:
        for q in range(c):
            x = X1[q, lo:hi]
            u = U[q, lo:hi]
            y = Y[q, lo:hi]
            w = W[q, lo:hi]
            r = R[q, lo:hi]
            t = d[lo:hi]
            acc = 0.0
            for i in range(hi - lo):
                z = x[i] - t[i] * u[i] + y[i]
                x[i] = z
                w[i] = r[i] + w[i]
                acc += r[i] * z
            rz[q] = acc
        return
    for q in range(c):
        b = beta[q]
        z = X1[q, lo:hi]
        mz = W[q, lo:hi]
        p = P[q, lo:hi]
        v = Q[q, lo:hi]
        acc = 0.0
        for i in range(hi - lo):
            a = z[i] + b * p[i]
            e = mz[i] + b * v[i]
            p[i] = a
            v[i] = e
            acc += a * e
        rz[q] = acc


def compile_kernels() -> None:
    """Compile every kernel above for ``(3, m)`` float64 vectors (a study's warm-up, before its clock)."""
    ptr = np.array([0, 0, 1], dtype=np.int64)  # (CsrGaussSeidel's parts: int64 pointers, the matrix's indices)
    idx = np.array([0], dtype=np.int32)
    val = np.array([0.5])
    rows = np.array([0, 1], dtype=np.int32)
    R, X, V, T = (np.ones((3, 2)) for _ in range(4))
    csr_forward_scatter(ptr, idx, val, ptr, idx, val, R, X, V, rows, True)
    csr_backward_scatter(ptr, idx, val, ptr, idx, val, R, X, V, rows, True)
    csr_gather_add(ptr, idx, val, X, V, rows)
    s = np.ones(2)
    smoothed_residual(s, T, V, 0, 2)
    smoothed_scale(s, V, T, 0, 2)
    out, beta = np.zeros(3), np.zeros(3)
    for first in (True, False):
        smoothed_direction(X, V, T, R, R.copy(), X.copy(), V.copy(), s, out, beta, 0, 2, first)
