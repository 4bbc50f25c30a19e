import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from quadnodes.errors import InputError
from quadnodes.fairing import FairingSystem, curvature_windows, fair, fairing_energy, fairing_matrix
from quadnodes.linalg import cg as linalg_cg
from quadnodes.linalg import threads as linalg_threads
from quadnodes.linalg.cg import DiagonalBlocks
from quadnodes.linalg.threads import RowBlocks
from quadnodes.mesh import QuadMesh, cylinder, grid
from quadnodes.noise import perturb
from quadnodes.zigzag import detect, window_deviation
from meshes import extraordinary_mesh, l_shape_with_hole, random_quads
from strategies import meshes

SETTINGS = dict(iterations=2, threshold=0.01)


def _dense_solve(vertices, windows, free, weight, anchor):
    """Least squares on the stacked dense system [A_free; sqrt(ω) I] x = [-A_fixed P; sqrt(ω) anchor]."""
    A = fairing_matrix(vertices, windows).toarray()
    Af, Ax = A[:, free], A[:, ~free]
    k = int(free.sum())
    lhs = np.vstack([Af, np.sqrt(weight) * np.eye(k)])
    rhs = np.vstack([-Ax @ vertices[~free], np.sqrt(weight) * anchor])
    return np.linalg.lstsq(lhs, rhs, rcond=None)[0]


@pytest.mark.parametrize("make", [lambda: perturb(grid(6, 7), tangential=0.3, normal=0.1, seed=1)[0],
                                  lambda: perturb(extraordinary_mesh(), tangential=0.2, seed=2)[0],
                                  lambda: perturb(l_shape_with_hole(), tangential=0.2, seed=3)[0],
                                  lambda: perturb(cylinder(5, 9), tangential=0.2, seed=4)[0]])
@pytest.mark.parametrize("weight", [0.01, 1.0])
def test_sparse_system_equals_dense_least_squares(make, weight):
    m = make()
    w = m.topology.windows
    free = detect(m, 0.0).free
    s = FairingSystem(m.vertices, w, free, weight)
    anchor = m.vertices[free] + 0.01
    np.testing.assert_allclose(s.solve(anchor), _dense_solve(m.vertices, w, free, weight, anchor), rtol=1e-9, atol=1e-12)


