import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from quadnodes.mesh import QuadMesh, cylinder, grid, grid_faces, torus
from quadnodes.topology import adjacency, corner_vertices, structure_lines, windows
from meshes import extraordinary_mesh, l_shape_with_hole


def _line_edges(lines) -> list[tuple[int, int]]:
    out = []
    for line, closed in zip(lines, lines.closed):
        seq = np.r_[line, line[:1]] if closed else line
        out += [tuple(sorted(map(int, p))) for p in zip(seq[:-1], seq[1:])]
    return out


def _every_edge_once(mesh):
    got = _line_edges(structure_lines(mesh))
    want = [tuple(e) for e in mesh.topology.edges.tolist()]
    assert sorted(got) == sorted(want)


def test_grid_lines_are_rows_and_columns():
    m = grid(4, 6)
    lines = structure_lines(m)
    assert len(lines) == 4 + 6 and not lines.closed.any()
    as_lists = sorted(l.tolist() for l in lines)
    rows = [list(range(i * 6, i * 6 + 6)) for i in range(4)]
    cols = [list(range(j, 24, 6)) for j in range(6)]
    assert as_lists == sorted(rows + cols)
    w = windows(lines)
    assert w.shape == (4 * 3 + 6 * 1, 4)
    _every_edge_once(m)


def test_cylinder_rings_are_closed_and_windows_wrap():
    m = cylinder(4, 7)
    lines = structure_lines(m)
    assert int(lines.closed.sum()) == 4 and len(lines) == 4 + 7
    w, line = windows(lines, return_line=True)
    closed_w = w[lines.closed[line]]
    assert len(closed_w) == 4 * 7
    # every ring vertex is a middle point of two windows of its ring
    assert m.topology.window_middle[:7].all()
    _every_edge_once(m)


def test_torus_all_lines_closed():
    m = torus(5, 8)
    lines = structure_lines(m)
    assert lines.closed.all() and len(lines) == 5 + 8
    assert len(windows(lines)) == 5 * 8 * 2
    assert m.topology.window_middle.all()
    _every_edge_once(m)


def test_extraordinary_vertices_end_lines():
    m = extraordinary_mesh()
    t = m.topology
    ext = np.flatnonzero(t.extraordinary)
    assert sorted(t.valence[ext].tolist()) == [3, 5]
    lines = structure_lines(m)
    for line, closed in zip(lines, lines.closed):
        inner = line if closed else line[1:-1]
        assert not np.isin(inner, ext).any(), "a line passes through an extraordinary vertex"
    # every edge at an extraordinary vertex starts or ends a line there
    ends = np.r_[[l[0] for l in lines], [l[-1] for l in lines]]
    for v in ext:
        assert (ends == v).sum() == t.valence[v]
    assert not t.window_middle[ext].any()
    _every_edge_once(m)


def test_l_shape_with_hole_lines_end_at_corners():
    m = l_shape_with_hole(9)
    t = m.topology
    corners = np.flatnonzero(t.corner_vertices)
    assert len(corners) == 10  # 5 convex + 1 reflex outer corners, 4 hole corners
    counts = np.bincount(t.vertex_face_count[corners])
    assert counts[1] == 5 and counts[3] == 5  # reflex outer corner and 4 hole corners have 3 faces
    lines = structure_lines(m)
    assert not lines.closed.any()
    for line in lines:
        assert not np.isin(line[1:-1], corners).any()
    # the bottom boundary row runs straight through, 9 vertices long
    assert any(l.tolist() == list(range(9)) for l in lines)
    _every_edge_once(m)


def test_corner_vertices_of_grid():
    assert np.flatnonzero(corner_vertices(grid(3, 4))).tolist() == [0, 3, 8, 11]


def test_adjacency_has_no_diagonals():
    a = adjacency(grid(3, 3))
    assert a[4].indices.tolist() == [1, 3, 5, 7]


