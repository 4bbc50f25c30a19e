"""Graph files: TOML and JSON round trips, syntax and model errors with lines."""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from quadnodes.errors import GraphError
from quadnodes.graph import Graph, dumps, keys, load, loads, parse_value, save
from quadnodes.graph.files import toml_dumps

TOML = """\
format = "quadnodes-graph"
version = 1

# a comment
[nodes.mesh]
op = "grid"
params = { rows = 4, cols = 5, spacing = 1 }

[nodes.up]
op = "lift@1"
inputs = { mesh = "mesh.mesh" }

[nodes.up.params]
dz = 0.25

[nodes.z]
op = "zoo"
params = { req = 2, fl = [1, 2], ff = 0.5, t = [1, 2], mode = "cotan", p = "out/a.obj" }
"""

JSON = """\
{"version": 1, "format": "quadnodes-graph",
 "nodes": {
  "z": {"op": "zoo", "params": {"req": 2.0, "fl": [1.0, 2.0], "ff": 0.5, "t": [1, 2], "mode": "cotan", "p": "out/a.obj"}},
  "up": {"op": "lift", "inputs": {"mesh": "mesh.mesh"}, "params": {"dz": 0.25}},
  "mesh": {"op": "grid", "params": {"rows": 4, "cols": 5.0, "spacing": 1.0}}
 }
}
"""


def test_toml_and_json_load_to_the_same_graph_and_keys(reg):
    gt = loads(TOML, fmt="toml", registry=reg)
    gj = loads(JSON, fmt="json", registry=reg)
    assert gt == gj
    assert gt.nodes["up"].op == "lift@1" and gt.nodes["mesh"].op == "grid@1"  # pinned
    assert keys(gt) == keys(gj)
    assert all(k is not None for k in keys(gt).values())


def test_round_trip_both_formats_sorted_keys(reg, tmp_path):
    g = loads(TOML, fmt="toml", registry=reg, base_dir=tmp_path)
    for name in ("g.toml", "g.json"):
        path = save(g, tmp_path / name)
        back = load(path, registry=reg)
        assert back == g and keys(back) == keys(g)
    text = (tmp_path / "g.toml").read_text()
    assert text.startswith('format = "quadnodes-graph"\nversion = 1\n')
    assert text.index("[nodes.mesh]") < text.index("[nodes.up]") < text.index("[nodes.z]")
    assert "cols = 5\nrows = 4\nspacing = 1.0" in text
    data = json.loads((tmp_path / "g.json").read_text())
    assert list(data) == ["format", "version", "nodes"]
    assert list(data["nodes"]) == sorted(data["nodes"])
    assert list(data["nodes"]["z"]["params"]) == sorted(data["nodes"]["z"]["params"])
    # both files hold the same tree
    assert tomllib.loads(text) == data


def test_saving_is_atomic_and_leaves_no_temporary_files(reg, tmp_path):
    g = loads(TOML, fmt="toml", registry=reg)
    save(g, tmp_path / "g.toml")
    save(g, tmp_path / "g.toml")
    assert [p.name for p in tmp_path.iterdir()] == ["g.toml"]


def test_relative_paths_are_rebased_on_save(reg, tmp_path):
    g = Graph(registry=reg, base_dir=tmp_path)
    g.add("zoo", id="z", req=1, p="data/a.obj")
    (tmp_path / "sub").mkdir()
    save(g, tmp_path / "sub" / "g.toml")
    back = load(tmp_path / "sub" / "g.toml", registry=reg)
    assert back.nodes["z"].params["p"] == Path("../data/a.obj")
    assert (back.base_dir / back.nodes["z"].params["p"]).resolve() == (tmp_path / "data" / "a.obj").resolve()


@pytest.mark.parametrize(
    ("text", "fmt", "expected"),
    [
        ('format = "quadnodes-graph"\nversion = 1\n[nodes.a]\nop = "num"\nparams = { value = }\n', "toml",
         r"^graph\.toml line 5, column 20: Invalid value"),
        ('format = "quadnodes-graph"\nversion = 1\n[nodes.a]\nop = "num"\n[nodes.a]\nop = "num"\n', "toml",
         r"^graph\.toml line 5, column 9: Cannot declare \('nodes', 'a'\) twice"),
        ('format = "quadnodes-graph"\nversion = 1\n[nodes.a\n', "toml", r"^graph\.toml line 3, column 9: "),
        ('{\n "format": "quadnodes-graph",\n "version": 1\n "nodes": {}\n}\n', "json",
         r"^graph\.json line 4, column 2: Expecting ',' delimiter"),
        ('{"format": "quadnodes-graph", "version": 1, "nodes": {\n "a": {"op": "num"},\n "a": {"op": "num"}\n}}', "json",
         r"^graph\.json line 3: node id 'a' appears twice"),
        ('{"format": "quadnodes-graph", "version": 1, "nodes": {\n "a": {"op": "num", "op": "num"}}}', "json",
         r"^graph\.json line 2: key 'op' appears twice"),
    ],
)
def test_syntax_errors_carry_the_line(reg, text, fmt, expected):
    with pytest.raises(GraphError, match=expected):
        loads(text, fmt=fmt, registry=reg)


