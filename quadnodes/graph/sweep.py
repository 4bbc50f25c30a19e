"""Design-space sweeps: many variants of one graph on Dask distributed, shared work done once.

A sweep varies settings (``{"fair.weight": [0.1, 0.3, 1], "noisy.seed": range(1, 21)}``),
runs the cartesian product (or the zipped lists) of their values, and writes one
folder per variant plus one table, ``sweep.csv``, with a row per variant.

Every node of every variant becomes one Dask task **keyed by its cache key** (see
:mod:`quadnodes.graph.run`; keys chain upstream keys), so a node that is the same
in several variants — the surface, the sampling, the noise when its seed is not
varied — is one task, computed once and shared. Each task writes its result to
the disk cache as ``run`` does, and the client plans from that cache first: a
node whose entry is on disk is loaded instead of computed, and is not even loaded
when nothing downstream needs it. A finished or interrupted sweep run again
therefore recomputes nothing that was done.

The same code runs on an embedded :class:`distributed.LocalCluster` of worker
processes or on an existing cluster (``dask scheduler`` + ``dask worker ADDRESS``
on each machine), given by its address. Dask is imported only when a sweep runs.

What crosses process boundaries: :class:`NodeCall` (the node type is pickled
by reference to its function, which workers import) and the node outputs;
QuadMesh, reports and arrays pickle as plain data, build123d faces pickle
exactly as OCP binary BREP (build123d registers that with :mod:`copyreg`).

Examples
--------
>>> parse_vary("fair.weight=0.1,0.3,1")
('fair.weight', [0.1, 0.3, 1])
>>> parse_vary("noisy.seed=1:4")
('noisy.seed', [1, 2, 3, 4])
>>> variants({"a.x": [1, 2], "b.y": [10, 20]})
[{'a.x': 1, 'b.y': 10}, {'a.x': 1, 'b.y': 20}, {'a.x': 2, 'b.y': 10}, {'a.x': 2, 'b.y': 20}]
>>> variants({"a.x": [1, 2], "b.y": [10, 20]}, zip=True)
[{'a.x': 1, 'b.y': 10}, {'a.x': 2, 'b.y': 20}]
"""

from __future__ import annotations

import csv
import hashlib
import html as _html
import io
import itertools
import json
import math
import os
import platform
import re
import socket
import sys
import time
import types
import uuid
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path, PurePath
from typing import Any, Union, get_args, get_origin

import numpy as np

from ..errors import GraphError, InputError, NodeError, QuadnodesError
from ..io._atomic import write_atomic, write_text_atomic
from ._util import label
from .cache import Cache, CacheEntry
from .files import parse_value
from .fingerprint import code_fingerprint, file_digest
from .graph import Graph
from .run import NodeCall, plan

__all__ = ["MAX_VARIANTS", "parse_vary", "variants", "run_sweep", "pareto_front", "SweepResult", "SweepRow"]

_RANGE_RE = re.compile(r"\s*([-+]?[0-9.eE+-]+)\s*:\s*([-+]?[0-9.eE+-]+)\s*(?::\s*([^:]*?)\s*)?\Z")
_SAFE_RE = re.compile(r"[^A-Za-z0-9._=+-]")
_MAX_LIST = 16  # lists in reports longer than this are not spread over columns
#: A sweep of more variants is refused before anything is built: each variant is a run of the whole graph
#: (10,000 of the quickstart's take hours), and a mistyped range (``0:1000000000``) must not fill the memory.
MAX_VARIANTS = 10_000
builtins_zip = zip  # the functions below take a keyword named zip


# ----------------------------------------------------------------------------- the variants
def _split_top(text: str) -> list[str]:
    """Split at commas outside brackets, braces and quotes."""
    parts, depth, quote, cur = [], 0, "", []
    for ch in text:
        if quote:
            cur.append(ch)
            if ch == quote:
                quote = ""
            continue
        if ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append("".join(cur))
            cur = []
            continue
        cur.append(ch)
    parts.append("".join(cur))
    return parts


def _range(key: str, text: str) -> list[Any]:
    m = _RANGE_RE.match(text)
    usage = "expected a:b (integers, both ends included) or a:b:count (count floats from a to b)"
    if m is None:
        raise GraphError(f"--vary {key}: range {text!r}: {usage}")
    a, b, count = m.group(1), m.group(2), m.group(3)
    if count is None:
        try:
            lo, hi = int(a), int(b)
        except ValueError:
            raise GraphError(f"--vary {key}: range {text!r}: a:b takes integers; "
                             f"for other numbers give a count, e.g. {a}:{b}:5") from None
        if hi < lo:
            raise GraphError(f"--vary {key}: range {text!r}: the end {hi} is below the start {lo}")
        _check_count(key, text, hi - lo + 1)
        return list(range(lo, hi + 1))
    try:
        lo_f, hi_f = float(a), float(b)
    except ValueError:
        raise GraphError(f"--vary {key}: range {text!r}: {a!r} or {b!r} is not a number; {usage}") from None
    try:
        n = int(count)
    except ValueError:
        raise GraphError(f"--vary {key}: range {text!r}: count {count!r} is not an integer; {usage}") from None
    if n < 2 or not (math.isfinite(lo_f) and math.isfinite(hi_f)):
        raise GraphError(f"--vary {key}: range {text!r}: needs a count of at least 2 and finite ends")
    _check_count(key, text, n)
    return [float(f"{x:.12g}") for x in np.linspace(lo_f, hi_f, n)]


