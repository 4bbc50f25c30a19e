"""quadnodes.reference: closest points against trimesh's exhaustive search and OCCT; fair(reference=...)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from quadnodes import surfaces
from quadnodes.errors import InputError
from quadnodes.fairing import fair
from quadnodes.mesh import grid
from quadnodes.metrics import distance_to_mesh
from quadnodes.noise import perturb
from quadnodes.reference import Reference, as_reference


def _surface(n: int = 12) -> object:
    y, x = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n), indexing="ij")
    return grid(n, n, spacing=1.0 / (n - 1), height=0.3 * np.sin(3 * x) * np.cos(2 * y))


def _points_near(seed: int, spread: float, count: int):
    """The test surface and ``count`` seeded points scattered ``spread`` edge lengths about its vertices."""
    ref_mesh = _surface()
    rng = np.random.default_rng(seed)
    at = rng.integers(0, ref_mesh.n_vertices, count)
    return ref_mesh, ref_mesh.vertices[at] + rng.normal(scale=spread * ref_mesh.mean_edge_length, size=(count, 3))


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 100_000), spread=st.floats(0.01, 1.0))
def test_closest_points_equal_the_exhaustive_search(seed, spread):
    ref_mesh, pts = _points_near(seed, spread, 60)
    h = ref_mesh.mean_edge_length
    q, d = Reference(ref_mesh).closest(pts)
    # brute force: every point against every triangle (trimesh.proximity.closest_point, which
    # metrics.distance_to_mesh uses, is off by up to ~1e-5 h for points this close to the surface)
    from trimesh.triangles import closest_point

    f = ref_mesh.faces
    tris = ref_mesh.vertices[np.concatenate([f[:, [0, 1, 2]], f[:, [0, 2, 3]]])]
    k = len(tris)
    c = closest_point(np.tile(tris, (len(pts), 1, 1)), np.repeat(pts, k, axis=0)).reshape(len(pts), k, 3)
    exhaustive = np.linalg.norm(c - pts[:, None], axis=2).min(axis=1)
    np.testing.assert_allclose(d, exhaustive, rtol=0, atol=1e-12 * h)
    assert (d <= distance_to_mesh(pts, ref_mesh) + 1e-12 * h).all()
    np.testing.assert_allclose(np.linalg.norm(q - pts, axis=1), d, atol=1e-12)


def test_face_reference_is_within_the_chord_error_of_occt():
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeVertex
    from OCP.BRepExtrema import BRepExtrema_DistShapeShape
    from OCP.gp import gp_Pnt

    face = surfaces.dome()
    mesh = surfaces.sample(face, 12, 12)
    ref = as_reference(face, mesh)
    assert ref.source == "face" and ref.mesh.grid_shape == (64, 64)
    h = mesh.mean_edge_length
    rng = np.random.default_rng(0)
    pts = mesh.vertices[::7] + rng.normal(scale=0.2 * h, size=mesh.vertices[::7].shape)
    _, d = ref.closest(pts)
    exact = []
    for p in pts:
        v = BRepBuilderAPI_MakeVertex(gp_Pnt(*p.tolist())).Vertex()
        exact.append(BRepExtrema_DistShapeShape(v, face.wrapped).Value())
    assert np.abs(d - np.array(exact)).max() < 2e-3 * h


def test_as_reference_accepts_meshes_and_rejects_others():
    m = _surface(5)
    r = as_reference(m, m)
    assert isinstance(r, Reference) and as_reference(r, m) is r
    with pytest.raises(InputError, match="reference: expected a QuadMesh, a build123d Face"):
        as_reference("dome.step", m)
    with pytest.raises(InputError, match="points"):
        r.closest(np.zeros((3, 2)))


def test_fair_with_a_reference_stays_closer_to_the_design_surface():
    clean = surfaces.example("E1")
    h = clean.mean_edge_length
    noisy, _ = perturb(clean, tangential=0.25, normal=0.1, seed=7, fix="corners")
    plain, _ = fair(noisy, iterations=3)
    slid, rep = fair(noisy, iterations=3, reference=clean)
    assert distance_to_mesh(slid.vertices, clean).max() < 0.5 * distance_to_mesh(plain.vertices, clean).max()
    assert rep.iterations[0].n_free > 0
    # corners never move; the zigzag is gone as well as without the reference
    c = clean.topology.corner_vertices
    np.testing.assert_array_equal(slid.vertices[c], noisy.vertices[c])
    from quadnodes.zigzag import detect

    assert detect(slid, 0.1).n_free == 0
    assert np.isfinite(slid.vertices).all() and h > 0


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 100_000), spread=st.floats(0.05, 3.0))
def test_triangle_kernel_equals_trimesh_point_by_point(seed, spread):
    # the vectorized region test of Reference.closest against trimesh's closest_point, per pair
    from trimesh.triangles import closest_point

    from quadnodes.reference import _triangle_coordinates

    rng = np.random.default_rng(seed)
    tris = rng.normal(size=(400, 3, 3))
    pts = rng.normal(scale=spread, size=(400, 3))
    a, ab, ac = tris[:, 0], tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    gram = np.stack([(ab * ab).sum(1), (ab * ac).sum(1), (ac * ac).sum(1)], axis=1)
    v, w, d2 = _triangle_coordinates(pts, a, ab, ac, gram, np.arange(400)[:, None])
    mine = a + v[:, :1] * ab + w[:, :1] * ac
    np.testing.assert_allclose(mine, closest_point(tris, pts), atol=1e-9)
    np.testing.assert_allclose(np.sqrt(d2[:, 0]), np.linalg.norm(mine - pts, axis=1), atol=1e-9)
    assert ((v >= -1e-12) & (w >= -1e-12) & (v + w <= 1 + 1e-12)).all()  # on the triangle


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 100_000), spread=st.floats(0.01, 2.0))
def test_compiled_closest_points_equal_the_numpy_path(seed, spread):
    # from COMPILED_MIN_POINTS points on the region test runs compiled, on the pool's threads: the same
    # closest points as the NumPy path, to the bit (the same formulas, every sum in the same order), so a
    # planarize result does not depend on whether the kernel had loaded in time
    import quadnodes.reference as R
    from quadnodes.linalg import threads as linalg_threads

    ref_mesh, pts = _points_near(seed, spread, 3000)
    with pytest.MonkeyPatch.context() as mp:  # (the kernels may be loaded by an earlier test)
        mp.setattr(R, "_compiled_kernel", lambda points: None)
        numpy_q, numpy_d = Reference(ref_mesh).closest(pts)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(R, "COMPILED_MIN_POINTS", 1)
        mp.setattr(R, "CHUNK", 256)  # several ranges on the threads
        mp.setattr(linalg_threads, "thread_count", lambda: 2)
        mp.setattr(R._compiled, "ready", lambda: True)  # (the kernel loads on its first call; no wait() that
        assert R._compiled_kernel(len(pts)) is not None  # would switch this process's later tests to the kernels)
        q, d = Reference(ref_mesh).closest(pts)
    np.testing.assert_array_equal(q, numpy_q)
    np.testing.assert_array_equal(d, numpy_d)


def test_a_reference_mesh_in_another_unit_is_converted_to_the_mesh_s_unit():
    # a reference mesh in metres was read as millimetres: fair pulled the vertices 570 mm towards a
    # surface a thousandth of its size, with no word
    clean = grid(6, 6, spacing=100.0)
    noisy, _ = perturb(clean, tangential=0.2, normal=0.2, seed=1)
    for ref in (clean.with_unit("m"), Reference(clean.with_unit("m")), Reference(clean.with_unit("in"))):
        r = as_reference(ref, noisy)
        assert r.mesh.unit == "mm"
        np.testing.assert_allclose(r.mesh.vertices, clean.vertices, atol=1e-9)
    want, _ = fair(noisy, reference=clean, iterations=2)
    got, _ = fair(noisy, reference=clean.with_unit("m"), iterations=2)
    np.testing.assert_allclose(got.vertices, want.vertices, atol=1e-6)
    same = Reference(clean)
    assert as_reference(same, noisy) is same  # nothing to convert: the same object
