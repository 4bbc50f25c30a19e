"""quadnodes.planarization: planar panels, fixed vertices, scale invariance, errors, the node and STEP."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from quadnodes.errors import InputError
from quadnodes.fairing import fair
from quadnodes.mesh import grid, torus
from quadnodes.noise import perturb
from quadnodes.flatness import diagonal_distance, nonconvex_panels
from quadnodes.planarization import planarize, quad_plane_projection
from quadnodes.zigzag import window_deviation


def hypar(n: int = 8, rise: float = 0.4) -> object:
    """z = rise·x·y on its rulings: every quad is skew."""
    y, x = np.meshgrid(np.linspace(-1, 1, n), np.linspace(-1, 1, n), indexing="ij")
    return grid(n, n, spacing=2.0 / (n - 1), height=rise * x * y)


def _check_quality(before, after, rep, tol=None):
    """The report's quality figures against independent counts; converged exactly when nothing is wrecked."""
    e = before.topology.edges
    ratio = (np.linalg.norm(after.vertices[e[:, 1]] - after.vertices[e[:, 0]], axis=1)
             / np.linalg.norm(before.vertices[e[:, 1]] - before.vertices[e[:, 0]], axis=1))
    assert rep.edge_length_ratio_min == pytest.approx(ratio.min()) and rep.edge_length_ratio_max == pytest.approx(ratio.max())
    new_bad = np.flatnonzero(nonconvex_panels(after) & ~nonconvex_panels(before)).tolist()
    assert rep.nonconvex == new_bad and rep.collapsed_edges == int((ratio < 0.2).sum())
    planar = rep.planarity_max <= rep.tolerance
    assert rep.converged == (planar and not new_bad and rep.collapsed_edges == 0)
    assert (rep.failure == "") == rep.converged
    for q in new_bad[:12]:
        assert str(q) in rep.failure


def test_a_planar_grid_stays_put():
    m = grid(6, 7)
    out, rep = planarize(m)
    assert out is m and rep.converged and rep.iterations == 0 and rep.moved_max == 0.0


def test_a_hyperbolic_paraboloid_becomes_planar_by_bounded_movement():
    m = hypar()
    assert diagonal_distance(m).max() > 0.01
    # corners held, shape="free": planar, but the corner quads turn into darts — not "converged" (issue 16)
    spiky, rep_c = planarize(m, planar_tolerance=1e-4, shape="free")
    assert rep_c.planarity_max <= 1e-4 and not rep_c.converged
    assert rep_c.nonconvex == [0, 6, 42, 48] and "non-convex" in rep_c.failure
    assert np.flatnonzero(nonconvex_panels(spiky)).tolist() == rep_c.nonconvex  # an independent count
    # shape="keep" (the default) prevents the darts: a sound mesh, unconverged, with what to change
    sound, rep_k = planarize(m, planar_tolerance=1e-4)
    _check_quality(m, sound, rep_k)
    assert rep_k.shape == "keep" and rep_k.guarded > 0 and not rep_k.converged
    assert not nonconvex_panels(sound).any() and rep_k.edge_length_ratio_min > 0.25
    assert rep_k.planarity_max < rep_k.planarity_max_before
    assert any("fix='none'" in n for n in rep_k.notes())
    out, rep = planarize(m, planar_tolerance=1e-4, fix="none")
    d = diagonal_distance(out)
    assert rep.converged and d.max() <= 1e-4 and rep.planarity_max == pytest.approx(d.max())
    assert rep.failure == "" and rep.nonconvex == [] and 0.8 < rep.edge_length_ratio_min <= rep.edge_length_ratio_max < 1.1
    h = m.mean_edge_length
    moved = np.linalg.norm(out.vertices - m.vertices, axis=1)
    # it has to move, and not further than the surface's rise (its corners are ±0.4 off the plane z=0)
    assert 0.01 * h < moved.max() <= 0.4 and rep.moved_max == pytest.approx(moved.max())
    assert rep.moved_max == pytest.approx(moved.max())
    # the history is the maximum planarity after every iteration and ends at the result
    assert len(rep.history) == rep.iterations and rep.history[-1] == pytest.approx(d.max())