def _check_count(key: str, text: str, n: int) -> None:
    if n > MAX_VARIANTS:
        raise GraphError(f"--vary {key}: range {text!r} has {n:,} values; a sweep runs at most {MAX_VARIANTS:,} "
                         "variants (each one a run of the graph): give fewer values, or split the sweep")


def parse_vary(item: str) -> tuple[str, list[Any]]:
    """Parse one ``--vary`` item: ``node.setting=v1,v2,...``, ``node.setting=a:b`` or ``node.setting=a:b:count``.

    Values are read like ``--set`` values (a TOML value, else the text itself);
    commas inside ``[...]`` or quotes do not split. ``a:b`` is every integer from
    a to b, both included; ``a:b:count`` is ``count`` evenly spaced floats from a to b.

    Parameters
    ----------
    item : str

    Returns
    -------
    (str, list)
        The ``node.setting`` key and its values.

    Raises
    ------
    GraphError
        Naming the item or the setting: no ``=``, no ``node.setting``, an empty
        value, a malformed or empty range.

    Examples
    --------
    >>> parse_vary("fair.deviation=[0.1, 0.05],0.1")
    ('fair.deviation', [[0.1, 0.05], 0.1])
    >>> parse_vary("fair.weight=0:1:3")
    ('fair.weight', [0.0, 0.5, 1.0])
    >>> parse_vary("noisy.seed=1:x")
    Traceback (most recent call last):
    ...
    quadnodes.errors.GraphError: --vary noisy.seed: range '1:x': expected a:b (integers, both ends included) or a:b:count (count floats from a to b)
    """
    if not isinstance(item, str):
        raise GraphError(f"--vary {item!r}: expected text node.setting=v1,v2,...")
    key, eq, rhs = item.partition("=")
    key = key.strip()
    node_id, dot, setting = key.partition(".")
    if not eq or not dot or not node_id or not setting:
        raise GraphError(f"--vary {item!r}: expected node.setting=v1,v2,... or node.setting=a:b")
    rhs = rhs.strip()
    if not rhs:
        raise GraphError(f"--vary {key}: no values after '='")
    if ":" in rhs and not any(c in rhs for c in ",[{\"'"):
        return key, _range(key, rhs)
    values = []
    for i, part in enumerate(_split_top(rhs)):
        if not part.strip():
            raise GraphError(f"--vary {key}: value {i + 1} of {rhs!r} is empty")
        values.append(parse_value(part.strip()))
    return key, values


def _as_values(key: str, values: Any) -> list[Any]:
    if isinstance(values, str):
        return parse_vary(f"{key}={values}")[1]
    if isinstance(values, np.ndarray):
        values = values.tolist()
    if isinstance(values, Mapping) or not isinstance(values, (Sequence, range)):
        raise GraphError(f"--vary {key}: expected a list of values or text 'v1,v2' / 'a:b', got {values!r}")
    out = [v.item() if isinstance(v, np.generic) else v for v in values]
    if not out:
        raise GraphError(f"--vary {key}: no values")
    return out


def variants(vary: Mapping[str, Any], *, zip: bool = False) -> list[dict[str, Any]]:  # noqa: A002
    """The variants of a sweep: every combination of the values (or the lists zipped), in order.

    Parameters
    ----------
    vary : mapping ``"node.setting"`` -> values
        A list (or range, array) of values, or text as after ``=`` in :func:`parse_vary`.
    zip : bool
        Pair the i-th values of every list instead of taking all combinations
        (the lists must have the same length).

    Returns
    -------
    list of dict
        One ``{"node.setting": value}`` per variant; the last key varies fastest.

    Raises
    ------
    GraphError
        An empty ``vary``, a malformed key, a list without values, or (``zip``)
        lists of different lengths (naming the settings and lengths).

    Examples
    --------
    >>> variants({"n.seed": "1:3"})
    [{'n.seed': 1}, {'n.seed': 2}, {'n.seed': 3}]
    >>> variants({"a.x": [1, 2], "b.y": [1]}, zip=True)
    Traceback (most recent call last):
    ...
    quadnodes.errors.GraphError: --zip: the lists differ in length: a.x has 2 values, b.y has 1 value
    """
    if not isinstance(vary, Mapping) or not vary:
        raise GraphError("a sweep needs at least one setting to vary (--vary node.setting=v1,v2,...)")
    keys, lists = [], []
    for key, values in vary.items():
        node_id, dot, setting = str(key).partition(".")
        if not dot or not node_id or not setting:
            raise GraphError(f"--vary {key!r}: expected node.setting=v1,v2,...")
        keys.append(str(key))
        lists.append(_as_values(str(key), values))
    if zip:
        if len({len(v) for v in lists}) > 1:
            sizes = ", ".join(f"{k} has {len(v)} value{'s' if len(v) != 1 else ''}"
                              for k, v in builtins_zip(keys, lists))
            raise GraphError(f"--zip: the lists differ in length: {sizes}")
        combos = list(builtins_zip(*lists))
    else:
        total = math.prod(len(v) for v in lists)
        if total > MAX_VARIANTS:
            sizes = " × ".join(f"{len(v)} ({k})" for k, v in builtins_zip(keys, lists))
            raise GraphError(f"--vary: {sizes} = {total:,} variants; a sweep runs at most {MAX_VARIANTS:,} (each one "
                             "a run of the graph): give fewer values, pair the lists with --zip, or split the sweep")
        combos = list(itertools.product(*lists))
    return [dict(builtins_zip(keys, c)) for c in combos]



