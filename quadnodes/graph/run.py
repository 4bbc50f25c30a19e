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
"""

from __future__ import annotations

import hashlib
import os
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path, PurePath
from typing import Any, Literal

from ..errors import NodeError, QuadnodesError
from ._types import to_plain
from ._util import graph_error, label
from .cache import Cache, CacheEntry
from .fingerprint import canonical_json, file_digest, fingerprint
from .graph import Constant, Graph, NodeHandle, NodeSpec, PortRef
from .node import NodeType
from ..progress import reporting

__all__ = ["RunRecord", "ProgressEvent", "RunResult", "run", "keys"]


@dataclass(frozen=True)
class RunRecord:
    """What happened to one node in a run.

    ``status`` is ``"ran"`` (the function was called) or ``"cached"`` (outputs
    reused); ``key`` is None for a node that cannot be cached; ``seconds`` is
    the wall time spent on the node in this run.
    """

    id: str
    op: str
    status: Literal["ran", "cached"]
    seconds: float
    key: str | None


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
) -> _Prepared:
    node_id = spec.id
    nt = g.registry.get(spec.op, node_id=node_id)
    where = label(node_id, nt.op)
    settings = nt.resolve_settings(spec.params, node_id=node_id)
    base = Path(g.base_dir) if g.base_dir is not None else None
    file_settings = set(nt.reads) | set(nt.writes)
    call_settings = {k: _resolve(v, base, strings=k in file_settings) for k, v in settings.items()}
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

    Returns
    -------
    RunResult
        ``.records`` (one :class:`RunRecord` per node, in run order) and
        ``.outputs[node_id][port]``.

    Raises
    ------
    GraphError
        If the graph (after overrides) is invalid; nothing runs then.
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
    g = graph.with_overrides(overrides) if overrides else graph
    g.validate()
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
        prep = _prepare(g, spec, node_keys, outputs)
        nt, key = prep.nt, prep.key
        node_keys[node_id] = key
        entry = cache.get(key) if (cache is not None and key is not None) else None
        if entry is not None and nt.writes:
            now = _written(nt, prep.settings)
            if any(now.get(s) != list(entry.files.get(s, ())) for s in nt.writes):
                entry = None  # an output file is gone or was changed: write it again
        if entry is not None:
            outputs[node_id] = entry.outputs  # type: ignore[assignment]  # read from disk: decoded on first use
            status: Literal["ran", "cached"] = "cached"
        else:
            for port, conn in (prep.links or {}).items():
                prep.inputs[port] = outputs[conn.node][conn.port]
            outputs[node_id] = _execute(prep, op, index, total, progress)
            status = "ran"
            if cache is not None and key is not None:
                written = _written(nt, prep.settings)
                if all(d is not None for ds in written.values() for d in ds):
                    cache.put(key, CacheEntry(dict(outputs[node_id]), written))  # type: ignore[arg-type]
        record = RunRecord(node_id, op, status, time.perf_counter() - t0, key)
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