def test_projection_centres_and_flattens_every_quad():
    m, _ = perturb(hypar(5), tangential=0.1, normal=0.2, seed=3)
    q = quad_plane_projection(m.vertices, m.faces)
    np.testing.assert_allclose(q.sum(axis=1), 0.0, atol=1e-12)
    # every projected quad on its own is flat, and each corner moved by half the diagonal gap
    from quadnodes.flatness import quad_diagonal_distance

    v = q.reshape(-1, 3)
    assert quad_diagonal_distance(v, np.arange(len(v)).reshape(-1, 4)).max() < 1e-12
    centred = m.vertices[m.faces] - m.vertices[m.faces].mean(axis=1, keepdims=True)
    gap = diagonal_distance(m, relative=False)
    np.testing.assert_allclose(np.linalg.norm(centred - q, axis=2), np.repeat(gap[:, None] / 2, 4, axis=1),
                               rtol=1e-9, atol=1e-12)


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 10_000), frac=st.floats(0.05, 0.5))
def test_fixed_vertices_never_move(seed, frac):
    m, _ = perturb(hypar(7), tangential=0.1, normal=0.1, seed=seed)
    rng = np.random.default_rng(seed)
    fixed = rng.random(m.n_vertices) < frac
    stuck = fixed[m.faces].all(axis=1) & (diagonal_distance(m) > 1e-3)
    if stuck.any():  # infeasible from the start: refused, naming the quads (issue 16)
        with pytest.raises(InputError, match=f"\\({int(np.flatnonzero(stuck)[0])}.*all four corners held"):
            planarize(m, fixed=fixed, fix="none", max_iterations=200)
        return
    out, rep = planarize(m, fixed=fixed, fix="none", max_iterations=200)
    _check_quality(m, out, rep)
    np.testing.assert_array_equal(out.vertices[fixed], m.vertices[fixed])
    assert np.isfinite(out.vertices).all()
    assert rep.planarity_max <= rep.planarity_max_before


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 10_000), scale=st.sampled_from([1e-3, 0.5, 7.0, 1e3]))
def test_scale_and_translation_equivariant(seed, scale):
    m, _ = perturb(hypar(6), tangential=0.1, normal=0.1, seed=seed)
    shift = np.array([10.0, -3.0, 2.0])
    m2 = m.with_vertices(scale * m.vertices + shift * scale)
    # a fixed number of steps (a tolerance that is never met, a fixed weight): where a run stops at the
    # tolerance, round-off may decide between two neighbouring iterations
    kw = {"planar_tolerance": 1e-14, "max_iterations": 40, "adapt": False, "method": "local-global"}
    out, rep = planarize(m, **kw)
    out2, rep2 = planarize(m2, **kw)
    assert rep.iterations == rep2.iterations == 40
    np.testing.assert_allclose(out2.vertices, scale * out.vertices + shift * scale, rtol=0, atol=1e-9 * scale)
    assert rep2.planarity_max == pytest.approx(rep.planarity_max, rel=1e-6, abs=1e-12)


def test_fairness_term_keeps_lines_fair():
    # a translational paraboloid: its grid quads are planar, so planarizing the faired noisy mesh should not
    # need to bend the structure lines
    y, x = np.meshgrid(np.linspace(-1, 1, 9), np.linspace(-1, 1, 9), indexing="ij")
    clean = grid(9, 9, spacing=0.25, height=0.3 * (x**2 + 0.5 * y**2))
    m, _ = perturb(clean, tangential=0.15, normal=0.05, seed=1, fix="corners")
    faired, _ = fair(m, iterations=3)
    out, rep = planarize(faired)
    w = faired.topology.windows
    assert rep.converged
    assert window_deviation(out.vertices, w).mean() < 3 * window_deviation(faired.vertices, w).mean() + 1e-4


