"""Direct factorizations: every order and back-end equals a dense solve; bad input raises, never crashes."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from quadnodes.errors import InputError
from quadnodes.linalg import cholmod_available, factorize, nested_dissection

BACKENDS = ["superlu", pytest.param("cholmod", marks=pytest.mark.skipif(not cholmod_available(),
                                                                       reason="scikit-sparse not installed"))]


def _spd(n: int, seed: int) -> sp.csc_matrix:
    """A sparse SPD matrix: a random graph Laplacian plus a small positive diagonal."""
    rng = np.random.default_rng(seed)
    i, j = rng.integers(0, n, 3 * n), rng.integers(0, n, 3 * n)
    W = sp.coo_matrix((rng.random(3 * n), (i, j)), shape=(n, n)).tocsr()
    W = W + W.T
    W.setdiag(0)
    W.eliminate_zeros()
    return (sp.diags(np.asarray(W.sum(axis=1)).ravel()) - W + sp.diags(0.05 + rng.random(n))).tocsc()


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("order", ["auto", "minimum_degree", "nested_dissection", "given"])
def test_spd_equals_a_dense_solve(backend: str, order: str) -> None:
    M = _spd(400, 3)
    rhs = np.random.default_rng(4).random((400, 3))
    how = nested_dissection(M)[::-1].copy() if order == "given" else order  # any permutation is valid
    f = factorize(M, kind="spd", order=how, backend=backend)
    assert f.backend == backend and not f.pivoted
    ref = np.linalg.solve(M.toarray(), rhs)
    np.testing.assert_allclose(f.solve(rhs), ref, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(f.solve(rhs[:, 0]), ref[:, 0], rtol=1e-9, atol=1e-12)


@settings(max_examples=25, deadline=None)
@given(n=st.integers(1, 120), seed=st.integers(0, 10_000), backend=st.sampled_from(["superlu", "auto"]))
def test_nested_dissection_equals_a_dense_solve(n: int, seed: int, backend: str) -> None:
    M = _spd(n, seed)
    rhs = np.random.default_rng(seed).random(n)
    x = factorize(M, kind="spd", order="nested_dissection", backend=backend).solve(rhs)
    np.testing.assert_allclose(M @ x, rhs, rtol=1e-8, atol=1e-10)


@pytest.mark.parametrize("order", ["minimum_degree", "nested_dissection"])
def test_quasi_definite_and_symmetric(order: str) -> None:
    """A quasi-definite KKT matrix in both orders, and the same matrix as 'symmetric' (pivoted)."""
    H = _spd(60, 1)
    G = sp.random(10, 60, density=0.2, random_state=2, format="csr")
    K = sp.bmat([[H, G.T], [G, -1e-3 * sp.identity(10)]], format="csc")
    rhs = np.random.default_rng(5).random(70)
    ref = np.linalg.solve(K.toarray(), rhs)
    for kind in ("quasi-definite", "symmetric"):
        x = factorize(K, kind=kind, negative=10, order=order).solve(rhs)
        np.testing.assert_allclose(x, ref, rtol=1e-8, atol=1e-10)


def test_symmetric_singular_raises() -> None:
    """An exactly singular symmetric matrix (a zero row and column) raises, in either order."""
    M = _spd(50, 6).tolil()
    M[7, :] = 0
    M[:, 7] = 0
    for order in ("minimum_degree", "nested_dissection"):
        with pytest.raises(InputError, match="singular"):
            factorize(M.tocsc(), kind="symmetric", order=order, what="demo")


@pytest.mark.parametrize("backend", BACKENDS)
def test_spd_refuses_what_is_not_definite(backend: str) -> None:
    """A zero or negative diagonal is refused before any factorization; an indefinite matrix with a positive
    diagonal is refused by CHOLMOD or solved exactly (SuperLU's unpivoted LDLᵀ meets no zero pivot here)."""
    with pytest.raises(InputError, match="not positive definite"):
        factorize(sp.csc_matrix(np.diag([1.0, 0.0, 2.0])), kind="spd", backend=backend)
    with pytest.raises(InputError, match="not positive definite"):
        factorize(sp.csc_matrix(np.diag([1.0, -1.0, 2.0])), kind="spd", backend=backend)
    M = sp.csc_matrix(np.array([[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]]))
    try:
        x = factorize(M, kind="spd", backend=backend, order="nested_dissection").solve(np.ones(3))
    except InputError as exc:
        assert backend == "cholmod" and "not positive definite" in str(exc)
    else:
        np.testing.assert_allclose(M @ x, np.ones(3), atol=1e-12)


def test_bad_options_and_values() -> None:
    M = _spd(30, 0)
    with pytest.raises(InputError, match="order"):
        factorize(M, kind="spd", order="metis")
    with pytest.raises(InputError, match="permutation"):
        factorize(M, kind="spd", order=np.zeros(30, dtype=int))
    with pytest.raises(InputError, match="permutation"):
        factorize(M, kind="spd", order=np.arange(29))
    with pytest.raises(InputError, match="backend"):
        factorize(M, kind="spd", backend="mumps")
    with pytest.raises(InputError, match="kind"):
        factorize(M, kind="hermitian")  # type: ignore[arg-type]
    bad = M.copy()
    bad.data[0] = np.nan
    with pytest.raises(InputError, match="not finite"):
        factorize(bad, kind="spd")
    with pytest.raises(InputError, match="rows"):
        factorize(M, kind="spd").solve(np.ones(29))
    if not cholmod_available():
        with pytest.raises(InputError, match="scikit-sparse"):
            factorize(M, kind="spd", backend="cholmod")
