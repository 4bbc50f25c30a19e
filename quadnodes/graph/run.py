"""Running a graph: topological order, a cache key per node, reuse or execute.

The key of a node is the sha256 of

- its ``op@version`` and code fingerprint (its source, its module's source when
  outside quadnodes, and a digest of the quadnodes sources);
- all its settings, coerced and with defaults filled in, as canonical JSON;
- per input port, in port order: the upstream node's key and port, or the
  fingerprint of a constant Python value (or "default" when unconnected);
- for settings listed in ``reads``: each path as written and the digest of the
  file's bytes (a folder: of all its files).

Keys chain, so a change anywhere upstream changes every key below it. A node
whose key cannot be computed exactly — a constant input that cannot be
fingerprinted, a node function without code, or an upstream node in that state —
has no key: it always runs and is never cached, and neither is anything
downstream of it. Nothing stale is ever reused.

A node with ``writes`` settings is reused from the cache only while every file
it wrote is still there with the same bytes; otherwise it runs again.

Before anything runs, the paths are checked (:mod:`quadnodes.graph.paths`):
writer paths resolve inside the run's output folder (``out``, else the graph's
folder, else the working directory), no two writers share a file, and a graph
loaded from a file reads only inside its own folder (plus ``allow_read``).
"""

from __future__ import annotations

import hashlib
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path, PurePath
from typing import Any, Literal

from ..errors import NodeError, QuadnodesError
from ._types import to_plain
from ._util import graph_error, label
from .cache import Cache, CacheEntry
from .fingerprint import canonical_json, file_digest, fingerprint
from .graph import Constant, Graph, NodeHandle, NodeSpec, PortRef
from .node import NodeType
from .templates import expand
from ..progress import reporting

__all__ = ["RunRecord", "ProgressEvent", "RunResult", "run", "keys", "NodeCall", "plan"]


@dataclass(frozen=True)
class RunRecord:
    """What happened to one node in a run.

    ``status`` is ``"ran"`` (the function was called) or ``"cached"`` (outputs
    reused); ``key`` is None for a node that cannot be cached; ``seconds`` is
    the wall time spent on the node in this run. ``files`` are the files of its
    ``writes`` settings that exist after the run: written by this run when
    ``status`` is ``"ran"``, found intact (same bytes as when written) when
    ``"cached"``.
    """

    id: str
    op: str
    status: Literal["ran", "cached"]
    seconds: float
    key: str | None
    files: tuple[Path, ...] = field(default=())


@dataclass(frozen=True)
class ProgressEvent:
    """A progress callback's argument.

    ``kind`` is ``"started"`` (before the cache lookup), ``"progress"`` (the
    node's function called :func:`~quadnodes.progress.report_progress`;
    ``fraction`` and ``message`` set) or ``"finished"`` (``record`` set).
    ``index`` counts nodes in run order from 0, of ``total``.
    """

    kind: Literal["started", "progress", "finished"]
    node_id: str
    op: str
    index: int
    total: int
    fraction: float | None = None
    message: str = ""
    record: RunRecord | None = None