def _text(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, (list, tuple)):
        return "[" + ",".join(_text(v) for v in value) + "]"
    return str(value)


def _folder_names(combos: list[dict[str, Any]]) -> list[str]:
    """Filesystem-safe, unique folder names such as ``fair.weight=0.3__noisy.seed=2``."""
    names, seen = [], set()
    for combo in combos:
        raw = "__".join(f"{k}={_text(v)}" for k, v in combo.items())
        name = _SAFE_RE.sub("_", raw).lstrip(".") or "variant"
        if len(name) > 120 or name.lower() in seen:
            name = f"{name[:100]}__{hashlib.sha256(raw.encode()).hexdigest()[:10]}"
        seen.add(name.lower())
        names.append(name)
    return names


def _rooted(graph: Graph, folder: Path) -> Graph:
    """Every output file of the graph's writer nodes placed in ``folder``."""
    g = graph.copy()
    for spec in g.nodes.values():
        nt = g.registry.get(spec.op, node_id=spec.id)
        for s in nt.writes:
            value = spec.params.get(s)
            if value is None:
                continue
            paths = value if isinstance(value, (list, tuple)) else [value]
            for p in paths:
                if Path(p).is_absolute():
                    raise GraphError(f"{label(spec.id, spec.op)}: setting {s!r} is an absolute path ({str(p)!r}); "
                                     "in a sweep every variant writes into its own folder, so give a relative path")
            new = [str(folder / p) for p in paths]
            g.set(spec.id, **{s: new if isinstance(value, (list, tuple)) else new[0]})
    return g


# ----------------------------------------------------------------------------- on the workers
@dataclass(frozen=True)
class _Done:
    """A node's result on a worker: its outputs, ``"ran"`` or ``"cached"``, seconds spent."""

    outputs: dict[str, Any]
    status: str
    seconds: float


_VERIFIED: set[tuple[str, str | None]] = set()
_WORKER_CACHES: dict[str, Cache] = {}


def _worker_cache(directory: str) -> Cache:
    c = _WORKER_CACHES.get(directory)
    if c is None:
        c = _WORKER_CACHES[directory] = Cache(directory, max_memory_entries=0)
    return c


def _check_code(call: NodeCall) -> None:
    """Refuse to run a node whose code differs from the client's (its results would be cached wrongly)."""
    nt = call.node_type
    tag = (nt.op, nt.code_fingerprint)
    if tag in _VERIFIED or nt.code_fingerprint is None:
        return
    if code_fingerprint(nt.func) != nt.code_fingerprint:
        raise NodeError(f"{label(call.node_id, nt.op)}: the worker on {socket.gethostname()} runs other quadnodes "
                        "code (or Python/NumPy/SciPy versions) than the client, or the sources changed after the "
                        "sweep started; install the same on every machine")
    _VERIFIED.add(tag)


def _compute(call: NodeCall, cache_dir: str | None, upstream: dict[str, _Done]) -> _Done:
    _check_code(call)
    inputs = {port: upstream[ref.node].outputs[ref.port] for port, ref in call.connections.items()}
    t0 = time.perf_counter()
    outputs = call.execute(inputs)
    seconds = time.perf_counter() - t0
    if cache_dir is not None and call.key is not None:
        written = call.written()
        if all(d is not None for ds in written.values() for d in ds):
            _worker_cache(cache_dir).put(call.key, CacheEntry(outputs, written))  # type: ignore[arg-type]
    return _Done(outputs, "ran", seconds)


def _load(call: NodeCall, cache_dir: str) -> _Done:
    entry = _worker_cache(cache_dir).get(call.key) if call.key is not None else None
    if entry is None or not call.reusable(entry):
        raise NodeError(f"{label(call.node_id, call.op)}: its cache entry is not readable in {cache_dir!r} on "
                        f"{socket.gethostname()}; with workers on several machines the cache folder must be "
                        "shared by all of them (or run the sweep without a disk cache)")
    return _Done(dict(entry.outputs), "cached", 0.0)


def _brief(done: _Done) -> tuple[str, float, dict[str, Any]]:
    return done.status, done.seconds, _scalars(done.outputs)


def _collect(briefs: dict[str, tuple[str, float, dict[str, Any]]]) -> dict[str, tuple[str, float, dict[str, Any]]]:
    return briefs


def _flatten(prefix: str, value: Any, out: dict[str, Any]) -> None:
    if isinstance(value, (bool, np.bool_)):
        out[prefix] = bool(value)
    elif isinstance(value, (int, float, np.integer, np.floating)):
        out[prefix] = value.item() if isinstance(value, np.generic) else value
    elif isinstance(value, str):
        out[prefix] = value
    elif isinstance(value, Mapping):
        for k, v in value.items():
            _flatten(f"{prefix}.{k}", v, out)
    elif isinstance(value, (list, tuple)) and len(value) <= _MAX_LIST:
        for i, v in enumerate(value):
            _flatten(f"{prefix}.{i}", v, out)
    elif callable(getattr(value, "to_dict", None)) and not isinstance(value, (type, Graph)):
        _flatten(prefix, value.to_dict(), out)


def _scalars(outputs: Mapping[str, Any]) -> dict[str, Any]:
    """Every number, bool and text in the node's outputs (dicts, reports, short lists), by flattened name."""
    out: dict[str, Any] = {}
    for port, value in outputs.items():
        if isinstance(value, PurePath):
            continue
        _flatten(port, value, out)
    return out