@given(st.sampled_from(["grid", "cylinder", "torus", "extraordinary", "lhole"]), st.integers(0, 10_000))
def test_lines_do_not_depend_on_face_order(kind, seed):
    m = {"grid": grid(5, 7), "cylinder": cylinder(4, 6), "torus": torus(4, 5),
         "extraordinary": extraordinary_mesh(), "lhole": l_shape_with_hole()}[kind]
    rng = np.random.default_rng(seed)
    f = m.faces[rng.permutation(m.n_faces)]
    shift = rng.integers(0, 4, len(f))
    f = np.take_along_axis(f, (np.arange(4) + shift[:, None]) % 4, axis=1)
    m2 = QuadMesh(m.vertices, f)
    a, b = structure_lines(m), structure_lines(m2)
    assert np.array_equal(a.indices, b.indices) and np.array_equal(a.offsets, b.offsets)
    assert np.array_equal(a.closed, b.closed)


def test_windows_of_short_lines():
    lines = structure_lines(grid(3, 3))
    assert windows(lines).shape == (0, 4)


def test_line_indexing():
    lines = structure_lines(grid(2, 3))
    assert lines[-1].tolist() == [3, 4, 5]
    with pytest.raises(IndexError):
        lines[5]


@given(st.integers(2, 9), st.integers(2, 9), st.integers(0, 10_000), st.booleans())
def test_grid_fast_path_equals_tracing(rows, cols, seed, reverse):
    """A complete vertex grid skips the tracing; the lines are exactly the traced ones,
    whatever the faces' order, starting corner and orientation."""
    from quadnodes.topology import Topology, _trace_lines, _window_walk

    rng = np.random.default_rng(seed)
    f = grid(rows, cols).faces[rng.permutation((rows - 1) * (cols - 1))]
    f = np.take_along_axis(f, (np.arange(4) + rng.integers(0, 4, len(f))[:, None]) % 4, axis=1)
    if reverse:
        f = f[:, ::-1]
    topo = Topology.from_faces(f, rows * cols)
    assert topo.grid_shape == (rows, cols)
    fast, traced = topo.structure_lines, _trace_lines(topo.edges, topo._successor)
    assert np.array_equal(fast.indices, traced.indices) and np.array_equal(fast.offsets, traced.offsets)
    assert not fast.closed.any() and not traced.closed.any()
    ext, start, _ = _window_walk(traced)  # and its walk by index arithmetic, the traced lines' walk
    assert all(np.array_equal(a, b) for a, b in zip(topo.window_walk, (ext, start)))


@given(st.integers(3, 10), st.integers(3, 10), st.sampled_from(["cylinder", "torus", "rings"]),
       st.integers(0, 10_000), st.booleans(), st.booleans())
def test_closed_grid_fast_path_equals_tracing(rows, cols, kind, seed, shuffle, reverse):
    """A cylinder or torus grid of at least 4 × 4 skips the tracing too; its lines are exactly the traced ones,
    whatever the faces' order, starting vertex and orientation; smaller ones are traced."""
    from quadnodes.topology import Topology, _trace_lines, _window_walk

    wrap_rows, wrap_cols = {"cylinder": (False, True), "torus": (True, True), "rings": (True, False)}[kind]
    rng = np.random.default_rng(seed)
    f = grid_faces(rows, cols, wrap_rows=wrap_rows, wrap_cols=wrap_cols)
    if shuffle:
        f = f[rng.permutation(len(f))]
        f = np.take_along_axis(f, (np.arange(4) + rng.integers(0, 4, len(f))[:, None]) % 4, axis=1)
    if reverse:
        f = f[:, ::-1]
    topo = Topology.from_faces(np.ascontiguousarray(f), rows * cols)
    assert topo.closed_grid == (rows, cols, wrap_rows, wrap_cols)
    fast, traced = topo.structure_lines, _trace_lines(topo.edges, topo._successor)
    assert np.array_equal(fast.indices, traced.indices) and np.array_equal(fast.offsets, traced.offsets)
    assert np.array_equal(fast.closed, traced.closed)
    assert int(fast.closed.sum()) == rows * wrap_cols + cols * wrap_rows
    # its windows, window walk and window middles by index arithmetic too: those of the traced lines
    ext, start, _ = _window_walk(traced)
    assert np.array_equal(topo.windows, ext[start[:, None] + np.arange(4)])
    fast_ext, fast_start = topo.window_walk
    assert np.array_equal(fast_ext, ext) and np.array_equal(fast_start, start)
    middle = np.zeros(rows * cols, bool)
    middle[ext[start[:, None] + np.arange(1, 3)].reshape(-1)] = True
    assert np.array_equal(topo.window_middle, middle)


