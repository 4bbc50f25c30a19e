r"""Graph files: TOML and JSON, one model.

A graph file names its format and version first, then the nodes by id::

    format = "quadnodes-graph"
    version = 1

    [nodes.surface]
    op = "sample@1"

    [nodes.surface.params]
    nu = 20

    [nodes.faired]
    op = "fair@1"

    [nodes.faired.inputs]
    mesh = "surface.mesh"

    [nodes.faired.params]
    iterations = 3

The JSON form is the same tree (``{"format": ..., "version": 1, "nodes": {...}}``).
Saving writes keys sorted (after ``format`` and ``version``), pins every op to
its ``name@version``, and writes atomically. No pickles, no code: only the data
types TOML and JSON share (TOML has no null: a setting whose default is None is
simply left out).

TOML is read with the standard library's :mod:`tomllib`; it is written by the
small writer here, which only has to cover this model (tables of nodes whose
values are strings, numbers, booleans, arrays and inline tables), and is tested
to read back identically with :mod:`tomllib`.

Errors are :class:`~quadnodes.errors.GraphError` prefixed with the file name
and, where known, the line: ``graph.toml line 12: ...``.

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
>>> text = '''
... format = "quadnodes-graph"
... version = 1
... [nodes.a]
... op = "num"
... params = { value = 2 }
... [nodes.b]
... op = "neg"
... inputs = { x = "a.out" }
... '''
>>> g = loads(text, fmt="toml", registry=reg)
>>> g.run()["b.out"]
-2.0
>>> print(dumps(g, fmt="json"), end="")
{
  "format": "quadnodes-graph",
  "version": 1,
  "nodes": {
    "a": {
      "op": "num@1",
      "params": {
        "value": 2.0
      }
    },
    "b": {
      "inputs": {
        "x": "a.out"
      },
      "op": "neg@1"
    }
  }
}
"""

from __future__ import annotations

import json
import math
import os
import pathlib
import re
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..errors import ExportError, GraphError, InputError
from ..units import parse_length
from . import _types
from ..io._atomic import write_atomic
from ._util import did_you_mean, graph_error, label
from .graph import Constant, Graph, PortRef, _ID_RE
from .node import Registry

__all__ = [
    "FORMAT",
    "VERSION",
    "to_dict",
    "from_dict",
    "dumps",
    "loads",
    "save",
    "load",
    "parse_value",
    "toml_dumps",
    "GRAPH_SETTINGS",
]

#: The ``format`` value at the top of every graph file.
FORMAT = "quadnodes-graph"
#: The newest graph file version this code reads and the one it writes.
VERSION = 1

#: Graph-wide settings: set once at the top of a graph file, inherited by every node that has a
#: setting of that name and does not set it itself (e.g. ``planar_tolerance = "2 mm"``).
GRAPH_SETTINGS = ("planar_tolerance",)
_TOP_KEYS = ("format", "version", "nodes", "layout") + GRAPH_SETTINGS
_NODE_KEYS = ("op", "inputs", "params")
_SUFFIXES = {".toml": "toml", ".json": "json"}


# ------------------------------------------------------------------ the model
def to_dict(graph: Graph, *, base_dir: str | os.PathLike[str] | None = None) -> dict[str, Any]:
    """The file model of ``graph`` as plain data (keys sorted).

    Parameters
    ----------
    graph : Graph
    base_dir : path, optional
        Folder the data will be saved in. Relative paths in settings are rewritten
        to stay pointing at the same files from there (they are relative to
        ``graph.base_dir``, or the working directory, before).

    Raises
    ------
    GraphError
        If an input is a constant Python value (names the node and port): only
        connections between nodes can be saved.
    """
    src_dir = Path(graph.base_dir) if graph.base_dir is not None else Path.cwd()
    dst_dir = Path(base_dir) if base_dir is not None else None
    shared = dict(getattr(graph, "graph_settings", {}))
    nodes: dict[str, Any] = {}
    for node_id in sorted(graph.nodes):
        spec = graph.nodes[node_id]
        body: dict[str, Any] = {"op": spec.op}
        inputs = {}
        for port in sorted(spec.inputs):
            conn = spec.inputs[port]
            if isinstance(conn, Constant):
                raise graph_error(
                    f"{label(node_id, spec.op)}: input {port!r} is a Python value "
                    f"({type(conn.value).__name__}), which a graph file cannot hold; "
                    "produce it with a node (e.g. one that reads a file) instead",
                    node_id=node_id,
                )
            inputs[port] = str(conn)
        if inputs:
            body["inputs"] = inputs
        params = {}
        for k in sorted(spec.params):
            v = spec.params[k]
            if k in shared and _types.to_plain(v) == shared[k]:
                continue  # inherited from the graph-wide setting
            if dst_dir is not None:
                v = _rebase(v, src_dir, dst_dir)
            params[k] = _sorted(_types.to_plain(v))
        if params:
            body["params"] = params
        nodes[node_id] = _sorted(body)
    data: dict[str, Any] = {"format": FORMAT, "version": VERSION, **{k: shared[k] for k in sorted(shared)},
                            "nodes": nodes}
    if graph.layout:
        data["layout"] = {k: [float(x) for x in graph.layout[k]] for k in sorted(graph.layout)}
    return data


