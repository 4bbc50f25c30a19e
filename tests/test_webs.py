import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from quadnodes.errors import InputError
from quadnodes.mesh import cylinder, grid
from quadnodes.noise import perturb
from quadnodes.topology import fixed_vertices
from quadnodes.webs import fair_web, line_differences, project_to_cylinders, web_energy
from meshes import extraordinary_mesh, l_shape_with_hole
from strategies import grids, irregular


def dense_energy_matrix(mesh, energy, tension, closeness):
    """Q built line by line in plain Python (independent of line_differences)."""
    n = mesh.n_vertices
    Q = np.zeros((n, n))
    for line, closed in zip(mesh.topology.structure_lines, mesh.topology.structure_lines.closed):
        line = list(line)
        L = len(line)
        pairs = [(line[k], line[(k + 1) % L]) for k in range(L if closed else L - 1)]
        triples = [(line[k - 1], line[k], line[(k + 1) % L]) for k in (range(L) if closed else range(1, L - 1))]
        w1 = 1.0 if energy == "E1" else (tension if energy == "tension" else 0.0)
        for a, b in pairs:
            row = np.zeros(n)
            row[a] -= 1
            row[b] += 1
            Q += w1 * np.outer(row, row)
        if energy != "E1":
            for a, b, c in triples:
                row = np.zeros(n)
                row[a] += 1
                row[b] -= 2
                row[c] += 1
                Q += np.outer(row, row)
    return Q + closeness * np.eye(n)


def direct(mesh, Q, hold, closeness):
    x0 = mesh.vertices
    f = np.flatnonzero(~hold)
    b = closeness * x0[f] - Q[np.ix_(f, np.flatnonzero(hold))] @ x0[hold]
    x = x0.copy()
    x[f] = np.linalg.solve(Q[np.ix_(f, f)], b)
    return x


@pytest.mark.parametrize("energy,tension,closeness", [("E1", 0.0, 0.0), ("E2", 0.0, 0.0), ("tension", 0.5, 0.0),
                                                      ("E2", 0.0, 0.3)])
@pytest.mark.parametrize("make", [lambda: perturb(grid(6, 7), tangential=0.2, normal=0.2, seed=1)[0],
                                  lambda: perturb(extraordinary_mesh(), normal=0.1, seed=2)[0],
                                  lambda: perturb(l_shape_with_hole(), normal=0.1, seed=3)[0]])
def test_without_cylinders_equals_direct_solve_of_normal_equations(make, energy, tension, closeness):
    m = make()
    out, rep = fair_web(m, energy=energy, tension=tension, closeness=closeness, fix="boundary")
    hold = fixed_vertices(m, "boundary")
    ref = direct(m, dense_energy_matrix(m, energy, tension, closeness), hold, closeness)
    np.testing.assert_allclose(out.vertices, ref, atol=1e-9 * m.mean_edge_length)
    assert rep.iterations == 0 and rep.energy <= rep.energy_input + 1e-9
    assert rep.n_fixed == int(hold.sum()) and rep.to_dict()["energy_kind"] == energy


def test_closed_lines_wrap():
    c = cylinder(4, 10)
    D1, D2 = line_differences(c)
    assert D1.shape[0] == len(c.topology.edges)
    assert D2.shape[0] == 4 * 10 + 10 * 2  # every ring vertex, plus the middle two of every axial line
    v = c.vertices.copy()
    v[:, :2] *= 1 + 0.05 * (-1) ** np.arange(40)[:, None]
    noisy = c.with_vertices(v)
    out, rep = fair_web(noisy, fix="none", closeness=0.05)
    ref = direct(noisy, dense_energy_matrix(noisy, "E2", 0, 0.05), np.zeros(40, bool), 0.05)
    np.testing.assert_allclose(out.vertices, ref, atol=1e-10)
    assert web_energy(out)["E2"] < web_energy(noisy)["E2"]


