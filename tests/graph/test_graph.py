"""The graph model and its fluent Python API: building, handles, validation errors."""

from __future__ import annotations

import pytest

from quadnodes.errors import GraphError
from quadnodes.graph import Constant, Graph, PortRef
from quadnodes.graph.files import from_dict
from quadnodes.mesh import grid


def test_fluent_api_handles_and_results(reg):
    g = Graph(registry=reg)
    m = g.add("grid", id="mesh", rows=4, cols=5)
    up = g.add("lift", m.mesh, dz=0.5)
    st = g.add("stats", up)  # single-output handle stands for its port
    assert up.id == "lift1" and st.id == "stats1"
    assert m.mesh == PortRef("mesh", "mesh") and m["mesh"] == m.mesh
    assert g.nodes["stats1"].inputs == {"mesh": PortRef("lift1", "mesh")}
    assert g.nodes["lift1"].params == {"dz": 0.5}
    assert g.order() == ["mesh", "lift1", "stats1"]
    res = g.run()
    assert res[st.zmax] == 0.5 and res[st.n] == 20 and res["stats1.n"] == 20
    assert res[up].n_vertices == 20 and res["lift1"] is res[up]
    assert res.outputs["stats1"] == {"zmax": 0.5, "n": 20}
    assert [r.status for r in res.records] == ["ran"] * 3
    with pytest.raises(GraphError, match=r"'stats1' \(stats@1\) has 2 outputs; pick one: stats1.zmax, stats1.n"):
        res[st]
    with pytest.raises(GraphError, match=r"no output port 'zmx'; did you mean 'zmax'\?"):
        st.zmx
    assert not hasattr(st, "zmx")  # also an AttributeError


def test_inputs_by_keyword_and_auto_ids(reg):
    g = Graph(registry=reg)
    a = g.add("num", value=1)
    b = g.add("num", value=2)
    s = g.add("add", b=b, a=a)
    assert (a.id, b.id, s.id) == ("num1", "num2", "add1")
    assert g.run()[s] == 3.0
    with pytest.raises(GraphError, match=r"node 'add2' \(add@1\): input 'a' given twice"):
        g.add("add", a, a=b)
    with pytest.raises(GraphError, match=r"takes 2 inputs \(a, b\), got 3"):
        g.add("add", a, a, a)


def test_constant_inputs_run_but_cannot_be_saved(reg, tmp_path):
    g = Graph(registry=reg)
    m = g.add("lift", grid(2, 3), id="up", dz=2.0)
    assert isinstance(g.nodes["up"].inputs["mesh"], Constant)
    assert g.run()[m].vertices[0, 2] == 2.0
    with pytest.raises(GraphError, match=r"node 'up' \(lift@1\): input 'mesh' is a Python value \(QuadMesh\)"):
        g.save(tmp_path / "g.toml")
    assert not (tmp_path / "g.toml").exists()


def test_constant_of_wrong_type(reg):
    g = Graph(registry=reg)
    with pytest.raises(GraphError, match=r"node 'lift1' \(lift@1\): input 'mesh' expects QuadMesh, got a str"):
        g.add("lift", "not a mesh")
    assert "lift1" not in g


def test_connection_of_wrong_type(reg):
    g = Graph(registry=reg)
    n = g.add("num", id="n", value=1)
    with pytest.raises(GraphError, match=r"node 'up' \(lift@1\): input 'mesh' expects QuadMesh, but 'n.value' gives float"):
        g.add("lift", n, id="up")


def test_handle_of_another_graph(reg):
    g1, g2 = Graph(registry=reg), Graph(registry=reg)
    a = g1.add("num", id="a")
    with pytest.raises(GraphError, match="refers to node 'a' of another graph"):
        g2.add("add", a)


def test_duplicate_and_malformed_ids(reg):
    g = Graph(registry=reg)
    g.add("num", id="a")
    with pytest.raises(GraphError, match=r"node 'a': the id is already used by another node \(num@1\)"):
        g.add("num", id="a")
    with pytest.raises(GraphError, match=r"node id 'a.b' \(num@1\): use letters"):
        g.add("num", id="a.b")


def test_unknown_op_setting_and_missing_input_in_python(reg):
    g = Graph(registry=reg)
    with pytest.raises(GraphError, match=r"node 'x': unknown op 'scael'; did you mean 'scale'\?"):
        g.add("scael", id="x")
    a = g.add("num", id="a")
    with pytest.raises(GraphError, match=r"node 's' \(scale@1\): unknown setting 'factr'; did you mean 'factor'\?"):
        g.add("scale", a, id="s", factr=2)
    with pytest.raises(GraphError, match=r"node 's' \(scale@1\): setting 'factor': expected float, got str"):
        g.add("scale", a, id="s", factor="2")
    with pytest.raises(GraphError, match=r"node 's' \(scale@1\): missing required input 'x' \(float\)"):
        g.add("scale", id="s")
    assert list(g) == ["a"]