def test_closed_grid_refuses_a_cell_twice_and_a_missing_cell():
    from quadnodes.topology import _closed_grid

    f = grid_faces(5, 6, wrap_rows=True, wrap_cols=True)
    assert _closed_grid(f, 30) == (5, 6, True, True)
    twice = f.copy()
    twice[7] = f[8]
    assert _closed_grid(twice, 30) is None
    assert _closed_grid(f[:-1], 30) is None


@given(st.integers(2, 9), st.integers(2, 9), st.integers(0, 10_000))
def test_grid_boundary_and_corners_by_index_arithmetic_equal_the_edge_counts(rows, cols, seed):
    """A complete vertex grid's boundary ring, boundary-edge counts, corners, valences and face counts come
    from index arithmetic; they equal what the edges and faces give (faces in any order and orientation)."""
    from quadnodes.topology import Topology

    rng = np.random.default_rng(seed)
    f = grid(rows, cols).faces[rng.permutation((rows - 1) * (cols - 1))]
    f = np.take_along_axis(f, (np.arange(4) + rng.integers(0, 4, len(f))[:, None]) % 4, axis=1)
    topo = Topology.from_faces(f, rows * cols)
    assert topo.grid_shape == (rows, cols)
    n = rows * cols
    ends = topo.edges[topo.boundary_edges].reshape(-1)
    count = np.bincount(ends, minlength=n)
    assert np.array_equal(topo._boundary_count, count)
    assert np.array_equal(topo.boundary_vertices, count > 0)
    assert np.array_equal(topo.corner_vertices, (count > 0) & ~topo.regular_boundary)
    assert np.array_equal(corner_vertices(QuadMesh(grid(rows, cols).vertices, f)), topo.corner_vertices)
    und = topo._undirected  # the edges as the faces give them
    assert np.array_equal(topo.edges, np.stack([np.repeat(np.arange(n), np.diff(und.indptr)), und.indices], axis=1))
    assert np.array_equal(topo.valence, np.bincount(topo.edges.reshape(-1), minlength=n))
    assert np.array_equal(topo.vertex_face_count, np.bincount(f.reshape(-1), minlength=n))
    assert not topo.extraordinary.any() and topo.regular_interior.sum() == (rows - 2) * (cols - 2)


@pytest.mark.parametrize("kind", ["missing cell", "cylinder", "extraordinary", "lhole", "transposed numbering"])
def test_grid_shape_only_for_complete_grids(kind):
    if kind == "missing cell":
        m = QuadMesh(grid(4, 5).vertices, grid(4, 5).faces[1:])
    elif kind == "transposed numbering":  # vertex j*rows + i: a grid, but not in row-major layout
        g = grid(4, 5)
        r, c = np.divmod(g.faces, 5)
        v = np.empty_like(g.vertices)
        v[(np.arange(20) % 5) * 4 + np.arange(20) // 5] = g.vertices  # the same points, renumbered
        m = QuadMesh(v, c * 4 + r)
    else:
        m = {"cylinder": cylinder(4, 6), "extraordinary": extraordinary_mesh(), "lhole": l_shape_with_hole()}[kind]
    if kind == "transposed numbering":
        assert m.topology.grid_shape == (5, 4)  # read as a 5 × 4 grid: still a complete grid
    else:
        assert m.topology.grid_shape is None
    _every_edge_once(m)


@pytest.mark.parametrize("kind", ["grid", "cylinder", "torus", "extraordinary", "lhole", "thin torus"])
def test_window_walk_spells_the_windows(kind):
    m = {"grid": grid(5, 7), "cylinder": cylinder(4, 6), "torus": torus(4, 5), "thin torus": torus(3, 3),
         "extraordinary": extraordinary_mesh(), "lhole": l_shape_with_hole()}[kind]
    topo = m.topology
    ext, start = topo.window_walk
    assert np.array_equal(topo.windows, windows(topo.structure_lines))
    assert np.array_equal(ext[start[:, None] + np.arange(4)], windows(topo.structure_lines))


# --- issue 16: grids from connectivity, corners by turning ------------------------------------


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), rows=st.integers(2, 7), cols=st.integers(2, 7))
def test_as_grid_recognizes_any_numbering(seed, rows, cols):
    from quadnodes.mesh import QuadMesh
    from quadnodes.topology import as_grid

    g = grid(rows, cols, height=np.random.default_rng(seed).normal(size=(rows, cols)))
    rng = np.random.default_rng(seed)
    p = rng.permutation(g.n_vertices)
    inv = np.argsort(p)
    faces = inv[g.faces][rng.permutation(g.n_faces)]
    faces = np.array([np.roll(f, int(k)) for f, k in zip(faces, rng.integers(0, 4, len(faces)))])
    shuffled = QuadMesh(g.vertices[p], faces, unit="m")
    out = as_grid(shuffled)
    assert out is not None and sorted(out.grid_shape) == sorted((rows, cols)) and out.unit == "m"
    r, c = out.grid_shape
    ids = np.arange(r * c).reshape(r, c)
    # the renumbered vertices are the same points, and grid neighbours are mesh neighbours
    np.testing.assert_array_equal(np.sort(out.vertices, axis=0), np.sort(g.vertices, axis=0))
    e = {tuple(x) for x in out.topology.edges.tolist()}
    assert {(int(a), int(b)) for a, b in zip(ids[:, :-1].ravel(), ids[:, 1:].ravel())} <= e
    assert {(int(a), int(b)) for a, b in zip(ids[:-1].ravel(), ids[1:].ravel())} <= e
    assert out.topology.grid_shape == out.grid_shape