def test_huge_cylinders_give_the_unconstrained_minimizer():
    m, _ = perturb(grid(8, 8), tangential=0.2, normal=0.3, seed=4)
    free, _ = fair_web(m)
    big, rep = fair_web(m, cylinder_radius=1e9, cylinder_height=1e9)
    np.testing.assert_array_equal(big.vertices, free.vertices)
    assert rep.cylinders and rep.n_on_cylinder == 0


@pytest.mark.parametrize("solver", ["newton", "admm", "projected_gradient"])
@pytest.mark.parametrize("energy", ["E1", "E2", "tension"])
def test_small_cylinders_hold_every_vertex_and_beat_clipping(solver, energy):
    m, _ = perturb(grid(9, 10, height=np.outer(np.linspace(0, 1, 9), np.linspace(0, 2, 10)) ** 2),
                tangential=0.25, normal=0.2, seed=5)
    h = m.mean_edge_length
    r = np.full(m.n_vertices, 0.15 * h)
    r[::3] = 0.05 * h  # per-vertex sizes
    out, rep = fair_web(m, energy=energy, cylinder_radius=r, cylinder_height=0.1 * h, solver=solver,
                        tolerance=1e-9, max_iterations=20000)
    assert rep.converged
    from quadnodes.discrete_curvature import vertex_normals

    axes = vertex_normals(m.vertices, m.faces)
    inside = project_to_cylinders(out.vertices, m.vertices, axes, r, np.full(m.n_vertices, 0.1 * h))
    assert np.abs(inside - out.vertices).max() <= 1e-12 * h * 100
    assert rep.max_outside <= 1e-9 * h and rep.n_on_cylinder > 0
    # the clipped unconstrained solution is feasible too, and worse
    unc, _ = fair_web(m, energy=energy)
    clipped = project_to_cylinders(unc.vertices, m.vertices, axes, r, np.full(m.n_vertices, 0.1 * h))

    def energy_at(x):
        e = web_energy(m, vertices=x)
        return e["E1"] if energy == "E1" else e["E2"] + (rep.tension * e["E1"] if energy == "tension" else 0)
    assert energy_at(out.vertices) < energy_at(clipped)
    assert abs(energy_at(out.vertices) - rep.energy) <= 1e-9 * max(rep.energy, 1.0)
    assert rep.energy_unconstrained <= rep.energy <= rep.energy_input


def test_solvers_agree():
    m, _ = perturb(grid(8, 9), tangential=0.25, normal=0.25, seed=8)
    a, ra = fair_web(m, cylinder_height=0.05, cylinder_radius=0.1, solver="admm", tolerance=1e-10,
                     max_iterations=50000)
    b, rb = fair_web(m, cylinder_height=0.05, cylinder_radius=0.1, solver="projected_gradient", tolerance=1e-10,
                     max_iterations=50000)
    assert abs(ra.energy - rb.energy) <= 1e-6 * ra.energy
    np.testing.assert_allclose(a.vertices, b.vertices, atol=1e-4)


def test_flat_grid_stays_flat():
    m, _ = perturb(grid(7, 9), tangential=0.3, seed=2)
    assert np.all(m.vertices[:, 2] == 0)
    for kw in ({}, {"energy": "E1"}, {"cylinder_radius": 0.1, "cylinder_height": 0.1}):
        out, _ = fair_web(m, **kw)
        assert np.abs(out.vertices[:, 2]).max() < 1e-12


@settings(max_examples=20)
@given(st.integers(5, 12), st.integers(0, 2**31 - 1))
def test_straight_lines_stay_straight(n, seed):
    rng = np.random.default_rng(seed)
    d = rng.normal(size=3)
    d /= np.linalg.norm(d)
    s = np.sort(rng.uniform(0, n, n))
    s[0], s[-1] = 0.0, float(n)
    s = np.sort(s + np.arange(n))  # distinct, uneven stations along the line
    side = np.cross(d, [0.3, 0.5, 0.8])
    side /= np.linalg.norm(side)
    v = np.vstack([s[:, None] * d, s[:, None] * d + side])
    m = grid(2, n).with_vertices(v)
    out, _ = fair_web(m, fix="corners")
    for row in (out.vertices[:n], out.vertices[n:]):
        rel = row - row[0]
        off = rel - np.outer(rel @ d, d)
        assert np.abs(off).max() < 1e-9 * n


