"""The ``quadnodes`` command line: run, watch, serve, sweep, check, nodes, new, compare.

Examples
--------
::

    quadnodes run examples/e3_wavy.toml --out out/e3 --set fair.iterations=5
    quadnodes watch examples/e3_wavy.toml
    quadnodes serve examples/quickstart.toml
    quadnodes sweep examples/quickstart.toml --vary fair.weight=0.1,0.3,1 --vary noisy.seed=1:5
    quadnodes nodes fair
    quadnodes compare --out out/thesis-comparison --examples E1 E3
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
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
params = {{ iterations = 3, threshold = 0.1 }}

[nodes.step]
op = "export_step@1"
inputs = {{ mesh = "fair.mesh" }}
params = {{ path = "panels.step" }}

[nodes.png]
op = "render_png@1"
inputs = {{ mesh = "noisy.mesh", mesh2 = "fair.mesh" }}
params = {{ path = "fair.png", titles = ["noisy", "faired, {{fair.iterations}} iterations"] }}
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


def _output_folder(out: Path) -> Path:
    """Create ``--out`` if needed and make sure files can be made in it; one-line errors otherwise."""
    from .errors import ExportError
    from .io._atomic import remove_stale_temporaries

    if out.exists() and not out.is_dir():
        raise ExportError(f"--out {str(out)!r}: a file is in the way; give a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ExportError(f"--out {str(out)!r}: cannot create the folder: {exc.strerror or exc}") from exc
    try:  # a probe: root ignores permission bits, a read-only mount or a full disk does not
        fd, probe = tempfile.mkstemp(prefix=".qn-", suffix=".tmp", dir=out)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise ExportError(f"--out {str(out)!r}: cannot write into the folder: {exc.strerror or exc}") from exc
    remove_stale_temporaries(out)  # leftovers of a run that was killed while writing
    return out


class _ProgressLine:
    """One progress line on a terminal, rewritten in place (at most ten times a second).

    Not on a terminal (a log file, a pipe), it prints nothing: the plain
    per-step lines of the caller are the whole output there.
    """

    clock = staticmethod(time.monotonic)  # seconds; replaceable in tests

    def __init__(self, stream: TextIO) -> None:
        self.stream = stream
        self.last = -1.0
        isatty = getattr(stream, "isatty", None)
        self.tty = bool(isatty()) if callable(isatty) else False
        self.open = False

    def show(self, fraction: float | None, message: str, *, force: bool = False) -> None:
        if not self.tty:
            return
        now = self.clock()
        if not force and now - self.last < 0.1 and (fraction or 0) < 1.0:
            return
        self.last = now
        pct = f"{100 * fraction:3.0f}%" if fraction is not None else "    "
        width = max(20, shutil.get_terminal_size((100, 24)).columns - 1)
        self.clear()
        self.stream.write(f"  {pct} {message}"[:width])
        self.stream.flush()
        self.open = True

    def clear(self) -> None:
        if self.open:
            self.stream.write("\r\033[K")
            self.stream.flush()
            self.open = False


class _Printer:
    """Prints node events: one plain line per finished node; progress inside a node on a terminal only."""

    def __init__(self, stream: TextIO) -> None:
        self.stream = stream
        self.line = _ProgressLine(stream)

    def __call__(self, ev: Any) -> None:
        if ev.kind == "started":
            self.line.show(None, f"{ev.node_id} ({ev.op}) ...", force=True)
        elif ev.kind == "progress":
            self.line.show(ev.fraction, f"{ev.node_id}: {ev.message}")
        elif ev.kind == "finished" and ev.record is not None:
            self.line.clear()
            r = ev.record
            print(f"  [{ev.index + 1}/{ev.total}] {r.status:6s} {r.id:16s} {r.op:22s} {r.seconds:8.3f} s",
                  file=self.stream, flush=True)


def _shown(path: Path) -> str:
    """A path as short as it is clear: relative below the working directory, else absolute."""
    rel = os.path.relpath(path)
    return str(path) if rel.startswith("..") else rel


def _notes(result: Any) -> list[str]:
    """``node: note`` lines from every output that has a ``notes()`` method (e.g. a fairing report)."""
    lines = []
    for r in result.records:
        outs = result.outputs.get(r.id, {})
        ready = getattr(outs, "decoded_ports", None)  # a cached face stays undecoded (no build123d import)
        for port in (ready() if callable(ready) else list(outs)):
            value = outs[port]
            notes = getattr(value, "notes", None)
            if callable(notes) and not isinstance(value, type):
                lines += [f"{r.id}: {n}" for n in notes()]
    return lines


def _run(args: argparse.Namespace, cache: Any, stream: TextIO) -> Any:
    from .errors import GraphError
    from .graph import load
    from .graph.paths import output_path_errors

    reg = _registry()
    path = Path(args.graph)
    graph = load(path, registry=reg)
    sets = _parse_sets(args.set or [])
    g = graph.with_overrides(sets) if sets else graph
    errors = output_path_errors(g)  # --set obj.path=/tmp/x is refused like the same text in the file
    if errors:
        raise GraphError("\n".join(str(e) for e in errors))
    out = _output_folder(Path(args.out) if args.out else _default_out(path))
    t0 = time.perf_counter()
    print(f"running {path} -> {out}/", file=stream, flush=True)
    allow = [Path(a) for a in (getattr(args, "allow_read", None) or [])]
    result = g.run(cache=cache, progress=_Printer(stream), out=out, allow_read=allow)
    print(f"done in {time.perf_counter() - t0:.2f} s: {len(result.ran)} ran, {len(result.cached)} from cache",
          file=stream)
    written = []
    for r in result.records:
        for f in r.files:
            print(f"  {'wrote' if r.status == 'ran' else 'unchanged':9s} {_shown(f)}", file=stream)
            written.append(f)
    notes = _notes(result)
    for line in notes:
        print(f"  note: {line}", file=stream)
    if cache.directory is not None:  # lets the next run of the unchanged graph skip loading the nodes
        from .graph import runlog
        from .graph.watch import watched_files

        runlog.note(cache.directory, _signature(args, path, out),
                    records=result.records, files=[*watched_files(path, graph), *written], written=written,
                    notes=notes)
    return graph


def _signature(args: argparse.Namespace, path: Path, out: Path) -> str | None:
    """What a run depends on besides its files: the graph file, --out, --set and --allow-read."""
    from .graph import runlog

    allow = sorted(str(Path(a).resolve()) for a in (getattr(args, "allow_read", None) or []))
    return runlog.signature(path, out=out, overrides={**_parse_sets(args.set or []), "--allow-read": allow})


def _replay(args: argparse.Namespace, cache: Any, stream: TextIO) -> bool:
    """Print the run and return True when the graph, its files and the cache are as the last run left them."""
    from .graph import runlog

    if cache.directory is None:
        return False
    t0 = time.perf_counter()
    path = Path(args.graph)
    out = Path(args.out) if args.out else _default_out(path)
    sig = _signature(args, path, out)
    hit = runlog.replay(cache.directory, sig)
    if hit is None:
        return False
    records, written = hit
    print(f"running {path} -> {out}/", file=stream, flush=True)
    for i, (node_id, op, _) in enumerate(records):
        print(f"  [{i + 1}/{len(records)}] {'cached':6s} {node_id:16s} {op:22s} {0.0:8.3f} s", file=stream)
    print(f"done in {time.perf_counter() - t0:.2f} s: 0 ran, {len(records)} from cache "
          "(graph, input files and outputs unchanged since the last run)", file=stream)
    for w in written:
        print(f"  unchanged {_shown(Path(w))}", file=stream)
    for line in runlog.replay_notes(cache.directory, sig):
        print(f"  note: {line}", file=stream)
    return True


def _cache(args: argparse.Namespace) -> Any:
    from .graph import Cache

    if args.no_cache:
        return Cache()
    if args.cache:
        return Cache(Path(args.cache))
    out = _output_folder(Path(args.out) if args.out else _default_out(Path(args.graph)))  # clear errors first
    return Cache(out / ".cache")


def cmd_run(args: argparse.Namespace) -> int:
    cache = _cache(args)
    if not _replay(args, cache, sys.stdout):
        _run(args, cache, sys.stdout)
    return 0


def cmd_watch(args: argparse.Namespace) -> int:
    from .graph.watch import watch
    from .linalg import compiled

    compiled.warm_up()  # every change re-runs: load the compiled solver kernels once, in the background
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
    from .graph.diagnostics import file_problems

    problems = file_problems(args.graph, registry=_registry())
    if problems:
        for err in problems:
            for line in str(err).splitlines():
                print(f"error: {line}", file=sys.stderr)
        n = len(problems)
        print(f"{args.graph}: {n} problem{'s' if n != 1 else ''}", file=sys.stderr)
        return 1
    from .graph.paths import check_paths

    g = load(args.graph, registry=_registry())
    out = Path(args.out) if args.out else _default_out(Path(args.graph))
    # where the files would go and come from (symbolic links followed), as `run` checks before running
    check_paths(g, out=out, read_roots=[g.base_dir, *[Path(a) for a in (args.allow_read or [])]])
    order = g.order()
    print(f"{args.graph}: ok, {len(order)} nodes: {' -> '.join(order)}")
    return 0


def _intro(doc: str) -> str:
    """A node's docstring without its Parameters section (shown setting by setting instead)."""
    import re

    m = re.search(r"^Parameters\n-{3,}$", doc, re.M)
    return (doc[: m.start()] if m else doc).strip()


