"""The HTTP API without a browser: Starlette's TestClient, and a real `quadnodes serve` process."""

from __future__ import annotations

import base64
import json
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest
from starlette.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from quadnodes.server import Session, create_app
from processes import ctrl_c_able

TOKEN = "test-token-123"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def client(graph_file, reg, tmp_path):
    session = Session(graph_file, out=tmp_path / "out", registry=reg)
    app = create_app(session, token=TOKEN, poll_interval=0.05)
    with TestClient(app, base_url="http://127.0.0.1:8765") as c:
        c.session = session
        _settled(c)
        yield c


def _settled(c, timeout: float = 60) -> dict:
    """The run of the latest graph revision, once it is over."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        r = c.get("/api/run", headers=AUTH).json()
        if r["state"] in ("done", "failed") and r["revision"] == r["graph_revision"]:
            return r
        time.sleep(0.02)
    raise TimeoutError(r)


@pytest.mark.parametrize("route", ["/", "/static/app.js", "/static/plotly.min.js", "/api/graph", "/api/run",
                                   "/api/palette", "/api/mesh/up/mesh"])
def test_every_route_needs_the_token(client, route):
    assert client.get(route).status_code == 401
    assert client.get(route, headers={"Authorization": "Bearer wrong"}).status_code == 401
    assert client.get(route + "?token=wrong").status_code == 401
    assert client.get(route + f"?token={TOKEN}").status_code == 200
    assert client.get(route, headers=AUTH).status_code == 200


def test_state_changing_routes_need_the_token(client, graph_file):
    before = graph_file.read_bytes()
    assert client.post("/api/nodes/up/settings", json={"dz": 1}).status_code == 401
    assert client.post("/api/nodes", json={"op": "plane"}).status_code == 401
    assert client.delete("/api/nodes/other").status_code == 401
    assert client.post("/api/connect", json={"node": "n", "port": "mesh", "source": "base.mesh"}).status_code == 401
    assert client.post("/api/layout", json={"positions": {"up": [0, 0]}}).status_code == 401
    assert graph_file.read_bytes() == before


def test_the_page_and_its_assets_ship_in_the_package(client):
    page = client.get("/", headers=AUTH)
    assert page.status_code == 200 and "toy.toml" in page.text and "/static/app.js" in page.text
    assert "cdn" not in page.text.lower()
    js = client.get("/static/plotly.min.js", headers=AUTH)
    assert js.status_code == 200 and len(js.content) > 1_000_000  # the installed plotly package's copy
    assert client.get("/static/../session.py", headers=AUTH).status_code == 404
    assert client.get("/static/nosuch.js", headers=AUTH).status_code == 404


def test_get_graph_is_the_file_model(client):
    g = client.get("/api/graph", headers=AUTH).json()
    assert g["file"] == "toy.toml" and g["format"] == "toml"
    assert g["nodes"]["up"] == {"op": "lift@1", "inputs": {"mesh": "base.mesh"}, "params": {"dz": 2.0}}
    assert g["order"][0] == "base" and set(g["layout"]) == set(g["nodes"])
    assert {t["op"] for t in client.get("/api/palette", headers=AUTH).json()} >= {"plane@1", "lift@1", "boom@1"}


def test_post_settings_reruns_only_downstream_and_writes_the_file(client, graph_file):
    res = client.post("/api/nodes/up/settings", json={"dz": -1.5}, headers=AUTH)
    assert res.status_code == 200 and res.json()["ok"]
    assert "dz = -1.5" in graph_file.read_text() and "# a small grid" in graph_file.read_text()
    run = _settled(client)
    assert run["state"] == "done"
    assert run["ran"] == ["up", "n", "save"] and sorted(run["cached"]) == ["base", "other"]
    assert all(run["nodes"][k]["seconds"] is not None for k in run["nodes"])
    mesh = client.get("/api/mesh/up/mesh", headers=AUTH).json()
    v = np.frombuffer(base64.b64decode(mesh["vertices"]), dtype="<f4").reshape(-1, 3)
    assert mesh["n_vertices"] == 20 and np.allclose(v[:, 2], -1.5)
    plain = client.get("/api/mesh/up/mesh?encoding=list", headers=AUTH).json()
    assert plain["faces"][0] == [0, 1, 6, 5] and np.allclose(np.array(plain["vertices"])[:, 2], -1.5)


def test_an_invalid_edit_is_refused_with_the_message(client, graph_file):
    before = graph_file.read_bytes()
    res = client.post("/api/nodes/up/settings", json={"dz": "lots"}, headers=AUTH)
    assert res.status_code == 422
    body = res.json()
    assert body["ok"] is False and body["node"] == "up"
    assert body["error"] == "toy.toml line 9: node 'up' (lift@1): setting 'dz': expected float, got str 'lots'"
    assert graph_file.read_bytes() == before
    assert client.get("/api/graph", headers=AUTH).json()["errors"] == {"up": body["error"]}
    assert client.post("/api/nodes/up/settings", content=b"{nope", headers=AUTH).status_code == 409
    assert client.post("/api/nodes/nosuch/settings", json={"dz": 1}, headers=AUTH).status_code == 422


def test_add_connect_disconnect_delete_over_http(client, graph_file):
    res = client.post("/api/nodes", json={"op": "lift", "inputs": {"mesh": "base.mesh"}, "pos": [600, 20]},
                      headers=AUTH).json()
    assert res["ok"] and res["id"] == "lift1"
    assert client.post("/api/connect", json={"node": "other", "port": "mesh", "source": "lift1.mesh"},
                       headers=AUTH).json()["ok"]
    run = _settled(client)
    assert run["ran"] == ["other"] or run["ran"] == ["lift1", "other"], run  # lift1 may have run for the add
    assert "up" in run["cached"] and client.session.output("other", "n") == 20
    res = client.post("/api/disconnect", json={"node": "other", "port": "mesh"}, headers=AUTH)
    assert res.status_code == 422 and "missing required input 'mesh'" in res.json()["error"]
    assert client.post("/api/connect", json={"node": "other", "port": "mesh", "source": "base.mesh"},
                       headers=AUTH).json()["ok"]
    assert client.delete("/api/nodes/lift1", headers=AUTH).json()["ok"]
    assert "lift1" not in graph_file.read_text()
    assert client.post("/api/nodes", json={"nope": 1}, headers=AUTH).status_code == 409


def test_failures_are_reported_per_node(client):
    client.post("/api/nodes", json={"op": "boom", "id": "bad", "inputs": {"mesh": "up.mesh"}}, headers=AUTH)
    run = _settled(client)
    assert run["state"] == "failed" and run["failed"] == ["bad"]
    assert "boom went off on purpose" in run["nodes"]["bad"]["error"]
    res = client.get("/api/mesh/bad/mesh", headers=AUTH)
    assert res.status_code == 409 and "not available (failed)" in res.json()["error"]
    assert client.get("/api/mesh/nosuch/mesh", headers=AUTH).status_code == 404
    assert client.get("/api/mesh/n/n", headers=AUTH).status_code == 409  # an int, not a mesh


def test_path_traversal_is_refused(client, graph_file):
    res = client.post("/api/nodes/save/settings", json={"path": "../../../etc/x"}, headers=AUTH).json()
    assert not res["ok"] and "output folder" in res["error"]
    assert "etc/x" not in graph_file.read_text()


def test_the_websocket_pushes_events_and_checks_origin_and_token(client):
    with client.websocket_connect(f"ws://127.0.0.1:8765/api/events?token={TOKEN}",
                                  headers={"Origin": "http://127.0.0.1:8765"}) as ws:
        assert ws.receive_json()["type"] == "hello"
        client.post("/api/nodes/up/settings", json={"dz": 7.0}, headers=AUTH)
        seen = []
        while not any(e.get("type") == "run" and e.get("state") == "done" for e in seen):
            seen.append(ws.receive_json())
        kinds = {e["type"] for e in seen}
        assert {"graph", "node", "run"} <= kinds
        assert any(e["type"] == "node" and e["id"] == "up" and e["status"] == "ran" for e in seen)
    for url, headers in ((f"ws://127.0.0.1:8765/api/events?token={TOKEN}", {"Origin": "http://evil.example"}),
                         ("/api/events", {}), ("/api/events?token=wrong", {})):
        with pytest.raises(WebSocketDisconnect):
            with client.websocket_connect(url, headers=headers) as ws:
                ws.receive_json()


def test_an_edit_in_an_editor_reaches_the_api(client, graph_file):
    rev = client.get("/api/graph", headers=AUTH).json()["revision"]
    graph_file.write_text(graph_file.read_text().replace("dz = 2.0", "dz = 8.0") + "# edited\n")
    deadline = time.monotonic() + 20
    while client.get("/api/graph", headers=AUTH).json()["revision"] == rev:
        assert time.monotonic() < deadline
        time.sleep(0.05)
    assert client.get("/api/graph", headers=AUTH).json()["nodes"]["up"]["params"]["dz"] == 8.0
    _settled(client)
    v = client.get("/api/mesh/up/mesh?encoding=list", headers=AUTH).json()["vertices"]
    assert v[0][2] == 8.0


# ------------------------------------------------------------ a real server
SMALL = """\
# grid -> noise -> fairing, built-in nodes only
format = "quadnodes-graph"
version = 1

