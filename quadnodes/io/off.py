"""Object File Format (OFF, Geomview; libigl's tutorial meshes) read with the quads kept.

meshio's OFF reader accepts triangles only (and ends the process with
``sys.exit`` on anything else), so this module reads the few lines OFF has
itself: an optional ``OFF`` / ``COFF`` / ``NOFF`` / ``CNOFF`` keyword, the counts
``n_vertices n_faces n_edges``, ``n`` vertex lines ``x y z [extra numbers]``,
then ``m`` face lines ``k i_1 ... i_k [colour]`` with 0-based indices. ``#``
starts a comment. OFF states no unit; pass ``unit=``.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Literal

import numpy as np

from ..errors import InputError
from ..mesh import QuadMesh
from ..units import DEFAULT_UNIT, check_unit
from ._polygons import quads_from_blocks

__all__ = ["parse_off", "load_off"]

_KEYWORDS = ("OFF", "COFF", "NOFF", "CNOFF", "STOFF", "STCOFF", "STNOFF")


def parse_off(
    text: str,
    *,
    name: str = "<string>",
    non_quads: Literal["error", "drop", "split"] = "error",
    unit: str = DEFAULT_UNIT,
) -> QuadMesh:
    """Read a quad mesh from OFF text.

    Parameters
    ----------
    text : str
    name : str
        The source in messages (a file name).
    non_quads : {"error", "drop", "split"}
        What to do with a face that is not a quad, as in :func:`quadnodes.io.obj.parse_obj`.
    unit : str
        The unit of the coordinates (OFF has none), one of :data:`quadnodes.units.UNITS`.

    Returns
    -------
    QuadMesh

    Raises
    ------
    InputError
        Naming ``name`` and the line: a missing or malformed count, coordinate
        or index, an index out of range, a face that is not a quad (see
        ``non_quads``), fewer lines than the counts promise.

    Examples
    --------
    >>> m = parse_off("OFF\\n4 1 0\\n0 0 0\\n1 0 0\\n1 1 0\\n0 1 0\\n4 0 1 2 3\\n")
    >>> m.faces.tolist(), m.unit
    ([[0, 1, 2, 3]], 'mm')
    """
    unit = check_unit(unit)
    lines: list[tuple[int, list[str]]] = []
    for number, raw in enumerate(text.lstrip("\ufeff").splitlines(), 1):
        tokens = raw.split("#", 1)[0].split()
        if tokens:
            lines.append((number, tokens))
    if not lines:
        raise InputError(f"{name}: empty OFF file")
    pos = 0
    number, tokens = lines[0]
    if tokens[0].upper() in _KEYWORDS or tokens[0].upper().endswith("OFF"):
        if tokens[0].upper() not in _KEYWORDS:
            raise InputError(f"{name}, line {number}: unsupported OFF variant {tokens[0]!r} (read: {', '.join(_KEYWORDS)})")
        tokens = tokens[1:]
        if not tokens:
            pos = 1
            if len(lines) < 2:
                raise InputError(f"{name}: the counts line 'n_vertices n_faces n_edges' is missing")
            number, tokens = lines[1]
    try:
        n_vertices, n_faces = int(tokens[0]), int(tokens[1])
    except (IndexError, ValueError):
        raise InputError(
            f"{name}, line {number}: expected the counts 'n_vertices n_faces n_edges', got {' '.join(tokens)!r}"
        ) from None
    if n_vertices < 0 or n_faces < 0:
        raise InputError(f"{name}, line {number}: negative count in {' '.join(tokens)!r}")
    pos += 1
    body = lines[pos:]
    if len(body) < n_vertices + n_faces:
        raise InputError(
            f"{name}: the counts promise {n_vertices} vertices and {n_faces} faces, "
            f"but only {len(body)} lines follow the counts (line {number})"
        )
    vlines = body[:n_vertices]
    coords = np.empty((n_vertices, 3))
    for i, (ln, tok) in enumerate(vlines):
        if len(tok) < 3:
            raise InputError(f"{name}, line {ln}: a vertex needs 3 coordinates, got {len(tok)}")
        try:
            coords[i] = (float(tok[0]), float(tok[1]), float(tok[2]))
        except ValueError:
            raise InputError(f"{name}, line {ln}: bad vertex coordinates {' '.join(tok[:3])!r}") from None
    by_size: dict[int, tuple[list[list[int]], list[int]]] = {}
    face_lines = []
    for f, (ln, tok) in enumerate(body[n_vertices : n_vertices + n_faces]):
        try:
            k = int(tok[0])
            idx = [int(t) for t in tok[1 : 1 + k]]
        except ValueError:
            raise InputError(f"{name}, line {ln}: bad face {' '.join(tok)!r}") from None
        if k < 0 or len(idx) < k:
            raise InputError(f"{name}, line {ln}: face says {k} corners but lists {len(idx)}")
        bad = [i for i in idx if not 0 <= i < n_vertices]
        if bad:
            raise InputError(
                f"{name}, line {ln}: vertex index {bad[0]} is out of range (the file has {n_vertices} vertices, 0-based)"
            )
        rows, where = by_size.setdefault(k, ([], []))
        rows.append(idx)
        where.append(f)
        face_lines.append(ln)
    blocks = [
        (np.array(rows, dtype=np.int64).reshape(len(rows), k), np.array(where)) for k, (rows, where) in by_size.items()
    ]
    try:
        faces = quads_from_blocks(blocks, non_quads=non_quads, name=name)
    except InputError as exc:
        raise InputError(_face_line(str(exc), face_lines)) from None
    if len(faces) == 0:
        raise InputError(f"{name}: no quad faces found ({n_vertices} vertices, {n_faces} faces)")
    try:
        return QuadMesh(coords, faces, unit=unit)
    except InputError as exc:
        raise InputError(f"{name}: {exc}") from None


def _face_line(message: str, face_lines: list[int]) -> str:
    """Add the file line to a ``face k`` message."""
    import re

    m = re.search(r"\bface (\d+)\b", message)
    if m and int(m.group(1)) < len(face_lines):
        return message.replace(m.group(0), f"{m.group(0)} (line {face_lines[int(m.group(1))]})", 1)
    return message


def load_off(
    path: str | os.PathLike[str],
    *,
    non_quads: Literal["error", "drop", "split"] = "error",
    unit: str = DEFAULT_UNIT,
) -> QuadMesh:
    """Read a quad mesh from an OFF file; see :func:`parse_off`.

    Raises
    ------
    InputError
        If the file cannot be read, or as :func:`parse_off`.
    """
    p = Path(os.fspath(path))
    try:
        text = p.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise InputError(f"cannot read {str(p)!r}: {exc}") from exc
    return parse_off(text, name=str(p), non_quads=non_quads, unit=unit)
