"""The public meshes of tests/data (see its README): loaded, detected, faired, planarized and exported (issue 16)."""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np
import pytest

from quadnodes.errors import InputError
from quadnodes.fairing import fair
from quadnodes.io import load, save_obj
from quadnodes.noise import perturb
from quadnodes.planarization import planarize
from quadnodes.topology import as_grid, corner_vertices, fixed_vertices
from quadnodes.zigzag import detect

DATA = Path(__file__).resolve().parent / "data"
MESHES = {
    "compas/quadmesh.obj": (100, 81, (10, 10)),
    "compas/tubemesh.obj": (200, 171, (20, 10)),
    "compas/hypar.obj": (81, 64, (9, 9)),
    "rounded_box.obj": (386, 384, None),
    "polygon_quads.obj": (603, 562, None),
    "quadmesh_hole.obj": (100, 77, None),
    "staircase_saddle.obj": (364, 321, None),
}


def test_every_data_file_is_small_and_described():
    readme = (DATA / "README.md").read_text()
    for name in MESHES:
        assert (DATA / name).stat().st_size < 200_000
        assert f"`{name}`" in readme
    assert "MIT" in (DATA / "compas" / "LICENSE").read_text()


@pytest.mark.parametrize("name", sorted(MESHES))
def test_load_detect_fair_planarize_export(name, tmp_path):
    n, m, shape = MESHES[name]
    mesh = load(DATA / name)
    assert (mesh.n_vertices, mesh.n_faces, mesh.grid_shape) == (n, m, shape)
    # clean designed meshes are left untouched by the default detection
    assert detect(mesh).n_free == 0
    same, _ = fair(mesh, iterations=2)
    np.testing.assert_array_equal(same.vertices, mesh.vertices)
    noisy, _ = perturb(mesh, tangential=0.2, normal=0.1, seed=3)
    h = mesh.mean_edge_length
    faired, rep = fair(noisy, iterations=3)
    err_before = np.linalg.norm(noisy.vertices - mesh.vertices, axis=1).mean()
    err_after = np.linalg.norm(faired.vertices - mesh.vertices, axis=1).mean()
    assert rep.effective_iterations >= 1 and err_after < err_before
    flat, prep = planarize(faired, planar_tolerance=1e-2, fix="none", max_iterations=300, method="local-global")
    assert prep.planarity_max <= 1e-2 or not prep.converged
    assert prep.converged == (prep.planarity_max <= 1e-2 and not prep.nonconvex and prep.collapsed_edges == 0)
    assert prep.edge_length_ratio_min > 0
    assert prep.moved_max == pytest.approx(np.linalg.norm(flat.vertices - faired.vertices, axis=1).max())
    save_obj(flat, tmp_path / "out.obj")
    back = meshio.read(tmp_path / "out.obj")  # an independent reader
    np.testing.assert_allclose(back.points, flat.vertices, rtol=0, atol=1e-6 * max(1.0, np.abs(flat.vertices).max()))
    assert sum(len(c.data) for c in back.cells) == m


def test_unordered_rhino_grids_are_renumbered_row_by_row():
    raw = load(DATA / "compas/quadmesh.obj", renumber_grid=False)
    assert raw.grid_shape is None
    g = load(DATA / "compas/quadmesh.obj")
    rows, cols = g.grid_shape
    ids = np.arange(rows * cols).reshape(rows, cols)
    # neighbours in the numbering are neighbours in the mesh: every row and column is an edge chain
    e = {tuple(sorted(x)) for x in g.topology.edges.tolist()}
    assert all((int(a), int(b)) in e for a, b in zip(ids[:, :-1].ravel(), ids[:, 1:].ravel()))
    assert all((int(a), int(b)) in e for a, b in zip(ids[:-1].ravel(), ids[1:].ravel()))
    # the same points, the same quads
    np.testing.assert_array_equal(np.sort(g.vertices, axis=0), np.sort(raw.vertices, axis=0))
    assert as_grid(raw).grid_shape == (rows, cols)


def test_staircase_boundary_has_few_corners_and_planarizes_with_defaults():
    m = load(DATA / "staircase_saddle.obj")
    topo = m.topology
    assert int(topo.corner_vertices.sum()) == 52  # by valence: every step of the staircase
    corners = corner_vertices(m)
    assert int(corners.sum()) == 18 and not (corners & ~topo.corner_vertices).any()
    assert not (m.topology.faces.shape[0] and np.all(corners[m.faces], axis=1).any())
    out, rep = planarize(m, planar_tolerance=1e-2, max_iterations=300)
    np.testing.assert_array_equal(out.vertices[corners], m.vertices[corners])
    assert rep.n_fixed == 18 and rep.methods_tried[0] == "local-global"
    # holding the whole valence-defined set would leave some quads with four held corners: refused, named
    with pytest.raises(InputError, match="have all four corners held"):
        planarize(m, fix="none", fixed=topo.corner_vertices | topo.boundary_vertices, planar_tolerance=1e-6)


