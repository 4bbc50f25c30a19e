"""quadnodes.linalg.gauss_seidel: the sweeps against dense triangular solves, and CG with them against a dense solve."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import quadnodes.linalg.threads as linalg_threads
from quadnodes.linalg.cg import SymmetricDiagonalBlocks, block_cg
from quadnodes.linalg.gauss_seidel import CsrGaussSeidel, SymmetricGaussSeidel, gauss_seidel_cg
from quadnodes.linalg.threads import RowBlocks


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


def one_step(sw, R: np.ndarray) -> tuple[np.ndarray, ...]:
    """P, T, W and the dots of one step from ``p = r`` (β = 0), run as gauss_seidel_cg runs it: the separators
    backward, every interior backward and forward, the separators forward (vectors in ``sw``'s layout)."""
    c = R.shape[0] if sw.columns else R.shape[1]
    P, T, W = np.zeros_like(R), np.zeros_like(R), np.zeros_like(R)
    S, beta = np.empty((c, sw.row)), np.zeros(c)
    dots = np.zeros(c)
    for part in sw.separators:
        sw.backward(R, P, T, beta, S, part)
    for part in sw.interiors:
        d = np.empty(c)
        sw.backward(R, P, T, beta, S, part)
        sw.forward(P, T, W, S, part, d)
        dots += d
    for part in sw.separators:
        d = np.empty(c)
        sw.forward(P, T, W, S, part, d)
        dots += d
    return P, T, W, dots


def check_one_step(Mt: np.ndarray, order: np.ndarray, R: np.ndarray, P, T, W, dots) -> None:
    """The step against dense solves: ``t = (I + U)⁻¹ r``, ``w = (I + L)⁻¹ (r − t)`` with ``L`` the strictly
    lower part of the whole scaled matrix in the sweeps' order (``order``: the rows in that order; ``(n, c)``)."""
    n = Mt.shape[0]
    Mo = Mt[np.ix_(order, order)]
    L, I = np.tril(Mo, -1), np.eye(n)
    r = R[order]
    t = np.linalg.solve(I + L.T, r)
    w = np.linalg.solve(I + L, r - t)
    np.testing.assert_allclose(P[order], r)
    np.testing.assert_allclose(T[order], t, rtol=1e-9, atol=1e-9 * np.abs(t).max())
    np.testing.assert_allclose(W[order], w, rtol=1e-9, atol=1e-9 * np.abs(w).max())
    np.testing.assert_allclose(dots, np.einsum("ij,ij->j", r, t + w), rtol=1e-9)
    Ahat = np.linalg.solve(I + L, Mo) @ np.linalg.inv(I + L.T)  # the preconditioned operator CG sees
    np.testing.assert_allclose(t + w, Ahat @ r, rtol=1e-8, atol=1e-8 * np.abs(t + w).max())


@settings(max_examples=25, deadline=None)
@given(rows=st.integers(4, 24), cols=st.integers(4, 24), threads=st.integers(1, 3), c=st.sampled_from([1, 2, 3, 4]),
       seed=st.integers(0, 2**16))
def test_one_step_is_the_symmetric_sweep_of_the_whole_matrix_interiors_first(rows, cols, threads, c, seed):
    """One step gives ``t = (I + U)⁻¹ p`` and ``w = (I + L)⁻¹ (p − t)``, ``L`` the strictly lower part of the
    whole matrix ordered interiors first and separators last (no coupling between threads left out); both
    the open grid's fast path and the row-by-row path, and the compressed rows' sweeps in their own order."""
    linalg_threads.PARALLEL_MIN_ROWS, saved = 8, linalg_threads.PARALLEL_MIN_ROWS
    try:
        M = grid_matrix(rows, cols, seed)
        blocks = blocks_of(M, threads)
        rows_blocks = RowBlocks(sp.csr_matrix(M), threads=threads)
    finally:
        linalg_threads.PARALLEL_MIN_ROWS = saved
    n = M.shape[0]
    s = 1.0 / np.sqrt(np.diag(M))
    Mt = M * s[:, None] * s[None, :]
    kp = -(-n // 64) * 64
    rng = np.random.default_rng(seed)
    r = rng.normal(size=(n, c))

    sw = SymmetricGaussSeidel(blocks)  # the grid's numbering, (c, m) vectors
    parts = sw.interiors + sw.separators
    order = np.concatenate([np.arange(p[0], p[1]) for p in parts])
    assert np.array_equal(np.sort(order), np.arange(n))  # every row in one part
    R = np.zeros((c, kp))
    R[:, :n] = r.T
    P, T, W, dots = one_step(sw, R)
    check_one_step(Mt, order, r, P[:, :n].T, T[:, :n].T, W[:, :n].T, dots)

    cs = CsrGaussSeidel(rows_blocks)  # compressed rows: (m, c) vectors, the rows of each block listed
    order = np.concatenate([p[0] for p in cs.interiors + cs.separators])
    assert np.array_equal(np.sort(order), np.arange(n))
    P, T, W, dots = one_step(cs, np.ascontiguousarray(r))
    check_one_step(Mt, order, r, P, T, W, dots)


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


@pytest.mark.parametrize("threads", [1, 2, 3])
@pytest.mark.parametrize("shape,wrap", [((30, 60), (False, True)), ((52, 56), (True, True)), ((52, 20), (True, False)),
                                        ((50, 64), (True, True))])  # (a periodic pair: fewer than 1 in 16 rows)
def test_a_closed_grid_takes_the_grid_sweeps_with_its_seams_outside_and_equals_the_dense_solve(small_ranges, threads,
                                                                                                shape, wrap):
    """A cylinder's or torus's periodic pairs stay out of the sweeps (``Âp = t + (I + L)⁻¹ (p − t + S̃ t)``): CG
    still solves the whole matrix, on one thread or several, in fewer steps than plain CG."""
    from quadnodes.linalg.grid import GridPattern
    from quadnodes.mesh import grid_faces
    from quadnodes.topology import Topology

    rows, cols = shape
    topo = Topology.from_faces(grid_faces(rows, cols, wrap_rows=wrap[0], wrap_cols=wrap[1]), rows * cols)
    rng = np.random.default_rng(threads)
    coef = rng.normal(size=(len(topo.windows), 4))
    free = np.ones(rows * cols, bool)
    free[rng.choice(rows * cols, 5, replace=False)] = False  # (identity rows, as fair's fixed vertices)
    pattern = GridPattern.closed_grid(rows, cols, [(0, 0, 1), (1, 0, cols), (0, 1, rows - 1)], wrap_rows=wrap[0],
                                      wrap_cols=wrap[1])
    offsets, data = pattern.normal_matrix(coef, free, 0.05)
    blocks = SymmetricDiagonalBlocks(offsets, data, threads=threads)
    assert SymmetricGaussSeidel.fits(blocks) and len(blocks.ranges) == threads
    sweeps = SymmetricGaussSeidel(blocks)
    assert sweeps.seam is not None
    M = sp.dia_matrix((data, offsets), shape=(rows * cols,) * 2).toarray()
    B, X0 = rng.normal(size=(rows * cols, 3)), rng.normal(size=(rows * cols, 3))
    x, steps, res = block_cg(blocks, B, X0, rtol=1e-12, maxiter=3000, precond=sweeps)
    exact = np.linalg.solve(M, B)
    assert res <= 1e-12
    assert np.abs(x - exact).max() <= 1e-9 * np.abs(exact).max()
    _, plain, _ = block_cg(blocks, B, X0, rtol=1e-12, maxiter=8000)
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
    interiors on the threads, separators after them (a shuffled numbering has no interiors to speak of:
    one thread sweeps)."""
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


@pytest.mark.parametrize("kind", ["grid", "rows"])
def test_threads_keep_every_coupling_so_they_take_about_the_steps_of_one(small_ranges, kind):
    """Interiors first and separators last is a Gauss–Seidel sweep of the whole matrix: on 2 and 3 threads
    the steps stay those of one thread within a few (dropping the couplings between ranges cost a quarter)."""
    M = grid_matrix(60, 12, seed=5)
    rng = np.random.default_rng(9)
    B = rng.normal(size=(M.shape[0], 3))
    exact = np.linalg.solve(M, B)
    steps = {}
    for t in (1, 2, 3):
        blocks = blocks_of(M, t) if kind == "grid" else RowBlocks(sp.csr_matrix(M), threads=t)
        sw = SymmetricGaussSeidel(blocks) if kind == "grid" else CsrGaussSeidel(blocks)
        assert len(sw.interiors) == t and len(sw.separators) == (t - 1 if kind == "grid" else int(t > 1))
        x, steps[t], res = gauss_seidel_cg(blocks, B, np.zeros_like(B), rtol=1e-12, maxiter=3000, sweeps=sw)
        assert res <= 1e-12 and np.abs(x - exact).max() <= 1e-9 * np.abs(exact).max()
    assert max(abs(steps[t] - steps[1]) for t in (2, 3)) <= max(2, steps[1] // 10), steps


def test_a_numbering_without_locality_sweeps_on_one_thread(small_ranges):
    M = grid_matrix(20, 30, seed=1)
    p = np.random.default_rng(1).permutation(M.shape[0])
    cs = CsrGaussSeidel(RowBlocks(sp.csr_matrix(M[p][:, p]), threads=2))
    assert len(cs.interiors) == 1 and not cs.separators


def test_a_monitor_sees_every_step_and_may_stop_the_solve():
    """``monitor(step, residual)`` is called after every step with the preconditioned residual relative to its
    right-hand side; returning True ends the solve there, with the iterate of a run capped at that step."""
    n = 60
    M = sp.diags([1.0, -4.0, 6.01, -4.0, 1.0], [-2, -1, 0, 1, 2], shape=(n, n)).todia()
    blocks = SymmetricDiagonalBlocks(M.offsets, M.data, threads=1)
    b = np.random.default_rng(0).normal(size=(n, 3))
    seen: list[tuple[int, float]] = []

    def monitor(step: int, residual: float) -> bool:
        seen.append((step, residual))
        return step == 7

    x, steps, res = gauss_seidel_cg(blocks, b, np.zeros_like(b), rtol=1e-12, maxiter=500, monitor=monitor)
    capped, capped_steps, capped_res = gauss_seidel_cg(blocks, b, np.zeros_like(b), rtol=1e-12, maxiter=7)
    assert steps == capped_steps == 7 and [s for s, _ in seen] == list(range(1, 8))
    assert np.array_equal(x, capped) and res == capped_res > 1e-12
    assert all(r > 0 for _, r in seen) and seen[-1][1] < seen[0][1]
    full, full_steps, full_res = gauss_seidel_cg(blocks, b, np.zeros_like(b), rtol=1e-12, maxiter=500,
                                                 monitor=lambda step, residual: False)
    assert full_res <= 1e-12 and full_steps > 7