def cmd_nodes(args: argparse.Namespace) -> int:
    import shutil
    import textwrap

    from .graph import describe

    reg = _registry()
    if not args.op:
        rows = [(nt.op, describe(nt.op, registry=reg)["summary"]) for nt in reg.latest()]
        width = max(len(op) for op, _ in rows)
        cols = max(60, shutil.get_terminal_size((100, 24)).columns) - width - 2
        for op, summary in rows:  # whole sentences, wrapped, never cut
            lines = textwrap.wrap(summary, cols) or [""]
            print(f"{op:{width}s}  {lines[0]}")
            for more in lines[1:]:
                print(f"{'':{width}s}  {more}")
        print("\n'quadnodes nodes OP' shows a node's inputs, settings (type, default, range, meaning) and outputs.")
        return 0
    d = describe(args.op, registry=reg)
    print(f"{d['op']}\n\n{_intro(d['doc'])}\n")
    print("inputs:")
    for p in d["inputs"]:
        print(f"  {p['name']}: {p['type']}{'' if p['required'] else '  (optional)'}")
    print("settings:")
    for s in d["settings"]:
        facts = ["required" if s["required"] else f"default {s['default']!r}"]
        if s.get("range"):
            facts.append(f"range {s['range']['text']}")
        if s.get("file"):
            facts.append("file read, inside the graph's folder" if s["file"] == "read"
                         else "file written, inside --out")
        print(f"  {s['name']}: {s['type']}  ({', '.join(facts)})")
        if s.get("doc"):
            print(f"      {s['doc']}")
    print("outputs:")
    for o in d["outputs"]:
        print(f"  {o['name']}: {o['type']}")
    return 0


