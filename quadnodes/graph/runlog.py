"""A note of the last complete run of a graph file, so an unchanged graph is recognised without loading nodes.

``quadnodes run`` of a graph whose every result is in the disk cache still had to
import every node's library (NumPy, SciPy, …) just to compute the cache keys —
most of its time. After a complete run it now leaves a note in the cache folder
(``runs/<signature>.json``): the run's records and the digests of every file the
graph read or wrote. The signature covers everything a cache key depends on
that can change without these files changing: the graph file's bytes and
absolute path (relative paths resolve against it), the output folder, the
``--set`` overrides, the quadnodes sources (which hold the node functions) and
the Python version. A later run with the same signature whose files still have
the same digests and whose cache entries are all still there is the same run:
every node would come from the cache, so nothing needs to be loaded.

Any difference — an edited graph, a changed input file, a written file that was
changed or deleted, a cleared cache, another quadnodes version — and the note is
simply not used. Reading a note runs no code (JSON).
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from ..io._atomic import write_text_atomic
from .fingerprint import canonical_json, file_digest, package_digest

__all__ = ["signature", "note", "replay"]

_FORMAT = "quadnodes-run-note"


def signature(graph_path: str | os.PathLike[str], *, out: str | os.PathLike[str],
              overrides: Mapping[str, Any]) -> str | None:
    """sha256 of what a run depends on besides the files it reads and writes; None if the graph is unreadable.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "g.toml"
    >>> _ = p.write_text('format = "quadnodes-graph"')
    >>> a = signature(p, out="out", overrides={})
    >>> a == signature(p, out="out", overrides={}), a == signature(p, out="out", overrides={"x.y": 1})
    (True, False)
    """
    p = Path(graph_path).resolve()
    try:
        text = p.read_bytes()
    except OSError:
        return None
    h = hashlib.sha256(f"{_FORMAT}\0{sys.version}\0{package_digest()}\0".encode())
    h.update(f"{p}\0{Path(out).resolve()}\0{canonical_json(dict(overrides))}\0".encode())
    h.update(text)
    return h.hexdigest()


def _path(cache_dir: Path, sig: str) -> Path:
    return Path(cache_dir) / "runs" / f"{sig}.json"


def note(cache_dir: str | os.PathLike[str], sig: str, *, records: Iterable[Any],
         files: Iterable[str | os.PathLike[str]], written: Iterable[str | os.PathLike[str]] = (),
         notes: Iterable[str] = ()) -> Path | None:
    """Write the note of a complete run (``records``: :class:`RunRecord`; ``files``: every path read or
    written; ``written``: the written ones, in the order the CLI lists them; ``notes``: the run summary's
    notes, shown again by a replay).

    Returns None (and writes nothing) when a node has no cache key or a file cannot be digested.
    """
    recs = [[r.id, r.op, r.status, r.seconds, r.key] for r in records]
    if any(r[4] is None for r in recs):
        return None
    digests = {}
    for f in files:
        d = file_digest(f)
        if d is None:
            return None
        digests[str(Path(f).resolve())] = d
    body = {"format": _FORMAT, "signature": sig, "records": recs, "files": digests,
            "written": [str(Path(w).resolve()) for w in written], "notes": [str(n) for n in notes]}
    path = _path(Path(cache_dir), sig)
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_text_atomic(path, json.dumps(body, sort_keys=True) + "\n")


def replay(cache_dir: str | os.PathLike[str], sig: str | None
           ) -> tuple[list[tuple[str, str, str]], list[str]] | None:
    """``([(id, op, key), ...], written paths)`` of the noted run when it still holds (see the module
    docstring), else None. The run's notes: :func:`replay_notes`."""
    if sig is None:
        return None
    path = _path(Path(cache_dir), sig)
    try:
        body = json.loads(path.read_text(encoding="utf-8"))
        if body.get("format") != _FORMAT or body.get("signature") != sig:
            return None
        recs = [(str(r[0]), str(r[1]), str(r[4])) for r in body["records"]]
        files = dict(body["files"])
        written = [str(w) for w in body["written"]]
    except (OSError, ValueError, KeyError, TypeError, IndexError):
        return None
    for f, d in files.items():
        if file_digest(f) != d:
            return None
    for _, _, key in recs:
        if not (Path(cache_dir) / key[:2] / f"{key}.npz").is_file():
            return None
    return recs, written


def replay_notes(cache_dir: str | os.PathLike[str], sig: str | None) -> list[str]:
    """The run summary's notes of the noted run (empty when there is none)."""
    if sig is None:
        return []
    try:
        body = json.loads(_path(Path(cache_dir), sig).read_text(encoding="utf-8"))
        return [str(n) for n in body.get("notes", [])]
    except (OSError, ValueError, TypeError, AttributeError):
        return []
