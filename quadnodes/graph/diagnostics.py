"""Every problem of a graph file at once (``quadnodes check``), not only the first.

:func:`quadnodes.graph.load` stops at the first error; :func:`file_problems`
goes on node by node and setting by setting, so one check lists everything to
fix: unknown ops, fields, ports and settings, wrong types, values out of range,
references to missing nodes or outputs, type mismatches across connections,
missing inputs, cycles, output paths leaving the output folder or shared by two
writers, and unknown ``{node.setting}`` in titles. Each message starts with the
file name and, where known, the line of the node.

Examples
--------
>>> import tempfile, pathlib
>>> import quadnodes.nodes  # noqa: F401
>>> p = pathlib.Path(tempfile.mkdtemp()) / "g.toml"
>>> _ = p.write_text('''format = "quadnodes-graph"
... version = 1
... [nodes.m]
... op = "grid@1"
... params = { rows = -3, colz = 4 }
... [nodes.f]
... op = "fair@1"
... inputs = { mesh = "m.mesh" }
... params = { iterations = -1 }
... ''')
>>> for e in file_problems(p):
...     print(str(e).replace(str(p), "g.toml"))
g.toml line 3: node 'm' (grid@1): setting 'rows': -3 is out of range (must be >= 2)
g.toml line 3: node 'm' (grid@1): unknown setting 'colz'; did you mean 'cols'? (settings: cols, rows, spacing)
g.toml line 6: node 'f' (fair@1): setting 'iterations': -1 is out of range (must be >= 1)
"""

from __future__ import annotations

import json
import os
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..errors import GraphError
from . import files as _files
from ._util import did_you_mean, graph_error, label
from .graph import Graph, NodeSpec, PortRef, _ID_RE
from .node import REGISTRY, Registry

__all__ = ["file_problems"]


def file_problems(path: str | os.PathLike[str], *, registry: Registry | None = None) -> list[GraphError]:
    """All problems of a graph file; an empty list when it loads and validates.

    Parameters
    ----------
    path : path-like
        A ``.toml`` or ``.json`` graph file.
    registry : Registry, optional
        Where ops are looked up (default: the global registry).

    Returns
    -------
    list of GraphError
        In file order, each naming the file, the node's line, the node and the
        field, port or setting at fault.
    """
    reg = REGISTRY if registry is None else registry
    p = Path(path)
    name = str(path)
    try:
        fmt = _files._fmt_of(p, None)
        text = p.read_bytes().decode("utf-8-sig")
    except GraphError as exc:
        return [exc]
    except OSError as exc:
        return [GraphError(f"cannot read graph file {name!r}: {exc.strerror or exc}")]
    except UnicodeDecodeError as exc:
        return [GraphError(f"{name!r}: not UTF-8 text ({exc})")]
    try:  # syntax errors: the parser stops at the first, so does this
        _files.loads(text, fmt=fmt, registry=reg, base_dir=p.parent.resolve(), source=name)
        return []
    except GraphError as exc:
        first = exc  # the name of an ``except ... as`` is unbound after the block
        try:
            data = tomllib.loads(text) if fmt == "toml" else json.loads(text)
        except ValueError:
            return [first]
    problems = _model_problems(data, reg, p.parent.resolve())
    if not problems:
        return [first]

    located: list[tuple[int, GraphError]] = []
    for err in problems:
        node_id = getattr(err, "node_id", None)
        line = _files._node_line(text, fmt, node_id) if node_id else None
        out = GraphError(f"{name}{f' line {line}' if line else ''}: {err}")
        out.node_id = node_id  # type: ignore[attr-defined]
        located.append((line if line is not None else 1 << 30, out))
    found = [e for _, e in sorted(located, key=lambda t: t[0])]  # in file order (stable within a node)
    if str(first) not in {str(e) for e in found}:  # e.g. a key given twice, seen only by the loader
        found.insert(0, first)
    return found