def test_as_grid_refuses_what_is_not_a_grid():
    from quadnodes.mesh import cylinder
    from quadnodes.topology import as_grid
    from meshes import extraordinary_mesh, l_shape_with_hole

    assert as_grid(extraordinary_mesh()) is None
    assert as_grid(l_shape_with_hole()) is None
    assert as_grid(cylinder(4, 6)).grid_wrap == (False, True)  # closed lines: a cylinder grid (item 5)
    g = grid(3, 4)
    assert as_grid(g) is g


def test_staircase_steps_are_not_corners_but_sides_ends_are():
    from quadnodes.mesh import QuadMesh

    # cells (i, j) with i + j <= 3 of a 5 x 5 vertex grid: a staircase hypotenuse
    n = 5
    cells = [(i, j) for i in range(n - 1) for j in range(n - 1) if i + j <= 3]
    f = np.array([[i * n + j, i * n + j + 1, (i + 1) * n + j + 1, (i + 1) * n + j] for i, j in cells])
    used = np.unique(f)
    remap = np.full(n * n, -1)
    remap[used] = np.arange(used.size)
    y, x = np.divmod(used, n)
    m = QuadMesh(np.stack([x, y, 0 * x], axis=1).astype(float), remap[f])
    by_valence = np.flatnonzero(m.topology.corner_vertices)
    by_turn = np.flatnonzero(corner_vertices(m))
    assert len(by_valence) == 10  # the three triangle corners and the 7 step vertices
    pos = m.vertices[by_turn, :2].tolist()
    assert sorted(map(tuple, pos)) == [(0.0, 0.0), (0.0, 4.0), (1.0, 4.0), (4.0, 0.0), (4.0, 1.0)]


# --- issue 16 item 5: cylinder and torus grids from connectivity alone ---------------------------


def _shuffled(m, rng, *, flip=False):
    """``m`` with its vertices renumbered, its faces listed in another order, each starting elsewhere."""
    p = rng.permutation(m.n_vertices)
    inv = np.argsort(p)
    faces = inv[m.faces][rng.permutation(m.n_faces)]
    faces = np.array([np.roll(f, int(k)) for f, k in zip(faces, rng.integers(0, 4, len(faces)))])
    if flip:
        faces = faces[:, ::-1]
    return QuadMesh(m.vertices[p], faces, unit="m"), p


def _line_set(lines, closed, relabel=None):
    """Lines as comparable tuples: closed ones from their smallest vertex towards the smaller neighbour,
    open ones from their smaller end."""
    out = set()
    for line, c in zip(lines, closed):
        line = np.asarray(line) if relabel is None else relabel[np.asarray(line)]
        if c:
            line = np.roll(line, -int(np.argmin(line)))
            if line.size > 2 and line[-1] < line[1]:
                line = np.r_[line[:1], line[:0:-1]]
        elif line[-1] < line[0]:
            line = line[::-1]
        out.add((bool(c), tuple(int(v) for v in line)))
    return out


