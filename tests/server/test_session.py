"""The live session without HTTP: edits validated like the loader, written back, re-runs of only what changed."""

from __future__ import annotations

import base64
import json
import os
import time
from pathlib import Path

import numpy as np
import pytest

from quadnodes.errors import GraphError
from quadnodes.graph import loads
from quadnodes.mesh import grid
from quadnodes.server.session import Session, auto_layout, encode_mesh, node_type_info


def _session(graph_file: Path, reg, tmp_path: Path) -> Session:
    return Session(graph_file, out=tmp_path / "out", registry=reg)


def _wait(s: Session, revision: int | None = None) -> dict:
    """Run until the run of the current revision is done (the session's worker is not started here)."""
    return s.run_once()


def test_first_run_then_only_downstream_of_a_setting_runs(graph_file, reg, tmp_path, calls):
    s = _session(graph_file, reg, tmp_path)
    first = _wait(s)
    assert first["state"] == "done" and first["cached"] == []
    assert (tmp_path / "out" / "n.txt").read_text() == "20\n"  # written under --out, as quadnodes run does
    calls.clear()
    res = s.set_settings("up", {"dz": 3.5})
    assert res["ok"] and res["revision"] == 2
    info = _wait(s)
    assert info["ran"] == ["up", "n", "save"]  # base and other come from the cache
    assert sorted(info["cached"]) == ["base", "other"]
    assert calls == ["lift", "count", "save_text"]
    assert np.allclose(s.output("up", "mesh").vertices[:, 2], 3.5)


def test_an_edit_keeps_the_comments_and_layout_of_the_toml(graph_file, reg, tmp_path):
    s = _session(graph_file, reg, tmp_path)
    s.set_settings("up", {"dz": 0.25, "mode": "scale"})
    text = graph_file.read_text()
    assert "# a toy graph for the server tests" in text and "# a small grid" in text
    assert 'params = { dz = 0.25, mode = "scale"' in text  # the same inline table, edited in place
    g = loads(text, fmt="toml", registry=reg)
    assert dict(g.nodes["up"].params) == {"dz": 0.25, "mode": "scale"}
    s.set_settings("up", {"mode": None})  # None: back to the default, the key goes
    assert "mode" not in loads(graph_file.read_text(), fmt="toml", registry=reg).nodes["up"].params


@pytest.mark.parametrize("change, expected", [
    ({"dz": "high"}, "node 'up' (lift@1): setting 'dz': expected float, got str 'high'"),
    ({"dzz": 1}, "unknown setting 'dzz'; did you mean 'dz'?"),
    ({"mode": "ADD"}, "setting 'mode'"),
    ({"mesh": "base.mesh"}, "'mesh' is an input port, not a setting"),
])
def test_an_invalid_setting_is_refused_with_the_loaders_message_and_nothing_changes(
        graph_file, reg, tmp_path, change, expected):
    s = _session(graph_file, reg, tmp_path)
    before = graph_file.read_bytes()
    res = s.set_settings("up", change)
    assert not res["ok"] and res["node"] == "up"
    assert expected in res["error"]
    assert graph_file.read_bytes() == before
    assert s.revision == 1 and s.node_errors == {"up": res["error"]}
    assert res["error"].startswith("toy.toml line 9: node 'up' (lift@1): ")


def test_the_refusal_is_the_loaders_own_message(graph_file, reg, tmp_path):
    s = _session(graph_file, reg, tmp_path)
    res = s.set_settings("up", {"dz": "high"})
    edited = graph_file.read_text().replace("params = { dz = 2.0 }", 'params = { dz = "high" }')
    with pytest.raises(GraphError) as exc:
        loads(edited, fmt="toml", registry=reg, source="toy.toml")
    assert res["error"] == str(exc.value)


def test_add_connect_disconnect_delete(graph_file, reg, tmp_path):
    s = _session(graph_file, reg, tmp_path)
    res = s.add_node("lift", inputs={"mesh": "base.mesh"}, params={"dz": -1.0}, pos=[500, 40])
    assert res["ok"] and res["id"] == "lift1"
    g = loads(graph_file.read_text(), fmt="toml", registry=reg)
    assert g.nodes["lift1"].op == "lift@1" and g.layout["lift1"] == [500.0, 40.0]
    assert s.connect("other", "mesh", "lift1.mesh")["ok"]
    assert str(s.graph.nodes["other"].inputs["mesh"]) == "lift1.mesh"
    # a wire to a missing output is refused with the loader's message
    res = s.connect("other", "mesh", "lift1.nope")
    assert not res["ok"] and "has no output 'nope'" in res["error"]
    # deleting a node that feeds a required input is refused: the graph would be invalid
    res = s.delete_node("lift1")
    assert not res["ok"] and "missing required input 'mesh'" in res["error"] and res["node"] == "other"
    assert "lift1" in s.graph.nodes
    assert s.connect("other", "mesh", "base.mesh")["ok"]
    assert s.delete_node("lift1")["ok"]
    text = graph_file.read_text()
    assert "lift1" not in text  # its table, its wires and its position are gone
    # an optional input can be disconnected; a required one cannot
    res = s.disconnect("n", "mesh")
    assert not res["ok"] and "missing required input 'mesh'" in res["error"]
    assert not s.add_node("nosuch")["ok"]


