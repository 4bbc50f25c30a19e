"""The graph model: nodes by id, each with an op, input connections and settings.

A graph is what a graph file holds (see :mod:`quadnodes.graph.files`) and what a
design script builds with the fluent API::

    g = Graph()
    src = g.add("grid", id="src", rows=10, cols=10)
    fa = g.add("fair", src, iterations=3)          # src: a single-output node
    result = g.run()
    result[fa.mesh]

Every node is checked when it is added; :meth:`Graph.validate` checks the whole
graph (references to other nodes, types across connections, cycles). All errors
are :class:`~quadnodes.errors.GraphError` naming the node id and the port or
setting at fault.
"""

from __future__ import annotations

import graphlib
import os
import re
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

from ..errors import GraphError
from . import _types
from ._util import did_you_mean, graph_error, label
from .node import REGISTRY, NodeType, Registry

if TYPE_CHECKING:
    from .cache import Cache
    from .run import RunResult

__all__ = ["PortRef", "Constant", "NodeSpec", "NodeHandle", "Graph"]

_ID_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_-]*\Z")


@dataclass(frozen=True)
class PortRef:
    """A reference to output ``port`` of node ``node``; written ``"node.port"`` in files.

    Examples
    --------
    >>> PortRef.parse("mesh.out")
    PortRef(node='mesh', port='out')
    >>> str(PortRef("fair1", "report"))
    'fair1.report'
    """

    node: str
    port: str

    def __str__(self) -> str:
        return f"{self.node}.{self.port}"

    @classmethod
    def parse(cls, text: str, *, where: str = "") -> PortRef:
        """Parse ``"node.port"``.

        Raises
        ------
        GraphError
            If ``text`` is not a string of that form (``where`` prefixes the message).
        """
        if isinstance(text, str):
            node_id, dot, port = text.strip().partition(".")
            if dot and _ID_RE.match(node_id) and re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", port):
                return cls(node_id, port)
        raise GraphError(f"{where}expected a reference 'node.port', got {text!r}")


class Constant:
    """A Python value fed straight into an input port (Python API only; not saved).

    Compared by identity: two constants are equal when they hold the same object.
    """

    __slots__ = ("value",)

    def __init__(self, value: Any) -> None:
        self.value = value

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Constant) and other.value is self.value

    def __hash__(self) -> int:
        return id(self.value)

    def __repr__(self) -> str:
        r = repr(self.value)
        return f"Constant({r if len(r) <= 60 else type(self.value).__name__ + '(...)'})"


@dataclass(frozen=True)
class NodeSpec:
    """One node of a graph: ``op`` resolved to ``"name@version"``, inputs, explicit settings.

    ``params`` holds only the settings given explicitly, already coerced; defaults
    are filled in when the graph runs.
    """

    id: str
    op: str
    inputs: Mapping[str, PortRef | Constant]
    params: Mapping[str, Any]

    def __post_init__(self) -> None:
        object.__setattr__(self, "inputs", MappingProxyType(dict(self.inputs)))
        object.__setattr__(self, "params", MappingProxyType(dict(self.params)))

    def __eq__(self, other: object) -> bool:
        return (
            isinstance(other, NodeSpec)
            and (self.id, self.op) == (other.id, other.op)
            and dict(self.inputs) == dict(other.inputs)
            and dict(self.params) == dict(other.params)
        )

    __hash__ = None  # type: ignore[assignment]


class _PortLookupError(GraphError, AttributeError):
    """An unknown output port asked of a :class:`NodeHandle` (also an AttributeError)."""


