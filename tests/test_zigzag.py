import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from quadnodes.errors import InputError
from quadnodes.mesh import grid
from quadnodes.noise import perturb
from quadnodes.zigzag import detect, vertex_deviation, window_deviation
from strategies import meshes


def _reference_deviation(v, w):
    out = []
    for p0, p1, p2, p3 in v[w]:
        u = [(b - a) / np.linalg.norm(b - a) for a, b in ((p0, p1), (p1, p2), (p2, p3))]
        r = 0.5 * (u[0] + u[2]) - u[1]
        out.append(r @ r)
    return np.array(out)


@given(meshes())
def test_window_deviation_matches_eq30(mesh):
    w = mesh.topology.windows
    np.testing.assert_allclose(window_deviation(mesh.vertices, w), _reference_deviation(mesh.vertices, w), atol=1e-14)


@given(meshes())
def test_vertex_deviation_is_max_over_middle_windows(mesh):
    w = mesh.topology.windows
    wd = window_deviation(mesh.vertices, w)
    vd = vertex_deviation(wd, w, mesh.n_vertices)
    for i in range(mesh.n_vertices):
        hit = (w[:, 1] == i) | (w[:, 2] == i)
        assert vd[i] == (wd[hit].max() if hit.any() else 0.0)


def test_straight_lines_have_zero_deviation():
    rep = detect(grid(6, 7, spacing=0.3), 0.0)
    assert rep.window_deviation.max() < 1e-28 and rep.n_free == 0


def test_free_means_strictly_greater():
    m, _ = perturb(grid(8, 8), tangential=0.3, seed=3)
    rep = detect(m, 0.05)
    t = np.sort(rep.vertex_deviation[~rep.fixed])[len(rep.fixed) // 3]
    at = detect(m, float(t))
    assert not at.free[at.vertex_deviation == t].any()
    assert (at.free == ((at.vertex_deviation > t) & ~at.fixed)).all()


def test_corners_user_mask_and_boundary_are_fixed():
    m, _ = perturb(grid(7, 7), tangential=0.4, normal=0.2, seed=0)
    rep = detect(m, 0.0)
    assert rep.fixed[[0, 6, 42, 48]].all() and not rep.free[[0, 6, 42, 48]].any()
    assert rep.free[m.topology.boundary_vertices & ~rep.fixed].any()
    rep_b = detect(m, 0.0, fix="boundary")
    assert not rep_b.free[m.topology.boundary_vertices].any()
    rep_u = detect(m, 0.0, fixed=[24, 25])
    assert not rep_u.free[[24, 25]].any() and rep.free[[24, 25]].all()


def test_bad_threshold():
    with pytest.raises(InputError, match="threshold"):
        detect(grid(4, 4), -0.1)
    with pytest.raises(InputError, match="threshold"):
        detect(grid(4, 4), float("nan"))
    with pytest.raises(InputError, match="fixed: vertex index 99"):
        detect(grid(4, 4), 0.1, fixed=[99])


# --- issue 16: alternating detection ---------------------------------------------------------


def test_alternating_tells_a_zigzag_from_a_steady_bend():
    from quadnodes.zigzag import window_alternation

    t = np.linspace(0, np.pi / 2, 6)
    arc = np.stack([np.cos(t), np.sin(t), 0 * t], axis=1)  # a steady quarter circle: 18° per vertex
    kink = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [2, 1, 0], [2, 2, 0.0]])  # one sharp 90° bend
    zig = np.array([[0, 0, 0], [1, 0.3, 0], [2, 0, 0], [3, 0.3, 0], [4, 0, 0.0]])
    w = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
    assert window_alternation(arc, w).max() == 0 and window_alternation(kink, w).max() == 0
    assert window_deviation(kink, w).max() > 0.1  # eq. 30 takes the bend for a zigzag
    np.testing.assert_allclose(window_alternation(zig, w), window_deviation(zig, w), rtol=1e-12)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), scale=st.sampled_from([1e-3, 1.0, 1e3]))
def test_alternation_is_scale_free_and_bounded(seed, scale):
    from quadnodes.zigzag import window_alternation

    v = np.random.default_rng(seed).normal(size=(4, 3))
    w = np.array([[0, 1, 2, 3]])
    a = window_alternation(v, w)
    np.testing.assert_allclose(window_alternation(scale * v + 5.0, w), a, rtol=1e-9, atol=1e-12)
    assert 0 <= a[0] <= 4 + 1e-12


def test_thesis_detection_is_eq30_and_alternating_leaves_a_bend_alone():
    # a clean grid folded along one row: every column bends once, sharply and steadily
    z = np.zeros((7, 5))
    z[4:] = np.arange(1, 4)[:, None] * 1.0
    m = grid(7, 5, height=z)
    th = detect(m, 0.1, detection="thesis")
    assert th.n_free > 0 and th.detection == "thesis"
    np.testing.assert_array_equal(th.vertex_deviation, vertex_deviation(window_deviation(m.vertices, th.windows), th.windows, m.n_vertices))
    alt = detect(m, 0.1)
    assert alt.n_free == 0 and alt.to_dict()["detection"] == "alternating"
    np.testing.assert_array_equal(alt.vertex_deviation, th.vertex_deviation)  # eq. 30 either way
    assert alt.vertex_alternation.max() <= 0.1 and th.vertex_alternation is None
    noisy, _ = perturb(m, tangential=0.2, seed=2)
    assert detect(noisy, 0.1).n_free > 0.5 * noisy.n_vertices - 2 * (7 + 5)