def cmd_new(args: argparse.Namespace) -> int:
    path = Path(args.name if args.name.endswith(".toml") else f"{args.name}.toml")
    if path.name == ".toml" or args.name.endswith(("/", os.sep)):  # '', 'dir/': only an extension would be left
        print(f"error: new: {args.name!r} has no file name; give one such as my_design (writes my_design.toml)",
              file=sys.stderr)
        return 1
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
    from .progress import reporting

    line = _ProgressLine(sys.stdout)

    def log(message: str) -> None:
        line.clear()
        print(f"  {message}", flush=True)

    with reporting(line.show):
        res = thesis_comparison(out, examples=args.examples, seed=args.seed, spread_seeds=extra,
                                interior_noise=not args.no_interior_noise, size_px=args.size,
                                variants_figure=not args.no_variants, log=log,
                                chapter3=not args.no_chapter3)
    line.clear()
    print(f"done in {res.seconds:.1f} s", flush=True)
    files = [*res.figures.values(), *res.variant_figures.values(), res.markdown, res.csv, res.seeds_csv]
    files += [*res.chapter3_figures.values(), res.chapter3_markdown, res.chapter3_csv]
    for p in files:
        if p is not None:
            print(f"  wrote {_shown(p)}")
    return 0


def _parse_plot(items: Sequence[str] | None) -> tuple[str, str] | None:
    from .errors import InputError

    if not items:
        return None
    axes = dict(item.partition("=")[::2] for item in items)
    if sorted(axes) != ["x", "y"] or not all(axes.values()):
        raise InputError(f"--plot {' '.join(items)}: expected x=COLUMN y=COLUMN (columns of sweep.csv)")
    return axes["x"], axes["y"]