def _may_have_scalars(annotation: Any) -> bool:
    """Whether an output so annotated can carry table numbers (then a cached one is read for the table).

    Judged from the annotation, not the value, so that the plan needs no data. An output annotated ``Any``
    (a build123d face) is not read; a dict returned under ``Any`` therefore reaches the table only in a
    sweep that computes it.
    """
    if annotation in (int, float, bool, str, dict) or get_origin(annotation) in (dict, Mapping):
        return True
    if get_origin(annotation) in (Union, types.UnionType):
        return any(_may_have_scalars(a) for a in get_args(annotation))
    return isinstance(annotation, type) and callable(getattr(annotation, "to_dict", None))


# ----------------------------------------------------------------------------- results
@dataclass
class SweepRow:
    """One variant: its settings, folder, status (``"ok"``, ``"error"``, ``"not run"``), error, numbers.

    ``seconds`` is the compute time of the variant's nodes that ran in this sweep (a node shared by
    several variants counts in each; ``node_seconds`` has it per node), ``elapsed`` the time from the
    start of the sweep until the variant was complete, ``ran`` / ``cached`` how many of its nodes ran or
    were reused (read from the cache, or not needed because what they feed was reused), ``outputs`` its
    files relative to the sweep folder (by ``node.setting``), ``values`` every scalar of its reports
    (``metrics.metrics.zigzag_max``).
    """

    index: int
    settings: dict[str, Any]
    folder: str
    status: str = "not run"
    error: str = ""
    seconds: float = 0.0
    elapsed: float | None = None
    ran: int = 0
    cached: int = 0
    outputs: dict[str, str] = field(default_factory=dict)
    values: dict[str, Any] = field(default_factory=dict)
    node_seconds: dict[str, float] = field(default_factory=dict)


@dataclass
class SweepResult:
    """What a sweep did: the rows, the files it wrote, and every distinct node task with its status.

    ``tasks`` maps a Dask key to ``(node_id, action)``, action being ``"compute"``
    (run on a worker) or ``"load"`` (read from the disk cache); nodes reused
    without loading do not appear. ``ran_nodes`` counts the computed tasks by node id.
    ``node_results`` is the number of node results the variants needed (nodes × variants).
    """

    out: Path
    rows: list[SweepRow]
    csv: Path
    manifest: Path
    tasks: dict[str, tuple[str, str]]
    seconds: float
    node_results: int = 0
    dashboard: str | None = None
    plots: list[Path] = field(default_factory=list)

    @property
    def ran_nodes(self) -> dict[str, int]:
        counts: dict[str, int] = {}
        for node_id, action in self.tasks.values():
            if action == "compute":
                counts[node_id] = counts.get(node_id, 0) + 1
        return counts

    def columns(self) -> list[str]:
        """The columns of ``sweep.csv``, in order."""
        return _columns(self.rows)

    def table(self) -> list[dict[str, Any]]:
        """The rows of ``sweep.csv`` as dicts (missing numbers are empty strings)."""
        cols = self.columns()
        return [{c: _cell(r, c) for c in cols} for r in self.rows]


_FIXED = ["status", "error", "seconds", "elapsed", "ran", "cached", "folder"]


def _columns(rows: list[SweepRow]) -> list[str]:
    settings: list[str] = []
    outputs: list[str] = []
    values: list[str] = []
    for r in rows:
        for k in r.settings:
            if k not in settings:
                settings.append(k)
        for k in r.outputs:
            if k not in outputs:
                outputs.append(k)
        for k in r.values:
            if k not in values:
                values.append(k)
    return settings + _FIXED + outputs + values


def _cell(row: SweepRow, col: str) -> Any:
    if col in row.settings:
        v = row.settings[col]
        return json.dumps(v) if isinstance(v, (list, dict, bool)) else v
    if col in _FIXED:
        v = getattr(row, col)
        if isinstance(v, float):
            return round(v, 4)
        return "" if v is None else v
    if col in row.outputs:
        return row.outputs[col]
    v = row.values.get(col, "")
    return json.dumps(v) if isinstance(v, bool) else v


def _write_csv(path: Path, rows: list[SweepRow]) -> Path:
    cols = _columns(rows)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    for r in rows:
        w.writerow([_cell(r, c) for c in cols])
    return write_text_atomic(path, buf.getvalue())


def _versions() -> dict[str, str]:
    from importlib import metadata

    from .. import __version__

    out = {"quadnodes": __version__, "python": platform.python_version()}
    for dist in ("numpy", "scipy", "build123d", "cadquery-ocp", "dask", "distributed", "matplotlib", "plotly"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            pass
    return out


# ----------------------------------------------------------------------------- the client
class _Client:
    """A Dask client on an embedded LocalCluster (``address`` None) or on an existing scheduler."""

    def __init__(self, address: str | None, workers: int) -> None:
        import logging

        from distributed import Client, LocalCluster

        self.cluster = None
        self.has_dashboard = True
        if address is None:
            try:
                import bokeh  # noqa: F401  (the dashboard's dependency)

                self.has_dashboard = True
            except ImportError:
                self.has_dashboard = False
            # the scheduler's HTTP server (health, and the dashboard when bokeh is there) on a free local port
            self.cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                        host="127.0.0.1", dashboard_address="127.0.0.1:0",
                                        silence_logs=logging.CRITICAL)
            self.client = Client(self.cluster)
        else:
            try:
                self.client = Client(address, timeout="20s")
            except (OSError, TimeoutError) as exc:
                raise InputError(f"--scheduler {address}: cannot reach a Dask scheduler there: {exc}") from exc
        self.dashboard = self._dashboard()

    def _dashboard(self) -> str | None:
        try:
            services = self.client.scheduler_info().get("services", {})
        except Exception:  # noqa: BLE001 - the address is a nicety; the sweep does not depend on it
            return None
        return self.client.dashboard_link if "dashboard" in services and self.has_dashboard else None

    def close(self) -> None:
        try:
            self.client.close()
        finally:
            if self.cluster is not None:
                self.cluster.close()


