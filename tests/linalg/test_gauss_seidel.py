"""quadnodes.linalg.gauss_seidel: the sweeps against dense triangular solves, and CG with them against a dense solve."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import quadnodes.linalg.threads as linalg_threads
from quadnodes.linalg._kernels import unit_backward_sweep, unit_forward_sweep
from quadnodes.linalg.cg import SymmetricDiagonalBlocks, block_cg
from quadnodes.linalg.gauss_seidel import SymmetricGaussSeidel, gauss_seidel_cg


def grid_matrix(rows: int, cols: int, seed: int, weight: float = 0.05) -> np.ndarray:
    """``AᵀA + ω I`` of random windows of four along every row and column of a grid (the fairing matrix's pattern)."""
    rng = np.random.default_rng(seed)
    n = rows * cols
    node = np.arange(n).reshape(rows, cols)
    lines = [node[r] for r in range(rows)] + [node[:, c] for c in range(cols)]
    A = [np.zeros(n) for line in lines for _ in range(len(line) - 3)]
    i = 0
    for line in lines:
        for j in range(len(line) - 3):
            A[i][line[j : j + 4]] = rng.normal(size=4)
            i += 1
    A = np.array(A).reshape(-1, n)
    return A.T @ A + weight * np.diag(rng.uniform(0.5, 2.0, n))


def blocks_of(M: np.ndarray, threads: int) -> SymmetricDiagonalBlocks:
    D = sp.dia_matrix(M)
    return SymmetricDiagonalBlocks(D.offsets, D.data, threads=threads)


@pytest.fixture
def small_ranges(monkeypatch):
    monkeypatch.setattr(linalg_threads, "PARALLEL_MIN_ROWS", 8)


@settings(max_examples=25, deadline=None)
@given(rows=st.integers(4, 24), cols=st.integers(4, 24), threads=st.integers(1, 3), c=st.sampled_from([1, 2, 3, 4]),
       seed=st.integers(0, 2**16))
def test_one_step_is_the_preconditioned_product_of_each_block(rows, cols, threads, c, seed):
    """One backward and one forward sweep give ``t = (I + Lᵀ)⁻¹ p`` and ``w = (I + L)⁻¹ (p − t + E t)`` with
    ``L`` the strictly lower part inside each thread's block and ``E`` the couplings between blocks (dense
    reference); both the open grid's fast path and the row-by-row path."""
    linalg_threads.PARALLEL_MIN_ROWS, saved = 8, linalg_threads.PARALLEL_MIN_ROWS
    try:
        M = grid_matrix(rows, cols, seed)
        blocks = blocks_of(M, threads)
    finally:
        linalg_threads.PARALLEL_MIN_ROWS = saved
    sw = SymmetricGaussSeidel(blocks)
    n = M.shape[0]
    s = 1.0 / np.sqrt(np.diag(M))
    Mt = M * s[:, None] * s[None, :]
    same = np.zeros((n, n), bool)
    for lo, hi in blocks.ranges:
        same[lo:hi, lo:hi] = True
    L = np.tril(np.where(same, Mt, 0.0), -1)
    E = np.where(same, 0.0, Mt)
    kp = -(-n // 64) * 64
    rng = np.random.default_rng(seed)
    R = np.zeros((c, kp))
    R[:, :n] = rng.normal(size=(c, n))
    P, T, W = np.zeros((c, kp)), np.zeros((c, kp)), np.zeros((c, kp))
    ranges = [(lo, kp if hi == n else hi) for lo, hi in blocks.ranges]
    for lo, hi in ranges:  # (β = 0: p = r)
        unit_backward_sweep(sw.upper, sw.offsets, R, P, T, np.zeros(c), np.empty((c, sw.row)), lo, hi)
    dots = np.zeros(c)
    for lo, hi in ranges:
        d = np.empty(c)
        unit_forward_sweep(sw.upper, sw.offsets, sw.forward_rows, P, T, W, np.empty((c, sw.row)), lo, hi, d)
        dots += d
    I = np.eye(n)
    t = np.linalg.solve(I + L.T, R[:, :n].T)
    w = np.linalg.solve(I + L, R[:, :n].T - t + E @ t)
    np.testing.assert_allclose(P[:, :n], R[:, :n])
    np.testing.assert_allclose(T[:, :n], t.T, rtol=1e-9, atol=1e-9 * np.abs(t).max())
    np.testing.assert_allclose(W[:, :n], w.T, rtol=1e-9, atol=1e-9 * np.abs(w).max())
    np.testing.assert_allclose(dots, np.einsum("ij,ji->i", R[:, :n], t + w), rtol=1e-9)
    Ahat = np.linalg.solve(I + L, Mt) @ np.linalg.inv(I + L.T)  # the preconditioned operator CG sees
    np.testing.assert_allclose((t + w).T, (Ahat @ R[:, :n].T).T, rtol=1e-8, atol=1e-8 * np.abs(t + w).max())


@pytest.mark.parametrize("threads", [1, 2, 3])
@pytest.mark.parametrize("shape", [(30, 40), (12, 9), (50, 5), (7, 60)])
def test_cg_with_the_sweeps_equals_the_dense_solve_in_fewer_steps(small_ranges, threads, shape):
    M = grid_matrix(*shape, seed=threads)
    blocks = blocks_of(M, threads)
    assert len(blocks.ranges) == threads
    rng = np.random.default_rng(7)
    B, X0 = rng.normal(size=(M.shape[0], 3)), rng.normal(size=(M.shape[0], 3))
    x, steps, res = block_cg(blocks, B, X0, rtol=1e-12, maxiter=2000, precond=SymmetricGaussSeidel(blocks))
    exact = np.linalg.solve(M, B)
    assert res <= 1e-12
    assert np.abs(M @ x - B).max() <= 1e-10 * np.abs(B).max()
    assert np.abs(x - exact).max() <= 1e-9 * np.abs(exact).max()
    _, plain, _ = block_cg(blocks, B, X0, rtol=1e-12, maxiter=5000)
    assert steps < plain / 2


def test_any_offsets_take_the_row_by_row_sweeps_and_any_column_count():
    """A band that is no open grid (offsets 1 and 5, a cylinder's seam, ...) is swept row by row."""
    n = 90
    M = sp.diags([0.3, -1.0, 4.0, -1.0, 0.3], [-5, -1, 0, 1, 5], shape=(n, n)).toarray()
    blocks = blocks_of(M, 1)
    sw = SymmetricGaussSeidel(blocks)
    assert sw.forward_rows.size == 0 and sw.row == 1
    B = np.random.default_rng(1).normal(size=(n, 2))
    x, steps, res = gauss_seidel_cg(blocks, B, np.zeros((n, 2)), rtol=1e-12, maxiter=500, sweeps=sw)
    np.testing.assert_allclose(x, np.linalg.solve(M, B), rtol=1e-9, atol=1e-10)
    assert res <= 1e-12 and steps > 0


def test_the_true_residual_decides_and_the_start_may_already_be_the_solution():
    M = grid_matrix(10, 10, seed=3)
    blocks = blocks_of(M, 1)
    B = np.random.default_rng(2).normal(size=(100, 3))
    exact = np.linalg.solve(M, B)
    x, steps, res = gauss_seidel_cg(blocks, B, exact, rtol=1e-9, maxiter=100)
    assert steps == 0 and res <= 1e-9 and np.array_equal(x, exact)
    x, steps, res = gauss_seidel_cg(blocks, B, np.zeros_like(B), rtol=1e-9, maxiter=3)  # capped: says so
    assert steps == 3 and res > 1e-9
    with pytest.raises(ValueError, match="rows"):
        gauss_seidel_cg(blocks, B[:50], B[:50], rtol=1e-9, maxiter=10)


def test_a_diagonal_that_is_not_positive_is_refused():
    M = grid_matrix(6, 6, seed=4)
    M[7, 7] = 0.0
    with pytest.raises(np.linalg.LinAlgError, match="diagonal entry 7"):
        SymmetricGaussSeidel(blocks_of(M, 1))


def test_a_matrix_that_is_not_positive_definite_stops_at_once_with_an_infinite_residual():
    """Positive diagonal, indefinite matrix: CG meets a direction with ``p·Âp ≤ 0`` and says so (the fairing
    falls back to the direct solver on a residual above rtol) instead of stepping to ``maxiter``."""
    n = 80
    M = sp.diags([-3.0, 1.0, -3.0], [-1, 0, 1], shape=(n, n)).toarray()  # diagonally far from dominant
    assert np.linalg.eigvalsh(M).min() < 0
    x, steps, res = gauss_seidel_cg(blocks_of(M, 1), np.ones((n, 3)), np.zeros((n, 3)), rtol=1e-9, maxiter=10_000)
    assert res == np.inf and steps < 100


@pytest.mark.parametrize("threads", [1, 2, 3])
@pytest.mark.parametrize("shuffle", [False, True])
@pytest.mark.parametrize("c", [3, 2])  # (x, y, z in registers; any other count in a loop)
def test_cg_with_csr_sweeps_equals_the_dense_solve_in_fewer_steps(small_ranges, threads, shuffle, c):
    """Compressed rows in any order (a shuffled numbering: a mesh that is no grid) — the sweeps row by row,
    each thread's block alone, the couplings between blocks as ``E t``."""
    from quadnodes.linalg.gauss_seidel import CsrGaussSeidel
    from quadnodes.linalg.threads import RowBlocks

    M = grid_matrix(20, 30, seed=threads)
    if shuffle:
        p = np.random.default_rng(threads).permutation(M.shape[0])
        M = M[p][:, p]
    blocks = RowBlocks(sp.csr_matrix(M), threads=threads)
    assert len(blocks.ranges) == threads
    rng = np.random.default_rng(8)
    B, X0 = rng.normal(size=(M.shape[0], c)), rng.normal(size=(M.shape[0], c))
    x, steps, res = block_cg(blocks, B, X0, rtol=1e-12, maxiter=3000, precond=CsrGaussSeidel(blocks))
    exact = np.linalg.solve(M, B)
    assert res <= 1e-12 and np.abs(x - exact).max() <= 1e-9 * np.abs(exact).max()
    _, plain, _ = block_cg(blocks, B, X0, rtol=1e-12, maxiter=5000)
    assert steps < plain / 2
