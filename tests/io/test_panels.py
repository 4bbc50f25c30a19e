import numpy as np
import pytest
from hypothesis import given, strategies as st

from quadnodes.errors import InputError
from quadnodes.io.panels import bilinear_area, edge_lengths, panel_labels, panel_rows_cols, planar_mask
from quadnodes.mesh import QuadMesh, cylinder, grid
from strategies import grids


def test_labels_on_a_grid_and_without():
    assert panel_labels(grid(3, 3)) == ["P_0_0", "P_0_1", "P_1_0", "P_1_1"]
    assert panel_labels(cylinder(2, 3)) == ["P_0", "P_1", "P_2"]
    assert panel_rows_cols(cylinder(2, 3)) is None


def test_planar_mask_tolerance():
    m = grid(2, 3, height=[[0, 0, 0], [0, 0, 1e-3]])
    assert planar_mask(m).tolist() == [True, False]
    assert planar_mask(m, planar_tol=1.0).tolist() == [True, True]
    with pytest.raises(InputError, match="planar_tol"):
        planar_mask(m, planar_tol=-1e-9)
    with pytest.raises(InputError, match="QuadMesh"):
        planar_mask(m.vertices)


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