def test_reference_surface_keeps_vertices_on_it():
    clean = hypar(9)
    noisy, _ = perturb(clean, tangential=0.2, normal=0.1, seed=2, fix="corners")
    faired, _ = fair(noisy, iterations=3)
    # the hypar's grid runs along its rulings (no conjugate net): with its corners held, planar quads would
    # fold (see test_a_hyperbolic_paraboloid...), so the whole mesh may move here
    a, ra = planarize(faired, fix="none")
    b, rb = planarize(faired, reference=clean, fix="none")
    assert ra.reference == "none" and rb.reference == "mesh"
    assert rb.planarity_max <= 1e-3 and rb.converged
    _check_quality(faired, b, rb)
    from quadnodes.metrics import distance_to_mesh

    np.testing.assert_allclose(distance_to_mesh(b.vertices, clean).max(), rb.reference_distance_max, rtol=1e-9)
    assert rb.reference_distance_mean < distance_to_mesh(a.vertices, clean).mean()


def test_boundary_fix_and_corners():
    m, _ = perturb(hypar(7), tangential=0.1, normal=0.1, seed=4)
    out, _ = planarize(m, fix="boundary", max_iterations=300)
    b = m.topology.boundary_vertices
    np.testing.assert_array_equal(out.vertices[b], m.vertices[b])
    out, _ = planarize(m, max_iterations=50)
    c = m.topology.corner_vertices
    np.testing.assert_array_equal(out.vertices[c], m.vertices[c])


def test_unreachable_tolerance_stops_unconverged():
    m = hypar(4)
    fixed = np.ones(m.n_vertices, bool)
    fixed[5] = False  # one free vertex cannot flatten four quads around it and the others
    # quads with all four corners held and non-planar: refused before any iteration, naming them
    with pytest.raises(InputError, match=r"5 quads \(2, 5, 6, 7, 8\) have all four corners held.*at least 0\.0895"):
        planarize(m, fixed=fixed, max_iterations=60)
    fixed = np.zeros(m.n_vertices, bool)
    fixed[[0, 3, 12, 15, 5]] = True  # now every quad has a free vertex, but 5 pins the middle
    out, rep = planarize(m, fixed=fixed, max_iterations=60, method="local-global")
    assert rep.methods_tried == ["local-global"] and rep.iterations <= 60
    _check_quality(m, out, rep)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"planar_tolerance": 0.0}, "planar_tolerance"),
        ({"planar_tolerance": float("nan")}, "planar_tolerance"),
        ({"max_iterations": 0}, "max_iterations"),
        ({"planarity_weight": -1.0}, "planarity_weight"),
        ({"fairness_weight": -0.1}, "fairness_weight"),
        ({"closeness_weight": -0.1}, "closeness_weight"),
        ({"input_weight": -0.1}, "input_weight"),
        ({"fix": "edges"}, "fix"),
        ({"reference": "surface.step"}, "reference"),
        ({"fixed": np.ones(64, bool)}, "every vertex is fixed"),
        ({"closeness_weight": 0.0, "fairness_weight": 0.0, "fix": "none"}, "closeness_weight"),
        ({"adapt": "yes"}, "adapt"),
        ({"method": "shapeup"}, "method"),
        ({"newton_steps": 0}, "newton_steps"),
        ({"shape": "KEEP"}, "shape"),
    ],
)
def test_bad_input_names_the_parameter(kwargs, match):
    with pytest.raises(InputError, match=match):
        planarize(hypar(8), **kwargs)


def test_node_and_step_export_write_planar_faces(tmp_path):
    from build123d import GeomType, import_step

    import quadnodes.nodes  # noqa: F401
    from quadnodes.graph import Graph

    g = Graph(base_dir=tmp_path)
    m = g.add("grid", id="grid", rows=7, cols=7, spacing=1.0)
    noisy = g.add("perturb", m, id="noisy", normal=0.15, seed=5)
    flat = g.add("planarize", noisy.mesh, id="flat", planar_tolerance=1e-4)
    g.add("export_step", flat.mesh, id="step", path="flat.step", planar_tolerance=1e-4)
    res = g.run()
    rep = res["flat.report"]
    assert rep.converged and rep.planarity_max <= 1e-4
    faces = import_step(str(tmp_path / "flat.step")).faces()
    assert len(faces) == 36 and {f.geom_type for f in faces} == {GeomType.PLANE}


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_newton_meets_the_tolerance_with_fixed_vertices_untouched(seed):
    m, _ = perturb(hypar(7), tangential=0.1, normal=0.1, seed=seed)
    out, rep = planarize(m, method="newton", planar_tolerance=1e-4, shape="free")
    assert rep.method == "newton" and rep.newton_steps <= 30 and rep.methods_tried == ["newton"]
    assert diagonal_distance(out).max() <= 1e-4
    _check_quality(m, out, rep)  # planar, but corners held: darts at the corners are reported, not "converged"
    c = m.topology.corner_vertices
    np.testing.assert_array_equal(out.vertices[c], m.vertices[c])
    # shape="keep": every Newton step is shortened so that nothing folds or collapses
    sound, rep_k = planarize(m, method="newton", planar_tolerance=1e-4)
    _check_quality(m, sound, rep_k)
    assert rep_k.nonconvex == [] and rep_k.edge_length_ratio_min >= 0.3 - 1e-12
    np.testing.assert_array_equal(sound.vertices[c], m.vertices[c])


