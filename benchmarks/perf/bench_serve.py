"""`quadnodes serve`: from a changed setting to the new mesh on the page, through the server's own HTTP API.

Backs docs/graphs.md "Speed" (the live editor's rows).

A real `quadnodes serve` process (uvicorn, 127.0.0.1, a free port) serves a copy of a graph; the script
changes ``fair.iterations`` with ``POST /api/nodes/fair/settings`` (1, 2, 4, 5, …: a new value each time,
so fair really runs), waits on the event WebSocket (``/api/events``, as the page does) for the fair node of that edit to
finish, and fetches ``GET /api/mesh/fair/mesh`` — the clock stops when the page would have the new mesh's
bytes. Two states:

- *idle*: the previous run, exporters included, had finished;
- *busy*: the edit arrives while the previous run's exporters (STEP, PNG, ...) are still going; the old run
  is given up at its next node or progress report.

Inputs: the quick-start (``examples/quickstart.toml``, 22×41 = 902 vertices, every node), and the same graph
sampled 100×100 (10 000 vertices) without its STEP, PNG and HTML writers (their cold run at that size takes
minutes and does not change when the new mesh is ready).
Peers in the same run: the fair node's own time inside the server, and `quadnodes run` as a whole process
(imports included) — with a warm cache and nothing changed, and after ``--set fair.iterations=N`` (what a
user of the CLI waits for instead).

Run:  python benchmarks/perf/bench_serve.py [--repeat 5]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import shutil
import socket
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}


class Server:
    def __init__(self, graph: Path, out: Path) -> None:
        port = _free_port()
        self.proc = subprocess.Popen([sys.executable, "-m", "quadnodes", "serve", str(graph), "--no-browser",
                                      "--port", str(port), "--out", str(out)], cwd=graph.parent, env=_env(),
                                     stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        assert self.proc.stdout is not None
        self.proc.stdout.readline()
        url = self.proc.stdout.readline().strip()
        self.base = f"http://127.0.0.1:{port}"
        self.token = url.split("token=", 1)[1]
        self.ws = None

    def events(self) -> None:
        from websockets.sync.client import connect

        deadline = time.monotonic() + 120
        while True:
            try:
                self._conn = connect(f"ws://127.0.0.1:{self.base.rsplit(':', 1)[1]}/api/events?token={self.token}",
                                     max_size=None, ping_interval=None)
                self.ws = self._conn.__enter__()
                return
            except OSError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.2)

    def call(self, path: str, data: object = None) -> tuple[dict, int]:
        req = urllib.request.Request(self.base + path, data=None if data is None else json.dumps(data).encode(),
                                     method="GET" if data is None else "POST")
        req.add_header("Authorization", f"Bearer {self.token}")
        req.add_header("Content-Type", "application/json")
        with urllib.request.urlopen(req, timeout=600) as r:
            body = r.read()
        return json.loads(body), len(body)

    def idle(self, timeout: float = 1800) -> dict:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                run, _ = self.call("/api/run")
                if run["state"] in ("done", "failed") and run["revision"] == run["graph_revision"]:
                    return run
            except OSError:
                pass
            time.sleep(0.05)
        raise TimeoutError("the server did not finish its run")

    def change(self, iterations: int) -> tuple[float, float, int]:
        """Seconds from the POST to the new mesh's bytes; the fair node's own seconds; payload bytes."""
        t0 = time.perf_counter()
        res, _ = self.call("/api/nodes/fair/settings", {"iterations": iterations})
        assert res["ok"], res
        while True:
            ev = json.loads(self.ws.recv(timeout=600))
            if (ev["type"] == "node" and ev["id"] == "fair" and ev["revision"] == res["revision"]
                    and ev["status"] in ("ran", "cached", "failed")):
                fair = ev
                break
        assert fair["status"] == "ran", fair
        mesh, size = self.call("/api/mesh/fair/mesh")
        elapsed = time.perf_counter() - t0
        assert mesh["key"] == fair["key"]
        return elapsed, fair["seconds"], size

    def stop(self) -> None:
        if self.ws is not None:
            self._conn.__exit__(None, None, None)
        self.proc.terminate()
        try:
            self.proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            self.proc.kill()


def _cli(graph: Path, out: Path, *extra: str) -> tuple[float, float]:
    """Wall seconds and CPU seconds (user + system) of one whole `quadnodes run` process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "quadnodes", "run", str(graph), "--out", str(out), *extra],
                   cwd=graph.parent, env=_env(), check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def _variant_100(text: str) -> str:
    text = text.replace("params = { nu = 22, nv = 41 }", "params = { nu = 100, nv = 100 }")
    for node in ("step", "png", "planarity_png", "html"):
        text = re.sub(rf"\n\[nodes\.{node}\]\n(?:[^\[\n].*\n)*", "\n", text)
    return text