@settings(max_examples=40, deadline=None)
@given(meshes(), st.integers(0, 2**32 - 1), st.sampled_from([0.05, 0.3, 0.9]))
def test_fixed_slots_kept_in_place_or_compressed_give_one_system(mesh, seed, share):
    """``PARTIAL_IN_PLACE``: windows with a fixed vertex keep their four slots (explicit zeros at a free vertex of
    the window) or are compressed; the matrix, the right-hand side, the solve and the energies are the same."""
    import quadnodes.fairing as fairing

    rng = np.random.default_rng(seed)
    w = mesh.topology.windows
    free = rng.random(mesh.n_vertices) > share
    if not free.any():
        free[0] = True
    if not free[w].any():
        return
    anchor = mesh.vertices[free] + 0.01
    made = []
    for every in (1, 10**9):  # (one: always in place; a billion: only where no window has a fixed vertex)
        old = fairing.PARTIAL_IN_PLACE
        fairing.PARTIAL_IN_PLACE = every
        try:
            made.append(FairingSystem(mesh.vertices, w, free, 0.5))
        finally:
            fairing.PARTIAL_IN_PLACE = old
    a, b = made
    np.testing.assert_array_equal(a.A.toarray(), b.A.toarray())
    np.testing.assert_array_equal(a.b, b.b)
    np.testing.assert_allclose(a._rhs, b._rhs, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(a._rhs, -(b.A.T @ b.b), rtol=1e-12, atol=1e-12)  # (−Aᵀb; here by the counts)
    np.testing.assert_allclose(a.matrix.toarray(), b.matrix.toarray(), rtol=1e-12, atol=1e-12)
    xa, xb = a.solve(anchor), b.solve(anchor)
    np.testing.assert_allclose(xa, xb, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(xa, _dense_solve(mesh.vertices, w, free, 0.5, anchor), rtol=1e-8, atol=1e-10)
    assert a.objective(xa, anchor) == pytest.approx(b.objective(xa, anchor), rel=1e-12)


@pytest.mark.parametrize("fixed", ["corners", "boundary"])
@pytest.mark.parametrize("shape", [(40, 50), "torus"])  # (the torus: 30 rings of 40)
def test_fixed_slots_in_place_on_the_grid_path_equal_the_direct_solve(monkeypatch, fixed, shape):
    """The grid path (diagonal storage from the same coefficients as ``A``, CG) with the windows' slots kept in place
    and compressed; ``-Aᵀb`` added in place for a few slots; ``A``'s data read-only where it is the grid's
    coefficients (SciPy's tidying methods would sort and sum them in place)."""
    import quadnodes.fairing as fairing
    from quadnodes.fairing import even_lengths
    from quadnodes.mesh import torus
    from quadnodes.zigzag import window_edges

    g = torus(30, 40) if shape == "torus" else grid(*shape)
    rng = np.random.default_rng(5)
    m = QuadMesh(g.vertices + rng.normal(scale=0.1 * g.mean_edge_length, size=g.vertices.shape), g.faces)
    t, w = m.topology, m.topology.windows
    inverse = even_lengths(1.0 / np.sqrt(np.stack([np.einsum("ij,ij->i", d, d) for d in window_edges(m.vertices, w)],
                                                  axis=1)))
    free = np.ones(m.n_vertices, bool)
    if fixed == "corners":  # (four vertices anywhere, as fair's four fixed corners: few windows touch them)
        free[rng.choice(m.n_vertices, 4, replace=False)] = False
    elif shape == "torus":  # (a torus has no boundary: one of its rings)
        free[:40] = False
    else:
        free.reshape(shape)[[0, -1]] = False
        free.reshape(shape)[:, [0, -1]] = False
    weight = 0.3 / m.mean_edge_length**2
    reference = FairingSystem(m.vertices, w, free, weight, solver="direct", _inverse_lengths=inverse)
    expected = reference.solve(m.vertices[free])
    extent = np.ptp(m.vertices, axis=0).max()
    in_place = fairing.PARTIAL_IN_PLACE
    for every in (in_place, 10**9):
        monkeypatch.setattr(fairing, "PARTIAL_IN_PLACE", every)
        s = FairingSystem(m.vertices, w, free, weight, solver="cg", _topology=t, _inverse_lengths=inverse)
        assert s._grid is not None
        np.testing.assert_allclose(s._rhs, -(s.A.T @ s.b), rtol=1e-12, atol=1e-12 * np.abs(s._rhs).max())
        if every == in_place:
            assert s.A.nnz == 4 * s.A.shape[0]  # (every window's four slots kept)
            if s.active.all():  # (no window wholly fixed: A's data is the grid's coefficients themselves)
                assert np.shares_memory(s.A.data, s._grid[1])
            assert not s.A.data.flags.writeable
            with pytest.raises(ValueError):
                abs(s.A)  # (would sort and sum the grid's coefficients in place)
        np.testing.assert_allclose(s.solve(m.vertices[free]), expected, atol=1e-8 * extent)
        assert s.solver == "cg" and s.iterations > 0
        assert isinstance(s._cg[0], DiagonalBlocks)  # (the grid's diagonal storage, built from those coefficients)


@given(meshes(), st.tuples(*[st.floats(-50, 50)] * 3))
def test_translation_equivariance(mesh, t):
    a, _ = fair(mesh, **SETTINGS)
    b, _ = fair(mesh.with_vertices(mesh.vertices + t), **SETTINGS)
    np.testing.assert_allclose(b.vertices - t, a.vertices, atol=1e-9 * (1 + np.abs(t).max()))


@given(meshes(), st.sampled_from([1e-3, 0.37, 25.0, 1e3]))
def test_normalized_weight_is_scale_invariant(mesh, s):
    a, _ = fair(mesh, **SETTINGS)
    b, _ = fair(mesh.with_vertices(mesh.vertices * s), **SETTINGS)
    np.testing.assert_allclose(b.vertices, s * a.vertices, rtol=1e-9, atol=1e-9 * s * np.abs(a.vertices).max())


def test_raw_weight_depends_on_scale():
    m, _ = perturb(grid(8, 8), tangential=0.3, seed=0)
    a, _ = fair(m, weight=0.01, weight_scale="raw")
    b, _ = fair(m.with_vertices(m.vertices * 1000), weight=0.01, weight_scale="raw")
    assert np.abs(b.vertices / 1000 - a.vertices).max() > 1e-3
    c, rep = fair(m, weight=0.01, weight_scale="normalized")
    assert rep.iterations[0].weight_effective == pytest.approx(0.01 / m.mean_edge_length**2)


@given(meshes(), st.sampled_from(["none", "corners", "boundary"]))
def test_fixed_vertices_never_move(mesh, fix):
    user = np.zeros(mesh.n_vertices, bool)
    user[:: max(1, mesh.n_vertices // 7)] = True
    out, rep = fair(mesh, iterations=3, threshold=0.0, fix=fix, fixed=user)
    still = user.copy()
    if fix == "boundary":
        still |= mesh.topology.boundary_vertices
    if not mesh.topology.extraordinary.any():  # else line ends get the term of quadnodes.line_ends and may move
        still |= ~mesh.topology.window_middle
    assert rep.fix == fix and rep.n_fixed >= int(user.sum())
    assert np.array_equal(out.vertices[still], mesh.vertices[still])
    # the thesis (and the pseudo-windows): what is no window's middle, and no extraordinary vertex, never moves
    for mode in ("hold", "lines"):
        out, _ = fair(mesh, iterations=3, threshold=0.0, fix=fix, fixed=user, extraordinary=mode)
        keep = still | (~mesh.topology.window_middle & (~mesh.topology.extraordinary if mode == "lines" else True))
        assert np.array_equal(out.vertices[keep], mesh.vertices[keep])


@given(meshes(), st.sampled_from([0.001, 0.3, 10.0]), st.sampled_from(["fair", "hold"]))
def test_energy_does_not_increase_and_outputs_are_finite(mesh, weight, spacing):
    out, rep = fair(mesh, iterations=3, threshold=0.0, weight=weight, line_spacing=spacing)
    assert np.isfinite(out.vertices).all()
    for r in rep.iterations:
        assert r.energy_after <= r.energy_before * (1 + 1e-12) + 1e-15
    # against the input's own energy with lengths frozen at the input (eq. 30 exactly with line_spacing="hold")
    w = mesh.topology.windows
    e_in = fairing_energy(mesh.vertices, w, line_spacing=spacing)
    if mesh.topology.extraordinary.any():  # the energy also holds the line ends' rows (quadnodes.line_ends)
        from quadnodes.fairing import EXTRAORDINARY_SCALE, _line_end_pairs, extraordinary_windows
        from quadnodes.line_ends import line_end_energy

        pairs = _line_end_pairs(mesh.topology)
        assert rep.iterations[0].energy_before == pytest.approx(
            e_in + line_end_energy(mesh.vertices, mesh.topology, pairs, line_spacing=spacing))
        _, rep = fair(mesh, iterations=3, threshold=0.0, weight=weight, extraordinary="lines", line_spacing=spacing)
        for r in rep.iterations:
            assert r.energy_after <= r.energy_before * (1 + 1e-12) + 1e-15
        xw = extraordinary_windows(mesh.vertices, mesh.topology)  # or the pseudo-windows' rows (scaled by s)
        assert rep.iterations[0].energy_before == pytest.approx(
            e_in + EXTRAORDINARY_SCALE**2 * fairing_energy(mesh.vertices, xw))
        out, rep = fair(mesh, iterations=3, threshold=0.0, weight=weight, extraordinary="hold", line_spacing=spacing)
    assert rep.iterations[0].energy_before == pytest.approx(e_in)
    assert fairing_energy(out.vertices, w, lengths_from=mesh.vertices, line_spacing=spacing) <= e_in * (1 + 1e-9) + 1e-15 \
        or len(rep.iterations) > 1


def test_straight_lines_are_unchanged():
    m = grid(7, 9, spacing=(0.5, 2.0))
    out, rep = fair(m, iterations=3, threshold=0.0)
    # nothing is free and no later threshold is lower: stops after the first iteration, and says so
    assert out is m and [r.n_free for r in rep.iterations] == [0]
    assert rep.iterations_asked == 3 and rep.effective_iterations == 0
    assert "nothing was faired" in rep.notes()[0]


def test_removes_zigzag_and_keeps_boundary_close():
    m, _ = perturb(grid(22, 41, height=np.outer(np.sin(np.linspace(0, 3, 22)), np.ones(41))),
                tangential=0.3, normal=0.1, seed=7, fix="corners")
    out, rep = fair(m, iterations=10, threshold=1.0, threshold_decay=0.5)
    before = window_deviation(m.vertices, m.topology.windows)
    after = window_deviation(out.vertices, m.topology.windows)
    assert after.mean() < 0.05 * before.mean()
    assert [r.threshold for r in rep.iterations][:3] == [1.0, 0.5, 0.25]
    assert max(r.max_displacement for r in rep.iterations) < m.mean_edge_length


def test_anchor_input_vs_current():
    m, _ = perturb(grid(10, 10), tangential=0.4, seed=5)
    a, _ = fair(m, iterations=4, threshold=0.0, weight=0.05, anchor="current")
    b, _ = fair(m, iterations=4, threshold=0.0, weight=0.05, anchor="input")
    da = np.linalg.norm(a.vertices - m.vertices, axis=1).mean()
    db = np.linalg.norm(b.vertices - m.vertices, axis=1).mean()
    assert db < da  # anchoring to the input holds vertices closer to it (on average: the first iteration,
    # the same for both, may already make the largest move)


def test_schedules():
    m, _ = perturb(grid(8, 8), tangential=0.3, seed=0)
    _, rep = fair(m, iterations=3, threshold=[0.5, 0.1, 0.0], weight=[1.0, 0.5, 0.25])
    assert [r.threshold for r in rep.iterations] == [0.5, 0.1, 0.0]
    assert [r.weight for r in rep.iterations] == [1.0, 0.5, 0.25]
    _, rep = fair(m, iterations=3, threshold=0.0, weight=1.0, weight_decay=0.1)
    assert [r.weight for r in rep.iterations] == pytest.approx([1.0, 0.1, 0.01])


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(weight=-1.0), "weight: must be > 0"),
        (dict(weight=float("nan")), "weight: must be finite"),
        (dict(weight=0.0), "weight: must be > 0"),
        (dict(iterations=3, weight=[1.0, 2.0]), "weight: the schedule has 2 values but 3 iterations"),
        (dict(iterations=2, threshold=[0.1]), "threshold: the schedule has 1 values"),
        (dict(threshold=-0.1), "threshold: must be >= 0"),
        (dict(iterations=0), "iterations: must be >= 1"),
        (dict(anchor="origin"), "anchor"),
        (dict(weight_scale="metres"), "weight_scale"),
        (dict(fix="boundary", fixed=np.ones(64, bool)), "every vertex .* is held"),
        (dict(threshold=[0.1], threshold_decay=0.5), "decay factor applies to a single number"),
    ],
)
def test_bad_parameters(kwargs, message):
    with pytest.raises(InputError, match=message):
        fair(perturb(grid(8, 8), tangential=0.3, seed=0)[0], **kwargs)


def test_every_interior_vertex_fixed_by_boundary_is_an_error():
    m = perturb(grid(2, 5), tangential=0.3, seed=0)[0]  # every window middle is on the boundary
    with pytest.raises(InputError, match="nothing can be faired"):
        fair(m, fix="boundary")


def test_no_zigzag_returns_input_unchanged():
    m = grid(5, 5, height=np.outer(np.arange(5.0), np.ones(5)) * 0.1)
    out, rep = fair(m, threshold=0.1)
    assert out is m and rep.iterations[0].n_free == 0


def test_system_reuses_factorization_for_new_anchors():
    m, _ = perturb(grid(6, 6), tangential=0.3, seed=1)
    free = detect(m, 0.0).free
    s = FairingSystem(m.vertices, m.topology.windows, free, 0.5)
    x1 = s.solve(m.vertices[free])
    x2 = s.solve(m.vertices[free] + 1.0)
    # the energy part is translation invariant: shifting the anchor shifts the result less than fully
    assert s.objective(x1, m.vertices[free]) <= s.objective(m.vertices[free], m.vertices[free])
    assert not np.allclose(x1, x2)
    with pytest.raises(InputError, match="anchor"):
        s.solve(np.zeros((2, 3)))


@pytest.mark.parametrize("weight", [0.001, 0.01, 0.3, 10.0])
@pytest.mark.parametrize("make", [
    lambda: perturb(grid(40, 50, spacing=25.0), tangential=0.25, normal=0.1, seed=3)[0].with_vertices,
    lambda: perturb(extraordinary_mesh(3), tangential=0.2, seed=4)[0].with_vertices,
    lambda: perturb(cylinder(30, 40), tangential=0.2, seed=5)[0].with_vertices,
])
def test_conjugate_gradients_equal_the_direct_solve(make, weight):
    with_vertices = make()
    m = with_vertices(with_vertices.__self__.vertices + [4000.0, -2500.0, 300.0])  # far from the origin
    free = detect(m, 0.0).free
    h = m.mean_edge_length
    d = FairingSystem(m.vertices, m.topology.windows, free, weight / h**2, solver="direct")
    c = FairingSystem(m.vertices, m.topology.windows, free, weight / h**2, solver="cg")
    a = m.vertices[free]
    xd, xc = d.solve(a), c.solve(a)
    assert c.solver == "cg" and c.iterations > 0 and c.residual <= 1e-9
    extent = np.ptp(m.vertices, axis=0).max()  # stricter than relative to the coordinates
    assert np.abs(xc - xd).max() <= 1e-8 * extent
    # and the fairing move itself to 1e-4 of its size
    assert np.abs(xc - xd).max() <= 1e-4 * np.abs(xd - a).max()


@pytest.mark.parametrize("threads", [2, 3])
@pytest.mark.parametrize("weight", [0.3, 0.01])  # plain CG, block-Jacobi CG
@pytest.mark.parametrize("columns", [True, False])  # (3, n) vectors, (n, 3) vectors
def test_threaded_conjugate_gradients_equal_one_thread(monkeypatch, threads, weight, columns):
    import quadnodes.fairing as fairing_module

    monkeypatch.setattr(fairing_module.kernels, "ready", lambda: False)  # the SciPy paths (as in a fresh process)
    monkeypatch.setattr(linalg_threads, "COLUMNS_MAX_NNZ", 10**9 if columns else 0)

    m, _ = perturb(grid(40, 50, spacing=25.0), tangential=0.25, normal=0.1, seed=3)
    m = m.with_vertices(m.vertices + [4000.0, -2500.0, 300.0])
    free = detect(m, 0.0).free
    w = weight / m.mean_edge_length**2
    one = FairingSystem(m.vertices, m.topology.windows, free, w, solver="cg")
    x1 = one.solve(m.vertices[free])
    monkeypatch.setattr(linalg_threads, "PARALLEL_MIN_ROWS", 10)
    monkeypatch.setattr(linalg_threads, "thread_count", lambda: threads)
    par = FairingSystem(m.vertices, m.topology.windows, free, w, solver="cg")
    xp = par.solve(m.vertices[free])
    assert len(par._cg[0].ranges) == threads and len(one._cg[0].ranges) == 1
    assert par.iterations == one.iterations and par.residual <= 1e-9
    assert (par._cg[1] is not None) == (weight < 0.1) and par._cg[0].columns == columns
    np.testing.assert_allclose(xp, x1, rtol=0, atol=1e-10 * np.ptp(m.vertices))
    d = FairingSystem(m.vertices, m.topology.windows, free, w, solver="direct").solve(m.vertices[free])
    assert np.abs(xp - d).max() <= 1e-8 * np.ptp(m.vertices, axis=0).max()


def test_solver_choice_and_report():
    m, _ = perturb(grid(60, 60), tangential=0.3, seed=1)
    _, rep = fair(m, threshold=0.0)
    r = rep.iterations[0]
    assert r.solver == "cg" and r.cg_iterations > 0 and r.residual <= 1e-9
    _, rep = fair(perturb(grid(10, 10), tangential=0.3, seed=1)[0], threshold=0.0)
    assert rep.iterations[0].solver == "direct"
    with pytest.raises(InputError, match="solver"):
        fair(m, solver="magic")


@given(meshes(), st.sampled_from(["fair", "hold"]))
def test_reported_energies_equal_direct_evaluation(mesh, spacing):
    w = mesh.topology.windows
    from quadnodes.fairing import EXTRAORDINARY_SCALE, _line_end_pairs, extraordinary_windows
    from quadnodes.line_ends import line_end_energy

    out, rep = fair(mesh, iterations=1, threshold=0.0, line_spacing=spacing, extraordinary="lines")
    r = rep.iterations[0]
    xw = extraordinary_windows(mesh.vertices, mesh.topology)  # empty without extraordinary vertices
    s2 = EXTRAORDINARY_SCALE**2  # (the pseudo-windows keep their own lengths)
    assert r.energy_before == pytest.approx(fairing_energy(mesh.vertices, w, line_spacing=spacing)
                                            + s2 * fairing_energy(mesh.vertices, xw), rel=1e-9, abs=1e-12)
    assert r.energy_after == pytest.approx(fairing_energy(out.vertices, w, lengths_from=mesh.vertices, line_spacing=spacing)
                                           + s2 * fairing_energy(out.vertices, xw, lengths_from=mesh.vertices),
                                           rel=1e-8, abs=1e-10)
    # the default: the line ends' rows (none without extraordinary vertices)
    out, rep = fair(mesh, iterations=1, threshold=0.0, line_spacing=spacing)
    r = rep.iterations[0]
    pairs = _line_end_pairs(mesh.topology) if mesh.topology.extraordinary.any() else np.empty((0, 2), np.int64)
    t = mesh.topology
    assert r.energy_before == pytest.approx(fairing_energy(mesh.vertices, w, line_spacing=spacing)
                                            + line_end_energy(mesh.vertices, t, pairs, line_spacing=spacing),
                                            rel=1e-9, abs=1e-12)
    assert r.energy_after == pytest.approx(
        fairing_energy(out.vertices, w, lengths_from=mesh.vertices, line_spacing=spacing)
        + line_end_energy(out.vertices, t, pairs, lengths_from=mesh.vertices, line_spacing=spacing), rel=1e-8, abs=1e-10)


def test_shared_window_geometry_gives_the_same_system():
    from quadnodes.zigzag import _window_geometry

    m, _ = perturb(l_shape_with_hole(), tangential=0.2, seed=3)
    w = m.topology.windows
    free = detect(m, 0.05).free
    dev, inverse = _window_geometry(m.vertices, w)
    np.testing.assert_array_equal(dev, window_deviation(m.vertices, w))
    a = FairingSystem(m.vertices, w, free, 0.5)
    b = FairingSystem(m.vertices, w, free, 0.5, _inverse_lengths=inverse)
    assert (a.A != b.A).nnz == 0 and np.array_equal(a.b, b.b) and np.array_equal(a._rhs, b._rhs)


def test_patch_order_is_a_permutation_in_compact_patches():
    from quadnodes.fairing import _patch_order

    m, _ = perturb(grid(13, 11), tangential=0.2, seed=1)
    free = detect(m, 0.0).free
    s = FairingSystem(m.vertices, m.topology.windows, free, 0.01)
    order = _patch_order(m.topology.windows, s.free_index, 4)
    assert np.array_equal(np.sort(order), np.arange(s.n_free))
    big, _ = perturb(grid(41, 43), tangential=0.2, seed=1)
    fi = np.flatnonzero(detect(big, 0.0).free)
    ij = np.stack(np.divmod(fi[_patch_order(big.topology.windows, fi, 4)], 43), axis=-1)
    blocks = ij[: len(ij) // 16 * 16].reshape(-1, 16, 2)
    compact = (np.ptp(blocks, axis=1) <= 7).all(axis=1)  # within two neighbouring 4 x 4 patches
    assert compact.mean() > 0.7


def _threaded_solve_in_child(queue):
    linalg_threads.PARALLEL_MIN_ROWS = 10
    linalg_threads.thread_count = lambda: 2
    m, _ = perturb(grid(20, 20), tangential=0.2, seed=1)
    free = detect(m, 0.0).free
    s = FairingSystem(m.vertices, m.topology.windows, free, 1.0, solver="cg")
    s.solve(m.vertices[free])
    queue.put((len(s._cg[0].ranges), s.residual))


@pytest.mark.skipif(not hasattr(__import__("os"), "fork"), reason="needs fork")
def test_threaded_solve_works_in_a_forked_child(monkeypatch):
    import multiprocessing

    monkeypatch.setattr(linalg_threads, "PARALLEL_MIN_ROWS", 10)
    monkeypatch.setattr(linalg_threads, "thread_count", lambda: 2)
    m, _ = perturb(grid(20, 20), tangential=0.2, seed=1)
    free = detect(m, 0.0).free
    FairingSystem(m.vertices, m.topology.windows, free, 1.0, solver="cg").solve(m.vertices[free])
    assert linalg_threads.pool() is not None  # the parent's pool exists before the fork
    ctx = multiprocessing.get_context("fork")
    queue = ctx.Queue()
    child = ctx.Process(target=_threaded_solve_in_child, args=(queue,))
    child.start()
    child.join(timeout=60)
    assert child.exitcode == 0
    ranges, residual = queue.get(timeout=5)
    assert ranges == 2 and residual <= 1e-9


def _grid_system(m, free, weight, **kw):
    """The system as fair() builds it: with the topology's window walk and grid shape."""
    from quadnodes.zigzag import _window_geometry

    t = m.topology
    _, inverse = _window_geometry(m.vertices, t.windows, t.window_walk)
    return FairingSystem(m.vertices, t.windows, free, weight, solver="cg", _inverse_lengths=inverse,
                         _topology=t, **kw)



def _assert_storage_is_the_system(offsets, data, system, free):
    """The grid's diagonal storage holds ``system``'s free-index matrix, and identity rows for the fixed vertices."""
    import scipy.sparse as sp

    n = free.size
    D = sp.dia_matrix((data, offsets), shape=(n, n)).toarray()
    fi = system.free_index
    np.testing.assert_allclose(D[np.ix_(fi, fi)], system.matrix.toarray(), rtol=1e-13, atol=1e-13 * np.abs(D).max())
    fixed = np.flatnonzero(~free)
    np.testing.assert_array_equal(D[fixed][:, fixed], np.eye(fixed.size))
    assert not D[np.ix_(fixed, fi)].any() and not D[np.ix_(fi, fixed)].any()

@given(st.integers(4, 9), st.integers(4, 9), st.floats(0.0, 0.4), st.integers(0, 10_000))
def test_grid_diagonal_matrix_equals_the_free_index_matrix(rows, cols, fixed_share, seed):
    """On a vertex grid the normal matrix in diagonal storage (grid numbering, fixed rows
    identity) holds exactly AᵀA + ωI of the free vertices."""
    from quadnodes.fairing import grid_pattern

    rng = np.random.default_rng(seed)
    m, _ = perturb(grid(rows, cols), tangential=0.2, normal=0.1, seed=seed)
    free = m.topology.window_middle & (rng.random(m.n_vertices) >= fixed_share)
    if not free.any():
        return
    s = FairingSystem(m.vertices, m.topology.windows, free, 0.7)
    t = m.topology
    offsets, data = grid_pattern(t).normal_matrix(window_coefficients_all(m), free, 0.7)
    _assert_storage_is_the_system(offsets, data, s, free)


def window_coefficients_all(m):
    from quadnodes.fairing import window_coefficients

    return window_coefficients(m.vertices, m.topology.windows)


@pytest.mark.parametrize("loaded", [False, True])
@pytest.mark.parametrize("weight", [0.3, 10.0])
@pytest.mark.parametrize("fix", ["corners", "boundary", "random"])
@pytest.mark.parametrize("threads", [1, 2])
def test_grid_diagonal_path_equals_the_direct_solve(monkeypatch, weight, fix, threads, loaded):
    """Plain CG on SciPy's kernel (a fresh process) and, with the compiled kernels loaded, symmetric
    Gauss–Seidel (Eisenstat's CG): within 1e-8 of the mesh's size of the direct solve."""
    import quadnodes.fairing as fairing_module
    from quadnodes.linalg.gauss_seidel import SymmetricGaussSeidel

    monkeypatch.setattr(fairing_module.kernels, "ready", lambda: loaded)
    m, _ = perturb(grid(40, 50, spacing=25.0), tangential=0.25, normal=0.1, seed=3)
    m = m.with_vertices(m.vertices + [4000.0, -2500.0, 300.0])
    free = m.topology.window_middle.copy()
    if fix == "boundary":
        free &= ~m.topology.boundary_vertices
    elif fix == "random":
        free &= np.random.default_rng(0).random(m.n_vertices) > 0.3
    if threads > 1:
        monkeypatch.setattr(linalg_threads, "PARALLEL_MIN_ROWS", 10)
        monkeypatch.setattr(linalg_threads, "thread_count", lambda: threads)
    w = weight / m.mean_edge_length**2
    s = _grid_system(m, free, w)
    x = s.solve(m.vertices[free])
    blocks = s._cg[0]
    assert isinstance(blocks, DiagonalBlocks) and len(blocks.ranges) == threads
    assert isinstance(s._cg[1], SymmetricGaussSeidel) == (loaded and weight < 1)  # (plain CG at large weights)
    assert s.residual <= 1e-9
    d = FairingSystem(m.vertices, m.topology.windows, free, w, solver="direct").solve(m.vertices[free])
    assert np.abs(x - d).max() <= 1e-8 * np.ptp(m.vertices, axis=0).max()


def test_grid_diagonal_path_only_when_it_pays(monkeypatch):
    import quadnodes.fairing as fairing_module
    from quadnodes.linalg.gauss_seidel import SymmetricGaussSeidel

    m, _ = perturb(grid(40, 50), tangential=0.25, seed=3)
    free = m.topology.window_middle.copy()
    w = 0.3 / m.mean_edge_length**2
    few = free & (np.random.default_rng(0).random(m.n_vertices) < 0.3)  # mostly fixed: free-index CSR
    s = _grid_system(m, few, w)
    s.solve(m.vertices[few])
    assert isinstance(s._cg[0], RowBlocks) and not isinstance(s._cg[0], DiagonalBlocks)
    small = 0.003 / m.mean_edge_length**2
    monkeypatch.setattr(fairing_module.kernels, "ready", lambda: False)  # a fresh process, a small grid
    monkeypatch.setattr(fairing_module.spectral, "loaded", lambda: False)  # (no transforms imported either)
    s = _grid_system(m, free, small)  # small weight: block-Jacobi CG
    s.solve(m.vertices[free])
    assert s._cg[1] is not None and not isinstance(s._cg[0], DiagonalBlocks)
    monkeypatch.setattr(fairing_module.kernels, "ready", lambda: True)  # kernels at hand: Gauss–Seidel at any weight
    g = _grid_system(m, free, small)
    xg = g.solve(m.vertices[free])
    assert isinstance(g._cg[0], DiagonalBlocks) and isinstance(g._cg[1], SymmetricGaussSeidel)
    assert g.iterations < s.iterations
    d = FairingSystem(m.vertices, m.topology.windows, free, small, solver="direct").solve(m.vertices[free])
    assert np.abs(xg - d).max() <= 1e-8 * np.ptp(m.vertices, axis=0).max()
    c = perturb(cylinder(30, 40), tangential=0.2, seed=5)[0]  # not a complete open grid
    assert c.topology.grid_shape is None


def test_fair_on_a_grid_uses_diagonal_storage_and_agrees_with_the_direct_solver():
    m, _ = perturb(grid(60, 60), tangential=0.2, normal=0.05, seed=7)
    a, ra = fair(m, iterations=2, threshold=0.0)
    b, rb = fair(m, iterations=2, threshold=0.0, solver="direct")
    assert [r.solver for r in ra.iterations] == ["cg", "cg"]
    assert np.abs(a.vertices - b.vertices).max() <= 1e-8 * np.ptp(m.vertices, axis=0).max()


def test_iterations_reuse_the_grid_pattern(monkeypatch):
    """Multi-iteration runs build the grid's diagonal pattern once per mesh, not per iteration."""
    from quadnodes.linalg.grid import GridPattern

    made = []
    open_grid = GridPattern.open_grid
    monkeypatch.setattr(GridPattern, "open_grid", lambda *a: (made.append(1), open_grid(*a))[1])
    m, _ = perturb(grid(60, 60), tangential=0.2, normal=0.05, seed=7)
    _, rep = fair(m, iterations=3, threshold=0.0)
    assert [r.solver for r in rep.iterations] == ["cg"] * 3 and len(made) == 1
    fair(m, iterations=2, threshold=0.0, weight=1.0)  # same mesh, other weight: still the one pattern
    assert len(made) == 1


def test_stops_early_when_nothing_can_change_and_says_so():
    m, _ = perturb(grid(12, 12), tangential=0.2, seed=3)
    out, rep = fair(m, iterations=10**5, threshold=0.1)  # was minutes of idle iterations
    assert len(rep.iterations) < 10 and rep.iterations_asked == 10**5
    assert rep.iterations[-1].n_free == 0 and rep.effective_iterations >= 1
    assert any("stopped after iteration" in note for note in rep.notes())
    # a lower threshold later on keeps it going
    _, rep2 = fair(m, iterations=3, threshold=[1e3, 1e3, 0.0])
    assert [r.n_free > 0 for r in rep2.iterations] == [False, False, True]
    assert rep2.notes() == ["iterations 1–2 freed no vertex"]


@pytest.mark.parametrize("iterations", [10**7, 2**63 - 1])
def test_absurd_iteration_counts_are_refused(iterations):
    with pytest.raises(InputError, match="iterations: at most 100000"):
        fair(grid(4, 4), iterations=iterations)


@pytest.mark.parametrize(
    ("old", "new"),
    [(dict(deviation=0.2), "threshold"), (dict(deviation_decay=0.5), "threshold_decay"),
     (dict(fix_boundary=True), "fix='boundary'")],
)
def test_old_names_say_the_new_one(old, new):
    with pytest.raises(InputError, match=f"was renamed: use {re.escape(new)}"):
        fair(grid(4, 4), **old)
    with pytest.raises(InputError, match="was renamed"):
        detect(grid(4, 4), fix_boundary=True)


@pytest.mark.parametrize(
    ("thing", "hint"),
    [(None, "got None"), (np.zeros((4, 3)), "an array"), ("mesh.obj", "a file name"),
     ((grid(3, 3), None), "unpack it")],
)
def test_something_other_than_a_mesh_is_named(thing, hint):
    with pytest.raises(InputError, match=re.escape(hint)):
        fair(thing)
    with pytest.raises(InputError, match="mesh: expected a QuadMesh"):
        detect(thing)


def test_a_build123d_face_is_told_to_be_sampled():
    from quadnodes import surfaces

    with pytest.raises(InputError, match="sample it first"):
        fair(surfaces.saddle())


def test_near_duplicate_vertices_are_named_not_a_singular_factor():
    m = grid(5, 5)
    v = m.vertices.copy()
    v[12] = v[13] - [1e-11, 0, 0]  # vertex 12 sits 1e-11 from vertex 13
    with pytest.raises(InputError, match="near-duplicate vertices 12 and 13"):
        QuadMesh(v, m.faces)


def test_negligible_weight_is_refused_by_the_direct_solver():
    m, _ = perturb(grid(6, 6), tangential=0.3, seed=1)
    with pytest.raises(InputError, match="numerically singular"):
        fair(m, weight=1e-14, threshold=0.0, solver="direct")


def test_held_vertices_far_off_the_reference_are_reported():
    clean = grid(8, 8)
    noisy, _ = perturb(clean, normal=0.3, seed=2, fix="none")  # the corners moved too
    _, rep = fair(noisy, iterations=2, reference=clean)
    assert rep.held_off_reference > 0.1 * rep.length_scale
    assert any("off the reference surface" in note for note in rep.notes())
    kept, _ = perturb(clean, normal=0.3, seed=2)  # the default keeps the corners
    _, rep = fair(kept, iterations=2, reference=clean)
    assert rep.held_off_reference == 0 and not any("reference" in n for n in rep.notes())


# --- issue 16: extraordinary vertices and detection -------------------------------------


def test_hold_and_thesis_leave_extraordinary_vertices_exactly_where_they_were():
    from meshes import extraordinary_mesh

    m = extraordinary_mesh(3)
    noisy, _ = perturb(m, tangential=0.2, normal=0.1, seed=1)
    out, _ = fair(noisy, iterations=3, extraordinary="hold", detection="thesis")
    e = m.topology.extraordinary
    assert e.sum() == 2
    np.testing.assert_array_equal(out.vertices[e], noisy.vertices[e])
    out2, _ = fair(noisy, iterations=3)  # default: extraordinary="fair"
    assert (np.linalg.norm(out2.vertices[e] - noisy.vertices[e], axis=1) > 0).all()


def test_fair_extraordinary_recovers_them_better_on_average():
    from meshes import extraordinary_mesh

    m = extraordinary_mesh(3)
    e = m.topology.extraordinary
    h = m.mean_edge_length
    held, faired = [], []
    for seed in range(4):
        noisy, _ = perturb(m, normal=0.2, seed=seed, fix="boundary")
        for mode, acc in (("hold", held), ("fair", faired)):
            out, _ = fair(noisy, iterations=5, extraordinary=mode)
            acc.append(np.linalg.norm(out.vertices - m.vertices, axis=1) / h)
    held, faired = np.array(held), np.array(faired)
    assert faired[:, e].max(axis=1).mean() < 0.5 * held[:, e].max(axis=1).mean()  # measured 0.053 vs 0.195
    assert faired.mean() < held.mean()


def test_extraordinary_windows_pair_most_opposite_arms():
    from meshes import extraordinary_mesh
    from quadnodes.fairing import extraordinary_windows

    m = extraordinary_mesh(2)
    xw = extraordinary_windows(m.vertices, m.topology)
    e = np.flatnonzero(m.topology.extraordinary)
    assert len(xw) and np.isin(xw[:, 1:3], e).any(axis=1).all()  # every pseudo-window has one in its middle
    adj = {tuple(sorted(x)) for x in m.topology.edges.tolist()}
    for w in xw:  # consecutive vertices are mesh edges: a continued structure line
        assert all(tuple(sorted((int(a), int(b)))) in adj for a, b in zip(w[:-1], w[1:]))


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 10_000))
def test_grids_are_unchanged_by_the_extraordinary_setting(seed):
    z = np.random.default_rng(seed).normal(size=(6, 8)) * 0.3
    g = grid(6, 8, height=z)
    for det in ("thesis", "alternating"):
        a, ra = fair(g, iterations=3, extraordinary="hold", detection=det)
        for mode in ("fair", "lines"):
            b, rb = fair(g, iterations=3, extraordinary=mode, detection=det)
            np.testing.assert_array_equal(a.vertices, b.vertices)


