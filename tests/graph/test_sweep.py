"""quadnodes sweep on Dask: same results as run --set, shared upstream once, errors as rows, a real cluster."""

from __future__ import annotations

import csv
import importlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import meshio
import numpy as np
import pytest

import quadnodes.nodes  # noqa: F401  (registers the built-in nodes)
from quadnodes.cli import main
from quadnodes.errors import GraphError
from quadnodes.graph.sweep import pareto_front, parse_vary, variants
from processes import ctrl_c_able

pytest.importorskip("distributed")

ROOT = Path(__file__).resolve().parents[2]

# A node that appends a line to a file each time it runs: an independent count of executions in any process.
COUNTER = '''
from quadnodes.graph import node
from quadnodes.mesh import QuadMesh


@node("count_calls", outputs=("mesh",))
def count_calls(mesh: QuadMesh, *, path: str) -> QuadMesh:
    """Pass the mesh on; append a line to ``path`` (counts executions across processes).

    Parameters
    ----------
    path : str
        The counter file.
    """
    with open(path, "a", encoding="utf-8") as f:
        f.write("ran\\n")
    return mesh
'''

GRAPH = '''format = "quadnodes-graph"
version = 1

[nodes.clean]
op = "{source_op}"
{source_inputs}params = {source_params}

[nodes.counted]
op = "count_calls@1"
inputs = {{ mesh = "clean.mesh" }}
params = {{ path = "{counter}" }}

[nodes.noisy]
op = "perturb@1"
inputs = {{ mesh = "counted.mesh" }}
params = {{ tangential = 0.2, normal = 0.1, seed = 1, fix = "corners" }}

[nodes.fair]
op = "fair@1"
inputs = {{ mesh = "noisy.mesh" }}
params = {{ iterations = 2 }}

[nodes.metrics]
op = "compare@1"
inputs = {{ original = "noisy.mesh", result = "fair.mesh", reference = "clean.mesh" }}

[nodes.report]
op = "export_report@1"
inputs = {{ data = "metrics.metrics" }}
params = {{ path = "metrics.json" }}

[nodes.obj]
op = "export_obj@1"
inputs = {{ mesh = "fair.mesh" }}
params = {{ path = "fair.obj" }}
'''


@pytest.fixture(scope="module")
def counter_module(tmp_path_factory):
    """The counting node in an importable module; workers find it (and this worktree) through PYTHONPATH."""
    d = tmp_path_factory.mktemp("sweepnodes")
    (d / "qn_sweep_counter.py").write_text(COUNTER)
    sys.path.insert(0, str(d))
    importlib.import_module("qn_sweep_counter")
    old = os.environ.get("PYTHONPATH")
    os.environ["PYTHONPATH"] = os.pathsep.join([str(ROOT), str(d)] + ([old] if old else []))
    yield d
    if old is None:
        os.environ.pop("PYTHONPATH", None)
    else:
        os.environ["PYTHONPATH"] = old


def _graph(tmp_path: Path, *, surface: bool) -> tuple[Path, Path]:
    counter = tmp_path / "counter.txt"
    if surface:  # a build123d face crosses to the sampling task (pickled as BREP)
        text = GRAPH.format(source_op="sample@1", source_inputs='inputs = { face = "surface.face" }\n',
                            source_params="{ nu = 6, nv = 5 }", counter=counter)
        text = text.replace("[nodes.clean]", '[nodes.surface]\nop = "saddle@1"\n\n[nodes.clean]')
    else:
        text = GRAPH.format(source_op="grid@1", source_inputs="", source_params="{ rows = 5, cols = 6 }",
                            counter=counter)
    path = tmp_path / "g.toml"
    path.write_text(text)
    return path, counter


def _rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


# ----------------------------------------------------------------------------- parsing, no cluster
def test_parse_vary_lists_and_ranges():
    assert parse_vary("fair.weight=0.1,0.3,1") == ("fair.weight", [0.1, 0.3, 1])
    assert parse_vary("noisy.seed=1:20")[1] == list(range(1, 21))
    assert parse_vary("fair.weight=0.1:0.5:5")[1] == [0.1, 0.2, 0.3, 0.4, 0.5]
    assert parse_vary("fair.deviation=[0.1,0.05],[0.2, 0.1]")[1] == [[0.1, 0.05], [0.2, 0.1]]
    assert parse_vary('png.titles=["a,b"]')[1] == [["a,b"]]


