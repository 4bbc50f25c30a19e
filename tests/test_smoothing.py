import numpy as np
import pytest
import trimesh
from hypothesis import given, strategies as st

from quadnodes.errors import InputError
from quadnodes.mesh import grid
from quadnodes.noise import perturb
from quadnodes.mesh import QuadMesh
from quadnodes.smoothing import SmoothingReport, laplacian, laplacian_operator, step_gain, taubin, taubin_lambda
from quadnodes.topology import fixed_vertices
from meshes import l_shape_with_hole
from strategies import meshes


def _dense_laplacian(mesh, weights="uniform", fixed=None):
    n = mesh.n_vertices
    L = np.zeros((n, n))
    for a, b in mesh.topology.edges:
        c = 1.0 if weights == "uniform" else 1.0 / np.linalg.norm(mesh.vertices[a] - mesh.vertices[b])
        L[a, b] = L[b, a] = c
    if fixed is not None:
        L[fixed] = 0.0
    s = L.sum(axis=1)
    L[s > 0] /= s[s > 0, None]
    L[np.diag_indices(n)] = np.where(s > 0, -1.0, 0.0)
    return L


@pytest.mark.parametrize("weights", ["uniform", "inverse_length"])
def test_operator_equals_dense_reference(weights):
    m, _ = perturb(l_shape_with_hole(), tangential=0.2, seed=0)
    fixed = m.topology.corner_vertices
    np.testing.assert_allclose(laplacian_operator(m, weighting=weights, fixed=fixed).toarray(),
                               _dense_laplacian(m, weights, fixed), atol=1e-15)


@given(meshes(), st.sampled_from(["uniform", "inverse_length"]))
def test_rows_sum_to_zero(mesh, weights):
    L = laplacian_operator(mesh, weighting=weights)
    np.testing.assert_allclose(np.asarray(L.sum(axis=1)).ravel(), 0.0, atol=1e-12)


def test_quad_diagonals_are_not_neighbours():
    L = laplacian_operator(grid(3, 3))
    assert set(L[4].indices.tolist()) == {1, 3, 4, 5, 7}
    # trimesh's filters smooth over the triangulation, where a diagonal is a neighbour
    tm = trimesh.Trimesh(grid(3, 3).vertices, [[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4],
                                               [3, 4, 7], [3, 7, 6], [4, 5, 8], [4, 8, 7]], process=False)
    assert len(tm.vertex_neighbors[4]) > 4


def test_one_step_matches_formula():
    m, _ = perturb(grid(5, 6), tangential=0.3, normal=0.2, seed=1)
    L = _dense_laplacian(m)
    np.testing.assert_allclose(laplacian(m, lam=0.4)[0].vertices, m.vertices + 0.4 * L @ m.vertices, atol=1e-14)
    lam, kpb = 0.5, 0.1
    mu = 1 / (kpb - 1 / lam)
    x = m.vertices + lam * L @ m.vertices
    x = x + mu * L @ x
    np.testing.assert_allclose(taubin(m, lam=lam, k_pb=kpb)[0].vertices, x, atol=1e-14)


def test_fujiwara_weights_are_recomputed_each_step():
    m, _ = perturb(grid(5, 6), tangential=0.3, normal=0.2, seed=1)
    x = m.vertices
    for _ in range(2):
        x = x + 0.5 * _dense_laplacian(m.with_vertices(x), "inverse_length") @ x
    np.testing.assert_allclose(laplacian(m, iterations=2, weighting="inverse_length")[0].vertices, x, atol=1e-13)


@given(meshes(), st.sampled_from(["corners", "boundary"]))
def test_fixed_vertices_never_move(mesh, fix):
    mask = fixed_vertices(mesh, fix)
    for out in (laplacian(mesh, iterations=3, fix=fix)[0], taubin(mesh, iterations=3, fix=fix)[0]):
        assert np.array_equal(out.vertices[mask], mesh.vertices[mask])


def test_laplacian_shrinks_and_taubin_does_not_as_much():
    y, x = np.meshgrid(np.arange(12.0), np.arange(12.0), indexing="ij")
    m = grid(12, 12, height=0.05 * ((x - 5.5) ** 2 + (y - 5.5) ** 2))
    d0 = np.ptp(m.vertices, axis=0)
    dl = np.ptp(laplacian(m, iterations=10)[0].vertices, axis=0)
    dt = np.ptp(taubin(m, iterations=10)[0].vertices, axis=0)
    assert (dl < 0.9 * d0).all()
    assert np.abs(dt / d0 - 1).max() < np.abs(dl / d0 - 1).max()


def test_taubin_lambda_rule():
    for k in (0.05, 0.1, 0.3):
        lam = taubin_lambda(k)
        mu = 1 / (k - 1 / lam)
        f = lambda t: (1 - lam * t) * (1 - mu * t)
        assert f(1) == pytest.approx(-f(2)) and mu < -lam


