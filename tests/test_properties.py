"""Every public function, random valid and invalid meshes and settings: only quadnodes' own errors,
never a NaN in an output, fixed vertices never move (issue 12)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import quadnodes as qn
from quadnodes.errors import QuadnodesError
from quadnodes.mesh import QuadMesh, cylinder, grid, torus
from meshes import extraordinary_mesh, l_shape_with_hole
from strategies import grids

#: Values a careless caller might pass for any setting.
JUNK = st.sampled_from([
    -1, 0, 1, 2, 10**7, 2**63 - 1, -0.5, 0.0, 1e-300, 1e300, math.nan, math.inf, -math.inf, True, False,
    "", "x", "NONE", "corners", "boundary", None, [], [0.1], [-1.0, 2.0], {}, (1, 2), b"bytes",
])
NOT_MESHES = st.sampled_from([None, 3, "mesh.obj", np.zeros((4, 3)), [[0, 0, 0]], (grid(3, 3), None)])


@st.composite
def any_mesh(draw) -> QuadMesh:
    kind = draw(st.sampled_from(["grid", "cylinder", "torus", "extraordinary", "lhole", "unused"]))
    if kind == "grid":
        return draw(grids(min_size=3, max_size=7))
    if kind == "unused":  # a vertex in no face
        g = grid(4, 5)
        return QuadMesh(np.vstack([g.vertices, [[7.0, 7.0, 7.0]]]), g.faces)
    base = {"cylinder": cylinder(4, 6), "torus": torus(4, 6), "extraordinary": extraordinary_mesh(),
            "lhole": l_shape_with_hole()}[kind]
    seed = draw(st.integers(0, 1000))
    return qn.perturb(base, tangential=0.15, normal=0.05, seed=seed, fix="none")[0]


def _call(fn, *args, **kwargs):
    """Run ``fn``; any exception but quadnodes' own fails the test. Returns the result or None."""
    try:
        return fn(*args, **kwargs)
    except QuadnodesError:
        return None


def _finite(value) -> None:
    if isinstance(value, QuadMesh):
        assert np.isfinite(value.vertices).all()
    elif isinstance(value, np.ndarray) and value.dtype.kind == "f":
        assert not np.isnan(value).any()
    elif isinstance(value, dict):
        for v in value.values():
            _finite(v)
    elif isinstance(value, (tuple, list)):
        for v in value:
            _finite(v)


#: (function, the settings it takes and whether the result's first item is a mesh whose fixed vertices stay)
METHODS = {
    "fair": (qn.fair, ["iterations", "threshold", "threshold_decay", "weight", "weight_decay", "weight_scale",
                       "anchor", "fix", "fixed", "solver"]),
    "laplacian": (qn.laplacian, ["iterations", "lam", "weighting", "fix", "fixed"]),
    "taubin": (qn.taubin, ["iterations", "lam", "k_pb", "mu", "weighting", "fix", "fixed"]),
    "perturb": (qn.perturb, ["tangential", "normal", "jitter", "seed", "fix", "fixed", "region"]),
    "planarize": (qn.planarize, ["planar_tolerance", "max_iterations", "planarity_weight", "fairness_weight",
                                 "closeness_weight", "input_weight", "fix", "fixed", "adapt", "anderson",
                                 "method", "newton_steps"]),
    "detect": (qn.detect, ["threshold", "fix", "fixed"]),
}
SMALL = {"iterations": 2, "max_iterations": 30, "newton_steps": 3}


@pytest.mark.parametrize("name", sorted(METHODS))
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mesh=any_mesh(), data=st.data())
def test_random_settings_give_a_result_or_a_quadnodes_error(name, mesh, data):
    fn, names = METHODS[name]
    chosen = data.draw(st.lists(st.sampled_from(names), max_size=3, unique=True))
    kwargs = {k: data.draw(JUNK) for k in chosen}
    for k, v in SMALL.items():  # keep valid runs short
        if k in names and k not in kwargs:
            kwargs[k] = v
    if kwargs.get("iterations") in (10**7, 2**63 - 1) and name != "detect":
        kwargs["iterations"] = 10**7  # refused up front, never run
    out = _call(fn, mesh, **kwargs)
    if out is None:
        return
    _finite(out)
    result = out[0] if isinstance(out, tuple) else None
    if isinstance(result, QuadMesh):
        fix = kwargs.get("fix", "corners" if name in ("fair", "perturb", "planarize", "detect") else "none")
        held = qn.topology.fixed_vertices(mesh, fix, kwargs.get("fixed")) if isinstance(fix, str) else None
        if held is not None:
            assert np.array_equal(result.vertices[held], mesh.vertices[held])


@pytest.mark.parametrize("fn", [qn.fair, qn.laplacian, qn.taubin, qn.perturb, qn.planarize, qn.detect,
                                qn.planarity, qn.structure_lines])
@settings(max_examples=6, deadline=None)
@given(thing=NOT_MESHES)
def test_something_other_than_a_mesh_is_a_clear_error(fn, thing):
    with pytest.raises(QuadnodesError, match="expected a QuadMesh"):
        fn(thing)


@settings(max_examples=25, deadline=None)
@given(mesh=any_mesh(), other=any_mesh(), thresholds=st.lists(JUNK, max_size=3))
def test_compare_and_measures(mesh, other, thresholds):
    out = _call(qn.compare, mesh, other, thresholds=thresholds)
    if out is not None:
        assert mesh.faces.shape == other.faces.shape and all(np.isfinite(v) for v in out.values())
    _finite(qn.planarity(mesh))
    w = qn.windows(qn.structure_lines(mesh))
    assert w.ndim == 2 and w.shape[1] == 4 and (w < mesh.n_vertices).all()


@settings(max_examples=40, deadline=None)
@given(vertices=st.lists(st.lists(st.sampled_from([0.0, 1.0, -1.0, 0.5, 1e-12, math.nan, math.inf, 1e308]),
                                  min_size=3, max_size=3), min_size=3, max_size=8),
       faces=st.lists(st.lists(st.integers(-2, 9), min_size=3, max_size=5), min_size=0, max_size=4))
def test_random_arrays_make_a_mesh_or_a_clear_error(vertices, faces):
    m = _call(QuadMesh, vertices, faces)
    if m is not None:
        assert np.isfinite(m.vertices).all() and m.faces.shape[1] == 4
        _call(qn.fair, m, iterations=1, threshold=0.0)