class RunResult:
    """Outputs and records of a run.

    Index it with a node handle (single-output node), a port reference
    (``h.mesh``), ``"node.port"`` or a node id (single output).
    """

    def __init__(self, graph: Graph, records: tuple[RunRecord, ...], outputs: dict[str, dict[str, Any]]) -> None:
        self.graph = graph
        self.records = records
        self.outputs = outputs

    def __getitem__(self, ref: NodeHandle | PortRef | str) -> Any:
        if isinstance(ref, NodeHandle):
            ref = ref.ref
        elif isinstance(ref, str):
            if "." in ref:
                ref = PortRef.parse(ref)
            else:
                if ref not in self.outputs:
                    raise graph_error(f"no node {ref!r} in this run", node_id=ref)
                ref = self.graph[ref].ref
        if not isinstance(ref, PortRef):
            raise TypeError(f"index a RunResult with a node handle, a port reference or a string, not {ref!r}")
        ports = self.outputs.get(ref.node)
        if ports is None:
            raise graph_error(f"no node {ref.node!r} in this run", node_id=ref.node)
        if ref.port not in ports:
            raise graph_error(f"{label(ref.node)} has no output {ref.port!r} (outputs: {', '.join(ports)})",
                              node_id=ref.node)
        return ports[ref.port]

    def record(self, node: str | NodeHandle) -> RunRecord:
        """The record of one node."""
        node_id = node.id if isinstance(node, NodeHandle) else node
        for r in self.records:
            if r.id == node_id:
                return r
        raise graph_error(f"no node {node_id!r} in this run", node_id=node_id)

    @property
    def ran(self) -> list[str]:
        """Ids of the nodes whose function was called, in run order."""
        return [r.id for r in self.records if r.status == "ran"]

    @property
    def cached(self) -> list[str]:
        """Ids of the nodes reused from the cache, in run order."""
        return [r.id for r in self.records if r.status == "cached"]

    def __repr__(self) -> str:
        return f"RunResult(ran={self.ran}, cached={self.cached})"


# ---------------------------------------------------------------------------
def _node_error(message: str, node_id: str) -> NodeError:
    err = NodeError(message)
    err.node_id = node_id  # type: ignore[attr-defined]
    return err


def _explain(exc: BaseException) -> str:
    text = str(exc)
    if isinstance(exc, QuadnodesError) and text:
        return text
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _path_values(value: Any) -> list[Any]:
    if value is None:
        return []
    if isinstance(value, (list, tuple)):
        return [p for v in value for p in _path_values(v)]
    return [value]


def _resolve(value: Any, base: Path | None, *, strings: bool) -> Any:
    """Relative paths joined to ``base``; strings too when ``strings`` (file settings typed str)."""
    if isinstance(value, PurePath):
        return value if base is None or value.is_absolute() else type(value)(base / value)
    if strings and isinstance(value, str):
        return value if base is None or os.path.isabs(value) else str(base / value)
    if isinstance(value, list):
        return [_resolve(v, base, strings=strings) for v in value]
    if isinstance(value, tuple):
        return tuple(_resolve(v, base, strings=strings) for v in value)
    if isinstance(value, dict):
        return {k: _resolve(v, base, strings=strings) for k, v in value.items()}
    return value


@dataclass
class _Prepared:
    node_id: str
    nt: NodeType
    settings: dict[str, Any]  # as passed to the function (paths resolved)
    inputs: dict[str, Any]
    key: str | None
    links: dict[str, PortRef] | None = None  # read from upstream outputs only when the node executes


def _prepare(
    g: Graph,
    spec: NodeSpec,
    keys: Mapping[str, str | None],
    outputs: Mapping[str, Mapping[str, Any]] | None,
    out: Path | None = None,
) -> _Prepared:
    node_id = spec.id
    nt = g.registry.get(spec.op, node_id=node_id)
    where = label(node_id, nt.op)
    settings = expand(g, nt, nt.resolve_settings(spec.params, node_id=node_id))  # {node.setting} in titles
    base = Path(g.base_dir) if g.base_dir is not None else None
    out_base = out if out is not None else base
    call_settings = {k: _resolve(v, out_base if k in nt.writes else base, strings=k in nt.reads or k in nt.writes)
                     for k, v in settings.items()}
    cacheable = nt.code_fingerprint is not None
    inputs: dict[str, Any] = {}
    links: dict[str, PortRef] = {}
    parts: list[list[Any]] = []
    for p in nt.inputs:
        conn = spec.inputs.get(p.name)
        if conn is None:
            parts.append([p.name, "default"])
        elif isinstance(conn, Constant):
            inputs[p.name] = conn.value
            fp = fingerprint(conn.value)
            cacheable &= fp is not None
            parts.append([p.name, "const", fp])
        else:
            if outputs is not None:
                links[p.name] = conn
            up = keys.get(conn.node)
            cacheable &= up is not None
            parts.append([p.name, "node", up, conn.port])
    files: list[list[Any]] = []
    for s in nt.reads:
        digests = []
        for shown, path in zip(_path_values(to_plain(settings[s])), _path_values(call_settings[s])):
            d = file_digest(path)
            if d is None:
                raise _node_error(f"{where}: setting {s!r}: file not found: {str(path)!r}", node_id)
            digests.append([shown, d])
        files.append([s, digests])
    key = None
    if cacheable:
        payload = {
            "op": nt.op,
            "code": nt.code_fingerprint,
            "settings": to_plain(settings),
            "inputs": parts,
            "files": files,
        }
        key = hashlib.sha256(canonical_json(payload).encode()).hexdigest()
    return _Prepared(node_id, nt, call_settings, inputs, key, links)


