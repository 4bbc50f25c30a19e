import numpy as np
import pytest
from hypothesis import given, settings

from quadnodes.errors import InputError
from quadnodes.mesh import cylinder, grid
from quadnodes.noise import perturb
from quadnodes.spring_model import spring, spring_displacement
from sphere_patch import distance, normals, patch
from strategies import irregular


def test_sphere_patch_stays_on_its_sphere():
    m = patch(17)
    h = m.mean_edge_length
    dn, _, energy, skipped = spring_displacement(m, m.vertices, normals=normals(m.vertices),
                                                 constrained=m.topology.boundary_vertices)
    inner = ~m.topology.boundary_vertices
    assert np.abs(dn[inner]).max() < 1e-3 * h and skipped == 0  # the normal displacement vanishes (to O(h²/R))
    out, rep = spring(m, normals=normals(m.vertices), tangential=False)
    assert rep.converged and distance(out.vertices).max() < 1e-5 * h
    assert rep.to_dict()["fix"] == "boundary"
    # the tangential move evens the spacing and leaves the sphere by O(h²/R), which refinement shrinks
    off = []
    for n in (9, 17, 33):
        m = patch(n)
        out, rep = spring(m, normals=normals(m.vertices), max_iterations=3000)
        assert rep.converged
        off.append(distance(out.vertices).max())
    assert off[1] < off[0] / 4 and off[2] < off[1] / 3 and off[2] < 3e-3 * m.mean_edge_length


def test_noisy_sphere_patch_converges_towards_the_sphere():
    m = patch(17)
    h = m.mean_edge_length
    noisy, _ = perturb(m, normal=0.2, seed=3, fix="boundary")
    before = distance(noisy.vertices).mean()
    out, rep = spring(noisy, normals=normals(m.vertices), max_iterations=2000)
    assert rep.converged and rep.history[-1] < rep.tolerance
    assert distance(out.vertices).mean() < before / 20  # 0.12 h -> about 0.003 h
    assert rep.energy < 1e-3 * rep.energy_input
    b = m.topology.boundary_vertices
    assert np.array_equal(out.vertices[b], noisy.vertices[b])


def test_parallel_normals_reduce_to_the_height_difference():
    z = np.zeros((3, 3))
    z[1, 1] = 0.2
    m = grid(3, 3, height=z)
    flat = np.tile([0.0, 0.0, 1.0], (9, 1))
    dn, dt, _, _ = spring_displacement(m, m.vertices, normals=flat, constrained=np.ones(9, bool))
    # eq. 23 with n_i = n_j = n: <p_j − p_i, n> n, averaged with inverse lengths (all equal here)
    np.testing.assert_allclose(dn[4], [0, 0, -0.2], atol=1e-12)
    np.testing.assert_allclose(dt[4], 0, atol=1e-12)


def test_closed_mesh_and_fixing():
    c = cylinder(5, 12)
    noisy, _ = perturb(c, normal=0.1, seed=1)
    out, rep = spring(noisy, fix="boundary", max_iterations=50)
    b = c.topology.boundary_vertices
    assert np.array_equal(out.vertices[b], noisy.vertices[b]) and rep.iterations <= 50
    out2, rep2 = spring(noisy, fix="none", fixed=[0, 1], max_iterations=5)
    assert np.array_equal(out2.vertices[:2], noisy.vertices[:2]) and rep2.n_fixed == 2


@given(irregular())
@settings(max_examples=6)
def test_any_mesh(m):
    out, rep = spring(m, fix="corners", max_iterations=20)
    assert np.isfinite(out.vertices).all() and len(rep.history) == rep.iterations


def test_errors():
    m = grid(4, 4)
    with pytest.raises(InputError, match="step"):
        spring(m, step=1.5)
    with pytest.raises(InputError, match="every vertex is fixed"):
        spring(m, fixed=np.ones(16, bool))
    with pytest.raises(InputError, match="normals"):
        spring(m, normals=np.ones((3, 3)))
    with pytest.raises(InputError, match="fix"):
        spring(m, fix="Boundary")


def test_a_vertex_in_no_face_stays_and_does_not_stop_convergence():
    # it made the largest move 0/0 = nan: 500 iterations, converged=False, max_displacement nan
    noisy, _ = perturb(grid(6, 6), tangential=0.2, seed=1)
    stray = noisy.__class__(np.vstack([noisy.vertices, [[50.0, 50.0, 50.0]]]), noisy.faces)
    a, ra = spring(noisy)
    b, rb = spring(stray)
    assert rb.converged and rb.iterations == ra.iterations and np.isfinite(rb.history).all()
    assert np.array_equal(b.vertices[-1], [50.0, 50.0, 50.0])
    assert np.allclose(b.vertices[:-1], a.vertices, atol=1e-12)