def cmd_sweep(args: argparse.Namespace) -> int:
    from .errors import GraphError
    from .graph import load
    from .graph.sweep import parse_vary, run_sweep

    path = Path(args.graph)
    vary: dict[str, Any] = {}
    for item in args.vary or []:
        key, values = parse_vary(item)
        if key in vary:
            raise GraphError(f"--vary {key}: given twice")
        vary[key] = values
    graph = load(path, registry=_registry())
    out = Path(args.out) if args.out else Path("out") / f"{path.stem}-sweep"
    cache: Any = False if args.no_cache else (Path(args.cache) if args.cache else True)
    command = ["quadnodes", "sweep", str(path)] + [f"--vary={v}" for v in args.vary or []] + \
        [f"--set={v}" for v in args.set or []] + (["--zip"] if args.zip else []) + ["--out", str(out)] + \
        (["--scheduler", args.scheduler] if args.scheduler else ["--workers", str(args.workers)]) + \
        (["--plot", *args.plot] if args.plot else [])

    def on_start(dashboard: str | None, n_tasks: int) -> None:
        where = args.scheduler or f"an embedded cluster of {args.workers} worker processes"
        print(f"sweep {path}: {n_variants} variants, {n_tasks} node tasks on {where} -> {out}/", flush=True)
        print(f"  dashboard: {dashboard}" if dashboard else
              "  dashboard: none (it needs bokeh: pip install bokeh)", flush=True)

    def progress(done: int, total: int, row: Any) -> None:
        width = len(str(total))
        detail = row.error if row.status == "error" else f"{row.ran} ran, {row.cached} cached"
        when = ""
        if row.elapsed is not None:
            left = row.elapsed / done * (total - done)
            when = f"  [{row.elapsed:.0f} s" + (f", about {left:.0f} s left]" if done < total else "]")
        print(f"  [{done:{width}d}/{total}] {row.status:5s} {row.folder}  {detail}{when}", flush=True)

    from .graph.sweep import variants

    n_variants = len(variants(vary, zip=args.zip))
    try:
        res = run_sweep(graph, vary, out=out, zip=args.zip, overrides=_parse_sets(args.set or []), cache=cache,
                        scheduler=args.scheduler, workers=args.workers, plot=_parse_plot(args.plot),
                        progress=progress, on_start=on_start, command=command, source=path)
    except KeyboardInterrupt:
        print(f"interrupted: {out / 'sweep.csv'} lists what finished; the same command continues the sweep "
              "(finished nodes come from the cache)", file=sys.stderr, flush=True)
        return 130
    n_ok = sum(r.status == "ok" for r in res.rows)
    computed = sum(a == "compute" for _, a in res.tasks.values())
    loaded = sum(a == "load" for _, a in res.tasks.values())
    print(f"done in {res.seconds:.1f} s: {n_ok} of {len(res.rows)} variants ok; of the {res.node_results} node "
          f"results they need, {computed} were computed (shared ones once) and {loaded} read from the cache",
          flush=True)
    if n_ok < len(res.rows):
        print(f"  {len(res.rows) - n_ok} variants failed: see the error column of sweep.csv", flush=True)
    for p in [res.csv, res.manifest, *res.plots]:
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
        p.add_argument("--allow-read", action="append", metavar="DIR",
                       help="let the graph read files from DIR too (by default only from the graph file's folder)")

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
    p = sub.add_parser("sweep", help="run variants of a graph on Dask (shared nodes once): one folder per "
                                     "variant, sweep.csv, a manifest, a Pareto plot")
    graph_args(p)
    p.add_argument("--vary", action="append", metavar="NODE.SETTING=VALUES", required=True,
                   help="values of a setting (repeatable): v1,v2,... (TOML values), a:b (integers a to b) or "
                        "a:b:count (count numbers from a to b); every combination runs")
    p.add_argument("--zip", action="store_true", help="pair the i-th values of every --vary instead")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="a running Dask scheduler (default: an embedded cluster on this machine)")
    p.add_argument("--workers", type=int, default=2, help="worker processes of the embedded cluster (default 2)")
    p.add_argument("--plot", nargs=2, metavar=("x=COLUMN", "y=COLUMN"),
                   help="scatter plot of two sweep.csv columns (PNG + HTML table), Pareto front highlighted")
    p.set_defaults(func=cmd_sweep)
    p = sub.add_parser("check", help="validate a graph file without running it; lists every problem")
    p.add_argument("graph", help="graph file (.toml or .json)")
    p.add_argument("--out", help="output folder the paths are checked against (default out/<graph name>/)")
    p.add_argument("--allow-read", action="append", metavar="DIR", help="as for run")
    p.set_defaults(func=cmd_check)
    p = sub.add_parser("nodes", help="list node types, or describe one")
    p.add_argument("op", nargs="?", help="a node type (e.g. fair): its inputs, settings, defaults and ranges")
    p.set_defaults(func=cmd_nodes)
    p = sub.add_parser("new", help="write a starter graph file")
    p.add_argument("name", help="the file to write (e.g. my_design: writes my_design.toml)")
    p.add_argument("--force", action="store_true", help="overwrite the file if it exists")
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
    p.add_argument("--no-chapter3", action="store_true",
                   help="skip the thesis's chapter-3 methods (fair webs, spring model, Schneider-Kobbelt, "
                        "Fourier descriptors on a closed example)")
    p.set_defaults(func=cmd_compare)
    return ap


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``quadnodes`` command; returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except QuadnodesError as exc:
        from .errors import GraphError

        lines = str(exc).splitlines() or [type(exc).__name__]
        # a graph error may list several problems, one per line; other errors say what matters first
        for line in lines if isinstance(exc, GraphError) else lines[:1]:
            print(f"error: {line}", file=sys.stderr)
        return 1
    except BrokenPipeError:  # the reader of our output went away (quadnodes nodes | head): nothing to say
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error at exit's flush
        except (OSError, ValueError):
            pass
        return 141  # 128 + SIGPIPE, as a shell reports a command stopped by a closed pipe
    except OSError as exc:  # a file system refusal outside a writer (e.g. the cache folder)
        where = f" {str(exc.filename)!r}" if exc.filename else ""
        print(f"error: cannot use{where}: {exc.strerror or exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:  # commands with their own words for it (watch, sweep) catch it first
        print("interrupted (Ctrl-C): no output is left half-written (each file is replaced whole or not at all); "
              "nodes that finished are cached, so the same command continues from them", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
