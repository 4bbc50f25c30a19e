"""The ``quadnodes`` command line: run, watch, serve, check, nodes, new, compare.

Examples
--------
::

    quadnodes run examples/e3_wavy.toml --out out/e3 --set fair.iterations=5
    quadnodes watch examples/e3_wavy.toml
    quadnodes serve examples/quickstart.toml
    quadnodes nodes fair
    quadnodes compare --out out/thesis-comparison --examples E1 E3
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, TextIO

from . import __version__
from .errors import QuadnodesError

__all__ = ["main"]

STARTER = '''\
# A quadnodes graph: sample a surface, add zigzag noise, fair it, export the panels.
# Run it with:  quadnodes run {name}        (outputs go to out/{stem}/)
format = "quadnodes-graph"
version = 1

[nodes.surface]
op = "saddle@1"
params = {{ width = 5000.0, depth = 5000.0, rise = 1000.0 }}

[nodes.mesh]
op = "sample@1"
inputs = {{ face = "surface.face" }}
params = {{ nu = 10, nv = 10 }}

[nodes.noisy]
op = "perturb@1"
inputs = {{ mesh = "mesh.mesh" }}
params = {{ tangential = 0.2, normal = 0.1, seed = 1, fix = "corners" }}

[nodes.fair]
op = "fair@1"
inputs = {{ mesh = "noisy.mesh" }}
params = {{ iterations = 3, deviation = 0.1 }}

[nodes.step]
op = "export_step@1"
inputs = {{ mesh = "fair.mesh" }}
params = {{ path = "panels.step" }}

[nodes.png]
op = "render_png@1"
inputs = {{ mesh = "noisy.mesh", mesh2 = "fair.mesh" }}
params = {{ path = "fair.png", titles = ["noisy", "faired"] }}
'''


def _registry() -> Any:
    from . import nodes  # noqa: F401  (registers the built-in node types)
    from .graph import REGISTRY

    return REGISTRY


def _parse_sets(items: Sequence[str]) -> dict[str, Any]:
    from .graph import parse_value
    from .errors import GraphError

    out: dict[str, Any] = {}
    for item in items:
        key, eq, value = item.partition("=")
        if not eq or "." not in key:
            raise GraphError(f"--set {item!r}: expected node.setting=value")
        out[key.strip()] = parse_value(value.strip())
    return out


def _default_out(graph_path: Path) -> Path:
    return Path("out") / graph_path.stem


def _with_outputs(graph: Any, out: Path) -> Any:
    """Re-root every relative output path of writer nodes under ``out``."""
    g = graph.copy()
    for spec in g.nodes.values():
        nt = g.registry.get(spec.op, node_id=spec.id)
        for s in nt.writes:
            value = spec.params.get(s)
            if isinstance(value, (str, os.PathLike)) and not Path(value).is_absolute():
                g.set(spec.id, **{s: str((out / value).resolve())})
    return g


class _Printer:
    """Prints node events; progress lines at most every half second per node."""

    def __init__(self, stream: TextIO) -> None:
        self.stream = stream
        self.last = 0.0

    def __call__(self, ev: Any) -> None:
        if ev.kind == "progress":
            now = time.monotonic()
            if now - self.last >= 0.5 or (ev.fraction or 0) >= 1.0:
                self.last = now
                pct = f"{100 * ev.fraction:3.0f}%" if ev.fraction is not None else "    "
                print(f"        {ev.node_id}: {pct} {ev.message}", file=self.stream, flush=True)
        elif ev.kind == "finished" and ev.record is not None:
            r = ev.record
            print(f"  [{ev.index + 1}/{ev.total}] {r.status:6s} {r.id:16s} {r.op:22s} {r.seconds:8.3f} s",
                  file=self.stream, flush=True)


def _run(args: argparse.Namespace, cache: Any, stream: TextIO) -> Any:
    from .graph import load

    reg = _registry()
    path = Path(args.graph)
    graph = load(path, registry=reg)
    out = Path(args.out) if args.out else _default_out(path)
    out.mkdir(parents=True, exist_ok=True)
    g = _with_outputs(graph, out)
    t0 = time.perf_counter()
    print(f"running {path} -> {out}/", file=stream, flush=True)
    result = g.run(cache=cache, overrides=_parse_sets(args.set or []), progress=_Printer(stream))
    written = []
    for spec in g.nodes.values():
        nt = g.registry.get(spec.op, node_id=spec.id)
        for s in nt.writes:
            written.append(spec.params.get(s))
    print(f"done in {time.perf_counter() - t0:.2f} s: {len(result.ran)} ran, {len(result.cached)} from cache",
          file=stream)
    for w in written:
        print(f"  wrote {os.path.relpath(w)}", file=stream)
    if cache.directory is not None:  # lets the next run of the unchanged graph skip loading the nodes
        from .graph import runlog
        from .graph.watch import watched_files

        runlog.note(cache.directory, runlog.signature(path, out=out, overrides=_parse_sets(args.set or [])),
                    records=result.records, files=[*watched_files(path, graph), *written], written=written)
    return graph


def _replay(args: argparse.Namespace, cache: Any, stream: TextIO) -> bool:
    """Print the run and return True when the graph, its files and the cache are as the last run left them."""
    from .graph import runlog

    if cache.directory is None:
        return False
    t0 = time.perf_counter()
    path = Path(args.graph)
    out = Path(args.out) if args.out else _default_out(path)
    hit = runlog.replay(cache.directory, runlog.signature(path, out=out, overrides=_parse_sets(args.set or [])))
    if hit is None:
        return False
    records, written = hit
    print(f"running {path} -> {out}/", file=stream, flush=True)
    for i, (node_id, op, _) in enumerate(records):
        print(f"  [{i + 1}/{len(records)}] {'cached':6s} {node_id:16s} {op:22s} {0.0:8.3f} s", file=stream)
    print(f"done in {time.perf_counter() - t0:.2f} s: 0 ran, {len(records)} from cache "
          "(graph, input files and outputs unchanged since the last run)", file=stream)
    for w in written:
        print(f"  unchanged {os.path.relpath(w)}", file=stream)
    return True


def _cache(args: argparse.Namespace) -> Any:
    from .graph import Cache

    if args.no_cache:
        return Cache()
    directory = Path(args.cache) if args.cache else (Path(args.out) if args.out else _default_out(Path(args.graph))) / ".cache"
    return Cache(directory)


def cmd_run(args: argparse.Namespace) -> int:
    cache = _cache(args)
    if not _replay(args, cache, sys.stdout):
        _run(args, cache, sys.stdout)
    return 0


def cmd_watch(args: argparse.Namespace) -> int:
    from .graph.watch import watch

    cache = _cache(args)

    def on_error(exc: QuadnodesError) -> None:
        print(f"error: {exc}", file=sys.stderr, flush=True)
        print("(watching for the next change; Ctrl-C to stop)", file=sys.stderr, flush=True)

    print(f"watching {args.graph} and the files it reads (Ctrl-C to stop)", flush=True)
    try:
        watch(args.graph, lambda: _run(args, cache, sys.stdout), interval=args.interval,
              on_error=on_error, max_runs=args.max_runs, timeout=args.timeout)
    except KeyboardInterrupt:
        print("stopped", flush=True)
    return 0


def cmd_serve(args: argparse.Namespace) -> int:
    from .server import serve

    return serve(args.graph, host=args.host, port=args.port, out=args.out, cache=args.cache,
                 browser=not args.no_browser)


def cmd_check(args: argparse.Namespace) -> int:
    from .graph import load

    g = load(args.graph, registry=_registry())
    g.validate()
    order = g.order()
    print(f"{args.graph}: ok, {len(order)} nodes: {' -> '.join(order)}")
    return 0


def cmd_nodes(args: argparse.Namespace) -> int:
    from .graph import describe

    reg = _registry()
    if not args.op:
        rows = [(nt.op, describe(nt.op, registry=reg)["summary"]) for nt in reg.latest()]
        width = max(len(op) for op, _ in rows)
        for op, summary in rows:
            print(f"{op:{width}s}  {summary}")
        print("\n'quadnodes nodes OP' shows a node's inputs, settings and outputs.")
        return 0
    d = describe(args.op, registry=reg)
    print(f"{d['op']}\n\n{d['doc'].strip()}\n")
    print("inputs:")
    for p in d["inputs"]:
        print(f"  {p['name']}: {p['type']}{'' if p['required'] else '  (optional)'}")
    print("settings:")
    for s in d["settings"]:
        default = "required" if s["required"] else f"default {s['default']!r}"
        print(f"  {s['name']}: {s['type']}  ({default}{', file' if s.get('file') else ''})")
    print("outputs:")
    for o in d["outputs"]:
        print(f"  {o['name']}: {o['type']}")
    return 0


def cmd_new(args: argparse.Namespace) -> int:
    path = Path(args.name if args.name.endswith(".toml") else f"{args.name}.toml")
    if path.exists() and not args.force:
        print(f"error: {path} exists (use --force to overwrite)", file=sys.stderr)
        return 1
    from .io._atomic import write_text_atomic

    write_text_atomic(path, STARTER.format(name=path, stem=path.stem))
    print(f"wrote {path}; run it with: quadnodes run {path}")
    return 0


def cmd_compare(args: argparse.Namespace) -> int:
    from .report import thesis_comparison

    out = Path(args.out)
    if args.spread_seeds < 0:
        print(f"error: --spread-seeds: must be >= 0, got {args.spread_seeds}", file=sys.stderr)
        return 1
    extra = [s for s in range(1, args.spread_seeds + 2) if s != args.seed][: args.spread_seeds]
    print(f"thesis comparison ({' '.join(args.examples)}; seed {args.seed}"
          f"{', spread over seeds ' + ' '.join(map(str, extra)) if extra else ''}) -> {out}/", flush=True)
    res = thesis_comparison(out, examples=args.examples, seed=args.seed, spread_seeds=extra,
                            interior_noise=not args.no_interior_noise, size_px=args.size,
                            variants_figure=not args.no_variants, log=lambda m: print(f"  {m}", flush=True))
    print(f"done in {res.seconds:.1f} s", flush=True)
    files = [*res.figures.values(), *res.variant_figures.values(), res.markdown, res.csv, res.seeds_csv]
    for p in files:
        if p is not None:
            print(f"  wrote {os.path.relpath(p)}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="quadnodes", description="Fair, buildable quad-panel surfaces.")
    ap.add_argument("--version", action="version", version=f"quadnodes {__version__}")
    sub = ap.add_subparsers(dest="command", required=True)

    def graph_args(p: argparse.ArgumentParser) -> None:
        p.add_argument("graph", help="graph file (.toml or .json)")
        p.add_argument("--set", action="append", metavar="NODE.SETTING=VALUE",
                       help="override a setting (repeatable); VALUE is a TOML value, e.g. 5, 0.1, [1, 0.5], true")
        p.add_argument("--out", help="folder for the outputs (default out/<graph name>/)")
        p.add_argument("--cache", help="disk cache folder (default <out>/.cache)")
        p.add_argument("--no-cache", action="store_true", help="do not read or write a disk cache")

    p = sub.add_parser("run", help="run a graph; print what ran and what came from the cache")
    graph_args(p)
    p.set_defaults(func=cmd_run)
    p = sub.add_parser("watch", help="re-run a graph whenever it or a file it reads changes")
    graph_args(p)
    p.add_argument("--interval", type=float, default=0.3, help="seconds between checks (default 0.3)")
    p.add_argument("--max-runs", type=int, default=None, help=argparse.SUPPRESS)
    p.add_argument("--timeout", type=float, default=None, help=argparse.SUPPRESS)
    p.set_defaults(func=cmd_watch)
    p = sub.add_parser("serve", help="edit a graph in the browser: nodes, wires, settings, live 3-D views; "
                                     "every edit is saved to the file and re-runs only what it affects")
    p.add_argument("graph", help="graph file (.toml or .json)")
    p.add_argument("--port", type=int, default=8765, help="port (default 8765)")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1: this machine only)")
    p.add_argument("--out", help="folder for the outputs (default out/<graph name>/)")
    p.add_argument("--cache", help="disk cache folder (default <out>/.cache)")
    p.add_argument("--no-browser", action="store_true", help="do not open the page in a browser")
    p.set_defaults(func=cmd_serve)
    p = sub.add_parser("check", help="validate a graph file without running it")
    p.add_argument("graph")
    p.set_defaults(func=cmd_check)
    p = sub.add_parser("nodes", help="list node types, or describe one")
    p.add_argument("op", nargs="?")
    p.set_defaults(func=cmd_nodes)
    p = sub.add_parser("new", help="write a starter graph file")
    p.add_argument("name")
    p.add_argument("--force", action="store_true")
    p.set_defaults(func=cmd_new)
    p = sub.add_parser("compare", help="Laplacian vs Taubin vs the new method on the thesis's examples: "
                                       "figures and metrics tables")
    p.add_argument("--out", default=str(Path("out") / "thesis-comparison"),
                   help="folder for the figures and tables (default out/thesis-comparison/)")
    p.add_argument("--examples", nargs="+", default=["E1", "E2", "E3", "E4"], metavar="NAME",
                   help="examples to run (default: E1 E2 E3 E4)")
    p.add_argument("--seed", type=int, default=7, help="seed of the zigzag noise for figures and tables (default 7)")
    p.add_argument("--spread-seeds", type=int, default=5, metavar="N",
                   help="also run N other seeds (1, 2, ...) and tabulate the range of the key numbers (default 5)")
    p.add_argument("--size", type=int, default=1200, help="figure width in pixels (default 1200)")
    p.add_argument("--no-variants", action="store_true",
                   help="skip the second figure per example (boundary-fixed baselines, default weight)")
    p.add_argument("--no-interior-noise", action="store_true",
                   help="skip the runs with noise on interior vertices only (clean boundary)")
    p.set_defaults(func=cmd_compare)
    return ap


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``quadnodes`` command; returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except QuadnodesError as exc:
        lines = str(exc).splitlines() or [type(exc).__name__]
        print(f"error: {lines[0]}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
