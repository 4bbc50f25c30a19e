"""Re-run a graph file when it, or any file it reads, changes.

Polling ``os.stat`` (modification time in nanoseconds, size, inode) every
``interval`` seconds: no extra dependency, no missed events on network or
container file systems, and an edit that an editor saves by rename is seen too.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

from ..errors import QuadnodesError
from .graph import Graph
from .run import _path_values

__all__ = ["watched_files", "snapshot", "watch"]

Stamp = tuple[int, int, int] | None


def watched_files(graph_path: str | os.PathLike[str], graph: Graph | None) -> list[Path]:
    """The graph file and every file named in a ``reads`` setting of its nodes.

    Relative paths are taken from the graph file's folder, as the runner does.
    """
    files = [Path(graph_path).resolve()]
    if graph is None:
        return files
    base = Path(graph.base_dir) if graph.base_dir is not None else Path(graph_path).resolve().parent
    for spec in graph.nodes.values():
        nt = graph.registry.get(spec.op, node_id=spec.id)
        for s in nt.reads:
            for p in _path_values(spec.params.get(s)):
                q = Path(os.fspath(p))
                files.append((q if q.is_absolute() else base / q).resolve())
    return sorted(set(files))


def snapshot(files: Iterable[Path]) -> dict[Path, Stamp]:
    """``(mtime_ns, size, inode)`` of each file, ``None`` when it is missing."""
    out: dict[Path, Stamp] = {}
    for f in files:
        try:
            st = os.stat(f)
            out[f] = (st.st_mtime_ns, st.st_size, st.st_ino)
        except OSError:
            out[f] = None
    return out


@dataclass
class WatchState:
    """What :func:`watch` keeps between runs."""

    runs: int = 0
    errors: int = 0


def watch(
    graph_path: str | os.PathLike[str],
    run_once: Callable[[], Graph | None],
    *,
    interval: float = 0.3,
    settle: float = 0.1,
    max_runs: int | None = None,
    timeout: float | None = None,
    on_error: Callable[[QuadnodesError], None] | None = None,
    sleep: Callable[[float], None] = time.sleep,
) -> WatchState:
    """Call ``run_once`` now and again whenever a watched file changes.

    Parameters
    ----------
    graph_path : path-like
        The graph file.
    run_once : callable
        Loads and runs the graph; returns the loaded :class:`Graph` (to learn which
        files it reads) or ``None``. A :class:`QuadnodesError` it raises is passed
        to ``on_error`` and watching goes on (a broken edit does not stop it).
    interval : float
        Seconds between polls.
    settle : float
        Seconds to wait after a change before running, so a save in several
        writes is read whole.
    max_runs, timeout : optional
        Stop after this many runs or seconds (for tests); by default watch until
        interrupted (Ctrl-C raises ``KeyboardInterrupt`` to the caller).

    Returns
    -------
    WatchState
    """
    state = WatchState()
    start = time.monotonic()
    graph: Graph | None = None

    def once() -> dict[Path, Stamp]:
        """Run, and return the stamps of the watched files as they were when the run *started*.

        An edit saved while the run is in progress then differs from these stamps
        and triggers the next run; stamps taken after the run would hide it.
        """
        nonlocal graph
        before = snapshot(watched_files(graph_path, graph))
        state.runs += 1
        try:
            g = run_once()
            if g is not None:
                graph = g
        except QuadnodesError as exc:
            state.errors += 1
            if on_error is not None:
                on_error(exc)
        files = watched_files(graph_path, graph)
        new = [f for f in files if f not in before]  # named by the edit just run: stamp them now
        return {**{f: before[f] for f in files if f in before}, **snapshot(new)}

    stamps = once()
    while (max_runs is None or state.runs < max_runs) and (timeout is None or time.monotonic() - start < timeout):
        now = snapshot(stamps)
        if now != stamps:
            sleep(settle)
            stamps = once()
            continue
        sleep(interval)
    return state
