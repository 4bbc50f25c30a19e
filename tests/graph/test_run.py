"""The runner and the cache: what re-runs after which change, disk reuse, errors, progress."""

from __future__ import annotations

import os
import warnings

import numpy as np
import pytest

from quadnodes.errors import GraphError, NodeError
from quadnodes.graph import Cache, CacheWarning, Graph, keys, load, run, save
from quadnodes.graph.cache import CacheEntry
from quadnodes.mesh import grid


def _statuses(result):
    return {r.id: r.status for r in result.records}


def _chain(reg):
    """a -> s1 -> s2, b -> s3, and sum(s2, s3)."""
    g = Graph(registry=reg)
    a = g.add("num", id="a", value=1)
    b = g.add("num", id="b", value=10)
    s1 = g.add("scale", a, id="s1")
    s2 = g.add("scale", s1, id="s2")
    s3 = g.add("scale", b, id="s3")
    g.add("add", s2, s3, id="sum")
    return g


def test_changing_one_setting_reruns_exactly_that_node_and_its_downstream(reg):
    g = _chain(reg)
    cache = Cache()
    first = run(g, cache=cache)
    assert first["sum.out"] == 1 * 4 + 10 * 2
    assert set(_statuses(first).values()) == {"ran"}
    again = run(g, cache=cache)
    assert set(_statuses(again).values()) == {"cached"}
    assert again["sum.out"] == first["sum.out"]
    changed = run(g, cache=cache, overrides={"s1.factor": 3})
    assert _statuses(changed) == {"a": "cached", "b": "cached", "s1": "ran", "s2": "ran", "s3": "cached", "sum": "ran"}
    assert changed["sum.out"] == 1 * 6 + 20
    # the keys chain: only s1 and below changed
    k0, k1 = keys(g), keys(g, overrides={"s1.factor": 3})
    assert {n for n in k0 if k0[n] != k1[n]} == {"s1", "s2", "sum"}
    assert {r.id: r.key for r in changed.records} == k1
    # back to the old setting: everything from the cache again
    assert set(_statuses(run(g, cache=cache)).values()) == {"cached"}


def test_equal_settings_written_differently_share_a_key(reg):
    g1, g2 = Graph(registry=reg), Graph(registry=reg)
    g1.add("scale", g1.add("num", value=1), factor=2)
    g2.add("scale", g2.add("num", value=1.0), factor=2.0)
    assert keys(g1) == keys(g2)


def test_without_a_cache_everything_runs(reg):
    g = _chain(reg)
    assert set(_statuses(run(g)).values()) == {"ran"}
    assert set(_statuses(run(g)).values()) == {"ran"}


def _readers(reg, tmp_path):
    (tmp_path / "a.txt").write_text("1.5")
    (tmp_path / "b.txt").write_text("2.5")
    g = Graph(registry=reg, base_dir=tmp_path)
    ra = g.add("read_num", id="ra", path="a.txt")
    rb = g.add("read_num", id="rb", path="b.txt")
    sa = g.add("scale", ra, id="sa")
    g.add("add", sa, rb, id="sum")
    return g


def test_editing_an_input_file_reruns_its_reader_and_downstream_only(reg, tmp_path):
    g = _readers(reg, tmp_path)
    cache = Cache()
    assert run(g, cache=cache)["sum.out"] == 1.5 * 2 + 2.5
    assert set(_statuses(run(g, cache=cache)).values()) == {"cached"}
    (tmp_path / "a.txt").write_text("4")
    res = run(g, cache=cache)
    assert _statuses(res) == {"ra": "ran", "rb": "cached", "sa": "ran", "sum": "ran"}
    assert res["sum.out"] == 8 + 2.5
    # same bytes again (e.g. an editor re-saving): nothing runs
    (tmp_path / "a.txt").write_text("4")
    assert set(_statuses(run(g, cache=cache)).values()) == {"cached"}


