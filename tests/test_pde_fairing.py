import numpy as np
import pytest
from hypothesis import given, settings

from quadnodes.errors import InputError
from quadnodes.mesh import cylinder, grid
from quadnodes.noise import perturb
from quadnodes.pde_fairing import grow_ring, schneider_kobbelt
from sphere_patch import distance, patch
from strategies import irregular


def test_sphere_patch_stays_on_its_sphere():
    m = patch(17)
    out, rep = schneider_kobbelt(m, inner=False)  # eq. 29 alone: moves along the normals only
    assert distance(out.vertices).max() < 1e-6 * m.mean_edge_length
    assert rep.converged and rep.iterations <= 3
    # with inner fairness the vertices even out along the surface and leave it by O(h²/R) only
    out, rep = schneider_kobbelt(m)
    assert rep.converged and distance(out.vertices).max() < 1e-2 * m.mean_edge_length


def test_noisy_sphere_patch_converges_towards_the_sphere():
    m = patch(17)
    h = m.mean_edge_length
    free = ~grow_ring(m, m.topology.boundary_vertices, 1)
    noisy = perturb(m, normal=0.2, seed=3, region=free)[0]  # the G1 boundary (boundary + one ring) is clean
    before = distance(noisy.vertices).mean()
    out, rep = schneider_kobbelt(noisy, max_iterations=300)
    assert rep.converged
    assert distance(out.vertices).mean() < before / 50  # about 0.1 h -> 0.001 h
    assert rep.energy < 1e-3 * rep.energy_input
    held = ~free
    assert np.array_equal(out.vertices[held], noisy.vertices[held])
    moved = out.vertices - noisy.vertices
    assert np.abs(moved[held]).max() == 0 and np.abs(moved).max() > 0.01 * h


def test_ring_and_fixing():
    m = grid(7, 7)
    assert int(grow_ring(m, m.topology.boundary_vertices, 1).sum()) == 49 - 9
    assert int(grow_ring(m, m.topology.boundary_vertices, 2).sum()) == 49 - 1
    with pytest.raises(InputError, match="cover the mesh"):
        schneider_kobbelt(m, ring=3)
    with pytest.raises(InputError, match="no vertex is held"):
        schneider_kobbelt(cylinder(4, 8), fix="none")
    out, rep = schneider_kobbelt(perturb(cylinder(8, 16), normal=0.1, seed=2)[0], max_iterations=10)
    assert rep.n_fixed == 4 * 16 and np.isfinite(out.vertices).all()


@given(irregular())
@settings(max_examples=6)
def test_any_mesh_keeps_the_held_vertices(m):
    out, rep = schneider_kobbelt(m, ring=0, max_iterations=5)
    b = m.topology.boundary_vertices
    assert np.array_equal(out.vertices[b], m.vertices[b]) and np.isfinite(out.vertices).all()


def test_a_vertex_in_no_face_stays_and_is_no_unanchored_part():
    # it was refused: "the Laplace–Beltrami system is singular; some part of the mesh holds no fixed vertex"
    noisy, _ = perturb(grid(8, 8), normal=0.2, seed=1)
    stray = noisy.__class__(np.vstack([noisy.vertices, [[50.0, 50.0, 50.0]]]), noisy.faces)
    a, ra = schneider_kobbelt(noisy)
    b, rb = schneider_kobbelt(stray)
    assert rb.iterations == ra.iterations and np.array_equal(b.vertices[-1], [50.0, 50.0, 50.0])
    assert np.allclose(b.vertices[:-1], a.vertices, atol=1e-9 * noisy.mean_edge_length)