def test_auto_falls_back_to_newton_where_local_global_stalls():
    # a noisy boundary held fixed: the projection iteration stalls near 3e-3 (docs/planarize.md)
    from quadnodes import surfaces

    clean = surfaces.example("E1")
    faired, _ = fair(perturb(clean, tangential=0.25, normal=0.1, seed=7, fix="corners")[0], iterations=3)
    lg, rep_lg = planarize(faired, fix="boundary", method="local-global")
    assert not rep_lg.converged and rep_lg.nonconvex == []
    # Newton reaches the tolerance only by folding two quads next to the held boundary
    nw, rep_nw = planarize(faired, fix="boundary", method="newton", shape="free")
    assert rep_nw.planarity_max <= 1e-3 and rep_nw.nonconvex and not rep_nw.converged
    # auto tries Gauss–Newton early where local/global stagnates, and again from the stalled local/global
    # mesh (issue 15: it would need a kinked line here), then Newton from the input; every method tried is
    # reported, the sound mesh returned — after the missed early attempt local/global went on exactly
    # where it was, so the result is the local/global one to the bit
    out, rep = planarize(faired, fix="boundary", shape="free")
    assert rep.methods_tried == ["local-global", "gauss-newton", "local-global", "gauss-newton", "newton"]
    assert rep.method == "local-global" and rep.nonconvex == []
    lg_free, _ = planarize(faired, fix="boundary", method="local-global", shape="free")
    np.testing.assert_array_equal(out.vertices, lg_free.vertices)
    _check_quality(faired, out, rep)
    assert rep.iterations == rep_lg.iterations  # the local/global iterations it tried first
    b = clean.topology.boundary_vertices
    np.testing.assert_array_equal(out.vertices[b], faired.vertices[b])


_CRASH_SCRIPT = r"""
import sys
import numpy as np
from quadnodes.errors import InputError
from quadnodes.mesh import grid, torus
from quadnodes.noise import perturb
from quadnodes.planarization import planarize
sys.path.insert(0, sys.argv[1])
from meshes import extraordinary_mesh, l_shape_with_hole

outcomes = []
for name, base in [("grid", grid(6, 7)), ("torus", torus(6, 8)), ("lhole", l_shape_with_hole()),
                   ("extraordinary", extraordinary_mesh())]:
    for seed in range(3):
        m, _ = perturb(base, normal=0.2, tangential=0.1, seed=seed, fix="none")
        for method in ("newton", "auto", "local-global"):
            for fix in ("corners", "none"):
                try:
                    out, rep = planarize(m, closeness_weight=0.0, method=method, fix=fix, max_iterations=60,
                                         newton_steps=4)
                    assert np.isfinite(out.vertices).all()
                    outcomes.append("ok")
                except InputError as exc:
                    outcomes.append("refused")
print(len(outcomes), outcomes.count("ok"), outcomes.count("refused"))
"""


def test_zero_closeness_never_crashes_the_interpreter(tmp_path):
    # was SIGSEGV/SIGABRT: a singular KKT matrix factorized without pivoting
    import os
    import subprocess
    import sys
    from pathlib import Path

    script = tmp_path / "crash.py"
    script.write_text(_CRASH_SCRIPT)
    tests = Path(__file__).parent
    paths = [str(tests.parent), *filter(None, [os.environ.get("PYTHONPATH")])]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(paths)}
    res = subprocess.run([sys.executable, str(script), str(tests)], capture_output=True, text=True, timeout=600, env=env)
    assert res.returncode == 0, res.stderr[-2000:]
    total, ok, refused = map(int, res.stdout.split())
    assert total == 72 and ok + refused == total and ok > 0


