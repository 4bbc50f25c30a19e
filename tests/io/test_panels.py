import numpy as np
import pytest
from hypothesis import given, strategies as st

from quadnodes.errors import InputError
from quadnodes.io.panels import (
    bilinear_area, corner_moves, degenerate_panels, edge_lengths, panel_labels, panel_rows_cols,
)
from quadnodes.mesh import QuadMesh, cylinder, grid
from strategies import grids


def test_labels_on_a_grid_and_without():
    assert panel_labels(grid(3, 3)) == ["P_0_0", "P_0_1", "P_1_0", "P_1_1"]
    assert panel_labels(cylinder(2, 3)) == ["P_0", "P_1", "P_2"]
    assert panel_rows_cols(cylinder(2, 3)) is None


def test_labels_on_cylinder_and_torus_grids_name_every_cell_once(tmp_path):
    from quadnodes.io.obj import load_obj, save_obj
    from quadnodes.mesh import torus
    from quadnodes.topology import as_grid

    c = as_grid(cylinder(2, 3))
    assert panel_labels(c) == ["P_0_0", "P_0_1", "P_0_2"]  # the last cell closes the ring
    t = as_grid(torus(3, 4))
    assert sorted(panel_labels(t)) == sorted(f"P_{i}_{j}" for i in range(3) for j in range(4))
    save_obj(t, tmp_path / "t.obj")  # the grid comment survives a round trip for a closed grid too
    back = load_obj(tmp_path / "t.obj")
    assert back.grid_shape == (3, 4) and back.grid_wrap == (True, True) and panel_labels(back) == panel_labels(t)


def test_degenerate_panels_name_the_reason():
    v = np.array([[0., 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [1.5, 0, 0], [2, 1, 0], [2, 0, 0]])
    m = QuadMesh(v, [[0, 1, 2, 3], [1, 4, 5, 2]])
    v[[2, 5]] = [[1.2, 0, 0], [3, 0, 0]]  # processing put face 1's corners on one line (QuadMesh() refuses that)
    mask, why = degenerate_panels(m.with_vertices(v))
    assert mask.tolist() == [False, True] and why == ["zero area (all four corners on one line)"]
    v[4] = [1 + 1e-13, 0, 0]  # and an edge collapsed: refused already when the mesh is made
    with pytest.raises(InputError, match="near-duplicate vertices 1 and 4"):
        m.with_vertices(v)


def test_a_mesh_too_large_for_double_precision_is_named_so_not_zero_edged(tmp_path):
    import warnings

    from quadnodes.errors import ExportError
    from quadnodes.io.rhino import save_3dm

    m = grid(3, 3, spacing=1e200)  # finite coordinates, but squared lengths overflow
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no overflow warnings either
        mask, why = degenerate_panels(m)
    assert mask.all() and set(why) == {"its size overflows double precision (an edge length or its area is "
                                       "infinite; scale the mesh down)"}
    with pytest.raises(ExportError, match="panel 0 .* overflows double precision"):
        save_3dm(m, tmp_path / "huge.3dm")
    assert list(tmp_path.iterdir()) == []
    assert not degenerate_panels(grid(3, 3, spacing=1e60))[0].any()  # large, but its area is representable


@given(grids(), st.floats(0.1, 10.0))
def test_corner_moves_are_half_the_gap_and_scale(m, s):
    planar = np.ones(m.n_faces, bool)
    moves = corner_moves(m, planar)
    p = m.vertices[m.faces]
    # the moved corners lie on the mid-plane: distance of each corner to the plane == the move
    n = np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 1])
    ok = np.linalg.norm(n, axis=1) > 1e-9
    n = n[ok] / np.linalg.norm(n[ok], axis=1)[:, None]
    h = np.abs(np.einsum("fkj,fj->fk", p[ok] - p[ok].mean(axis=1)[:, None], n))
    np.testing.assert_allclose(h, np.repeat(moves[ok][:, None], 4, axis=1), atol=1e-9 * (1 + np.abs(p).max()))
    np.testing.assert_allclose(corner_moves(m.with_vertices(m.vertices * s), planar), moves * s, rtol=1e-9,
                               atol=1e-12)
    assert (corner_moves(m, ~planar) == 0).all()


@given(grids(), st.floats(0.1, 10.0))
def test_area_scales_with_the_square(m, s):
    np.testing.assert_allclose(bilinear_area(m.with_vertices(m.vertices * s)), bilinear_area(m) * s * s, rtol=1e-12)


@given(grids())
def test_area_is_at_least_the_projected_area(m):
    # each cell projects onto a unit square in xy; a surface is never smaller than its shadow
    assert (bilinear_area(m) >= 1.0 - 1e-12).all()


@pytest.mark.parametrize("seed", range(3))
def test_area_agrees_with_adaptive_quadrature(seed):
    from scipy.integrate import dblquad

    p = 0.3 * np.random.default_rng(seed).normal(size=(4, 3)) + [[0, 0, 0], [3, 0, 0], [3, 3, 0], [0, 3, 0]]
    m = QuadMesh(p, [[0, 1, 2, 3]])

    def density(v, u):
        su = (1 - v) * (p[1] - p[0]) + v * (p[2] - p[3])
        sv = (1 - u) * (p[3] - p[0]) + u * (p[2] - p[1])
        return np.linalg.norm(np.cross(su, sv))

    reference, _ = dblquad(density, 0, 1, 0, 1, epsabs=0, epsrel=1e-12)
    assert bilinear_area(m)[0] == pytest.approx(reference, rel=1e-9)


def test_edge_lengths():
    np.testing.assert_array_equal(edge_lengths(grid(2, 3, spacing=(2.0, 5.0))), [[2, 5, 2, 5]] * 2)