def _layout(value: Any) -> dict[str, list[float]]:
    """The ``[layout]`` table: node id -> ``[x, y]`` position on the page of ``quadnodes serve``.

    Raises
    ------
    GraphError
        For a value that is not a table of ``[x, y]`` pairs of finite numbers (names the node).

    Examples
    --------
    >>> _layout({"fair": [120, 40.5]})
    {'fair': [120.0, 40.5]}
    >>> _layout({"fair": [1]})
    Traceback (most recent call last):
    ...
    quadnodes.errors.GraphError: layout.fair: expected a position [x, y] of two numbers, got [1]
    """
    if not isinstance(value, Mapping):
        raise GraphError(f"layout: expected a table of node positions [x, y] by node id, got {value!r}")
    out: dict[str, list[float]] = {}
    for node_id, pos in value.items():
        ok = (isinstance(pos, (list, tuple)) and len(pos) == 2
              and all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in pos))
        if not ok:
            raise GraphError(f"layout.{node_id}: expected a position [x, y] of two numbers, got {pos!r}")
        out[str(node_id)] = [float(pos[0]), float(pos[1])]
    return out


def _rebase(value: Any, src: Path, dst: Path) -> Any:
    if isinstance(value, pathlib.PurePath) and not value.is_absolute():
        a, b = os.path.abspath(src), os.path.abspath(dst)
        if a == b:
            return value
        return type(value)(os.path.relpath(os.path.join(a, value), b))
    if isinstance(value, list):
        return [_rebase(v, src, dst) for v in value]
    if isinstance(value, tuple):
        return tuple(_rebase(v, src, dst) for v in value)
    if isinstance(value, dict):
        return {k: _rebase(v, src, dst) for k, v in value.items()}
    return value


def _sorted(v: Any) -> Any:
    if isinstance(v, Mapping):
        return {k: _sorted(v[k]) for k in sorted(v)}
    if isinstance(v, list):
        return [_sorted(x) for x in v]
    return v