def _same_bits(a, b):
    return a.shape == b.shape and a.dtype == b.dtype and np.array_equal(a.view(np.int64), b.view(np.int64))


def _both_geometries(vertices, topology, **kw):
    """The window geometry along the walk from NumPy and from the compiled kernel."""
    from quadnodes import zigzag

    args = (vertices, topology.windows, topology.window_walk)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(zigzag._compiled, "ready", lambda: False)
        numpy_path = zigzag._window_geometry(*args, **kw)
        mp.setattr(zigzag._compiled, "ready", lambda: True)
        compiled_path = zigzag._window_geometry(*args, **kw)
    return numpy_path, compiled_path


@settings(max_examples=25, deadline=None)
@given(mesh=meshes(), seed=st.integers(0, 1000), alternation=st.booleans(), even=st.booleans())
def test_compiled_window_geometry_equals_numpy_to_the_bit(mesh, seed, alternation, even):
    # detection and fairing must not depend on whether the kernel was loaded in time
    v = mesh.vertices + np.random.default_rng(seed).normal(scale=0.2 * mesh.mean_edge_length, size=mesh.vertices.shape)
    a, b = _both_geometries(v, mesh.topology, alternation=alternation, even=even)
    assert len(a) == len(b) == 2 + alternation + 2 * even
    assert all(_same_bits(x, y) for x, y in zip(a, b))


@pytest.mark.parametrize("threads", [1, 2])
def test_compiled_window_geometry_on_a_torus_with_degenerate_edges_and_threads(monkeypatch, threads):
    from quadnodes import zigzag
    from quadnodes.mesh import torus

    monkeypatch.setattr(zigzag, "_PARALLEL_MIN_WINDOWS", 7)
    monkeypatch.setattr(zigzag._threads, "thread_count", lambda: threads)
    m = torus(9, 12)
    v = m.vertices + np.random.default_rng(3).normal(scale=0.05, size=m.vertices.shape)
    v[5] = v[6]  # an edge of length 0: inf and NaN where NumPy has them
    v[40, 0] = np.nan
    a, b = _both_geometries(v, m.topology, alternation=True, even=True)
    assert np.isnan(a[0]).any() and np.isinf(a[1]).any() and np.isfinite(a[0]).sum() > len(a[0]) // 2
    assert all(_same_bits(x, y) for x, y in zip(a, b))


@settings(max_examples=25, deadline=None)
@given(mesh=meshes(), seed=st.integers(0, 1000), chunk=st.integers(1, 9), alternation=st.booleans(),
       even=st.booleans())
def test_the_numpy_geometry_in_pieces_equals_one_pass_to_the_bit(mesh, seed, chunk, alternation, even):
    """Long walks go through NumPy in pieces of windows (for the cache); any piece size gives the same bits and
    layouts as one pass — open and closed lines, extraordinary vertices, an edge of length 0."""
    from quadnodes import zigzag

    v = mesh.vertices + np.random.default_rng(seed).normal(scale=0.2 * mesh.mean_edge_length, size=mesh.vertices.shape)
    v[1] = v[0]  # (an edge of length 0 where they are neighbours: inf and NaN as one pass has them)
    args = (v, mesh.topology.windows, mesh.topology.window_walk)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(zigzag._compiled, "ready", lambda: False)
        whole = zigzag._window_geometry(*args, alternation=alternation, even=even)
        mp.setattr(zigzag, "_WALK_CHUNK", chunk)
        pieces = zigzag._window_geometry(*args, alternation=alternation, even=even)
    assert all(_same_bits(x, y) and x.strides == y.strides for x, y in zip(whole, pieces))


def test_the_numpy_geometry_in_pieces_takes_any_order_of_windows(monkeypatch):
    """A walk whose windows do not start in increasing order (no topology makes one): each piece reads the stretch
    its windows reach, so the numbers are those of one pass."""
    from quadnodes import zigzag

    m = grid(6, 9)
    v = m.vertices + np.random.default_rng(4).normal(scale=0.1, size=m.vertices.shape)
    ext, start = m.topology.window_walk
    shuffled = np.random.default_rng(5).permutation(start)
    monkeypatch.setattr(zigzag._compiled, "ready", lambda: False)
    whole = zigzag._window_geometry(v, None, (ext, shuffled), alternation=True, even=True)
    monkeypatch.setattr(zigzag, "_WALK_CHUNK", 3)
    pieces = zigzag._window_geometry(v, None, (ext, shuffled), alternation=True, even=True)
    assert all(_same_bits(x, y) and x.strides == y.strides for x, y in zip(whole, pieces))
