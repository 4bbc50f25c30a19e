"""quadnodes.linalg.grid: diagonal storage of a grid's line operator."""

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings, strategies as st

from quadnodes.linalg import grid as grid_module, threads
from quadnodes.linalg.grid import GridPattern


def _open_operator(rows, cols, coef, blocks):
    """``A`` ``(w, n)`` of an open grid whose windows come as ``blocks`` (the pattern's contract), built entry by entry."""
    r, c, v = [], [], []
    w = 0
    for family, first, count in blocks:
        length = cols if family == 0 else rows
        for line in range(first, first + count):
            for j in range(max(length - 3, 0)):
                for i in range(4):
                    x = j + i
                    r.append(w)
                    c.append(line * cols + x if family == 0 else x * cols + line)
                    v.append(coef[w, i])
                w += 1
    return sp.csr_matrix((v, (r, c)), shape=(w, rows * cols))


def _storage(pattern, coef, free, weight, loaded):
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(grid_module.compiled, "ready", lambda: loaded)
        return pattern.normal_matrix(coef, free, weight)


@settings(max_examples=30, deadline=None)
@given(rows=st.integers(2, 9), cols=st.integers(4, 9), seed=st.integers(0, 10_000), threads_=st.sampled_from([1, 2]))
def test_compiled_open_grid_storage_equals_numpy_to_the_bit_and_the_normal_matrix(rows, cols, seed, threads_):
    # (the kernels load on first call; compiled.wait() would switch this process's later tests to them)
    rng = np.random.default_rng(seed)
    blocks = [(0, 0, 1), (1, 0, cols), (0, 1, rows - 1)]  # the window walk's order: row 0, the columns, the rest
    w = rows * (cols - 3) + cols * max(rows - 3, 0)
    coef = rng.normal(size=(w, 4))
    free = rng.random(rows * cols) > 0.2
    pattern = GridPattern.open_grid(rows, cols, blocks)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(threads, "PARALLEL_MIN_ROWS", 4)  # several line ranges even on a small grid
        mp.setattr(threads, "thread_count", lambda: threads_)
        off, data = _storage(pattern, coef, free, 0.7, loaded=True)
    off_np, data_np = _storage(pattern, coef, free, 0.7, loaded=False)
    assert np.array_equal(off, off_np)
    assert np.array_equal(data.view(np.int64), data_np.view(np.int64))
    # and it is the system: AᵀA + ωI on the unknowns (fixed nodes dropped from A), the identity elsewhere
    A = _open_operator(rows, cols, coef, blocks) @ sp.diags(free.astype(float))
    expected = (A.T @ A).toarray() + np.diag(np.where(free, 0.7, 1.0))
    n = rows * cols
    M = sp.dia_matrix((data, off), shape=(n, n)).toarray()
    np.testing.assert_allclose(M, expected, rtol=1e-12, atol=1e-12)


def test_open_grid_storage_refuses_coefficients_of_another_grid():
    pattern = GridPattern.open_grid(4, 5, [(0, 0, 1), (1, 0, 5), (0, 1, 3)])
    for loaded in (False, True):
        with pytest.raises(ValueError, match="coef: expected 13 rows"):
            _storage(pattern, np.ones((12, 4)), np.ones(20, bool), 1.0, loaded)


@settings(max_examples=40, deadline=None)
@given(rows=st.integers(7, 14), cols=st.integers(7, 14), kind=st.sampled_from(["cylinder", "torus", "rings"]),
       seed=st.integers(0, 10_000))
def test_closed_grid_storage_sums_a_seam_pair_once_and_is_the_normal_matrix(rows, cols, kind, seed):
    """A closed line's walk repeats its first three nodes, so a pair near its start sits at two places; the storage
    writes their sum once (:attr:`GridPattern.repeats`) — equal to summing every entry by bincount, and AᵀA."""
    from quadnodes.mesh import grid_faces
    from quadnodes.topology import Topology

    wrap_rows, wrap_cols = {"cylinder": (False, True), "torus": (True, True), "rings": (True, False)}[kind]
    topo = Topology.from_faces(grid_faces(rows, cols, wrap_rows=wrap_rows, wrap_cols=wrap_cols), rows * cols)
    ext, start = topo.window_walk
    pattern = GridPattern(ext, start, rows * cols, cols, wrap_rows=wrap_rows, wrap_cols=wrap_cols)
    assert pattern.valid and pattern.summed and pattern.repeats is not None
    rng = np.random.default_rng(seed)
    w = topo.windows
    coef = rng.normal(size=(len(w), 4))
    free = rng.random(rows * cols) > 0.2
    off, data = pattern.normal_matrix(coef, free, 0.7)
    repeats, pattern.repeats = pattern.repeats, None  # every entry summed by bincount
    off_sum, data_sum = pattern.normal_matrix(coef, free, 0.7)
    pattern.repeats = repeats
    assert np.array_equal(off, off_sum)
    np.testing.assert_allclose(data, data_sum, rtol=1e-14, atol=1e-14)
    A = sp.csr_matrix((coef.reshape(-1), (np.repeat(np.arange(len(w)), 4), w.reshape(-1))),
                      shape=(len(w), rows * cols)) @ sp.diags(free.astype(float))
    expected = (A.T @ A).toarray() + np.diag(np.where(free, 0.7, 1.0))
    n = rows * cols
    M = sp.dia_matrix((data, off), shape=(n, n)).toarray()
    np.testing.assert_allclose(M, expected, rtol=1e-12, atol=1e-12)


def test_closed_grid_storage_sums_every_entry_for_a_walk_in_another_layout():
    """The shortcut needs Topology.window_walk's layout; windows in another order, or one missing, are summed (a
    reviewer's input: the windows reversed took the shortcut and lost a seam pair's term, 1.76 off)."""
    from quadnodes.mesh import cylinder

    m = cylinder(5, 8)
    ext, start = m.topology.window_walk
    rng = np.random.default_rng(1)
    coef = rng.normal(size=(len(start), 4))
    free = np.ones(m.n_vertices, bool)
    walk = GridPattern(ext, start, 40, 8, wrap_cols=True)
    assert walk.repeats is not None
    _, expected = walk.normal_matrix(coef, free, 0.3)
    reversed_ = GridPattern(ext, start[::-1].copy(), 40, 8, wrap_cols=True)
    assert reversed_.repeats is None
    np.testing.assert_allclose(reversed_.normal_matrix(coef[::-1].copy(), free, 0.3)[1], expected, atol=1e-13)
    assert GridPattern(ext, start[1:].copy(), 40, 8, wrap_cols=True).repeats is None