@pytest.mark.parametrize("item, words", [
    ("noisy.seed=1:x", ["noisy.seed", "range"]),
    ("noisy.seed=5:1", ["noisy.seed", "below the start"]),
    ("fair.weight=0.1:1", ["fair.weight", "count"]),
    ("fair.weight=0:1:1", ["fair.weight", "count of at least 2"]),
    ("fair.weight=0.1,,0.3", ["fair.weight", "value 2", "empty"]),
    ("fair.weight=", ["fair.weight", "no values"]),
    ("fairweight=1,2", ["fairweight=1,2", "node.setting"]),
    ("fair.weight", ["fair.weight", "node.setting"]),
])
def test_parse_vary_errors_name_the_setting(item, words):
    with pytest.raises(GraphError) as e:
        parse_vary(item)
    for w in words:
        assert w in str(e.value)


def test_variants_product_zip_and_lengths():
    assert len(variants({"a.x": "1:3", "b.y": [0.1, 0.2]})) == 6
    assert variants({"a.x": [1, 2], "b.y": [3, 4]}, zip=True) == [{"a.x": 1, "b.y": 3}, {"a.x": 2, "b.y": 4}]
    with pytest.raises(GraphError, match="a.x has 2 values, b.y has 3"):
        variants({"a.x": [1, 2], "b.y": [1, 2, 3]}, zip=True)
    with pytest.raises(GraphError, match="at least one setting"):
        variants({})


def test_a_sweep_too_large_to_run_is_refused_before_anything_is_built():
    # a mistyped range would have built a list of 10¹² seeds (the memory filled) or started 10⁶ runs
    with pytest.raises(GraphError, match=r"noisy.seed: range '0:1000000000000' has 1,000,000,000,001 values"):
        parse_vary("noisy.seed=0:1000000000000")
    with pytest.raises(GraphError, match=r"fair.weight: range .* has 1,000,000 values; a sweep runs at most 10,000"):
        parse_vary("fair.weight=1:1000000:1000000")
    with pytest.raises(GraphError, match=r"200 \(a.x\) × 200 \(b.y\) = 40,000 variants"):
        variants({"a.x": "1:200", "b.y": "1:200"})
    assert len(variants({"a.x": "1:100", "b.y": "1:100"})) == 10_000  # the limit itself runs
    assert len(variants({"a.x": "1:10000", "b.y": "1:10000"}, zip=True)) == 10_000


def test_pareto_front_is_the_non_dominated_set():
    rng = np.random.default_rng(3)
    x, y = rng.random(60), rng.random(60)
    x[5] = np.nan
    front = pareto_front(x, y)
    for i in range(60):
        dominated = np.any((x <= x[i]) & (y <= y[i]) & ((x < x[i]) | (y < y[i])))
        assert front[i] == (np.isfinite(x[i]) and not dominated)


def test_cli_bad_vary_names_the_setting_before_any_cluster_starts(tmp_path, counter_module, capsys):
    g, _ = _graph(tmp_path, surface=False)
    cases = [
        (["--vary", "noisy.seed=1:x"], "noisy.seed"),
        (["--vary", "fair.wieght=0.1,0.3"], "did you mean 'weight'"),
        (["--vary", "noisy.seed=a,b"], "setting 'seed'"),
        (["--vary", "nois.seed=1,2"], "no node 'nois'"),
        (["--vary", "fair.weight=1,2", "--vary", "noisy.seed=1:3", "--zip"], "fair.weight has 2 values"),
    ]
    for extra, words in cases:
        t0 = time.perf_counter()
        assert main(["sweep", str(g), "--out", str(tmp_path / "o"), *extra]) == 1
        err = capsys.readouterr().err
        assert words in err, (extra, err)
        assert time.perf_counter() - t0 < 30  # no cluster was started for a bad command
    assert not (tmp_path / "o" / "sweep.csv").exists()