def test_unknown_extraordinary_and_detection_are_refused():
    with pytest.raises(InputError, match="extraordinary"):
        fair(grid(4, 4), extraordinary="Fair")
    with pytest.raises(InputError, match="detection"):
        fair(grid(4, 4), detection="eq30")


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("case", ["torus", "extraordinary"])
def test_cg_on_closed_and_irregular_meshes_equals_the_direct_solve(monkeypatch, threads, case):
    """Broadband noise on a closed torus and on a mesh with extraordinary vertices: CG (one or two
    threads) within 1e-8 of the mesh's size of the direct solve; held vertices do not move."""
    from quadnodes.mesh import torus

    base = torus(24, 40) if case == "torus" else extraordinary_mesh(3)
    rng = np.random.default_rng(11)
    m = base.with_vertices(base.vertices + rng.normal(scale=0.2 * base.mean_edge_length, size=base.vertices.shape))
    if threads > 1:
        monkeypatch.setattr(linalg_threads, "PARALLEL_MIN_ROWS", 10)
        monkeypatch.setattr(linalg_threads, "thread_count", lambda: threads)
    free = m.topology.window_middle & (rng.random(m.n_vertices) > 0.1)
    w = 0.3 / m.mean_edge_length**2
    s = FairingSystem(m.vertices, m.topology.windows, free, w, solver="cg")
    x = s.solve(m.vertices[free])
    assert len(s._cg[0].ranges) == threads and s.residual <= 1e-9
    d = FairingSystem(m.vertices, m.topology.windows, free, w, solver="direct").solve(m.vertices[free])
    assert np.abs(x - d).max() <= 1e-8 * np.ptp(m.vertices, axis=0).max()
    out, _ = fair(m, threshold=0.0, fixed=~free, fix="none", solver="cg")
    np.testing.assert_array_equal(out.vertices[~free], m.vertices[~free])


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("noise", ["broadband", "zigzag"])
def test_line_preconditioner_on_a_grid_equals_the_direct_solve(monkeypatch, threads, noise):
    import quadnodes.fairing as fairing_module
    from quadnodes.linalg.cg import LinePreconditioner, SymmetricDiagonalBlocks
    from quadnodes.linalg.gauss_seidel import SymmetricGaussSeidel

    m = perturb(grid(40, 50, spacing=25.0), tangential=0.25, normal=0.1, seed=3)[0] if noise == "zigzag" else \
        grid(40, 50, spacing=25.0)
    if noise == "broadband":
        m = m.with_vertices(m.vertices + np.random.default_rng(5).normal(scale=5.0, size=m.vertices.shape))
    m = m.with_vertices(m.vertices + [4000.0, -2500.0, 300.0])
    free = m.topology.window_middle & ~m.topology.boundary_vertices
    if threads > 1:
        monkeypatch.setattr(linalg_cg, "LINES_PARALLEL_MIN_ROWS", 10)
        monkeypatch.setattr(linalg_threads, "PARALLEL_MIN_ROWS", 10)
        monkeypatch.setattr(linalg_threads, "thread_count", lambda: threads)
    w = 0.3 / m.mean_edge_length**2
    s = _grid_system(m, free, w, preconditioner="lines")
    x = s.solve(m.vertices[free])
    plain = _grid_system(m, free, w, preconditioner="none")
    plain.solve(m.vertices[free])
    assert plain._cg[1] is None
    monkeypatch.setattr(fairing_module.kernels, "ready", lambda: False)  # (as in a fresh process)
    monkeypatch.setattr(fairing_module.spectral, "loaded", lambda: False)  # (no transforms imported either)
    small = _grid_system(m, free, w)  # below COMPILED_MIN_UNKNOWNS: SciPy's kernel, no line solves
    small._cg_setup()
    assert small._cg[1] is None and not isinstance(small._cg[0], SymmetricDiagonalBlocks)
    monkeypatch.setattr(fairing_module.kernels, "ready", lambda: True)  # loaded already: compiled at any size
    loaded = _grid_system(m, free, w)
    loaded._cg_setup()
    # an open grid with the kernels at hand: "auto" takes symmetric Gauss–Seidel at any noise
    assert isinstance(loaded._cg[0], SymmetricDiagonalBlocks) and isinstance(loaded._cg[1], SymmetricGaussSeidel)
    assert np.abs(loaded.solve(m.vertices[free]) - x).max() <= 1e-8 * np.ptp(m.vertices, axis=0).max()
    monkeypatch.setattr(fairing_module, "COMPILED_MIN_UNKNOWNS", 100)
    auto = _grid_system(m, free, w)
    auto._cg_setup()
    assert isinstance(auto._cg[0], SymmetricDiagonalBlocks) and isinstance(auto._cg[1], SymmetricGaussSeidel)
    xa = auto.solve(m.vertices[free])
    assert np.abs(xa - x).max() <= 1e-8 * np.ptp(m.vertices, axis=0).max()
    assert auto.residual <= 1e-9 and auto.iterations < plain.iterations
    assert isinstance(s._cg[1], LinePreconditioner) and len(s._cg[0].ranges) == threads
    assert s.residual <= 1e-9 and s.iterations < plain.iterations
    d = FairingSystem(m.vertices, m.topology.windows, free, w, solver="direct").solve(m.vertices[free])
    assert np.abs(x - d).max() <= 1e-8 * np.ptp(m.vertices, axis=0).max()
    with pytest.raises(InputError, match="preconditioner"):
        FairingSystem(m.vertices, m.topology.windows, free, w, preconditioner="multigrid")


def _record_setups(monkeypatch, what):
    """``FairingSystem._cg_setup`` wrapped: each set-up appends ``what(system, (blocks, preconditioner, order))`` to
    the returned list."""
    picked = []
    setup = FairingSystem._cg_setup

    def record(self):
        out = setup(self)
        picked.append(what(self, out))
        return out

    monkeypatch.setattr(FairingSystem, "_cg_setup", record)
    return picked


def _noisy(m, seed=5, share=0.2):
    """``m`` with broadband noise: independent Gaussian offsets of ``share`` edge lengths, moved off the origin."""
    rng = np.random.default_rng(seed)
    m = m.with_vertices(m.vertices + rng.normal(scale=share * m.mean_edge_length, size=m.vertices.shape))
    return m.with_vertices(m.vertices + [4000.0, -2500.0, 300.0])


def _graded(rows, cols, ratio, spacing=25.0, rows_ratio=1.0):
    """A grid whose columns' spacing grows by ``ratio`` from the first to the last (geometrically), and its rows'
    by ``rows_ratio``."""
    def axis(n, r):
        u = np.linspace(0.0, 1.0, n)
        return u * spacing * (n - 1) if r == 1.0 else (r**u - 1.0) / (r - 1.0) * spacing * (n - 1)

    m = grid(rows, cols, spacing=spacing)
    v = m.vertices.copy()
    v[:, 0] = np.tile(axis(cols, ratio), rows)
    v[:, 1] = np.repeat(axis(rows, rows_ratio), cols)
    return QuadMesh(v, m.faces)


def _tower(rows, cols, taper):
    """An open cylinder whose radius shrinks by ``taper`` from its first ring to its last."""
    c = cylinder(rows, cols, radius=500.0, height=900.0)
    v = c.vertices.copy()
    v[:, :2] *= (1.0 + (1.0 / taper - 1.0) * v[:, 2] / 900.0)[:, None]
    return QuadMesh(v, c.faces)


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("case", ["sheet", "boundary", "pins", "anisotropic", "cylinder", "torus", "compiled",
                                  "graded", "tower"])
def test_spectral_preconditioner_on_grids_equals_the_direct_solve(monkeypatch, threads, case):
    """The transforms' preconditioner on open, closed and anisotropic grids, with the boundary or a few inner
    vertices fixed, on SciPy's product or the compiled one, with coefficients that vary along an axis (an uneven
    spacing, a tapered cylinder: their profile): within 1e-8 of the mesh's size of the direct solve, fewer steps
    than plain CG."""
    import quadnodes.fairing as fairing_module
    from quadnodes.linalg.cg import SymmetricDiagonalBlocks
    from quadnodes.linalg.spectral import SpectralPreconditioner
    from quadnodes.mesh import torus

    monkeypatch.setattr(fairing_module.kernels, "ready", lambda: case == "compiled")

    base = {"cylinder": lambda: cylinder(30, 40, radius=500.0, height=900.0),
            "torus": lambda: torus(24, 40, major=800.0, minor=200.0),
            "anisotropic": lambda: QuadMesh(grid(40, 50, spacing=25.0).vertices * [1.0, 2.8, 1.0], grid(40, 50).faces),
            "graded": lambda: _graded(40, 50, 10.0), "tower": lambda: _tower(30, 40, 3.0)}.get(
        case, lambda: grid(40, 50, spacing=25.0))()
    m = _noisy(base)
    free = m.topology.window_middle.copy()
    if case == "boundary":
        free &= ~m.topology.boundary_vertices
    elif case == "pins":
        free[np.random.default_rng(2).choice(np.flatnonzero(free), 5, replace=False)] = False
    if threads > 1:
        monkeypatch.setattr(linalg_threads, "PARALLEL_MIN_ROWS", 10)
        monkeypatch.setattr(linalg_threads, "thread_count", lambda: threads)
    w = 0.3 / m.mean_edge_length**2
    s = _grid_system(m, free, w, preconditioner="spectral")
    x = s.solve(m.vertices[free])
    assert isinstance(s._cg[0], DiagonalBlocks) and isinstance(s._cg[1], SpectralPreconditioner)
    assert isinstance(s._cg[0], SymmetricDiagonalBlocks) == (case == "compiled")
    assert len(s._cg[0].ranges) == threads and s.residual <= 1e-9
    assert s._cg[1].wrap == s._grid[0].wrap
    assert (s._cg[1].profile is not None) == (case in ("graded", "tower"))
    plain = _grid_system(m, free, w, preconditioner="none")
    plain.solve(m.vertices[free])
    assert s.iterations < plain.iterations
    d = FairingSystem(m.vertices, m.topology.windows, free, w, solver="direct").solve(m.vertices[free])
    assert np.abs(x - d).max() <= 1e-8 * np.ptp(m.vertices, axis=0).max()


@pytest.mark.parametrize("loaded", [False, True])
def test_fair_takes_the_spectral_preconditioner_with_its_even_spacing_only(monkeypatch, loaded):
    """fair()'s default line_spacing="fair" gives every window one length (NumPy's and the compiled pass alike):
    "auto" takes the transforms there without the compiled sweeps, and not under eq. 32's own lengths."""
    from quadnodes.linalg import compiled, spectral
    from quadnodes.linalg.spectral import SpectralPreconditioner
    from quadnodes.zigzag import _window_geometry

    m = _noisy(grid(60, 70, spacing=25.0))
    t = m.topology
    if loaded:
        assert compiled.wait()
    monkeypatch.setattr(compiled, "ready", lambda: loaded)  # (the geometry pass's path: compiled or NumPy)
    inv = _window_geometry(m.vertices, t.windows, t.window_walk, even=True)[-2]
    assert np.array_equal(inv[:, 0], inv[:, 1]) and np.array_equal(inv[:, 1], inv[:, 2])
    monkeypatch.setattr(compiled, "ready", lambda: False)  # (the solver: no compiled sweeps)
    monkeypatch.setattr(spectral, "loaded", lambda: True)
    picked = _record_setups(monkeypatch, lambda system, out: type(out[1]))
    out, rep = fair(m, threshold=0.0)
    assert picked == [SpectralPreconditioner] and rep.iterations[0].residual <= 1e-9
    picked.clear()
    held, _ = fair(m, threshold=0.0, line_spacing="hold")
    assert picked and SpectralPreconditioner not in picked


@pytest.mark.parametrize("loaded", [False, True])
def test_a_torus_takes_the_spectral_preconditioner_at_every_weight(monkeypatch, loaded):
    """A torus has no line ends, so the transforms' steps barely grow as the weight falls: "auto" takes them with
    or without the compiled kernels, from the default weight to 10⁻⁶ (no Gauss–Seidel, no two-grid switch), and
    fair() keeps within 1e-8 of the mesh's size of the direct solve."""
    import warnings

    from quadnodes.linalg import compiled, spectral
    from quadnodes.linalg.cg import SymmetricDiagonalBlocks
    from quadnodes.linalg.spectral import SpectralPreconditioner
    from quadnodes.mesh import torus

    m = _noisy(torus(48, 60, major=800.0, minor=200.0))
    if loaded:
        assert compiled.wait()
    monkeypatch.setattr(compiled, "ready", lambda: loaded)
    monkeypatch.setattr(spectral, "loaded", lambda: True)
    picked = _record_setups(monkeypatch, lambda system, out: (type(out[1]), system._switch_to,
                                                              isinstance(out[0], SymmetricDiagonalBlocks)))
    size = np.ptp(m.vertices, axis=0).max()
    steps = []
    for weight in (0.3, 1e-4, 1e-6):
        picked.clear()
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # (a fallback to the direct solve warns: here it is a failure)
            out, rep = fair(m, threshold=0.0, weight=weight, solver="cg", line_curvature="fair")
        assert picked == [(SpectralPreconditioner, None, loaded)], (weight, picked)
        assert rep.iterations[0].solver == "cg" and rep.iterations[0].cg_iterations > 0
        steps.append(rep.iterations[0].cg_iterations)
        ref, _ = fair(m, threshold=0.0, weight=weight, solver="direct", line_curvature="fair")
        assert np.abs(out.vertices - ref.vertices).max() <= 1e-8 * size, weight
    assert steps[-1] < 3 * steps[0], steps  # (Gauss–Seidel's grow as 1/√ω: some 30× here)
    # fixed vertices (off the boundary, as every one on a torus) are inverted around exactly: still the transforms
    # at tiny weights, as few steps, the same accuracy
    fixed = np.zeros(m.n_vertices, bool)
    fixed[[100, 1700, 2000]] = True
    for weight in (1e-6, 0.3):
        picked.clear()
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            out, rep = fair(m, threshold=0.0, weight=weight, fixed=fixed, solver="cg", line_curvature="fair")
        assert picked[0][0] is SpectralPreconditioner and rep.iterations[0].cg_iterations < 2 * steps[-1]
        ref, _ = fair(m, threshold=0.0, weight=weight, fixed=fixed, solver="direct", line_curvature="fair")
        assert np.abs(out.vertices - ref.vertices).max() <= 1e-8 * size, weight
        assert np.array_equal(out.vertices[fixed], m.vertices[fixed])
    # more than the stored columns take (64): at tiny weights the closed axes take their exact basis
    fixed[np.random.default_rng(4).choice(m.n_vertices, 100, replace=False)] = True
    picked.clear()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out, rep = fair(m, threshold=0.0, weight=1e-6, fixed=fixed, solver="cg", line_curvature="fair")
    assert picked[0][0] is SpectralPreconditioner and rep.iterations[0].cg_iterations < 2 * steps[-1]
    ref, _ = fair(m, threshold=0.0, weight=1e-6, fixed=fixed, solver="direct", line_curvature="fair")
    assert np.abs(out.vertices - ref.vertices).max() <= 1e-8 * size


