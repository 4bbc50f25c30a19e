"""quadnodes.linalg.multigrid: the interpolation against polynomials, the cycle against its dense formula, CG with it."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import quadnodes.linalg.threads as linalg_threads
from quadnodes.linalg import compiled
from quadnodes.linalg.cg import DiagonalBlocks, SymmetricDiagonalBlocks, block_cg
from quadnodes.linalg.multigrid import LineTwoGrid, TwoGrid, cubic_interpolation, grid_interpolation, line_interpolation
from quadnodes.linalg.threads import RowBlocks
from quadnodes.mesh import QuadMesh, cylinder, grid, torus
from quadnodes.topology import structure_lines

from meshes import extraordinary_mesh, l_shape_with_hole

pytestmark = pytest.mark.skipif(not compiled.wait(), reason="the compiled kernels (Numba) are not available")


def line_matrix(rows: int, cols: int, weight: float, seed: int = 0,
                closed: tuple[bool, bool] = (False, False)) -> np.ndarray:
    """``AᵀA + ω I`` of third differences along every row and column of a grid, each window scaled at random.

    Like the fairing matrix, the line energy does not see a motion that is quadratic along the lines, so at
    a small ω the smooth modes are slow. ``closed``: the columns' and the rows' windows wrap around (a
    cylinder's or a torus's lines)."""
    rng = np.random.default_rng(seed)
    node = np.arange(rows * cols).reshape(rows, cols)
    lines = [(node[r], closed[1]) for r in range(rows)] + [(node[:, c], closed[0]) for c in range(cols)]
    windows = [np.take(line, np.arange(j, j + 4), mode="wrap") for line, wrap in lines
               for j in range(len(line) if wrap else len(line) - 3)]
    A = np.zeros((len(windows), rows * cols))
    for i, window in enumerate(windows):
        A[i, window] = np.array([-1.0, 3.0, -3.0, 1.0]) * rng.uniform(0.5, 2.0)
    return A.T @ A + weight * np.eye(rows * cols)


def with_fixed(M: np.ndarray, fixed: np.ndarray) -> np.ndarray:
    """``M`` with the ``fixed`` vertices as identity rows and columns (the grid path's numbering)."""
    M = M.copy()
    M[fixed] = 0.0
    M[:, fixed] = 0.0
    M[fixed, fixed] = 1.0
    return M


def blocks_of(M: np.ndarray, threads: int, closed: tuple[bool, bool] = (False, False)) -> DiagonalBlocks:
    """The grid path's storage: symmetric diagonals on an open grid, plain ones (the seams') on a closed one."""
    D = sp.dia_matrix(M)
    return (DiagonalBlocks if any(closed) else SymmetricDiagonalBlocks)(D.offsets, D.data, threads=threads)


@settings(max_examples=60, deadline=None)
@given(st.integers(2, 40), st.integers(2, 6), st.integers(0, 3))
def test_cubic_interpolation_is_exact_on_polynomials_up_to_its_degree(n, stride, degree):
    P = cubic_interpolation(n, stride)
    coarse = np.unique(np.r_[np.arange(0, n, stride), n - 1])
    assert P.shape == (n, coarse.size)
    t = np.linspace(-1.0, 1.0, n)
    if degree <= min(3, coarse.size - 1):
        assert np.allclose(P @ t[coarse] ** degree, t**degree, atol=1e-12)
    assert np.array_equal(P[coarse].toarray(), np.eye(coarse.size))  # a coarse node is copied
    assert np.allclose(np.asarray(P.sum(axis=1)).ravel(), 1.0)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 30), st.integers(2, 5), st.integers(0, 3))
