"""The threaded block CG, its row ranges, block Jacobi, diagonal storage and the BLAS pin."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from quadnodes.linalg import cg as linalg_cg
from quadnodes.linalg import threads as linalg_threads
from quadnodes.linalg.cg import BlockJacobi, DiagonalBlocks, block_cg, permuted
from quadnodes.linalg.threads import RowBlocks, blas_pinned


def _poisson(n: int, shift: float = 0.01) -> sp.csr_matrix:
    T = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n))
    return (sp.kronsum(T, T) + shift * sp.identity(n * n)).tocsr()


@pytest.mark.parametrize("threads", [1, 2, 3])
@pytest.mark.parametrize("columns", [True, False])
@pytest.mark.parametrize("jacobi", [False, True])
def test_block_cg_solves_every_column(monkeypatch, threads, columns, jacobi):
    monkeypatch.setattr(linalg_threads, "PARALLEL_MIN_ROWS", 10)
    monkeypatch.setattr(linalg_threads, "thread_count", lambda: threads)
    monkeypatch.setattr(linalg_threads, "COLUMNS_MAX_NNZ", 10**9 if columns else 0)
    M = _poisson(30)
    rng = np.random.default_rng(0)
    B = rng.normal(size=(M.shape[0], 3))
    blocks = RowBlocks(M)
    assert len(blocks.ranges) == threads and blocks.columns == columns
    pre = BlockJacobi(M, 16) if jacobi else None
    x, steps, res = block_cg(blocks, B, np.zeros_like(B), rtol=1e-11, maxiter=5000, precond=pre)
    assert res <= 1e-11 and steps > 0
    np.testing.assert_allclose(x, sp.linalg.spsolve(M.tocsc(), B), atol=1e-8)


def test_diagonal_storage_equals_csr_products(monkeypatch):
    monkeypatch.setattr(linalg_threads, "PARALLEL_MIN_ROWS", 10)
    monkeypatch.setattr(linalg_threads, "thread_count", lambda: 2)
    M = _poisson(20).todia()
    d = DiagonalBlocks(M.offsets, M.data)
    assert len(d.ranges) == 2
    X = np.random.default_rng(1).normal(size=(3, M.shape[0]))
    Y = np.empty_like(X)
    for lo, hi in d.ranges:
        d.matvec(X, Y, lo, hi)
    np.testing.assert_allclose(Y, (M @ X.T).T, atol=1e-12)


def test_permuted_is_a_symmetric_permutation():
    M = _poisson(9)
    order = np.random.default_rng(2).permutation(M.shape[0])
    np.testing.assert_array_equal(permuted(M, order).toarray(), M.toarray()[order][:, order])


@pytest.mark.parametrize("block", [1, 4, 16])
def test_block_jacobi_inverts_its_diagonal_blocks_in_both_layouts(block: int) -> None:
    """Each block of ``block`` consecutive unknowns solved exactly, in the (c, n) and (n, c) layouts alike; the
    padding past the last whole block untouched by the solve's rows."""
    M = _poisson(11)  # (121 unknowns: the last block partial for 4 and 16)
    bj = BlockJacobi(M, block)
    D = M.toarray()
    n = M.shape[0]
    R = np.zeros((3, bj.inv.shape[0] * block))
    R[:, :n] = np.random.default_rng(0).normal(size=(3, n))
    Z = np.empty_like(R)
    bj.apply(R, Z, 0, R.shape[1], True)
    Zr = np.empty_like(R.T)
    bj.apply(np.ascontiguousarray(R.T), Zr, 0, R.shape[1], False)
    np.testing.assert_allclose(Zr, Z.T, rtol=1e-12, atol=1e-12)
    for b in range(n // block):
        blk = slice(block * b, block * b + block)
        np.testing.assert_allclose(D[blk, blk] @ Z[:, blk].T, R[:, blk].T, rtol=1e-10, atol=1e-10)


def test_blas_is_pinned_to_one_thread_inside_and_restored_after():
    from threadpoolctl import threadpool_info

    before = [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]
    with blas_pinned():
        inside = [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]
    after = [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]
    assert inside and all(t == 1 for t in inside)
    assert after == before


def test_blas_libraries_are_scanned_again_only_when_a_shared_object_was_loaded():
    """The BLAS scan (threadpoolctl, ~20 ms) is kept while no shared object arrives; a new one makes
    blas_pinned look again (a BLAS can only arrive that way). In a child: the test process's own
    modules stay as they are."""
    code = textwrap.dedent(
        """
        import sys
        from quadnodes.linalg import threads
        threads.prime_blas_controller()
        first = threads._CONTROLLER
        with threads.blas_pinned():
            pass
        assert threads._CONTROLLER is first  # nothing new loaded: no second scan
        import importlib, importlib.util
        name = next(m for m in ("_ctypes_test", "_sqlite3", "_curses", "_lzma", "_dbm", "_bz2", "readline")
                    if m not in sys.modules
                    and str(getattr(importlib.util.find_spec(m), "origin", "")).endswith(".so"))
        n = threads._library_count()
        importlib.import_module(name)  # an extension module: one more shared object
        assert threads._library_count() > n
        with threads.blas_pinned():
            pass
        assert threads._CONTROLLER is not first and threads._CONTROLLER[0] == threads._library_count()
        print("ok")
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"


def test_block_cg_pins_blas_only_where_it_may_call_it():
    """Threaded passes without a preconditioner call no BLAS (no pin, no library scan); block Jacobi's
    batched matmul and a single range's BLAS level-1 updates are pinned. In a child: a fresh scan state."""
    code = textwrap.dedent(
        """
        import numpy as np, scipy.sparse as sp
        from quadnodes.linalg import threads
        from quadnodes.linalg.cg import BlockJacobi, block_cg, permuted
        from quadnodes.linalg.threads import RowBlocks
        threads.PARALLEL_MIN_ROWS = 10
        threads.thread_count = lambda: 2
        n = 400
        M = (sp.diags([-1.0, 2.5, -1.0], [-1, 0, 1], shape=(n, n))).tocsr()
        b = np.ones((n, 3))
        x, _, res = block_cg(RowBlocks(M), b, np.zeros((n, 3)), rtol=1e-10, maxiter=500)
        assert len(RowBlocks(M).ranges) == 2 and res <= 1e-10
        assert threads._CONTROLLER is None  # never scanned: nothing was pinned
        block_cg(RowBlocks(M), b, np.zeros((n, 3)), rtol=1e-10, maxiter=500, precond=BlockJacobi(M, 64))
        assert threads._CONTROLLER is not None
        print("ok")
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"


def _solve_in_child(queue):
    linalg_threads.PARALLEL_MIN_ROWS = 10
    linalg_threads.thread_count = lambda: 2
    M = _poisson(20)
    blocks = RowBlocks(M)
    x, _, res = block_cg(blocks, np.ones((M.shape[0], 3)), np.zeros((M.shape[0], 3)), rtol=1e-10, maxiter=2000)
    queue.put((len(blocks.ranges), res))


@pytest.mark.skipif(not hasattr(__import__("os"), "fork"), reason="needs fork")
def test_the_pool_works_in_a_forked_child(monkeypatch):
    import multiprocessing

    monkeypatch.setattr(linalg_threads, "PARALLEL_MIN_ROWS", 10)
    monkeypatch.setattr(linalg_threads, "thread_count", lambda: 2)
    M = _poisson(20)
    block_cg(RowBlocks(M), np.ones((M.shape[0], 3)), np.zeros((M.shape[0], 3)), rtol=1e-10, maxiter=2000)
    assert linalg_threads.pool() is not None  # the parent's pool exists before the fork
    ctx = multiprocessing.get_context("fork")
    queue = ctx.Queue()
    child = ctx.Process(target=_solve_in_child, args=(queue,))
    child.start()
    child.join(timeout=60)
    assert child.exitcode == 0
    ranges, residual = queue.get(timeout=5)
    assert ranges == 2 and residual <= 1e-10


@pytest.mark.parametrize("rows, cols, threads", [(7, 9, 1), (19, 11, 1), (19, 11, 2), (33, 5, 2), (4, 40, 2)])
def test_line_preconditioner_is_the_sum_of_the_two_families_block_inverses(monkeypatch, rows, cols, threads):
    """Against dense solves, for line counts that do and do not fill the kernels' blocks of 8
    lines, on one and two threads."""
    from quadnodes.linalg.cg import LinePreconditioner

    if threads > 1:
        monkeypatch.setattr(linalg_threads, "PARALLEL_MIN_ROWS", 10)
        monkeypatch.setattr(linalg_cg, "LINES_PARALLEL_MIN_ROWS", 10)
        monkeypatch.setattr(linalg_threads, "thread_count", lambda: threads)
    n = rows * cols
    rng = np.random.default_rng(3)
    # random SPD bands along rows (offsets 1..3) and along columns (offsets cols..3 cols)
    def band(step, length, count):
        A = np.zeros((n, n))
        for line in range(count):
            idx = (np.arange(length) * step + line * (cols if step == 1 else 1))
            B = rng.normal(size=(length + 3, length))
            for i in range(length):
                B[i + 4:, i] = 0.0
                B[: max(i - 3, 0), i] = 0.0
            A[np.ix_(idx, idx)] += B.T @ B * np.tri(length, length, 3) * np.tri(length, length, 3).T
        return A
    Ar, Ac = band(1, cols, rows), band(cols, rows, cols)
    D = np.diag(np.abs(Ar).sum(1) + np.abs(Ac).sum(1) + 0.5 + rng.random(n))  # (masking a band loses definiteness)
    B1, B2 = Ar + D, Ac + D
    def ab(A, step):  # upper banded form in the nodes' order: row 3 - k holds A[j - k·step, j]
        return np.vstack([np.r_[np.zeros(k * step), np.diag(A, k * step)] for k in (3, 2, 1, 0)])
    P = LinePreconditioner(ab(B1, 1), ab(B2, cols), cols)
    assert len(P._col_ranges) == threads  # the column lines split over the threads
    kp = -(-n // 64) * 64
    R = np.zeros((3, kp))
    R[:, :n] = rng.normal(size=(3, n))
    Z = np.full_like(R, np.nan)
    P.apply(R, Z, 0, kp, True)
    ref = np.linalg.solve(B1, R[:, :n].T) + np.linalg.solve(B2, R[:, :n].T)
    np.testing.assert_allclose(Z[:, :n].T, ref, atol=1e-10)
    assert not Z[:, n:].any()
    Zr = np.full((kp, 3), np.nan)
    P.apply(np.ascontiguousarray(R.T), Zr, 0, kp, False)  # (n, c) layout
    np.testing.assert_allclose(Zr, Z.T, atol=1e-12)
    Z2 = np.full_like(R, np.nan)
    P.apply(R, Z2, 0, kp, True)  # the same operator every time (CG needs a fixed one)
    np.testing.assert_array_equal(Z2, Z)


@settings(max_examples=40, deadline=None)
@given(rows=st.integers(1, 20), cols=st.integers(4, 12), c=st.integers(1, 3), seed=st.integers(0, 2**31),
       cut=st.floats(0, 1))
def test_symmetric_diagonal_storage_equals_the_full_product(rows, cols, c, seed, cut):
    """Whole products and products cut into two row ranges anywhere (on grids of 7 rows and more the
    rows away from both ends take the 7-diagonal kernel, the others the general one)."""
    from quadnodes.linalg.cg import SymmetricDiagonalBlocks

    n = rows * cols
    rng = np.random.default_rng(seed)
    offsets = np.array([-3 * cols, -2 * cols, -cols, -3, -2, -1, 0, 1, 2, 3, cols, 2 * cols, 3 * cols])
    A = sp.random(n, n, density=0.5, random_state=rng.integers(2**31)).toarray()
    keep = np.zeros((n, n), bool)
    for o in offsets:
        keep |= np.eye(n, k=o, dtype=bool)
    A = np.where(keep, A + A.T, 0.0)
    M = sp.dia_matrix(A)
    data = np.zeros((13, n))
    for d, o in enumerate(offsets):  # data[d, j] = A[j - o, j]
        j = np.arange(max(o, 0), min(n, n + o))
        data[d, j] = A[j - o, j]
    blocks = SymmetricDiagonalBlocks(offsets, data)
    kp = -(-n // 64) * 64
    X = np.zeros((c, kp))
    X[:, :n] = rng.normal(size=(c, n))
    Y = np.full_like(X, np.nan)
    blocks.run(lambda lo, hi: blocks.matvec(X, Y, lo, hi))
    ref = (M @ X[:, :n].T).T
    np.testing.assert_allclose(Y[:, :n], ref, rtol=1e-12, atol=1e-12)
    split = int(cut * n)
    Y2 = np.full_like(X, np.nan)
    blocks.matvec(X, Y2, 0, split)
    blocks.matvec(X, Y2, split, n)
    np.testing.assert_allclose(Y2[:, :n], ref, rtol=1e-12, atol=1e-12)
    assert np.isnan(Y2[:, n:]).all()  # padding columns are neither read nor written


def test_line_preconditioner_refuses_a_block_that_is_not_positive_definite():
    from quadnodes.linalg.cg import LinePreconditioner

    band = np.vstack([np.zeros((3, 12)), np.ones((1, 12))])
    bad = band.copy()
    bad[2, 5] = 3.0  # |M[4, 5]| > 1: the 2 × 2 block is indefinite
    with pytest.raises(np.linalg.LinAlgError, match="row lines"):
        LinePreconditioner(bad, band, 4)
    with pytest.raises(np.linalg.LinAlgError, match="column lines"):
        LinePreconditioner(band, np.vstack([np.zeros((2, 12)), np.r_[np.zeros(4), 3.0 * np.ones(8)], np.ones(12)]), 4)
    with pytest.raises(ValueError, match="rows of 5"):
        LinePreconditioner(band, band, 5)


def _path_matrix(rng, paths, kd, k, closed):
    """An SPD matrix whose couplings run along the paths (up to kd steps, around a closed path's seam)."""
    rows, cols, vals = [], [], []
    for p, c in zip(paths, closed):
        L = len(p)
        for d in range(1, kd + 1):
            pairs = [(i, i + d) for i in range(L - d)] + ([(i, (i + d) % L) for i in range(L - d, L)] if c else [])
            for i, j in pairs:
                if p[i] == p[j]:
                    continue
                v = rng.uniform(-1.0, 0.2)
                rows += [p[i], p[j]]
                cols += [p[j], p[i]]
                vals += [v, v]
    A = sp.csr_matrix((vals, (rows, cols)), shape=(k, k))
    A.sum_duplicates()
    d = np.asarray(abs(A).sum(axis=1)).ravel() + rng.uniform(0.1, 1.0, size=k)  # diagonally dominant
    return (A + sp.diags(d)).tocsr()


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000), st.booleans())
def test_path_line_preconditioner_is_the_sum_of_the_band_inverses(seed, closed):
    from quadnodes.linalg import compiled
    from quadnodes.linalg.cg import PathLinePreconditioner

    assert compiled.wait()
    rng = np.random.default_rng(seed)
    k = int(rng.integers(12, 40))
    paths = [rng.permutation(k)[: int(rng.integers(5, 12))] for _ in range(int(rng.integers(2, 5)))]
    flags = [closed and i % 2 == 0 for i in range(len(paths))]
    M = _path_matrix(rng, paths, 3, k, flags)
    path = np.concatenate(paths)
    starts = np.concatenate([np.r_[True, np.zeros(len(p) - 1, bool)] for p in paths])
    ring = np.concatenate([np.r_[c, np.zeros(len(p) - 1, bool)] for p, c in zip(paths, flags)])
    P = PathLinePreconditioner(M, path, starts, ring)
    # reference: every path's band of M (off-diagonals within 3 steps, whole diagonal; a closed path's
    # couplings across the seam moved onto the diagonal as absolute values), inverted densely, summed
    D = M.toarray()
    ref = np.zeros((k, k))
    for p, c in zip(paths, flags):
        L = len(p)
        B = np.diag(D[p, p])
        for i in range(L):
            for j in range(i + 1, min(L, i + 4)):
                B[i, j] = B[j, i] = D[p[i], p[j]]
            for j in range(i + 4, L):
                if c and (i + L - j) <= 3:  # around the seam, beyond the band
                    B[i, i] += abs(D[p[i], p[j]])
                    B[j, j] += abs(D[p[i], p[j]])
        E = np.zeros((k, L))
        E[p, np.arange(L)] = 1.0
        ref += E @ np.linalg.inv(B) @ E.T
    lone = np.setdiff1d(np.arange(k), path)
    ref[lone, lone] += 1.0 / D[lone, lone]
    R = rng.normal(size=(3, k))
    Z = np.empty_like(R)
    P.apply(R, Z, 0, k, True)
    np.testing.assert_allclose(Z, (ref @ R.T).T, rtol=1e-9, atol=1e-12)
    Zt = np.empty((k, 3))
    P.apply(np.ascontiguousarray(R.T), Zt, 0, k, False)
    np.testing.assert_allclose(Zt, Z.T, rtol=1e-12, atol=1e-14)
    with pytest.MonkeyPatch.context() as mp:  # the paths in two stretches on two threads: the same operator
        mp.setattr(linalg_cg, "LINES_PARALLEL_MIN_ROWS", 0)
        mp.setattr(linalg_threads, "thread_count", lambda: 2)
        P2 = PathLinePreconditioner(M, path, starts, ring)
    assert 0 < P2._cut < path.size and starts[P2._cut]
    for columns, shape in ((True, (3, k)), (False, (k, 3))):
        Z2 = np.full(shape, np.nan)
        P2.apply(R if columns else np.ascontiguousarray(R.T), Z2, 0, k, columns)
        np.testing.assert_allclose(Z2 if columns else Z2.T, Z, rtol=1e-12, atol=1e-14)
    # as a preconditioner, in both vector layouts: CG reaches the direct solve
    for columns in (True, False):
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(linalg_threads, "COLUMNS_MAX_NNZ", 10**9 if columns else 0)
            blocks = RowBlocks(M)
            assert blocks.columns == columns
            x, steps, res = block_cg(blocks, R.T.copy(), np.zeros((k, 3)), rtol=1e-12, maxiter=500, precond=P)
        np.testing.assert_allclose(x, np.linalg.solve(D, R.T), atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10_000), st.integers(1, 3))
def test_strongest_lines_against_a_plain_count(seed, kd):
    """Each entry's tie (the mean ``|M|`` to the entries up to ``kd`` steps along its path, none across paths), each
    unknown's strongest over its weakest (1 on fewer than two paths, within ``kd`` of a path's end, or tied to
    none), and one strongest entry per
    unknown on a path (the first of equals), against loops over the paths."""
    from quadnodes.linalg.cg import strongest_lines

    rng = np.random.default_rng(seed)
    k = int(rng.integers(8, 30))
    paths = [rng.permutation(k)[: int(rng.integers(1, 16))] for _ in range(int(rng.integers(1, 6)))]
    M = _path_matrix(rng, paths, 3, k, [False] * len(paths))
    if rng.random() < 0.3:  # (equal ties: the first entry wins)
        M.data[:] = np.sign(M.data)
    if rng.random() < 0.3:  # (ties of 0: a path that does not tie its unknowns at all)
        keep = np.triu(rng.random(M.shape) < 0.5, 1)
        M = sp.csr_matrix(M.multiply(keep | keep.T) + sp.diags(M.diagonal()))  # (symmetric, as M must be)
    path = np.concatenate(paths)
    starts = np.concatenate([np.r_[True, np.zeros(len(p) - 1, bool)] for p in paths])
    ratio, strongest = strongest_lines(M, path, starts, kd=kd)
    D = np.abs(M.toarray())
    ties, nears, entry = [], [], 0
    best: dict[int, tuple[float, int]] = {}
    for p in paths:
        for i, v in enumerate(p):
            near = [j for j in range(max(0, i - kd), min(len(p), i + kd + 1)) if j != i]
            tie = sum(D[v, p[j]] for j in near) / max(len(near), 1)
            ties.append(tie)
            nears.append(near)
            if v not in best or tie > best[v][0]:
                best[v] = (tie, entry)
            entry += 1
    for v in range(k):
        mine = [t for t, u in zip(ties, path) if u == v]
        whole = all(len(near) == 2 * kd for near, u in zip(nears, path) if u == v)
        if len(mine) >= 2 and whole and max(mine) > 0:
            want = max(mine) / min(mine) if min(mine) > 0 else np.inf
        else:
            want = 1.0
        assert ratio[v] == pytest.approx(want, rel=1e-12)
    assert np.array_equal(np.flatnonzero(strongest), np.sort([e for _, e in best.values()]))


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000), st.integers(1, 4))
def test_the_unrolled_band_solve_equals_the_general_one_to_the_bit(seed, stretches):
    """``path_band_solve_xyz`` (half-bandwidth 3, three columns) against ``path_band_solve`` on the same factor:
    paths of 1 to 12 unknowns end to end (shorter than the band too), repeats, a solve of a middle stretch only,
    adding into what ``Z`` holds; equal to the last bit."""
    from scipy.linalg import cholesky_banded

    from quadnodes.linalg import compiled
    from quadnodes.linalg._kernels import path_band_solve, path_band_solve_xyz

    assert compiled.wait()
    rng = np.random.default_rng(seed)
    k = int(rng.integers(10, 40))
    paths = [rng.integers(0, k, size=int(rng.integers(1, 13))) for _ in range(stretches)]
    S = sum(len(p) for p in paths)
    band = np.zeros((4, S))
    band[3] = 4.0 + rng.random(S)
    first = np.cumsum([0] + [len(p) for p in paths])[:-1]
    for d in (1, 2, 3):
        band[3 - d, d:] = rng.uniform(-0.5, 0.5, size=max(S - d, 0))
        for f in first:  # (no coupling across paths)
            band[3 - d, f : f + d] = 0.0
    F = cholesky_banded(band, lower=False, check_finite=False)
    path = np.concatenate(paths).astype(np.int64)
    R = rng.normal(size=(k, 3))
    a = int(first[int(rng.integers(0, stretches))])
    for lo, hi in ((0, S), (a, S)):
        Z0 = rng.normal(size=(k, 3))
        outs = []
        for solve in (path_band_solve, path_band_solve_xyz):
            Z = Z0.copy()
            solve(F, 1.0 / F[3], path, R, Z, np.empty((S, 3)), lo, hi)
            outs.append(Z)
        assert np.array_equal(outs[0], outs[1])


