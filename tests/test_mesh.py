import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from quadnodes.errors import InputError
from quadnodes.mesh import QuadMesh, cylinder, from_grid_points, grid, grid_faces, torus


def test_grid_constructor_shapes_and_orientation():
    m = grid(3, 4, spacing=(2.0, 1.0))
    assert m.vertices.shape == (12, 3) and m.faces.shape == (6, 4)
    assert m.grid_shape == (3, 4)
    assert m.vertices[4 * 2 + 3].tolist() == [6.0, 2.0, 0.0]
    p = m.vertices[m.faces]
    normal = np.cross(p[:, 1] - p[:, 0], p[:, 3] - p[:, 0])
    assert (normal[:, 2] > 0).all()  # counter-clockwise seen from +z


def test_arrays_are_readonly_copies():
    v = np.zeros((4, 3)); v[1, 0] = v[2, :2] = v[3, 1] = 1
    f = np.array([[0, 1, 2, 3]])
    m = QuadMesh(v, f)
    v[0, 0] = 99.0
    assert m.vertices[0, 0] == 0.0
    with pytest.raises(ValueError):
        m.vertices[0, 0] = 1.0
    with pytest.raises(ValueError):
        m.faces[0, 0] = 1


def test_with_vertices_shares_topology():
    m = grid(4, 4)
    lines = m.topology.structure_lines
    m2 = m.with_vertices(m.vertices * 2)
    assert m2.topology.structure_lines is lines
    assert m2.grid_shape == (4, 4)
    with pytest.raises(InputError, match="shape"):
        m.with_vertices(np.zeros((3, 3)))


def test_closed_constructors():
    assert cylinder(4, 6).n_faces == 18
    t = torus(5, 7)
    assert t.n_faces == 35 and not t.topology.boundary_vertices.any()
    with pytest.raises(InputError, match="cols"):
        grid_faces(3, 2, wrap_cols=True)


def _square():
    return np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.0]])


@pytest.mark.parametrize(
    "vertices, faces, message",
    [
        ([[0, 0, 0], [1, 0, np.nan], [1, 1, 0], [0, 1, 0]], [[0, 1, 2, 3]], "vertex 1 has a non-finite"),
        (_square(), [[0, 1, 2, 4]], "face 0 refers to vertex 4"),
        (_square(), [[0, 1, 1, 3]], "face 0 repeats a vertex"),
        (_square(), np.zeros((0, 4), int), "empty"),
        (np.zeros((0, 3)), [[0, 1, 2, 3]], "empty"),
        (_square(), [[0, 1, 2]], r"shape \(m, 4\)"),
        (_square()[:, :2], [[0, 1, 2, 3]], r"shape \(n, 3\)"),
        ([[0, 0, 0], [1, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2, 3]], "face 0 has a zero-length edge"),
        (_square(), [[0, 1, 2, 3.5]], "integers"),
    ],
)
def test_validation_errors_name_the_culprit(vertices, faces, message):
    with pytest.raises(InputError, match=message):
        QuadMesh(vertices, faces)


def test_edge_in_three_faces_is_rejected():
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [1, -1, 0], [0, -1, 0], [1, 0, 1], [0, 0, 1.0]])
    faces = [[0, 1, 2, 3], [1, 0, 5, 4], [0, 1, 6, 7]]
    with pytest.raises(InputError, match=r"edge \(0, 1\) is shared by 3 faces \[0, 1, 2\]"):
        QuadMesh(v, faces)


def test_inconsistent_orientation_is_rejected():
    v = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0], [1, 1, 0], [2, 1, 0.0]])
    with pytest.raises(InputError, match="faces 0 and 1 .*same direction"):
        QuadMesh(v, [[0, 1, 4, 3], [1, 4, 5, 2]])


def test_grid_shape_must_match():
    with pytest.raises(InputError, match="grid_shape"):
        QuadMesh(_square(), [[0, 1, 2, 3]], grid_shape=(3, 3))


def test_from_grid_points_checks_shape():
    with pytest.raises(InputError, match="rows, cols, 3"):
        from_grid_points(np.zeros((4, 3)))


def test_grid_shape_faces_must_be_grid_cells():
    f = grid_faces(3, 3)
    QuadMesh(grid(3, 3).vertices, f[:, ::-1], grid_shape=(3, 3))  # any winding is a cell
    flat = grid(2, 3)  # a 2 x 3 grid declared as 3 x 2
    with pytest.raises(InputError, match=r"face 0 \[0, 1, 4, 3\] is not a cell of a 3 x 2"):
        QuadMesh(flat.vertices, flat.faces, grid_shape=(3, 2))