@dataclass
class _Plan:
    row: SweepRow
    calls: dict[str, NodeCall]
    action: dict[str, str]  # node id -> compute | load | cached | skipped
    dkey: dict[str, str]


def _dask_key(call: NodeCall, sweep_id: str, index: int) -> str:
    name = call.node_type.name
    if call.key is None:
        return f"{name}-{sweep_id}-{index}-{call.node_id}"
    return f"{name}-{call.key}"


def _plan_variant(row: SweepRow, calls: list[NodeCall], cache: Cache | None, reusable: dict[str, bool],
                  sweep_id: str) -> _Plan:
    """Decide per node: compute, load from the disk cache, cached (not even loaded) or skipped (not needed)."""
    by_id = {c.node_id: c for c in calls}
    consumers: dict[str, list[str]] = {c.node_id: [] for c in calls}
    for c in calls:
        for ref in c.connections.values():
            consumers[ref.node].append(c.node_id)
    need_data: set[str] = set()
    action: dict[str, str] = {}
    for c in reversed(calls):
        scalars = any(_may_have_scalars(p.annotation) for p in c.node_type.outputs) and not c.node_type.writes
        demanded = c.node_id in need_data or scalars or not consumers[c.node_id]
        if not demanded:
            action[c.node_id] = "skipped"
            continue
        ok = False
        if cache is not None and cache.directory is not None and c.key is not None:
            if c.key not in reusable:
                ok = cache.on_disk(c.key)
                if ok and c.node_type.writes:
                    entry = cache.get(c.key)
                    ok = entry is not None and c.reusable(entry)
                reusable[c.key] = ok
            ok = reusable[c.key]
        if ok:
            action[c.node_id] = "load" if (c.node_id in need_data or scalars) else "cached"
        else:
            action[c.node_id] = "compute"
            need_data.update(ref.node for ref in c.connections.values())
    return _Plan(row, by_id, action, {c.node_id: _dask_key(c, sweep_id, row.index) for c in calls})


