"""The live state behind ``quadnodes serve``: one graph file, its edits, its runs.

A :class:`Session` owns the graph file. Every edit (a setting, a node added or
deleted, a wire connected or removed, a node moved) is applied to the file's own
text — with :mod:`tomlkit` for TOML, so comments and layout stay; JSON is
rewritten with sorted keys — and the new text is validated by the same loader as
``quadnodes run`` (:func:`quadnodes.graph.loads`), so an edit is accepted or
refused with exactly the loader's message, and a refused edit changes nothing.
An accepted edit is written to the file atomically and the graph re-runs in a
worker thread with a disk cache, so only the nodes downstream of the change
execute. A newer edit supersedes a run in progress at the next node boundary.

The file stays the single source of truth: :meth:`Session.poll` notices an edit
made in a text editor (file stamps, as ``quadnodes watch`` does) and reloads.

File settings are confined: a node may read files only inside the graph file's
folder or the output folder, and writes only inside the output folder (output
paths are relative to it, as in ``quadnodes run``).
"""

from __future__ import annotations

import base64
import json
import math
import os
import threading
import time
import types
import typing
from collections.abc import Callable, Mapping
from pathlib import Path, PurePath
from typing import Any

import numpy as np

from ..errors import ExportError, GraphError, NodeError, QuadnodesError
from ..graph import Cache, Graph, loads
from ..graph import _types
from ..graph.node import NO_DEFAULT, NodeType, Registry, Setting
from ..graph.watch import snapshot, watched_files
from ..io._atomic import write_text_atomic

__all__ = ["Session", "EditResult", "setting_field", "node_type_info", "auto_layout", "encode_mesh"]

Event = dict[str, Any]


class _Superseded(Exception):
    """A newer edit arrived while a run was going on: stop at the next node boundary."""


class EditResult(dict):
    """The answer to an edit: ``{"ok": True, "revision": n}`` or ``{"ok": False, "error": ..., "node": id}``."""


# --------------------------------------------------------------- node types
def _setting_range(s: Setting, nt: NodeType) -> list[float] | None:
    """The ``[low, high]`` of a numeric setting's declared range (``@node(ranges=...)``) when both ends are
    finite — the page then shows a slider — else None."""
    r = s.range
    lo = getattr(r, "min", None)
    hi = getattr(r, "max", None)
    try:
        lo, hi = float(lo), float(hi)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return None
    return [lo, hi] if math.isfinite(lo) and math.isfinite(hi) and hi > lo else None


def _is_union(ann: Any) -> bool:
    return typing.get_origin(ann) in (typing.Union, types.UnionType)


def _path_values(value: Any) -> list[Any]:
    """The paths in a file setting's value (a path, a list of them, or None)."""
    if value is None:
        return []
    if isinstance(value, (list, tuple)):
        return [p for v in value for p in _path_values(v)]
    return [value]


def _kind(ann: Any) -> dict[str, Any]:
    origin, args = typing.get_origin(ann), typing.get_args(ann)
    if ann is bool:
        return {"kind": "bool"}
    if ann is int:
        return {"kind": "int"}
    if ann is float:
        return {"kind": "float"}
    if ann is str or (isinstance(ann, type) and issubclass(ann, PurePath)):
        return {"kind": "str"}
    if origin is typing.Literal:
        return {"kind": "choice", "options": [_types.to_plain(a) for a in args]}
    if origin in (list, tuple) or ann in (list, tuple):
        item = _kind(args[0]) if args else {"kind": "json"}
        return {"kind": "list", "item": item.get("kind", "json")}
    if _is_union(ann):
        rest = [a for a in args if a is not type(None)]
        kinds = [_kind(a) for a in rest]
        out: dict[str, Any]
        if len(kinds) == 1:
            out = dict(kinds[0])
        elif {k["kind"] for k in kinds} <= {"int", "float", "list"} and any(k["kind"] == "list" for k in kinds):
            out = {"kind": "number_or_list", "item": "float"}
        else:
            out = {"kind": "json"}
        if len(rest) < len(args):
            out["nullable"] = True
        return out
    return {"kind": "json"}