@given(grids(), st.floats(0.2, 50.0), st.lists(st.floats(-100, 100), min_size=3, max_size=3))
def test_translation_and_scale_equivariance(m, s, t):
    h = m.mean_edge_length
    kw = dict(energy="tension", tension=0.3, cylinder_radius=0.2 * h, cylinder_height=0.1 * h, tolerance=1e-10,
              max_iterations=20000)
    out, _ = fair_web(m, **kw)
    moved, _ = fair_web(m.with_vertices(m.vertices + np.array(t)), **kw)
    np.testing.assert_allclose(moved.vertices - np.array(t), out.vertices, atol=1e-6 * (1 + np.abs(t).max()))
    kw_s = {**kw, "cylinder_radius": 0.2 * h * s, "cylinder_height": 0.1 * h * s}
    scaled, _ = fair_web(m.with_vertices(m.vertices * s), **kw_s)
    np.testing.assert_allclose(scaled.vertices / s, out.vertices, atol=1e-6)


@given(irregular())
@settings(max_examples=8)
def test_any_mesh_fixed_vertices_stay(m):
    out, rep = fair_web(m, fix="boundary", cylinder_height=0.05)
    b = m.topology.boundary_vertices
    assert np.array_equal(out.vertices[b], m.vertices[b])
    assert np.isfinite(out.vertices).all() and rep.max_outside < 1e-9


def test_lengths_as_text_and_errors():
    m, _ = perturb(grid(6, 6, spacing=100.0), normal=0.3, seed=1)
    a, _ = fair_web(m, cylinder_height="0.01 m")
    b, _ = fair_web(m, cylinder_height=10.0)
    c, _ = fair_web(m, cylinder_height=np.float32(10.0))
    np.testing.assert_array_equal(a.vertices, b.vertices)
    np.testing.assert_array_equal(c.vertices, b.vertices)
    with pytest.raises(InputError, match="no unique minimum"):
        fair_web(m, fix="none")
    with pytest.raises(InputError, match="energy"):
        fair_web(m, energy="e2")
    with pytest.raises(InputError, match=r"cylinder_radius: expected one number or an array of shape \(36,\)"):
        fair_web(m, cylinder_radius=np.ones(5))
    with pytest.raises(InputError, match="cylinder_height: must be >= 0"):
        fair_web(m, cylinder_height=-1.0)
    with pytest.raises(InputError, match="no unique minimum"):  # lines of the valence-5 star with one fixed end
        fair_web(extraordinary_mesh(1))
    with pytest.raises(InputError, match="every vertex is fixed"):
        fair_web(m, fixed=np.ones(36, bool))


def own_projection(x, c, n, r, h):
    """Cylinder projection written out per vertex (independent of project_to_cylinders)."""
    out = np.empty_like(x)
    for i in range(len(x)):
        d = x[i] - c[i]
        a = d @ n[i]
        t = d - a * n[i]
        tl = np.linalg.norm(t)
        out[i] = c[i] + np.clip(a, -h[i], h[i]) * n[i] + (t * (r[i] / tl) if tl > r[i] else t)
    return out


def cylinder_problem(rows, cols, seed, energy, closeness):
    from quadnodes.discrete_curvature import vertex_normals

    relief = 0.4 * np.outer(np.sin(np.linspace(0, 3, rows)), np.cos(np.linspace(0, 2, cols)))
    m, _ = perturb(grid(rows, cols, height=relief), tangential=0.25, normal=0.15, seed=seed)
    h = m.mean_edge_length
    rng = np.random.default_rng(seed)
    r = 0.3 * h * rng.choice([0.2, 1.0, 5.0], m.n_vertices)  # small, mixed and large cylinders side by side
    hc = 0.1 * h * rng.choice([0.2, 1.0, 5.0], m.n_vertices)
    hold = fixed_vertices(m, "corners")
    Q = dense_energy_matrix(m, energy, 0.5, closeness)
    axes = vertex_normals(m.vertices, m.faces)
    return m, h, r, hc, hold, Q, axes


