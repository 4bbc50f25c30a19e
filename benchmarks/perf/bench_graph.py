"""Incremental re-run: change one fair setting in a 100×100 pipeline, time the re-run.

Backs the pipeline table in docs/graphs.md.

Pipeline: wavy surface -> sample 100×100 -> perturb -> fair -> compare -> OBJ + CSV
export (STEP is left out so the table isolates the graph engine's overhead; add it
and the re-run grows by the export time). Rows: the cold run, a re-run with nothing
changed (all from the cache), a re-run after ``fair.iterations`` changed (fair and
its downstream run), with each node's own time in that re-run and what is left:
the engine's overhead. Median of 5 repetitions, in-memory cache.

Run:  python benchmarks/perf/bench_graph.py
"""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

import quadnodes.nodes  # noqa: F401
from quadnodes.graph import Cache, Graph


def build(out: Path) -> Graph:
    g = Graph()
    face = g.add("wavy", id="surface")
    mesh = g.add("sample", face.face, id="mesh", nu=100, nv=100)
    noisy = g.add("perturb", mesh.mesh, id="noisy", tangential=0.2, normal=0.05, seed=1, fix="corners")
    new = g.add("fair", noisy.mesh, id="fair", iterations=1)
    g.add("compare", noisy.mesh, new.mesh, id="metrics")
    g.add("export_obj", new.mesh, id="obj", path=str(out / "f.obj"))
    g.add("export_csv", new.mesh, id="csv", path=str(out / "f.csv"))
    return g


def main() -> None:
    rows: dict[str, list[float]] = {"cold run (all nodes run)": [], "re-run, nothing changed": [],
                                    "re-run after fair.iterations changed": []}
    for k in ("fair", "metrics", "obj", "csv"):
        rows[f"  of which node '{k}'"] = []
    rows["  of which the engine (keys, cache, bookkeeping)"] = []
    with tempfile.TemporaryDirectory() as d:
        for rep in range(5):
            g = build(Path(d))
            cache = Cache()
            t = time.perf_counter(); g.run(cache=cache); rows["cold run (all nodes run)"].append(time.perf_counter() - t)
            t = time.perf_counter(); r = g.run(cache=cache); rows["re-run, nothing changed"].append(time.perf_counter() - t)
            assert r.ran == []
            t = time.perf_counter()
            r = g.run(cache=cache, overrides={"fair.iterations": 2})
            total = time.perf_counter() - t
            rows["re-run after fair.iterations changed"].append(total)
            assert sorted(r.ran) == ["csv", "fair", "metrics", "obj"], r.ran
            for k in ("fair", "metrics", "obj", "csv"):
                rows[f"  of which node '{k}'"].append(r.record(k).seconds)
            rows["  of which the engine (keys, cache, bookkeeping)"].append(total - sum(x.seconds for x in r.records))
    print("| 100×100 pipeline | median wall time (s) |")
    print("|---|---:|")
    for k, v in rows.items():
        print(f"| {k} | {statistics.median(v):.3f} |")


if __name__ == "__main__":
    main()