def setting_field(s: Setting, nt: NodeType) -> dict[str, Any]:
    """How the page shows one setting: its form field kind, default, choices and range.

    Examples
    --------
    >>> from quadnodes import nodes  # noqa: F401
    >>> from quadnodes.graph import REGISTRY
    >>> nt = REGISTRY.get("fair")
    >>> f = setting_field(nt.setting("solver"), nt)
    >>> f["kind"], f["options"], f["default"]
    ('choice', ['auto', 'direct', 'cg'], 'auto')
    >>> setting_field(nt.setting("threshold"), nt)["kind"]
    'number_or_list'
    """
    d: dict[str, Any] = {"name": s.name, "type": s.type_name, "required": s.required, "file": s.file}
    d.update(_kind(s.annotation))
    if not s.required:
        d["default"] = _types.to_plain(s.default)
    r = _setting_range(s, nt) if d["kind"] in ("int", "float", "number_or_list") else None
    if r is not None:
        d["range"] = r
    return d


def _is_mesh_type(ann: Any) -> bool:
    from ..mesh import QuadMesh

    return ann is QuadMesh or (_is_union(ann) and QuadMesh in typing.get_args(ann))


def node_type_info(nt: NodeType) -> dict[str, Any]:
    """Ports and setting fields of a node type, as the page and the palette use them."""
    doc = nt.doc.strip()
    return {
        "op": nt.op,
        "name": nt.name,
        "summary": " ".join(doc.split("\n\n", 1)[0].split()) if doc else "",
        "inputs": [{"name": p.name, "type": p.type_name, "required": p.required} for p in nt.inputs],
        "outputs": [{"name": p.name, "type": p.type_name, "mesh": _is_mesh_type(p.annotation)} for p in nt.outputs],
        "settings": [setting_field(s, nt) for s in nt.settings],
    }


def auto_layout(graph: Graph, *, saved: Mapping[str, list[float]] | None = None,
                dx: float = 250.0, dy: float = 18.0, column_height: float = 1000.0,
                node_height: Callable[[str], float] | None = None) -> dict[str, list[float]]:
    """Positions of every node: saved ones kept, the others in columns by topological depth.

    A column taller than ``column_height`` flows on into a further column beside it.

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
    >>> a = g.add("num", id="a"); b = g.add("neg", a, id="b"); c = g.add("neg", a, id="c")
    >>> auto_layout(g, node_height=lambda n: 500.0)
    {'a': [20.0, 20.0], 'b': [270.0, 20.0], 'c': [520.0, 20.0]}
    """
    saved = dict(saved or {})

    def _height(n: str) -> float:  # the page shows ports, the settings set in the file and required ones
        nt, spec = graph.node_type(n), graph.nodes[n]
        shown = sum(1 for s in nt.settings if s.name in spec.params or s.required)
        return 40.0 + 16.0 * max(len(nt.inputs), len(nt.outputs)) + 22.0 * shown + 22.0

    height = node_height or _height
    order = graph.order()
    depth: dict[str, int] = {}
    for nid in order:
        ups = [c.node for c in graph.nodes[nid].inputs.values() if hasattr(c, "node")]
        depth[nid] = 1 + max((depth[u] for u in ups if u in depth), default=-1)
    out: dict[str, list[float]] = {}
    x = 20.0
    for col in range(max(depth.values(), default=-1) + 1):
        y, used = 20.0, False
        for nid in (n for n in order if depth[n] == col and n not in saved):
            h = height(nid)
            if used and y + h > column_height:
                x, y = x + dx, 20.0
            out[nid] = [x, y]
            y += h + dy
            used = True
        if used:
            x += dx
    out.update({k: [float(v[0]), float(v[1])] for k, v in saved.items() if k in depth})
    return {k: out[k] for k in order}


# --------------------------------------------------------------- mesh data
def _b64(a: np.ndarray, dtype: str) -> str:
    return base64.b64encode(np.ascontiguousarray(a, dtype=dtype).tobytes()).decode("ascii")