def from_dict(
    data: Any,
    *,
    registry: Registry | None = None,
    base_dir: str | os.PathLike[str] | None = None,
) -> Graph:
    """Build and validate a graph from its file model.

    Raises
    ------
    GraphError
        Naming the node id and field at fault: wrong or missing ``format``,
        unsupported ``version``, unknown top-level key or node field, malformed
        id, missing or unknown op, a malformed reference, everything
        :meth:`Graph.validate` checks, and an output path that is absolute, leads
        out of the output folder with ``..`` or is written by two nodes
        (:func:`quadnodes.graph.paths.output_path_errors`).
    """
    if not isinstance(data, Mapping):
        raise GraphError(f"expected a table at the top level, got {type(data).__name__}")
    for k in data:
        if k not in _TOP_KEYS:
            raise GraphError(f"unknown top-level key {k!r}{did_you_mean(str(k), _TOP_KEYS, kind='keys')}")
    if "format" not in data:
        raise GraphError(f"missing 'format = \"{FORMAT}\"' at the top")
    if data["format"] != FORMAT:
        raise GraphError(f"format: expected {FORMAT!r}, got {data['format']!r}")
    version = data.get("version")
    if version is None:
        raise GraphError(f"missing 'version = {VERSION}' at the top")
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise GraphError(f"version: expected a positive integer, got {version!r}")
    if version > VERSION:
        raise GraphError(f"version {version} is newer than this quadnodes reads (up to {VERSION}); upgrade quadnodes")
    nodes = data.get("nodes", {})
    if not isinstance(nodes, Mapping):
        raise GraphError(f"nodes: expected a table of nodes by id, got {type(nodes).__name__}")
    shared = {k: data[k] for k in GRAPH_SETTINGS if k in data}
    for k, v in shared.items():
        if isinstance(v, bool) or not isinstance(v, (int, float, str)):
            raise GraphError(f"{k}: expected a number or a length such as '2 mm', got {v!r}")
        try:
            parse_length(v, "mm", k)
        except InputError as exc:
            raise GraphError(f"top-level setting {exc}") from None
    g = Graph(registry=registry, base_dir=base_dir)
    g.graph_settings = shared  # type: ignore[attr-defined]
    for node_id, body in nodes.items():
        if not isinstance(node_id, str) or not _ID_RE.match(node_id):
            raise graph_error(
                f"node id {node_id!r}: use letters, digits, '_' and '-', starting with a letter or '_'",
                node_id=str(node_id),
            )
        where = label(node_id)
        if not isinstance(body, Mapping):
            raise graph_error(f"{where}: expected a table with op, inputs and params, got {body!r}",
                              node_id=node_id)
        for k in body:
            if k not in _NODE_KEYS:
                raise graph_error(f"{where}: unknown field {k!r}{did_you_mean(str(k), _NODE_KEYS, kind='fields')}",
                                  node_id=node_id)
        if "op" not in body:
            raise graph_error(f"{where}: missing field 'op'", node_id=node_id)
        if not isinstance(body["op"], str):
            raise graph_error(f"{where}: field 'op': expected a string such as 'fair@1', got {body['op']!r}",
                              node_id=node_id)
        nt = g.registry.get(body["op"], node_id=node_id)
        inputs = body.get("inputs", {})
        params = body.get("params", {})
        for field, value in (("inputs", inputs), ("params", params)):
            if not isinstance(value, Mapping):
                raise graph_error(f"{where}: field {field!r}: expected a table, got {value!r}", node_id=node_id)
        conns: dict[str, PortRef | Constant] = {}
        for port, ref in inputs.items():
            try:
                conns[port] = PortRef.parse(ref, where=f"{label(node_id, nt.op)}: field 'inputs.{port}': ")
            except GraphError as exc:
                raise graph_error(str(exc), node_id=node_id) from None
        inherited = {k: v for k, v in shared.items() if k not in params and nt.setting(k) is not None}
        g._check_new_id(node_id, nt.op)
        g._insert(node_id, nt, conns, {**params, **inherited}, check_refs=False)
    g.validate()
    if "layout" in data:
        g.layout = _layout(data["layout"])

    from .paths import output_path_errors

    for err in output_path_errors(g):  # a graph file writes only inside the output folder
        raise err
    return g


# ------------------------------------------------------------------ text forms
def dumps(graph: Graph, *, fmt: str = "toml", base_dir: str | os.PathLike[str] | None = None) -> str:
    """The text of a graph file (``fmt`` ``"toml"`` or ``"json"``).

    Raises
    ------
    GraphError
        For constant inputs (see :func:`to_dict`), an unknown format, or (TOML) a
        value TOML cannot hold, such as None where the default is not None.
    """
    data = to_dict(graph, base_dir=base_dir)
    if fmt == "toml":
        return toml_dumps(data)
    if fmt == "json":
        return json.dumps(data, indent=2, ensure_ascii=False, allow_nan=True) + "\n"
    raise GraphError(f"fmt: expected 'toml' or 'json', got {fmt!r}")


def loads(
    text: str,
    *,
    fmt: str,
    registry: Registry | None = None,
    base_dir: str | os.PathLike[str] | None = None,
    source: str | None = None,
) -> Graph:
    """Parse and validate graph file text.

    Parameters
    ----------
    text : str
    fmt : {"toml", "json"}
    registry : Registry, optional
    base_dir : path, optional
        Folder relative paths in settings are resolved against when running.
    source : str, optional
        Name used in messages (default ``"graph.toml"`` / ``"graph.json"``).

    Raises
    ------
    GraphError
        ``"<source> line N, column C: <parser message>"`` for syntax errors (and
        duplicate keys); model errors name the node and field, prefixed with the
        source and, when the node's table can be found, its line.

    Examples
    --------
    >>> loads('format = "quadnodes-graph"\\nversion = 1\\n[nodes.a]\\nop = = 1\\n', fmt="toml")
    Traceback (most recent call last):
    ...
    quadnodes.errors.GraphError: graph.toml line 4, column 6: Invalid value
    """
    if fmt not in ("toml", "json"):
        raise GraphError(f"fmt: expected 'toml' or 'json', got {fmt!r}")
    name = source or f"graph.{fmt}"
    if fmt == "toml":
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise GraphError(_toml_message(name, str(exc), text)) from exc
    else:
        try:
            data = json.loads(text, object_pairs_hook=_no_duplicates)
        except json.JSONDecodeError as exc:
            raise GraphError(f"{name} line {exc.lineno}, column {exc.colno}: {exc.msg}") from exc
        except _DuplicateKey as exc:
            line = _nth_line(text, rf'"{re.escape(exc.key)}"\s*:', 2)
            at = f" line {line}" if line else ""
            raise GraphError(f"{name}{at}: {exc.what} {exc.key!r} appears twice") from None
    try:
        return from_dict(data, registry=registry, base_dir=base_dir)
    except GraphError as exc:
        node_id = getattr(exc, "node_id", None)
        line = _node_line(text, fmt, node_id) if node_id else None
        at = f" line {line}" if line else ""
        err = GraphError(f"{name}{at}: {exc}")
        err.node_id = node_id  # type: ignore[attr-defined]
        raise err from None