def test_a_graph_file_resolves_paths_against_its_folder(reg, tmp_path, monkeypatch):
    g = _readers(reg, tmp_path)
    save(g, tmp_path / "g.toml")
    monkeypatch.chdir("/")
    assert load(tmp_path / "g.toml", registry=reg).run()["sum.out"] == 5.5


def test_a_missing_input_file_is_a_node_error(reg, tmp_path):
    g = _readers(reg, tmp_path)
    os.remove(tmp_path / "b.txt")
    with pytest.raises(NodeError) as e:
        run(g)
    assert str(e.value) == f"node 'rb' (read_num@1): setting 'path': file not found: {str(tmp_path / 'b.txt')!r}"
    assert e.value.node_id == "rb"


def test_disk_cache_is_reused_by_a_second_runner(reg, tmp_path):
    g = Graph(registry=reg)
    m = g.add("grid", id="m", rows=4, cols=3)
    up = g.add("lift", m, id="up", dz=0.5)
    g.add("stats", up, id="st")
    first = run(g, cache=Cache(tmp_path / "cache"))
    assert set(_statuses(first).values()) == {"ran"}
    second = run(g, cache=Cache(tmp_path / "cache"))  # new process: empty memory
    assert set(_statuses(second).values()) == {"cached"}
    mesh = second[up]
    assert np.array_equal(mesh.vertices, first[up].vertices) and mesh.grid_shape == (4, 3)
    assert not mesh.vertices.flags.writeable
    assert second["st.n"] == 12 and type(second["st.n"]) is int
    assert [r.key for r in first.records] == [r.key for r in second.records]
    assert not list((tmp_path / "cache").rglob("*.tmp"))


def test_values_that_cannot_be_stored_stay_in_memory(reg, tmp_path):
    g = Graph(registry=reg)
    g.add("opaque", id="o")
    c = Cache(tmp_path / "cache")
    run(g, cache=c)
    assert _statuses(run(g, cache=c)) == {"o": "cached"}  # in memory
    assert _statuses(run(g, cache=Cache(tmp_path / "cache"))) == {"o": "ran"}  # not on disk


def test_corrupt_disk_entry_is_a_miss_with_a_warning(reg, tmp_path):
    g = Graph(registry=reg)
    g.add("num", id="a", value=3)
    run(g, cache=Cache(tmp_path / "cache"))
    (entry,) = (tmp_path / "cache").rglob("*.npz")
    entry.write_bytes(b"garbage")
    with pytest.warns(CacheWarning, match="unreadable"):
        res = run(g, cache=Cache(tmp_path / "cache"))
    assert _statuses(res) == {"a": "ran"} and res["a.value"] == 3.0


def test_unfingerprintable_constant_disables_caching_downstream(reg):
    g = Graph(registry=reg)
    x = g.add("anything", object(), id="x")
    y = g.add("scale", x, id="y")
    n = g.add("num", id="n", value=2)
    g.add("scale", n, id="z")
    cache = Cache()
    run(g, cache=cache)
    res = run(g, cache=cache)
    assert _statuses(res) == {"x": "ran", "y": "ran", "n": "cached", "z": "cached"}
    assert res.record("x").key is None and res.record(y).key is None


def test_fingerprintable_constant_is_cached_by_content(reg):
    g = Graph(registry=reg)
    g.add("lift", grid(3, 3), id="up")
    cache = Cache()
    run(g, cache=cache)
    assert _statuses(run(g, cache=cache)) == {"up": "cached"}
    h = Graph(registry=reg)
    h.add("lift", grid(3, 3, spacing=2.0), id="up")
    assert _statuses(run(h, cache=cache)) == {"up": "ran"}


def _writer(reg, tmp_path):
    g = Graph(registry=reg, base_dir=tmp_path)
    a = g.add("num", id="a", value=1)
    w = g.add("write_num", a, id="w", path="out.txt")
    g.add("scale", w, id="s")
    return g