def encode_mesh(mesh: Any, *, encoding: str = "base64") -> dict[str, Any]:
    """A mesh as the page draws it: vertices, faces, edges, zigzag deviation per edge, planarity per face.

    With ``encoding="base64"`` the arrays are little-endian float32 / int32 typed arrays
    in base64 (about 5.3 bytes per float, against ~19 as JSON text); with ``"list"`` plain JSON lists.

    Raises
    ------
    InputError
        If ``mesh`` is not a QuadMesh, or ``encoding`` is unknown.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> d = encode_mesh(grid(2, 3), encoding="list")
    >>> d["n_vertices"], d["n_faces"], d["faces"][0], len(d["edges"])
    (6, 2, [0, 1, 4, 3], 7)
    """
    from .. import _validate
    from .._view import edge_deviation
    from ..errors import InputError
    from ..flatness import planarity

    _validate.quad_mesh(mesh)
    if encoding not in ("base64", "list"):
        raise InputError(f"encoding: expected 'base64' or 'list', got {encoding!r}")
    edges = mesh.topology.edges
    dev = edge_deviation(mesh)
    plan = planarity(mesh)["diagonal"]
    arrays = {"vertices": (mesh.vertices, "<f4"), "faces": (mesh.faces, "<i4"), "edges": (edges, "<i4"),
              "edge_deviation": (dev, "<f4"), "planarity": (plan, "<f4")}
    out: dict[str, Any] = {
        "n_vertices": int(mesh.n_vertices), "n_faces": int(len(mesh.faces)), "n_edges": int(len(edges)),
        "unit": getattr(mesh, "unit", "mm"), "encoding": encoding,
        "grid_shape": list(mesh.grid_shape) if mesh.grid_shape else None,
        "max_deviation": float(dev.max()) if len(dev) else 0.0,
        "max_planarity": float(np.nanmax(plan)) if len(plan) else 0.0,
    }
    for name, (a, dt) in arrays.items():
        out[name] = _b64(a, dt) if encoding == "base64" else np.asarray(a).tolist()
    return out


# ------------------------------------------------------------------ session
def _stamp(path: Path) -> Any:
    return snapshot([path])[path]


def _inside(path: Path, folder: Path) -> bool:
    try:
        path.relative_to(folder)
    except ValueError:
        return False
    return True