def bench(name: str, text: str, repeat: int, rows: list[tuple[str, str, str]]) -> None:
    with tempfile.TemporaryDirectory() as d:
        graph = Path(d) / "graph.toml"
        graph.write_text(text)
        out = Path(d) / "out"
        server = Server(graph, out)
        try:
            t0 = time.perf_counter()
            server.events()
            first = server.idle()
            cold = time.perf_counter() - t0
            idle, own, busy, sizes = [], [], [], []
            values = iter(v for v in range(1, 100) if v != 3)  # slider steps: 1, 2, 4, 5, ... (3 is the file's)
            for _ in range(repeat):
                server.idle()
                e, s, b = server.change(next(values))
                idle.append(e), own.append(s), sizes.append(b)
            for _ in range(repeat):  # each edit right after the previous fair finished: exporters still busy
                e, _, _ = server.change(next(values))
                busy.append(e)
            server.idle()
        finally:
            server.stop()
        nv = 902 if "22" in name else 10_000
        rows.append((name, "first run in the server (cold cache, all nodes)", f"{cold:.2f} s"))
        rows.append((name, "new mesh on the page after fair.iterations changed, idle server",
                     f"{1000 * statistics.median(idle):.0f} ms"))
        rows.append((name, "  of which the fair node itself", f"{1000 * statistics.median(own):.0f} ms"))
        rows.append((name, "new mesh on the page, edit while the exporters still run",
                     f"{1000 * statistics.median(busy):.0f} ms"))
        rows.append((name, f"mesh payload ({nv} vertices, base64 float32/int32 JSON)",
                     f"{statistics.median(sizes) / 1024:.0f} KiB"))
        assert first["state"] == "done", first.get("error")
        # the CLI in the same run, sharing nothing with the server (its own cache folder)
        cli_out = Path(d) / "cli"
        _cli(graph, cli_out)
        warm = [_cli(graph, cli_out) for _ in range(repeat)]
        rows.append((name, "`quadnodes run`, warm cache, nothing changed (whole process): wall / CPU",
                     f"{statistics.median(w for w, _ in warm):.2f} s / {statistics.median(c for _, c in warm):.2f} s"))
        sets = [_cli(graph, cli_out, "--set", f"fair.iterations={30 + k}") for k in range(min(repeat, 3))]
        rows.append((name, "`quadnodes run --set fair.iterations=N` (whole process, all writers): wall / CPU",
                     f"{statistics.median(w for w, _ in sets):.2f} s / {statistics.median(c for _, c in sets):.2f} s"))
        for r in rows[-7:]:
            print(f"| {r[0]} | {r[1]} | {r[2]} |", file=sys.stderr, flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--skip-100", action="store_true", help="only the quick-start")
    args = ap.parse_args()
    text = (ROOT / "examples" / "quickstart.toml").read_text()
    rows: list[tuple[str, str, str]] = []
    load0 = os.getloadavg()[0]
    bench("quick-start 22×41", text, args.repeat, rows)
    if not args.skip_100:
        bench("quick-start 100×100, no STEP/PNG/HTML", _variant_100(text), args.repeat, rows)
    print(f"median of {args.repeat}; `python benchmarks/perf/bench_serve.py --repeat {args.repeat}`; "
          f"{os.cpu_count()} cores, load average {load0:.1f} at the start, {os.getloadavg()[0]:.1f} at the end\n")
    print("| graph | measure | value |")
    print("|---|---|---:|")
    for r in rows:
        print(f"| {r[0]} | {r[1]} | {r[2]} |")


if __name__ == "__main__":
    main()
