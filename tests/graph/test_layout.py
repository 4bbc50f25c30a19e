"""The ``[layout]`` table of graph files: node positions on the page of ``quadnodes serve``, kept by the loader."""

from __future__ import annotations

import json
import tomllib

import pytest

from quadnodes.errors import GraphError
from quadnodes.graph import dumps, keys, load, loads, save

TEXT = """\
format = "quadnodes-graph"
version = 1

[nodes.a]
op = "num"
params = { value = 2 }

[nodes.b]
op = "scale"
inputs = { x = "a.value" }

[layout]
a = [20, 40.5]
b = [300.0, 40.5]
"""


def test_the_layout_is_read_and_saved_in_both_formats(reg, tmp_path):
    g = loads(TEXT, fmt="toml", registry=reg)
    assert g.layout == {"a": [20.0, 40.5], "b": [300.0, 40.5]}
    for fmt in ("toml", "json"):
        p = save(g, tmp_path / f"g.{fmt}")
        back = load(p, registry=reg)
        assert back.layout == g.layout and back == g
    data = tomllib.loads(dumps(g, fmt="toml"))
    assert data["layout"] == {"a": [20.0, 40.5], "b": [300.0, 40.5]}
    assert json.loads(dumps(g, fmt="json"))["layout"]["b"] == [300.0, 40.5]
    assert g.copy().layout == g.layout and g.copy().layout is not g.layout


def test_positions_do_not_change_cache_keys(reg):
    with_layout = loads(TEXT, fmt="toml", registry=reg)
    without = loads(TEXT.split("[layout]")[0], fmt="toml", registry=reg)
    assert without.layout == {} and keys(with_layout) == keys(without)
    assert "layout" not in json.loads(dumps(without, fmt="json"))


@pytest.mark.parametrize("table, message", [
    ('a = [1]', "layout.a: expected a position [x, y] of two numbers, got [1]"),
    ('a = ["x", 2]', "layout.a: expected a position [x, y] of two numbers"),
    ('a = [true, 2]', "layout.a: expected a position [x, y] of two numbers"),
    ('a = [nan, 2]', "layout.a: expected a position [x, y] of two numbers"),
])
def test_a_malformed_position_is_an_error(reg, table, message):
    text = TEXT.split("[layout]")[0] + "[layout]\n" + table + "\n"
    with pytest.raises(GraphError, match=message.replace("[", r"\[").replace("]", r"\]")):
        loads(text, fmt="toml", registry=reg)
    with pytest.raises(GraphError, match="layout: expected a table"):
        loads(TEXT.split("[layout]")[0].replace("version = 1", "version = 1\nlayout = 3"), fmt="toml", registry=reg)
