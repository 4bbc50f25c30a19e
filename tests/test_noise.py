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
    a = perturb(mesh, seed=seed, **KW)
    b = perturb(mesh, seed=seed, **KW)
    assert a.vertices.tobytes() == b.vertices.tobytes()
    assert perturb(mesh, seed=seed + 1, **KW).vertices.tobytes() != a.vertices.tobytes()


@given(meshes(), st.sampled_from([1e-3, 7.0, 1e3]))
def test_amplitudes_follow_the_scale(mesh, s):
    a = perturb(mesh, seed=3, **KW)
    b = perturb(mesh.with_vertices(mesh.vertices * s), seed=3, **KW)
    np.testing.assert_allclose(b.vertices, s * a.vertices, rtol=1e-9, atol=1e-12 * s)


def test_makes_zigzags_along_both_families():
    m = perturb(grid(10, 12), tangential=0.2, seed=0)
    rep = detect(m, 0.05)
    inner = ~m.topology.boundary_vertices
    assert rep.free[inner].mean() > 0.9
    # the tangential noise stays in the plane of a flat grid
    assert np.abs(m.vertices[:, 2]).max() < 1e-12
    n = perturb(grid(10, 12), normal=0.2, seed=0)
    assert np.allclose(n.vertices[:, :2], grid(10, 12).vertices[:, :2])
    assert (np.sign(n.vertices[:, 2]) == np.where(checkerboard(grid(10, 12)) == 0, 1, -1)).all()


def test_fix_and_region():
    m = grid(6, 6)
    b = m.topology.boundary_vertices
    out = perturb(m, fix="boundary", **KW)
    assert np.array_equal(out.vertices[b], m.vertices[b]) and not np.array_equal(out.vertices, m.vertices)
    out = perturb(m, fix="corners", region=np.arange(18), **KW)
    assert np.array_equal(out.vertices[18:], m.vertices[18:])
    assert np.array_equal(out.vertices[[0, 5]], m.vertices[[0, 5]])


def test_closed_lines():
    out = perturb(cylinder(5, 10), **KW)
    assert np.isfinite(out.vertices).all()


def test_errors():
    with pytest.raises(InputError, match="tangential"):
        perturb(grid(4, 4), tangential=-1)
    with pytest.raises(InputError, match="seed"):
        perturb(grid(4, 4), seed=1.5)
    with pytest.raises(InputError, match="region"):
        perturb(grid(4, 4), region=[100])