@pytest.mark.parametrize("fix", ["corners", "boundary"])
def test_tiny_weights_take_the_spectral_preconditioner_on_open_grids(monkeypatch, fix):
    """With the compiled kernels at hand, below a weight of about 0.025 on a small open grid (a Gershgorin bound
    above _spectral_contrast ω) it takes the exact lines' transforms in place of Gauss–Seidel and the two-grid
    switch: steps that barely grow as the weight falls, within 1e-8 of the mesh's size of the direct solve, the
    fixed vertices (corners, or the whole boundary: the box shrinks to the interior) unmoved."""
    import warnings

    from quadnodes.linalg import compiled, spectral
    from quadnodes.linalg.gauss_seidel import SymmetricGaussSeidel
    from quadnodes.linalg.spectral import SpectralPreconditioner

    assert compiled.wait()
    m = _noisy(grid(48, 60, spacing=25.0))
    monkeypatch.setattr(compiled, "ready", lambda: True)
    monkeypatch.setattr(spectral, "loaded", lambda: True)
    picked = _record_setups(monkeypatch, lambda system, out: out[1])
    size = np.ptp(m.vertices, axis=0).max()
    steps = []
    for weight in (1e-4, 1e-6, 1e-8):
        picked.clear()
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # (a fallback to the direct solve warns: here it is a failure)
            out, rep = fair(m, threshold=0.0, weight=weight, solver="cg", fix=fix)
        assert [type(p) for p in picked] == [SpectralPreconditioner], (weight, picked)
        assert picked[0]._axes[0].kind == picked[0]._axes[1].kind == "exact"
        if fix == "boundary":
            assert picked[0]._box_shape == (46, 58) and picked[0]._inner.size == 0
        else:  # (the four corners and a vertex or so line_gaps holds, inside the box, inverted around)
            assert 4 <= picked[0]._inner.size <= 8 and picked[0]._factored is not None
        steps.append(rep.iterations[0].cg_iterations)
        assert rep.iterations[0].residual <= 1e-9
        if weight >= 1e-6:  # (below, the direct solve's own rounding, some 10⁻¹⁶ times the condition, is larger)
            ref, _ = fair(m, threshold=0.0, weight=weight, solver="direct", fix=fix)
            assert np.abs(out.vertices - ref.vertices).max() <= 1e-8 * size, weight
        held = m.topology.boundary_vertices if fix == "boundary" else m.topology.corner_vertices
        assert np.array_equal(out.vertices[held], m.vertices[held])
    assert steps[-1] < 2 * steps[0], steps
    # the default weight down to 0.03 (a bound of about 1.5·10³ ω here): Gauss–Seidel; from 0.02 (2.2·10³ ω, above a
    # small grid's floor SPECTRAL_CONTRAST_MIN) the exact lines, in fewer steps
    steps_at = {}
    for weight, kind in ((0.3, SymmetricGaussSeidel), (0.1, SymmetricGaussSeidel), (0.03, SymmetricGaussSeidel),
                         (0.02, SpectralPreconditioner), (0.01, SpectralPreconditioner)):
        picked.clear()
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            out, rep = fair(m, threshold=0.0, weight=weight, solver="cg", fix=fix)
        assert type(picked[0]) is kind, (weight, picked)
        steps_at[weight] = rep.iterations[0].cg_iterations
        ref, _ = fair(m, threshold=0.0, weight=weight, solver="direct", fix=fix)
        assert np.abs(out.vertices - ref.vertices).max() <= 1e-8 * size, weight
    assert steps_at[0.02] < steps_at[0.03] / 2, steps_at
    # ... but not with more than SPECTRAL_FLOOR_MAX_INSIDE fixed vertices inside the box, whose correction's set-up
    # then costs more than Gauss–Seidel's solve: there the bound stays SPECTRAL_CONTRAST ω (here ω ≈ 0.0044)
    scattered = np.zeros(m.n_vertices, bool)
    scattered[np.random.default_rng(3).choice(m.n_vertices, 150, replace=False)] = True
    for weight, kind in ((0.01, SymmetricGaussSeidel), (0.002, SpectralPreconditioner)):
        picked.clear()
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            out, _ = fair(m, threshold=0.0, weight=weight, solver="cg", fix=fix, fixed=scattered)
        assert type(picked[0]) is kind, (weight, picked)
        ref, _ = fair(m, threshold=0.0, weight=weight, solver="direct", fix=fix, fixed=scattered)
        assert np.abs(out.vertices - ref.vertices).max() <= 1e-8 * size, weight
    # many fixed vertices scattered inside (far above the 64 that stored columns take): the exact lines correct
    # them in their own coordinates, in single precision, down to the smallest weights CG handles
    fixed = np.zeros(m.n_vertices, bool)
    fixed[np.random.default_rng(3).choice(m.n_vertices, 150, replace=False)] = True
    for weight in (1e-4, 1e-8):
        picked.clear()
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            out, rep = fair(m, threshold=0.0, weight=weight, solver="cg", fix=fix, fixed=fixed)
        assert picked and all(type(p) is SpectralPreconditioner and p._factored is not None for p in picked)
        assert picked[0]._dtype == np.float32 and rep.iterations[0].cg_iterations < 2 * steps[-1]
        if weight >= 1e-6:
            ref, _ = fair(m, threshold=0.0, weight=weight, solver="direct", fix=fix, fixed=fixed)
            assert np.abs(out.vertices - ref.vertices).max() <= 1e-8 * size, weight
        assert np.array_equal(out.vertices[fixed], m.vertices[fixed])


@pytest.mark.parametrize("case", ["graded", "tower", "both ways"])
def test_varying_coefficients_take_their_profile(monkeypatch, case):
    """Where the window coefficients vary along an axis (spacing that grows tenfold across a sheet, a cylinder
    tapering to a third of its radius, a sheet graded both ways) the transforms follow their profile along it (and
    along the other axis for the other family where it varies there too): far fewer steps than with constant
    coefficients, the same result; an even sheet keeps the constant ones."""
    import quadnodes.fairing as fairing_module
    from quadnodes.linalg import spectral
    from quadnodes.linalg.spectral import SpectralPreconditioner

    monkeypatch.setattr(fairing_module.kernels, "ready", lambda: False)
    monkeypatch.setattr(spectral, "loaded", lambda: True)  # (the transforms at any size)
    m = _noisy({"graded": lambda: _graded(50, 60, 10.0), "tower": lambda: _tower(50, 60, 3.0),
                "both ways": lambda: _graded(50, 60, 10.0, rows_ratio=10.0)}[case]())
    picked = _record_setups(monkeypatch, lambda system, out: out[1])
    out, rep = fair(m, threshold=0.0)
    assert isinstance(picked[0], SpectralPreconditioner) and picked[0].profile is not None
    axis, across = picked[0].profile[0], picked[0].profile[3]
    if case != "both ways":  # (along the graded columns' axis; along the tower's height)
        assert axis == (1 if case == "graded" else 0) and across is None
    else:  # (either axis, with the other family's windows varying along the other)
        assert across is not None and across.max() / across.min() > 10
    spread = fairing_module.PROFILE_MIN_SPREAD
    monkeypatch.setattr(fairing_module, "PROFILE_MIN_SPREAD", np.inf)
    picked.clear()
    same, constant = fair(m, threshold=0.0)
    assert isinstance(picked[0], SpectralPreconditioner) and picked[0].profile is None
    assert rep.iterations[0].cg_iterations * 1.5 < constant.iterations[0].cg_iterations
    size = np.ptp(m.vertices, axis=0).max()
    assert np.abs(out.vertices - same.vertices).max() <= 2e-8 * size
    monkeypatch.setattr(fairing_module, "PROFILE_MIN_SPREAD", spread)
    picked.clear()
    fair(_noisy(grid(50, 60, spacing=25.0)), threshold=0.0)
    assert isinstance(picked[0], SpectralPreconditioner) and picked[0].profile is None


@pytest.mark.parametrize("case", ["boundary", "line"])
def test_a_profile_beside_fixed_lines_keeps_its_steps_at_small_weights(monkeypatch, case):
    """Windows with a fixed end have no end coupling in the matrix's storage; the profile reads them from the
    windows that do (a fixed boundary, a fixed line across the grading): at ω = 10⁻⁴ no more steps than constant
    coefficients take, and the direct solve's result."""
    import quadnodes.fairing as fairing_module
    from quadnodes.linalg import spectral
    from quadnodes.linalg.spectral import SpectralPreconditioner

    monkeypatch.setattr(fairing_module.kernels, "ready", lambda: False)
    monkeypatch.setattr(spectral, "loaded", lambda: True)
    m = _noisy(_graded(50, 60, 10.0))
    kw = dict(threshold=0.0, weight=1e-4)
    if case == "boundary":
        kw["fix"] = "boundary"
    else:
        line = np.zeros((50, 60), bool)
        line[:, 30] = True  # (a column across the rows' grading)
        kw["fixed"] = np.flatnonzero(line)
    picked = _record_setups(monkeypatch, lambda system, out: out[1])
    out, rep = fair(m, **kw)
    assert isinstance(picked[0], SpectralPreconditioner) and picked[0].profile is not None
    assert np.all(picked[0].profile[1] > 0) and np.all(picked[0].profile[2] > 0)
    monkeypatch.setattr(fairing_module, "PROFILE_MIN_SPREAD", np.inf)
    _, constant = fair(m, **kw)
    assert rep.iterations[0].cg_iterations <= constant.iterations[0].cg_iterations
    ref, _ = fair(m, solver="direct", **kw)
    assert np.abs(out.vertices - ref.vertices).max() <= 1e-8 * np.ptp(m.vertices, axis=0).max()


def test_cylinders_keep_the_spectral_bound_without_the_open_grids_floor(monkeypatch):
    """A cylinder's Gershgorin bound is some 3–5 times a sheet's at the same weight and its spectral steps about
    twice as many, so the floor under small open grids (SPECTRAL_CONTRAST_MIN) is not its own: it keeps
    Gauss–Seidel down to a bound of SPECTRAL_CONTRAST ω (on this 48 × 60 cylinder ω = 0.02) and takes the spectral
    lines below, each within 1e-8 of the mesh's size of the direct solve."""
    import warnings

    from quadnodes.linalg import compiled, spectral
    from quadnodes.linalg.gauss_seidel import SymmetricGaussSeidel
    from quadnodes.linalg.spectral import SpectralPreconditioner

    assert compiled.wait()
    m = _noisy(cylinder(48, 60, radius=500.0, height=900.0))
    monkeypatch.setattr(compiled, "ready", lambda: True)
    monkeypatch.setattr(spectral, "loaded", lambda: True)
    picked = _record_setups(monkeypatch, lambda system, out: out[1])
    size = np.ptp(m.vertices, axis=0).max()
    for weight, kind in ((0.05, SymmetricGaussSeidel), (0.02, SymmetricGaussSeidel), (0.01, SpectralPreconditioner)):
        picked.clear()
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            out, _ = fair(m, threshold=0.0, weight=weight, solver="cg", fix="corners")
        assert type(picked[0]) is kind, (weight, picked)
        ref, _ = fair(m, threshold=0.0, weight=weight, solver="direct", fix="corners")
        assert np.abs(out.vertices - ref.vertices).max() <= 1e-8 * size, weight