class Session:
    """A graph file made live: edits, validation, runs and events.

    Parameters
    ----------
    path : path-like
        The graph file (.toml or .json).
    out : path-like, optional
        Output folder (default ``out/<graph name>/`` in the working directory, as ``quadnodes run``).
    cache : Cache, optional
        Default: a disk cache in ``<out>/.cache`` (shared with ``quadnodes run``).
    registry : Registry, optional
        Node types (default: the built-in nodes).

    Raises
    ------
    GraphError
        If the file cannot be read or is invalid at the start.
    """

    def __init__(self, path: str | os.PathLike[str], *, out: str | os.PathLike[str] | None = None,
                 cache: Cache | None = None, registry: Registry | None = None) -> None:
        if registry is None:
            from .. import nodes  # noqa: F401  (registers the built-in node types)
            from ..graph import REGISTRY

            registry = REGISTRY
        self.registry = registry
        self.path = Path(path).resolve()
        self.fmt = {".toml": "toml", ".json": "json"}.get(self.path.suffix.lower())
        if self.fmt is None:
            raise GraphError(f"{str(path)!r}: cannot tell the format from the suffix; use .toml or .json")
        self.base = self.path.parent
        self.out = (Path(out) if out is not None else Path("out") / self.path.stem).resolve()
        self.out.mkdir(parents=True, exist_ok=True)
        self.cache = cache if cache is not None else Cache(self.out / ".cache", max_memory_entries=512)
        self._lock = threading.RLock()
        self._listeners: list[Callable[[Event], None]] = []
        self.text = self._read()
        self._document: Any = None
        self.graph = self._validate(self.text)
        self.stamp = _stamp(self.path)
        self._read_stamps = snapshot(self._read_files())
        self.revision = 1
        self.node_errors: dict[str, str] = {}
        self.file_error: str | None = None
        self.run_state: dict[str, Any] = {"revision": 0, "state": "idle", "nodes": {}}
        self._outputs: dict[str, Mapping[str, Any]] = {}
        self._mesh_cache: dict[tuple[str, str, str], dict[str, Any]] = {}
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._worker: threading.Thread | None = None

    # ------------------------------------------------------------ lifecycle
    def start(self) -> None:
        """Start the worker thread and the first run."""
        if self._worker is None:
            self._worker = threading.Thread(target=self._work, name="quadnodes-run", daemon=True)
            self._worker.start()
        self._wake.set()

    def close(self, *, timeout: float = 5.0) -> None:
        """Stop the worker: a run in progress stops at the next node (waits up to ``timeout`` seconds for it;
        the worker is a daemon thread, so a long node never keeps the process alive)."""
        self._stop.set()
        self._wake.set()
        if self._worker is not None:
            self._worker.join(timeout=timeout)

    def subscribe(self, listener: Callable[[Event], None]) -> Callable[[], None]:
        """Call ``listener(event)`` for every event (from any thread); returns the unsubscribe function."""
        with self._lock:
            self._listeners.append(listener)

        def remove() -> None:
            with self._lock:
                if listener in self._listeners:
                    self._listeners.remove(listener)

        return remove

    def _emit(self, event: Event) -> None:
        for f in list(self._listeners):
            f(event)

    # ----------------------------------------------------------- the model
    def _read(self) -> str:
        try:
            return self.path.read_bytes().decode("utf-8-sig")
        except OSError as exc:
            raise GraphError(f"cannot read graph file {str(self.path)!r}: {exc.strerror or exc}") from exc
        except UnicodeDecodeError as exc:
            raise GraphError(f"{str(self.path)!r}: not UTF-8 text ({exc})") from exc

    def _validate(self, text: str) -> Graph:
        g = loads(text, fmt=self.fmt, registry=self.registry, base_dir=self.base, source=self.path.name)
        self._check_paths(g)
        return g

    def _check_paths(self, g: Graph) -> None:
        """Refuse file settings that leave the graph's folder (reads) or the output folder (writes)."""
        for spec in g.nodes.values():
            nt = g.registry.get(spec.op, node_id=spec.id)
            for s in (*nt.reads, *nt.writes):
                for p in _path_values(spec.params.get(s)):
                    text = os.fspath(p) if isinstance(p, (str, os.PathLike)) else str(p)
                    where = f"node {spec.id!r} ({nt.op}): setting {s!r}"
                    if s in nt.writes:
                        target = (self.out / text).resolve()
                        if os.path.isabs(text) or not _inside(target, self.out) or target == self.out:
                            raise self._refusal(
                                f"{where}: {text!r} leaves the output folder; write paths are relative to "
                                f"--out ({self.out}) and stay inside it", spec.id)
                    else:
                        target = (self.base / text).resolve()
                        if not (_inside(target, self.base) or _inside(target, self.out)):
                            raise self._refusal(
                                f"{where}: {text!r} is outside the graph's folder ({self.base}) and the output "
                                f"folder; the page reads files only from there", spec.id)

    @staticmethod
    def _refusal(message: str, node_id: str) -> GraphError:
        err = GraphError(message)
        err.node_id = node_id  # type: ignore[attr-defined]
        return err

    def _read_files(self) -> list[Path]:
        return [f for f in watched_files(self.path, self.graph) if f != self.path]

    def _run_graph(self, g: Graph) -> Graph:
        """The graph as it runs: output paths stay relative and resolve under ``out`` in :meth:`run_once`
        (``Graph.run(out=...)`` confines them there, as ``quadnodes run`` does)."""
        return g

    def describe(self) -> dict[str, Any]:
        """``GET /api/graph``: the file model, positions, node types in use, refused edits."""
        from ..graph.files import to_dict

        with self._lock:
            g = self.graph
            model = to_dict(g)
            types = {}
            for spec in g.nodes.values():
                types[spec.op] = node_type_info(g.registry.get(spec.op, node_id=spec.id))
            return {
                "file": self.path.name,
                "path": str(self.path),
                "format": self.fmt,
                "out": str(self.out),
                "revision": self.revision,
                "nodes": model["nodes"],
                "order": g.order(),
                "layout": auto_layout(g, saved=g.layout),
                "saved_layout": sorted(k for k in g.layout if k in g.nodes),
                "types": types,
                "errors": dict(self.node_errors),
                "file_error": self.file_error,
            }

    def palette(self) -> list[dict[str, Any]]:
        """Every registered node type (latest version), for the page's palette."""
        return [node_type_info(nt) for nt in self.registry.latest()]

    # ---------------------------------------------------------------- edits
    def _doc(self) -> Any:
        """The document of :attr:`text`, kept between accepted edits (parsing TOML with comments is slow)."""
        if self._document is None:
            if self.fmt == "toml":
                import tomlkit

                self._document = tomlkit.parse(self.text)
            else:
                self._document = json.loads(self.text)
        return self._document

    def _dump(self, doc: Any) -> str:
        if self.fmt == "toml":
            import tomlkit

            return tomlkit.dumps(doc)
        return json.dumps(doc, indent=2, sort_keys=True, ensure_ascii=False) + "\n"

    def _table(self, inline: bool = True) -> Any:
        if self.fmt == "toml":
            import tomlkit

            return tomlkit.inline_table() if inline else tomlkit.table()
        return {}

    def _node(self, doc: Any, node_id: str) -> Any:
        nodes = doc.get("nodes")
        if not isinstance(nodes, Mapping) or node_id not in nodes:
            raise self._refusal(f"no node {node_id!r} in {self.path.name}", node_id)
        return nodes[node_id]

    def _sub(self, body: Any, name: str) -> Any:
        if name not in body:
            body[name] = self._table()
        return body[name]

    def _edit(self, node_id: str | None, change: Callable[[Any], None], *, rerun: bool = True) -> EditResult:
        with self._lock:
            try:
                doc = self._doc()
                change(doc)
                text = self._dump(doc)
                g = self._validate(text)
            except GraphError as exc:
                self._document = None  # the change may have touched it: parse the file's text again next time
                at = getattr(exc, "node_id", None) or node_id
                if at is not None:
                    self.node_errors = {at: str(exc)}
                self._emit({"type": "refused", "node": at, "error": str(exc), "revision": self.revision})
                return EditResult(ok=False, error=str(exc), node=at, revision=self.revision)
            if text != self.text:
                try:
                    write_text_atomic(self.path, text)
                except (ExportError, OSError) as exc:
                    self._document = None
                    return EditResult(ok=False, error=f"cannot write {self.path.name}: {exc}", node=node_id,
                                      revision=self.revision)
            self.text, self.graph, self.stamp = text, g, _stamp(self.path)
            self.node_errors = {}
            self.file_error = None
            self.revision += 1
            rev = self.revision
            if rerun:  # (under the lock: the worker takes the wake-up and the revision together, see run_once)
                self._wake.set()
        self._emit({"type": "graph", "revision": rev})
        return EditResult(ok=True, revision=rev)

    def set_settings(self, node_id: str, settings: Mapping[str, Any]) -> EditResult:
        """``POST /api/nodes/{id}/settings``: change settings (None removes one, back to its default)."""
        def change(doc: Any) -> None:
            if not isinstance(settings, Mapping):
                raise self._refusal(
                    f"node {node_id!r}: settings: expected a JSON object of setting -> value, got {settings!r}",
                    node_id)
            params = self._sub(self._node(doc, node_id), "params")
            for k, v in settings.items():
                if v is None:
                    if k in params:
                        del params[k]
                else:
                    params[k] = v

        return self._edit(node_id, change)

    def add_node(self, op: str, *, node_id: str | None = None, inputs: Mapping[str, str] | None = None,
                 params: Mapping[str, Any] | None = None, pos: list[float] | None = None) -> EditResult:
        """Add a node of type ``op`` (id: the op name and the first free number unless given)."""
        try:
            nt = self.registry.get(op)
        except GraphError as exc:
            return EditResult(ok=False, error=str(exc), node=None, revision=self.revision)
        if node_id is None:
            k = 1
            while f"{nt.name}{k}" in self.graph.nodes:
                k += 1
            node_id = f"{nt.name}{k}"

        def change(doc: Any) -> None:
            nodes = doc.get("nodes")
            if nodes is None:
                doc["nodes"] = nodes = self._table(inline=False)
            if node_id in nodes:
                raise self._refusal(f"node {node_id!r}: the id is already used by another node", node_id)
            body = self._table(inline=False)
            body["op"] = nt.op
            if inputs:
                t = self._table()
                t.update(dict(inputs))
                body["inputs"] = t
            if params:
                t = self._table()
                t.update(dict(params))
                body["params"] = t
            nodes[node_id] = body
            if pos is not None:
                self._set_pos(doc, node_id, pos)

        res = self._edit(node_id, change)
        res["id"] = node_id
        return res

    def delete_node(self, node_id: str) -> EditResult:
        """Delete a node, the wires into it and its saved position."""
        def change(doc: Any) -> None:
            self._node(doc, node_id)
            del doc["nodes"][node_id]
            for body in doc["nodes"].values():
                ins = body.get("inputs") if isinstance(body, Mapping) else None
                if isinstance(ins, Mapping):
                    for port in [p for p, ref in ins.items() if str(ref).split(".", 1)[0] == node_id]:
                        del ins[port]
            lay = doc.get("layout")
            if isinstance(lay, Mapping) and node_id in lay:
                del lay[node_id]

        return self._edit(node_id, change)

    def connect(self, node_id: str, port: str, source: str) -> EditResult:
        """Wire ``source`` (``"node.port"``) into input ``port`` of ``node_id``."""
        def change(doc: Any) -> None:
            self._sub(self._node(doc, node_id), "inputs")[port] = source

        return self._edit(node_id, change)

    def disconnect(self, node_id: str, port: str) -> EditResult:
        """Remove the wire into input ``port`` of ``node_id``."""
        def change(doc: Any) -> None:
            ins = self._node(doc, node_id).get("inputs")
            if ins is None or port not in ins:
                raise self._refusal(f"node {node_id!r}: input {port!r} is not connected", node_id)
            del ins[port]

        return self._edit(node_id, change)

    def _set_pos(self, doc: Any, node_id: str, pos: Any) -> None:
        if "layout" not in doc:
            doc["layout"] = self._table(inline=False)
        doc["layout"][node_id] = [round(float(pos[0]), 1), round(float(pos[1]), 1)]

    def move(self, positions: Mapping[str, Any]) -> EditResult:
        """Save node positions in the file's ``[layout]`` table (no re-run)."""
        def change(doc: Any) -> None:
            if not isinstance(positions, Mapping):
                raise GraphError(f"positions: expected an object of node id -> [x, y], got {positions!r}")
            for nid, pos in positions.items():
                self._node(doc, nid)
                if not (isinstance(pos, (list, tuple)) and len(pos) == 2
                        and all(isinstance(x, (int, float)) and math.isfinite(x) for x in pos)):
                    raise self._refusal(f"layout.{nid}: expected a position [x, y] of two numbers, got {pos!r}", nid)
                self._set_pos(doc, nid, pos)

        return self._edit(None, change, rerun=False)

    # -------------------------------------------------------- file changes
    def poll(self) -> bool:
        """Reload after an edit of the file in another program; re-run when a file a node reads changed.

        Returns True when something changed. An invalid file keeps the last good graph
        and sets :attr:`file_error` (the page shows it).
        """
        now = _stamp(self.path)
        reads_now = snapshot(self._read_files())
        if now == self.stamp and reads_now == self._read_stamps:
            return False
        with self._lock:
            self._read_stamps = reads_now
            if now == self.stamp:
                self._wake.set()
                return True
            self.stamp = now
            try:
                text = self._read()
            except GraphError as exc:
                self.file_error = str(exc)
                self._emit({"type": "graph", "revision": self.revision})
                return True
            if text == self.text and self.file_error is None:
                return False
            try:
                g = self._validate(text)
            except GraphError as exc:
                self.file_error = str(exc)
                self._emit({"type": "graph", "revision": self.revision})
                return True
            self.text, self.graph, self.file_error, self.node_errors = text, g, None, {}
            self._document = None
            self.revision += 1
            rev = self.revision
            self._read_stamps = snapshot(self._read_files())
            self._wake.set()  # (under the lock, as in _edit)
        self._emit({"type": "graph", "revision": rev})
        return True

    # ---------------------------------------------------------------- runs
    def _work(self) -> None:
        while not self._stop.is_set():
            self._wake.wait()
            if self._stop.is_set():
                return
            try:
                self.run_once()
            except _Superseded:
                continue

    def run_once(self) -> dict[str, Any]:
        """Run the current graph (only what changed executes); returns :meth:`run_info`.

        Raises
        ------
        _Superseded
            When a newer edit arrived during the run (the worker then runs again).
        """
        with self._lock:
            # the wake-up taken with the revision it asked for (edits set it under this lock): one that comes later
            # is a later change, never a second run of this one (which would report everything as cached)
            self._wake.clear()
            rev, g = self.revision, self._run_graph(self.graph)
            order = g.order()
            nodes = {nid: {"status": "waiting", "seconds": None, "error": None, "key": None} for nid in order}
            state = {"revision": rev, "state": "running", "nodes": nodes, "started": time.time(),
                     "seconds": None}
            self.run_state = state
        self._emit({"type": "run", "revision": rev, "state": "running"})
        t0 = time.perf_counter()

        def progress(ev: Any) -> None:
            if self._stop.is_set() or self.revision != rev:
                raise _Superseded()
            if ev.kind == "started":
                nodes[ev.node_id]["status"] = "running"
                self._emit({"type": "node", "revision": rev, "id": ev.node_id, **nodes[ev.node_id]})
            elif ev.kind == "finished" and ev.record is not None:
                r = ev.record
                nodes[r.id].update(status=r.status, seconds=round(r.seconds, 4), key=r.key)
                self._emit({"type": "node", "revision": rev, "id": r.id, **nodes[r.id]})

        try:
            result = g.run(cache=self.cache, progress=progress, out=self.out)
        except NodeError as exc:
            if isinstance(exc.__cause__, _Superseded):
                raise exc.__cause__ from None
            nid = getattr(exc, "node_id", None)
            if nid in nodes:
                nodes[nid].update(status="failed", error=str(exc),
                                  seconds=round(time.perf_counter() - t0, 4))
            for v in nodes.values():
                if v["status"] in ("waiting", "running"):
                    v["status"] = "skipped"
            state.update(state="failed", seconds=round(time.perf_counter() - t0, 4), error=str(exc))
        except QuadnodesError as exc:  # e.g. a file a node reads vanished between validation and run
            state.update(state="failed", seconds=round(time.perf_counter() - t0, 4), error=str(exc))
        else:
            with self._lock:
                if self.revision == rev:
                    self._outputs = dict(result.outputs)
            state.update(state="done", seconds=round(time.perf_counter() - t0, 4))
        self._emit({"type": "run", "revision": rev, "state": state["state"], "error": state.get("error")})
        return self.run_info()

    def run_info(self) -> dict[str, Any]:
        """``GET /api/run``: the latest run — per node status, time, key, error; lists of ran/cached/failed."""
        st = self.run_state
        nodes = {k: dict(v) for k, v in st["nodes"].items()}
        by = {s: [k for k, v in nodes.items() if v["status"] == s] for s in ("ran", "cached", "failed")}
        return {"revision": st["revision"], "graph_revision": self.revision, "state": st["state"],
                "seconds": st.get("seconds"), "error": st.get("error"), "nodes": nodes, **by}

    def output(self, node_id: str, port: str) -> Any:
        """The latest value of output ``node_id.port`` (as soon as that node finished).

        Raises
        ------
        GraphError
            Unknown node or port, or no value yet (the node has not run, or failed).
        """
        with self._lock:
            g = self.graph
        if node_id not in g.nodes:
            raise self._refusal(f"no node {node_id!r}", node_id)
        nt = g.node_type(node_id)
        if nt.output(port) is None:
            raise self._refusal(f"node {node_id!r} ({nt.op}) has no output {port!r} "
                                f"(outputs: {', '.join(nt.output_names)})", node_id)
        info = self.run_state["nodes"].get(node_id)
        key = info.get("key") if info else None
        if key is not None:
            entry = self.cache.get(key)
            if entry is not None:
                return entry.outputs[port]
        outs = self._outputs.get(node_id)
        if outs is not None and info is not None and info["status"] in ("ran", "cached"):
            return outs[port]
        status = info["status"] if info else "not run"
        raise self._refusal(f"node {node_id!r}: output {port!r} is not available ({status})", node_id)

    def mesh(self, node_id: str, port: str, *, encoding: str = "base64") -> dict[str, Any]:
        """``GET /api/mesh/{id}/{port}``: the mesh data of an output (see :func:`encode_mesh`)."""
        from ..mesh import QuadMesh

        value = self.output(node_id, port)
        if not isinstance(value, QuadMesh):
            raise self._refusal(f"output {node_id}.{port} is a {type(value).__name__}, not a mesh", node_id)
        key = (self.run_state["nodes"].get(node_id) or {}).get("key") or f"id{id(value)}"
        ck = (key, port, encoding)
        data = self._mesh_cache.get(ck)
        if data is None:
            data = encode_mesh(value, encoding=encoding)
            if len(self._mesh_cache) > 64:
                self._mesh_cache.clear()
            self._mesh_cache[ck] = data
        return {"id": node_id, "port": port, "key": key, "revision": self.run_state["revision"], **data}