def _grid_rows_cols(r, c, wrap_rows, wrap_cols):
    ids = np.arange(r * c).reshape(r, c)
    return [(wrap_cols, list(x)) for x in ids] + [(wrap_rows, list(x)) for x in ids.T]


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), rows=st.integers(2, 7), cols=st.integers(3, 8),
       kind=st.sampled_from(["cylinder", "torus"]), flip=st.booleans())
def test_as_grid_recognizes_cylinders_and_tori_in_any_numbering(seed, rows, cols, kind, flip):
    from quadnodes.io.panels import panel_labels
    from quadnodes.topology import as_grid

    rows = max(rows, 3) if kind == "torus" else rows
    base = cylinder(rows, cols) if kind == "cylinder" else torus(rows, cols)
    rng = np.random.default_rng(seed)
    base = base.with_vertices(base.vertices + rng.normal(scale=0.01, size=base.vertices.shape))
    shuffled, p = _shuffled(base, rng, flip=flip)
    out = as_grid(shuffled)
    assert out is not None and out.unit == "m"
    r, c = out.grid_shape
    if kind == "cylinder":  # the rows are the rings: the shape is never transposed
        assert (r, c) == (rows, cols) and out.grid_wrap == (False, True)
    else:  # either family may be the rows on a torus
        assert sorted((r, c)) == sorted((rows, cols)) and out.grid_wrap == (True, True)
    # the same points, and the faces are exactly the grid's cells (closed as the grid closes)
    np.testing.assert_array_equal(np.sort(out.vertices, axis=0), np.sort(base.vertices, axis=0))
    want = grid_faces(r, c, wrap_rows=out.grid_wrap[0], wrap_cols=out.grid_wrap[1])
    assert {frozenset(f) for f in out.faces.tolist()} == {frozenset(f) for f in want.tolist()}
    # rows and columns are the lines the tracer finds in the shuffled mesh, numbered as in the output
    relabel = np.empty(out.n_vertices, dtype=np.int64)
    pos = {tuple(v): k for k, v in enumerate(out.vertices.tolist())}
    relabel[:] = [pos[tuple(v)] for v in shuffled.vertices.tolist()]
    traced = structure_lines(shuffled)
    grid_lines = _grid_rows_cols(r, c, *out.grid_wrap)
    assert _line_set(traced, traced.closed, relabel) == _line_set([g for _, g in grid_lines],
                                                                     [w for w, _ in grid_lines])
    # deterministic: the same input gives the same numbering; the labels are every cell once
    again = as_grid(QuadMesh(shuffled.vertices, shuffled.faces))
    np.testing.assert_array_equal(again.faces, out.faces)
    labels = panel_labels(out)
    assert len(set(labels)) == out.n_faces and all(lab.startswith("P_") and lab.count("_") == 2 for lab in labels)
    # the seam: row 0 starts at the smallest vertex of its loop (cylinder: boundary loop), orientation kept
    first = shuffled.topology.boundary_vertices if kind == "cylinder" else np.ones(out.n_vertices, bool)
    assert relabel[int(np.flatnonzero(first)[0])] == 0
    n0 = shuffled.faces[0]
    assert any(np.array_equal(np.roll(relabel[n0], k), f) for f in out.faces.tolist() for k in range(4))


def test_as_grid_keeps_a_numbered_cylinder_and_torus():
    from quadnodes.topology import as_grid

    for m, shape in ((cylinder(4, 6), (4, 6)), (cylinder(2, 3), (2, 3)), (torus(3, 3), (3, 3)), (torus(5, 8), (5, 8))):
        out = as_grid(m)
        assert out is not None and out.grid_shape == shape and out.n_faces == m.n_faces
        np.testing.assert_array_equal(out.vertices, m.vertices)  # already row by row: the same numbering


def test_as_grid_refuses_a_torus_glued_with_a_shift():
    from quadnodes.topology import as_grid

    # a 4 x 6 torus whose last row is glued to row 0 shifted by one column: the columns are helices
    r, c, s = 4, 6, 1
    f = grid_faces(r, c, wrap_cols=True).tolist()
    f += [[(r - 1) * c + j, (r - 1) * c + (j + 1) % c, (j + 1 + s) % c, (j + s) % c] for j in range(c)]
    t = torus(r, c)
    m = QuadMesh(t.vertices, np.array(f))
    assert m.topology.valence.min() == 4 and as_grid(m) is None