def test_auto_takes_the_spectral_preconditioner_where_it_pays(monkeypatch):
    """Without the compiled kernels, on a mostly free grid: where plain CG's work is large enough or the
    transforms are imported, with few inner vertices fixed and no stiff spots; never on request off a grid."""
    import quadnodes.fairing as fairing_module
    from quadnodes.linalg import spectral
    from quadnodes.linalg.gauss_seidel import SymmetricGaussSeidel
    from quadnodes.linalg.spectral import SpectralPreconditioner

    m = _noisy(grid(40, 50, spacing=25.0))
    free = m.topology.window_middle.copy()
    w = 0.3 / m.mean_edge_length**2

    from quadnodes.zigzag import _window_geometry

    t = m.topology
    even = _window_geometry(m.vertices, t.windows, t.window_walk, even=True)[-2]  # fair's line_spacing="fair"

    def pick(free=free, weight=w, kinds=None):
        s = FairingSystem(m.vertices, t.windows, free, weight, solver="cg", _inverse_lengths=even, _topology=t)
        precond = s._cg_setup()[1]
        if kinds is not None:  # (the open axes' lines: cosine at large weights, exact at small ones)
            kinds.extend(ax.kind for ax in precond._axes)
        return type(precond)

    monkeypatch.setattr(fairing_module.kernels, "ready", lambda: False)
    monkeypatch.setattr(spectral, "loaded", lambda: False)
    assert pick() is type(None)  # 1,996 unknowns: plain CG's work is below SPECTRAL_MIN_WORK (the import)
    monkeypatch.setattr(fairing_module, "SPECTRAL_MIN_WORK", 1e4)
    kinds = []
    assert pick(kinds=kinds) is SpectralPreconditioner
    assert kinds == ["exact", "exact"]  # (SciPy's transforms not imported: exact lines, which need none)
    monkeypatch.setattr(fairing_module, "SPECTRAL_MIN_WORK", 1e12)
    monkeypatch.setattr(spectral, "loaded", lambda: True)  # imported already: at any size
    assert pick() is SpectralPreconditioner
    kinds = []
    assert pick(kinds=kinds) is SpectralPreconditioner and kinds == ["exact", "exact"]  # (a bound above 100 ω)
    kinds.clear()
    assert pick(weight=1.0 / m.mean_edge_length**2, kinds=kinds) is SpectralPreconditioner
    assert kinds == ["dct", "dct"]  # (imported, a bound below SPECTRAL_EXACT_CONTRAST ω: cosine lines)
    kinds.clear()
    assert pick(weight=0.003 / m.mean_edge_length**2, kinds=kinds) is SpectralPreconditioner  # (not block Jacobi)
    assert kinds == ["exact", "exact"]  # (a bound above SPECTRAL_EXACT_CONTRAST ω)
    assert pick(weight=30.0 / m.mean_edge_length**2) is type(None)  # a large weight: plain CG's few steps
    assert not fairing_module._spectral_pays(10**9, fairing_module.GAUSS_SEIDEL_CONTRAST)
    # eq. 32's own lengths: the windows are no scaled third differences, which the transforms model
    own = _window_geometry(m.vertices, t.windows, t.window_walk)[1]
    s = FairingSystem(m.vertices, t.windows, free, w, solver="cg", _inverse_lengths=own, _topology=t)
    assert not s._third_differences and type(s._cg_setup()[1]) is not SpectralPreconditioner
    # the compiled kernels wanted but missing (no Numba): the transforms, not block Jacobi
    monkeypatch.setattr(fairing_module, "COMPILED_MIN_UNKNOWNS", 100)
    wait = fairing_module.kernels.wait
    monkeypatch.setattr(fairing_module.kernels, "wait", lambda: False)
    assert pick(weight=0.003 / m.mean_edge_length**2) is SpectralPreconditioner
    monkeypatch.setattr(fairing_module, "COMPILED_MIN_UNKNOWNS", 250_000)
    inner = np.flatnonzero(free & ~m.topology.boundary_vertices)
    chosen = np.random.default_rng(0).choice(inner, spectral.MAX_CORRECTED + 1, replace=False)
    pins = free.copy()
    pins[chosen[:-1]] = False
    pins[m.topology.boundary_vertices] = False  # (fixed vertices around the unknowns' box do not count)
    larger = 1.0 / m.mean_edge_length**2  # (a bound below SPECTRAL_EXACT_CONTRAST ω: cosine lines, stored columns)
    assert pick(free=pins, weight=larger) is SpectralPreconditioner
    pins[chosen[-1]] = False  # one more than the stored columns take
    assert pick(free=pins, weight=larger) is type(None)
    kinds = []
    assert pick(free=pins, kinds=kinds) is SpectralPreconditioner  # (exact lines: the lines' coordinates take them)
    assert kinds == ["exact", "exact"]
    # more than the correction's set-up repays at this weight (p² > CORRECTION_PAYS √(bound/ω)): not at the default
    # weight, where plain CG needs few steps, but at a small one
    many = free.copy()
    many[np.random.default_rng(1).choice(inner, 100, replace=False)] = False
    assert pick(free=many) is not SpectralPreconditioner
    assert pick(free=many, weight=0.003 / m.mean_edge_length**2) is SpectralPreconditioner
    # a stiff spot: a collapsed stretch of a line (three vertices pulled onto their neighbour)
    v = m.vertices.copy()
    v[1021:1024] = v[1020] + 0.01 * (v[1021:1024] - v[1020])
    even_v = _window_geometry(v, t.windows, t.window_walk, even=True)[-2]
    stiff = FairingSystem(v, t.windows, free, w, solver="cg", _inverse_lengths=even_v, _topology=t)
    assert stiff._third_differences and type(stiff._cg_setup()[1]) is not SpectralPreconditioner
    offsets, data = stiff._cg[0].offsets, stiff._cg[0].data
    assert fairing_module._stiffness(offsets, data, stiff._grid[2], stiff.weight) > fairing_module.SPECTRAL_MAX_STIFFNESS
    monkeypatch.setattr(fairing_module.kernels, "wait", wait)
    monkeypatch.setattr(fairing_module.kernels, "ready", lambda: True)  # the compiled sweeps win where loaded
    assert pick() is SymmetricGaussSeidel
    with pytest.raises(InputError, match="spectral"):
        FairingSystem(m.vertices, m.topology.windows, free, w, solver="cg", preconditioner="spectral")._cg_setup()


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("kind", ["sheet", "torus"])
def test_stiff_spots_take_the_line_preconditioner(monkeypatch, threads, kind):
    """Under eq. 32's own lengths a nearly collapsed stretch of a line makes a stiff spot (fairing diagonals
    hundreds of times the median): "auto" takes the lines' banded solves there, on an open grid and a torus, at
    any size (the kernels loaded for it), and fairs within 1e-8 of the mesh's size of the direct solve; not where
    the matrix has no stiff spot, nor at a weight where the two-grid switch may be wanted."""
    import quadnodes.fairing as fairing_module
    from quadnodes.linalg import compiled
    from quadnodes.linalg.cg import LinePreconditioner
    from quadnodes.mesh import torus
    from quadnodes.topology import as_grid
    from quadnodes.zigzag import _window_geometry

    monkeypatch.setattr(linalg_threads, "PARALLEL_MIN_ROWS", 10)
    monkeypatch.setattr(linalg_threads, "thread_count", lambda: threads)
    monkeypatch.setattr(fairing_module, "LINES_MIN_WORK", 0.0)  # (a small grid: the kernels loaded for it anyway)
    if kind == "sheet":
        m, _ = perturb(grid(40, 50), tangential=0.2, normal=0.1, seed=3)
    else:
        base, _ = perturb(torus(24, 40, major=800.0, minor=200.0), tangential=0.2, normal=0.1, seed=3)
        m = as_grid(base)
    free = detect(m, 0.0).free
    w = 0.3 / m.mean_edge_length**2
    calm = _grid_system(m, free, w)
    assert not isinstance(calm._cg_setup()[1], LinePreconditioner)
    v = m.vertices.copy()
    row = v.shape[0] // 2 - 7  # three vertices of a row line pulled onto their neighbour
    v[row + 1:row + 4] = v[row] + 0.01 * (v[row + 1:row + 4] - v[row])
    stiff_mesh = m.with_vertices(v)
    s = _grid_system(stiff_mesh, free, w)
    offsets, data = s._cg_setup()[0].offsets, s._cg[0].data
    assert fairing_module._stiffness(offsets, data, s._grid[2], s.weight) >= fairing_module.LINES_MIN_STIFFNESS
    assert isinstance(s._cg[1], LinePreconditioner) and compiled.ready()
    x = s.solve(v[free])
    ref = FairingSystem(v, stiff_mesh.topology.windows, free, w, solver="direct",
                        _inverse_lengths=_window_geometry(v, stiff_mesh.topology.windows,
                                                          stiff_mesh.topology.window_walk)[1]).solve(v[free])
    extent = float(np.ptp(v, axis=0).max())
    assert np.abs(x - ref).max() <= 1e-8 * extent
    tiny = _grid_system(stiff_mesh, free, w * 1e-6)  # (a bound above TWO_GRID_CONTRAST ω: Gauss–Seidel's switch)
    assert tiny._cg_setup() and not isinstance(tiny._cg[1], LinePreconditioner)


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("kind", ["cylinder", "torus"])
def test_closed_grids_fair_on_the_grid_path_as_on_the_general_path(monkeypatch, threads, kind):
    """A cylinder or torus renumbered row by row (``as_grid``, closed ``grid_wrap``) takes the grid's
    diagonal storage with periodic diagonals for the windows across the seam, and fairs exactly as the
    file's numbering on the general path: within 1e-8 of the mesh's size, with CG (one or two threads)
    and direct."""
    from quadnodes.fairing import grid_pattern
    from quadnodes.mesh import torus
    from quadnodes.topology import as_grid

    base = cylinder(30, 40, radius=500.0, height=900.0) if kind == "cylinder" else torus(24, 40, major=800.0, minor=200.0)
    rng = np.random.default_rng(13)
    noisy = base.with_vertices(base.vertices + rng.normal(scale=0.2 * base.mean_edge_length, size=base.vertices.shape))
    p = rng.permutation(noisy.n_vertices)
    inv = np.argsort(p)
    shuffled = QuadMesh(noisy.vertices[p], inv[noisy.faces][rng.permutation(noisy.n_faces)])
    g = as_grid(shuffled)
    assert g is not None and g.grid_wrap[1] and grid_pattern(shuffled.topology) is None
    pattern = grid_pattern(g.topology)
    assert pattern is not None and pattern.offsets.size == (19 if kind == "cylinder" else 25)
    if threads > 1:
        monkeypatch.setattr(linalg_threads, "PARALLEL_MIN_ROWS", 10)
        monkeypatch.setattr(linalg_threads, "thread_count", lambda: threads)
    size = np.ptp(noisy.vertices, axis=0).max()
    where = {tuple(v): k for k, v in enumerate(shuffled.vertices.tolist())}
    back = np.array([where[tuple(v)] for v in g.vertices.tolist()])  # g's vertex k is shuffled's back[k]
    # one system on the grid path (diagonal storage) against the direct solve
    free = g.topology.window_middle & (rng.random(g.n_vertices) > 0.1)
    w = 0.3 / g.mean_edge_length**2
    s = FairingSystem(g.vertices, g.topology.windows, free, w, solver="cg", _topology=g.topology)
    x = s.solve(g.vertices[free])
    assert isinstance(s._cg[0], DiagonalBlocks) and len(s._cg[0].ranges) == threads and s.residual <= 1e-9
    d = FairingSystem(g.vertices, g.topology.windows, free, w, solver="direct").solve(g.vertices[free])
    assert np.abs(x - d).max() <= 1e-8 * size
    # the compiled kernels (symmetric storage with the periodic diagonals) and the line solves, whose
    # closed lines drop the couplings across the seam onto the diagonal
    import quadnodes.fairing as fairing_module
    from quadnodes.linalg.cg import LinePreconditioner, SymmetricDiagonalBlocks

    monkeypatch.setattr(fairing_module, "COMPILED_MIN_UNKNOWNS", 100)
    monkeypatch.setattr(linalg_cg, "LINES_PARALLEL_MIN_ROWS", 10 if threads > 1 else 10**9)
    steps = {}
    for pre in ("none", "lines"):
        c = FairingSystem(g.vertices, g.topology.windows, free, w, solver="cg", preconditioner=pre, _topology=g.topology)
        xc = c.solve(g.vertices[free])
        assert isinstance(c._cg[0], SymmetricDiagonalBlocks) and isinstance(c._cg[1], LinePreconditioner) == (pre == "lines")
        assert np.abs(xc - d).max() <= 1e-8 * size
        steps[pre] = c.iterations
    assert steps["lines"] < steps["none"]
    a, ra = fair(shuffled, threshold=0.0, solver="direct")  # the general path in the file's numbering
    for solver in ("cg", "direct"):
        b, rb = fair(g, threshold=0.0, solver=solver)
        assert [r.n_free for r in ra.iterations] == [r.n_free for r in rb.iterations]
        assert rb.iterations[0].solver == solver
        assert np.abs(b.vertices - a.vertices[back]).max() <= 1e-8 * size


# --- issue 16 item 6: spacing along the lines, thresholds for broadband noise ----------------------


def test_a_vertex_slid_along_its_line_goes_back_with_spacing_fair():
    """Frozen per-edge lengths (the thesis, ``line_spacing="hold"``) hold a vertex slid along its row; the window's
    mean length (``line_spacing="fair"``) brings it back. The same vertices are free either way."""
    g = grid(7, 9)
    v = g.vertices.copy()
    v[3 * 9 + 4, 0] += 0.3  # along row 3: its column now zigzags, its row is only unevenly spaced
    m = g.with_vertices(v)
    a, ra = fair(m, iterations=3, line_spacing="fair")
    b, rb = fair(m, iterations=3, line_spacing="hold")
    assert [r.n_free for r in ra.iterations] == [r.n_free for r in rb.iterations]
    err_a = np.linalg.norm(a.vertices - g.vertices, axis=1).max()
    err_b = np.linalg.norm(b.vertices - g.vertices, axis=1).max()
    assert err_a < 0.05 < err_b and err_b > 0.15


@given(st.floats(-0.3, 0.3), st.floats(0.5, 2.0), st.integers(0, 3))
def test_spacing_fair_costs_nothing_on_evenly_or_linearly_graded_lines(grade, step, axis):
    from quadnodes.fairing import even_lengths, window_coefficients

    # a straight line whose edges grow linearly: edge k has length step * (1 + grade * k / 8)
    lengths = step * (1 + grade * np.arange(8) / 8)
    direction = np.roll([1.0, 0.5, -0.25], axis)
    p = np.r_[0.0, np.cumsum(lengths)][:, None] * (direction / np.linalg.norm(direction)) + [3.0, -1.0, 2.0]
    w = np.arange(6)[:, None] + np.arange(4)
    c = window_coefficients(p, w, line_spacing="fair")
    assert np.abs(np.einsum("wk,wkj->wj", c, p[w])).max() <= 1e-12 * (1 + np.abs(p).max())
    np.testing.assert_allclose(c.sum(axis=1), 0.0, atol=1e-12)  # translation invariant
    inv = 1 / lengths[w[:, :3]]
    np.testing.assert_allclose(even_lengths(inv), np.repeat(3 / lengths[w[:, :3]].sum(axis=1), 3).reshape(-1, 3))


def test_default_threshold_follows_the_detection():
    from quadnodes.zigzag import DEFAULT_THRESHOLDS, detect

    m, _ = perturb(grid(8, 8), tangential=0.2, seed=1)
    assert detect(m).threshold == DEFAULT_THRESHOLDS["alternating"] == 0.03
    assert detect(m, detection="thesis").threshold == DEFAULT_THRESHOLDS["thesis"] == 0.1
    assert fair(m)[1].iterations[0].threshold == 0.03
    assert fair(m, detection="thesis")[1].iterations[0].threshold == 0.1
    assert fair(m, threshold=0.5, detection="thesis")[1].iterations[0].threshold == 0.5  # a given one is kept
    with pytest.raises(InputError, match="line_spacing"):
        fair(m, line_spacing="even")


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), rows=st.integers(2, 11), cols=st.integers(3, 11),
       kind=st.sampled_from(["cylinder", "torus"]), fixed_share=st.sampled_from([0.0, 0.3]))
def test_closed_grid_diagonal_storage_equals_the_normal_matrix(seed, rows, cols, kind, fixed_share):
    """On a cylinder or torus grid the periodic diagonals hold exactly AᵀA + ωI of the free vertices
    (windows across the seam included); grids with fewer than 7 vertices around a closed direction
    have no pattern (their diagonals would share offsets) and take the general path."""
    from quadnodes.fairing import grid_pattern
    from quadnodes.mesh import torus

    rows = max(rows, 3) if kind == "torus" else rows
    base = cylinder(rows, cols) if kind == "cylinder" else torus(rows, cols)
    rng = np.random.default_rng(seed)
    m = base.with_vertices(base.vertices + rng.normal(scale=0.05 * base.mean_edge_length, size=base.vertices.shape))
    t = m.topology
    pattern = grid_pattern(t)
    small = cols < 7 or (kind == "torus" and rows < 7)
    assert (pattern is None) == small
    if small:
        return
    free = t.window_middle & (rng.random(m.n_vertices) >= fixed_share)
    if not free.any():
        return
    s = FairingSystem(m.vertices, t.windows, free, 0.7)
    offsets, data = pattern.normal_matrix(window_coefficients_all(m), free, 0.7)
    _assert_storage_is_the_system(offsets, data, s, free)


def _shuffled(m, seed):
    """``m`` with its vertices renumbered at random (no grid of any kind any more)."""
    rng = np.random.default_rng(seed)
    perm = rng.permutation(m.n_vertices)
    inv = np.empty_like(perm)
    inv[perm] = np.arange(perm.size)
    return QuadMesh(m.vertices[perm], inv[m.faces])


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("kind", ["torus", "extraordinary", "holed", "rounded_box"])
def test_line_preconditioner_on_any_mesh_equals_the_direct_solve(monkeypatch, threads, kind):
    """Along the structure lines of a mesh that is no grid (closed lines, lines through held
    vertices, extraordinary vertices, a hole): CG with the path line preconditioner reaches the
    direct solve to 1e-8 of the mesh's size, held vertices never move."""
    from pathlib import Path

    from quadnodes.fairing import _line_paths
    from quadnodes.io import load
    from quadnodes.linalg.cg import PathLinePreconditioner
    from quadnodes.topology import fixed_vertices
    from quadnodes.zigzag import _window_geometry

    if kind == "torus":
        from quadnodes.mesh import torus

        m = _shuffled(torus(12, 17), 3)
    elif kind == "extraordinary":
        m = extraordinary_mesh()
    elif kind == "holed":
        m = l_shape_with_hole()
    else:
        m = load(Path(__file__).parent / "data" / "rounded_box.obj")
    assert m.topology.grid_shape is None and m.topology.closed_grid is None
    h = m.mean_edge_length
    m = m.with_vertices(m.vertices + np.random.default_rng(4).normal(scale=0.2 * h, size=m.vertices.shape))
    if threads > 1:
        monkeypatch.setattr(linalg_threads, "PARALLEL_MIN_ROWS", 10)
        monkeypatch.setattr(linalg_threads, "thread_count", lambda: threads)
    t = m.topology
    held = fixed_vertices(m, "corners") | (np.random.default_rng(5).random(m.n_vertices) < 0.1)
    free = t.window_middle & ~held
    _, inverse = _window_geometry(m.vertices, t.windows, t.window_walk)  # eq. 32's own lengths: stiff spots
    w = 0.3 / h**2
    s = FairingSystem(m.vertices, t.windows, free, w, solver="cg", _inverse_lengths=inverse,
                      preconditioner="lines", _lines=t.structure_lines)
    x = s.solve(m.vertices[free])
    assert isinstance(s._cg[1], PathLinePreconditioner)
    ref = FairingSystem(m.vertices, t.windows, free, w, solver="direct", _inverse_lengths=inverse)
    d = ref.solve(m.vertices[free])
    assert np.abs(x - d).max() <= 1e-8 * np.ptp(m.vertices, axis=0).max()
    path, starts, closed = _line_paths(t.structure_lines, s.free_index, m.n_vertices)
    assert path.size == np.isin(t.structure_lines.indices, s.free_index).sum()  # every free line vertex once
    assert not closed[~starts].any()


def test_line_paths_turn_a_closed_line_to_begin_at_a_held_vertex():
    from quadnodes.fairing import _line_paths
    from quadnodes.topology import StructureLines

    # one closed line 0..5 with vertex 2 held, one open line 6..9, one closed line 10..13 all free
    flat = np.array([0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13])
    lines = StructureLines(flat, np.array([0, 6, 10, 14]), np.array([True, False, True]))
    free_index = np.setdiff1d(np.arange(14), [2])
    path, starts, closed = _line_paths(lines, free_index, 14)
    unknown = free_index[path]  # back to vertex ids
    assert unknown.tolist() == [3, 4, 5, 0, 1, 6, 7, 8, 9, 10, 11, 12, 13]
    assert np.flatnonzero(starts).tolist() == [0, 5, 9] and np.flatnonzero(closed).tolist() == [9]


# --- gaps: a vertex between two found vertices of a line ----------------------------------


def test_gaps_hold_is_the_default_of_the_thesis_detection_and_a_lone_spike_is_not_spread():
    z = np.zeros((5, 7)); z[2, 3] = 0.5
    g = grid(5, 7, height=z)
    a, ra = fair(g, iterations=2, threshold=0.01)
    b, rb = fair(g, iterations=2, threshold=0.01, gaps="hold")
    np.testing.assert_array_equal(a.vertices, b.vertices)  # nothing lies between two found vertices
    t, _ = fair(g, iterations=2, detection="thesis")
    u, _ = fair(g, iterations=2, detection="thesis", gaps="hold")
    np.testing.assert_array_equal(t.vertices, u.vertices)
    with pytest.raises(InputError, match="gaps"):
        fair(g, gaps="grow")


@given(st.integers(0, 2**31 - 1))
def test_gaps_fill_broadband_noise_on_grids(seed):
    from quadnodes.zigzag import line_gaps

    clean = grid(9, 11, height=np.outer(np.sin(np.linspace(0, 2, 9)), np.ones(11)))
    noisy, _ = perturb(clean, jitter=0.2, seed=seed)
    found = detect(noisy)
    filled = line_gaps(found.free, noisy.topology.windows, found.fixed)
    assert (filled >= found.free).all() and not (filled & found.fixed).any()
    _, rep = fair(noisy)
    assert rep.iterations[0].n_free == int(filled.sum())


@pytest.mark.parametrize("rows", [2, 3, 4, 7])
def test_compiled_grid_path_on_grids_with_few_rows(monkeypatch, rows):
    """Grids of 2 and 3 rows have diagonals past the matrix (3 columns away): the compiled storage keeps
    them zero (it used to fail with a broadcast error) and CG equals the direct solve."""
    import quadnodes.fairing as fairing_module
    from quadnodes.linalg.cg import SymmetricDiagonalBlocks

    if not fairing_module.kernels.wait():
        pytest.skip("compiled kernels unavailable")
    m = grid(rows, 12, spacing=10.0)
    m = m.with_vertices(m.vertices + np.random.default_rng(rows).normal(scale=1.0, size=m.vertices.shape))
    free = m.topology.window_middle.copy()
    w = 0.3 / m.mean_edge_length**2
    s = _grid_system(m, free, w)
    s._cg_setup()
    assert isinstance(s._cg[0], SymmetricDiagonalBlocks)
    x = s.solve(m.vertices[free])
    d = FairingSystem(m.vertices, m.topology.windows, free, w, solver="direct").solve(m.vertices[free])
    assert np.abs(x - d).max() <= 1e-8 * np.ptp(m.vertices, axis=0).max()
    out, _ = fair(m, threshold=0.0, solver="cg")
    ref, _ = fair(m, threshold=0.0, solver="direct")
    assert np.abs(out.vertices - ref.vertices).max() <= 1e-8 * np.ptp(m.vertices, axis=0).max()