_AT = re.compile(r"\s*\(at line (\d+), column (\d+)\)\s*$")


def _toml_message(name: str, msg: str, text: str) -> str:
    m = _AT.search(msg)
    if m:
        return f"{name} line {m.group(1)}, column {m.group(2)}: {msg[: m.start()]}"
    if msg.endswith("(at end of document)"):
        last = text.count("\n") + (0 if text.endswith("\n") else 1)
        return f"{name} line {max(last, 1)} (end of document): {msg[: -len('(at end of document)')].strip()}"
    return f"{name}: {msg}"


class _DuplicateKey(Exception):
    def __init__(self, key: str, what: str) -> None:
        super().__init__(key)
        self.key = key
        self.what = what


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in pairs:
        if k in out:
            both_nodes = all(isinstance(x, dict) and "op" in x for x in (out[k], v))
            raise _DuplicateKey(k, "node id" if both_nodes else "key")
        out[k] = v
    return out


def _nth_line(text: str, pattern: str, n: int) -> int | None:
    hits = list(re.finditer(pattern, text))
    if len(hits) < n:
        return None
    return text.count("\n", 0, hits[n - 1].start()) + 1


def _node_line(text: str, fmt: str, node_id: str) -> int | None:
    """Line of the node's table, when it can be found unambiguously."""
    q = re.escape(node_id)
    if fmt == "toml":
        pat = rf'(?m)^[ \t]*\[[ \t]*nodes[ \t]*\.[ \t]*(?:{q}|"{q}"|\'{q}\')[ \t]*[\].]'
        hits = list(re.finditer(pat, text))
        if not hits:
            hits = list(re.finditer(rf'(?m)^[ \t]*nodes[ \t]*\.[ \t]*(?:{q}|"{q}")[ \t]*[.=]', text))
    else:
        hits = list(re.finditer(rf'"{q}"\s*:\s*\{{', text))
        if len(hits) != 1:
            return None
    return text.count("\n", 0, hits[0].start()) + 1 if hits else None


# ----------------------------------------------------------------- TOML writer
_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+\Z")
_ESCAPES = {'"': '\\"', "\\": "\\\\", "\b": "\\b", "\t": "\\t", "\n": "\\n", "\f": "\\f", "\r": "\\r"}


def _toml_str(s: str) -> str:
    out = []
    for ch in s:
        if ch in _ESCAPES:
            out.append(_ESCAPES[ch])
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _toml_key(k: str) -> str:
    return k if _BARE_KEY.match(k) else _toml_str(k)


def _toml_value(v: Any, where: str) -> str:
    if v is None:
        raise GraphError(
            f"{where}: TOML has no null value; leave the setting out to use its default, or save as JSON"
        )
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return _toml_str(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x, f"{where}[{i}]") for i, x in enumerate(v)) + "]"
    if isinstance(v, Mapping):
        items = [f"{_toml_key(str(k))} = {_toml_value(x, f'{where}.{k}')}" for k, x in v.items()]
        return "{ " + ", ".join(items) + " }" if items else "{}"
    raise GraphError(f"{where}: {type(v).__name__} {v!r} is not a TOML value")