def test_grid_shape_accepts_closed_grids_and_labels_the_seam():
    from quadnodes.errors import InputError
    from quadnodes.io.panels import panel_rows_cols

    m = QuadMesh(cylinder(3, 4).vertices, grid_faces(3, 4, wrap_cols=True), grid_shape=(3, 4))
    assert m.grid_wrap == (False, True) and m.topology.grid_shape is None  # the solver's open-grid path: not taken
    r, c = panel_rows_cols(m)
    assert sorted(zip(r.tolist(), c.tolist())) == [(i, j) for i in range(2) for j in range(4)]
    assert m.with_vertices(m.vertices * 2).grid_wrap == (False, True)
    with pytest.raises(InputError, match="not a cell"):
        QuadMesh(cylinder(3, 4).vertices, grid_faces(3, 4, wrap_cols=True), grid_shape=(4, 3))


def test_fixed_vertices_holds_a_vertex_in_no_face():
    # an OBJ with an unreferenced vertex (or read with non_quads="drop") keeps it; no energy acts on it, so
    # every method must hold it rather than divide by its zero edge length or find it "unanchored"
    from quadnodes.topology import fixed_vertices

    g = grid(3, 3)
    m = QuadMesh(np.vstack([g.vertices, [[9.0, 9.0, 9.0]]]), g.faces)
    for fix, want in [("none", [9]), ("corners", [0, 2, 6, 8, 9]), ("boundary", [0, 1, 2, 3, 5, 6, 7, 8, 9])]:
        assert np.flatnonzero(fixed_vertices(m, fix)).tolist() == want
    assert np.flatnonzero(fixed_vertices(g, "none")).tolist() == []


def _both_tracers(mesh):
    """The lines of ``mesh`` by the compiled tracer and by SciPy's walks (both through ``_canonical``)."""
    from quadnodes.topology import _compiled_trace, _lines_from_edges, _scipy_trace

    topo = mesh.topology
    e, succ = topo.edges, topo._successor
    pred = np.full(succ.size, -1, dtype=np.int64)
    src = np.flatnonzero(succ >= 0)
    pred[succ[src]] = src
    ends = (e.reshape(-1), e[:, ::-1].reshape(-1))
    compiled = _compiled_trace(succ, pred)
    assert compiled is not None
    return _lines_from_edges(*compiled, *ends), _lines_from_edges(*_scipy_trace(succ, pred, src, succ[src]), *ends)


@settings(max_examples=40, deadline=None)
@given(st.sampled_from(["grid", "cylinder", "torus", "extraordinary", "lhole", "cube", "holes"]),
       st.integers(0, 10_000))
def test_compiled_tracer_gives_the_scipy_tracers_lines(kind, seed):
    """Open lines, closed lines, lines ending at extraordinary vertices and at holes, any face order: the
    compiled tracer's lines are SciPy's, vertex for vertex, after the canonical ordering."""
    rng = np.random.default_rng(seed)
    m = {"grid": lambda: grid(int(rng.integers(2, 9)), int(rng.integers(2, 9))),
         "cylinder": lambda: cylinder(int(rng.integers(2, 8)), int(rng.integers(3, 9))),
         "torus": lambda: torus(int(rng.integers(3, 8)), int(rng.integers(3, 9))),
         "extraordinary": extraordinary_mesh, "lhole": l_shape_with_hole,
         "cube": lambda: _cube_sphere(int(rng.integers(1, 6))),  # every line closes, eight valence-3 corners
         "holes": lambda: _grid_with_holes(rng)}[kind]()
    f = m.faces[rng.permutation(m.n_faces)]
    f = np.take_along_axis(f, (np.arange(4) + rng.integers(0, 4, len(f))[:, None]) % 4, axis=1)
    if rng.random() < 0.5:
        f = f[:, ::-1]
    fast, traced = _both_tracers(QuadMesh(m.vertices, np.ascontiguousarray(f)))
    assert np.array_equal(fast.indices, traced.indices) and np.array_equal(fast.offsets, traced.offsets)
    assert np.array_equal(fast.closed, traced.closed)