# --- line_curvature: bias correction (twicing) -----------------------------------------------


@given(meshes(), st.sampled_from([0.01, 0.3, 10.0]), st.sampled_from(["fair", "hold"]))
def test_holding_curvature_never_moves_a_mesh_more_than_fairing_it(mesh, weight, spacing):
    # one iteration, the same free vertices and frozen lengths: on every eigenmode of the system the displacement
    # of "hold" (twicing at ω/2) is λ(λ + ω)/(λ + ω/2)² ≤ 1 of that of "fair" — a clean design drifts less
    kw = dict(threshold=0.0, weight=weight, line_spacing=spacing)
    once, r1 = fair(mesh, **kw, line_curvature="fair")
    twice, r2 = fair(mesh, **kw, line_curvature="hold")
    assert [r.n_free for r in r1.iterations] == [r.n_free for r in r2.iterations]
    assert np.isfinite(twice.vertices).all()
    d1 = np.linalg.norm(once.vertices - mesh.vertices)
    d2 = np.linalg.norm(twice.vertices - mesh.vertices)
    assert d2 <= d1 * (1 + 1e-9) + 1e-12 * mesh.mean_edge_length
    # what fairing does not move, holding curvature does not move either
    still = np.all(once.vertices == mesh.vertices, axis=1)
    assert np.array_equal(twice.vertices[still], mesh.vertices[still])


@pytest.mark.parametrize("weight", [0.05, 0.3, 3.0])
def test_line_curvature_hold_is_twicing_at_half_the_weight(weight):
    # the thesis's rows (own lengths, no line-end rows): x₂ = x₁ + S(a − x₁) = S(2a − x₁) at ω/2, corners held
    noisy, _ = perturb(grid(8, 9, height=np.outer(np.linspace(0, 1, 8) ** 3, np.ones(9))), jitter=0.2, seed=4)
    out, rep = fair(noisy, threshold=0.0, weight=weight, weight_scale="raw", detection="thesis",
                    line_spacing="hold", extraordinary="hold", line_curvature="hold", solver="direct")
    from quadnodes.topology import fixed_vertices

    free = noisy.topology.window_middle & ~fixed_vertices(noisy, "corners")
    s = FairingSystem(noisy.vertices, noisy.topology.windows, free, weight / 2, solver="direct")
    a = noisy.vertices[free]
    x1 = s.solve(a)
    expected = x1 + (s.solve(a + (a - x1)) - s.solve(a))  # x₁ + S(a − x₁), S the linear part
    np.testing.assert_allclose(out.vertices[free], expected, atol=1e-9)
    np.testing.assert_array_equal(out.vertices[~free], noisy.vertices[~free])
    assert rep.iterations[0].weight_effective == pytest.approx(weight / 2)
    # with conjugate gradients, the report counts the steps of both solves
    _, r_cg = fair(noisy, threshold=0.0, weight=weight, weight_scale="raw", detection="thesis",
                   line_spacing="hold", extraordinary="hold", line_curvature="hold", solver="cg")
    _, r_once = fair(noisy, threshold=0.0, weight=weight / 2, weight_scale="raw", detection="thesis",
                     line_spacing="hold", extraordinary="hold", line_curvature="fair", solver="cg")
    assert r_cg.iterations[0].cg_iterations > r_once.iterations[0].cg_iterations > 0


def test_line_curvature_auto_is_the_default_and_bad_values_are_named():
    noisy, _ = perturb(grid(6, 7), jitter=0.2, seed=1)
    np.testing.assert_array_equal(fair(noisy)[0].vertices, fair(noisy, line_curvature="auto")[0].vertices)
    with pytest.raises(InputError, match="line_curvature"):
        fair(noisy, line_curvature="keep")
    with pytest.raises(InputError, match="line_curvature"):
        fair(noisy, line_curvature="Auto")  # exact lower-case, as every choice


def test_compiled_coefficients_equal_numpy_to_the_bit(monkeypatch):
    from quadnodes import fairing as fairing_module
    # (the kernels load on first call; compiled.wait() would switch this process's later tests to them)
    inverse = np.random.default_rng(5).random((3, 1000)).T * 10.0 ** np.arange(-3, 4).repeat(150)[:1000, None]
    inverse[7, 1] = np.inf  # an edge of length 0
    monkeypatch.setattr(fairing_module.kernels, "ready", lambda: False)
    a = fairing_module._coefficients(inverse[:, 0], inverse[:, 1], inverse[:, 2])
    monkeypatch.setattr(fairing_module.kernels, "ready", lambda: True)
    b = fairing_module._coefficients(inverse[:, 0], inverse[:, 1], inverse[:, 2])
    assert a.shape == b.shape == (1000, 4) and b.flags.c_contiguous
    assert np.array_equal(a.view(np.int64), b.view(np.int64))



# --- line_curvature="auto": the correction where the design's lines change curvature ------------


def _wavy_sheet(n: int = 40) -> QuadMesh:
    y, x = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n), indexing="ij")
    return grid(n, n, spacing=1.0 / (n - 1), height=0.3 * np.sin(3 * x) * np.cos(2 * y))


@pytest.mark.parametrize("noise", [dict(tangential=0.2, normal=0.05), dict(normal=0.2), "white"])
def test_auto_curvature_is_fair_to_the_bit_with_one_solve_on_evenly_curved_sheets(noise):
    # a finely sampled, evenly curved sheet (the benchmark's z = 0.3 sin 3x cos 2y): its lines change their
    # turning by far less than CURVATURE_CHANGE per window, so no window is held and the one solve is the result
    # (white noise on every vertex, the benchmark's "broadband": the few residual-noise windows that pass the
    # levels are below CURVATURE_MIN_SHARE from about 60² on; at 40² one seed of three holds 17 of ~3,000 windows)
    sheet = _wavy_sheet(60 if noise == "white" else 40)
    if noise == "white":
        rng = np.random.default_rng(2)
        noisy = sheet.with_vertices(sheet.vertices + rng.normal(scale=0.2 * sheet.mean_edge_length,
                                                                size=sheet.vertices.shape))
    else:
        noisy, _ = perturb(sheet, seed=2, **noise)
    auto, ra = fair(noisy, line_curvature="auto", solver="cg")
    once, rf = fair(noisy, line_curvature="fair", solver="cg")
    np.testing.assert_array_equal(auto.vertices, once.vertices)
    assert ra.iterations[0].n_free > 0 and ra.iterations[0].n_curvature_held == 0
    # one solve: the same CG steps as "fair" (the report counts both solves when there are two)
    assert ra.iterations[0].cg_iterations == rf.iterations[0].cg_iterations > 0
    # and a clean flat grid: nothing is free, nothing moves, no solve
    flat = grid(9, 11)
    out, rep = fair(flat, line_curvature="auto")
    assert out is flat and rep.iterations[0].n_free == 0


def test_auto_curvature_holds_the_windows_where_a_line_starts_to_bend():
    # an L-shaped sheet, two flat faces joined by a rounded edge of radius 2.5 h (the rounded box's feature): the
    # lines across the edge change their turning from 0 to 0.4 per edge and back, which one solve rounds off where
    # normal noise frees every vertex; "auto" holds the windows where the turning changes and drifts less
    n, cols, h, r, start = 12, 26, 1.0, 2.5, 9.0
    s = np.arange(cols) * h - start  # arc length from the start of the rounded edge
    arc = np.clip(s, 0.0, r * np.pi / 2)
    x = np.where(s <= 0, s + start, start + r * np.sin(arc / r))
    z = np.where(s <= 0, 0.0, r * (1 - np.cos(arc / r)) + np.clip(s - r * np.pi / 2, 0.0, None))
    verts = np.zeros((n, cols, 3))
    verts[..., 0] = x[None, :]
    verts[..., 1] = np.arange(n)[:, None] * h
    verts[..., 2] = z[None, :]
    clean = grid(n, cols).with_vertices(verts.reshape(-1, 3))
    noisy, _ = perturb(clean, normal=0.2, seed=5, fix="corners")
    err = {}
    for mode in ("fair", "auto"):
        out, rep = fair(noisy, line_curvature=mode)
        err[mode] = np.linalg.norm(out.vertices - clean.vertices, axis=1).mean() / h
        held = rep.iterations[0].n_curvature_held
    assert held > 0
    assert err["auto"] < 0.85 * err["fair"]


def test_auto_curvature_solves_once_with_the_lengths_held():
    # line_spacing="hold" freezes the noisy edge lengths: the faired terms then show the lengths' noise, so "auto"
    # is "fair" there — and the thesis's triple with the default line_curvature is the thesis exactly
    from quadnodes.io import load

    box = load(Path(__file__).parent / "data" / "rounded_box.obj")
    noisy, _ = perturb(box, normal=0.2, seed=0, fix="corners")
    thesis = dict(extraordinary="hold", detection="thesis", line_spacing="hold")
    out, rep = fair(noisy, **thesis)
    np.testing.assert_array_equal(out.vertices, fair(noisy, **thesis, line_curvature="fair")[0].vertices)
    assert rep.iterations[0].n_free > 0 and rep.iterations[0].n_curvature_held == 0
    # with the default spacing the same noisy box holds windows
    assert fair(noisy)[1].iterations[0].n_curvature_held > 0


def test_curvature_windows_needs_two_consecutive_windows_above_every_level():
    win = np.arange(10)[:, None] + np.arange(4)  # one line of 13 vertices
    f1 = np.zeros((10, 3))
    f1[4:7, 1] = 0.2
    noisy = np.full((10, 3), 0.3)
    inner = np.ones(10, bool)
    assert np.flatnonzero(curvature_windows(f1, noisy, win, inner)).tolist() == [4, 5, 6]
    # below the absolute level: evenly curved or finely sampled designs are left alone
    assert not curvature_windows(0.2 * f1, noisy, win, inner).any()
    # a noisy input whose typical window term is large raises the level (what one solve leaves of the noise)
    assert not curvature_windows(f1, np.full((10, 3), 2.0), win, inner).any()
    # windows with a vertex that is not free carry its noise, not the design's
    inner[5] = False
    assert np.flatnonzero(curvature_windows(f1, noisy, win, inner)).tolist() == []
    inner[5], inner[4] = True, False
    assert np.flatnonzero(curvature_windows(f1, noisy, win, inner)).tolist() == [5, 6]
    # windows of different lines are not consecutive
    win2 = win.copy()
    win2[5:] += 100
    assert np.flatnonzero(curvature_windows(f1, noisy, win2, np.ones(10, bool))).tolist() == [5, 6]
    # a pair among 1,000 windows of a line is below CURVATURE_MIN_SHARE: not worth a second solve of the whole
    long = np.arange(1000)[:, None] + np.arange(4)
    f_long = np.zeros((1000, 3))
    f_long[500:502, 1] = 0.2
    assert not curvature_windows(f_long, np.full((1000, 3), 0.3), long, np.ones(1000, bool)).any()
    f_long[500:505, 1] = 0.2  # 5 of 1,000 are
    assert curvature_windows(f_long, np.full((1000, 3), 0.3), long, np.ones(1000, bool)).sum() == 5
    # line-end rows after the windows are never held
    f_end = np.vstack([f1, np.full((3, 3), 0.5)])
    out = curvature_windows(f_end, np.vstack([noisy, noisy[:3]]), win, np.ones(13, bool))
    assert out.shape == (13,) and not out[10:].any()
    # shapes that do not fit are named
    with pytest.raises(InputError, match="noisy"):
        curvature_windows(f1, noisy[:5], win, np.ones(10, bool))
    with pytest.raises(InputError, match="windows"):
        curvature_windows(f1, noisy, np.vstack([win, win]), np.ones(10, bool))
    with pytest.raises(InputError, match="inner"):
        curvature_windows(f1, noisy, win, np.ones(10))
    with pytest.raises(InputError, match="faired"):
        curvature_windows(f1[:, :2], noisy, win, np.ones(10, bool))


@pytest.mark.parametrize("threads", [1, 2])
def test_gauss_seidel_on_any_mesh_equals_the_direct_solve(monkeypatch, threads):
    """``preconditioner="gauss-seidel"`` loads the kernels and runs at any size: an open grid's and a cylinder's
    fast sweeps (its seam's couplings kept out of them), a torus grid's, a narrow cylinder's and an irregular mesh's
    compressed rows (shuffled numbering too); within 1e-8 of the mesh's size
    of the direct solve at tiny (the error guard), small, default and large weights; "auto" takes it on a mesh that is no grid once the
    kernels are at hand."""
    import quadnodes.fairing as fairing_module
    from quadnodes.linalg.gauss_seidel import CsrGaussSeidel, SymmetricGaussSeidel
    from quadnodes.mesh import torus

    if threads > 1:
        monkeypatch.setattr(linalg_threads, "PARALLEL_MIN_ROWS", 10)
        monkeypatch.setattr(linalg_threads, "thread_count", lambda: threads)
    rng = np.random.default_rng(4)
    g, _ = perturb(grid(20, 30, spacing=25.0), tangential=0.25, normal=0.1, seed=3)
    t = torus(24, 40, major=800.0, minor=200.0)
    t = t.with_vertices(t.vertices + rng.normal(scale=0.2 * t.mean_edge_length, size=t.vertices.shape))
    e = extraordinary_mesh(3)
    e = e.with_vertices(e.vertices + rng.normal(scale=0.1 * e.mean_edge_length, size=e.vertices.shape))
    p = rng.permutation(e.n_vertices)
    shuffled = QuadMesh(e.vertices[p], np.argsort(p)[e.faces])
    c = cylinder(20, 56, radius=300.0, height=400.0)  # (56 around: its seam's pairs read as entries)
    c = c.with_vertices(c.vertices + rng.normal(scale=0.2 * c.mean_edge_length, size=c.vertices.shape))
    narrow = cylinder(20, 30, radius=300.0, height=400.0)  # (30 around: its seam's pairs too many for entries)
    narrow = narrow.with_vertices(narrow.vertices + rng.normal(scale=0.2 * narrow.mean_edge_length,
                                                               size=narrow.vertices.shape))
    for m, kind, topology in ((g, SymmetricGaussSeidel, True), (t, CsrGaussSeidel, True), (c, SymmetricGaussSeidel, True),
                              (narrow, CsrGaussSeidel, True), (e, CsrGaussSeidel, False),
                              (shuffled, CsrGaussSeidel, False)):
        free = m.topology.window_middle & (rng.random(m.n_vertices) > 0.1)
        for weight in (1e-6, 0.003, 0.3, 10.0):
            w = weight / m.mean_edge_length**2
            s = FairingSystem(m.vertices, m.topology.windows, free, w, solver="cg", preconditioner="gauss-seidel",
                              _topology=m.topology if topology else None)
            x = s.solve(m.vertices[free])
            assert isinstance(s._cg[1], kind) and s.residual <= 1e-9
            assert len(s._cg[0].ranges) == threads
            assert (getattr(s._cg[1], "seam", None) is not None) == (m is c)  # (the cylinder's seam kept outside)
            d = FairingSystem(m.vertices, m.topology.windows, free, w, solver="direct").solve(m.vertices[free])
            assert np.abs(x - d).max() <= 1e-8 * np.ptp(m.vertices, axis=0).max()
    monkeypatch.setattr(fairing_module.kernels, "ready", lambda: True)
    free = e.topology.window_middle
    auto = FairingSystem(e.vertices, e.topology.windows, free, 0.3 / e.mean_edge_length**2, solver="cg")
    auto._cg_setup()
    assert isinstance(auto._cg[1], CsrGaussSeidel)
    monkeypatch.setattr(fairing_module.kernels, "ready", lambda: False)  # a fresh process, a small mesh: plain CG
    fresh = FairingSystem(e.vertices, e.topology.windows, free, 0.3 / e.mean_edge_length**2, solver="cg")
    fresh._cg_setup()
    assert not getattr(fresh._cg[1], "eisenstat", False)


