import numpy as np
import pytest

from quadnodes.errors import InputError
from quadnodes.mesh import grid
from quadnodes.metrics import compare, distance_to_mesh, zigzag_stats
from quadnodes.noise import perturb
from quadnodes.smoothing import laplacian


def test_compare_reports_everything():
    clean = grid(8, 9)
    noisy, _ = perturb(clean, tangential=0.3, normal=0.2, seed=0)
    out, _ = laplacian(noisy, iterations=3)
    r = compare(noisy, out, reference=clean)
    for key in ("zigzag_mean", "zigzag_max", "vertices_above_0.1", "vertices_above_0.01",
                "displacement_mean", "displacement_max", "boundary_displacement_max",
                "bbox_diagonal_change_pct", "planarity_mean", "planarity_max",
                "angle_defect_mean", "angle_defect_max", "reference_mean", "reference_max"):
        assert key in r
    d = np.linalg.norm(out.vertices - noisy.vertices, axis=1)
    assert r["displacement_max"] == pytest.approx(d.max())
    assert r["bbox_diagonal_change_pct"] < 0  # Laplacian shrinks
    # distance to the flat reference is |z|
    assert r["reference_max"] == pytest.approx(np.abs(out.vertices[:, 2]).max(), abs=1e-9)
    # same connectivity: vertex-to-vertex distance too
    assert r["reference_vertex_max"] == pytest.approx(np.linalg.norm(out.vertices - clean.vertices, axis=1).max())
    assert "reference_vertex_mean" not in compare(noisy, out, reference=grid(3, 3))


def test_distance_to_mesh_on_a_plane():
    ref = grid(5, 5)
    pts = np.array([[1.5, 2.5, 0.3], [2.0, 2.0, -1.0], [10.0, 2.0, 0.0]])
    np.testing.assert_allclose(distance_to_mesh(pts, ref), [0.3, 1.0, 6.0], atol=1e-12)


def test_zigzag_counts():
    s = zigzag_stats(perturb(grid(8, 8), tangential=0.4, seed=1)[0], thresholds=(0.1, 0.01, 1e-6))
    assert s["vertices_above_1e-06"] >= s["vertices_above_0.01"] >= s["vertices_above_0.1"] > 0


def test_compare_needs_same_faces():
    with pytest.raises(InputError, match="same faces"):
        compare(grid(3, 3), grid(3, 4))


def test_meshes_in_other_units_are_compared_in_the_original_s_unit():
    # a reference or result in metres was read as millimetres: reference_mean 392 mm instead of 0
    clean = grid(6, 6, spacing=100.0)
    noisy, _ = perturb(clean, tangential=0.2, normal=0.2, seed=1)
    out, _ = laplacian(noisy, iterations=2)
    want = compare(noisy, out, reference=clean)
    for got in (compare(noisy, out, reference=clean.with_unit("m")), compare(noisy, out.with_unit("m"), reference=clean),
                compare(noisy, out.with_unit("cm"), reference=clean.with_unit("ft"))):
        assert set(got) == set(want)
        for k in want:
            assert got[k] == pytest.approx(want[k], rel=1e-9, abs=1e-9), k
