"""Where a graph may write and read: output paths confined to the output folder, reads to the graph's folder.

A graph file may come from someone else, so the files it names are checked
before anything runs:

- every path in a ``writes`` setting (an output of ``export_obj``, ``render_png``,
  …) is relative, and resolves — symbolic links followed — to a place inside the
  run's output folder (``quadnodes run --out``; for :func:`quadnodes.graph.run`,
  its ``out`` argument, else the graph's folder, else the working directory);
- no two writer settings name the same file;
- a writer fixed to one format (``export_step``, ``render_png``, …) writes only
  under that format's suffixes (declared as ``func.file_suffixes``);
- every path in a ``reads`` setting of a graph loaded from a file resolves inside
  the graph file's folder, unless the user allows another folder
  (``quadnodes run --allow-read DIR``, ``run(..., allow_read=[DIR])``).

:func:`output_path_errors` needs no folder (it looks at the text of the paths:
absolute, or leading up with ``..``, or duplicated) and runs when a file is
loaded; :func:`check_paths` resolves against the real folders and runs at the
start of every run.

Examples
--------
>>> from quadnodes.graph.node import Registry, node
>>> reg = Registry()
>>> @node("save_text", writes=("path",), registry=reg)
... def save_text(*, path: str = "a.txt") -> str:
...     return path
>>> from quadnodes.graph.graph import Graph
>>> g = Graph(registry=reg)
>>> _ = g.add("save_text", id="ok", path="sub/a.txt")
>>> _ = g.add("save_text", id="up", path="../escape.txt")
>>> [str(e) for e in output_path_errors(g)]
["node 'up' (save_text@1): setting 'path': '../escape.txt' leads out of the output folder; give a path inside it, such as 'escape.txt'"]
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

from ..errors import GraphError
from ._types import to_plain
from ._util import graph_error, label
from .graph import Graph

__all__ = ["output_path_errors", "check_paths", "outputs_of"]


def _values(value: Any) -> list[Any]:
    if value is None:
        return []
    if isinstance(value, (list, tuple)):
        return [p for v in value for p in _values(v)]
    return [value]


def _file_settings(graph: Graph, kind: str) -> Iterator[tuple[str, str, str, list[str]]]:
    """``(node_id, op, setting, [path text, ...])`` for every ``reads``/``writes`` setting of the graph."""
    for spec in graph.nodes.values():
        nt = graph.registry.get(spec.op, node_id=spec.id)
        for s in (nt.writes if kind == "write" else nt.reads):
            setting = nt.setting(s)
            value = spec.params.get(s, None if setting is None or setting.required else setting.default)
            texts = [os.fspath(v) if isinstance(v, os.PathLike) else v for v in _values(to_plain(value))]
            yield spec.id, spec.op, s, [t for t in texts if isinstance(t, str)]


def _suffix_problem(graph: Graph, node_id: str, op: str, setting: str, text: str) -> str | None:
    """Why ``text`` does not end in a suffix the node declares for ``setting`` (``func.file_suffixes``,
    e.g. ``{"path": (".step", ".stp")}``), else None: a writer fixed to one format would otherwise put it
    under another format's name (STEP text in ``panels.stl``)."""
    nt = graph.registry.get(op, node_id=node_id)
    suffixes = getattr(nt.func, "file_suffixes", {}).get(setting)
    if not suffixes or Path(text).suffix.lower() in suffixes:
        return None
    kinds = " or ".join(suffixes)
    return (f"{label(node_id, op)}: setting {setting!r}: {text!r} does not end in {kinds}, the kind of file "
            f"{nt.name} writes; name it e.g. {Path(text).stem + suffixes[0]!r}")


