import numpy as np
import pytest
from hypothesis import given

from quadnodes import surfaces
from quadnodes.discrete_curvature import cotangent_laplacian, curvature, line_curvature, moreton_sequin
from quadnodes.errors import InputError
from quadnodes.mesh import cylinder, grid
from meshes import extraordinary_mesh, l_shape_with_hole
from strategies import meshes

SPHERE_R = (6000.0**2 / 4 + 1200.0**2) / 2400.0


def analytic(name, v):
    """Mean, Gaussian, k1, k2 of the default surfaces (sign: the faces' normal)."""
    x, y, _ = v.T
    n = len(v)
    if name == "dome":
        k = np.full(n, 1 / SPHERE_R)
        return k, k * k, k, k
    if name == "cylinder_segment":
        return np.full(n, 0.5 / 5000.0), np.zeros(n), np.full(n, 1 / 5000.0), np.zeros(n)
    if name == "torus_patch":
        a, r = 6000.0, 2000.0
        c = (np.hypot(x, y) - a) / r
        k1, k2 = np.full(n, 1 / r), c / (a + r * c)
        return (k1 + k2) / 2, k1 * k2, k1, k2
    w = d = 5000.0
    rise = 1000.0
    fx, fy, fxx, fyy = 8 * rise * x / w**2, -8 * rise * y / d**2, 8 * rise / w**2, -8 * rise / d**2
    g = 1 + fx**2 + fy**2
    H = ((1 + fy**2) * fxx + (1 + fx**2) * fyy) / (2 * g**1.5)
    K = fxx * fyy / g**2
    s = np.sqrt(np.maximum(H * H - K, 0))
    return H, K, H + s, H - s  # Monge-patch formulas: positive H bends towards the upward normal


def cotangent_reference(mesh):
    """Dense cotangent matrix, triangle by triangle in plain Python, both triangulations averaged."""
    n = mesh.n_vertices
    L = np.zeros((n, n))
    x = mesh.vertices
    for f in mesh.faces:
        for tris in (((0, 1, 2), (0, 2, 3)), ((0, 1, 3), (1, 2, 3))):
            for t in tris:
                ids = [f[k] for k in t]
                for c in range(3):
                    p, q, r = ids[c], ids[(c + 1) % 3], ids[(c + 2) % 3]
                    u, v = x[q] - x[p], x[r] - x[p]
                    cot = np.dot(u, v) / np.linalg.norm(np.cross(u, v))
                    L[q, r] -= 0.25 * cot
                    L[r, q] -= 0.25 * cot
    L[np.diag_indices(n)] = -L.sum(axis=1)
    return L


@pytest.mark.parametrize("mesh", [surfaces.sample(surfaces.saddle(), 5, 6), extraordinary_mesh(1),
                                  l_shape_with_hole(), cylinder(3, 7)], ids=["saddle", "extraordinary", "hole", "cyl"])
def test_laplace_beltrami_symmetric_rows_zero_and_equals_dense_reference(mesh):
    L = cotangent_laplacian(mesh)
    dense = L.toarray()
    np.testing.assert_allclose(dense, dense.T, atol=1e-12 * np.abs(dense).max())
    np.testing.assert_allclose(dense.sum(axis=1), 0, atol=1e-12 * np.abs(dense).max())
    np.testing.assert_allclose(dense, cotangent_reference(mesh), atol=1e-12 * np.abs(dense).max())


@given(meshes())
def test_laplace_beltrami_properties_on_any_mesh(m):
    L = cotangent_laplacian(m)
    assert abs(L - L.T).max() < 1e-12 * abs(L).max()
    assert np.abs(np.asarray(L.sum(axis=1))).max() < 1e-12 * abs(L).max()
    np.testing.assert_allclose(L @ np.ones(m.n_vertices), 0, atol=1e-12 * abs(L).max())


def test_flat_grid_has_zero_curvature():
    c = curvature(grid(6, 7))
    inner = ~np.isnan(c["mean"])
    assert inner.sum() == 4 * 5
    for k in ("mean", "gaussian", "gaussian_1", "gaussian_2", "gaussian_3", "k1", "k2"):
        assert np.abs(c[k][inner]).max() < 1e-12
    assert np.isnan(c["mean"][0]) and np.isnan(c["gaussian"][0])  # boundary


@pytest.mark.parametrize("name", ["dome", "cylinder_segment", "torus_patch", "saddle"])
def test_curvatures_converge_at_second_order(name):
    face = getattr(surfaces, name)()
    keys = ("mean", "gaussian", "gaussian_1", "gaussian_2", "gaussian_3", "k1", "k2")
    errs = {k: [] for k in keys}
    hs = []
    for n in (9, 17, 33):
        m = surfaces.sample(face, n, n)
        c = curvature(m)
        H, K, k1, k2 = analytic(name, m.vertices)
        if name == "saddle" and np.nanmean(c["normal"][:, 2]) > 0:  # ours: positive bends away from the normal
            H, k1, k2 = -H, -k2, -k1
        inner = ~m.topology.boundary_vertices
        ref = dict(mean=H, gaussian=K, gaussian_1=K, gaussian_2=K, gaussian_3=K, k1=k1, k2=k2)
        hs.append(m.mean_edge_length)
        for k in keys:
            errs[k].append(np.max(np.abs(c[k][inner] - ref[k][inner])))
    for k in keys:
        e = np.array(errs[k])
        size = 1 / 2000.0 if k in ("mean", "k1", "k2") else 1 / 2000.0**2
        if e.max() < 1e-10 * size:  # the cylinder: exact up to rounding
            continue
        rate = np.polyfit(np.log(hs), np.log(e), 1)[0]
        assert rate > 1.8, (k, e, rate)
        assert e[-1] < 1e-2 * size, (k, e)


def test_principal_directions_on_a_cylinder():
    m = surfaces.sample(surfaces.cylinder_segment(), 9, 9)
    c = curvature(m)
    inner = ~m.topology.boundary_vertices
    axis = np.array([0.0, 1.0, 0.0])
    assert np.abs(c["direction1"][inner] @ axis).max() < 1e-9  # around the axis: k1 = 1/R
    assert np.abs(np.abs(c["direction2"][inner] @ axis) - 1).max() < 1e-9
    np.testing.assert_allclose(np.einsum("ij,ij->i", c["direction1"], c["normal"])[inner], 0, atol=1e-12)


def test_moreton_sequin_on_a_sphere():
    m = surfaces.sample(surfaces.dome(), 17, 17)
    fit = moreton_sequin(m)
    inner = ~m.topology.boundary_vertices
    np.testing.assert_allclose(fit["H"][inner], -1 / SPHERE_R, rtol=1e-3)  # eq. 28's sign: outward normals
    assert fit["rank_ok"][inner].all()
    assert (fit["dH_dt"][inner] < 0).all()


def test_line_curvature_definition_2_33():
    k = line_curvature(cylinder(3, 12, radius=2.0, height=1.0))
    m = cylinder(3, 12, radius=2.0, height=1.0)
    lines = m.topology.structure_lines
    closed = np.repeat(lines.closed, lines.lengths)
    np.testing.assert_allclose(k[closed], 0.5, rtol=1e-12)  # rings: circles of radius 2
    axial = ~closed
    assert np.nanmax(np.abs(k[axial])) < 1e-12 and np.isnan(k[axial]).sum() == 2 * 12  # open ends
    c = curvature(m)
    np.testing.assert_allclose(c["line_max"], 0.5, rtol=1e-12)


def test_curvature_rejects_non_mesh():
    with pytest.raises(InputError, match="mesh: expected a QuadMesh"):
        curvature(np.zeros((3, 3)))