def test_model_errors_carry_file_node_and_line(reg, tmp_path):
    bad = TOML.replace("dz = 0.25", "dz = 'high'")
    p = tmp_path / "graph.toml"
    p.write_text(bad)
    with pytest.raises(GraphError) as e:
        load(p, registry=reg)
    line = bad.splitlines().index("[nodes.up]") + 1
    assert str(e.value) == (
        f"{p} line {line}: node 'up' (lift@1): setting 'dz': expected float, got str 'high'"
    )
    assert e.value.node_id == "up"

    bad = JSON.replace('"cols": 5.0', '"colls": 5.0')
    p = tmp_path / "graph.json"
    p.write_text(bad)
    with pytest.raises(GraphError, match=rf"^{p} line 5: node 'mesh' \(grid@1\): unknown setting 'colls'; did you mean 'cols'\?"):
        load(p, registry=reg)


def test_unknown_op_in_a_file(reg):
    with pytest.raises(GraphError, match=r"^graph\.toml line 5: node 'mesh': unknown op 'gird'; did you mean 'grid'\?"):
        loads(TOML.replace('op = "grid"', 'op = "gird"'), fmt="toml", registry=reg)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('version = 1\n', r"missing 'format = \"quadnodes-graph\"'"),
        ('format = "other"\nversion = 1\n', r"format: expected 'quadnodes-graph', got 'other'"),
        ('format = "quadnodes-graph"\n', r"missing 'version = 1'"),
        ('format = "quadnodes-graph"\nversion = 2\n', r"version 2 is newer than this quadnodes reads"),
        ('format = "quadnodes-graph"\nversion = "1"\n', r"version: expected a positive integer"),
        ('format = "quadnodes-graph"\nversion = 1\nnode = {}\n', r"unknown top-level key 'node'; did you mean 'nodes'\?"),
    ],
)
def test_header_errors(reg, text, message):
    with pytest.raises(GraphError, match=message):
        loads(text, fmt="toml", registry=reg)


def test_file_errors(reg, tmp_path):
    with pytest.raises(GraphError, match="cannot read graph file"):
        load(tmp_path / "missing.toml", registry=reg)
    (tmp_path / "g.yaml").write_text("x")
    with pytest.raises(GraphError, match="use .toml or .json"):
        load(tmp_path / "g.yaml", registry=reg)
    (tmp_path / "g.toml").write_bytes(b"\xff\xfe")
    with pytest.raises(GraphError, match="not UTF-8"):
        load(tmp_path / "g.toml", registry=reg)


def test_empty_graph_round_trip(reg):
    g = Graph(registry=reg)
    assert loads(dumps(g), fmt="toml", registry=reg) == g
    assert loads(dumps(g, fmt="json"), fmt="json", registry=reg) == g


def test_toml_cannot_hold_null():
    with pytest.raises(GraphError, match=r"node 'a': params.x: TOML has no null"):
        toml_dumps({"format": "quadnodes-graph", "nodes": {"a": {"op": "x@1", "params": {"x": None}}}})


_keys = st.text(min_size=1, max_size=8)
_scalars = st.one_of(
    st.booleans(),
    st.integers(-(2**63), 2**63 - 1),
    st.floats(allow_nan=False),
    st.text(max_size=20),
)
_values = st.recursive(
    _scalars,
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(_keys, inner, max_size=4)),
    max_leaves=12,
)


@given(st.dictionaries(_keys, _values, max_size=6))
def test_toml_writer_reads_back_with_tomllib(params):
    data = {"format": "quadnodes-graph", "version": 1, "nodes": {"n-1": {"op": "x@1", "params": params}}}
    back = tomllib.loads(toml_dumps(data))
    assert back["nodes"]["n-1"].get("params", {}) == params


def test_toml_writer_special_floats():
    text = toml_dumps({"nodes": {"a": {"params": {"x": [math.inf, -math.inf, math.nan, 1e-300, -0.0]}}}})
    x = tomllib.loads(text)["nodes"]["a"]["params"]["x"]
    assert x[:2] == [math.inf, -math.inf] and math.isnan(x[2]) and x[3] == 1e-300
    assert math.copysign(1, x[4]) == -1


def test_parse_value():
    assert parse_value("3") == 3 and parse_value("[0.1, 0.05]") == [0.1, 0.05]
    assert parse_value("cotan") == "cotan" and parse_value("true") is True