# ----------------------------------------------------------------------------- embedded cluster
def test_sweep_equals_run_set_shares_upstream_and_survives_a_broken_variant(tmp_path, counter_module, capsys):
    g, counter = _graph(tmp_path, surface=True)
    out = tmp_path / "sweep"
    args = ["sweep", str(g), "--vary", "fair.weight=0.3,-1,1", "--vary", "noisy.seed=1:2", "--out", str(out),
            "--workers", "2", "--plot", "x=metrics.metrics.zigzag_max", "y=metrics.metrics.displacement_max"]
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "[6/6]" in printed and "dashboard:" in printed
    rows = _rows(out / "sweep.csv")
    assert [(r["fair.weight"], r["noisy.seed"]) for r in rows] == [
        ("0.3", "1"), ("0.3", "2"), ("-1", "1"), ("-1", "2"), ("1", "1"), ("1", "2")]
    # the upstream (surface, sampling, the counting node) ran once for six variants, in whichever worker
    assert counter.read_text().count("ran") == 1
    for r in rows:
        if r["fair.weight"] == "-1":
            assert r["status"] == "error" and "node 'fair'" in r["error"] and "weight" in r["error"]
            continue
        assert r["status"] == "ok" and r["error"] == ""
        folder = out / r["folder"]
        assert r["folder"] == f"fair.weight={r['fair.weight']}__noisy.seed={r['noisy.seed']}"
        assert r["obj.path"] == f"{r['folder']}/fair.obj"
        # the same variant run on its own with --set: byte-equal OBJ, equal metrics
        one = tmp_path / f"run-{r['folder']}"
        assert main(["run", str(g), "--out", str(one), "--no-cache",
                     "--set", f"fair.weight={r['fair.weight']}", "--set", f"noisy.seed={r['noisy.seed']}"]) == 0
        assert (folder / "fair.obj").read_bytes() == (one / "fair.obj").read_bytes()
        metrics = json.loads((one / "metrics.json").read_text())
        assert json.loads((folder / "metrics.json").read_text()) == metrics
        for k, v in metrics.items():
            assert float(r[f"metrics.metrics.{k}"]) == v, k
        assert float(r["fair.report.iterations.0.weight"]) == float(r["fair.weight"])
        m = meshio.read(folder / "fair.obj")
        assert len(m.points) == 30 and sum(len(c.data) for c in m.cells) == 20
    capsys.readouterr()
    # the two seeds give different meshes, the weights too
    objs = {r["folder"]: (out / r["folder"] / "fair.obj").read_bytes() for r in rows if r["status"] == "ok"}
    assert len(set(objs.values())) == 4
    manifest = json.loads((out / "sweep.json").read_text())
    assert manifest["graph_file_sha256"] and manifest["versions"]["dask"] and manifest["variants"] == 6
    assert manifest["status"] == {"ok": 4, "error": 2, "not run": 0}
    assert "--vary=fair.weight=0.3,-1,1" in manifest["command"]
    from PIL import Image

    with Image.open(out / "sweep.png") as im:
        assert im.size[0] > 500 and im.size[1] > 400
    page = (out / "sweep.html").read_text()
    assert "plotly.js v" in page and "Pareto front" in page and "fair.weight=0.3__noisy.seed=1" in page

    # run again: nothing that finished is computed again, the files stay
    before = {k: (out / k / "fair.obj").stat().st_mtime_ns for k in objs}
    counted = counter.read_text().count("ran")  # 1 + the four single runs above
    assert main(args) == 0
    assert counter.read_text().count("ran") == counted
    rows2 = _rows(out / "sweep.csv")
    for r1, r2 in zip(rows, rows2):
        assert r1["status"] == r2["status"]
        if r2["status"] == "ok":
            assert r2["ran"] == "0"
            assert r2["metrics.metrics.zigzag_max"] == r1["metrics.metrics.zigzag_max"]
    assert {k: (out / k / "fair.obj").stat().st_mtime_ns for k in objs} == before


