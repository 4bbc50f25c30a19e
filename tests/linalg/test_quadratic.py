"""The min_quad_with_fixed engine: direct and CG back-ends equal a dense solve; known unknowns never move."""

from __future__ import annotations

import re

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from quadnodes.errors import InputError
from quadnodes.linalg import QuadraticProblem, cholmod_available, direct
from quadnodes.linalg import threads as linalg_threads


def _spd(n: int, seed: int) -> sp.csr_matrix:
    """A sparse SPD matrix: a random graph Laplacian plus a small diagonal."""
    rng = np.random.default_rng(seed)
    i = rng.integers(0, n, 4 * n)
    j = rng.integers(0, n, 4 * n)
    w = rng.random(4 * n)
    W = sp.coo_matrix((w, (i, j)), shape=(n, n)).tocsr()
    W = W + W.T
    W.setdiag(0)
    W.eliminate_zeros()
    L = sp.diags(np.asarray(W.sum(axis=1)).ravel()) - W
    return (L + sp.diags(0.05 + rng.random(n))).tocsr()


def _dense(Q, known, Y, B, Aeq=None, Beq=None):
    Q = Q.toarray()
    n = Q.shape[0]
    u = np.setdiff1d(np.arange(n), known)
    rhs = -B[u] - Q[np.ix_(u, known)] @ Y
    K = Q[np.ix_(u, u)]
    if Aeq is not None:
        A = Aeq.toarray()
        m = A.shape[0]
        K = np.block([[K, A[:, u].T], [A[:, u], np.zeros((m, m))]])
        rhs = np.vstack([rhs, Beq - A[:, known] @ Y])
    z = np.empty((n, B.shape[1]))
    z[u] = np.linalg.solve(K, rhs)[: u.size]
    z[known] = Y
    return z


@settings(max_examples=25, deadline=None)
@given(st.integers(5, 60), st.floats(0.0, 0.6), st.integers(0, 10_000), st.sampled_from(["direct", "cg"]))
def test_equals_a_dense_solve_and_known_values_stay(n, share, seed, method):
    rng = np.random.default_rng(seed)
    Q = _spd(n, seed)
    known = np.flatnonzero(rng.random(n) < share)
    if known.size == n:
        known = known[1:]
    Y = rng.normal(size=(known.size, 3))
    B = rng.normal(size=(n, 3))
    p = QuadraticProblem(Q, known=known, method=method, rtol=1e-13)
    z = p.solve(B, Y=Y)
    np.testing.assert_array_equal(z[known], Y)  # exactly, not approximately
    ref = _dense(Q, known, Y, B)
    np.testing.assert_allclose(z, ref, rtol=0, atol=1e-8 * max(1.0, np.abs(ref).max()))


def test_linear_constraints_hold_and_match_the_dense_kkt_solve():
    rng = np.random.default_rng(1)
    n = 40
    Q = _spd(n, 1)
    known = np.array([0, 7, 39])
    Aeq = sp.csr_matrix(rng.normal(size=(3, n)))
    Y, B, Beq = rng.normal(size=(3, 2)), rng.normal(size=(n, 2)), rng.normal(size=(3, 2))
    p = QuadraticProblem(Q, known=known, Aeq=Aeq)
    z = p.solve(B, Y=Y, Beq=Beq)
    np.testing.assert_allclose(Aeq @ z, Beq, atol=1e-10)
    np.testing.assert_allclose(z, _dense(Q, known, Y, B, Aeq, Beq), atol=1e-9)
    assert p.method == "direct"


@pytest.mark.parametrize("threads", [1, 2])
def test_cg_back_end_threaded_equals_direct(monkeypatch, threads):
    monkeypatch.setattr(linalg_threads, "PARALLEL_MIN_ROWS", 10)
    monkeypatch.setattr(linalg_threads, "thread_count", lambda: threads)
    Q = _spd(3000, 4)
    B = np.random.default_rng(4).normal(size=(3000, 3))
    cg = QuadraticProblem(Q, known=[5, 6], method="cg", rtol=1e-12)
    assert len(cg._blocks.ranges) == threads
    d = QuadraticProblem(Q, known=[5, 6], method="direct")
    a, b = cg.solve(B, Y=np.ones((2, 3))), d.solve(B, Y=np.ones((2, 3)))
    assert cg.iterations > 0
    np.testing.assert_allclose(a, b, atol=1e-8 * np.abs(b).max())