def test_closed_cubic_interpolation_is_exact_on_polynomials_around_each_node(extra, stride, degree):
    """On a closed line every fine node takes the cubic through the two coarse nodes on each side, counted
    across the seam: a polynomial in the distance along the line, centred at the node, is reproduced there
    (on lines of 8 coarse intervals or more, where those four nodes lie within half the line)."""
    n = 8 * stride + extra
    P = cubic_interpolation(n, stride, closed=True)
    coarse = np.arange(0, n, stride)
    assert P.shape == (n, coarse.size)
    assert np.array_equal(P[coarse].toarray(), np.eye(coarse.size))  # a coarse node is copied
    assert np.allclose(np.asarray(P.sum(axis=1)).ravel(), 1.0)
    for i in range(n):
        # each coarse node's signed distance to i around the closed line, in (-n/2, n/2]
        d = (coarse - i + n // 2) % n - n // 2
        assert np.isclose(P[i] @ (d / n) ** degree, 0.0 ** degree, atol=1e-12), i
    if n % stride == 0:  # turning the line by a coarse interval turns the interpolation with it
        c = np.random.default_rng(n).normal(size=coarse.size)
        assert np.allclose(P @ np.roll(c, 1), np.roll(P @ c, stride), atol=1e-12)


def test_cubic_interpolation_refuses_a_line_or_stride_too_short():
    with pytest.raises(ValueError, match="stride"):
        cubic_interpolation(10, 1)
    with pytest.raises(ValueError, match="n >= 2"):
        cubic_interpolation(1, 4)
    with pytest.raises(ValueError, match="3 coarse nodes.*at least 4"):
        cubic_interpolation(12, 4, closed=True)


def test_grid_interpolation_is_the_tensor_product_with_fixed_rows_zero():
    moving = np.ones(9 * 14, bool)
    moving[[0, 13, 50]] = False
    P = grid_interpolation(9, 14, 4, moving).toarray()
    full = np.kron(cubic_interpolation(9, 4).toarray(), cubic_interpolation(14, 4).toarray())
    assert np.array_equal(P[moving], full[moving]) and not P[~moving].any()
    torus = grid_interpolation(16, 20, 4, wrap=(True, True)).toarray()
    assert np.array_equal(torus, np.kron(cubic_interpolation(16, 4, True).toarray(),
                                         cubic_interpolation(20, 4, True).toarray()))


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_transfers_equal_the_prolongation_matrix(monkeypatch, threads):
    monkeypatch.setattr(linalg_threads, "PARALLEL_MIN_ROWS", 8)
    rows, cols = 13, 17
    M = line_matrix(rows, cols, 0.01)
    moving = np.ones(rows * cols, bool)
    moving[[0, cols - 1, rows * cols - 1]] = False
    tg = TwoGrid(blocks_of(with_fixed(M, ~moving), threads), (rows, cols), moving, stride=4)
    rng = np.random.default_rng(1)
    Y = rng.normal(size=(3, rows * cols + 11))  # (padded past the matrix's rows, as block_cg's vectors)
    assert np.allclose(tg.restrict(Y), tg.P.T @ Y[:, : rows * cols].T, atol=1e-12)
    E, X = rng.normal(size=(tg.P.shape[1], 3)), np.zeros((3, rows * cols + 11))
    tg.prolong(E, X)
    assert np.allclose(X[:, : rows * cols].T, tg.P @ E, atol=1e-12) and not X[:, rows * cols :].any()


@pytest.mark.parametrize("closed", [(False, False), (False, True), (True, True)])
def test_one_cycle_equals_its_dense_formula(closed):
    """One thread (the sweeps in the grid's order): ``x = (D+L)⁻¹r``, ``x += P C⁻¹ Pᵀ(r − Mx)``,
    ``x += (D+U)⁻¹(r − Mx)`` with dense matrices (``C = PᵀMP`` plus 1e-10 of its diagonal); on an open grid
    (the grid's sweeps), a cylinder and a torus (compressed rows, the seams' diagonals)."""
    rows, cols = 17, 19
    moving = np.ones(rows * cols, bool)
    moving[[0, cols - 1, (rows - 1) * cols, rows * cols - 1]] = False  # the corners, as fair's all-free grid
    M = with_fixed(line_matrix(rows, cols, 0.002, seed=2, closed=closed), ~moving)
    tg = TwoGrid(blocks_of(M, 1, closed), (rows, cols), moving, stride=4, wrap=closed)
    assert type(tg.sweeps).__name__ == ("CsrGaussSeidel" if any(closed) else "SymmetricGaussSeidel")
    R = np.random.default_rng(3).normal(size=(3, rows * cols))
    R[:, ~moving] = 0.0
    Z = np.zeros_like(R)
    tg.apply(R, Z, 0, rows * cols, True)
    P = tg.P.toarray()
    C = P.T @ M @ P
    d = np.diag(C).copy()
    C += np.diag(np.where(d > 0, 1e-10 * d, 1.0))  # (the identity where no free vertex, the definite shift)
    r = R.T
    x = np.linalg.solve(np.tril(M), r)
    x += P @ np.linalg.solve(C, P.T @ (r - M @ x))
    x += np.linalg.solve(np.triu(M), r - M @ x)
    assert np.allclose(Z.T, x, rtol=1e-9, atol=1e-9 * np.abs(x).max())


@pytest.mark.parametrize("threads", [1, 2, 3])
@pytest.mark.parametrize("closed", [(False, False), (True, True)])
def test_the_cycle_is_symmetric_positive_definite_on_threads(monkeypatch, threads, closed):
    """CG needs ``B⁻¹`` symmetric positive definite, whatever the threads' order of the sweeps (the grid's
    sweeps on an open grid, compressed rows with separators on a torus)."""
    monkeypatch.setattr(linalg_threads, "PARALLEL_MIN_ROWS", 8)
    rows, cols = (16, 21) if not any(closed) else (40, 30)  # (a torus of 40 rows: separators below n/4)
    M = line_matrix(rows, cols, 1e-3, seed=5, closed=closed)
    tg = TwoGrid(blocks_of(M, threads, closed), (rows, cols), np.ones(rows * cols, bool), stride=4, wrap=closed)
    if any(closed) and threads > 1:  # the compressed rows' sweeps with separators, not one thread's
        assert tg.sweeps.separators and len(tg.sweeps.interiors) == threads
    n = rows * cols
    kp = -(-n // linalg_threads.RANGE_ALIGN) * linalg_threads.RANGE_ALIGN
    B = np.zeros((n, n))
    for start in range(0, n, 3):  # B⁻¹ column by column, three at a time
        R = np.zeros((3, kp))
        for j in range(3):
            if start + j < n:
                R[j, start + j] = 1.0
        Z = np.zeros_like(R)
        tg.apply(R, Z, 0, kp, True)
        assert not Z[:, n:].any()
        for j in range(3):
            if start + j < n:
                B[:, start + j] = Z[j, :n]
    assert np.allclose(B, B.T, atol=1e-10 * np.abs(B).max())
    assert np.linalg.eigvalsh(0.5 * (B + B.T)).min() > 0


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("closed", [(False, False), (True, False)])
def test_cg_steps_do_not_grow_as_the_weight_falls(monkeypatch, threads, closed):
    """CG with the cycle solves to the dense solution; from ω = 1e-2 down to 1e-8 its steps stay within a few,
    where symmetric Gauss–Seidel's grow many times (an open grid and a cylinder)."""
    from quadnodes.linalg.gauss_seidel import CsrGaussSeidel, SymmetricGaussSeidel

    monkeypatch.setattr(linalg_threads, "PARALLEL_MIN_ROWS", 100)
    rows, cols = 40, 36
    steps = {}
    for weight in (1e-2, 1e-5, 1e-8):
        M = line_matrix(rows, cols, weight, seed=7, closed=closed)
        blocks = blocks_of(M, threads, closed)
        b = M @ np.random.default_rng(8).normal(size=(rows * cols, 3))
        x, steps[weight], res = block_cg(blocks, b, np.zeros_like(b), rtol=1e-10, maxiter=5000,
                                         precond=TwoGrid(blocks, (rows, cols), np.ones(rows * cols, bool),
                                                         wrap=closed))
        assert res <= 1e-10
        assert np.abs(x - np.linalg.solve(M, b)).max() <= 1e-6 * np.abs(b).max() / weight
        if weight == 1e-8:
            gs = block_cg(blocks, b, np.zeros_like(b), rtol=1e-10, maxiter=20000,
                          precond=(CsrGaussSeidel if any(closed) else SymmetricGaussSeidel)(blocks))[1]
            assert gs > 5 * steps[weight]
    assert max(steps.values()) <= 1.5 * min(steps.values()) + 5, steps


def test_refuses_a_grid_of_the_wrong_shape_or_without_a_coarse_grid():
    M = line_matrix(6, 8, 0.1)
    blocks = blocks_of(M, 1)
    with pytest.raises(ValueError, match="does not match"):
        TwoGrid(blocks, (7, 8), np.ones(48, bool))
    with pytest.raises(ValueError, match="no coarse grid"):
        TwoGrid(blocks, (6, 8), np.ones(48, bool), stride=6)


def mesh_line_matrix(mesh: QuadMesh, weight: float, seed: int = 0) -> np.ndarray:
    """``AᵀA + ω I`` of third differences along every structure line of ``mesh`` (closed lines wrap), each window
    scaled at random: :func:`line_matrix` on any mesh."""
    rng = np.random.default_rng(seed)
    windows = mesh.topology.windows
    A = np.zeros((len(windows), mesh.n_vertices))
    np.add.at(A, (np.arange(len(windows))[:, None], windows),
              np.array([-1.0, 3.0, -3.0, 1.0]) * rng.uniform(0.5, 2.0, size=(len(windows), 1)))
    return A.T @ A + weight * np.eye(mesh.n_vertices)


def interpolation_of(mesh: QuadMesh, stride: int = 4) -> tuple[sp.csr_matrix, np.ndarray]:
    lines = structure_lines(mesh)
    return line_interpolation(lines.indices, lines.offsets, lines.closed, mesh.n_vertices, stride)


@settings(max_examples=40, deadline=None)
@given(st.integers(11, 45), st.integers(11, 45), st.integers(0, 3), st.integers(0, 3))
def test_line_interpolation_on_a_grid_is_exact_on_bicubics(rows, cols, a, b):
    """On an open grid the rows' and the columns' interpolations agree: ``P`` reproduces ``iᵃ jᵇ`` (a, b ≤ 3),
    copies its coarse nodes, and its kept rows and columns lie at most ``stride + 1`` apart (two fronts from
    the boundary meet in the middle; the gap there is split). (From 11 rows and columns on, every line has at
    least 4 coarse nodes; a 10-row grid keeps rows 0, 4 and 9 only: quadratics.)"""
    P, coarse = interpolation_of(grid(rows, cols))
    i, j = np.divmod(np.arange(rows * cols), cols)
    f = (i / rows) ** a * (j / cols) ** b
    assert np.allclose(P @ f[coarse], f, atol=1e-12)
    assert np.array_equal(P[coarse].toarray(), np.eye(coarse.size))
    for kept in (np.unique(i[coarse]), np.unique(j[coarse])):
        assert kept[0] == 0 and kept[-1] in (rows - 1, cols - 1) and np.diff(kept).max() <= 5
    # no two kept lines side by side (fronts meeting at the same distance keep one): no weight much above the
    # grid's own (1.78 where kept lines lie 2 apart; side by side they reached 4.4)
    assert np.abs(P.data).max() <= 2.0


@pytest.mark.parametrize("name", ["torus", "small torus", "cylinder", "extraordinary", "l-shape with hole"])
def test_line_interpolation_on_any_mesh_is_a_partition_of_unity(name):
    """Closed lines, extraordinary vertices, holes: every row sums to 1 (none is zero: a closed line with fewer
    than 4 coarse nodes, as on a 12 × 12 torus, interpolates with fewer), coarse nodes are copied, every
    extraordinary vertex and corner (where lines end) is coarse, and the coarse nodes are about one in stride²
    (between a 25th and a 6th)."""
    mesh = {"torus": lambda: torus(40, 30), "small torus": lambda: torus(12, 12), "cylinder": lambda: cylinder(37, 26),
            "extraordinary": lambda: extraordinary_mesh(4), "l-shape with hole": lambda: l_shape_with_hole(40)}[name]()
    P, coarse = interpolation_of(mesh)
    assert np.allclose(np.asarray(P.sum(axis=1)).ravel(), 1.0, atol=1e-12)
    assert np.array_equal(P[coarse].toarray(), np.eye(coarse.size))
    lines = structure_lines(mesh)
    ends = np.r_[lines.offsets[:-1], lines.offsets[1:] - 1][np.r_[~lines.closed, ~lines.closed]]
    through = np.bincount(lines.indices, minlength=mesh.n_vertices)
    extraordinary = np.unique(lines.indices[ends][through[lines.indices[ends]] != 2])
    assert np.isin(extraordinary, coarse).all()
    assert mesh.n_vertices / 25 < coarse.size < mesh.n_vertices / 6 and P.getnnz(axis=1).min() > 0


def test_line_interpolation_refuses_bad_lines():
    lines = structure_lines(grid(6, 6))
    with pytest.raises(ValueError, match="stride >= 2"):
        line_interpolation(lines.indices, lines.offsets, lines.closed, 36, stride=1)
    with pytest.raises(ValueError, match="do not describe lines"):
        line_interpolation(lines.indices, lines.offsets, lines.closed, 30)
    with pytest.raises(ValueError, match="do not describe lines"):
        line_interpolation(lines.indices, lines.offsets[:-1], lines.closed, 36)
    with pytest.raises(ValueError, match="do not describe lines"):
        line_interpolation(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, bool), 36)


@pytest.mark.parametrize("name", ["extraordinary", "torus"])
def test_the_line_cycle_equals_its_dense_formula(name):
    """One thread, compressed rows in the mesh's numbering: ``x = (D+L)⁻¹r``, ``x += P C⁻¹ Pᵀ(r − Mx)``,
    ``x += (D+U)⁻¹(r − Mx)`` with dense matrices, on both of CG's vector layouts."""
    mesh = extraordinary_mesh(3) if name == "extraordinary" else torus(20, 18)
    M = mesh_line_matrix(mesh, 1e-4, seed=3)
    n = mesh.n_vertices
    P = interpolation_of(mesh)[0]
    cycle = LineTwoGrid(RowBlocks(sp.csr_matrix(M), threads=1), P)
    R = np.random.default_rng(4).normal(size=(3, n + 5))
    R[:, n:] = 0.0
    Z = np.zeros_like(R)
    cycle.apply(R, Z, 0, n + 5, True)
    Zt = np.zeros_like(R.T)
    cycle.apply(np.ascontiguousarray(R.T), Zt, 0, n + 5, False)
    P = P.toarray()
    C = P.T @ M @ P
    C += np.diag(1e-10 * np.diag(C))
    r = R[:, :n].T
    x = np.linalg.solve(np.tril(M), r)
    x += P @ np.linalg.solve(C, P.T @ (r - M @ x))
    x += np.linalg.solve(np.triu(M), r - M @ x)
    for out in (Z, Zt.T):
        assert np.allclose(out[:, :n].T, x, rtol=1e-9, atol=1e-9 * np.abs(x).max()) and not out[:, n:].any()


@pytest.mark.parametrize("threads", [1, 2])
def test_cg_with_the_line_cycle_keeps_its_steps_as_the_weight_falls(monkeypatch, threads):
    """On a mesh with extraordinary vertices and a hole (no grid), CG with the line cycle solves to the dense
    solution in steps that stay within a few from ω = 1e-2 to 1e-8, where Gauss–Seidel's grow many times; the
    cycle is symmetric positive definite with the sweeps' separators on threads."""
    from quadnodes.linalg.gauss_seidel import CsrGaussSeidel

    monkeypatch.setattr(linalg_threads, "PARALLEL_MIN_ROWS", 100)
    mesh = l_shape_with_hole(30)
    n = mesh.n_vertices
    P = interpolation_of(mesh)[0]
    steps = {}
    for weight in (1e-2, 1e-5, 1e-8):
        M = mesh_line_matrix(mesh, weight, seed=7)
        blocks = RowBlocks(sp.csr_matrix(M), threads=threads)
        cycle = LineTwoGrid(blocks, P)
        b = M @ np.random.default_rng(8).normal(size=(n, 3))
        x, steps[weight], res = block_cg(blocks, b, np.zeros_like(b), rtol=1e-10, maxiter=5000, precond=cycle)
        assert res <= 1e-10
        assert np.abs(x - np.linalg.solve(M, b)).max() <= 1e-6 * np.abs(b).max() / weight
        if weight == 1e-8:
            gs = block_cg(blocks, b, np.zeros_like(b), rtol=1e-10, maxiter=20000, precond=CsrGaussSeidel(blocks))[1]
            assert gs > 5 * steps[weight], (gs, steps)
        if weight == 1e-5:  # (at 1e-8 the coarse solve's rounding is of the order of the test's tolerance)
            if threads > 1:
                assert cycle.sweeps.separators
            B = np.zeros((n, n))
            for start in range(0, n, 3):  # B⁻¹ column by column
                R = np.zeros((3, n))
                R[np.arange(3)[start + np.arange(3) < n], start + np.arange(3)[start + np.arange(3) < n]] = 1.0
                Z = np.zeros_like(R)
                cycle.apply(R, Z, 0, n, True)
                B[:, start : start + 3] = Z[: min(3, n - start)].T
            assert np.allclose(B, B.T, atol=1e-10 * np.abs(B).max())
            assert np.linalg.eigvalsh(0.5 * (B + B.T)).min() > 0
    assert max(steps.values()) <= 1.5 * min(steps.values()) + 5, steps


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_the_line_cycles_transfers_equal_the_prolongation_on_threads(monkeypatch, threads):
    """Restriction and prolongation on the blocks' threads (rows of ``Pᵀ`` and of ``P`` in ranges of equal
    nonzeros) equal SciPy's products, on the cycle's own ``(n, c)`` vectors seen transposed (no copy) and on
    ``(c, ≥ n)`` arrays (copied); prolongation adds to what is there."""
    monkeypatch.setattr(linalg_threads, "PARALLEL_MIN_ROWS", 8)
    monkeypatch.setattr(linalg_threads, "RANGE_ALIGN", 1)
    mesh = extraordinary_mesh(6)
    n = mesh.n_vertices
    P = interpolation_of(mesh)[0]
    cycle = LineTwoGrid(RowBlocks(sp.csr_matrix(mesh_line_matrix(mesh, 1e-3, seed=5)), threads=threads), P)
    for rows in (cycle._prolong_rows, cycle._restrict_rows):  # (every range holds rows: all threads write)
        assert len(rows.ranges) == threads and all(lo < hi for lo, hi in rows.ranges)
    rng = np.random.default_rng(6)
    for Y in (np.ascontiguousarray(rng.normal(size=(n, 3))).T, rng.normal(size=(3, n + 7))):
        assert np.allclose(cycle.restrict(Y), P.T @ Y[:, :n].T, rtol=0, atol=1e-12)
    E = rng.normal(size=(P.shape[1], 3))
    for X in (np.ascontiguousarray(rng.normal(size=(n, 3))).T, rng.normal(size=(3, n + 7))):
        before = X.copy()
        cycle.prolong(E, X)
        assert np.allclose(X[:, :n].T, before[:, :n].T + P @ E, rtol=0, atol=1e-12)
        assert np.array_equal(X[:, n:], before[:, n:])


def thin_line_matrix(mesh: QuadMesh, weight: float, seed: int = 0) -> np.ndarray:
    """:func:`mesh_line_matrix` with each structure line's windows scaled alike, by 10^u (u uniform in −2 … 2): a
    vertex may be tied a thousand times more strongly along one of its lines than along the other, as on long,
    thin faces."""
    rng = np.random.default_rng(seed)
    lines = structure_lines(mesh)
    A = []
    for line, closed in zip(lines, lines.closed):
        scale = 10.0 ** rng.uniform(-2.0, 2.0)
        starts = range(len(line)) if closed else range(len(line) - 3)
        for j in starts:
            row = np.zeros(mesh.n_vertices)
            np.add.at(row, np.take(line, np.arange(j, j + 4), mode="wrap"), np.array([-1.0, 3.0, -3.0, 1.0]) * scale)
            A.append(row)
    A = np.array(A)
    return A.T @ A + weight * np.eye(mesh.n_vertices)


def line_solves_of(mesh: QuadMesh, M: np.ndarray):  # type: ignore[no-untyped-def]
    """Banded solves along each vertex's most strongly tied structure line (as fair makes them)."""
    from quadnodes.linalg.cg import PathLinePreconditioner, strongest_lines

    lines = structure_lines(mesh)
    starts = np.zeros(lines.indices.size, dtype=bool)
    starts[lines.offsets[:-1]] = True
    strongest = strongest_lines(sp.csr_matrix(M), lines.indices, starts)[1]
    kept = np.flatnonzero(strongest)
    stretch = starts[kept]
    stretch[1:] |= kept[1:] != kept[:-1] + 1
    stretch[0] = True
    return PathLinePreconditioner(sp.csr_matrix(M), lines.indices[kept], stretch)


def dense_inverse(solves, n: int) -> np.ndarray:  # type: ignore[no-untyped-def]
    """The line solves' ``L⁻¹`` as a dense matrix, column by column."""
    Linv = np.zeros((n, n))
    for j in range(n):
        e = np.zeros((n, 1))
        e[j] = 1.0
        z = np.zeros((n, 1))
        solves.apply(e, z, 0, n, False)
        Linv[:, j] = z[:, 0]
    return Linv


def test_the_line_cycle_with_line_solves_equals_its_dense_formula():
    """With ``lines``: ``x = (D+L)⁻¹r``, ``x += θ L⁻¹(r − Mx)``, ``x += P C⁻¹ Pᵀ(r − Mx)``, ``x += θ L⁻¹(r − Mx)``,
    ``x += (D+U)⁻¹(r − Mx)`` with dense matrices (``L⁻¹`` the line solves' own, column by column); the cycle is
    symmetric positive definite, and θ times ``L⁻¹M``'s largest eigenvalue is below 2 (its Lanczos estimate from
    below, within 2 %)."""
    from quadnodes.linalg.multigrid import LINE_DAMPING, line_spectral_radius

    mesh = extraordinary_mesh(3)
    M = thin_line_matrix(mesh, 1e-4, seed=3)
    n = mesh.n_vertices
    P = interpolation_of(mesh)[0]
    blocks = RowBlocks(sp.csr_matrix(M), threads=1)
    solves = line_solves_of(mesh, M)
    cycle = LineTwoGrid(blocks, P, lines=solves)
    assert cycle.line_solves is solves
    Linv = dense_inverse(solves, n)
    top = np.linalg.eigvals(Linv @ M).real.max()
    estimate = line_spectral_radius(blocks, solves)
    assert 0.98 * top < estimate <= top * (1 + 1e-9)  # (Lanczos: from below, and close)
    assert cycle.damping == pytest.approx(LINE_DAMPING / estimate) and cycle.damping * top < 2
    R = np.random.default_rng(4).normal(size=(3, n + 5))
    R[:, n:] = 0.0
    Z = np.zeros_like(R)
    cycle.apply(R, Z, 0, n + 5, True)
    Pd = P.toarray()
    C = Pd.T @ M @ Pd
    C += np.diag(1e-10 * np.diag(C))
    r = R[:, :n].T
    theta = cycle.damping
    x = np.linalg.solve(np.tril(M), r)
    x += theta * Linv @ (r - M @ x)
    x += Pd @ np.linalg.solve(C, Pd.T @ (r - M @ x))
    x += theta * Linv @ (r - M @ x)
    x += np.linalg.solve(np.triu(M), r - M @ x)
    # (the lines' ties span 10⁸: the dense solves' rounding reaches some 10⁻⁹ of the largest entry)
    assert np.allclose(Z[:, :n].T, x, rtol=0, atol=1e-7 * np.abs(x).max()) and not Z[:, n:].any()
    B = np.zeros((n, n))
    for start in range(0, n, 3):
        cols = np.arange(start, min(start + 3, n))
        R = np.zeros((3, n))
        R[np.arange(cols.size), cols] = 1.0
        Z = np.zeros_like(R)
        cycle.apply(R, Z, 0, n, True)
        B[:, cols] = Z[: cols.size].T
    assert np.allclose(B, B.T, atol=1e-9 * np.abs(B).max())
    assert np.linalg.eigvalsh(0.5 * (B + B.T)).min() > 0


@pytest.mark.parametrize("mesh_levels", [1, 2])
def test_line_spectral_radius_stays_at_or_below_the_top_where_the_krylov_space_closes(mesh_levels):
    """Where the lines hold nearly all of M (a few eigenvalue clusters, fewer than the steps), the Lanczos estimate
    stays at or below ``L⁻¹M``'s largest eigenvalue and close to it, for any start and number of steps (a reviewer's
    case: with ``M q`` carried by the recurrence it reached 4,872 × the top)."""
    from quadnodes.linalg.multigrid import line_spectral_radius

    mesh = extraordinary_mesh(mesh_levels)
    M = thin_line_matrix(mesh, 1e-3)
    n = mesh.n_vertices
    solves = line_solves_of(mesh, M)
    Linv = dense_inverse(solves, n)
    top = np.linalg.eigvals(Linv @ M).real.max()
    blocks = RowBlocks(sp.csr_matrix(M), threads=1)
    for steps in (1, 2, 5, 12, 3 * n):
        for seed in range(8):
            estimate = line_spectral_radius(blocks, solves, steps=steps, seed=seed)
            assert estimate <= top * (1 + 1e-7), (steps, seed, estimate / top)
            if steps >= 12:
                assert estimate >= 0.9 * top, (steps, seed, estimate / top)


@pytest.mark.parametrize("threads", [1, 2])
def test_line_solves_take_what_the_point_sweeps_leave_on_thin_faces(monkeypatch, threads):
    """Where each line is tied 10⁻² to 10² times as strongly as the next, CG with the line cycle reaches the dense
    solution in fewer steps with the line solves than without them, from ω = 1e-3 to 1e-7; a line set that
    does not cover the unknowns is refused by name."""
    from quadnodes.linalg.cg import PathLinePreconditioner

    from quadnodes.linalg import cg as linalg_cg

    monkeypatch.setattr(linalg_threads, "PARALLEL_MIN_ROWS", 100)
    if threads > 1:  # (the line solves in two stretches on two threads too)
        monkeypatch.setattr(linalg_cg, "LINES_PARALLEL_MIN_ROWS", 0)
        monkeypatch.setattr(linalg_threads, "thread_count", lambda: threads)
    mesh = l_shape_with_hole(30)
    n = mesh.n_vertices
    P = interpolation_of(mesh)[0]
    for weight in (1e-3, 1e-7):
        M = thin_line_matrix(mesh, weight, seed=7)
        blocks = RowBlocks(sp.csr_matrix(M), threads=threads)
        b = M @ np.random.default_rng(8).normal(size=(n, 3))
        steps = {}
        for with_lines in (False, True):
            cycle = LineTwoGrid(blocks, P, lines=line_solves_of(mesh, M) if with_lines else None)
            if with_lines:
                assert (cycle.line_solves._cut < cycle.line_solves.path.size) == (threads > 1)
            x, steps[with_lines], res = block_cg(blocks, b, np.zeros_like(b), rtol=1e-10, maxiter=5000,
                                                 precond=cycle)
            assert res <= 1e-10
            assert np.abs(x - np.linalg.solve(M, b)).max() <= 1e-6 * np.abs(b).max() / weight
        assert steps[True] < 0.8 * steps[False], steps
    with pytest.raises(ValueError, match="lines: 3 unknowns"):
        small = PathLinePreconditioner(sp.identity(3, format="csr"), np.arange(3), np.eye(1, 3, dtype=bool)[0])
        LineTwoGrid(blocks, P, lines=small)


def test_the_line_cycle_refuses_a_prolongation_of_the_wrong_size():
    M = sp.csr_matrix(mesh_line_matrix(grid(6, 6), 0.1))
    with pytest.raises(ValueError, match="30 rows for the matrix's 36"):
        LineTwoGrid(RowBlocks(M, threads=1), sp.csr_matrix((30, 4)))


@settings(max_examples=25, deadline=None)
@given(st.integers(6, 30), st.integers(1, 3), st.integers(0, 2**31 - 1), st.sampled_from([2, 3, 4, 5]))
def test_line_interpolation_on_random_quad_meshes(points, levels, seed, stride):
    """Quad meshes from a random triangulation split ``levels`` times (valence 3, 5, 6 … vertices everywhere,
    a ragged boundary): ``P`` is finite, each row sums to 1 (a vertex no line interpolates keeps a zero row),
    coarse nodes are copied, every extraordinary vertex and corner is coarse, and split three times the coarse
    nodes are fewer than the vertices."""
    from scipy.spatial import Delaunay

    from meshes import subdivide

    rng = np.random.default_rng(seed)
    xy = rng.random((points, 2))
    v = np.column_stack([xy, 0.1 * rng.random(points)])
    polys = Delaunay(xy).simplices.tolist()
    for _ in range(levels):
        v, polys = subdivide(v, polys)
    mesh = QuadMesh(v, np.array(polys))
    P, coarse = interpolation_of(mesh, stride)
    n = mesh.n_vertices
    assert P.shape == (n, coarse.size) and np.isfinite(P.data).all()
    assert coarse.size < n if levels == 3 else coarse.size <= n  # (split once, every vertex may end a line)
    sums = np.asarray(P.sum(axis=1)).ravel()
    assert np.allclose(sums[P.getnnz(axis=1) > 0], 1.0, atol=1e-9)
    assert np.array_equal(P[coarse].toarray(), np.eye(coarse.size))
    lines = structure_lines(mesh)
    through = np.bincount(lines.indices, minlength=n)
    ends = lines.indices[np.r_[lines.offsets[:-1], lines.offsets[1:] - 1][np.r_[~lines.closed, ~lines.closed]]]
    assert np.isin(ends[through[ends] != 2], coarse).all()  # (extraordinary vertices and corners)
