import numpy as np
import pytest
from hypothesis import given

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