def force_path(monkeypatch, path):
    """Make ``solver="newton"`` take the contact method (``"contact"``, whatever the share of touching vertices)
    or the primal Newton method (``"primal"``) alone."""
    import quadnodes.webs as webs

    if path == "primal":
        monkeypatch.setattr(webs, "_CONTACT_MAX", 0)
    else:
        monkeypatch.setattr(webs, "_CONTACT_FRACTION", 1.0)
        monkeypatch.setattr(webs, "_CONTACT_STALL", np.inf)
        monkeypatch.setattr(webs, "_CONTACT_ROUNDS", 10_000)


def check_path(rep, path):
    assert (rep.contact_vertices > 0) == (path == "contact") and (rep.warm_start_iterations > 0) == (path == "primal")


@pytest.mark.parametrize("path", ["contact", "primal"])
@pytest.mark.parametrize("energy,closeness", [("E1", 0.0), ("E2", 0.0), ("tension", 0.0), ("E2", 0.2),
                                              ("tension", 0.05)])
def test_kkt_and_scipy_reference(monkeypatch, energy, closeness, path):
    """The Newton result is the constrained minimizer: KKT residual below the tolerance, and equal to SLSQP's —
    by the contact method and by the primal method."""
    from scipy.optimize import minimize

    force_path(monkeypatch, path)
    m, h, r, hc, hold, Q, axes = cylinder_problem(6, 7, 11, energy, closeness)
    out, rep = fair_web(m, energy=energy, tension=0.5, closeness=closeness, fix="corners", cylinder_radius=r,
                        cylinder_height=hc, tolerance=1e-7)
    assert rep.solver == "newton" and rep.converged and rep.kkt_residual <= 1e-7
    if energy != "E1" or closeness:  # (E1 without closeness: ADMM's warm start alone converges on the primal path)
        check_path(rep, path)
    assert rep.max_outside <= 1e-12 * h and rep.projection_move <= 1e-12 * h
    x0 = m.vertices
    f = np.flatnonzero(~hold)
    P = Q[np.ix_(f, f)]
    b = closeness * x0[f] - Q[np.ix_(f, np.flatnonzero(hold))] @ x0[hold]
    c, n, rf, hf = x0[f], axes[f], r[f], hc[f]
    x = out.vertices[f]
    # KKT residual recomputed here: one projected Jacobi step moves nothing by more than 1e-7 h
    step = own_projection(x - (P @ x - b) / P.diagonal().max(), c, n, rf, hf)
    assert np.abs(x - step).max() <= 1.01e-7 * h
    # every vertex inside, and the same point as SciPy's SLSQP with the constraints written out
    assert np.abs(own_projection(x, c, n, rf, hf) - x).max() <= 1e-12 * h

    def fun(v):
        v = v.reshape(-1, 3)
        return 0.5 * np.einsum("ij,ij->", v, P @ v) - np.einsum("ij,ij->", b, v), (P @ v - b).ravel()

    def cons(v):
        d = v.reshape(-1, 3) - c
        a = np.einsum("ij,ij->i", d, n)
        t = d - a[:, None] * n
        return np.concatenate([(hf ** 2 - a ** 2) / h ** 2, (rf ** 2 - np.einsum("ij,ij->i", t, t)) / h ** 2])

    start = own_projection(c, c, n, rf, hf)
    ref = minimize(fun, start.ravel(), jac=True, method="SLSQP", constraints={"type": "ineq", "fun": cons},
                   options={"ftol": 1e-12, "maxiter": 2000})
    # SciPy 1.17's SLSQP may stop at the optimum with status 8 ("positive directional derivative for linesearch")
    # when ftol asks more than its line search resolves; its point, if feasible, is checked below like any other
    assert ref.success or (ref.status == 8 and cons(ref.x).min() >= -1e-9), ref.message
    assert fun(x.ravel())[0] <= ref.fun + 1e-9 * abs(ref.fun)
    np.testing.assert_allclose(x, ref.x.reshape(-1, 3), atol=1e-4 * h)