def test_mask_fixing_and_errors():
    m = grid(4, 4)
    assert fixed_vertices(m, "none", [0, 5]).sum() == 2
    assert laplacian(m, fixed=[5])[1].n_fixed == 1
    with pytest.raises(InputError, match="fix"):
        laplacian(m, fix="edges")
    with pytest.raises(InputError, match="lam"):
        laplacian(m, lam=1.5)[0]
    with pytest.raises(InputError, match="mu"):
        taubin(m, lam=0.5, mu=-0.2)[0]
    with pytest.raises(InputError, match="k_pb"):
        taubin(m, lam=0.5, k_pb=3.0)[0]
    with pytest.raises(InputError, match="weighting"):
        laplacian(m, weighting="cotan")
    with pytest.raises(InputError, match="'weights' was renamed: use weighting"):
        laplacian(m, weights="uniform")
    with pytest.raises(InputError, match="mu: expected a number"):
        taubin(m, mu="x")
    with pytest.raises(InputError, match="iterations"):
        taubin(m, iterations=0)[0]


@pytest.mark.parametrize("fix", ["none", "corners", "boundary"])
@pytest.mark.parametrize("columns", [True, False])  # (3, n) or (n, 3) coordinates
def test_threaded_taubin_equals_dense_steps(monkeypatch, fix, columns):
    from quadnodes.linalg import threads

    monkeypatch.setattr(threads, "COLUMNS_MAX_NNZ", 10**9 if columns else 0)

    m, _ = perturb(grid(30, 40), tangential=0.3, normal=0.1, seed=2)
    fixed = fixed_vertices(m, fix)
    lam, mu = taubin_lambda(0.1), 1.0 / (0.1 - 1.0 / taubin_lambda(0.1))
    L = _dense_laplacian(m, fixed=fixed)
    ref = m.vertices.copy()
    for _ in range(3):
        for f in (lam, mu):
            ref = ref + f * (L @ ref)
    one = taubin(m, iterations=3, fix=fix)[0].vertices
    monkeypatch.setattr(threads, "PARALLEL_MIN_ROWS", 10)
    monkeypatch.setattr(threads, "thread_count", lambda: 3)
    par = taubin(m, iterations=3, fix=fix)[0].vertices
    np.testing.assert_allclose(one, ref, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(par, one)
    assert np.array_equal(par[fixed], m.vertices[fixed])


@pytest.mark.parametrize("lam", [0.75, 1.0])
def test_taubin_refuses_factors_that_blow_the_mesh_up(lam):
    # lam=1 with Taubin's mu multiplied the highest frequency by 3.2 per iteration: 1e9 after 20
    with pytest.raises(InputError, match=r"frequency k=2 \(of 0..2\) by \d"):
        taubin(grid(6, 6), lam=lam, iterations=20)
    with pytest.raises(InputError, match="grow without bound"):
        taubin(grid(6, 6), lam=0.1, mu=-10.0)


@given(st.floats(0.05, 0.7), st.floats(0.01, 0.2))
def test_accepted_taubin_factors_never_amplify_above_the_pass_band(lam, k_pb):
    if k_pb >= 1 / lam:
        return
    mu = 1 / (k_pb - 1 / lam)
    if not mu < -lam:
        return
    try:
        out, rep = taubin(grid(8, 8, height=np.random.default_rng(0).normal(size=(8, 8))), lam=lam, k_pb=k_pb,
                          iterations=50)
    except InputError as exc:
        assert "grow without bound" in str(exc)
        assert step_gain([lam, mu], low=1 / lam + 1 / mu)[0] > 1
        return
    assert rep.gain_max <= 1 + 1e-9
    assert np.abs(out.vertices).max() < 10


@pytest.mark.parametrize("weighting", ["uniform", "inverse_length"])
def test_unused_vertices_are_left_alone(weighting):
    g = grid(4, 4)
    m = QuadMesh(np.vstack([g.vertices, [[9.0, 9.0, 9.0]]]), g.faces)  # the last vertex is in no face
    for out, rep in (laplacian(m, weighting=weighting), taubin(m, weighting=weighting)):
        assert out.vertices[-1].tolist() == [9.0, 9.0, 9.0] and np.isfinite(out.vertices).all()


def test_report_says_what_was_done():
    m, _ = perturb(grid(6, 6), tangential=0.2, seed=3)
    out, rep = taubin(m, iterations=4, fix="boundary")
    assert isinstance(rep, SmoothingReport) and rep.method == "taubin" and rep.iterations == 4
    assert rep.fix == "boundary" and rep.n_fixed == 20 and rep.weighting == "uniform"
    moved = np.linalg.norm(out.vertices - m.vertices, axis=1)
    assert rep.moved_max == pytest.approx(moved.max()) and rep.to_dict()["unit"] == "mm"