class NodeHandle:
    """A node added to a :class:`Graph`; its attributes are references to its output ports.

    ``h.mesh`` (or ``h["mesh"]``) is a :class:`PortRef`; for a single-output node
    the handle itself can be passed wherever a reference is expected.
    """

    __slots__ = ("_graph", "_id")

    def __init__(self, graph: Graph, node_id: str) -> None:
        self._graph = graph
        self._id = node_id

    @property
    def id(self) -> str:
        """The node id."""
        return self._id

    @property
    def graph(self) -> Graph:
        return self._graph

    @property
    def spec(self) -> NodeSpec:
        return self._graph.nodes[self._id]

    @property
    def node_type(self) -> NodeType:
        return self._graph.registry.get(self.spec.op, node_id=self._id)

    def __getitem__(self, port: str) -> PortRef:
        nt = self.node_type
        if nt.output(port) is None:
            hint = did_you_mean(port, nt.output_names, kind="outputs")
            raise _PortLookupError(f"{label(self._id, nt.op)}: no output port {port!r}{hint}")
        return PortRef(self._id, port)

    def __getattr__(self, port: str) -> PortRef:
        if port.startswith("_"):
            raise AttributeError(port)
        return self[port]

    @property
    def ref(self) -> PortRef:
        """The only output of a single-output node.

        Raises
        ------
        GraphError
            If the node has several outputs (the message lists them).
        """
        nt = self.node_type
        if len(nt.outputs) != 1:
            names = ", ".join(f"{self._id}.{n}" for n in nt.output_names)
            raise graph_error(
                f"{label(self._id, nt.op)} has {len(nt.outputs)} outputs; pick one: {names}", node_id=self._id
            )
        return PortRef(self._id, nt.outputs[0].name)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, NodeHandle) and other._graph is self._graph and other._id == self._id

    def __hash__(self) -> int:
        return hash((id(self._graph), self._id))

    def __repr__(self) -> str:
        op = self._graph.nodes[self._id].op if self._id in self._graph.nodes else "?"
        return f"NodeHandle({self._id!r}, op={op!r})"