def test_compiled_tracer_refuses_what_is_not_chains_and_cycles_and_scipy_traces_it():
    from quadnodes.topology import _compiled_trace

    # two edges leading into one (a successor shared), and a walk into a cycle it does not start on
    shared_succ = np.array([4, -1, 4, -1, -1, -1], dtype=np.int64)  # 0 → 4 and 2 → 4
    shared_pred = np.array([-1, -1, -1, -1, 2, -1], dtype=np.int64)
    assert _compiled_trace(shared_succ, shared_pred) is None
    rho_succ = np.array([2, -1, 4, -1, 2, -1], dtype=np.int64)  # 0 → 2 → 4 → 2 …
    rho_pred = np.array([-1, -1, 4, -1, 2, -1], dtype=np.int64)
    assert _compiled_trace(rho_succ, rho_pred) is None


def _cube_sphere(k: int) -> QuadMesh:
    """Six ``k × k`` grids on the faces of a cube, glued along its edges (vertices merged by position)."""
    t = np.linspace(-1.0, 1.0, k + 1)
    pts, faces = [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            a, b = np.meshgrid(t, t, indexing="ij")
            p = np.zeros((k + 1, k + 1, 3))
            p[..., axis] = sign
            p[..., (axis + 1) % 3], p[..., (axis + 2) % 3] = a, b
            base = sum(len(q) for q in pts)
            pts.append(p.reshape(-1, 3))
            g = grid_faces(k + 1, k + 1) + base
            faces.append(g if sign > 0 else g[:, ::-1])
    P = np.concatenate(pts)
    _, first, inverse = np.unique(np.round(P, 9), axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    order = np.argsort(first)
    renumber = np.empty_like(order)
    renumber[order] = np.arange(order.size)
    return QuadMesh(P[first[order]] / np.linalg.norm(P[first[order]], axis=1)[:, None],
                    renumber[inverse][np.concatenate(faces)])


def _grid_with_holes(rng) -> QuadMesh:
    """A grid with a few faces taken out (lines end at the holes' rims) and its unused vertices dropped."""
    rows, cols = int(rng.integers(5, 10)), int(rng.integers(5, 10))
    m = grid(rows, cols)
    keep = np.ones(m.n_faces, bool)
    keep[rng.choice(m.n_faces, size=int(rng.integers(1, 4)), replace=False)] = False
    f = m.faces[keep]
    used = np.unique(f)
    index = np.full(m.n_vertices, -1)
    index[used] = np.arange(used.size)
    return QuadMesh(m.vertices[used], index[f])


def test_a_pillow_vertex_ends_its_lines_instead_of_crashing_the_tracer():
    """Two faces sharing both their edges at a vertex (a "pillow", which QuadMesh accepts): straight through leads
    back along the arriving edge; lines end there, every edge on one line (a reviewer's input crashed SciPy's
    tracer with a negative index)."""
    from quadnodes import fair

    rng = np.random.default_rng(0)
    m = QuadMesh(rng.normal(size=(9, 3)), np.array([[0, 1, 3, 2], [0, 2, 4, 1], [0, 5, 7, 6], [0, 6, 8, 5]]))
    _every_edge_once(m)
    assert not structure_lines(m).closed.any()
    out, report = fair(m)
    assert np.isfinite(out.vertices).all() and report.iterations


@pytest.mark.parametrize("make", [lambda: cylinder(5, 9), lambda: cylinder(2, 3), lambda: torus(6, 7),
                                  lambda: QuadMesh(torus(6, 7).vertices, grid_faces(6, 7, wrap_rows=True))])
def test_a_closed_grid_has_no_corners_without_walking_its_boundary(make, monkeypatch):
    """A cylinder's or torus's corners by its layout (none: its end rings are regular boundary) — what the
    boundary walk gives."""
    from quadnodes.topology import corner_vertices

    m = make()
    assert m.topology.closed_grid is not None
    fast = corner_vertices(m)
    monkeypatch.setattr(type(m.topology), "closed_grid", property(lambda self: None))
    walked = corner_vertices(QuadMesh(m.vertices, m.faces))
    assert not fast.any() and np.array_equal(fast, walked)