def output_path_errors(graph: Graph) -> list[GraphError]:
    """Every writer path that is absolute, leads out with ``..``, or is named by two settings.

    Looks at the text only (no folder needed), so it runs when a graph file is
    loaded and after ``--set``.

    Returns
    -------
    list of GraphError
        Each names the node and the setting (both nodes for a duplicate).
    """
    errors: list[GraphError] = []
    seen: dict[str, tuple[str, str, str]] = {}
    for node_id, op, s, texts in _file_settings(graph, "write"):
        where = f"{label(node_id, op)}: setting {s!r}"
        for text in texts:
            if text.strip() == "":
                errors.append(graph_error(f"{where}: empty path", node_id=node_id))
                continue
            if os.path.isabs(text) or Path(text).drive:
                errors.append(graph_error(
                    f"{where}: {text!r} is an absolute path; output paths are relative to the output folder "
                    f"(quadnodes run --out DIR), e.g. {Path(text).name!r}", node_id=node_id))
                continue
            norm = os.path.normpath(text)
            if norm == ".." or norm.startswith(".." + os.sep) or norm == ".":
                errors.append(graph_error(
                    f"{where}: {text!r} leads out of the output folder; give a path inside it, "
                    f"such as {Path(text).name!r}", node_id=node_id))
                continue
            wrong = _suffix_problem(graph, node_id, op, s, text)
            if wrong:
                errors.append(graph_error(wrong, node_id=node_id))
                continue
            key = os.path.normcase(norm)
            if key in seen and seen[key][0] != node_id:
                other, other_op, other_s = seen[key]
                errors.append(graph_error(
                    f"{where}: {text!r} is also written by {label(other, other_op)} (setting {other_s!r}); "
                    "give each output its own file", node_id=node_id))
            elif key in seen:
                errors.append(graph_error(f"{where}: names {text!r} twice", node_id=node_id))
            else:
                seen[key] = (node_id, op, s)
    return errors


def _inside(path: str, folder: str) -> bool:
    return path == folder or path.startswith(folder.rstrip(os.sep) + os.sep)


def outputs_of(graph: Graph, out: str | os.PathLike[str]) -> dict[tuple[str, str], list[Path]]:
    """Writer paths by ``(node_id, setting)``, joined to ``out`` (not resolved, not checked)."""
    base = Path(out)
    return {(node_id, s): [base / t for t in texts] for node_id, _, s, texts in _file_settings(graph, "write")}


def check_paths(
    graph: Graph,
    *,
    out: str | os.PathLike[str],
    read_roots: Iterable[str | os.PathLike[str]] | None = None,
) -> None:
    """Refuse a graph whose outputs leave ``out`` or whose reads leave ``read_roots``, before it runs.

    Parameters
    ----------
    graph : Graph
    out : path-like
        The output folder; relative writer paths are joined to it. Absolute writer
        paths are accepted only when they lie inside it (the Python API); graph
        files and ``--set`` are refused absolute paths earlier, by
        :func:`output_path_errors`.
    read_roots : paths, optional
        Folders reads may come from (relative reads are joined to
        ``graph.base_dir``). None: reads are not restricted.

    Raises
    ------
    GraphError
        Naming the node and setting: a writer path that resolves (symbolic links
        followed) outside ``out``, two writer settings that resolve to the same
        file, or a read outside ``read_roots``. All problems are listed, one per
        line.
    """
    errors: list[str] = []
    first: str | None = None
    out_real = os.path.realpath(out)
    seen: dict[str, tuple[str, str, str]] = {}
    for node_id, op, s, texts in _file_settings(graph, "write"):
        where = f"{label(node_id, op)}: setting {s!r}"
        for text in texts:
            real = os.path.realpath(os.path.join(out_real, text))
            wrong = _suffix_problem(graph, node_id, op, s, text)
            if wrong:
                errors.append(wrong)
            elif not _inside(real, out_real) or real == out_real:
                errors.append(f"{where}: {text!r} resolves to {real!r}, outside the output folder {out_real!r}"
                              + (" (through a symbolic link)" if not os.path.isabs(text) else ""))
            elif real in seen:
                other, other_op, other_s = seen[real]
                errors.append(f"{where}: {text!r} is the same file as the one {label(other, other_op)} writes "
                              f"(setting {other_s!r}); give each output its own file")
            else:
                seen[real] = (node_id, op, s)
                continue
            first = first or node_id
    if read_roots is not None:
        roots = [os.path.realpath(r) for r in read_roots]
        base = os.fspath(graph.base_dir) if graph.base_dir is not None else os.getcwd()
        for node_id, op, s, texts in _file_settings(graph, "read"):
            for text in texts:
                real = os.path.realpath(os.path.join(base, text))
                if not any(_inside(real, r) for r in roots):
                    errors.append(
                        f"{label(node_id, op)}: setting {s!r}: {text!r} is outside the graph's folder "
                        f"{roots[0]!r}; a graph file reads only from its own folder unless you allow another "
                        f"(quadnodes run --allow-read {os.path.dirname(real) or real})")
                    first = first or node_id
    if errors:
        raise graph_error("\n".join(errors), node_id=first)