class Graph:
    """A graph of nodes.

    Parameters
    ----------
    registry : Registry, optional
        Where ops are looked up (default: the global :data:`~quadnodes.graph.node.REGISTRY`).
    base_dir : path, optional
        Folder that relative file paths in settings are resolved against when the
        graph runs (a loaded graph: the graph file's folder; default: the working
        directory at run time).

    Examples
    --------
    >>> from quadnodes.graph.node import Registry, node
    >>> reg = Registry()
    >>> @node("num", outputs=("value",), registry=reg)
    ... def num(*, value: float) -> float:
    ...     return value
    >>> @node("add", registry=reg)
    ... def add(a: float, b: float = 0.0) -> float:
    ...     return a + b
    >>> g = Graph(registry=reg)
    >>> x = g.add("num", id="x", value=2)
    >>> s = g.add("add", x, x.value)
    >>> s.id, g.nodes["add1"].inputs["b"]
    ('add1', PortRef(node='x', port='value'))
    >>> g.run()[s]
    4.0
    >>> g.add("add", x, id="x")
    Traceback (most recent call last):
    ...
    quadnodes.errors.GraphError: node 'x': the id is already used by another node (num@1)
    """

    def __init__(self, *, registry: Registry | None = None, base_dir: str | os.PathLike[str] | None = None) -> None:
        self._registry = REGISTRY if registry is None else registry
        self._nodes: dict[str, NodeSpec] = {}
        self.base_dir: Path | None = None if base_dir is None else Path(base_dir)
        #: Node positions ``[x, y]`` by id on the page of ``quadnodes serve`` (the file's ``[layout]`` table).
        self.layout: dict[str, list[float]] = {}

    # ----------------------------------------------------------------- access
    @property
    def registry(self) -> Registry:
        return self._registry

    @property
    def nodes(self) -> Mapping[str, NodeSpec]:
        """The nodes by id, in the order they were added (read-only view)."""
        return MappingProxyType(self._nodes)

    def __getitem__(self, node_id: str) -> NodeHandle:
        if node_id not in self._nodes:
            raise graph_error(f"no node {node_id!r}{did_you_mean(node_id, self._nodes, kind='nodes')}",
                              node_id=node_id)
        return NodeHandle(self, node_id)

    def __contains__(self, node_id: object) -> bool:
        return node_id in self._nodes

    def __iter__(self) -> Iterator[str]:
        return iter(self._nodes)

    def __len__(self) -> int:
        return len(self._nodes)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Graph) and self._nodes == other._nodes

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        ids = ", ".join(self._nodes)
        return f"Graph({len(self._nodes)} nodes: {ids})" if self._nodes else "Graph(empty)"

    def node_type(self, node_id: str) -> NodeType:
        """The node type of node ``node_id``."""
        return self._registry.get(self._nodes[node_id].op, node_id=node_id)

    def copy(self) -> Graph:
        """A shallow copy (specs are immutable, so this is a full copy of the model)."""
        g = Graph(registry=self._registry, base_dir=self.base_dir)
        g._nodes = dict(self._nodes)
        g.layout = {k: list(v) for k, v in self.layout.items()}
        return g

    # --------------------------------------------------------------- building
    def add(
        self,
        op: str | Callable[..., Any],
        /,
        *inputs: Any,
        id: str | None = None,  # noqa: A002 - the natural name in a graph
        **kwargs: Any,
    ) -> NodeHandle:
        """Add a node and return its handle.

        Parameters
        ----------
        op : str or node function
            ``"name"`` (latest version), ``"name@version"``, or a ``@node`` function.
        *inputs
            Values for the input ports in order: a :class:`NodeHandle` (its only
            output), a :class:`PortRef` (``h.mesh``), or any other Python value,
            taken as a constant (such a graph runs but cannot be saved).
        id : str, optional
            Node id (letters, digits, ``_``, ``-``; starting with a letter or ``_``).
            Default: the op name and the first free number, ``fair1``, ``fair2``…
        **kwargs
            Settings; a keyword naming an input port connects that port instead.

        Returns
        -------
        NodeHandle

        Raises
        ------
        GraphError
            Unknown op, duplicate or malformed id, too many inputs, an input given
            twice, a reference to a missing node or output port or to another
            graph, an input of a type the port cannot take, a missing required
            input, an unknown, wrong-typed or missing required setting.
        """
        nt = self._registry.get(op, node_id=id)
        node_id = self._next_id(nt.name) if id is None else id
        self._check_new_id(node_id, nt.op)
        where = label(node_id, nt.op)
        if len(inputs) > len(nt.inputs):
            names = ", ".join(p.name for p in nt.inputs) or "none"
            raise graph_error(f"{where}: takes {len(nt.inputs)} inputs ({names}), got {len(inputs)}",
                              node_id=node_id)
        wired: dict[str, Any] = {p.name: v for p, v in zip(nt.inputs, inputs)}
        params: dict[str, Any] = {}
        for k, v in kwargs.items():
            if nt.input(k) is not None:
                if k in wired:
                    raise graph_error(f"{where}: input {k!r} given twice", node_id=node_id)
                wired[k] = v
            else:
                params[k] = v
        conns = {p: self._as_connection(node_id, nt, p, v) for p, v in wired.items()}
        self._insert(node_id, nt, conns, params, check_refs=True)
        return NodeHandle(self, node_id)

    def set(self, node_id: str, /, **params: Any) -> None:
        """Change settings of a node (validated; ``None`` for a setting whose default is None removes it).

        Raises
        ------
        GraphError
            Unknown node, unknown or wrong-typed setting.
        """
        spec = self._nodes.get(node_id)
        if spec is None:
            raise graph_error(f"no node {node_id!r}{did_you_mean(node_id, self._nodes, kind='nodes')}",
                              node_id=node_id)
        nt = self._registry.get(spec.op, node_id=node_id)
        merged = {**spec.params, **params}
        self._nodes[node_id] = NodeSpec(node_id, spec.op, spec.inputs, self._coerce_params(node_id, nt, merged))

    def with_overrides(self, overrides: Mapping[str, Any]) -> Graph:
        """A copy with settings replaced: ``{"fair1.iterations": 5}``.

        Raises
        ------
        GraphError
            Malformed key, unknown node, unknown or wrong-typed setting.
        """
        g = self.copy()
        for key, value in overrides.items():
            node_id, dot, setting = str(key).partition(".")
            if not dot or not setting:
                raise GraphError(f"override {key!r}: expected 'node.setting'")
            if node_id not in g._nodes:
                raise graph_error(
                    f"override {key!r}: no node {node_id!r}{did_you_mean(node_id, g._nodes, kind='nodes')}",
                    node_id=node_id,
                )
            g.set(node_id, **{setting: value})
        return g

    # ------------------------------------------------------------- validation
    def validate(self) -> None:
        """Check the whole graph.

        Raises
        ------
        GraphError
            Naming the node and the port or setting at fault: unknown op, unknown
            or wrong-typed setting, unknown input port, a reference to a missing
            node or output port, mismatched types across a connection, a missing
            required input, a cycle (naming every node on it), or a
            ``{node.setting}`` in a template setting naming no such setting.
        """
        from .templates import template_errors

        for spec in self._nodes.values():
            nt = self._registry.get(spec.op, node_id=spec.id)
            nt.resolve_settings(spec.params, node_id=spec.id)
            self._check_inputs(spec.id, nt, spec.inputs)
        self.order()
        for err in template_errors(self):
            raise err

    def order(self) -> list[str]:
        """Node ids in an order where every node follows the nodes it reads from.

        Ties keep the insertion order.

        Raises
        ------
        GraphError
            On a cycle, naming its nodes: ``cycle: a -> b -> a``.
        """
        ts: graphlib.TopologicalSorter[str] = graphlib.TopologicalSorter()
        for spec in self._nodes.values():
            ts.add(spec.id, *[c.node for c in spec.inputs.values() if isinstance(c, PortRef)])
        try:
            ts.prepare()
        except graphlib.CycleError as exc:
            cycle = list(exc.args[1])  # each node feeds the next
            raise graph_error(
                f"cycle: {' -> '.join(cycle)} (nodes {', '.join(sorted(set(cycle)))})", node_id=cycle[0]
            ) from None
        rank = {nid: i for i, nid in enumerate(self._nodes)}
        out: list[str] = []
        while ts.is_active():
            ready = sorted(ts.get_ready(), key=lambda n: rank.get(n, -1))
            out += ready
            ts.done(*ready)
        return [n for n in out if n in self._nodes]

    # ----------------------------------------------------------- running, io
    def run(
        self,
        *,
        cache: Cache | None = None,
        overrides: Mapping[str, Any] | None = None,
        progress: Callable[[Any], None] | None = None,
        out: str | os.PathLike[str] | None = None,
        allow_read: Any = (),
    ) -> RunResult:
        """Run the graph; see :func:`quadnodes.graph.run.run`."""
        from .run import run

        return run(self, cache=cache, overrides=overrides, progress=progress, out=out, allow_read=allow_read)

    def sweep(self, vary: Mapping[str, Any], **options: Any) -> Any:
        """Run variants of the graph on Dask; see :func:`quadnodes.graph.sweep.run_sweep`."""
        from .sweep import run_sweep

        return run_sweep(self, vary, **options)

    def to_dict(self) -> dict[str, Any]:
        """The file model; see :func:`quadnodes.graph.files.to_dict`."""
        from .files import to_dict

        return to_dict(self)

    def save(self, path: str | os.PathLike[str], *, fmt: str | None = None) -> Path:
        """Write a TOML or JSON graph file; see :func:`quadnodes.graph.files.save`."""
        from .files import save

        return save(self, path, fmt=fmt)

    @classmethod
    def load(cls, path: str | os.PathLike[str], *, registry: Registry | None = None) -> Graph:
        """Read a TOML or JSON graph file; see :func:`quadnodes.graph.files.load`."""
        from .files import load

        return load(path, registry=registry)

    # --------------------------------------------------------------- internal
    def _next_id(self, name: str) -> str:
        k = 1
        while f"{name}{k}" in self._nodes:
            k += 1
        return f"{name}{k}"

    def _check_new_id(self, node_id: Any, op: str) -> None:
        if not isinstance(node_id, str) or not _ID_RE.match(node_id):
            raise graph_error(
                f"node id {node_id!r} ({op}): use letters, digits, '_' and '-', starting with a letter or '_'",
                node_id=str(node_id),
            )
        if node_id in self._nodes:
            raise graph_error(
                f"{label(node_id)}: the id is already used by another node ({self._nodes[node_id].op})",
                node_id=node_id,
            )

    def _as_connection(self, node_id: str, nt: NodeType, port: str, value: Any) -> PortRef | Constant:
        if isinstance(value, NodeHandle):
            if value.graph is not self:
                raise graph_error(
                    f"{label(node_id, nt.op)}: input {port!r} refers to node {value.id!r} of another graph",
                    node_id=node_id,
                )
            return value.ref
        if isinstance(value, (PortRef, Constant)):
            return value
        return Constant(value)

    def _coerce_params(self, node_id: str, nt: NodeType, params: Mapping[str, Any]) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for k, v in params.items():
            coerced = nt.coerce_setting(k, v, node_id=node_id)
            s = nt.setting(k)
            if coerced is None and s is not None and s.default is None:
                continue  # same as leaving it out; keeps TOML (no null) and JSON files alike
            out[k] = coerced
        return out

    def _insert(
        self,
        node_id: str,
        nt: NodeType,
        inputs: Mapping[str, PortRef | Constant],
        params: Mapping[str, Any],
        *,
        check_refs: bool,
    ) -> None:
        coerced = self._coerce_params(node_id, nt, params)
        nt.resolve_settings(coerced, node_id=node_id)  # missing required settings
        if check_refs:
            self._check_inputs(node_id, nt, inputs)
        self._nodes[node_id] = NodeSpec(node_id, nt.op, inputs, coerced)

    def _check_inputs(self, node_id: str, nt: NodeType, inputs: Mapping[str, PortRef | Constant]) -> None:
        for err in self._input_errors(node_id, nt, inputs):
            raise err

    def _input_errors(
        self, node_id: str, nt: NodeType, inputs: Mapping[str, PortRef | Constant]
    ) -> list[GraphError]:
        """Every problem of a node's connections (unknown port, missing node/output, type, missing input)."""
        errors: list[GraphError] = []
        where = label(node_id, nt.op)
        for port, conn in inputs.items():
            p = nt.input(port)
            if p is None:
                if nt.setting(port) is not None:
                    msg = f"{where}: {port!r} is a setting, not an input port; put it in params"
                else:
                    msg = f"{where}: unknown input port {port!r}" + did_you_mean(
                        port, [q.name for q in nt.inputs], kind="inputs"
                    )
                errors.append(graph_error(msg, node_id=node_id))
                continue
            if isinstance(conn, Constant):
                if not _types.maybe_instance(conn.value, p.annotation):
                    errors.append(graph_error(
                        f"{where}: input {port!r} expects {p.type_name}, got a {type(conn.value).__name__}",
                        node_id=node_id,
                    ))
                continue
            src = self._nodes.get(conn.node)
            if src is None:
                hint = did_you_mean(conn.node, [n for n in self._nodes if n != node_id], kind="nodes")
                errors.append(graph_error(
                    f"{where}: input {port!r} refers to {str(conn)!r}: no node {conn.node!r}{hint}", node_id=node_id))
                continue
            src_nt = self._registry.get(src.op, node_id=src.id)
            out = src_nt.output(conn.port)
            if out is None:
                hint = did_you_mean(conn.port, src_nt.output_names, kind="outputs")
                errors.append(graph_error(
                    f"{where}: input {port!r} refers to {str(conn)!r}: "
                    f"node {conn.node!r} ({src_nt.op}) has no output {conn.port!r}{hint}",
                    node_id=node_id,
                ))
                continue
            if not _types.maybe_compatible(out.annotation, p.annotation):
                errors.append(graph_error(
                    f"{where}: input {port!r} expects {p.type_name}, but {str(conn)!r} gives {out.type_name}",
                    node_id=node_id,
                ))
        for p in nt.inputs:
            if p.required and p.name not in inputs:
                errors.append(graph_error(f"{where}: missing required input {p.name!r} ({p.type_name})",
                                          node_id=node_id))
        return errors