def test_zero_closeness_without_a_held_vertex_is_refused_with_the_settings():
    m, _ = perturb(torus(6, 8), normal=0.2, seed=1)  # a torus has no corners: nothing holds it
    with pytest.raises(InputError, match=r"closeness_weight=0, input_weight=0, fix='corners': nothing holds"):
        planarize(m, closeness_weight=0.0, method="local-global")


def test_length_tolerance_in_the_mesh_unit():
    clean = grid(6, 6, spacing=1000.0)  # mm
    noisy, _ = perturb(clean, normal=0.05, seed=3)
    out, rep = planarize(noisy, planar_tolerance="0.5 mm")
    assert rep.converged and rep.tolerance_kind == "length" and rep.tolerance == pytest.approx(0.5)
    assert diagonal_distance(out, relative=False).max() <= 0.5 + 1e-9
    assert rep.planarity_max_length <= 0.5 + 1e-9
    same, rep_m = planarize(noisy.with_unit("m"), planar_tolerance="0.5 mm")
    assert rep_m.tolerance == pytest.approx(5e-4) and rep_m.unit == "m"
    with pytest.raises(InputError, match="planar_tolerance"):
        planarize(noisy, planar_tolerance="half a mm")


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), push=st.floats(0.0, 1.5))
def test_kept_shape_projection_is_planar_and_keeps_the_bounds(seed, push):
    from quadnodes.flatness import quad_diagonal_distance
    from quadnodes.planarization import KEPT_CORNER_HEIGHT, KEPT_EDGE_RATIO, kept_shape_projection

    rng = np.random.default_rng(seed)
    rest = hypar(4).vertices
    faces = hypar(4).faces
    x = rest + rng.normal(scale=0.15, size=rest.shape)
    x[5] += push * (x[10] - x[5])  # drive one vertex towards (and past) the opposite corner: darts, bow-ties
    q = kept_shape_projection(x, faces, rest=rest)
    np.testing.assert_allclose(q.sum(axis=1), 0.0, atol=1e-12)
    flat = q.reshape(-1, 3)
    quads = np.arange(len(flat)).reshape(-1, 4)
    assert quad_diagonal_distance(flat, quads).max() < 1e-9
    from quadnodes._validate import corner_turns

    # every target is convex, with no edge far below its kept length
    against, _ = corner_turns(flat, quads)
    assert (against == 0).all()
    l_q = np.linalg.norm(np.roll(q, -1, axis=1) - q, axis=2)
    l_rest = np.linalg.norm(np.roll(rest[faces], -1, axis=1) - rest[faces], axis=2)
    assert (l_q >= 0.9 * KEPT_EDGE_RATIO * l_rest).all()
    # quads that keep their bounds are projected exactly as before (here: the rest shape itself, all convex)
    np.testing.assert_array_equal(kept_shape_projection(rest, faces, rest=rest), quad_plane_projection(rest, faces))
    assert 0 < KEPT_CORNER_HEIGHT < 1 and 0.2 < KEPT_EDGE_RATIO < 1


def test_shape_setting_reaches_the_node(tmp_path):
    import quadnodes.nodes  # noqa: F401
    from quadnodes.graph import Graph

    g = Graph(base_dir=tmp_path)
    m = g.add("grid", id="grid", rows=6, cols=6, spacing=1.0)
    noisy = g.add("perturb", m, id="noisy", normal=0.15, seed=5)
    g.add("planarize", noisy.mesh, id="keep")
    g.add("planarize", noisy.mesh, id="free", shape="free")
    res = g.run()
    assert res["keep.report"].shape == "keep" and res["free.report"].shape == "free"


def test_kept_shape_projection_checks_its_input():
    from quadnodes.planarization import kept_shape_projection

    v = hypar(3).vertices
    f = hypar(3).faces
    with pytest.raises(InputError, match="rest"):
        kept_shape_projection(v, f, rest=v[:-1])
    with pytest.raises(InputError, match="faces"):
        kept_shape_projection(v, f + 100, rest=v)