def test_python_api_sweep_zip_and_executed_list(tmp_path, counter_module):
    from quadnodes.graph import load

    g, counter = _graph(tmp_path, surface=False)
    res = load(g).sweep({"fair.weight": [0.3, 1.0], "fair.iterations": [1, 2]}, zip=True, out=tmp_path / "o",
                        cache=False, workers=1)
    assert [r.status for r in res.rows] == ["ok", "ok"]
    assert [r.folder for r in res.rows] == ["fair.weight=0.3__fair.iterations=1", "fair.weight=1.0__fair.iterations=2"]
    ran = res.ran_nodes
    assert ran["clean"] == ran["counted"] == ran["noisy"] == 1  # shared by both variants
    assert ran["fair"] == ran["metrics"] == ran["obj"] == 2
    assert counter.read_text().count("ran") == 1
    assert res.node_results == 14
    assert not (tmp_path / "o" / ".cache").exists()


def test_an_interrupted_sweep_continues_without_recomputing(tmp_path, counter_module):
    import signal

    g, counter = _graph(tmp_path, surface=False)
    out = tmp_path / "o"
    cmd = [sys.executable, "-c", "import sys, qn_sweep_counter; from quadnodes.cli import main; sys.exit(main())",
           "sweep", str(g),
           "--vary", "fair.iterations=1:8", "--out", str(out), "--workers", "1"]
    p = subprocess.Popen(cmd, env=dict(os.environ), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         preexec_fn=ctrl_c_able)
    try:
        for line in p.stdout:
            if "[2/8]" in line:
                break
        p.send_signal(signal.SIGINT)  # Ctrl-C after two variants
        _, err = p.communicate(timeout=120)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    assert p.returncode == 130 and "continues the sweep" in err, err[-2000:]
    first = {r["folder"]: r["status"] for r in _rows(out / "sweep.csv")}
    finished = [f for f, st in first.items() if st == "ok"]
    assert len(finished) >= 2 and len(first) == 8
    from quadnodes.graph import load

    res = load(g).sweep({"fair.iterations": "1:8"}, out=out, workers=1)
    assert [r.status for r in res.rows] == ["ok"] * 8
    assert counter.read_text().count("ran") == 1  # the shared upstream is not run again
    for r in res.rows:
        if r.folder in finished:
            assert r.ran == 0, r.folder  # a variant done before the interruption: nothing recomputed
    assert "clean" not in res.ran_nodes and "noisy" not in res.ran_nodes


# ----------------------------------------------------------------------------- an existing cluster
def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_sweep_on_a_running_dask_scheduler_and_two_workers(tmp_path, counter_module, capsys):
    env = dict(os.environ)
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    log = open(tmp_path / "cluster.log", "w")
    procs = []
    try:
        procs.append(subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", str(port),
             "--no-dashboard", "--no-show"], env=env, stdout=log, stderr=subprocess.STDOUT))
        for _ in range(2):
            procs.append(subprocess.Popen(
                [sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads", "1",
                 "--nworkers", "1", "--host", "127.0.0.1", "--no-dashboard", "--no-nanny"],
                env=env, stdout=log, stderr=subprocess.STDOUT))
        from distributed import Client

        with Client(address, timeout="60s") as c:
            c.wait_for_workers(2, timeout=120)
        g, counter = _graph(tmp_path, surface=False)
        out = tmp_path / "o"
        assert main(["sweep", str(g), "--vary", "noisy.seed=1,2", "--vary", "fair.weight=0.3,1",
                     "--scheduler", address, "--out", str(out)]) == 0
        printed = capsys.readouterr().out
        assert address in printed and "[4/4]" in printed
        rows = _rows(out / "sweep.csv")
        assert [r["status"] for r in rows] == ["ok"] * 4
        assert counter.read_text().count("ran") == 1
        for r in rows:
            m = meshio.read(out / r["obj.path"])
            assert m.points.shape == (30, 3)
        assert json.loads((out / "sweep.json").read_text())["scheduler"] == address
    finally:
        for p in procs:
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        log.close()