def test_planarize_keeps_quads_sound_on_the_issue_cases():
    # issue 16, item 4: with reference=input the ruled hypar's edges collapsed to 0.6 % of their length
    m = load(DATA / "compas/hypar.obj")
    _, free = planarize(m, reference=m, shape="free")
    assert free.edge_length_ratio_min < 0.01 and free.nonconvex and not free.converged
    _, keep = planarize(m, reference=m)
    assert keep.shape == "keep" and keep.nonconvex == [] and keep.collapsed_edges == 0
    assert keep.edge_length_ratio_min > 0.25
    # its grid runs along the rulings (no conjugate net): with the corners held, planar quads must fold,
    # so the sound result is not converged, and the report says what to change
    assert not keep.converged and any("fix='none'" in n for n in keep.notes())
    # the staircase mesh, noisy and faired, nothing held: the plain projection folds quads; "keep" converges
    st = load(DATA / "staircase_saddle.obj")
    # (faired as before issue 16 item 6: eq. 32's lengths and threshold 0.1 leave the case the issue met;
    # fair's defaults since then leave a mesh the plain projection planarizes without folds)
    faired, _ = fair(perturb(st, tangential=0.2, normal=0.1, seed=3)[0], iterations=3, line_spacing="hold",
                     threshold=0.1)
    _, f2 = planarize(faired, fix="none", shape="free")
    assert f2.nonconvex and not f2.converged
    flat, k2 = planarize(faired, fix="none")
    assert k2.converged and k2.nonconvex == [] and k2.planarity_max <= 1e-3
    assert k2.edge_length_ratio_min > 0.25


def test_holding_curvature_recovers_the_closed_box_from_normal_noise():
    # the clean box is no minimizer of the line energy (its rounded edges change curvature): with every vertex
    # free it drifts; line_curvature="hold" (twicing at half the weight) drifts less and recovers the box better
    clean = load(DATA / "rounded_box.obj")
    h = clean.mean_edge_length

    def err(m):
        return float(np.linalg.norm(m.vertices - clean.vertices, axis=1).mean() / h)

    drift = {c: err(fair(clean, threshold=0.0, detection="thesis", line_curvature=c)[0]) for c in ("fair", "hold")}
    assert drift["hold"] < 0.7 * drift["fair"]
    noisy, _ = perturb(clean, normal=0.2, seed=0, fix="corners")
    e = {c: err(fair(noisy, line_curvature=c)[0]) for c in ("fair", "hold")}
    assert e["hold"] < 0.8 * e["fair"] and e["hold"] < err(noisy) / 5


def test_auto_curvature_recovers_the_closed_box_within_the_goal():
    # fair's default line_curvature="auto" holds the line terms where the box's rounded edges change curvature:
    # the clean box drifts less than with "fair", and on normal noise (seeds 0 and 1, the benchmark's rows) fair
    # is within 20 % of the best tuned trimesh filter_taubin (the goal of docs/real-meshes.md; "fair": +28 %)
    import trimesh
    from trimesh.smoothing import filter_taubin

    clean = load(DATA / "rounded_box.obj")
    h = clean.mean_edge_length

    def err(m):
        return float(np.linalg.norm(m.vertices - clean.vertices, axis=1).mean() / h)

    drift, rep = fair(clean, threshold=0.0, detection="thesis")
    assert rep.iterations[0].n_curvature_held > 0
    assert err(drift) < 0.9 * err(fair(clean, threshold=0.0, detection="thesis", line_curvature="fair")[0])
    noisy = [perturb(clean, normal=0.2, seed=s, fix="corners")[0] for s in (0, 1)]
    auto = np.mean([err(fair(m)[0]) for m in noisy])
    once = np.mean([err(fair(m, line_curvature="fair")[0]) for m in noisy])
    held = fixed_vertices(clean, "corners")
    f = clean.faces
    tri = np.concatenate([f[:, [0, 1, 2]], f[:, [0, 2, 3]]])

    def taubin(m, k):
        t = trimesh.Trimesh(m.vertices.copy(), tri, process=False)
        filter_taubin(t, iterations=k)
        v = np.asarray(t.vertices).copy()
        v[held] = m.vertices[held]
        return clean.with_vertices(v)

    peer = min(np.mean([err(taubin(m, k)) for m in noisy]) for k in (2, 5, 10, 20))
    assert auto < 0.9 * once
    assert auto <= 1.2 * peer < once