def _sound(before, after, keep=0.3):
    """No quad convex in ``before`` non-convex in ``after``, no edge below ``keep`` of its length."""
    e = before.topology.edges
    ratio = (np.linalg.norm(after.vertices[e[:, 1]] - after.vertices[e[:, 0]], axis=1)
             / np.linalg.norm(before.vertices[e[:, 1]] - before.vertices[e[:, 0]], axis=1))
    return not (nonconvex_panels(after) & ~nonconvex_panels(before)).any() and ratio.min() >= keep - 1e-12


def test_gauss_newton_meets_the_tolerance_on_a_free_form_sample_in_a_few_steps():
    # a wavy B-spline face sampled 30 × 30 (not a conjugate net): local/global needs ~280 iterations,
    # Gauss–Newton a few steps after its 10 warm-up iterations; sound, corners held, lines as fair
    from quadnodes import surfaces

    face = surfaces.wavy(10000.0, 10000.0, 400.0, waves_u=0.5, waves_v=1.0)
    clean = surfaces.sample(face, 30, 30)
    faired, _ = fair(perturb(clean, tangential=0.25, normal=0.1, seed=7, fix="corners")[0], iterations=3)
    out, rep = planarize(faired, reference=clean, method="gauss-newton")
    assert rep.converged and rep.method == "gauss-newton" and rep.methods_tried == ["local-global", "gauss-newton"]
    assert rep.planarity_max <= 1e-3 and rep.iterations == 10 and 1 <= rep.newton_steps <= 10
    assert _sound(faired, out)
    _check_quality(faired, out, rep)
    c = faired.topology.corner_vertices
    np.testing.assert_array_equal(out.vertices[c], faired.vertices[c])
    w = faired.topology.windows
    assert window_deviation(out.vertices, w).max() <= max(2 * window_deviation(faired.vertices, w).max(), 0.01)
    lg, rep_lg = planarize(faired, reference=clean, method="local-global")
    assert rep_lg.converged and rep_lg.iterations > 10 * (rep.iterations + rep.newton_steps)


def _reference_kernel_settled() -> None:
    """Finish a load of the compiled kernels that an earlier test started (reference.warm_up), so that two
    runs compared bit for bit take the same paths (the closest points agree to the bit; the solver's own
    compiled product does not)."""
    from quadnodes.linalg import compiled

    if compiled._THREAD is not None:
        compiled._THREAD.join()


def test_auto_switches_to_gauss_newton_where_local_global_stagnates():
    # a wavy face sampled 50 × 50: local/global gains < 5 % over three weight doublings from iteration
    # ~15 on (it would need ~330 iterations); auto hands over to Gauss–Newton there and keeps its result,
    # which meets the tolerance soundly
    from quadnodes import surfaces
    from quadnodes.planarization import STALL_DOUBLINGS, STALL_PROGRESS

    face = surfaces.wavy(10000.0, 10000.0, 400.0, waves_u=0.5, waves_v=1.0)
    clean = surfaces.sample(face, 50, 50)
    faired, _ = fair(perturb(clean, tangential=0.25, normal=0.1, seed=7, fix="corners")[0], iterations=3)
    _reference_kernel_settled()
    out, rep = planarize(faired, reference=clean)
    assert rep.converged and rep.method == "gauss-newton" and rep.methods_tried == ["local-global", "gauss-newton"]
    assert rep.iterations <= 60 and rep.planarity_max <= 1e-3 and _sound(faired, out)
    _check_quality(faired, out, rep)
    c = faired.topology.corner_vertices
    np.testing.assert_array_equal(out.vertices[c], faired.vertices[c])
    # the hand-over came at the first weight doubling that met the stagnation test, after the same
    # local/global iterates as method="local-global"
    lg, rep_lg = planarize(faired, reference=clean, method="local-global", max_iterations=rep.iterations)
    h = rep_lg.history
    assert h == rep.history[: rep.iterations] and not rep_lg.converged
    doubled, last = [], 0  # the adaptive weight's rule, replayed on the history
    for it in range(10, len(h) + 1):
        if it - last >= 10 and h[it - 1] > 0.99 * h[it - 10]:
            doubled.append(it)
            last = it
    stalled = [doubled[j] for j in range(STALL_DOUBLINGS, len(doubled))
               if h[doubled[j] - 1] > (1 - STALL_PROGRESS) * h[doubled[j - STALL_DOUBLINGS] - 1]]
    assert stalled == [rep.iterations]