def test_boom_failure_is_reported_on_the_node(graph_file, reg, tmp_path):
    s = _session(graph_file, reg, tmp_path)
    assert s.add_node("boom", node_id="bad", inputs={"mesh": "up.mesh"})["ok"]
    info = _wait(s)
    assert info["state"] == "failed" and info["failed"] == ["bad"]
    assert "boom went off on purpose" in info["nodes"]["bad"]["error"]
    with pytest.raises(GraphError, match="not available"):
        s.output("bad", "mesh")
    assert s.set_settings("bad", {"fail": False})["ok"]
    assert _wait(s)["state"] == "done"


@pytest.mark.parametrize("path", ["../escape.txt", "../../x.txt", "/tmp/abs.txt", "sub/../../n.txt", "."])
def test_write_paths_stay_inside_out(graph_file, reg, tmp_path, path):
    s = _session(graph_file, reg, tmp_path)
    before = graph_file.read_bytes()
    res = s.set_settings("save", {"path": path})
    assert not res["ok"] and "output folder" in res["error"] and "'path'" in res["error"]
    assert graph_file.read_bytes() == before


def test_read_paths_stay_inside_the_graph_folder_or_out(graph_file, reg, tmp_path):
    (graph_file.parent / "num.txt").write_text("7\n")
    (tmp_path / "secret.txt").write_text("1\n")
    s = _session(graph_file, reg, tmp_path)
    assert s.add_node("read_text", node_id="r", params={"path": "num.txt"})["ok"]
    res = s.set_settings("r", {"path": "../secret.txt"})
    assert not res["ok"] and "outside the graph's folder" in res["error"]
    res = s.set_settings("r", {"path": str(tmp_path / "secret.txt")})
    assert not res["ok"]
    assert _wait(s)["nodes"]["r"]["status"] == "ran"
    assert s.output("r", "n") == 7


def test_a_file_that_escapes_is_refused_at_the_start(graph_file, reg, tmp_path):
    graph_file.write_text(graph_file.read_text().replace('path = "n.txt"', 'path = "../../n.txt"'))
    with pytest.raises(GraphError, match="output folder"):
        _session(graph_file, reg, tmp_path)


def test_an_edit_in_a_text_editor_is_picked_up(graph_file, reg, tmp_path):
    s = _session(graph_file, reg, tmp_path)
    assert not s.poll()
    text = graph_file.read_text().replace("dz = 2.0", "dz = 5.0")
    graph_file.write_text(text + "\n")  # size changes, so the stamp changes even within one mtime tick
    assert s.poll()
    assert s.graph.nodes["up"].params["dz"] == 5.0 and s.revision == 2
    # a broken save keeps the last good graph and says why
    graph_file.write_text(text.replace("dz = 5.0", "dz = = 5"))
    assert s.poll()
    assert s.graph.nodes["up"].params["dz"] == 5.0
    assert s.file_error is not None and "line" in s.file_error
    assert s.describe()["file_error"] == s.file_error


def test_a_changed_input_file_reruns_its_reader(graph_file, reg, tmp_path):
    src = graph_file.parent / "num.txt"
    src.write_text("7\n")
    s = _session(graph_file, reg, tmp_path)
    s.add_node("read_text", node_id="r", params={"path": "num.txt"})
    _wait(s)
    src.write_text("11\n")
    os.utime(src, ns=(time.time_ns() + 10**9,) * 2)
    assert s.poll()
    info = _wait(s)
    assert "r" in info["ran"] and s.output("r", "n") == 11


def test_json_files_are_rewritten_with_sorted_keys(tmp_path, reg):
    p = tmp_path / "g.json"
    p.write_text(json.dumps({"version": 1, "format": "quadnodes-graph",
                             "nodes": {"b": {"op": "plane@1"}, "a": {"op": "plane@1"}}}))
    s = Session(p, out=tmp_path / "out", registry=reg)
    assert s.set_settings("b", {"rows": 3})["ok"]
    data = json.loads(p.read_text())
    assert list(data) == sorted(data) and list(data["nodes"]) == ["a", "b"]
    assert data["nodes"]["b"]["params"] == {"rows": 3}


def test_positions_are_saved_in_the_layout_table(graph_file, reg, tmp_path):
    s = _session(graph_file, reg, tmp_path)
    assert s.move({"up": [310, 55.5]})["ok"]
    assert "[layout]" in graph_file.read_text()
    assert loads(graph_file.read_text(), fmt="toml", registry=reg).layout == {"up": [310.0, 55.5]}
    assert s.describe()["layout"]["up"] == [310.0, 55.5]
    assert not s.move({"nosuch": [0, 0]})["ok"]
    assert not s.move({"up": [0, "x"]})["ok"]