def test_a_deleted_output_file_makes_its_writer_rerun(reg, tmp_path):
    g = _writer(reg, tmp_path)
    cache = Cache()
    run(g, cache=cache)
    assert (tmp_path / "out.txt").read_text() == "1.0"
    assert set(_statuses(run(g, cache=cache)).values()) == {"cached"}
    os.remove(tmp_path / "out.txt")
    res = run(g, cache=cache)
    assert _statuses(res) == {"a": "cached", "w": "ran", "s": "cached"}
    assert (tmp_path / "out.txt").read_text() == "1.0"


def test_an_output_file_overwritten_by_another_setting_is_rewritten(reg, tmp_path):
    g = _writer(reg, tmp_path)
    cache = Cache()
    run(g, cache=cache)
    run(g, cache=cache, overrides={"a.value": 2})
    assert (tmp_path / "out.txt").read_text() == "2.0"
    res = run(g, cache=cache)  # back to value=1: the file holds 2.0, so the writer must run
    assert res.record("w").status == "ran"
    assert (tmp_path / "out.txt").read_text() == "1.0"


def test_failures_become_node_errors_with_the_cause(reg):
    g = Graph(registry=reg)
    a = g.add("num", id="a", value=1)
    g.add("fail", a, id="fail1", message="no solution")
    with pytest.raises(NodeError, match=r"^node 'fail1' \(fail@1\): ValueError: no solution$") as e:
        run(g)
    assert isinstance(e.value.__cause__, ValueError)


def test_multi_output_returns(reg):
    g = Graph(registry=reg)
    m = g.add("grid", id="m")
    d = g.add("stats_dict", m, id="d")
    res = run(g)
    assert res[d.n] == 9 and res[d.zmax] == 0.0
    g.add("bad_return", g.add("num", value=1), id="bad")
    with pytest.raises(NodeError, match=r"node 'bad' \(bad_return@1\): TypeError: returned float; expected a tuple of 2"):
        run(g)


def test_invalid_graph_runs_nothing(reg):
    g = _chain(reg)
    with pytest.raises(GraphError, match="unknown setting 'fctor'"):
        run(g, overrides={"s1.fctor": 2})


def test_progress_events(reg):
    g = Graph(registry=reg)
    a = g.add("num", id="a", value=1)
    g.add("scale", a, id="s")
    events = []
    cache = Cache()
    run(g, cache=cache, progress=events.append)
    kinds = [(e.kind, e.node_id) for e in events]
    assert kinds == [("started", "a"), ("finished", "a"), ("started", "s")] + [("progress", "s")] * 4 + [("finished", "s")]
    fractions = [e.fraction for e in events if e.kind == "progress"]
    assert fractions == [0.25, 0.5, 0.75, 1.0] and events[3].message == "step 1"
    assert events[-1].record.status == "ran" and events[-1].index == 1 and events[-1].total == 2
    events.clear()
    run(g, cache=cache, progress=events.append)
    assert [e.kind for e in events] == ["started", "finished"] * 2  # cached: no progress


def test_result_indexing_errors(reg):
    g = _chain(reg)
    res = run(g)
    with pytest.raises(GraphError, match="no node 'nope'"):
        res["nope"]
    with pytest.raises(GraphError, match="has no output 'x'"):
        res["a.x"]


def test_unwritable_cache_folder_warns_and_runs_on(reg, tmp_path, monkeypatch):
    import quadnodes.graph.cache as cache_module

    def refuse(path, write):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(cache_module, "write_atomic", refuse)
    g = Graph(registry=reg)
    g.add("num", id="a", value=1)
    c = Cache(tmp_path / "cache")
    with pytest.warns(CacheWarning, match="cannot write cache entry"):
        run(g, cache=c)
    assert _statuses(run(g, cache=c)) == {"a": "cached"}  # still in memory
    assert c.put("ab" * 32, CacheEntry({"out": object()})) is False  # not encodable: silently memory only


def test_memory_limit_drops_least_recently_used():
    c = Cache(max_memory_entries=2)
    for k in "abc":
        c.put(k * 64, CacheEntry({"out": k}))
    assert c.get("a" * 64) is None and c.get("c" * 64) is not None


def test_no_warnings_in_a_normal_run(reg, tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        run(_chain(reg), cache=Cache(tmp_path / "c"))