def test_refusals_name_the_problem():
    Q = sp.diags([1.0, 0.0, 1.0]).tocsr()
    with pytest.raises(InputError, match="demo: the matrix is not positive definite"):
        QuadraticProblem(Q, what="demo")
    with pytest.raises(InputError, match="not positive definite"):
        QuadraticProblem(Q, method="cg")
    QuadraticProblem(Q, known=[1])  # the singular direction is known: fine
    with pytest.raises(InputError, match="every unknown is known"):
        QuadraticProblem(Q, known=[0, 1, 2])
    with pytest.raises(InputError, match="method"):
        QuadraticProblem(sp.identity(3), method="magic")
    with pytest.raises(InputError, match="known index 5"):
        QuadraticProblem(sp.identity(3), known=[5])
    with pytest.raises(InputError, match="takes no linear constraints"):
        QuadraticProblem(sp.identity(3), Aeq=sp.csr_matrix(np.ones((1, 3))), method="cg")
    p = QuadraticProblem(sp.identity(3), known=[0])
    with pytest.raises(InputError, match="Y has shape"):
        p.solve(np.zeros(3), Y=[1.0, 2.0])
    with pytest.raises(InputError, match="B has shape"):
        p.solve(np.zeros(4))
    # a singular KKT system (dependent constraints) is an error, never a crash
    with pytest.raises(InputError, match="singular"):
        QuadraticProblem(sp.identity(3), Aeq=sp.csr_matrix(np.ones((2, 3))))


def _grid_laplacian(rows: int, cols: int, seed: int) -> sp.csr_matrix:
    """A weighted grid graph's Laplacian: positive semi-definite, singular (constants), positive diagonal."""
    rng = np.random.default_rng(seed)
    idx = np.arange(rows * cols).reshape(rows, cols)
    e = np.concatenate([np.c_[idx[:, :-1].ravel(), idx[:, 1:].ravel()], np.c_[idx[:-1].ravel(), idx[1:].ravel()]])
    W = sp.coo_matrix((0.1 + rng.random(len(e)), (e[:, 0], e[:, 1])), shape=(idx.size,) * 2).tocsr()
    W = W + W.T
    return (sp.diags(np.asarray(W.sum(axis=1)).ravel()) - W).tocsr()