def test_describe_gives_typed_fields(graph_file, reg, tmp_path):
    d = _session(graph_file, reg, tmp_path).describe()
    assert d["nodes"]["up"] == {"op": "lift@1", "inputs": {"mesh": "base.mesh"}, "params": {"dz": 2.0}}
    fields = {f["name"]: f for f in d["types"]["lift@1"]["settings"]}
    assert fields["dz"]["kind"] == "float" and fields["dz"]["range"] == [-10.0, 10.0]
    assert fields["mode"] == {"name": "mode", "type": "'add' | 'scale'", "required": False, "file": None,
                              "kind": "choice", "options": ["add", "scale"], "default": "add"}
    assert fields["keep"]["kind"] == "bool" and "range" not in fields["keep"]
    assert d["types"]["lift@1"]["outputs"] == [{"name": "mesh", "type": "QuadMesh", "mesh": True}]
    assert set(d["layout"]) == set(d["nodes"])


def test_node_type_fields_of_the_built_in_nodes():
    from quadnodes import nodes  # noqa: F401
    from quadnodes.graph import REGISTRY

    f = {s["name"]: s for s in node_type_info(REGISTRY.get("fair"))["settings"]}
    assert f["iterations"]["kind"] == "int" and f["fix"]["kind"] == "choice"
    assert f["threshold"]["kind"] == "number_or_list" and f["weight_scale"]["kind"] == "choice"
    p = {s["name"]: s for s in node_type_info(REGISTRY.get("laplacian"))["settings"]}
    assert p["lam"]["range"] == [0.0, 1.0]  # a declared range with two finite ends: a slider
    t = {s["name"]: s for s in node_type_info(REGISTRY.get("torus_patch"))["settings"]}
    assert t["u_range"] == {**t["u_range"], "kind": "list", "item": "float", "nullable": True}


def test_auto_layout_puts_each_node_right_of_its_inputs(graph_file, reg):
    g = loads(graph_file.read_text(), fmt="toml", registry=reg)
    pos = auto_layout(g)
    for spec in g.nodes.values():
        for c in spec.inputs.values():
            assert pos[c.node][0] < pos[spec.id][0]
    assert auto_layout(g, saved={"up": [1.0, 2.0]})["up"] == [1.0, 2.0]


def test_encode_mesh_is_compact_and_exact_to_float32():
    m = grid(30, 40, height=np.random.default_rng(3).normal(size=(30, 40)))
    d = encode_mesh(m)
    v = np.frombuffer(base64.b64decode(d["vertices"]), dtype="<f4").reshape(-1, 3)
    f = np.frombuffer(base64.b64decode(d["faces"]), dtype="<i4").reshape(-1, 4)
    assert np.array_equal(v, m.vertices.astype(np.float32)) and np.array_equal(f, m.faces)
    e = np.frombuffer(base64.b64decode(d["edges"]), dtype="<i4").reshape(-1, 2)
    assert np.array_equal(e, m.topology.edges)
    assert len(np.frombuffer(base64.b64decode(d["planarity"]), dtype="<f4")) == m.n_faces
    plain = encode_mesh(m, encoding="list")
    assert len(d["vertices"]) == 4 * -(-m.n_vertices * 12 // 3)  # 4 bytes a coordinate, in base64
    assert len(json.dumps(d)) < 0.6 * len(json.dumps(plain))


def test_superseded_runs_stop_at_the_next_node(graph_file, reg, tmp_path, calls):
    s = _session(graph_file, reg, tmp_path)
    _wait(s)
    calls.clear()
    seen = []

    def listener(ev):
        if ev["type"] == "node" and ev["status"] == "running" and ev["id"] == "up" and not seen:
            seen.append(ev)
            s.set_settings("up", {"dz": 9.0})  # a newer edit while this run is on its way

    s.set_settings("up", {"dz": 4.0})
    s.subscribe(listener)
    from quadnodes.server.session import _Superseded

    with pytest.raises(_Superseded):
        s.run_once()
    info = _wait(s)
    assert info["state"] == "done" and s.output("up", "mesh").vertices[0, 2] == 9.0


def test_a_graph_file_that_cannot_be_written_refuses_the_edit(graph_file, reg, tmp_path, monkeypatch):
    from quadnodes.errors import ExportError
    from quadnodes.server import session as mod

    s = _session(graph_file, reg, tmp_path)
    before = graph_file.read_bytes()

    def fail(path, text):
        raise ExportError(f"cannot write {path}: disk full")

    monkeypatch.setattr(mod, "write_text_atomic", fail)
    res = s.set_settings("up", {"dz": 4.0})
    assert not res["ok"] and "disk full" in res["error"] and graph_file.read_bytes() == before
    monkeypatch.undo()
    assert s.graph.nodes["up"].params["dz"] == 2.0
    assert s.set_settings("up", {"dz": 4.0})["ok"] and "dz = 4.0" in graph_file.read_text()