def run_sweep(
    graph: Graph,
    vary: Mapping[str, Any],
    *,
    out: str | os.PathLike[str],
    zip: bool = False,  # noqa: A002
    overrides: Mapping[str, Any] | None = None,
    cache: str | os.PathLike[str] | Cache | bool = True,
    scheduler: str | None = None,
    workers: int = 2,
    plot: tuple[str, str] | None = None,
    progress: Callable[[int, int, SweepRow], None] | None = None,
    on_start: Callable[[str | None, int], None] | None = None,
    command: Sequence[str] | None = None,
    source: str | os.PathLike[str] | None = None,
) -> SweepResult:
    """Run every variant of ``graph`` on Dask; shared nodes once; one folder and one CSV row per variant.

    Parameters
    ----------
    graph : Graph
        The design; writer nodes must name relative output paths.
    vary : mapping ``"node.setting"`` -> values
        See :func:`variants`; every value is checked like a ``--set`` value first.
    out : path
        Folder of the results: ``<variant folder>/`` per variant, ``sweep.csv``,
        ``sweep.json`` (the manifest), and with ``plot`` ``sweep.png`` + ``sweep.html``.
    zip : bool
        Pair the values instead of taking every combination.
    overrides : mapping, optional
        ``{"node.setting": value}`` applied to every variant (``--set``).
    cache : path, Cache, bool
        The disk cache folder, which workers read and write (on several machines
        it must be shared by all); True: ``<out>/.cache``; False: none (shared
        nodes still run once within the sweep).
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``); None: an
        embedded cluster of ``workers`` processes with one thread each.
    workers : int
        Worker processes of the embedded cluster.
    plot : (str, str), optional
        Columns for x and y of the scatter plot (Pareto front: lower is better on both).
    progress : callable, optional
        ``progress(done, total, row)`` after each variant.
    on_start : callable, optional
        ``on_start(dashboard_address_or_None, n_tasks)`` once the tasks are submitted.
    command, source : optional
        The command line and graph file, for the manifest.

    Returns
    -------
    SweepResult

    Raises
    ------
    GraphError
        A malformed ``vary``, a value a setting does not take (naming it), an
        absolute output path, an invalid graph.
    InputError
        ``workers`` below 1, an unreachable scheduler, a plot column that is not in the table.

    Examples
    --------
    A design script (guard it with ``if __name__ == "__main__":`` — the embedded
    cluster starts worker processes)::

        from quadnodes.graph import load
        import quadnodes.nodes
        res = load("examples/quickstart.toml").sweep(
            {"fair.weight": [0.1, 0.3, 1], "noisy.seed": "1:5"}, out="out/qs-sweep")
        best = min((r for r in res.rows if r.status == "ok"),
                   key=lambda r: r.values["metrics_fair.metrics.zigzag_max"])
    """
    t_start = time.perf_counter()
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise InputError(f"workers: expected a positive int, got {workers!r}")
    combos = variants(vary, zip=zip)
    base = graph.with_overrides(overrides) if overrides else graph
    base.validate()
    checked: set[str] = set()
    for combo in combos:  # every value once, like --set: the message names node and setting
        for k, v in combo.items():
            tag = f"{k}\0{json.dumps(v, sort_keys=True, default=str)}"
            if tag not in checked:
                checked.add(tag)
                try:
                    base.with_overrides({k: v})
                except GraphError as exc:
                    if not getattr(exc, "out_of_range", False):
                        raise  # unknown node or setting, wrong type: the whole sweep is wrong
                    # a value out of range spoils its variants only: each becomes a row with the error
    out_dir = Path(out).expanduser().resolve()
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"out: cannot create {str(out_dir)!r}: {exc}") from exc
    if cache is True:
        disk: Cache | None = Cache(out_dir / ".cache")
    elif cache is False or cache is None:
        disk = None
    elif isinstance(cache, Cache):
        disk = cache if cache.directory is not None else None
    else:
        disk = Cache(Path(cache).expanduser().resolve())
    cache_dir = str(disk.directory) if disk is not None and disk.directory is not None else None

    _rooted(base, out_dir)  # refuses absolute output paths before anything runs
    sweep_id = uuid.uuid4().hex[:12]
    names = _folder_names(combos)
    rows = [SweepRow(i, dict(c), n) for i, (c, n) in enumerate(builtins_zip(combos, names))]
    plans: list[_Plan] = []
    reusable: dict[str, bool] = {}
    for row in rows:
        folder = out_dir / row.folder
        try:
            g = _rooted(base.with_overrides(row.settings), folder)
            calls = plan(g)
            folder.mkdir(exist_ok=True)
        except QuadnodesError as exc:  # e.g. a file it reads is missing
            row.status, row.error = "error", str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            continue
        for c in calls:
            for s in c.node_type.writes:
                v = c.settings[s]
                for i, p in enumerate(v if isinstance(v, (list, tuple)) else [v]):
                    col = f"{c.node_id}.{s}" + (f".{i}" if isinstance(v, (list, tuple)) else "")
                    row.outputs[col] = os.path.relpath(p, out_dir)
        plans.append(_plan_variant(row, calls, disk, reusable, sweep_id))
    if plot is not None:
        _check_plot_columns(plot)

    tasks: dict[str, tuple[str, str]] = {}
    dashboard = None
    client = None
    try:
        if plans:
            client = _Client(scheduler, workers)
            dashboard = client.dashboard
            _submit_and_wait(client.client, plans, tasks, cache_dir, sweep_id, out_dir, t_start,
                             progress, on_start, len(rows), dashboard)
    finally:
        if client is not None:
            client.close()
        csv_path = _write_csv(out_dir / "sweep.csv", rows)
        manifest = _write_manifest(out_dir, graph, source, command, vary, zip, overrides, scheduler, workers,
                                   cache_dir, rows, tasks, time.perf_counter() - t_start)
    result = SweepResult(out_dir, rows, csv_path, manifest, tasks, time.perf_counter() - t_start,
                         sum(len(p.calls) for p in plans), dashboard)
    if plot is not None:
        result.plots = _plots(result, plot)
    return result


def _submit_and_wait(client: Any, plans: list[_Plan], tasks: dict[str, tuple[str, str]], cache_dir: str | None,
                     sweep_id: str, out_dir: Path, t_start: float,
                     progress: Callable[[int, int, SweepRow], None] | None,
                     on_start: Callable[[str | None, int], None] | None, total: int,
                     dashboard: str | None) -> None:
    from distributed import as_completed

    futures: dict[str, Any] = {}
    briefs: dict[str, Any] = {}
    uses: dict[str, int] = {}
    summaries: dict[Any, _Plan] = {}
    for p in plans:
        variant_briefs = {}
        for node_id, call in p.calls.items():
            act = p.action[node_id]
            if act not in ("compute", "load"):
                continue
            dk = p.dkey[node_id]
            if dk not in futures:
                if act == "load":
                    futures[dk] = client.submit(_load, call, cache_dir, key=dk, pure=False)
                else:
                    up = {ref.node: futures[p.dkey[ref.node]] for ref in call.connections.values()}
                    futures[dk] = client.submit(_compute, call, cache_dir, up, key=dk, pure=False)
                briefs[dk] = client.submit(_brief, futures[dk], key=f"brief-{dk}", pure=False)
                tasks[dk] = (node_id, act)
            uses[dk] = uses.get(dk, 0) + 1
            variant_briefs[node_id] = briefs[dk]
        fut = client.submit(_collect, variant_briefs, key=f"variant-{sweep_id}-{p.row.index}", pure=False)
        summaries[fut] = p
    if on_start is not None:
        on_start(dashboard, len(tasks))
    done = total - len(plans)  # rows that failed while planning are done already
    for fut in as_completed(list(summaries)):
        p = summaries.pop(fut)
        row = p.row
        row.elapsed = time.perf_counter() - t_start
        if fut.status == "error":
            exc = fut.exception()
            text = str(exc) if isinstance(exc, QuadnodesError) and str(exc) else f"{type(exc).__name__}: {exc}"
            row.status, row.error = "error", text.splitlines()[0] if text else type(exc).__name__
        else:
            result = fut.result()
            for node_id, act in p.action.items():
                if node_id in result:
                    status, seconds, scalars = result[node_id]
                    row.node_seconds[node_id] = seconds
                    if status == "ran":
                        row.ran += 1
                        row.seconds += seconds
                    else:
                        row.cached += 1
                    for k, v in scalars.items():
                        row.values[f"{node_id}.{k}"] = v
                else:  # read without loading, or not needed because what it feeds was reused
                    row.cached += 1
            missing = [rel for rel in row.outputs.values() if not (out_dir / rel).exists()]
            if missing:
                row.status = "error"
                row.error = (f"{missing[0]} was written on a worker but is not visible here; with workers on "
                             "several machines the output folder must be shared by all of them")
            else:
                row.status = "ok"
        for dk in set(p.dkey[n] for n, a in p.action.items() if a in ("compute", "load")):
            uses[dk] -= 1
            if uses[dk] == 0:  # no pending variant needs it: let the cluster free it
                futures.pop(dk, None)
                briefs.pop(dk, None)
        done += 1
        if progress is not None:
            progress(done, total, row)
        del fut


