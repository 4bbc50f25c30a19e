"""The panels' OCCT topology written as BRep text and read by BRepTools (quadnodes.io._brep).

Checked with OCCT's own analysers, not with the module's code: BRepCheck_Analyzer on the whole shape,
TopExp's edge -> face map for the sharing, BRep_Tool for every vertex's point and tolerance.
"""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from quadnodes.flatness import diagonal_distance, planar_panels
from quadnodes.io import step as step_mod
from quadnodes.mesh import QuadMesh, cylinder, grid
from meshes import extraordinary_mesh


def _built(mesh, mode, tol=1e-3):
    built, report = step_mod._build(mesh, mode=mode, planar_tolerance=tol, colors=False, name="panels",
                                    check=False, renamed={}, where="test")
    return built, report


def _vertices(shape):
    """(points, tolerances) of the distinct vertices of an OCP shape."""
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_VERTEX
    from OCP.TopExp import TopExp
    from OCP.TopoDS import TopoDS
    from OCP.collections import IndexedMap_TopoDS_Shape_TopTools_ShapeMapHasher as ShapeMap

    vmap = ShapeMap()
    TopExp.MapShapes_s(shape, TopAbs_VERTEX, vmap)
    pts, tols = [], []
    for i in range(1, vmap.Extent() + 1):
        v = TopoDS.Vertex(vmap.FindKey(i))
        p = BRep_Tool.Pnt_s(v)
        pts.append((p.X(), p.Y(), p.Z()))
        tols.append(BRep_Tool.Tolerance_s(v))
    return np.array(pts), np.array(tols)


def _faces_per_edge(shape):
    from OCP.collections import IndexedDataMap_TopoDS_Shape_List_TopoDS_Shape_TopTools_ShapeMapHasher as EMap
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE
    from OCP.TopExp import TopExp

    emap = EMap()
    TopExp.MapShapesAndAncestors_s(shape, TopAbs_EDGE, TopAbs_FACE, emap)
    return np.array([emap.FindFromIndex(i).Size() for i in range(1, emap.Extent() + 1)])


def _is_valid(shape):
    from OCP.BRepCheck import BRepCheck_Analyzer

    return BRepCheck_Analyzer(shape).IsValid()


def _face_corners(face):
    return sorted(tuple(np.round(p, 9)) for p in _vertices(face)[0].tolist())


@settings(max_examples=25, deadline=None)
@given(st.integers(2, 6), st.integers(2, 6), st.floats(0, 4), st.floats(-12, -1), st.integers(0, 2**31 - 1),
       st.sampled_from([1e-3, 1e-6, 0.0, "2 mm", "0.001 mm"]))
def test_shell_shares_the_mesh_vertices_and_edges_and_is_valid(rows, cols, log_spacing, log_np, seed, tol):
    # spacing 1 mm … 10 m, panels out of plane by about 1e-12 … 1e-1 of their size, any tolerance
    rng = np.random.default_rng(seed)
    spacing = 10.0**log_spacing
    m = grid(rows, cols, spacing=spacing, height=rng.normal(0, spacing * 10.0**log_np, (rows, cols)))
    built, report = _built(m, "shell", tol)
    shape = built.shape.wrapped
    assert _is_valid(shape)
    pts, tols = _vertices(shape)
    # one vertex per mesh vertex, at the mesh vertex itself
    assert len(pts) == m.n_vertices
    np.testing.assert_array_equal(np.unique(pts, axis=0), np.unique(m.vertices, axis=0))
    # one edge per mesh edge; interior edges shared by exactly two panels
    per_edge = _faces_per_edge(shape)
    assert len(per_edge) == len(m.topology.edges)
    assert sorted(per_edge.tolist()) == sorted(m.topology.edge_face_count.tolist())
    # tolerances: the planar panels' real deviation (half their diagonal distance), nothing more
    assert tols.max() <= 1.01 * report.max_corner_move + 2e-7
    assert report.n_planar == int(planar_panels(m, tol).sum())
    # every face in panel order is bounded by its own panel's corners
    for k, face in enumerate(built.faces):
        assert _face_corners(face) == sorted(tuple(np.round(p, 9)) for p in m.vertices[m.faces[k]].tolist())


@pytest.mark.parametrize("mesh", [extraordinary_mesh(levels=1), cylinder(3, 8)], ids=["extraordinary", "cylinder"])
def test_shell_of_irregular_and_closed_meshes(mesh):
    built, report = _built(mesh, "shell")
    assert _is_valid(built.shape.wrapped)
    per_edge = _faces_per_edge(built.shape.wrapped)
    assert sorted(per_edge.tolist()) == sorted(mesh.topology.edge_face_count.tolist())
    assert (report.n_shared_edges, report.n_free_edges) == (int((per_edge == 2).sum()), int((per_edge == 1).sum()))


def test_compound_faces_are_free_and_planar_corners_lie_on_their_plane():
    i, j = np.indices((4, 5))
    m = grid(4, 5, spacing=1000.0, height=0.3 * (-1.0) ** (i + j) + 50.0 * (j >= 3) * i * j)
    built, report = _built(m, "compound")
    shape = built.shape.wrapped
    assert _is_valid(shape)
    assert len(_faces_per_edge(shape)) == 4 * m.n_faces and (_faces_per_edge(shape) == 1).all()
    pts, tols = _vertices(shape)
    assert len(pts) == 4 * m.n_faces and tols.max() <= 2e-7  # corners on the plane: nothing to tolerate
    planar = planar_panels(m, 1e-3)
    assert 0 < planar.sum() < m.n_faces
    gap = diagonal_distance(m, relative=False)
    for k, face in enumerate(built.faces):
        corners = _vertices(face)[0]
        exact = m.vertices[m.faces[k]]
        moved = np.linalg.norm(corners[:, None] - exact[None], axis=2).min(axis=1)
        expected = 0.5 * gap[k] if planar[k] else 0.0
        np.testing.assert_allclose(moved, expected, atol=1e-9)


def test_a_closed_mesh_gives_a_closed_shell(tmp_path):
    from quadnodes.mesh import torus

    m = torus(6, 8)
    built, report = _built(m, "shell")
    assert built.shape.wrapped.Closed() and _is_valid(built.shape.wrapped)
    assert report.n_free_edges == 0 and report.n_shared_edges == len(m.topology.edges)
    text = step_mod.save_step(m, tmp_path / "t.step", mode="shell").read_text()
    assert "CLOSED_SHELL" in text and "OPEN_SHELL" not in text
    open_text = step_mod.save_step(grid(3, 3), tmp_path / "g.step", mode="shell").read_text()
    assert "OPEN_SHELL" in open_text and "CLOSED_SHELL" not in open_text