def _model_problems(data: Any, reg: Registry, base_dir: Path) -> list[GraphError]:
    if not isinstance(data, Mapping):
        return [GraphError(f"expected a table at the top level, got {type(data).__name__}")]
    errors: list[GraphError] = []
    try:  # the header (format, version, top-level keys), with the nodes checked below
        _files.from_dict({k: v for k, v in data.items() if k != "nodes"}, registry=reg)
    except GraphError as exc:
        errors.append(exc)
    nodes = data.get("nodes", {})
    if not isinstance(nodes, Mapping):
        return errors + [GraphError(f"nodes: expected a table of nodes by id, got {type(nodes).__name__}")]
    g = Graph(registry=reg, base_dir=base_dir)
    broken: set[str] = set()  # nodes whose op is unknown: references to them are not errors of their own
    for node_id, body in nodes.items():
        node_errors = _node_problems(g, reg, node_id, body)
        if node_id not in g.nodes:
            broken.add(str(node_id))
        errors += node_errors
    for spec in g.nodes.values():
        nt = reg.get(spec.op, node_id=spec.id)
        for err in g._input_errors(spec.id, nt, spec.inputs):
            if not any(f"{str(c)!r}: no node {c.node!r}" in str(err)
                       for c in spec.inputs.values() if isinstance(c, PortRef) and c.node in broken):
                errors.append(err)
    try:
        g.order()
    except GraphError as exc:
        errors.append(exc)
    from .paths import output_path_errors
    from .templates import template_errors

    errors += output_path_errors(g)
    errors += template_errors(g)
    return errors


def _node_problems(g: Graph, reg: Registry, node_id: Any, body: Any) -> list[GraphError]:
    """Problems of one node; a node whose op is known is added to ``g`` with its valid settings."""
    if not isinstance(node_id, str) or not _ID_RE.match(node_id):
        return [graph_error(f"node id {node_id!r}: use letters, digits, '_' and '-', starting with a letter or '_'",
                            node_id=str(node_id))]
    where = label(node_id)
    if not isinstance(body, Mapping):
        return [graph_error(f"{where}: expected a table with op, inputs and params, got {body!r}", node_id=node_id)]
    errors: list[GraphError] = []
    for k in body:
        if k not in ("op", "inputs", "params"):
            errors.append(graph_error(
                f"{where}: unknown field {k!r}{did_you_mean(str(k), ('op', 'inputs', 'params'), kind='fields')}",
                node_id=node_id))
    op = body.get("op")
    if op is None:
        return errors + [graph_error(f"{where}: missing field 'op'", node_id=node_id)]
    try:
        nt = reg.get(op, node_id=node_id)
    except GraphError as exc:
        return errors + [exc]
    where = label(node_id, nt.op)
    inputs, params = body.get("inputs", {}), body.get("params", {})
    conns: dict[str, PortRef] = {}
    if not isinstance(inputs, Mapping):
        errors.append(graph_error(f"{where}: field 'inputs': expected a table, got {inputs!r}", node_id=node_id))
    else:
        for port, ref in inputs.items():
            try:
                conns[port] = PortRef.parse(ref, where=f"{where}: field 'inputs.{port}': ")
            except GraphError as exc:
                errors.append(graph_error(str(exc), node_id=node_id))
    good: dict[str, Any] = {}
    if not isinstance(params, Mapping):
        errors.append(graph_error(f"{where}: field 'params': expected a table, got {params!r}", node_id=node_id))
    else:
        for k, v in params.items():
            try:
                good[k] = nt.coerce_setting(k, v, node_id=node_id)
            except GraphError as exc:
                errors.append(exc)
    for s in nt.settings:
        if s.required and s.name not in params:
            errors.append(graph_error(f"{where}: missing required setting {s.name!r} ({s.type_name})",
                                      node_id=node_id))
    if node_id in g.nodes:
        return errors + [graph_error(f"{where}: the id is used twice", node_id=node_id)]
    g._nodes[node_id] = NodeSpec(node_id, nt.op, conns, {k: v for k, v in good.items() if v is not None})
    return errors