def _stamp(path: Any) -> tuple[int, int, int] | None:
    """``(mtime_ns, inode, size)`` of a file, None when missing: tells a file rewritten by this run."""
    try:
        st = os.stat(os.fspath(path))
    except (OSError, TypeError, ValueError):
        return None
    return (st.st_mtime_ns, st.st_ino, st.st_size)


def _written(nt: NodeType, settings: Mapping[str, Any]) -> dict[str, list[str | None]]:
    return {s: [file_digest(p) for p in _path_values(settings[s])] for s in nt.writes}


def keys(graph: Graph, *, overrides: Mapping[str, Any] | None = None) -> dict[str, str | None]:
    """The cache key of every node, without running anything.

    Files named in ``reads`` settings must exist already (a file written by an
    upstream node of the same graph only exists after a run).

    Raises
    ------
    GraphError
        If the graph is invalid.
    NodeError
        If a file named in a ``reads`` setting is missing.

    Examples
    --------
    >>> from quadnodes.graph.node import Registry, node
    >>> reg = Registry()
    >>> @node("num", registry=reg)
    ... def num(*, value: float = 0.0) -> float:
    ...     return value
    >>> g = Graph(registry=reg)
    >>> a = g.add("num", value=1); b = g.add("num", value=1.0)
    >>> k = keys(g)
    >>> k["num1"] == k["num2"], len(k["num1"])
    (True, 64)
    """
    g = graph.with_overrides(overrides) if overrides else graph
    g.validate()
    out: dict[str, str | None] = {}
    for node_id in g.order():
        out[node_id] = _prepare(g, g.nodes[node_id], out, None).key
    return out