@pytest.mark.parametrize("threads", [1, 2])
def test_two_grid_equals_the_direct_solve_at_tiny_weights(monkeypatch, threads):
    """``preconditioner="two-grid"`` on an open grid: within 1e-8 of the mesh's size of the direct solve from
    the default weight down to 1e-7, with steps that do not grow as the weight falls; the fixed vertices stay
    put (identity rows). "auto" below TWO_GRID_CONTRAST (loading the kernels for it in a fresh process too) runs
    Gauss–Seidel and switches to it after TWO_GRID_AFTER steps, and not where scattered fixed vertices make
    Gauss–Seidel fast; at the default weight it keeps Gauss–Seidel (or, fresh and small, plain CG). A mesh
    without a grid is refused by name."""
    import quadnodes.fairing as fairing_module
    from quadnodes.linalg.gauss_seidel import SymmetricGaussSeidel
    from quadnodes.linalg.multigrid import TwoGrid
    from quadnodes.mesh import torus

    if threads > 1:
        monkeypatch.setattr(linalg_threads, "PARALLEL_MIN_ROWS", 10)
        monkeypatch.setattr(linalg_threads, "thread_count", lambda: threads)
    rng = np.random.default_rng(6)
    m = grid(48, 41, spacing=0.5)
    m = m.with_vertices(m.vertices + rng.normal(scale=0.2 * 0.5, size=m.vertices.shape))
    free = m.topology.window_middle & (rng.random(m.n_vertices) > 0.05)
    steps = {}
    for weight in (0.3, 1e-3, 1e-5, 1e-7):
        w = weight / m.mean_edge_length**2
        s = FairingSystem(m.vertices, m.topology.windows, free, w, solver="cg", preconditioner="two-grid",
                          _topology=m.topology)
        x = s.solve(m.vertices[free])
        assert isinstance(s._cg[1], TwoGrid) and s.residual <= 1e-9
        assert s._cg[1].strides == (4, 4)  # (square quads: no axis's couplings much weaker)
        steps[weight] = s.iterations
        d = FairingSystem(m.vertices, m.topology.windows, free, w, solver="direct").solve(m.vertices[free])
        assert np.abs(x - d).max() <= 1e-8 * np.ptp(m.vertices, axis=0).max(), weight
    # (from 1e-3 down only the error guard's target moves, ∝ ω: a few steps per decade, not Gauss–Seidel's 1/√ω)
    assert steps[1e-7] <= 1.5 * steps[1e-3] and steps[1e-3] <= 2.5 * steps[0.3], steps
    every = m.topology.window_middle  # (all free: Gauss–Seidel needs 1,201 steps at 1e-6, the cycle 130)
    for ready, weight, kind in ((True, 1e-6, TwoGrid), (True, 0.3, SymmetricGaussSeidel),
                                (False, 1e-6, TwoGrid), (False, 0.3, type(None))):  # (False: a fresh process)
        monkeypatch.setattr(fairing_module.kernels, "ready", lambda: ready)
        w = weight / m.mean_edge_length**2
        auto = FairingSystem(m.vertices, m.topology.windows, every, w, solver="cg", _topology=m.topology)
        x = auto.solve(m.vertices[every])  # (at 1e-6: Gauss–Seidel's TWO_GRID_AFTER steps, then the two-grid cycle)
        assert isinstance(auto._cg[1], kind), (ready, weight)
        assert (auto.iterations > fairing_module.TWO_GRID_AFTER) == (kind is TwoGrid)
        d = FairingSystem(m.vertices, m.topology.windows, every, w, solver="direct").solve(m.vertices[every])
        assert np.abs(x - d).max() <= 1e-8 * np.ptp(m.vertices, axis=0).max()
    # a coarse space priced as dear as 143 coarse nodes at a per-node cost of 1 (TWO_GRID_REMAINING_COARSE = 1):
    # worth 700·√143 ≈ 8,400 Gauss–Seidel steps, more than all 1,201 it needs, so it goes on: no switch
    monkeypatch.setattr(fairing_module.kernels, "ready", lambda: True)
    priced = fairing_module.TWO_GRID_REMAINING_COARSE
    monkeypatch.setattr(fairing_module, "TWO_GRID_REMAINING_COARSE", 1)
    auto = FairingSystem(m.vertices, m.topology.windows, every, 1e-6 / m.mean_edge_length**2, solver="cg",
                         _topology=m.topology)
    auto.solve(m.vertices[every])
    assert auto._coarse == 13 * 11 and isinstance(auto._cg[1], SymmetricGaussSeidel)
    assert auto.iterations > 2 * fairing_module.TWO_GRID_AFTER and auto.residual <= 1e-9
    monkeypatch.setattr(fairing_module, "TWO_GRID_REMAINING_COARSE", priced)  # (the cases below as priced)
    # 5 % fixed at random: Gauss–Seidel needs some 500 steps, past TWO_GRID_AFTER, but its rate says it is nearly
    # done (fewer than TWO_GRID_REMAINING to go), so it goes on: no switch
    monkeypatch.setattr(fairing_module.kernels, "ready", lambda: True)
    auto = FairingSystem(m.vertices, m.topology.windows, free, 1e-6 / m.mean_edge_length**2, solver="cg",
                         _topology=m.topology)
    auto.solve(m.vertices[free])
    assert isinstance(auto._cg[1], SymmetricGaussSeidel) and auto.iterations > fairing_module.TWO_GRID_AFTER
    # a third of the vertices fixed at random hold the smooth modes: Gauss-Seidel converges, no switch
    held = free & (rng.random(m.n_vertices) > 0.3)
    auto = FairingSystem(m.vertices, m.topology.windows, held, 1e-6 / m.mean_edge_length**2, solver="cg",
                         _topology=m.topology)
    auto.solve(m.vertices[held])
    assert isinstance(auto._cg[1], SymmetricGaussSeidel) and auto.iterations < fairing_module.TWO_GRID_AFTER
    t = torus(24, 40, major=800.0, minor=200.0)  # neither its grid (_topology) nor its lines (_lines): refused
    with pytest.raises(InputError, match="two-grid.*needs the mesh's structure lines"):
        FairingSystem(t.vertices, t.topology.windows, t.topology.window_middle, 1e-9, solver="cg",
                      preconditioner="two-grid")._cg_setup()


@pytest.mark.parametrize("kind", ["cylinder", "torus"])
def test_two_grid_on_cylinders_and_tori(monkeypatch, kind):
    """A cylinder's or torus's grid (the seams' diagonals, compressed-row sweeps) takes the two-grid cycle with
    coarse lines closed around: within 1e-8 of the mesh's size of the direct solve from 1e-3 down to 1e-7, steps
    that do not grow as Gauss–Seidel's; "auto" at 1e-6 switches to it after TWO_GRID_AFTER steps, and in a
    fresh process loads the kernels for it (it used to keep block Jacobi there)."""
    import quadnodes.fairing as fairing_module
    from quadnodes.linalg.multigrid import TwoGrid
    from quadnodes.mesh import torus

    rng = np.random.default_rng(11)
    base = cylinder(30, 40, radius=500.0, height=900.0) if kind == "cylinder" else torus(24, 40, major=800.0,
                                                                                         minor=200.0)
    m = base.with_vertices(base.vertices + rng.normal(scale=0.2 * base.mean_edge_length, size=base.vertices.shape))
    free = m.topology.window_middle
    extent = np.ptp(m.vertices, axis=0).max()
    steps, strides = {}, {}
    for weight in (1e-3, 1e-5, 1e-7):
        w = weight / m.mean_edge_length**2
        d = FairingSystem(m.vertices, m.topology.windows, free, w, solver="direct").solve(m.vertices[free])
        s = FairingSystem(m.vertices, m.topology.windows, free, w, solver="cg", preconditioner="two-grid",
                          _topology=m.topology)
        x = s.solve(m.vertices[free])
        assert isinstance(s._cg[1], TwoGrid) and s._cg[1].sweeps.columns is False and s.residual <= 1e-9
        strides[weight] = s._cg[1].strides
        assert np.abs(x - d).max() <= 1e-8 * extent, weight
        steps[weight] = s.iterations
        if weight == 1e-5:
            gs = FairingSystem(m.vertices, m.topology.windows, free, w, solver="cg", preconditioner="gauss-seidel",
                               _topology=m.topology)
            gs.solve(m.vertices[free])
            assert gs.iterations > 2 * s.iterations, (gs.iterations, s.iterations)
    assert steps[1e-7] <= 1.5 * steps[1e-3], steps
    # the cylinder's edges around are 2.5 times those along, the torus's around its axis 2.4 times those around
    # its tube (on average): the couplings along the rows are weak, so the coarse grid takes every 2nd vertex of a
    # row (TWO_GRID_ANISOTROPY)
    assert set(strides.values()) == {(4, 2)}, strides
    monkeypatch.setattr(fairing_module.kernels, "ready", lambda: False)  # a fresh process
    w = 1e-6 / m.mean_edge_length**2
    auto = FairingSystem(m.vertices, m.topology.windows, free, w, solver="cg", _topology=m.topology)
    x = auto.solve(m.vertices[free])
    assert isinstance(auto._cg[1], TwoGrid) and auto.iterations > fairing_module.TWO_GRID_AFTER
    d = FairingSystem(m.vertices, m.topology.windows, free, w, solver="direct").solve(m.vertices[free])
    assert np.abs(x - d).max() <= 1e-8 * extent


@pytest.mark.parametrize("kind", ["extraordinary", "holed, boundary fixed", "rounded_box"])
def test_two_grid_on_meshes_that_are_no_grid(monkeypatch, kind):
    """A mesh that is no grid (extraordinary vertices, a hole with its boundary fixed, a closed box) takes the
    two-grid cycle on coarse nodes along its structure lines (LineTwoGrid): within 1e-8 of the mesh's size of the
    direct solve from 1e-3 down to 1e-7 on one and two threads, the fixed vertices put, steps that do not grow as
    Gauss–Seidel's; "auto" at 1e-6 switches to it where Gauss–Seidel is slow, in a fresh process too."""
    import quadnodes.fairing as fairing_module
    from quadnodes.io import load
    from quadnodes.linalg.multigrid import LineTwoGrid

    if kind == "extraordinary":
        base = extraordinary_mesh(4)
    elif kind == "rounded_box":
        base = load(Path(__file__).parent / "data" / "rounded_box.obj")
    else:
        base = l_shape_with_hole(50)
    rng = np.random.default_rng(12)
    m = base.with_vertices(base.vertices + rng.normal(scale=0.2 * base.mean_edge_length, size=base.vertices.shape))
    free = m.topology.window_middle.copy()
    if kind.endswith("fixed"):
        free &= ~m.topology.boundary_vertices
    lines = m.topology.structure_lines
    extent = np.ptp(m.vertices, axis=0).max()
    steps = {}
    for threads in (1, 2):
        if threads > 1:
            monkeypatch.setattr(linalg_threads, "PARALLEL_MIN_ROWS", 10)
            monkeypatch.setattr(linalg_threads, "thread_count", lambda: threads)
        for weight in (1e-3, 1e-5, 1e-7):
            w = weight / m.mean_edge_length**2
            d = FairingSystem(m.vertices, m.topology.windows, free, w, solver="direct").solve(m.vertices[free])
            s = FairingSystem(m.vertices, m.topology.windows, free, w, solver="cg", preconditioner="two-grid",
                              _lines=lines)
            x = s.solve(m.vertices[free])
            assert isinstance(s._cg[1], LineTwoGrid) and s.residual <= 1e-9
            assert np.abs(x - d).max() <= 1e-8 * extent, (threads, weight)
            steps[threads, weight] = s.iterations
        assert steps[threads, 1e-7] <= 1.5 * steps[threads, 1e-3] + 5, steps
    gs = FairingSystem(m.vertices, m.topology.windows, free, 1e-7 / m.mean_edge_length**2, solver="cg",
                       preconditioner="gauss-seidel", _lines=lines)
    gs.solve(m.vertices[free])
    assert gs.iterations > 1.5 * steps[2, 1e-7], (gs.iterations, steps)
    if kind.startswith("holed"):  # Gauss–Seidel needs thousands of steps here at 1e-6: "auto" switches
        held = m.topology.boundary_vertices  # (the public path, fair(): equal to the direct one, held put)
        faired = [fair(m, weight=1e-6, threshold=0.0, fix="boundary", solver=solver)[0].vertices
                  for solver in ("cg", "direct")]
        assert np.array_equal(faired[0][held], m.vertices[held])
        assert np.abs(faired[0] - faired[1]).max() <= 1e-8 * extent
        monkeypatch.setattr(fairing_module.kernels, "ready", lambda: False)  # (a fresh process: loads the kernels)
        w = 1e-6 / m.mean_edge_length**2
        auto = FairingSystem(m.vertices, m.topology.windows, free, w, solver="cg", _lines=lines)
        x = auto.solve(m.vertices[free])
        assert isinstance(auto._cg[1], LineTwoGrid) and auto.iterations > fairing_module.TWO_GRID_AFTER
        assert auto._coarse == auto._cg[1].P.shape[1]  # (what the switch was priced at: the lines' coarse nodes)
        d = FairingSystem(m.vertices, m.topology.windows, free, w, solver="direct").solve(m.vertices[free])
        assert np.abs(x - d).max() <= 1e-8 * extent


@pytest.mark.parametrize("threads", [1, 2])
def test_the_line_cycle_solves_along_the_lines_where_faces_are_long_and_thin(monkeypatch, threads):
    """Random quads (slivers of a Delaunay triangulation split three times: more than LINE_SMOOTHING_SHARE of the
    unknowns tied over LINE_SMOOTHING_RATIO times more strongly one way): the lines' two-grid cycle takes the line
    solves, along each unknown's strongest line, every unknown once; within 1e-8 of the mesh's size of the direct
    solve at 1e-3 and 1e-7, in fewer steps than without them; "auto" at 1e-7 takes that cycle too. On the
    extraordinary mesh (square faces) the cycle keeps the point sweeps alone."""
    import quadnodes.fairing as fairing_module
    from quadnodes.linalg.multigrid import LineTwoGrid

    if threads > 1:
        monkeypatch.setattr(linalg_threads, "PARALLEL_MIN_ROWS", 10)
        monkeypatch.setattr(linalg_threads, "thread_count", lambda: threads)
    base = random_quads(20, 3, seed=3)
    rng = np.random.default_rng(5)
    m = base.with_vertices(base.vertices + rng.normal(scale=0.2 * base.mean_edge_length, size=base.vertices.shape))
    t = m.topology
    free = t.window_middle.copy()
    extent = np.ptp(m.vertices, axis=0).max()
    for weight in (1e-3, 1e-7):
        w = weight / m.mean_edge_length**2
        d = FairingSystem(m.vertices, t.windows, free, w, solver="direct").solve(m.vertices[free])
        steps = {}
        for share in (1.0, fairing_module.LINE_SMOOTHING_SHARE):  # (1.0: never)
            monkeypatch.setattr(fairing_module, "LINE_SMOOTHING_SHARE", share)
            s = FairingSystem(m.vertices, t.windows, free, w, solver="cg", preconditioner="two-grid",
                              _lines=t.structure_lines)
            x = s.solve(m.vertices[free])
            cycle = s._cg[1]
            assert isinstance(cycle, LineTwoGrid) and (cycle.line_solves is None) == (share == 1.0)
            assert np.abs(x - d).max() <= 1e-8 * extent, (weight, share)
            steps[share] = s.iterations
        assert np.array_equal(np.sort(cycle.line_solves.path), np.arange(s.n_free))  # (every unknown once)
        assert steps[fairing_module.LINE_SMOOTHING_SHARE] < steps[1.0], steps
    auto = FairingSystem(m.vertices, t.windows, free, w, solver="cg", _lines=t.structure_lines)
    x = auto.solve(m.vertices[free])
    assert isinstance(auto._cg[1], LineTwoGrid) and auto._cg[1].line_solves is not None
    assert np.abs(x - d).max() <= 1e-8 * extent
    square = extraordinary_mesh(4)
    s = FairingSystem(square.vertices, square.topology.windows, square.topology.window_middle, 1e-6, solver="cg",
                      preconditioner="two-grid", _lines=square.topology.structure_lines)
    s.solve(square.vertices[square.topology.window_middle])
    assert isinstance(s._cg[1], LineTwoGrid) and s._cg[1].line_solves is None


def test_auto_starts_the_line_cycle_at_once_where_the_contrast_is_huge_and_few_vertices_are_held(monkeypatch):
    """On a mesh that is no grid with its Gershgorin bound above TWO_GRID_AT_ONCE_CONTRAST ω and at most
    TWO_GRID_AT_ONCE_HELD of its vertices held, "auto" takes the lines' two-grid cycle from the first step (equal to
    the direct solve, in fewer than TWO_GRID_AFTER steps); below that contrast, or with 5 % of the vertices held,
    it starts on Gauss–Seidel, ready to switch; where the cycle cannot be made, on Gauss–Seidel too."""
    import quadnodes.fairing as fairing_module
    from quadnodes.linalg.gauss_seidel import CsrGaussSeidel
    from quadnodes.linalg.multigrid import LineTwoGrid

    base = random_quads(20, 3, seed=3)
    rng = np.random.default_rng(5)
    m = base.with_vertices(base.vertices + rng.normal(scale=0.2 * base.mean_edge_length, size=base.vertices.shape))
    t = m.topology
    w = 1e-7 / m.mean_edge_length**2
    extent = np.ptp(m.vertices, axis=0).max()
    few_held = t.window_middle | ~t.boundary_vertices  # (0.5 % held)
    some_held = few_held & (rng.random(m.n_vertices) >= 0.05)
    for free, at_once_from, starts_on in ((few_held, fairing_module.TWO_GRID_AT_ONCE_CONTRAST, LineTwoGrid),
                                          (few_held, np.inf, CsrGaussSeidel),
                                          (some_held, fairing_module.TWO_GRID_AT_ONCE_CONTRAST, CsrGaussSeidel)):
        monkeypatch.setattr(fairing_module, "TWO_GRID_AT_ONCE_CONTRAST", at_once_from)
        auto = FairingSystem(m.vertices, t.windows, free, w, solver="cg", _lines=t.structure_lines)
        assert auto._contrast == 0.0 and isinstance(auto._cg_setup()[1], starts_on)
        assert auto._contrast > 5e6
        assert (auto._switch_to is not None) == (starts_on is CsrGaussSeidel)
        x = auto.solve(m.vertices[free])
        assert (auto.iterations < fairing_module.TWO_GRID_AFTER) == (starts_on is LineTwoGrid)
        d = FairingSystem(m.vertices, t.windows, free, w, solver="direct").solve(m.vertices[free])
        assert np.abs(x - d).max() <= 1e-8 * extent
    # where the cycle cannot be made (a coarse matrix that does not factorize: not expected), "auto" starts on
    # Gauss–Seidel instead and still reaches the direct solve
    monkeypatch.setattr(fairing_module, "TWO_GRID_AT_ONCE_CONTRAST", 5e6)

    def refused(*args, **kwargs):  # type: ignore[no-untyped-def]
        raise InputError("two-grid coarse matrix: refused (a test's stand-in)")

    monkeypatch.setattr(fairing_module, "LineTwoGrid", refused)
    auto = FairingSystem(m.vertices, t.windows, few_held, w, solver="cg", _lines=t.structure_lines)
    assert isinstance(auto._cg_setup()[1], CsrGaussSeidel)
    x = auto.solve(m.vertices[few_held])
    d = FairingSystem(m.vertices, t.windows, few_held, w, solver="direct").solve(m.vertices[few_held])
    assert np.abs(x - d).max() <= 1e-8 * extent


