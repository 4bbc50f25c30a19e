"""Registry, @node registration, setting coercion and describe."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from quadnodes.errors import GraphError
from quadnodes.graph import Registry, describe, node


def test_lookup_latest_and_pinned_versions():
    r = Registry()

    @node("inc", version=1, registry=r)
    def inc1(x: float) -> float:
        return x + 1

    @node("inc", version=2, registry=r)
    def inc2(x: float, *, step: float = 1.0) -> float:
        return x + step

    assert r.get("inc").op == "inc@2"
    assert r.get("inc@1").func is inc1
    assert r.get(inc2) is inc2.node_type
    assert inc1(1.0) == 2.0  # the decorator returns the plain function
    assert r.ops() == ["inc@1", "inc@2"]
    assert "inc@1" in r and "inc@3" not in r
    with pytest.raises(GraphError, match=r"unknown version 3 of op 'inc' \(registered: 1, 2\)"):
        r.get("inc@3")
    with pytest.raises(GraphError, match=r"unknown op 'icn'; did you mean 'inc'\?"):
        r.get("icn")
    with pytest.raises(GraphError, match="expected 'name' or 'name@version'"):
        r.get("inc@x")


def test_reregistering_another_function_is_refused_but_a_reload_replaces():
    r = Registry()

    def make():
        @node("f", registry=r)
        def f(x: float) -> float:
            return x

        return f

    first = make()
    second = make()  # same module and qualname: a reload
    assert r.get("f").func is second and first is not second

    with pytest.raises(GraphError, match="'f@1' is already registered"):
        @node("f", registry=r)
        def other(x: float) -> float:
            return x


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda r: node("g", registry=r)(lambda *xs: 0), r"\*args/\*\*kwargs"),
        (lambda r: node("1bad", registry=r)(lambda x: x), "expected a Python identifier"),
        (lambda r: node("g", version=0, registry=r)(lambda x: x), "positive int"),
        (lambda r: node("g", reads=("pth",), registry=r)(_reader), r"reads names 'pth'.*did you mean 'path'"),
        (lambda r: node("g", outputs=("a", "a"), registry=r)(lambda x: x), "not a unique Python identifier"),
    ],
)
def test_registration_errors(make, message):
    with pytest.raises(GraphError, match=message):
        make(Registry())


def _reader(*, path: Path) -> str:
    return str(path)


def test_setting_annotation_must_be_a_file_value():
    with pytest.raises(GraphError, match=r"setting 'm': ndarray is not a JSON/TOML value; make it an input port"):
        @node("g", registry=Registry())
        def g(x: float, *, m: np.ndarray = None) -> float:  # noqa: RUF013
            return x


def test_default_must_fit_annotation():
    with pytest.raises(GraphError, match=r"setting 'n': default 'three' does not fit int"):
        @node("g", registry=Registry())
        def g(x: float, *, n: int = "three") -> float:
            return x


def test_unresolvable_annotation_is_a_graph_error():
    with pytest.raises(GraphError, match="cannot resolve the annotations"):
        @node("g", registry=Registry())
        def g(x: "NoSuchType") -> float:  # noqa: F821
            return 1.0


def test_id_is_a_reserved_parameter_name():
    with pytest.raises(GraphError, match="'id' is reserved"):
        @node("g", registry=Registry())
        def g(*, id: int = 1) -> float:  # noqa: A002
            return 1.0


def test_ports_and_settings_from_the_signature(reg):
    nt = reg.get("add")
    assert [(p.name, p.required) for p in nt.inputs] == [("a", True), ("b", False)]
    nt = reg.get("stats")
    assert [(p.name, p.type_name) for p in nt.outputs] == [("zmax", "float"), ("n", "int")]
    nt = reg.get("read_num")
    assert nt.reads == ("path",) and nt.writes == ()
    assert reg.get("zoo").setting("req").required


@pytest.mark.parametrize(
    ("name", "value", "expected"),
    [
        ("i", 3, 3),
        ("i", 3.0, 3),
        ("i", np.int64(4), 4),
        ("f", 2, 2.0),
        ("f", np.float32(0.5), 0.5),
        ("b", True, True),
        ("s", "x", "x"),
        ("mode", "cotan", "cotan"),
        ("fl", [1, 2.5], [1.0, 2.5]),
        ("fl", (1, 2), [1.0, 2.0]),
        ("fl", np.array([1.0, 2.0]), [1.0, 2.0]),
        ("ff", 3, 3.0),
        ("ff", [0.1, 0.05], [0.1, 0.05]),
        ("t", [1, 2], (1.0, 2.0)),
        ("opt", None, None),
        ("opt", 5, 5),
        ("p", "a/b.obj", Path("a/b.obj")),
        ("p", None, None),
    ],
)
def test_coercion(reg, name, value, expected):
    got = reg.get("zoo").coerce_setting(name, value, node_id="z1")
    assert got == expected and type(got) is type(expected)


@pytest.mark.parametrize(
    ("name", "value", "message"),
    [
        ("i", 2.5, r"setting 'i': expected int, got float 2.5"),
        ("i", True, r"setting 'i': expected int, got bool True"),
        ("i", "3", r"setting 'i': expected int, got str '3'"),
        ("f", "0.1", r"setting 'f': expected float, got str '0.1'"),
        ("b", 1, r"setting 'b': expected bool"),
        ("s", 3, r"setting 's': expected str"),
        ("mode", "cotangent", r"setting 'mode': expected one of 'uniform', 'cotan', got str 'cotangent'; did you mean 'cotan'\?"),
        ("fl", [0.1, "x"], r"setting 'fl'\[1\]: expected float, got str 'x'"),
        ("fl", 0.1, r"setting 'fl': expected list\[float\], got float 0.1"),
        ("ff", "x", r"setting 'ff': expected float \| list\[float\], got str 'x'"),
        ("t", [1, 2, 3], r"setting 't': expected tuple\[float, float\] \(2 items\), got 3 items"),
        ("opt", 1.5, r"setting 'opt': expected int \| None"),
        ("p", 3, r"setting 'p': expected Path \| None"),
    ],
)
def test_wrong_type_names_node_and_setting(reg, name, value, message):
    with pytest.raises(GraphError, match=r"^node 'z1' \(zoo@1\): " + message):
        reg.get("zoo").coerce_setting(name, value, node_id="z1")


def test_misspelled_setting_suggests_the_closest(reg):
    with pytest.raises(GraphError) as e:
        reg.get("scale").resolve_settings({"factr": 3}, node_id="s1")
    assert str(e.value) == "node 's1' (scale@1): unknown setting 'factr'; did you mean 'factor'? (settings: factor)"
    with pytest.raises(GraphError, match="'x' is an input port, not a setting"):
        reg.get("scale").resolve_settings({"x": 3}, node_id="s1")


def test_missing_required_setting(reg):
    with pytest.raises(GraphError, match=r"node 'z' \(zoo@1\): missing required setting 'req' \(int\)"):
        reg.get("zoo").resolve_settings({}, node_id="z")
    s = reg.get("zoo").resolve_settings({"req": 1}, node_id="z")
    assert s["fl"] == [0.1] and s["mode"] == "uniform" and s["p"] is None


def test_describe(reg):
    d = describe("zoo", registry=reg)
    assert d["op"] == "zoo@1" and d["summary"] == "Every kind of setting."
    by_name = {s["name"]: s for s in d["settings"]}
    assert by_name["req"] == {"name": "req", "type": "int", "required": True, "file": None, "range": None,
                              "doc": ""}
    assert by_name["ff"]["type"] == "float | list[float]" and by_name["ff"]["default"] == 0.1
    assert by_name["t"]["default"] == [0.0, 0.0]
    assert by_name["mode"]["type"] == "'uniform' | 'cotan'"
    assert by_name["p"]["type"] == "Path | None"
    d = describe("read_num@1", registry=reg)
    assert d["settings"][0]["file"] == "read"
    d = describe("stats", registry=reg)
    assert d["inputs"] == [{"name": "mesh", "type": "QuadMesh", "required": True}]
    assert d["outputs"] == [{"name": "zmax", "type": "float"}, {"name": "n", "type": "int"}]
    import json

    json.dumps(describe("zoo", registry=reg))  # JSON-ready


# ------------------------------------------------------------ ranges and setting docs (issue 12, items 7 and 9)
def test_ranges_are_checked_whenever_a_setting_is_given():
    from quadnodes.graph import Graph
    from quadnodes.graph.node import Range

    reg = Registry()

    @node("smooth", registry=reg, ranges={"rounds": Range(min=1), "lam": Range(min=0, max=1, min_open=True)})
    def smooth(x: float, *, rounds: int = 1, lam: float | list[float] = 0.5) -> float:
        """Smooth.

        Parameters
        ----------
        rounds : int
            How many passes. More is smoother.
        lam : float or list of float
            Step size (per pass when a list).
        """
        return x

    nt = reg.get("smooth")
    with pytest.raises(GraphError, match=r"^node 's' \(smooth@1\): setting 'rounds': -1 is out of range \(must be >= 1\)$"):
        nt.coerce_setting("rounds", -1, node_id="s")
    with pytest.raises(GraphError, match=r"setting 'lam'\[1\]: 0.0 is out of range \(must be > 0 and <= 1\)"):
        nt.coerce_setting("lam", [0.5, 0], node_id="s")
    with pytest.raises(GraphError, match="nan is out of range"):
        nt.coerce_setting("lam", float("nan"), node_id="s")
    g = Graph(registry=reg)
    h = g.add("smooth", 1.0, id="s")
    with pytest.raises(GraphError, match="'rounds': 0 is out of range"):
        g.with_overrides({"s.rounds": 0})
    assert g.run(overrides={"s.rounds": 2})[h] == 1.0
    d = describe("smooth", registry=reg)
    by = {s["name"]: s for s in d["settings"]}
    assert by["rounds"]["range"] == {"min": 1, "max": None, "min_open": False, "max_open": False, "text": ">= 1"}
    assert by["rounds"]["doc"] == "How many passes." and by["lam"]["doc"] == "Step size (per pass when a list)."


def test_a_default_outside_its_range_or_a_range_of_no_setting_is_refused():
    from quadnodes.graph.node import Range

    reg = Registry()
    with pytest.raises(GraphError, match="setting 'n': default 0 is out of range"):
        @node("a", registry=reg, ranges={"n": Range(min=1)})
        def a(*, n: int = 0) -> int:
            return n
    with pytest.raises(GraphError, match="ranges names 'm', which is not a setting"):
        @node("b", registry=reg, ranges={"m": Range(min=1)})
        def b(*, n: int = 1) -> int:
            return n


def test_a_non_finite_number_is_refused_in_every_float_setting_ranged_or_not():
    # `quadnodes check` passed weight = inf and azim = inf; the run then failed in the node, after the
    # nodes before it had run (minutes on a big graph). No setting means anything by inf or nan.
    from quadnodes.graph.node import Range

    reg = Registry()

    @node("look", registry=reg, ranges={"weight": Range(min=0, min_open=True)})
    def look(x: float, *, weight: float = 0.3, azim: float = -60.0, lams: list[float] | None = None,
             tol: float | str = 1e-3, rounds: int = 1) -> float:
        """Look."""
        return x

    nt = reg.get("look")
    with pytest.raises(GraphError, match=r"^node 'l' \(look@1\): setting 'weight': inf is out of range \(must be > 0\)$"):
        nt.coerce_setting("weight", float("inf"), node_id="l")
    with pytest.raises(GraphError, match=r"^node 'l' \(look@1\): setting 'azim': inf is not a finite number$"):
        nt.coerce_setting("azim", float("inf"), node_id="l")
    with pytest.raises(GraphError, match=r"setting 'azim': nan is not a finite number"):
        nt.coerce_setting("azim", float("nan"), node_id="l")
    with pytest.raises(GraphError, match=r"setting 'lams'\[1\]: -inf is not a finite number"):
        nt.coerce_setting("lams", [0.5, -math.inf], node_id="l")
    with pytest.raises(GraphError, match=r"setting 'tol': inf is not a finite number"):
        nt.coerce_setting("tol", math.inf, node_id="l")
    with pytest.raises(GraphError, match=r"setting 'rounds': expected int, got float inf"):
        nt.coerce_setting("rounds", math.inf, node_id="l")
    assert nt.coerce_setting("azim", -1e300, node_id="l") == -1e300
    assert nt.coerce_setting("tol", "2 mm", node_id="l") == "2 mm"
    assert nt.coerce_setting("lams", [0.1, 0.2], node_id="l") == [0.1, 0.2]
