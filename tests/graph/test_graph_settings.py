"""Graph-wide settings: one planar_tolerance at the top of a graph file (issue 13)."""

import pytest

import quadnodes.nodes  # noqa: F401  (registers the node types)
from quadnodes.errors import GraphError
from quadnodes.graph.files import dumps, loads

TEXT = """format = "quadnodes-graph"
version = 1
planar_tolerance = "2 mm"

[nodes.g]
op = "grid@1"

[nodes.step]
op = "export_step@1"
inputs = { mesh = "g.mesh" }
params = { path = "a.step" }

[nodes.csv]
op = "export_csv@1"
inputs = { mesh = "g.mesh" }
params = { path = "a.csv", planar_tolerance = 0.01 }
"""


def test_nodes_inherit_the_graph_tolerance_unless_they_set_their_own():
    g = loads(TEXT, fmt="toml")
    assert g.nodes["step"].params["planar_tolerance"] == "2 mm"
    assert g.nodes["csv"].params["planar_tolerance"] == 0.01
    assert "planar_tolerance" not in g.nodes["g"].params  # grid has no such setting


def test_the_graph_tolerance_survives_a_save():
    text = dumps(loads(TEXT, fmt="toml"))
    assert text.startswith('format = "quadnodes-graph"\nversion = 1\nplanar_tolerance = "2 mm"\n')
    assert text.count("planar_tolerance") == 2  # the top, and the node that sets its own
    again = loads(text, fmt="toml")
    assert again.nodes["step"].params["planar_tolerance"] == "2 mm"


def test_bad_graph_tolerance_is_a_graph_error():
    with pytest.raises(GraphError, match="planar_tolerance"):
        loads(TEXT.replace('"2 mm"', "[1, 2]"), fmt="toml")
    with pytest.raises(GraphError, match="planar_tolerance"):
        loads(TEXT.replace('"2 mm"', '"2 furlongs"'), fmt="toml")


def test_old_setting_name_points_to_the_new_one():
    with pytest.raises(GraphError, match="planar_tolerance"):
        loads(TEXT.replace("params = { path = \"a.step\" }", "params = { path = \"a.step\", planar_tol = 0.1 }"), fmt="toml")