def test_100x100_converges_within_the_cap():
    """The height field of the speed benchmark at 100 × 100, E2, with mixed cylinders (0.1-10 × 0.5 h / 0.2 h).

    (The other energies and closeness are checked against SLSQP above; they take longer here, not differently.)
    """
    energy, closeness = "E2", 0.0
    n = 100
    y, x = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n), indexing="ij")
    m, _ = perturb(grid(n, n, spacing=1.0 / (n - 1), height=0.3 * np.sin(3 * x) * np.cos(2 * y)), tangential=0.2,
                   normal=0.05, seed=0)
    h = m.mean_edge_length
    rng = np.random.default_rng(1)
    r = 0.5 * h * rng.choice([0.1, 1.0, 10.0], m.n_vertices)
    hc = 0.2 * h * rng.choice([0.1, 1.0, 10.0], m.n_vertices)
    out, rep = fair_web(m, energy=energy, tension=0.5, closeness=closeness, fix="corners", cylinder_radius=r,
                        cylinder_height=hc, max_iterations=50)
    assert rep.converged and rep.iterations <= 50 and rep.kkt_residual <= 1e-5
    assert rep.max_outside <= 1e-12 * h and rep.projection_move <= 1e-12 * h
    assert rep.energy_unconstrained <= rep.energy <= rep.energy_input


@pytest.mark.parametrize("cholmod", [False, True])
def test_nested_dissection_gives_the_same_minimizer(monkeypatch, cholmod):
    """Every factorization in nested-dissection order (forced on a small mesh) reaches the same minimizer as
    minimum degree — through SuperLU, and through CHOLMOD when scikit-sparse is importable."""
    import quadnodes.linalg.direct as direct
    import quadnodes.webs as webs

    if cholmod and not direct.cholmod_available():
        pytest.skip("scikit-sparse not installed")
    if not cholmod:
        monkeypatch.setattr(direct, "_cholmod", lambda: None)
    m, _ = perturb(grid(12, 13), tangential=0.2, normal=0.3, seed=4)
    h = m.mean_edge_length
    kw = dict(energy="E2", fix="corners", cylinder_radius=0.1 * h, cylinder_height=0.05 * h, tolerance=1e-10)
    ref, rep_ref = fair_web(m, **kw)
    monkeypatch.setattr(webs, "NESTED_DISSECTION_MIN", 1)
    calls = []
    real = webs.factorize

    def spy(A, **options):
        f = real(A, **options)
        calls.append(f.order)
        return f

    monkeypatch.setattr(webs, "factorize", spy)
    out, rep = fair_web(m, **kw)
    assert rep.converged and rep_ref.converged and rep.iterations >= 1
    assert "given" in calls  # the vertex order reached the factorizations
    np.testing.assert_allclose(out.vertices, ref.vertices, atol=1e-9 * h)


@pytest.mark.parametrize("cylinders", [(0.5, 0.2), (2.0, 1.0), (0.1, 0.05)])
def test_contact_method_equals_primal_method(monkeypatch, cylinders):
    """On a 16 × 17 height field (E2, corners fixed) with few vertices touching (0.5 h / 0.2 h, 2 h / 1 h) and
    with every one touching (0.1 h / 0.05 h) the contact method and the primal Newton method reach the same
    minimizer, and the default takes the contact method exactly where few touch."""
    import quadnodes.webs as webs

    y, x = np.meshgrid(np.linspace(0, 1, 16), np.linspace(0, 1, 17), indexing="ij")
    m, _ = perturb(grid(16, 17, spacing=1.0 / 15, height=0.3 * np.sin(3 * x) * np.cos(2 * y)), tangential=0.2,
                   normal=0.05, seed=3)
    h = m.mean_edge_length
    kw = dict(energy="E2", fix="corners", cylinder_radius=cylinders[0] * h, cylinder_height=cylinders[1] * h,
              tolerance=1e-9)
    _, default = fair_web(m, **kw)
    out = {}
    for path in ("contact", "primal"):
        with monkeypatch.context() as mp:
            force_path(mp, path)
            out[path], rep = fair_web(m, **kw)
        assert rep.converged and rep.kkt_residual <= 1e-9 and rep.max_outside <= 1e-12 * h
        check_path(rep, path)
    np.testing.assert_allclose(out["contact"].vertices, out["primal"].vertices, atol=1e-8 * h)
    few = default.n_on_cylinder < 0.25 * default.n_free
    assert few == (cylinders[0] > 0.1) and (default.contact_vertices > 0) == few
    assert default.n_on_cylinder <= default.contact_vertices or not few
    assert webs._CONTACT_MAX > 0


