"""The note of the last complete run: an unchanged graph is recognised without loading its nodes."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

from quadnodes.graph import Cache, load, runlog
from quadnodes.graph.run import RunRecord

ROOT = Path(__file__).resolve().parents[2]

GRAPH = """\
format = "quadnodes-graph"
version = 1

[nodes.src]
op = "read_num@1"
params = { path = "x.txt" }

[nodes.twice]
op = "scale@1"
inputs = { x = "src.out" }

[nodes.out]
op = "write_num@1"
inputs = { x = "twice.out" }
params = { path = "y.txt" }
"""


def _setup(tmp_path, reg):
    (tmp_path / "x.txt").write_text("3\n")
    g = tmp_path / "g.toml"
    g.write_text(GRAPH)
    graph = load(g, registry=reg)
    out = tmp_path / "out"
    out.mkdir()
    graph.set("out", path=str(out / "y.txt"))
    cache = Cache(tmp_path / "cache")
    result = graph.run(cache=cache)
    sig = runlog.signature(g, out=out, overrides={})
    files = [g, tmp_path / "x.txt", out / "y.txt"]
    assert runlog.note(cache.directory, sig, records=result.records, files=files, written=[out / "y.txt"])
    return g, out, cache, sig


def test_a_noted_run_replays_while_nothing_changed(tmp_path, reg):
    g, out, cache, sig = _setup(tmp_path, reg)
    recs, written = runlog.replay(cache.directory, sig)
    assert [r[0] for r in recs] == ["src", "twice", "out"] and written == [str((out / "y.txt").resolve())]
    assert runlog.signature(g, out=out, overrides={}) == sig


def test_any_change_voids_the_note(tmp_path, reg):
    g, out, cache, sig = _setup(tmp_path, reg)
    (tmp_path / "x.txt").write_text("4\n")  # an input file
    assert runlog.replay(cache.directory, sig) is None
    (tmp_path / "x.txt").write_text("3\n")
    assert runlog.replay(cache.directory, sig) is not None
    (out / "y.txt").write_text("edited\n")  # an output file
    assert runlog.replay(cache.directory, sig) is None
    (out / "y.txt").unlink()
    assert runlog.replay(cache.directory, sig) is None


def test_a_cleared_cache_or_another_graph_voids_the_note(tmp_path, reg):
    g, out, cache, sig = _setup(tmp_path, reg)
    assert runlog.signature(g, out=out, overrides={"twice.factor": 3}) != sig
    assert runlog.signature(g, out=tmp_path / "elsewhere", overrides={}) != sig
    g.write_text(GRAPH + "# a comment\n")
    assert runlog.signature(g, out=out, overrides={}) != sig
    assert runlog.signature(tmp_path / "missing.toml", out=out, overrides={}) is None
    assert runlog.replay(cache.directory, None) is None
    cache.clear(disk=True)
    assert runlog.replay(cache.directory, sig) is None


def test_a_run_with_an_uncacheable_node_is_not_noted(tmp_path):
    rec = RunRecord("a", "opaque@1", "ran", 0.1, None)
    assert runlog.note(tmp_path, "s" * 64, records=[rec], files=[]) is None
    assert not (tmp_path / "runs").exists()
    (tmp_path / "runs").mkdir()
    (tmp_path / "runs" / ("t" * 64 + ".json")).write_text("{not json")
    assert runlog.replay(tmp_path, "t" * 64) is None


def test_quadnodes_run_of_an_unchanged_graph_loads_no_node_library(tmp_path):
    g = tmp_path / "g.toml"
    g.write_text('format = "quadnodes-graph"\nversion = 1\n[nodes.mesh]\nop = "grid@1"\nparams = { rows = 4 }\n'
                 '[nodes.obj]\nop = "export_obj@1"\ninputs = { mesh = "mesh.mesh" }\nparams = { path = "m.obj" }\n')
    code = ("import sys; from quadnodes.cli import main; rc = main(sys.argv[1:]); "
            "print('scipy loaded' if 'scipy' in sys.modules else 'scipy not loaded'); sys.exit(rc)")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    args = [sys.executable, "-c", code, "run", str(g), "--out", str(tmp_path / "out")]
    first = subprocess.run(args, capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300)
    assert first.returncode == 0 and "2 ran" in first.stdout and "scipy loaded" in first.stdout, first.stderr
    second = subprocess.run(args, capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300)
    assert "0 ran, 2 from cache (graph, input files and outputs unchanged" in second.stdout, second.stdout
    assert "unchanged out/m.obj" in second.stdout and "scipy not loaded" in second.stdout
    (tmp_path / "out" / "m.obj").write_text("# edited by hand\n")
    third = subprocess.run(args, capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300)
    assert "1 ran, 1 from cache" in third.stdout and re.search(r"wrote +out/m.obj", third.stdout), third.stdout
    assert (tmp_path / "out" / "m.obj").read_text().startswith(("#", "v")) and "edited" not in (
        tmp_path / "out" / "m.obj").read_text()
