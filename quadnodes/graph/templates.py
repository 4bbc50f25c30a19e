"""Text settings that name other nodes' settings: ``"faired, {fair.iterations} iterations"``.

A node type lists such settings in ``@node(templates=...)`` (the figure titles of
``render_png``, for instance). When the graph runs, each ``{node.setting}`` is
replaced by that node's resolved setting — after ``--set`` overrides and with
defaults filled in — so a figure says what produced it. A format spec may
follow: ``{fair.weight:.3g}``. ``{{`` and ``}}`` are literal braces.

The references are checked with the graph (:meth:`Graph.validate`, so when a
file is loaded): an unknown node or setting is a :class:`GraphError` naming
both, before anything runs.

Examples
--------
>>> from quadnodes.graph.node import Registry, node
>>> from quadnodes.graph.graph import Graph
>>> reg = Registry()
>>> @node("smooth", registry=reg)
... def smooth(*, rounds: int = 3) -> int:
...     return rounds
>>> @node("caption", registry=reg, templates=("text",))
... def caption(x: int, *, text: str = "") -> str:
...     return text
>>> g = Graph(registry=reg)
>>> s = g.add("smooth", id="s")
>>> c = g.add("caption", s, id="c", text="smoothed {s.rounds} times, {{literal}}")
>>> g.run(overrides={"s.rounds": 5})[c]
'smoothed 5 times, {literal}'
>>> g.set("c", text="{s.round} rounds")
>>> g.validate()
Traceback (most recent call last):
...
quadnodes.errors.GraphError: node 'c' (caption@1): setting 'text': '{s.round}' names no setting 'round' of node 's' (smooth@1); did you mean 'rounds'? (settings: rounds)
"""

from __future__ import annotations

import string
from collections.abc import Iterator, Mapping
from typing import TYPE_CHECKING, Any

from ..errors import GraphError
from ._util import did_you_mean, graph_error, label

if TYPE_CHECKING:
    from .graph import Graph
    from .node import NodeType

__all__ = ["template_errors", "expand"]

_FORMATTER = string.Formatter()


def _strings(value: Any) -> Iterator[tuple[str, str]]:
    """``(where, text)`` for a str or the strings of a list."""
    if isinstance(value, str):
        yield "", value
    elif isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            if isinstance(v, str):
                yield f"[{i}]", v


def _fields(text: str) -> list[tuple[str, str]]:
    """``(field, format_spec)`` of every ``{...}`` in ``text``.

    Raises
    ------
    ValueError
        On unbalanced braces.
    """
    return [(f, spec or "") for _, f, spec, _ in _FORMATTER.parse(text) if f is not None]


def template_errors(graph: Graph) -> list[GraphError]:
    """Every malformed or unknown ``{node.setting}`` in the template settings of ``graph``."""
    errors: list[GraphError] = []
    for spec in graph.nodes.values():
        nt = graph.registry.get(spec.op, node_id=spec.id)
        for s in nt.settings:
            if not s.template or s.name not in spec.params:
                continue
            for where, text in _strings(spec.params[s.name]):
                at = f"{label(spec.id, nt.op)}: setting {s.name!r}{where}"
                try:
                    fields = _fields(text)
                except ValueError as exc:
                    errors.append(graph_error(f"{at}: {text!r}: {exc} (write {{{{ and }}}} for literal braces)",
                                              node_id=spec.id))
                    continue
                for field, _ in fields:
                    msg = _field_problem(graph, field)
                    if msg:
                        errors.append(graph_error(f"{at}: {msg}", node_id=spec.id))
    return errors


def _field_problem(graph: Graph, field: str) -> str | None:
    node_id, dot, setting = field.partition(".")
    if not dot or not setting:
        return f"'{{{field}}}': expected '{{node.setting}}', e.g. '{{fair.iterations}}'"
    if node_id not in graph.nodes:
        return f"'{{{field}}}' names no node {node_id!r}{did_you_mean(node_id, graph.nodes, kind='nodes')}"
    other = graph.registry.get(graph.nodes[node_id].op, node_id=node_id)
    if other.setting(setting) is None:
        hint = did_you_mean(setting, [x.name for x in other.settings], kind="settings")
        return f"'{{{field}}}' names no setting {setting!r} of {label(node_id, other.op)}{hint}"
    return None


def _text(value: Any, spec: str) -> str:
    if isinstance(value, (list, tuple)):
        return ", ".join(_text(v, spec) for v in value)
    if spec:
        return format(value, spec)
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def expand(graph: Graph, nt: NodeType, settings: Mapping[str, Any]) -> dict[str, Any]:
    """``settings`` with every template setting's ``{node.setting}`` replaced by that resolved value.

    Raises
    ------
    GraphError
        On a reference :func:`template_errors` would report, or a format spec
        that does not fit the value.
    """
    out = dict(settings)
    for s in nt.settings:
        if not s.template or out.get(s.name) is None:
            continue
        value = out[s.name]
        if isinstance(value, str):
            out[s.name] = _expand_one(graph, nt, s.name, value)
        elif isinstance(value, (list, tuple)):
            out[s.name] = type(value)(_expand_one(graph, nt, s.name, v) if isinstance(v, str) else v for v in value)
    return out


def _expand_one(graph: Graph, nt: NodeType, setting: str, text: str) -> str:
    parts: list[str] = []
    try:
        parsed = list(_FORMATTER.parse(text))
    except ValueError as exc:
        raise GraphError(f"{nt.op}: setting {setting!r}: {text!r}: {exc}") from None
    for literal, field, spec, _ in parsed:
        parts.append(literal)
        if field is None:
            continue
        msg = _field_problem(graph, field)
        if msg:
            raise GraphError(f"{nt.op}: setting {setting!r}: {msg}")
        node_id, _, name = field.partition(".")
        other_spec = graph.nodes[node_id]
        other = graph.registry.get(other_spec.op, node_id=node_id)
        value = other.resolve_settings(other_spec.params, node_id=node_id)[name]
        try:
            parts.append(_text(value, spec or ""))
        except (ValueError, TypeError) as exc:
            raise GraphError(f"{nt.op}: setting {setting!r}: '{{{field}:{spec}}}': {exc}") from None
    return "".join(parts)
