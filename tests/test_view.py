"""quadnodes._view: per-edge and per-panel zigzag values against plain loops, the shared camera."""

import numpy as np
import pytest
from hypothesis import given, strategies as st

from meshes import extraordinary_mesh, l_shape_with_hole
from quadnodes._view import edge_deviation, edge_ids, face_deviation, face_edges
from quadnodes.errors import InputError
from quadnodes.mesh import cylinder, grid
from quadnodes.noise import perturb
from quadnodes.zigzag import detect, window_deviation


def _reference(mesh):
    """Edge deviation by a loop over windows: max over windows whose middle edge it is, else over the
    windows it is a side edge of, else 0."""
    w = mesh.topology.windows
    wd = window_deviation(mesh.vertices, w)
    mid, side = {}, {}
    for (p0, p1, p2, p3), d in zip(w.tolist(), wd):
        k = (min(p1, p2), max(p1, p2))
        mid[k] = max(mid.get(k, 0.0), d)
        for a, b in ((p0, p1), (p2, p3)):
            k = (min(a, b), max(a, b))
            side[k] = max(side.get(k, 0.0), d)
    return np.array([mid.get(k, side.get(k, 0.0)) for k in map(tuple, mesh.topology.edges.tolist())])


@pytest.mark.parametrize("make", [
    lambda: perturb(grid(5, 7), tangential=0.2, seed=1)[0],
    lambda: perturb(cylinder(4, 7), tangential=0.2, seed=2)[0],
    extraordinary_mesh,
    l_shape_with_hole,
    lambda: grid(2, 3),
])
def test_edge_deviation_matches_a_loop(make):
    m = make()
    np.testing.assert_allclose(edge_deviation(m), _reference(m), rtol=1e-12, atol=1e-15)  # the walk sums in another order
    fd = face_deviation(m)
    e = m.topology.edges
    for f, face in enumerate(m.faces.tolist()):
        sides = [tuple(sorted((face[k], face[(k + 1) % 4]))) for k in range(4)]
        assert [tuple(x) for x in e[face_edges(m)[f]].tolist()] == sides
        assert fd[f] == max(edge_deviation(m)[edge_ids(m, *np.array(sides).T)])


@given(st.integers(0, 10_000))
def test_precomputed_window_deviation_gives_the_same(seed):
    m, _ = perturb(grid(4, 6), tangential=0.3, seed=seed)
    wd = detect(m, 0.0).window_deviation  # as a pipeline passes it on
    np.testing.assert_array_equal(edge_deviation(m, deviation=wd), edge_deviation(m))
    wd = window_deviation(m.vertices, m.topology.windows)  # the generic per-window route
    np.testing.assert_allclose(edge_deviation(m, deviation=wd), edge_deviation(m), rtol=1e-12, atol=1e-15)


def test_errors():
    m = grid(3, 5)
    with pytest.raises(InputError, match=r"^deviation: expected shape \(6,\)"):
        edge_deviation(m, deviation=np.zeros(5))
    with pytest.raises(InputError, match="^mesh: expected a QuadMesh"):
        edge_deviation(np.zeros((3, 3)))