def toml_dumps(data: Mapping[str, Any]) -> str:
    """TOML text of a graph file model (the dict of :func:`to_dict`).

    Scalars and arrays of the top level come first (in the given order), then one
    ``[nodes.<id>]`` table per node (ids and keys sorted) with ``op`` and sub-tables ``inputs`` and ``params``; deeper
    mappings become inline tables.

    Raises
    ------
    GraphError
        For None or a value that is not a TOML type (the message names where).

    Examples
    --------
    >>> print(toml_dumps({"format": "quadnodes-graph", "version": 1,
    ...                   "nodes": {"a": {"op": "num@1", "params": {"value": 0.5, "tags": ["x", "y"]}}}}))
    format = "quadnodes-graph"
    version = 1
    <BLANKLINE>
    [nodes.a]
    op = "num@1"
    <BLANKLINE>
    [nodes.a.params]
    tags = ["x", "y"]
    value = 0.5
    <BLANKLINE>
    """
    lines = []
    for k, v in data.items():
        if k not in ("nodes", "layout"):
            lines.append(f"{_toml_key(k)} = {_toml_value(v, k)}")
    nodes = data.get("nodes", {})
    for node_id in sorted(nodes):
        body = _sorted(nodes[node_id])
        head = f"nodes.{_toml_key(node_id)}"
        where = label(node_id)
        lines += ["", f"[{head}]"]
        for k, v in body.items():
            if not isinstance(v, Mapping):
                lines.append(f"{_toml_key(k)} = {_toml_value(v, f'{where}: {k}')}")
        for k, v in body.items():
            if isinstance(v, Mapping):
                lines += ["", f"[{head}.{_toml_key(k)}]"]
                for kk, vv in v.items():
                    lines.append(f"{_toml_key(kk)} = {_toml_value(vv, f'{where}: {k}.{kk}')}")
    layout = data.get("layout") or {}
    if layout:
        lines += ["", "[layout]  # node positions on the page of quadnodes serve"]
        lines += [f"{_toml_key(k)} = {_toml_value(layout[k], f'layout.{k}')}" for k in sorted(layout)]
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------- files
def _fmt_of(path: Path, fmt: str | None) -> str:
    if fmt is not None:
        if fmt not in ("toml", "json"):
            raise GraphError(f"fmt: expected 'toml' or 'json', got {fmt!r}")
        return fmt
    f = _SUFFIXES.get(path.suffix.lower())
    if f is None:
        raise GraphError(f"{str(path)!r}: cannot tell the format from the suffix; use .toml or .json")
    return f


def save(graph: Graph, path: str | os.PathLike[str], *, fmt: str | None = None) -> Path:
    """Write ``graph`` to a ``.toml`` or ``.json`` file atomically.

    Relative file paths in settings are rewritten relative to the file's folder
    (see :func:`to_dict`), so the saved graph names the same files.

    Returns
    -------
    Path

    Raises
    ------
    GraphError
        If the graph cannot be expressed in a file (constant inputs) or the
        format is unknown.
    ExportError
        If the file cannot be written; an existing file is left unchanged.
    """
    p = Path(path)
    f = _fmt_of(p, fmt)
    text = dumps(graph, fmt=f, base_dir=p.parent)

    def _write(tmp: str) -> None:
        with open(tmp, "w", encoding="utf-8", newline="\n") as fh:
            fh.write(text)

    try:
        return write_atomic(p, _write)
    except ExportError as exc:
        raise ExportError(f"cannot write graph file {str(p)!r}: {exc}") from exc


def load(path: str | os.PathLike[str], *, registry: Registry | None = None, fmt: str | None = None) -> Graph:
    """Read and validate a ``.toml`` or ``.json`` graph file.

    Relative file paths in the graph's settings are resolved against the file's
    folder when it runs.

    Raises
    ------
    GraphError
        If the file cannot be read, or on any error of :func:`loads` (messages
        start with the path as given, and the line where known).
    """
    p = Path(path)
    f = _fmt_of(p, fmt)
    try:
        text = p.read_bytes().decode("utf-8-sig")
    except OSError as exc:
        raise GraphError(f"cannot read graph file {str(p)!r}: {exc.strerror or exc}") from exc
    except UnicodeDecodeError as exc:
        raise GraphError(f"{str(p)!r}: not UTF-8 text ({exc})") from exc
    return loads(text, fmt=f, registry=registry, base_dir=p.parent.resolve(), source=str(path))


def parse_value(text: str) -> Any:
    """A setting value typed on a command line: a TOML value, else the text itself.

    Examples
    --------
    >>> parse_value("3"), parse_value("0.1"), parse_value("[0.1, 0.05]"), parse_value("true")
    (3, 0.1, [0.1, 0.05], True)
    >>> parse_value("raw"), parse_value('"3"')
    ('raw', '3')
    """
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text