def _write_manifest(out_dir: Path, graph: Graph, source: Any, command: Any, vary: Mapping[str, Any], zip_: bool,
                    overrides: Any, scheduler: str | None, workers: int, cache_dir: str | None,
                    rows: list[SweepRow], tasks: dict[str, tuple[str, str]], seconds: float) -> Path:
    from .files import dumps

    try:
        graph_text = dumps(graph, fmt="toml")
    except QuadnodesError:
        graph_text = None
    data = {
        "format": "quadnodes-sweep",
        "version": 1,
        "graph_file": None if source is None else str(source),
        "graph_file_sha256": None if source is None else file_digest(source),
        "graph_sha256": None if graph_text is None else hashlib.sha256(graph_text.encode()).hexdigest(),
        "command": None if command is None else list(command),
        "vary": {k: (list(v) if not isinstance(v, str) else v) for k, v in vary.items()},
        "zip": zip_,
        "set": {} if not overrides else dict(overrides),
        "scheduler": scheduler or f"embedded LocalCluster, {workers} worker processes x 1 thread",
        "cache": cache_dir,
        "versions": _versions(),
        "host": socket.gethostname(),
        "finished_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "seconds": round(seconds, 3),
        "variants": len(rows),
        "status": {s: sum(r.status == s for r in rows) for s in ("ok", "error", "not run")},
        "tasks": {"compute": sum(a == "compute" for _, a in tasks.values()),
                  "load": sum(a == "load" for _, a in tasks.values())},
        "node_runs_needed": sum(r.ran for r in rows),
    }
    return write_text_atomic(out_dir / "sweep.json", json.dumps(data, indent=2, default=str) + "\n")


# ----------------------------------------------------------------------------- picking: plot and page
def _check_plot_columns(plot: Any) -> None:
    if not (isinstance(plot, (tuple, list)) and len(plot) == 2 and all(isinstance(c, str) and c for c in plot)):
        raise InputError(f"plot: expected (x column, y column), got {plot!r}")