def test_auto_keeps_local_global_where_it_progresses():
    # E2 (13 × 13, not a conjugate net) gains ≥ 13 % over any three weight doublings: auto never tries
    # Gauss–Newton there and returns the local/global result to the bit
    from quadnodes import surfaces

    clean = surfaces.example("E2")
    faired, _ = fair(perturb(clean, tangential=0.25, normal=0.1, seed=7, fix="corners")[0], iterations=3)
    _reference_kernel_settled()
    out, rep = planarize(faired, reference=clean)
    lg, rep_lg = planarize(faired, reference=clean, method="local-global")
    assert rep.converged and rep.methods_tried == ["local-global"]
    np.testing.assert_array_equal(out.vertices, lg.vertices)


def test_gauss_newton_does_not_buy_planarity_with_a_kinked_line():
    # E1 with its noisy boundary held: planar quads there need a sharp bend of the lines next to the
    # boundary (or folds, as Newton makes); Gauss–Newton returns its last iterate without such a kink,
    # unconverged, and auto keeps the flatter sound local/global mesh
    from quadnodes import surfaces

    clean = surfaces.example("E1")
    faired, _ = fair(perturb(clean, tangential=0.25, normal=0.1, seed=7, fix="corners")[0], iterations=3)
    w = faired.topology.windows
    bound = max(2 * window_deviation(faired.vertices, w).max(), 0.01)
    out, rep = planarize(faired, fix="boundary", method="gauss-newton")
    assert not rep.converged and _sound(faired, out)
    assert window_deviation(out.vertices, w).max() <= bound + 1e-12
    _check_quality(faired, out, rep)


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 10_000), noise=st.floats(0.05, 0.3), fix=st.sampled_from(["corners", "boundary", "none"]))
def test_gauss_newton_never_returns_a_folded_quad(seed, noise, fix):
    # whatever it reaches, the accepted steps keep every quad convex and every edge above the shape bound
    m, _ = perturb(hypar(7, rise=0.6), tangential=noise, normal=noise, seed=seed, fix="corners")
    if nonconvex_panels(m).any():
        return  # the bound is stated for quads convex in the input
    out, rep = planarize(m, fix=fix, method="gauss-newton", planar_tolerance=1e-4)
    assert _sound(m, out)
    _check_quality(m, out, rep)
    assert rep.nonconvex == [] and rep.collapsed_edges == 0
    assert rep.planarity_max <= rep.planarity_max_before
    held = m.topology.corner_vertices if fix == "corners" else (
        m.topology.boundary_vertices if fix == "boundary" else np.array([], dtype=np.int64))
    np.testing.assert_array_equal(out.vertices[held], m.vertices[held])


def test_large_meshes_take_the_cg_global_step_with_the_direct_result(monkeypatch):
    # above DIRECT_LIMIT free vertices the global step is CG from the current positions (a factorization
    # of 10⁶ unknowns is out of reach): the same iterates as the factorized step, to the CG tolerance
    import quadnodes.planarization as P

    m, _ = perturb(hypar(9), tangential=0.1, normal=0.1, seed=5)
    direct, rep_d = planarize(m, method="local-global", max_iterations=40, adapt=False)
    monkeypatch.setattr(P, "DIRECT_LIMIT", 10)
    cg, rep_c = planarize(m, method="local-global", max_iterations=40, adapt=False)
    assert rep_c.iterations == rep_d.iterations
    np.testing.assert_allclose(cg.vertices, direct.vertices, rtol=0, atol=1e-6 * m.mean_edge_length)
    # auto tries no fallback there (each Gauss–Newton or Newton step would factorize)
    monkeypatch.setattr(P, "NEWTON_LIMIT", 10)
    _, rep = planarize(m, max_iterations=5)
    assert rep.methods_tried == ["local-global"]
