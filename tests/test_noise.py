import numpy as np
import pytest
from hypothesis import given, strategies as st

from quadnodes.errors import InputError
from quadnodes.mesh import cylinder, grid
from quadnodes.noise import checkerboard, perturb
from quadnodes.zigzag import detect
from strategies import meshes

KW = dict(tangential=0.2, normal=0.1, jitter=0.05)


@given(meshes(), st.integers(0, 2**31 - 1))
def test_same_seed_same_bytes(mesh, seed):
    a, _ = perturb(mesh, seed=seed, **KW)
    b, _ = perturb(mesh, seed=seed, **KW)
    assert a.vertices.tobytes() == b.vertices.tobytes()
    assert perturb(mesh, seed=seed + 1, **KW)[0].vertices.tobytes() != a.vertices.tobytes()


@given(meshes(), st.sampled_from([1e-3, 7.0, 1e3]))
def test_amplitudes_follow_the_scale(mesh, s):
    a, _ = perturb(mesh, seed=3, **KW)
    b, _ = perturb(mesh.with_vertices(mesh.vertices * s), seed=3, **KW)
    np.testing.assert_allclose(b.vertices, s * a.vertices, rtol=1e-9, atol=1e-12 * s)


def test_makes_zigzags_along_both_families():
    m, _ = perturb(grid(10, 12), tangential=0.2, seed=0)
    rep = detect(m, 0.05)
    inner = ~m.topology.boundary_vertices
    assert rep.free[inner].mean() > 0.9
    # the tangential noise stays in the plane of a flat grid
    assert np.abs(m.vertices[:, 2]).max() < 1e-12
    n, _ = perturb(grid(10, 12), normal=0.2, seed=0, fix="none")
    assert np.allclose(n.vertices[:, :2], grid(10, 12).vertices[:, :2])
    assert (np.sign(n.vertices[:, 2]) == np.where(checkerboard(grid(10, 12)) == 0, 1, -1)).all()


def test_fix_and_region():
    m = grid(6, 6)
    b = m.topology.boundary_vertices
    out, _ = perturb(m, fix="boundary", **KW)
    assert np.array_equal(out.vertices[b], m.vertices[b]) and not np.array_equal(out.vertices, m.vertices)
    out, _ = perturb(m, fix="corners", region=np.arange(18), **KW)
    assert np.array_equal(out.vertices[18:], m.vertices[18:])
    assert np.array_equal(out.vertices[[0, 5]], m.vertices[[0, 5]])


def test_closed_lines():
    out, _ = perturb(cylinder(5, 10), **KW)
    assert np.isfinite(out.vertices).all()


def test_errors():
    with pytest.raises(InputError, match="tangential"):
        perturb(grid(4, 4), tangential=-1)[0]
    with pytest.raises(InputError, match="seed"):
        perturb(grid(4, 4), seed=1.5)[0]
    with pytest.raises(InputError, match="region"):
        perturb(grid(4, 4), region=[100])[0]


def test_default_keeps_the_corners_that_fairing_holds():
    m = grid(6, 7)
    out, rep = perturb(m, tangential=0.3, normal=0.2, jitter=0.1, seed=4)
    corners = m.topology.corner_vertices
    assert np.array_equal(out.vertices[corners], m.vertices[corners])
    assert rep.fix == "corners" and rep.n_fixed == 4 and rep.n_moved == m.n_vertices - 4
    assert rep.moved_max == pytest.approx(np.linalg.norm(out.vertices - m.vertices, axis=1).max())
    moved, _ = perturb(m, tangential=0.3, seed=4, fix="none")
    assert not np.array_equal(moved.vertices[corners], m.vertices[corners])


def test_fixed_indices_and_an_ambiguous_mask():
    m = grid(5, 5)
    out, rep = perturb(m, jitter=0.2, seed=1, fix="none", fixed=[12])
    assert out.vertices[12].tolist() == m.vertices[12].tolist() and rep.n_fixed == 1
    with pytest.raises(InputError, match="looks like a 0/1 mask"):
        perturb(m, jitter=0.2, fixed=m.topology.boundary_vertices.astype(int))


def test_a_negative_seed_is_refused_by_name():
    # numpy's default_rng raised "ValueError: expected non-negative integer", naming no setting
    with pytest.raises(InputError, match=r"^seed: expected an integer >= 0, got -7$"):
        perturb(grid(4, 4), tangential=0.2, seed=-7)
    assert perturb(grid(4, 4), tangential=0.2, seed=np.int64(2**40))[1].seed == 2**40
