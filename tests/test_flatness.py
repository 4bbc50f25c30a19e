import numpy as np
import pytest
from hypothesis import given, strategies as st
from scipy.spatial.transform import Rotation

from quadnodes.mesh import QuadMesh, grid
from quadnodes.flatness import angle_defect, diagonal_distance, planarity, summary
from strategies import grids


@given(st.integers(2, 9), st.integers(2, 9), st.integers(0, 10_000))
def test_flat_grid_has_planarity_zero_in_any_pose(r, c, seed):
    m = grid(r, c, spacing=(0.7, 1.3))
    rot = Rotation.random(random_state=seed).as_matrix()
    moved = m.with_vertices(m.vertices @ rot.T + [3.0, -2.0, 5.0])
    assert diagonal_distance(moved).max() < 1e-12
    assert np.abs(angle_defect(moved)).max() < 1e-9


def test_twisted_quad():
    m = QuadMesh([[0, 0, 0], [1, 0, 0], [1, 1, 1], [0, 1, 0.0]], [[0, 1, 2, 3]])
    assert diagonal_distance(m, relative=False)[0] == pytest.approx(1 / np.sqrt(6))
    assert angle_defect(m)[0] < 0


@given(grids(), st.floats(1e-3, 1e3))
def test_relative_measures_are_scale_invariant(m, s):
    scaled = m.with_vertices(m.vertices * s)
    np.testing.assert_allclose(diagonal_distance(scaled), diagonal_distance(m), rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(angle_defect(scaled), angle_defect(m), atol=1e-9)


def test_planarity_and_summary():
    m = grid(3, 3, height=[[0, 0, 0], [0, 1, 0], [0, 0, 0]])
    p = planarity(m)
    assert p["diagonal"].shape == (4,) and (p["diagonal"] > 0).all()
    s = summary(p["diagonal"])
    assert s["max"] >= s["p95"] >= s["median"] > 0
    assert summary(np.array([]))["max"] == 0.0