def test_contact_method_zero_radius(monkeypatch):
    """A zero radius pins a vertex across its axis (the contact step holds the circumferential direction too)."""
    force_path(monkeypatch, "contact")
    m, _ = perturb(grid(8, 9), tangential=0.3, normal=0.3, seed=5)
    h = m.mean_edge_length
    r = np.full(m.n_vertices, 0.5 * h)
    r[[20, 31]] = 0.0
    out, rep = fair_web(m, energy="E2", fix="corners", cylinder_radius=r, cylinder_height=0.2 * h, tolerance=1e-9)
    assert rep.converged and rep.contact_vertices > 0
    n = vertex_normals_of(m)
    d = out.vertices[[20, 31]] - m.vertices[[20, 31]]
    t = d - np.einsum("ij,ij->i", d, n[[20, 31]])[:, None] * n[[20, 31]]
    assert np.abs(t).max() <= 1e-12 * h
    force_path(monkeypatch, "primal")
    ref, rep_p = fair_web(m, energy="E2", fix="corners", cylinder_radius=r, cylinder_height=0.2 * h, tolerance=1e-9)
    assert rep_p.converged
    np.testing.assert_allclose(out.vertices, ref.vertices, atol=1e-8 * h)


def vertex_normals_of(m):
    from quadnodes.discrete_curvature import vertex_normals

    return vertex_normals(m.vertices, m.faces)


@pytest.mark.parametrize("cylinders", ["small", "mixed"])
def test_primal_steps_reuse_a_factorization(monkeypatch, cylinders):
    """Where most vertices touch (the primal path), the Newton steps that reuse a factorization as the
    preconditioner of conjugate gradients reach the minimizer the steps with a factorization each reach:
    the same point (to 1e-8 h, tolerance 1e-9 h), both with a KKT residual — recomputed here with this
    file's own projection — below the tolerance, and with fewer factorizations than steps."""
    import quadnodes.webs as webs

    n = 24
    y, x = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n + 1), indexing="ij")
    m, _ = perturb(grid(n, n + 1, spacing=1.0 / (n - 1), height=0.3 * np.sin(3 * x) * np.cos(2 * y)),
                   tangential=0.2, normal=0.05, seed=6)
    h = m.mean_edge_length
    if cylinders == "small":
        r, hc = np.full(m.n_vertices, 0.1 * h), np.full(m.n_vertices, 0.05 * h)
    else:  # the benchmark's mixed cylinders: 0.1, 1 or 10 × 0.5 h / 0.2 h per vertex
        rng = np.random.default_rng(1)
        r = 0.5 * h * rng.choice([0.1, 1.0, 10.0], m.n_vertices)
        hc = 0.2 * h * rng.choice([0.1, 1.0, 10.0], m.n_vertices)
    kw = dict(energy="E2", fix="corners", cylinder_radius=r, cylinder_height=hc, tolerance=1e-9)
    out, rep = fair_web(m, **kw)
    assert rep.contact_vertices == 0 and rep.warm_start_iterations > 0  # the default took the primal path
    assert rep.n_on_cylinder > 0.4 * rep.n_free
    assert rep.converged and 1 <= rep.factorizations < rep.iterations
    with monkeypatch.context() as mp:
        mp.setattr(webs, "_REUSE_SWITCHES", -1)  # every step factorizes its own system (the method before reuse)
        ref, rep_ref = fair_web(m, **kw)
    assert rep_ref.converged and rep_ref.factorizations == rep_ref.iterations
    np.testing.assert_allclose(out.vertices, ref.vertices, atol=1e-8 * h)
    hold = fixed_vertices(m, "corners")
    Q = dense_energy_matrix(m, "E2", 0.0, 0.0)
    f = np.flatnonzero(~hold)
    P = Q[np.ix_(f, f)]
    b = -Q[np.ix_(f, np.flatnonzero(hold))] @ m.vertices[hold]
    c, ax, xf = m.vertices[f], vertex_normals_of(m)[f], out.vertices[f]
    for v, report in ((xf, rep), (ref.vertices[f], rep_ref)):
        step = own_projection(v - (P @ v - b) / P.diagonal().max(), c, ax, r[f], hc[f])
        assert np.abs(v - step).max() <= 1.01e-9 * h and report.kkt_residual <= 1e-9
        assert np.abs(own_projection(v, c, ax, r[f], hc[f]) - v).max() <= 1e-12 * h
    assert rep.energy == pytest.approx(rep_ref.energy, rel=1e-10)