def run(
    graph: Graph,
    *,
    cache: Cache | None = None,
    overrides: Mapping[str, Any] | None = None,
    progress: Callable[[ProgressEvent], None] | None = None,
    out: str | os.PathLike[str] | None = None,
    allow_read: Sequence[str | os.PathLike[str]] = (),
) -> RunResult:
    """Run every node of ``graph`` in dependency order, reusing cached results.

    Parameters
    ----------
    graph : Graph
    cache : Cache, optional
        Where results are looked up and stored. None: nothing is reused (keys are
        still computed and recorded).
    overrides : mapping, optional
        ``{"node.setting": value}`` applied to a copy of the graph first.
    progress : callable, optional
        Called with a :class:`ProgressEvent` when a node starts and finishes, and
        whenever its function calls :func:`~quadnodes.progress.report_progress`.
    out : path-like, optional
        The output folder: relative paths of ``writes`` settings are joined to it,
        and every output must resolve inside it. Default: the graph's folder
        (``graph.base_dir``), else the working directory.
    allow_read : paths
        Folders besides the graph file's own that a graph loaded from a file may
        read from (a graph built in Python, without ``base_dir``, reads anywhere).

    Returns
    -------
    RunResult
        ``.records`` (one :class:`RunRecord` per node, in run order) and
        ``.outputs[node_id][port]``.

    Raises
    ------
    GraphError
        If the graph (after overrides) is invalid, or an output leaves ``out``, two
        outputs share a file, or a read leaves the graph's folder (see
        :mod:`quadnodes.graph.paths`); nothing runs then.
    NodeError
        ``"node 'fair1' (fair@1): <message>"`` when a node's function raises (the
        original exception is chained as ``__cause__``), or a file named in its
        ``reads`` settings is missing. The error has a ``node_id`` attribute. The
        run stops there; results of nodes that finished stay in the cache.

    Examples
    --------
    >>> from quadnodes.graph.node import Registry, node
    >>> reg = Registry()
    >>> @node("num", registry=reg)
    ... def num(*, value: float = 0.0) -> float:
    ...     return value
    >>> @node("inv", registry=reg)
    ... def inv(x: float) -> float:
    ...     return 1 / x
    >>> g = Graph(registry=reg)
    >>> x = g.add("num", id="x", value=4)
    >>> y = g.add("inv", x, id="y")
    >>> c = Cache()
    >>> run(g, cache=c)[y], [r.status for r in run(g, cache=c).records]
    (0.25, ['cached', 'cached'])
    >>> run(g, cache=c, overrides={"x.value": 2}).ran
    ['x', 'y']
    >>> run(g, overrides={"x.value": 0})
    Traceback (most recent call last):
    ...
    quadnodes.errors.NodeError: node 'y' (inv@1): ZeroDivisionError: float division by zero
    """
    from .paths import check_paths

    g = graph.with_overrides(overrides) if overrides else graph
    g.validate()
    out_dir = Path(out) if out is not None else Path(g.base_dir) if g.base_dir is not None else Path.cwd()
    check_paths(g, out=out_dir, read_roots=None if g.base_dir is None else [g.base_dir, *allow_read])
    order = g.order()
    total = len(order)
    node_keys: dict[str, str | None] = {}
    outputs: dict[str, dict[str, Any]] = {}
    records: list[RunRecord] = []
    for index, node_id in enumerate(order):
        spec = g.nodes[node_id]
        op = spec.op
        t0 = time.perf_counter()
        if progress is not None:
            progress(ProgressEvent("started", node_id, op, index, total))
        prep = _prepare(g, spec, node_keys, outputs, out_dir)
        nt, key = prep.nt, prep.key
        node_keys[node_id] = key
        entry = cache.get(key) if (cache is not None and key is not None) else None
        now: dict[str, list[str | None]] = {}
        now_reported: dict[str, list[str | None]] = {}
        if entry is not None and nt.writes:
            now = _written(nt, prep.settings)
            if any(now.get(s) != list(entry.files.get(s, ())) for s in nt.writes):
                entry = None  # an output file is gone or was changed: write it again
        if entry is not None:
            outputs[node_id] = entry.outputs  # type: ignore[assignment]  # read from disk: decoded on first use
            status: Literal["ran", "cached"] = "cached"
        else:
            before = {p: _stamp(p) for s in nt.writes for p in _path_values(prep.settings[s])}
            for port, conn in (prep.links or {}).items():
                prep.inputs[port] = outputs[conn.node][conn.port]
            outputs[node_id] = _execute(prep, op, index, total, progress)
            status = "ran"
            now = _written(nt, prep.settings) if nt.writes else {}
            # a file this run did not touch (the node skipped it) is not reported as written
            now_reported = {s: [d if d is not None and _stamp(p) != before.get(p) else None
                                for p, d in zip(_path_values(prep.settings[s]), ds)] for s, ds in now.items()}
            if cache is not None and key is not None:
                if all(d is not None for ds in now.values() for d in ds):
                    cache.put(key, CacheEntry(dict(outputs[node_id]), now))  # type: ignore[arg-type]
        shown = now_reported if status == "ran" else now
        files = tuple(Path(os.fspath(p)) for s in nt.writes
                      for p, d in zip(_path_values(prep.settings[s]), shown.get(s, ())) if d is not None)
        record = RunRecord(node_id, op, status, time.perf_counter() - t0, key, files)
        records.append(record)
        if progress is not None:
            progress(ProgressEvent("finished", node_id, op, index, total, record=record))
    return RunResult(g, tuple(records), outputs)