def test_path_line_preconditioner_refuses_a_band_that_is_not_positive_definite():
    from quadnodes.linalg import compiled
    from quadnodes.linalg.cg import PathLinePreconditioner

    assert compiled.wait()
    M = sp.csr_matrix(np.array([[1.0, 2.0, 0], [2.0, 1.0, 0], [0, 0, 1.0]]))
    with pytest.raises(np.linalg.LinAlgError):
        PathLinePreconditioner(M, np.array([0, 1, 2]), np.array([True, False, False]))


@pytest.mark.parametrize("kind", ["torus 7x9", "torus 48x60", "cylinder 12x30", "torus 80x96", "cylinder 100x90"])
def test_symmetric_diagonal_storage_of_closed_grids_equals_the_full_product(kind):
    """A cylinder's or torus's fairing matrix in diagonal storage (the periodic pairs after the first 13 offsets,
    their upper offsets out of order): the compiled symmetric product equals SciPy's, whole and cut — the
    periodic pairs read as diagonals on a small grid, as a list of entries where they hold fewer than one entry in
    SPARSE_DIAGONAL_FRACTION (the larger two)."""
    from quadnodes.fairing import grid_pattern, window_coefficients
    from quadnodes.linalg.cg import SPARSE_DIAGONAL_FRACTION, SymmetricDiagonalBlocks
    from quadnodes.mesh import cylinder, torus

    name, size = kind.split()
    a, b = (int(v) for v in size.split("x"))
    m = torus(a, b, major=800.0, minor=200.0) if name == "torus" else cylinder(a, b, radius=500.0, height=900.0)
    rng = np.random.default_rng(3)
    m = m.with_vertices(m.vertices + rng.normal(scale=0.2 * m.mean_edge_length, size=m.vertices.shape))
    pattern = grid_pattern(m.topology)
    assert pattern is not None and pattern.offsets.size > 13
    offsets, data = pattern.normal_matrix(window_coefficients(m.vertices, m.topology.windows),
                                          np.ones(m.n_vertices, bool), 0.3)
    n = data.shape[1]
    blocks = SymmetricDiagonalBlocks(offsets, data)
    periodic = np.count_nonzero(blocks.upper, axis=1)[7:]  # (3 entries a line at most)
    assert (blocks._seam is not None) == bool((periodic * SPARSE_DIAGONAL_FRACTION < n).all())
    assert (blocks._seam is not None) == (kind in ("torus 80x96", "cylinder 100x90"))
    if blocks._seam is not None:  # the open grid's seven diagonals, the kernel's fast rows
        assert blocks._dense[1].tolist() == [0, 1, 2, 3, b, 2 * b, 3 * b]
    X = np.zeros((3, -(-n // 64) * 64))
    X[:, :n] = rng.normal(size=(3, n))
    ref = (sp.dia_matrix((data, offsets), shape=(n, n)) @ X[:, :n].T).T
    Y = np.full_like(X, np.nan)
    blocks.run(lambda lo, hi: blocks.matvec(X, Y, lo, hi))
    np.testing.assert_allclose(Y[:, :n], ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
    Y2 = np.full_like(X, np.nan)
    blocks.matvec(X, Y2, 0, n // 3)
    blocks.matvec(X, Y2, n // 3, n)
    np.testing.assert_allclose(Y2[:, :n], ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