def test_set_and_overrides(reg):
    g = Graph(registry=reg)
    a = g.add("num", id="a", value=1)
    s = g.add("scale", a, id="s")
    g.set("s", factor=3)
    assert g.nodes["s"].params == {"factor": 3.0}
    h = g.with_overrides({"a.value": 2, "s.factor": 10})
    assert h.run()[s] == 20.0 and g.run()[s] == 3.0
    with pytest.raises(GraphError, match=r"override 'b.value': no node 'b'"):
        g.with_overrides({"b.value": 1})
    with pytest.raises(GraphError, match=r"node 's' \(scale@1\): unknown setting 'fctor'; did you mean 'factor'"):
        g.with_overrides({"s.fctor": 1})
    with pytest.raises(GraphError, match=r"expected 'node.setting'"):
        g.with_overrides({"s": 1})


def test_none_for_a_none_default_is_the_same_as_leaving_it_out(reg):
    g = Graph(registry=reg)
    g.add("zoo", id="z", req=1, opt=None)
    assert g.nodes["z"].params == {"req": 1}


def _model(nodes):
    return {"format": "quadnodes-graph", "version": 1, "nodes": nodes}


@pytest.mark.parametrize(
    ("nodes", "message"),
    [
        ({"a": {"op": "nmu"}}, r"node 'a': unknown op 'nmu'; did you mean 'num'\?"),
        ({"a": {"op": "num", "params": {"valeu": 1}}}, r"node 'a' \(num@1\): unknown setting 'valeu'; did you mean 'value'\?"),
        ({"a": {"op": "num", "params": {"value": "x"}}}, r"node 'a' \(num@1\): setting 'value': expected float, got str 'x'"),
        ({"a": {"op": "num"}, "b": {"op": "scale", "inputs": {"y": "a.value"}}},
         r"node 'b' \(scale@1\): unknown input port 'y' \(inputs: x\)"),
        ({"a": {"op": "num"}, "b": {"op": "scale", "inputs": {"factor": "a.value"}}},
         r"node 'b' \(scale@1\): 'factor' is a setting, not an input port"),
        ({"b": {"op": "scale", "inputs": {"x": "c.value"}}},
         r"node 'b' \(scale@1\): input 'x' refers to 'c.value': no node 'c'"),
        ({"a": {"op": "num"}, "b": {"op": "scale", "inputs": {"x": "a.valu"}}},
         r"node 'b' \(scale@1\): input 'x' refers to 'a.valu': node 'a' \(num@1\) has no output 'valu'; did you mean 'value'\?"),
        ({"a": {"op": "num"}, "b": {"op": "scale"}}, r"node 'b' \(scale@1\): missing required input 'x'"),
        ({"a": {"op": "num"}, "b": {"op": "lift", "inputs": {"mesh": "a.value"}}},
         r"node 'b' \(lift@1\): input 'mesh' expects QuadMesh, but 'a.value' gives float"),
        ({"a": {"op": "zoo"}}, r"node 'a' \(zoo@1\): missing required setting 'req'"),
        ({"a": {"op": "num", "inputs": {"x": "bad ref"}}}, r"node 'a' \(num@1\): field 'inputs.x': expected a reference 'node.port', got 'bad ref'"),
        ({"a": {"op": "num", "parms": {}}}, r"node 'a': unknown field 'parms'; did you mean 'params'\?"),
        ({"a": {"params": {}}}, r"node 'a': missing field 'op'"),
        ({"a": {"op": 3}}, r"node 'a': field 'op': expected a string"),
        ({"a": {"op": "num", "params": [1]}}, r"node 'a': field 'params': expected a table"),
        ({"a.b": {"op": "num"}}, r"node id 'a.b': use letters"),
        ({"a": "num"}, r"node 'a': expected a table with op, inputs and params"),
    ],
)
def test_model_errors_name_node_and_field(reg, nodes, message):
    with pytest.raises(GraphError, match=message) as e:
        from_dict(_model(nodes), registry=reg)
    assert e.value.node_id in nodes or e.value.node_id == "a.b"


def test_cycle_names_every_node_on_it(reg):
    nodes = {
        "src": {"op": "num"},
        "a": {"op": "add", "inputs": {"a": "src.value", "b": "c.out"}},
        "b": {"op": "scale", "inputs": {"x": "a.out"}},
        "c": {"op": "scale", "inputs": {"x": "b.out"}},
    }
    with pytest.raises(GraphError, match=r"cycle: .*\(nodes a, b, c\)") as e:
        from_dict(_model(nodes), registry=reg)
    chain = str(e.value).split("cycle: ")[1].split(" (")[0].split(" -> ")
    assert chain[0] == chain[-1] and set(chain) == {"a", "b", "c"}
    # each node feeds the next one
    feeds = {("a", "b"), ("b", "c"), ("c", "a")}
    assert all(pair in feeds for pair in zip(chain, chain[1:]))


def test_self_loop(reg):
    with pytest.raises(GraphError, match=r"cycle: a -> a"):
        from_dict(_model({"a": {"op": "scale", "inputs": {"x": "a.out"}}}), registry=reg)


def test_graph_equality_and_copy(reg):
    g = Graph(registry=reg)
    a = g.add("num", id="a", value=1)
    g.add("scale", a, id="s")
    h = g.copy()
    assert h == g
    h.set("s", factor=5)
    assert h != g