def test_unit_is_carried_and_converted():
    m = grid(3, 3, spacing=1000.0)
    assert m.unit == "mm"
    mm = m.with_vertices(m.vertices + 1.0)
    assert mm.unit == "mm"
    metres = m.with_unit("m")
    assert metres.unit == "m" and np.allclose(metres.vertices, m.vertices / 1000.0)
    assert metres.topology is m.topology or metres.faces is m.faces
    assert m.with_unit("mm") is m and metres.with_unit("m") is metres  # already in that unit: itself
    with pytest.raises(InputError, match="unit: expected one of"):
        m.with_unit("furlong")
    with pytest.raises(InputError, match="unit: expected one of"):
        QuadMesh(m.vertices, m.faces, unit="furlong")


def test_a_duplicate_face_is_named_as_one_not_as_an_orientation_problem():
    # an OBJ listing a panel twice was told "inconsistent orientation; flip one of them", which leaves a
    # two-faced pillow; and a panel repeated inside a mesh was told only "edge shared by 3 faces"
    g = grid(3, 3)
    f = g.faces.tolist()
    for dup in ([1, 2, 5, 4], [2, 5, 4, 1]):  # the same panel, from the same or another corner
        with pytest.raises(InputError, match=r"^faces: faces 1 and 4 are the same panel \(vertices \[1, 2, 5, 4\]"
                                             r"\) listed twice; remove one$"):
            QuadMesh(g.vertices, f + [dup])
    with pytest.raises(InputError, match=r"^faces: faces 3 and 4 are the same panel \(vertices \[4, 5, 8, 7\]\) "
                                         r"listed twice; remove one$"):
        QuadMesh(g.vertices, f + [[7, 8, 5, 4]])  # reversed: the edges are shared by three faces
    with pytest.raises(InputError, match=r"^faces: faces 0 and 1 are the same panel \(vertices \[0, 1, 2, 3\]\) "
                                         r"listed twice; remove one$"):
        QuadMesh(_square(), [[0, 1, 2, 3], [3, 2, 1, 0]])  # a lone panel and its reverse: a closed pillow


@settings(max_examples=30, deadline=None)
@given(st.integers(2, 12), st.integers(2, 12), st.integers(0, 10_000))
def test_a_grids_mean_edge_length_by_index_arithmetic_is_the_edge_lists_to_the_bit(rows, cols, seed):
    """An open grid measures its edges without building the edge list, in the same order: the same float."""
    rng = np.random.default_rng(seed)
    m = grid(rows, cols)
    f = m.faces[rng.permutation(len(m.faces))]
    m = QuadMesh(m.vertices + rng.normal(scale=0.3, size=m.vertices.shape), f)
    assert m.topology.grid_shape == (rows, cols)
    e = m.topology.edges
    d = m.vertices[e[:, 1]] - m.vertices[e[:, 0]]
    assert m.mean_edge_length == float(np.sqrt(np.einsum("ij,ij->i", d, d)).mean())


@pytest.mark.parametrize("offset, words", [(0.0, "zero-length edge between vertices 7 and 12"),
                                           (1e-12, "near-duplicate vertices 7 and 12")])
def test_a_grids_new_positions_are_checked_edge_by_edge_without_the_edge_list_gathers(offset, words):
    m = grid(4, 5)
    assert m.topology.grid_shape == (4, 5)
    v = m.vertices.copy()
    v[12] = v[7] + offset  # (7 and 12: one above the other)
    with pytest.raises(InputError, match=words):
        m.with_vertices(v)
    v = m.vertices.copy()
    v[12, 2] += 0.5
    assert m.with_vertices(v).vertices[12, 2] == 0.5


@pytest.mark.parametrize("make", [lambda: grid(5, 7), lambda: cylinder(4, 9), lambda: torus(5, 6)])
def test_with_vertices_keeps_the_mean_edge_length_it_measured_to_the_bit(make):
    """The edge check measures every edge; the new mesh keeps that mean instead of measuring again."""
    m = make()
    m.topology.edges  # (the topology known: the check measures the edges)
    v = m.vertices + np.random.default_rng(2).normal(scale=0.05, size=m.vertices.shape)
    kept = m.with_vertices(v)
    assert "mean_edge_length" in kept.__dict__
    assert kept.mean_edge_length == QuadMesh(v, m.faces).mean_edge_length