BACKENDS = ["superlu", pytest.param("cholmod", marks=pytest.mark.skipif(not cholmod_available(),
                                                                       reason="scikit-sparse not installed"))]


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("shape", [(3, 4), (20, 20), (120, 150)])
def test_an_energy_that_leaves_a_motion_free_is_refused(monkeypatch, backend: str, shape: tuple[int, int]) -> None:
    """A graph Laplacian with nothing known leaves the constant free. Its diagonal is positive, and the unpivoted
    factorization meets no exact zero pivot on larger grids (rounding leaves one of 10⁻¹⁶–10⁻¹³ of its diagonal,
    of either sign): the pivots are read back, and the problem is refused naming an unknown of Q, never solved
    into a meaningless answer. One known unknown fixes it; so does a shift of 10⁻¹⁰ of the diagonal."""
    if backend == "superlu":
        monkeypatch.setattr(direct, "_cholmod", lambda: None)
    L = _grid_laplacian(*shape, seed=1)
    n = L.shape[0]
    with pytest.raises(InputError, match=r"demo: the matrix is (not positive definite|singular)"):
        QuadraticProblem(L, method="direct", what="demo")
    with pytest.raises(InputError, match=r"not positive definite|singular") as info:  # (Q's unknowns 2 … n + 1)
        QuadraticProblem(sp.block_diag([sp.identity(2), L]).tocsr(), known=[0], method="direct")
    named = [int(j) for j in re.findall(r"unknown (\d+)", str(info.value))]
    if backend == "superlu" and n > 12:  # (the pivots' test fires: no exact zero on a grid this size)
        assert "working precision" in str(info.value) and named
    assert all(2 <= j < n + 2 for j in named)
    p = QuadraticProblem(L, known=[n // 2], method="direct")
    B = np.random.default_rng(2).normal(size=(n, 3))
    B -= B.mean(axis=0)
    x = p.solve(B, Y=np.zeros((1, 3)))
    if n <= 400:
        ref = _dense(L, np.array([n // 2]), np.zeros((1, 3)), B)
        np.testing.assert_allclose(x, ref, rtol=1e-8, atol=1e-10 * np.abs(ref).max())
    else:  # (the residual of the reduced system)
        u = p.unknown
        np.testing.assert_allclose(L[u][:, u] @ x[u], -B[u], atol=1e-9 * np.abs(B).max())
    QuadraticProblem(L, shift=1e-10, method="direct")  # (definite by 10⁻¹⁰ of the diagonal: accepted)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("constrained", [False, True])
def test_an_indefinite_energy_with_a_positive_diagonal_is_refused(monkeypatch, backend: str,
                                                                  constrained: bool) -> None:
    """A saddle (a graph Laplacian minus half its smallest diagonal entry's worth of identity: every diagonal
    entry positive, some eigenvalues negative) has no minimizer; its factorization meets negative pivots, and
    the problem is refused — by CHOLMOD itself or by the pivots' test after SuperLU, with linear constraints and a
    shift (the quasi-definite path, always SuperLU) too — never solved to a stationary point that is no minimum."""
    if backend == "superlu":
        monkeypatch.setattr(direct, "_cholmod", lambda: None)
    L = _grid_laplacian(15, 15, seed=3)
    Q = (L - 0.5 * L.diagonal().min() * sp.identity(L.shape[0])).tocsr()
    assert (Q.diagonal() > 0).all() and np.linalg.eigvalsh(Q.toarray())[0] < 0
    kw = dict(Aeq=sp.csr_matrix(np.eye(1, L.shape[0])), constraint_shift=1e-9) if constrained else {}
    with pytest.raises(InputError, match="demo: the matrix is not positive definite"):
        QuadraticProblem(Q, method="direct", what="demo", **kw)


def test_an_exact_zero_pivot_that_superlu_pivots_around_is_refused() -> None:
    """[[1, 1, 0], [1, 1, 1], [0, 1, 1]] (eigenvalues 1 ± √2 and 1) meets an exact zero on the diagonal in its
    natural order; SuperLU, told not to pivot, still swaps rows there and factorizes an indefinite matrix with
    positive pivots. The swap itself shows the matrix is not definite: refused, in a given order too."""
    M = sp.csc_matrix(np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 1.0], [0.0, 1.0, 1.0]]))
    with pytest.raises(InputError, match="demo: the matrix is not positive definite"):
        direct.factorize(M, kind="spd", backend="superlu", order=np.arange(3), check=True, what="demo")
    K = sp.bmat([[M, sp.csr_matrix(np.eye(1, 3)).T], [sp.csr_matrix(np.eye(1, 3)), -1e-9 * sp.identity(1)]])
    with pytest.raises(InputError, match="not positive definite"):
        direct.factorize(K.tocsc(), kind="quasi-definite", negative=1, order=np.arange(4), check=True)


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_pivots_test_in_a_given_order_names_the_free_unknown(monkeypatch, backend: str) -> None:
    """A definite energy with one near-singular 2 × 2 block (two unknowns coupled so that only their sum is held,
    by 10⁻¹⁵ of the diagonal, below n·ε), factorized in a given (reversed) order: refused, naming one of the two."""
    if backend == "superlu":
        monkeypatch.setattr(direct, "_cholmod", lambda: None)
    Q = _spd(60, 5).tolil()
    a, b = 17, 42
    Q[a, :] = 0.0
    Q[:, a] = 0.0
    Q[b, :] = 0.0
    Q[:, b] = 0.0
    Q[a, a] = Q[b, b] = 1.0
    Q[a, b] = Q[b, a] = -(1.0 - 1e-15)
    with pytest.raises(InputError, match="not positive definite") as info:
        QuadraticProblem(Q.tocsr(), method="direct", order=np.arange(60)[::-1].copy())
    named = [int(j) for j in re.findall(r"unknown (\d+)", str(info.value))]
    assert named and set(named) <= {a, b}


@settings(max_examples=20, deadline=None)
@given(st.integers(6, 50), st.integers(1, 4), st.integers(0, 2**31))
def test_constraint_shift_is_the_regularized_kkt_system(n, m, seed):
    """``constraint_shift=ε`` solves [[Q, Aᵀ], [A, −εI]] (quasi-definite, unpivoted): equal to a dense
    solve of that system, and to the exact constraints as ε → 0."""
    rng = np.random.default_rng(seed)
    Q = _spd(n, seed)
    A = sp.csr_matrix(rng.normal(size=(m, n)))
    B = rng.normal(size=(n, 2))
    Beq = rng.normal(size=(m, 2))
    eps = 1e-3  # (a well-conditioned system for the comparison; the Newton step uses 1e-9)
    z = QuadraticProblem(Q, Aeq=A, method="direct", constraint_shift=eps).solve(B, Beq=Beq)
    K = np.block([[Q.toarray(), A.toarray().T], [A.toarray(), -eps * np.eye(m)]])
    ref = np.linalg.solve(K, np.vstack([-B, Beq]))[:n]
    np.testing.assert_allclose(z, ref, rtol=1e-9, atol=1e-10 * (1 + np.abs(ref).max()))
    z = QuadraticProblem(Q, Aeq=A, method="direct", constraint_shift=1e-9).solve(B, Beq=Beq)
    exact = QuadraticProblem(Q, Aeq=A, method="direct").solve(B, Beq=Beq)
    assert np.abs(A @ z - Beq).max() <= 1e-6 * (1 + np.abs(Beq).max() + np.abs(exact).max())
    with pytest.raises(InputError, match="constraint_shift"):
        QuadraticProblem(Q, Aeq=A, constraint_shift=-1.0)


def _grid_operator(rows: int, cols: int, seed: int) -> sp.csr_matrix:
    """An SPD grid operator with 13 diagonals: quad couplings plus steps of two along the lines, as planarize's."""
    rng = np.random.default_rng(seed)
    n = rows * cols
    idx = np.arange(n).reshape(rows, cols)
    pairs = [(idx[:, :-1], idx[:, 1:]), (idx[:-1], idx[1:]), (idx[:-1, :-1], idx[1:, 1:]),
             (idx[:-1, 1:], idx[1:, :-1]), (idx[:, :-2], idx[:, 2:]), (idx[:-2], idx[2:])]
    i = np.concatenate([a.ravel() for a, _ in pairs])
    j = np.concatenate([b.ravel() for _, b in pairs])
    w = rng.random(i.size) + 0.1
    W = sp.coo_matrix((w, (i, j)), shape=(n, n)).tocsr()
    W = W + W.T
    L = sp.diags(np.asarray(W.sum(axis=1)).ravel()) - W
    return (L + sp.diags(0.05 + rng.random(n))).tocsr()


@settings(max_examples=15, deadline=None)
@given(st.integers(3, 12), st.integers(3, 12), st.floats(0.0, 0.5), st.integers(0, 10_000),
       st.sampled_from(["none", "jacobi", "block-jacobi"]), st.sampled_from(["csr", "diagonal"]))
def test_preconditioned_and_diagonal_storage_cg_equal_a_dense_solve(rows, cols, share, seed, preconditioner,
                                                                    storage):
    rng = np.random.default_rng(seed)
    Q = _grid_operator(rows, cols, seed)
    n = rows * cols
    known = np.flatnonzero(rng.random(n) < share)
    if known.size == n:
        known = known[1:]
    Y = rng.normal(size=(known.size, 3))
    B = rng.normal(size=(n, 3))
    p = QuadraticProblem(Q, known=known, method="cg", rtol=1e-13, preconditioner=preconditioner, storage=storage)
    assert p.storage == storage
    guess = rng.normal(size=(n - known.size, 3))
    z = p.solve(B, Y=Y, guess=guess)
    np.testing.assert_array_equal(z[known], Y)
    ref = _dense(Q, known, Y, B)
    np.testing.assert_allclose(z, ref, rtol=0, atol=1e-8 * max(1.0, np.abs(ref).max()))


def test_diagonal_storage_takes_the_iterates_of_the_reduced_system():
    # the known unknowns stay in diagonal storage as identity rows with a zero right-hand side:
    # CG takes the same steps as on the reduced system in compressed rows
    Q = _grid_operator(30, 40, 3)
    rng = np.random.default_rng(3)
    known = [0, 39, 1160, 1199, 600]
    B, Y = rng.normal(size=(1200, 3)), rng.normal(size=(5, 3))
    a = QuadraticProblem(Q, known=known, method="cg", rtol=1e-10, storage="csr")
    b = QuadraticProblem(Q, known=known, method="cg", rtol=1e-10, storage="diagonal")
    za, zb = a.solve(B, Y=Y), b.solve(B, Y=Y)
    assert (a.storage, b.storage) == ("csr", "diagonal") and a.iterations == b.iterations
    np.testing.assert_allclose(za, zb, rtol=0, atol=1e-9 * np.abs(za).max())


def test_diagonal_storage_and_preconditioner_refusals():
    with pytest.raises(InputError, match="preconditioner"):
        QuadraticProblem(sp.identity(3), method="cg", preconditioner="ilu")
    with pytest.raises(InputError, match="storage"):
        QuadraticProblem(sp.identity(3), method="cg", storage="dense")
    Q = _spd(60, 2)  # a random graph: many distinct diagonals
    with pytest.raises(InputError, match="at most 25 distinct diagonals"):
        QuadraticProblem(Q, method="cg", storage="diagonal")
    assert QuadraticProblem(Q, method="cg").storage == "csr"  # auto: compressed rows
