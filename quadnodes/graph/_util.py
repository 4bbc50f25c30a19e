"""Small helpers shared by the graph modules: error messages (atomic writes live in quadnodes.io._atomic)."""

from __future__ import annotations

import difflib
from collections.abc import Iterable

from ..errors import GraphError

__all__ = ["label", "graph_error", "did_you_mean"]


def label(node_id: str, op: str | None = None) -> str:
    """``node 'fair1' (fair@1)``: how every message names a node.

    Examples
    --------
    >>> label("fair1", "fair@1")
    "node 'fair1' (fair@1)"
    """
    return f"node {node_id!r} ({op})" if op else f"node {node_id!r}"


def graph_error(message: str, *, node_id: str | None = None) -> GraphError:
    """A :class:`GraphError` that remembers the node at fault (``err.node_id``)."""
    err = GraphError(message)
    err.node_id = node_id  # type: ignore[attr-defined]
    return err


def did_you_mean(name: str, choices: Iterable[str], *, kind: str = "") -> str:
    """``"; did you mean 'x'? (kind: a, b)"`` — the closest valid name, then all of them.

    Examples
    --------
    >>> did_you_mean("iteratons", ["iterations", "weight"], kind="settings")
    "; did you mean 'iterations'? (settings: iterations, weight)"
    >>> did_you_mean("zzz", [], kind="settings")
    ' (this node has no settings)'
    """
    options = sorted(choices)
    if not options:
        return f" (this node has no {kind})" if kind else ""
    close = difflib.get_close_matches(name, options, n=1, cutoff=0.6)
    hint = f"; did you mean {close[0]!r}?" if close else ""
    listing = f" ({kind}: {', '.join(options)})" if kind else ""
    return hint + listing
