"""Small helpers shared by the graph modules: error messages, atomic writes."""

from __future__ import annotations

import difflib
import os
import tempfile
from collections.abc import Callable, Iterable
from pathlib import Path

from ..errors import GraphError

__all__ = ["label", "graph_error", "did_you_mean", "write_atomic"]


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


def write_atomic(path: str | os.PathLike[str], write: Callable[[str], None]) -> Path:
    """Write ``path`` through ``write(tmp)``: temporary file in the same folder, then ``os.replace``.

    On any failure the temporary file is removed and the exception propagates;
    an existing file at ``path`` is left as it was.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> p = write_atomic(pathlib.Path(tempfile.mkdtemp()) / "a.txt",
    ...                  lambda tmp: pathlib.Path(tmp).write_text("hi"))
    >>> p.read_text()
    'hi'
    """
    target = Path(os.fspath(path))
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    os.close(fd)
    try:
        mask = os.umask(0o022)
        os.umask(mask)
        os.chmod(tmp, 0o666 & ~mask)
        write(tmp)
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        os.replace(tmp, target)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    return target