def _number(v: Any) -> float:
    if isinstance(v, bool) or v == "" or v is None:
        return math.nan
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def pareto_front(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Mask of the points no other point beats on both x and y (lower is better; NaN never on the front).

    Examples
    --------
    >>> pareto_front(np.array([1.0, 2, 3, 2]), np.array([3.0, 1, 2, 3])).tolist()
    [True, True, False, False]
    """
    x, y = np.asarray(x, float), np.asarray(y, float)
    ok = np.isfinite(x) & np.isfinite(y)
    order = np.lexsort((y, x))
    front = np.zeros(len(x), bool)
    best = math.inf
    for i in order:
        if ok[i] and y[i] < best:
            front[i] = True
            best = y[i]
    return front


def _plots(result: SweepResult, plot: tuple[str, str]) -> list[Path]:
    xcol, ycol = plot
    table = result.table()
    cols = result.columns()
    for c in (xcol, ycol):
        if c not in cols:
            numeric = [k for k in cols if any(math.isfinite(_number(r[k])) for r in table)]
            from ._util import did_you_mean

            raise InputError(f"--plot: no column {c!r} in sweep.csv{did_you_mean(c, numeric, kind='numeric columns')}")
    ok = [r for r in table if r["status"] == "ok"]
    x = np.array([_number(r[xcol]) for r in ok])
    y = np.array([_number(r[ycol]) for r in ok])
    front = pareto_front(x, y) if len(ok) else np.zeros(0, bool)
    labels = [r["folder"] for r in ok]
    return [_scatter_png(result.out / "sweep.png", x, y, front, labels, xcol, ycol),
            _scatter_html(result.out / "sweep.html", table, cols, x, y, front, ok, xcol, ycol)]


def _scatter_png(path: Path, x: np.ndarray, y: np.ndarray, front: np.ndarray, labels: list[str],
                 xcol: str, ycol: str) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 6), dpi=120)
    ax = fig.add_subplot()
    ax.scatter(x[~front], y[~front], s=22, c="#9aa5b1", label="variant", zorder=2)
    order = np.argsort(x[front])
    fx, fy = x[front][order], y[front][order]
    ax.step(fx, fy, where="post", color="#d9480f", lw=1.2, zorder=3)
    ax.scatter(fx, fy, s=48, c="#d9480f", edgecolors="black", linewidths=0.6, zorder=4,
               label=f"Pareto front ({len(fx)}): lower is better on both")
    fl = [labels[i] for i in np.flatnonzero(front)[order]]
    for xi, yi, t in builtins_zip(fx, fy, fl[:12]):
        ax.annotate(t.replace("__", "\n"), (xi, yi), textcoords="offset points", xytext=(6, 4), fontsize=6.5)
    ax.set_xlabel(xcol)
    ax.set_ylabel(ycol)
    ax.grid(True, alpha=0.3)
    ax.set_title(f"{len(x)} variants ok", fontsize=10)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    return write_atomic(path, lambda tmp: fig.savefig(tmp, format="png"))


def _scatter_html(path: Path, table: list[dict[str, Any]], cols: list[str], x: np.ndarray, y: np.ndarray,
                  front: np.ndarray, ok: list[dict[str, Any]], xcol: str, ycol: str) -> Path:
    import plotly.graph_objects as go
    import plotly.io as pio

    names = [r["folder"] for r in ok]
    fig = go.Figure()
    for mask, name, color, size in ((~front, "variant", "#9aa5b1", 8), (front, "Pareto front", "#d9480f", 11)):
        idx = np.flatnonzero(mask)
        fig.add_trace(go.Scatter(x=x[idx], y=y[idx], mode="markers", name=name,
                                 marker={"color": color, "size": size, "line": {"width": 1, "color": "#333"}},
                                 text=[names[i] for i in idx], customdata=[names[i] for i in idx],
                                 hovertemplate="%{text}<br>x=%{x:.4g}<br>y=%{y:.4g}<extra></extra>"))
    order = np.flatnonzero(front)[np.argsort(x[front])]
    fig.add_trace(go.Scatter(x=x[order], y=y[order], mode="lines", line={"shape": "hv", "color": "#d9480f"},
                             hoverinfo="skip", showlegend=False))
    fig.update_layout(xaxis_title=xcol, yaxis_title=ycol, height=520, margin={"l": 60, "r": 20, "t": 30, "b": 50},
                      legend={"orientation": "h"})
    body = pio.to_html(fig, full_html=False, include_plotlyjs=True, include_mathjax=False, div_id="plot",
                       config={"displaylogo": False, "responsive": True})
    settings = [c for c in cols[: cols.index("status")]] if "status" in cols else []
    first = settings + [xcol, ycol, "status", "error", "folder"]
    show = first + [c for c in cols if c not in first]
    links = {c for r in table for c in show if isinstance(r.get(c), str) and "/" in r[c] and c.endswith("path")}
    on_front = {names[i] for i in np.flatnonzero(front)}
    head = "".join(f"<th onclick=\"sortBy({i})\">{_html.escape(c)}</th>" for i, c in enumerate(show))
    body_rows = []
    for r in table:
        cells = []
        for c in show:
            v = r.get(c, "")
            text = _html.escape(f"{v:.6g}" if isinstance(v, float) else str(v))
            if (c == "folder" or c in links) and v:
                text = f"<a href=\"{_html.escape(str(v))}{'/' if c == 'folder' else ''}\">{text}</a>"
            elif c in (xcol, ycol):
                text = f"<b>{text}</b>"
            cells.append(f"<td>{text}</td>")
        cls = " class=\"front\"" if r["folder"] in on_front else ""
        body_rows.append(f"<tr id=\"{_html.escape(r['folder'])}\"{cls}>{''.join(cells)}</tr>")
    page = (
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
        f"<title>sweep: {_html.escape(ycol)} vs {_html.escape(xcol)} — quadnodes</title>\n<style>\n"
        "body { font-family: system-ui, sans-serif; margin: 12px; }\n"
        ".wrap { overflow: auto; max-height: 45vh; }\n"
        "table { border-collapse: collapse; font-size: 12px; }\n"
        "th, td { border: 1px solid #ddd; padding: 2px 6px; white-space: nowrap; text-align: right; }\n"
        "th { position: sticky; top: 0; background: #f1f3f5; cursor: pointer; }\n"
        "tr.front td { background: #fff4e6; } tr.picked td { background: #d0ebff; }\n"
        "</style>\n</head>\n<body>\n"
        f"<p>{len(table)} variants; Pareto front (lower is better on both) in orange. Click a point to find its "
        "row; click a column head to sort.</p>\n"
        f"{body}\n<div class=\"wrap\"><table id=\"rows\"><thead><tr>{head}</tr></thead><tbody>"
        + "".join(body_rows)
        + "</tbody></table></div>\n<script>\n"
        "function sortBy(i) { const tb = document.querySelector('#rows tbody');\n"
        "  const rows = Array.from(tb.rows); const asc = tb.dataset.col == i ? tb.dataset.asc != '1' : true;\n"
        "  const key = r => { const t = r.cells[i].innerText; const n = parseFloat(t);\n"
        "    return isNaN(n) ? t : n; };\n"
        "  rows.sort((a, b) => { const x = key(a), y = key(b); return (x < y ? -1 : x > y ? 1 : 0) * (asc ? 1 : -1); });\n"
        "  rows.forEach(r => tb.appendChild(r)); tb.dataset.col = i; tb.dataset.asc = asc ? '1' : '0'; }\n"
        "document.getElementById('plot').on('plotly_click', ev => { const id = ev.points[0].customdata;\n"
        "  document.querySelectorAll('tr.picked').forEach(r => r.classList.remove('picked'));\n"
        "  const row = document.getElementById(id); if (row) { row.classList.add('picked');\n"
        "    row.scrollIntoView({block: 'center'}); } });\n"
        "</script>\n</body>\n</html>\n"
    )
    return write_text_atomic(path, page)