[nodes.mesh]
op = "grid@1"
params = { rows = 8, cols = 9, spacing = 100.0 }

[nodes.noisy]
op = "perturb@1"
inputs = { mesh = "mesh.mesh" }
params = { tangential = 0.2, normal = 0.1, seed = 3, fix = "corners" }

[nodes.fair]
op = "fair@1"
inputs = { mesh = "noisy.mesh" }
params = { iterations = 2 }

[nodes.obj]
op = "export_obj@1"
inputs = { mesh = "fair.mesh" }
params = { path = "fair.obj" }
"""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}


def _call(url: str, *, method: str = "GET", data: object = None, token: str | None = None) -> tuple[int, dict]:
    req = urllib.request.Request(url, method=method, data=None if data is None else json.dumps(data).encode())
    if token:
        req.add_header("Authorization", f"Bearer {token}")
    if data is not None:
        req.add_header("Content-Type", "application/json")
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read())


def test_quadnodes_serve_runs_a_real_server_and_stops_on_ctrl_c(tmp_path):
    g = tmp_path / "small.toml"
    g.write_text(SMALL)
    port = _free_port()
    proc = subprocess.Popen([sys.executable, "-m", "quadnodes", "serve", str(g), "--no-browser", "--port", str(port),
                             "--out", str(tmp_path / "out")], cwd=tmp_path, env=_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=ctrl_c_able)
    try:
        assert proc.stdout is not None
        lines = [proc.stdout.readline(), proc.stdout.readline()]
        url = lines[1].strip()
        assert url.startswith(f"http://127.0.0.1:{port}/?token="), lines
        token = url.split("token=", 1)[1]
        base = f"http://127.0.0.1:{port}"
        deadline = time.monotonic() + 60
        while True:
            try:
                status, run = _call(f"{base}/api/run", token=token)
                if run["state"] == "done":
                    break
            except (urllib.error.URLError, ConnectionError):
                pass
            assert time.monotonic() < deadline and proc.poll() is None, proc.stderr.read() if proc.poll() else ""
            time.sleep(0.1)
        assert (tmp_path / "out" / "fair.obj").is_file()  # written where quadnodes run writes it
        assert _call(f"{base}/api/graph")[0] == 401
        status, res = _call(f"{base}/api/nodes/fair/settings", method="POST", data={"iterations": 1}, token=token)
        assert status == 200 and res["ok"]
        assert "iterations = 1" in g.read_text()
        while True:
            status, run = _call(f"{base}/api/run", token=token)
            if run["revision"] == res["revision"] and run["state"] == "done":
                break
            time.sleep(0.05)
        assert run["ran"] == ["fair", "obj"] and run["cached"] == ["mesh", "noisy"]
        status, mesh = _call(f"{base}/api/mesh/fair/mesh", token=token)
        assert status == 200 and mesh["n_vertices"] == 72
        from websockets.sync.client import connect

        # Ctrl-C while a page is connected to the event socket
        with connect(f"ws://127.0.0.1:{port}/api/events?token={token}", origin=base, ping_interval=None) as ws:
            assert json.loads(ws.recv(timeout=30))["type"] == "hello"
            proc.send_signal(signal.SIGINT)
            out, err = proc.communicate(timeout=30)
        assert proc.returncode == 0, err
        assert "stopped" in out and "Traceback" not in err
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
