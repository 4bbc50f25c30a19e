"""The line-end term (quadnodes.line_ends): properties of the ring rows, detection, and what fair does with them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from quadnodes.fairing import _line_end_pairs, fair
from quadnodes.errors import InputError
from quadnodes.io import load
from quadnodes.line_ends import (LINE_END_MARGIN, RING_SCALE, line_end_arms, line_end_energy, line_end_free, line_end_measure,
                                 line_end_rows, ring_arms, turning_matrix)
from quadnodes.mesh import QuadMesh, cylinder, grid, torus
from quadnodes.noise import perturb
from quadnodes.topology import fixed_vertices
from meshes import extraordinary_mesh
from strategies import irregular, meshes

DATA = Path(__file__).parent / "data"


def _star(k: int, radius: float, turn: float) -> QuadMesh:
    """A planar regular star: one interior vertex of valence ``k`` with ``k`` quads around it."""
    a = turn + 2 * np.pi * np.arange(2 * k) / (2 * k)
    r = np.where(np.arange(2 * k) % 2 == 0, radius, radius / np.cos(np.pi / k) if k > 2 else radius)
    ring = np.stack([r * np.cos(a), r * np.sin(a), np.zeros(2 * k)], axis=1)
    v = np.vstack([[0.0, 0.0, 0.0], ring])
    faces = [[0, 1 + 2 * i, 2 + 2 * i, 1 + (2 * i + 2) % (2 * k)] for i in range(k)]
    return QuadMesh(v, np.array(faces))


@given(st.integers(3, 8), st.floats(0.1, 100.0), st.floats(0.0, 6.3))
def test_a_regular_star_costs_nothing_at_any_valence(k, radius, turn):
    m = _star(k, radius, turn)
    t = turning_matrix(m.vertices, ring_arms(m.topology)) @ m.vertices
    assert np.abs(t[0]).max() < 1e-9 * radius  # the centre's mean turning: k unit arms evenly spread
    # so an extraordinary vertex in the middle of a regular star feels no pull (unlike a line continued through it):
    # the centre's row of the turning matrix, applied to any in-plane move of the centre alone, is first order
    d = np.zeros_like(m.vertices)
    d[0] = [1e-3 * radius, 0, 0]
    assert np.linalg.norm((turning_matrix(m.vertices, ring_arms(m.topology)) @ (m.vertices + d))[0]) > 0


@given(irregular(), st.sampled_from(["fair", "hold"]), st.floats(1e-3, 1e3), st.integers(0, 2**31 - 1))
def test_rows_are_invariant_under_translation_rotation_and_scale(mesh, spacing, scale, seed):
    t = mesh.topology
    pairs = line_end_arms(t, ~t.window_middle)
    R = line_end_rows(mesh.vertices, t, pairs, line_spacing=spacing)
    assert np.allclose(np.asarray(R.sum(axis=1)).ravel(), 0.0, atol=1e-9)  # each row sums to zero
    q, _ = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    moved = scale * mesh.vertices @ q.T + np.array([3.0, -2.0, 7.0])
    e0 = line_end_energy(mesh.vertices, t, pairs, line_spacing=spacing)
    e1 = line_end_energy(moved, t, pairs, line_spacing=spacing)  # dimensionless, like the window term
    assert e1 == pytest.approx(e0, rel=1e-8, abs=1e-12)
    m0 = line_end_measure(mesh.vertices, t, pairs, line_spacing=spacing)
    m1 = line_end_measure(moved, t, pairs, line_spacing=spacing)
    np.testing.assert_allclose(m1, m0, rtol=1e-8, atol=1e-12)


def _closed_or_loose(kind: str, rows: int, cols: int) -> QuadMesh:
    """A cylinder or torus grid, or a grid with a vertex in no face (first or last)."""
    if kind == "cylinder":
        return cylinder(rows, cols)
    if kind == "torus":
        return torus(rows, cols)
    g = grid(rows, cols)
    loose = np.array([[0.5, 0.5, 9.0]])
    if kind == "loose first":
        return QuadMesh(np.vstack([loose, g.vertices]), g.faces + 1)
    return QuadMesh(np.vstack([g.vertices, loose]), g.faces)


_ARM_MESHES = st.one_of(meshes(), st.builds(_closed_or_loose, st.sampled_from(["cylinder", "torus", "loose first",
                                                                               "loose last"]),
                                            st.integers(3, 7), st.integers(3, 8)))


@given(_ARM_MESHES, st.integers(0, 2**31 - 1), st.floats(0.0, 1.0))
def test_the_arms_of_some_vertices_are_those_rows_of_the_whole_ring(mesh, seed, share):
    t = mesh.topology
    rng = np.random.default_rng(seed)
    where = rng.random(mesh.n_vertices) < share
    whole = ring_arms(t)
    some = ring_arms(t, where)
    assert some.dtype == np.int64
    np.testing.assert_array_equal(some, whole[where[whole[:, 0]]])  # the same rows, in the same order
    np.testing.assert_array_equal(ring_arms(t, np.flatnonzero(where)), some)  # indices as a mask
    # line_end_arms on any selection: what the whole ring gave (its arms at no corner, each edge once)
    for marked in (where, ~t.window_middle):
        a = whole[marked[whole[:, 0]] & ~t.corner_vertices[whole].any(axis=1)]
        expected = np.unique(np.sort(a, axis=1), axis=0) if len(a) else np.empty((0, 2), np.int64)
        np.testing.assert_array_equal(line_end_arms(t, marked), expected)
    # and the turning rows built from them: the whole ring's rows of the pairs' vertices
    pairs = line_end_arms(t, where)
    if len(pairs):
        used = np.zeros(mesh.n_vertices, bool)
        used[pairs.reshape(-1)] = True
        R = line_end_rows(mesh.vertices, t, pairs)
        T = turning_matrix(mesh.vertices, whole[used[whole[:, 0]]])
        i, j = pairs[:, 0], pairs[:, 1]
        expected = 0.5 * RING_SCALE * (T[i] - T[j])
        np.testing.assert_allclose(R.toarray(), expected.toarray(), rtol=1e-13, atol=1e-13)


def test_the_arms_refuse_a_malformed_vertex_selection():
    t = grid(3, 3).topology
    for bad, what in ((np.ones(4, bool), "shape"), ([9], "range"), (np.ones(9, int), "zeros and ones"),
                      (np.ones(9), "dtype")):
        with pytest.raises(InputError, match="where"):
            ring_arms(t, bad)
        with pytest.raises(InputError, match="where"):
            line_end_arms(t, bad)


@given(irregular())
def test_the_turning_of_a_line_vertex_is_the_line_turning(mesh):
    # k = 2 arms with their own lengths: t = u1 - u0, the turning vector of eq. 30
    t = mesh.topology
    arms = ring_arms(t)
    T = turning_matrix(mesh.vertices, arms, line_spacing="hold") @ mesh.vertices
    k = np.bincount(arms[:, 0], minlength=mesh.n_vertices)
    v = np.flatnonzero(k == 2)
    for i in v[:5]:
        a, b = arms[arms[:, 0] == i, 1]
        ua = mesh.vertices[a] - mesh.vertices[i]
        ub = mesh.vertices[b] - mesh.vertices[i]
        np.testing.assert_allclose(T[i], ua / np.linalg.norm(ua) + ub / np.linalg.norm(ub), atol=1e-12)


def test_arms_to_boundary_corners_get_no_term():
    t = grid(5, 5).topology
    pairs = line_end_arms(t, np.ones(25, bool))
    assert not t.corner_vertices[pairs].any()
    assert len(line_end_arms(t, np.zeros(25, bool))) == 0


def test_detection_frees_found_line_ends_and_their_arm_neighbours_only():
    m = extraordinary_mesh(2)
    t = m.topology
    pairs = _line_end_pairs(t)
    none = np.zeros(m.n_vertices, bool)
    held = t.boundary_vertices
    assert not line_end_free(m.vertices, t, pairs, none, held, 0.03).any()  # clean: nothing found
    noisy, _ = perturb(m, tangential=0.25, seed=1, fix="boundary")
    found = line_end_measure(noisy.vertices, t, pairs) > LINE_END_MARGIN * 0.03
    free = line_end_free(noisy.vertices, t, pairs, none, held, 0.03)
    assert (free >= (found & ~held)).all() and not (free & held).any()
    # every freed vertex that was not found has a found (or free) neighbour along an arm
    extra = np.flatnonzero(free & ~found)
    for v in extra:
        nb = np.r_[pairs[pairs[:, 0] == v, 1], pairs[pairs[:, 1] == v, 0]]
        assert (found | free)[nb].any()


def test_every_clean_real_mesh_is_left_untouched():
    for name in ("polygon_quads.obj", "rounded_box.obj"):
        m = load(DATA / name)
        out, rep = fair(m, iterations=3)
        assert out is m and rep.effective_iterations == 0


@pytest.mark.parametrize("kind, amp, ratio", [("tangential", 0.25, 0.45), ("normal", 0.2, 0.55), ("jitter", 0.2, 0.75)])
def test_short_lines_are_faired(kind, amp, ratio):
    # polygon_quads: 464 of 528 lines have three vertices; before the line-end term fair kept 85-98 % of the error
    m = load(DATA / "polygon_quads.obj")
    noisy, _ = perturb(m, seed=0, fix="corners", **{kind: amp})
    before = np.linalg.norm(noisy.vertices - m.vertices, axis=1).mean()
    out, _ = fair(noisy)
    after = np.linalg.norm(out.vertices - m.vertices, axis=1).mean()
    hold, _ = fair(noisy, extraordinary="hold")
    kept = np.linalg.norm(hold.vertices - m.vertices, axis=1).mean()
    assert after < ratio * before and after < 0.8 * kept


@settings(max_examples=20)
@given(irregular(), st.sampled_from(["alternating", "thesis"]))
def test_the_term_moves_only_free_vertices_and_never_raises_the_energy(mesh, detection):
    out, rep = fair(mesh, iterations=2, detection=detection)
    assert np.isfinite(out.vertices).all()
    for r in rep.iterations:
        assert r.energy_after <= r.energy_before * (1 + 1e-12) + 1e-15
    held = fixed_vertices(mesh, "corners")
    np.testing.assert_array_equal(out.vertices[held], mesh.vertices[held])
    # the thesis's triple moves no vertex that is no window's middle
    thesis, _ = fair(mesh, iterations=2, extraordinary="hold", detection="thesis", line_spacing="hold")
    still = ~mesh.topology.window_middle
    np.testing.assert_array_equal(thesis.vertices[still], mesh.vertices[still])