def test_step_solver_falls_back_to_a_factorization():
    """``_StepSolver``: a system far from the factorized one (CG would not converge within its cap) is
    factorized anew; a nearby one is solved by preconditioned CG to the asked accuracy."""
    import scipy.sparse as sp

    import quadnodes.webs as webs

    rng = np.random.default_rng(0)
    k = 60
    L = sp.diags([-np.ones(k - 1), 2.0 * np.ones(k), -np.ones(k - 1)], [-1, 0, 1], format="csc")
    A = (L @ L + 1e-6 * sp.identity(k)).tocsc()
    keys = np.arange(k)
    s = webs._StepSolver(None, 1e-10)
    rhs = rng.standard_normal(k)
    np.testing.assert_allclose(s.solve(A, rhs, keys, keys, 1.0, np.zeros(k)), np.linalg.solve(A.toarray(), rhs), rtol=1e-9)
    assert s.factorizations == 1
    near = (A + sp.diags(1e-3 * rng.random(k))).tocsc()
    y = s.solve(near, rhs, keys, keys, 1.0, np.zeros(k))
    assert s.factorizations == 1 and s.cg_iterations >= 1
    exact = np.linalg.solve(near.toarray(), rhs)
    assert np.abs(y - exact).max() <= 1e-8 * np.abs(exact).max()
    far = (A + sp.diags(rng.random(k) * 4.0)).tocsc()  # a new system: no longer like the factorized one
    y = s.solve(far, rhs, keys, keys, 1.0, np.zeros(k))
    assert s.factorizations == 2
    np.testing.assert_allclose(y, np.linalg.solve(far.toarray(), rhs), rtol=1e-9)
    # unknowns the factorized system lacks (a slab that switched) are preconditioned by their diagonal
    sub = far[:-2][:, :-2].tocsc()
    y = s.solve(sub, rhs[:-2], keys[2:], keys[2:], 1.0, np.zeros(k - 2))
    assert np.abs(y - np.linalg.solve(sub.toarray(), rhs[:-2])).max() <= 1e-9  # 10 × the accuracy asked for


def test_a_vertex_in_no_face_stays_and_is_no_unanchored_part():
    # it was refused: "some part of the structure-line network has no fixed vertex"
    noisy, _ = perturb(grid(8, 8), tangential=0.2, seed=1)
    stray = noisy.__class__(np.vstack([noisy.vertices, [[50.0, 50.0, 50.0]]]), noisy.faces)
    a, ra = fair_web(noisy)
    b, rb = fair_web(stray)
    assert np.array_equal(b.vertices[-1], [50.0, 50.0, 50.0])
    assert np.allclose(b.vertices[:-1], a.vertices, atol=1e-9 * noisy.mean_edge_length)