def test_the_switch_and_the_cycle_share_one_line_step(monkeypatch):
    """Where "auto" starts on Gauss–Seidel (5 % held) and switches to the lines' cycle, the line step is chosen
    once: the monitor's question (is the cycle cheaper?) and the cycle take the same line solves; the price is
    lowered only where there are some."""
    import quadnodes.fairing as fairing_module
    from quadnodes.linalg.multigrid import LineTwoGrid

    base = random_quads(20, 3, seed=3)
    rng = np.random.default_rng(5)
    m = base.with_vertices(base.vertices + rng.normal(scale=0.2 * base.mean_edge_length, size=base.vertices.shape))
    t = m.topology
    free = (t.window_middle | ~t.boundary_vertices) & (rng.random(m.n_vertices) >= 0.05)
    made = []
    original = FairingSystem._line_smoothing
    monkeypatch.setattr(FairingSystem, "_line_smoothing", lambda self, M: made.append(original(self, M)) or made[-1])
    asked = []
    check = fairing_module._SwitchCheck
    monkeypatch.setattr(fairing_module, "_SwitchCheck",
                        lambda rtol, remaining, cheaper=None: asked.append(cheaper) or check(rtol, remaining, cheaper))
    w = 1e-7 / m.mean_edge_length**2
    auto = FairingSystem(m.vertices, t.windows, free, w, solver="cg", _lines=t.structure_lines)
    x = auto.solve(m.vertices[free])
    assert isinstance(auto._cg[1], LineTwoGrid) and auto.iterations > fairing_module.TWO_GRID_AFTER
    assert len(made) == 1 and made[0] is not None and auto._cg[1].line_solves is made[0]
    assert len(asked) == 1 and asked[0] is not None and asked[0]() is True and len(made) == 1
    d = FairingSystem(m.vertices, t.windows, free, w, solver="direct").solve(m.vertices[free])
    assert np.abs(x - d).max() <= 1e-8 * np.ptp(m.vertices, axis=0).max()


def test_auto_keeps_gauss_seidel_where_the_line_coarse_space_is_too_large(monkeypatch):
    """"auto" makes the line coarse space before Gauss–Seidel starts: above TWO_GRID_COARSE_MAX coarse nodes it
    does not switch (no restart), and still equals the direct solve; "two-grid" asked for refuses by name."""
    import quadnodes.fairing as fairing_module
    from quadnodes.linalg.gauss_seidel import CsrGaussSeidel

    base = l_shape_with_hole(50)
    rng = np.random.default_rng(12)
    m = base.with_vertices(base.vertices + rng.normal(scale=0.2 * base.mean_edge_length, size=base.vertices.shape))
    free = m.topology.window_middle & ~m.topology.boundary_vertices
    w = 1e-6 / m.mean_edge_length**2
    monkeypatch.setattr(fairing_module, "TWO_GRID_COARSE_MAX", 50)
    monkeypatch.setattr(fairing_module.kernels, "ready", lambda: True)
    auto = FairingSystem(m.vertices, m.topology.windows, free, w, solver="cg", _lines=m.topology.structure_lines)
    x = auto.solve(m.vertices[free])
    assert isinstance(auto._cg[1], CsrGaussSeidel) and auto._switch_to is None
    d = FairingSystem(m.vertices, m.topology.windows, free, w, solver="direct").solve(m.vertices[free])
    assert np.abs(x - d).max() <= 1e-8 * np.ptp(m.vertices, axis=0).max()
    with pytest.raises(InputError, match=r"^preconditioner='two-grid': \d+ coarse nodes along the structure lines"):
        FairingSystem(m.vertices, m.topology.windows, free, w, solver="cg", preconditioner="two-grid",
                      _lines=m.topology.structure_lines).solve(m.vertices[free])


@pytest.mark.parametrize(("kind", "line_curvature"), [("holed", "auto"), ("holed", "hold"), ("grid", "hold")])
def test_second_solves_at_tiny_weights_keep_to_the_direct_solver(kind, line_curvature):
    """fair()'s second solve (``line_curvature="auto"``: the anchor a + AᵀHf/ω, far off the mesh at a tiny ω;
    ``"hold"``: 2a − x₁) starts CG at the first solution: from the anchor, the updated residual's rounding (in
    proportion to the first residual) left 1.3e-6 of the extent on the holed L-shape at ω = 1e-6, and the error
    guard measured the anchor's extent instead of the mesh's."""
    rng = np.random.default_rng(12)
    base = grid(48, 41, spacing=0.5) if kind == "grid" else l_shape_with_hole(50)
    m = base.with_vertices(base.vertices + rng.normal(scale=0.2 * base.mean_edge_length, size=base.vertices.shape))
    faired = [fair(m, weight=1e-6, threshold=0.0, fix="boundary", solver=solver, line_curvature=line_curvature)
              for solver in ("cg", "direct")]
    if line_curvature == "auto":
        assert faired[0][1].iterations[0].n_curvature_held > 0  # (a second solve ran)
    assert np.abs(faired[0][0].vertices - faired[1][0].vertices).max() <= 1e-8 * np.ptp(m.vertices, axis=0).max()


def test_solve_refuses_a_start_of_the_wrong_shape():
    m = grid(6, 7)
    s = FairingSystem(m.vertices, m.topology.windows, m.topology.window_middle, 0.3, solver="cg")
    with pytest.raises(InputError, match=r"start: expected shape \(\d+, 3\)"):
        s.solve(m.vertices[s.free_index], start=np.zeros((3, 3)))


def test_switch_check_extrapolates_the_residuals_decay():
    """The monitor of "auto"'s Gauss–Seidel run: at step TWO_GRID_AFTER (and every TWO_GRID_AFTER after) it
    switches where the decay of the last 100 steps needs more than TWO_GRID_REMAINING more to reach rtol, or where
    the residual no longer falls; not before, and not where Gauss–Seidel is nearly done."""
    from quadnodes.fairing import TWO_GRID_AFTER, TWO_GRID_REMAINING, _SwitchCheck

    def run(rate: float, rtol: float = 1e-10, noise: float = 0.0,
            remaining: float = TWO_GRID_REMAINING) -> tuple[bool, int]:
        check, wobble = _SwitchCheck(rtol, remaining), np.random.default_rng(0)
        for step in range(1, 4 * TWO_GRID_AFTER + 1):
            residual = np.exp(-rate * step) * np.exp(noise * wobble.normal())
            if check(step, residual):
                return check.switch, step
        return check.switch, step

    # the residual at TWO_GRID_AFTER is exp(-rate·300); rtol 1e-10 is ln 1e-10 ≈ -23.0 away from 1
    slow = 23.0 / (TWO_GRID_AFTER + 2 * TWO_GRID_REMAINING)  # about 2,000 steps still to go at the check
    fast = 23.0 / (TWO_GRID_AFTER + TWO_GRID_REMAINING / 2)  # about 500
    assert run(slow) == (True, TWO_GRID_AFTER)
    assert run(slow, noise=0.3) == (True, TWO_GRID_AFTER)  # (means over 10 steps: a noisy residual too)
    assert run(fast) == (False, 4 * TWO_GRID_AFTER)
    assert run(0.0) == (True, TWO_GRID_AFTER)  # stagnating
    assert run(-0.001) == (True, TWO_GRID_AFTER)  # growing
    assert run(slow, remaining=4 * TWO_GRID_REMAINING) == (False, 4 * TWO_GRID_AFTER)  # (a dearer coarse space)


def test_switch_check_asks_whether_the_cycle_is_cheaper_only_between_the_prices():
    """With ``cheaper`` (where the lines' cycle takes its line step): Gauss–Seidel that needs between
    LINE_STEP_PRICE · remaining and remaining more steps switches where ``cheaper()`` says so, and ``cheaper`` is
    not asked where the full price decides alone (many more steps, or fewer than the lower price)."""
    from quadnodes.fairing import LINE_STEP_PRICE, TWO_GRID_AFTER, TWO_GRID_REMAINING, _SwitchCheck

    def run(still: float, answer: bool) -> tuple[bool, int, int]:
        asked = []
        check = _SwitchCheck(1e-10, TWO_GRID_REMAINING, cheaper=lambda: asked.append(1) or answer)
        rate = 23.0 / (TWO_GRID_AFTER + still)  # (about `still` steps to go at the first check)
        for step in range(1, 4 * TWO_GRID_AFTER + 1):
            if check(step, np.exp(-rate * step)):
                break
        return check.switch, step, len(asked)

    between = 0.5 * (1.0 + LINE_STEP_PRICE) * TWO_GRID_REMAINING
    assert run(between, True) == (True, TWO_GRID_AFTER, 1)
    assert run(between, False)[::2] == (False, 1)  # (asked at the first check; by the next, nearly done)
    assert run(2 * TWO_GRID_REMAINING, True) == (True, TWO_GRID_AFTER, 0)  # (the full price decides)
    assert run(0.5 * LINE_STEP_PRICE * TWO_GRID_REMAINING, True)[::2] == (False, 0)  # (nearly done: not asked)


def test_line_prolongation_keeps_every_third_line_up_to_its_size(monkeypatch):
    """On a mesh that is no grid the two-grid coarse space keeps every TWO_GRID_LINE_STRIDE-th structure line up
    to TWO_GRID_LINE_STRIDE_MAX unknowns and every TWO_GRID_STRIDE-th above: the unknowns' rows of
    line_interpolation at that stride."""
    import quadnodes.fairing as fairing_module
    from quadnodes.linalg.multigrid import TWO_GRID_STRIDE, line_interpolation

    m = l_shape_with_hole(60)
    lines, free = m.topology.structure_lines, m.topology.window_middle
    s = FairingSystem(m.vertices, m.topology.windows, free, 1e-6 / m.mean_edge_length**2, solver="cg",
                      _lines=lines)
    coarse = {}
    for stride in (fairing_module.TWO_GRID_LINE_STRIDE, TWO_GRID_STRIDE):
        P = line_interpolation(lines.indices, lines.offsets, lines.closed, m.n_vertices, stride=stride)[0]
        P = P[s.free_index]
        coarse[stride] = P[:, np.flatnonzero(P.getnnz(axis=0))]
    assert fairing_module.TWO_GRID_LINE_STRIDE == 3 and s.n_free <= fairing_module.TWO_GRID_LINE_STRIDE_MAX
    assert (s._line_prolongation() != coarse[3]).nnz == 0
    monkeypatch.setattr(fairing_module, "TWO_GRID_LINE_STRIDE_MAX", s.n_free)  # (up to and with)
    assert (s._line_prolongation() != coarse[3]).nnz == 0
    monkeypatch.setattr(fairing_module, "TWO_GRID_LINE_STRIDE_MAX", s.n_free - 1)
    assert (s._line_prolongation() != coarse[TWO_GRID_STRIDE]).nnz == 0
    small, large = coarse[TWO_GRID_STRIDE].shape[1], coarse[3].shape[1]
    assert large > small
    # every 3rd line over the cap, every 4th within: every 4th; both over: refused (and "auto" keeps Gauss–Seidel)
    monkeypatch.setattr(fairing_module, "TWO_GRID_LINE_STRIDE_MAX", s.n_free)
    monkeypatch.setattr(fairing_module, "TWO_GRID_COARSE_MAX", large - 1)
    assert (s._line_prolongation() != coarse[TWO_GRID_STRIDE]).nnz == 0
    monkeypatch.setattr(fairing_module, "TWO_GRID_COARSE_MAX", small - 1)
    with pytest.raises(InputError, match=f"{small} coarse nodes along the structure lines"):
        s._line_prolongation()


def test_switch_remaining_grows_with_the_coarse_space():
    """A coarse space up to TWO_GRID_REMAINING_COARSE nodes is worth TWO_GRID_REMAINING Gauss–Seidel steps; a
    larger one more, with the square root of its size (its factor fills more per node)."""
    from quadnodes.fairing import TWO_GRID_REMAINING, TWO_GRID_REMAINING_COARSE, _switch_remaining

    assert _switch_remaining(1) == _switch_remaining(TWO_GRID_REMAINING_COARSE) == TWO_GRID_REMAINING
    assert _switch_remaining(4 * TWO_GRID_REMAINING_COARSE) == pytest.approx(2 * TWO_GRID_REMAINING)


def test_switch_remaining_on_the_lines_stops_growing():
    """On the structure lines the price grows as on a grid up to TWO_GRID_LINE_REMAINING_COARSE coarse nodes, then
    stays (their compressed-row Gauss–Seidel steps cost more next to the cycle)."""
    from quadnodes.fairing import TWO_GRID_LINE_REMAINING_COARSE as cap
    from quadnodes.fairing import _switch_remaining

    assert _switch_remaining(1_000, lines=True) == _switch_remaining(1_000)
    assert _switch_remaining(cap, lines=True) == _switch_remaining(cap)
    assert _switch_remaining(5 * cap, lines=True) == _switch_remaining(cap) < _switch_remaining(5 * cap)


def test_the_switch_is_priced_on_the_lines_as_lines_and_on_a_grid_as_a_grid(monkeypatch):
    """Where "auto" may switch, Gauss–Seidel's monitor asks _switch_remaining for the price of the coarse space it
    would switch to: with lines=True for the structure lines' cycle (a holed L-shape), lines=False for a grid's."""
    import quadnodes.fairing as fairing_module

    asked = []
    priced = fairing_module._switch_remaining
    monkeypatch.setattr(fairing_module, "_switch_remaining",
                        lambda coarse, lines=False: asked.append((coarse, lines)) or priced(coarse, lines))
    rng = np.random.default_rng(3)
    for m, kw in ((l_shape_with_hole(50), "_lines"), (grid(48, 41, spacing=0.5), "_topology")):
        m = m.with_vertices(m.vertices + rng.normal(scale=0.2 * m.mean_edge_length, size=m.vertices.shape))
        free = m.topology.window_middle & ~m.topology.boundary_vertices
        extra = {"_lines": m.topology.structure_lines} if kw == "_lines" else {"_topology": m.topology}
        s = FairingSystem(m.vertices, m.topology.windows, free, 1e-6 / m.mean_edge_length**2, solver="cg", **extra)
        s.solve(m.vertices[free])
        assert asked and asked[-1] == (s._coarse, kw == "_lines"), asked
        asked.clear()


def test_gauss_seidel_at_tiny_weights_keeps_to_the_direct_solve(monkeypatch):
    """At tiny weights a residual within rtol leaves smooth error far beyond it: the error guard (‖r‖₂ ≤ 1e-8 ·
    extent · ω · √k) keeps it (the 120² bench sheet, ω = 1e-6: 2.0e-7 of the extent without, within 1e-8 with it),
    and a run that hits the cap falls back to the direct solve with a warning, never returns the capped iterate."""
    import quadnodes.fairing as fairing_module
    from quadnodes.fairing import even_lengths
    from quadnodes.zigzag import _window_geometry

    rng = np.random.default_rng(0)  # (the bench sheet of benchmarks/_common.py, broadband noise)
    y, x = np.meshgrid(np.linspace(0, 1, 120), np.linspace(0, 1, 120), indexing="ij")
    m = grid(120, 120, spacing=1.0 / 119, height=0.3 * np.sin(3 * x) * np.cos(2 * y))
    m = m.with_vertices(m.vertices + rng.normal(scale=0.2 / 119, size=m.vertices.shape))
    free = detect(m, 0.0).free  # (fair()'s all-free set at deviation 0)
    w = 1e-6 / m.mean_edge_length**2
    t = m.topology  # fair()'s default line_spacing="fair": the windows' even lengths
    even = {"_inverse_lengths": even_lengths(_window_geometry(m.vertices, t.windows, t.window_walk)[1])}

    def system(**kw) -> FairingSystem:
        return FairingSystem(m.vertices, t.windows, free, w, **(kw or {"solver": "cg", "preconditioner": "gauss-seidel",
                                                                      "_topology": t}), **even)

    direct = system(solver="direct").solve(m.vertices[free])
    s = system()
    x = s.solve(m.vertices[free])
    assert s.iterations > 0 and np.abs(x - direct).max() <= 1e-8 * np.ptp(m.vertices, axis=0).max()
    monkeypatch.setattr(fairing_module, "MAX_CG_ITERATIONS", 200)
    s = system()
    with pytest.warns(UserWarning, match=r"after 200 iterations \(the cap: 200\); falling back to the direct"):
        x = s.solve(m.vertices[free])
    assert s.iterations == 0 and np.abs(x - direct).max() <= 1e-10 * np.ptp(m.vertices, axis=0).max()


def test_two_grid_with_a_held_patch_holding_one_free_vertex():
    """A 29 × 29 held patch with one free vertex in it: several coarse nodes see only that vertex, so the coarse
    matrix is only semidefinite. The cycle is made definite (1e-10 of its diagonal), "auto" switches to it and
    "two-grid" takes it, both within 1e-8 of the extent of the direct solve (this raised "not positive definite")."""
    from quadnodes.linalg.multigrid import TwoGrid

    rng = np.random.default_rng(0)
    m = grid(120, 120, spacing=1.0)
    m = m.with_vertices(m.vertices + rng.normal(scale=0.2, size=m.vertices.shape))
    keep = np.ones((120, 120), bool)
    keep[46:75, 46:75] = False
    keep[61, 61] = True
    free = m.topology.window_middle & keep.ravel()
    d = FairingSystem(m.vertices, m.topology.windows, free, 1e-6, solver="direct").solve(m.vertices[free])
    for kind in ("auto", "two-grid"):
        s = FairingSystem(m.vertices, m.topology.windows, free, 1e-6, solver="cg", preconditioner=kind,
                          _topology=m.topology)
        x = s.solve(m.vertices[free])
        assert isinstance(s._cg[1], TwoGrid), kind
        assert np.abs(x - d).max() <= 1e-8 * np.ptp(m.vertices, axis=0).max(), kind