# --------------------------------------------------------------- faces and meshes are told apart (followups)
# quadnodes.nodes annotated face ports with Any (build123d is imported lazily), so the checker let a surface into
# a mesh input, and the reverse; the error came only when the node ran, from deep inside it.

FACE_INTO_MESH = '''format = "quadnodes-graph"
version = 1

[nodes.surface]
op = "saddle@1"

[nodes.plane]
op = "grid@1"

[nodes.fair]
op = "fair@1"
inputs = { mesh = "surface.face" }

[nodes.clean]
op = "sample@1"
inputs = { face = "plane.mesh" }
'''


def test_a_face_wired_into_a_mesh_input_is_refused_and_the_reverse(tmp_path):
    import quadnodes.nodes  # noqa: F401
    from quadnodes.graph import REGISTRY
    from quadnodes.graph.diagnostics import file_problems
    from quadnodes.graph.files import loads

    g = Graph(registry=REGISTRY)
    s = g.add("saddle", id="surface")
    m = g.add("grid", id="plane")
    with pytest.raises(GraphError, match=r"^node 'fair' \(fair@1\): input 'mesh' expects QuadMesh, "
                                         r"but 'surface.face' gives Face$"):
        g.add("fair", s.face, id="fair")
    with pytest.raises(GraphError, match=r"^node 'clean' \(sample@1\): input 'face' expects Face, "
                                         r"but 'plane.mesh' gives QuadMesh$"):
        g.add("sample", m.mesh, id="clean")
    with pytest.raises(GraphError, match=r"input 'mesh' expects QuadMesh, but 'surface.face' gives Face"):
        loads(FACE_INTO_MESH, fmt="toml", registry=REGISTRY)
    p = tmp_path / "g.toml"
    p.write_text(FACE_INTO_MESH)
    assert [str(e) for e in file_problems(p, registry=REGISTRY)] == [  # every one, in file order
        f"{p} line 10: node 'fair' (fair@1): input 'mesh' expects QuadMesh, but 'surface.face' gives Face",
        f"{p} line 14: node 'clean' (sample@1): input 'face' expects Face, but 'plane.mesh' gives QuadMesh",
    ]
    # what is right stays accepted: a face into a face input and into the references that take a face or a mesh
    c = g.add("sample", s.face, id="clean", nu=5, nv=5)
    f = g.add("fair", c.mesh, None, s.face, id="fair")
    g.add("compare", c.mesh, f.mesh, s.face, id="cmp")
    g.add("planarize", f.mesh, s.face, id="flat")
    res = g.run()
    assert res["cmp.metrics"]["reference_max"] < 1e-3 * 5000  # faired on the clean grid, pulled to the saddle


def test_face_constants_and_build123d_annotations_are_checked_by_the_face_type():
    import build123d

    import quadnodes.nodes  # noqa: F401
    from quadnodes.graph import REGISTRY, Registry, node
    from quadnodes.nodes import Face
    from quadnodes.surfaces import saddle

    g = Graph(registry=REGISTRY)
    face = saddle(1000.0, 1000.0, 100.0)  # a build123d face given in Python is a face; a mesh is not
    c = g.add("sample", face, id="clean", nu=4, nv=3)
    with pytest.raises(GraphError, match=r"node 'bad' \(sample@1\): input 'face' expects Face, got a QuadMesh"):
        g.add("sample", grid(3, 3), id="bad")
    with pytest.raises(GraphError, match=r"node 'bad' \(fair@1\): input 'mesh' expects QuadMesh, got a Face"):
        g.add("fair", face, id="bad")
    assert g.run()[c].grid_shape == (4, 3)
    assert isinstance(build123d.Shell([face]), Face) and not isinstance(object(), Face)
    assert issubclass(build123d.Face, Face) and not issubclass(type(grid(2, 2)), Face)
    # a node of one's own whose ports say build123d.Face connects with the built-in face ports both ways
    reg = Registry()
    for nt in REGISTRY.latest():
        if nt.name in ("saddle", "sample", "grid"):
            reg.register(nt)

    def lift_face(face, *, dz: float = 1.0):
        return face.moved(build123d.Location((0, 0, dz)))

    lift_face.__annotations__.update({"face": build123d.Face, "return": build123d.Face})  # objects, not text
    node("lift_face", outputs=("face",), registry=reg)(lift_face)

    h = Graph(registry=reg)
    lifted = h.add("lift_face", h.add("saddle", id="s").face, id="up", dz=10.0)
    m = h.add("sample", lifted.face, id="m", nu=3, nv=3)
    with pytest.raises(GraphError, match=r"input 'face' expects Face, but 'g.mesh' gives QuadMesh"):
        h.add("lift_face", h.add("grid", id="g").mesh)
    res = h.run()
    assert res[m].vertices[:, 2].min() == pytest.approx(-1000.0 + 10.0)


def test_importing_the_nodes_does_not_import_build123d():
    import subprocess
    import sys

    code = "import sys, quadnodes.nodes; print('build123d' in sys.modules, 'OCP' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]
