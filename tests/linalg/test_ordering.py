"""Nested dissection: a permutation for every graph, separators numbered after the parts they split, less fill."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.sparse.linalg import splu

from quadnodes.errors import InputError
from quadnodes.linalg import expand_order, nested_dissection


def _grid_laplacian(rows: int, cols: int) -> sp.csc_matrix:
    """The 5-point Laplacian of a rows × cols grid plus the identity (SPD)."""
    a = sp.diags([-np.ones(cols - 1), 2 * np.ones(cols), -np.ones(cols - 1)], [-1, 0, 1])
    b = sp.diags([-np.ones(rows - 1), 2 * np.ones(rows), -np.ones(rows - 1)], [-1, 0, 1])
    return (sp.kron(sp.identity(rows), a) + sp.kron(b, sp.identity(cols)) + sp.identity(rows * cols)).tocsc()


def _random_graph(n: int, edges: int, seed: int) -> sp.csr_matrix:
    rng = np.random.default_rng(seed)
    i, j = rng.integers(0, n, edges), rng.integers(0, n, edges)
    return sp.csr_matrix((np.ones(edges), (i, j)), shape=(n, n))


def _is_permutation(p: np.ndarray, n: int) -> bool:
    return p.dtype == np.int64 and p.shape == (n,) and np.array_equal(np.sort(p), np.arange(n))


@settings(max_examples=40, deadline=None)
@given(n=st.integers(0, 300), density=st.floats(0.0, 4.0), seed=st.integers(0, 10_000), leaf=st.integers(1, 40))
def test_a_permutation_of_every_graph(n: int, density: float, seed: int, leaf: int) -> None:
    """Random graphs (disconnected, with loops and repeated edges, not symmetric) give a permutation."""
    M = _random_graph(n, int(density * n), seed)
    assert _is_permutation(nested_dissection(M, leaf=leaf), n)


def test_separators_follow_the_parts_they_split() -> None:
    """On a path every vertex numbered after a part of the path splits it into pieces numbered before it."""
    n = 200
    path = sp.diags([np.ones(n - 1), np.ones(n - 1)], [-1, 1], shape=(n, n))
    p = nested_dissection(path, leaf=4)
    assert _is_permutation(p, n)
    pos = np.empty(n, dtype=np.int64)
    pos[p] = np.arange(n)
    # on a path the fill of an elimination in this order stays within the tree: each vertex has at most two
    # neighbours numbered after it once the earlier ones are eliminated — checked by the factor's size
    lu = splu(sp.csc_matrix(path + 4 * sp.identity(n))[p][:, p].tocsc(), permc_spec="NATURAL",
              diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    assert lu.L.nnz <= 3 * n
    assert pos[n // 2 - 1: n // 2 + 1].max() >= n - 2  # the top separator (the middle) is numbered last


def test_less_fill_than_the_natural_order_on_a_grid() -> None:
    """On a 60 × 60 grid, nested dissection's Cholesky factor is much smaller than the banded natural order's."""
    A = _grid_laplacian(60, 60)
    p = nested_dissection(A)
    nd = splu(A[p][:, p].tocsc(), permc_spec="NATURAL", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    nat = splu(A, permc_spec="NATURAL", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    assert nd.L.nnz < 0.5 * nat.L.nnz


def test_a_dense_block_is_placed_whole() -> None:
    """A clique has no separator: it is numbered in its input order, whatever the leaf size."""
    assert nested_dissection(sp.csr_matrix(np.ones((10, 10))), leaf=2).tolist() == list(range(10))


def test_components_and_isolated_vertices() -> None:
    """Two grids and isolated vertices side by side: a permutation; each grid keeps its vertices together."""
    A = sp.block_diag([_grid_laplacian(20, 20), sp.identity(5), _grid_laplacian(15, 10)]).tocsr()
    p = nested_dissection(A, leaf=8)
    assert _is_permutation(p, A.shape[0])


def test_bad_input() -> None:
    with pytest.raises(InputError, match="square"):
        nested_dissection(sp.csr_matrix((3, 4)))
    with pytest.raises(InputError, match="leaf"):
        nested_dissection(sp.identity(3), leaf=0)


def test_expand_order_keeps_each_node_together() -> None:
    order = np.array([1, 2, 0])
    group = np.array([0, 0, 0, 1, 2, 2])
    out = expand_order(order, group)
    assert out.tolist() == [3, 4, 5, 0, 1, 2]
    assert _is_permutation(out, group.size)