def _execute(
    prep: _Prepared,
    op: str,
    index: int,
    total: int,
    progress: Callable[[ProgressEvent], None] | None,
) -> dict[str, Any]:
    def forward(fraction: float, message: str) -> None:
        if progress is not None:
            progress(ProgressEvent("progress", prep.node_id, op, index, total, fraction, message))

    try:
        with reporting(forward):
            return prep.nt.call(prep.inputs, prep.settings)
    except Exception as exc:
        raise _node_error(f"{label(prep.node_id, op)}: {_explain(exc)}", prep.node_id) from exc



# --------------------------------------------------------------------------- one node at a time, elsewhere
@dataclass(frozen=True)
class NodeCall:
    """One node of a graph, ready to run in another process (what :mod:`quadnodes.graph.sweep` ships to workers).

    ``settings`` are as passed to the function (defaults filled in, relative
    paths resolved), ``constants`` the Python values wired into input ports,
    ``connections`` the upstream ports by input port, ``key`` the cache key
    (None: never cached). Plain dicts, so it pickles.
    """

    node_id: str
    node_type: NodeType
    settings: dict[str, Any]
    constants: dict[str, Any]
    connections: dict[str, PortRef]
    key: str | None

    @property
    def op(self) -> str:
        return self.node_type.op

    def execute(self, inputs: Mapping[str, Any]) -> dict[str, Any]:
        """Call the node with ``inputs`` (upstream values by port; constants are added).

        Raises
        ------
        NodeError
            ``"node 'fair' (fair@1): <message>"`` when the function raises (chained).
        """
        prep = _Prepared(self.node_id, self.node_type, dict(self.settings), {**self.constants, **inputs}, self.key)
        return _execute(prep, self.op, 0, 1, None)

    def written(self) -> dict[str, list[str | None]]:
        """Digests of the files named by the node's ``writes`` settings (None for a missing file)."""
        return _written(self.node_type, self.settings)

    def reusable(self, entry: CacheEntry) -> bool:
        """Whether a cache entry may stand for this node: every file it wrote is still there, unchanged."""
        if not self.node_type.writes:
            return True
        now = self.written()
        return all(now.get(s) == list(entry.files.get(s, ())) for s in self.node_type.writes)


def plan(graph: Graph, *, overrides: Mapping[str, Any] | None = None) -> list[NodeCall]:
    """Every node of ``graph`` as a :class:`NodeCall`, in run order, with the keys :func:`run` would use.

    Raises
    ------
    GraphError
        If the graph (after overrides) is invalid.
    NodeError
        If a file named in a ``reads`` setting is missing.

    Examples
    --------
    >>> from quadnodes.graph.node import Registry, node
    >>> reg = Registry()
    >>> @node("num", registry=reg)
    ... def num(*, value: float = 0.0) -> float:
    ...     return value
    >>> @node("neg", registry=reg)
    ... def neg(x: float) -> float:
    ...     return -x
    >>> g = Graph(registry=reg)
    >>> x = g.add("num", id="x", value=2); y = g.add("neg", x, id="y")
    >>> calls = plan(g)
    >>> [c.node_id for c in calls], calls[1].connections, calls[1].key == keys(g)["y"]
    (['x', 'y'], {'x': PortRef(node='x', port='out')}, True)
    >>> calls[1].execute({"x": calls[0].execute({})["out"]})
    {'out': -2.0}
    """
    g = graph.with_overrides(overrides) if overrides else graph
    g.validate()
    node_keys: dict[str, str | None] = {}
    out: list[NodeCall] = []
    for node_id in g.order():
        spec = g.nodes[node_id]
        prep = _prepare(g, spec, node_keys, None)
        node_keys[node_id] = prep.key
        connections = {p: c for p, c in spec.inputs.items() if isinstance(c, PortRef)}
        out.append(NodeCall(node_id, prep.nt, dict(prep.settings), dict(prep.inputs), connections, prep.key))
    return out
