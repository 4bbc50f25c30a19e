"""Wavefront OBJ with the quads kept as quads.

trimesh triangulates quads when it loads or exports OBJ, so this module writes
and reads the few statements a quad mesh needs by itself.

Writing: ``v x y z`` lines with shortest round-trip float text (``repr``), so
the coordinates read back bit for bit, and ``f a b c d`` lines with 1-based
indices. A comment ``# quadnodes grid_shape <rows> <cols>`` records the grid
(other readers ignore comments; :func:`load_obj` restores ``grid_shape`` from
it when the faces are still that grid's faces), and ``# quadnodes unit <unit>``
the mesh's unit (OBJ itself has none), which :func:`load_obj` reads back.

The text may start with a byte-order mark and use ``\n``, ``\r\n`` or ``\r``
line ends and tabs between tokens; :func:`load_obj` also reads UTF-16 files
that start with their byte-order mark.

Reading supports ``v`` (the first three numbers; a fourth weight or trailing
vertex colours are ignored), ``f`` with corners written ``a``, ``a/b``,
``a/b/c`` or ``a//c`` (only the vertex index ``a`` is used), negative
(relative) indices, ``#`` comments, blank lines and ``\\`` line continuations.
Every other statement (``vt``, ``vn``, ``g``, ``o``, ``s``, ``usemtl``, ``l``,
...) is skipped.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Literal

import numpy as np

from .. import __version__
from ..errors import InputError
from ..mesh import QuadMesh
from ..units import DEFAULT_UNIT, check_unit
from .. import _validate
from ._atomic import write_text_atomic
from ._polygons import NON_QUAD_OPTIONS

__all__ = ["NON_QUAD_OPTIONS", "obj_text", "save_obj", "parse_obj", "load_obj"]


_GRID_COMMENT = "quadnodes grid_shape"
_UNIT_COMMENT = "quadnodes unit"
_LINE_END = re.compile(r"\r\n|\r|\n")


def obj_text(mesh: QuadMesh, *, header: bool = True) -> str:
    """The OBJ text of ``mesh``, quads kept.

    Parameters
    ----------
    mesh : QuadMesh
    header : bool
        Start with comment lines (generator, counts, the unit, and
        ``grid_shape`` when the mesh has one).

    Returns
    -------
    str
        ``n`` vertex lines, then ``m`` face lines, ``\\n``-terminated.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> print(obj_text(grid(2, 2, spacing=0.5), header=False), end="")
    v 0.0 0.0 0.0
    v 0.5 0.0 0.0
    v 0.0 0.5 0.0
    v 0.5 0.5 0.0
    f 1 2 4 3
    """
    _validate.quad_mesh(mesh)
    parts = []
    if header:
        parts.append(f"# quadnodes {__version__}: {mesh.n_vertices} vertices, {mesh.n_faces} quads\n")
        parts.append(f"# {_UNIT_COMMENT} {mesh.unit}\n")
        if mesh.grid_shape is not None:
            parts.append(f"# {_GRID_COMMENT} {mesh.grid_shape[0]} {mesh.grid_shape[1]}\n")
    # One formatting call per block instead of a Python loop per line; %r gives
    # the shortest text that reads back as the same float.
    parts.append(("v %r %r %r\n" * mesh.n_vertices) % tuple(mesh.vertices.ravel().tolist()))
    parts.append(("f %d %d %d %d\n" * mesh.n_faces) % tuple((mesh.faces + 1).ravel().tolist()))
    return "".join(parts)


def save_obj(mesh: QuadMesh, path: str | os.PathLike[str], *, header: bool = True) -> Path:
    """Write ``mesh`` to an OBJ file atomically (see :func:`obj_text`).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ExportError
        If the path is not writable; no partial or temporary file is left.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from quadnodes.mesh import grid
    >>> p = save_obj(grid(3, 3), pathlib.Path(tempfile.mkdtemp()) / "g.obj")
    >>> load_obj(p).grid_shape
    (3, 3)
    """
    return write_text_atomic(path, obj_text(mesh, header=header))


def _where(name: str, line: int) -> str:
    return f"{name}, line {line}"


def _logical_lines(text: str) -> Iterator[tuple[int, str]]:
    """Yield ``(line_number, content)`` with comments cut and ``\\`` continuations joined."""
    pending = ""
    start = 0
    # only CR, LF and CRLF end a line (str.splitlines also splits at form feeds, U+2028, ...,
    # which would put the line numbers in messages off from what an editor shows)
    for number, raw in enumerate(_LINE_END.split(text), 1):
        if not pending:
            start = number
        line = raw
        if line.rstrip().endswith("\\") and "#" not in line:
            pending += line.rstrip()[:-1] + " "
            continue
        yield start, pending + line
        pending = ""
    if pending:
        yield start, pending


def _with_lines(message: str, face_lines: list[int], vertex_lines: list[int]) -> str:
    """Append the file line of every ``face k`` / ``vertex k`` that ``message`` names."""
    notes = []
    for kind, lines in (("face", face_lines), ("vertex", vertex_lines)):
        for m in re.finditer(rf"\b{kind}s? (\d+)(?: and (\d+))?", message):
            for g in m.groups():
                if g is not None and int(g) < len(lines):
                    notes.append(f"{kind} {g} is on line {lines[int(g)]}")
    return message + (f" ({'; '.join(dict.fromkeys(notes))})" if notes else "")


def parse_obj(
    text: str,
    *,
    name: str = "<string>",
    non_quads: Literal["error", "drop", "split"] = "error",
    unit: str | None = None,
) -> QuadMesh:
    """Read a quad mesh from OBJ text.

    Parameters
    ----------
    text : str
        The OBJ content.
    name : str
        What to call the source in error messages (a file name).
    non_quads : {"error", "drop", "split"}
        What to do with a face that does not have four corners.
        ``"error"`` (default): raise :class:`InputError` naming its line.
        ``"drop"``: skip it (its vertices stay, unreferenced).
        ``"split"``: split a polygon with an even number ``k >= 6`` of corners
        into the fan of ``k/2 - 1`` quads ``(c0, c1, c2, c3), (c0, c3, c4, c5), ...``
        (no new vertices); a triangle or any odd polygon cannot be split into
        quads without new vertices and still raises :class:`InputError`.
    unit : str, optional
        The unit of the coordinates. Default: the ``# quadnodes unit`` comment,
        else ``"mm"``. A unit given here that contradicts the comment is an error.

    Returns
    -------
    QuadMesh
        With ``grid_shape`` when the text carries a ``# quadnodes grid_shape``
        comment that matches its vertices and faces, and its ``unit``.

    Raises
    ------
    InputError
        Naming ``name`` and the line: a malformed number or index, an index of
        0 or out of range, a face with fewer than four corners or too many (see
        ``non_quads``), no faces at all, a ``unit`` that contradicts the file's;
        or a mesh that :class:`QuadMesh` rejects (the message then names the
        offending faces' lines).

    Examples
    --------
    >>> m = parse_obj("v 0 0 0\\nv 1 0 0\\nv 1 1 0\\nv 0 1 0\\nf 1/1/1 2/2/2 -2//3 -1\\n")
    >>> m.faces.tolist()
    [[0, 1, 2, 3]]
    >>> parse_obj("v 0 0 0\\nv 1 0 0\\nv 0 1 0\\nf 1 2 3\\n", name="tri.obj")
    Traceback (most recent call last):
      ...
    quadnodes.errors.InputError: tri.obj, line 4: face with 3 corners; only quads are supported (non_quads='drop' skips such faces, 'split' splits even polygons)
    """
    mode = _validate.choice(non_quads, NON_QUAD_OPTIONS, "non_quads")
    coords: list[tuple[str, str, str]] = []
    vertex_lines: list[int] = []
    faces: list[list[int]] = []
    face_lines: list[int] = []
    forward: list[tuple[int, int]] = []  # (line, index) of positive indices past the end
    grid_shape: tuple[int, int] | None = None
    file_unit: tuple[int, str] | None = None

    for number, line in _logical_lines(text.removeprefix("\ufeff")):
        stripped = line.strip()
        if stripped.startswith("#"):
            body = stripped[1:].split()
            if len(body) == 4 and " ".join(body[:2]) == _GRID_COMMENT:
                try:
                    grid_shape = (int(body[2]), int(body[3]))
                except ValueError:
                    grid_shape = None
            elif len(body) == 3 and " ".join(body[:2]) == _UNIT_COMMENT:
                file_unit = (number, check_unit(body[2], f"{_where(name, number)}: unit"))
            continue
        tokens = stripped.split("#", 1)[0].split()
        if not tokens:
            continue
        key = tokens[0]
        if key == "v":
            if len(tokens) < 4:
                raise InputError(f"{_where(name, number)}: a vertex needs 3 coordinates, got {len(tokens) - 1}")
            coords.append((tokens[1], tokens[2], tokens[3]))
            vertex_lines.append(number)
        elif key == "f":
            corners = []
            n_so_far = len(coords)
            for tok in tokens[1:]:
                head = tok.split("/", 1)[0]
                try:
                    idx = int(head)
                except ValueError:
                    raise InputError(f"{_where(name, number)}: bad vertex index {tok!r}") from None
                if idx > 0:
                    if idx > n_so_far:
                        forward.append((number, idx))
                    corners.append(idx - 1)
                elif idx < 0:
                    if -idx > n_so_far:
                        raise InputError(
                            f"{_where(name, number)}: relative index {idx} points before the first "
                            f"vertex ({n_so_far} vertices defined so far)"
                        )
                    corners.append(n_so_far + idx)
                else:
                    raise InputError(f"{_where(name, number)}: vertex index 0 (OBJ indices start at 1)")
            k = len(corners)
            if k == 4:
                faces.append(corners)
                face_lines.append(number)
            elif k < 3:
                raise InputError(f"{_where(name, number)}: a face needs at least 3 corners, got {k}")
            elif mode == "drop":
                continue
            elif mode == "split" and k % 2 == 0:
                for s in range(1, k - 2, 2):
                    faces.append([corners[0], corners[s], corners[s + 1], corners[s + 2]])
                    face_lines.append(number)
            else:
                extra = (
                    "an odd polygon cannot be split into quads without new vertices"
                    if mode == "split"
                    else "only quads are supported (non_quads='drop' skips such faces, "
                    "'split' splits even polygons)"
                )
                raise InputError(f"{_where(name, number)}: face with {k} corners; {extra}")

    n = len(coords)
    for number, idx in forward:
        if idx > n:
            raise InputError(f"{_where(name, number)}: vertex index {idx} is out of range (the file has {n} vertices)")
    if not faces:
        raise InputError(f"{name}: no quad faces found ({n} vertices)")
    try:
        vertices = np.array(coords, dtype=np.float64)
    except ValueError:
        for number, row in zip(vertex_lines, coords):
            try:
                [float(c) for c in row]
            except ValueError:
                raise InputError(f"{_where(name, number)}: bad vertex coordinates {' '.join(row)!r}") from None
        raise  # pragma: no cover - np.array failed but every float() succeeded
    face_array = np.array(faces, dtype=np.int64)
    if unit is None:
        unit = DEFAULT_UNIT if file_unit is None else file_unit[1]
    else:
        unit = check_unit(unit)
        if file_unit is not None and file_unit[1] != unit:
            raise InputError(
                f"unit: {unit!r} given, but {_where(name, file_unit[0])} says the file is in {file_unit[1]!r}; "
                "leave unit unset to use the file's (convert afterwards with mesh.with_unit)"
            )
    if grid_shape is not None:
        r, c = grid_shape
        if not (r >= 2 and c >= 2 and r * c == n and _validate.grid_wrap(face_array, r, c) is not None):
            grid_shape = None
    try:
        return QuadMesh(vertices, face_array, grid_shape=grid_shape, unit=unit)
    except InputError as exc:
        raise InputError(f"{name}: {_with_lines(str(exc), face_lines, vertex_lines)}") from None


def load_obj(
    path: str | os.PathLike[str],
    *,
    non_quads: Literal["error", "drop", "split"] = "error",
    unit: str | None = None,
) -> QuadMesh:
    """Read a quad mesh from an OBJ file; see :func:`parse_obj`.

    UTF-8 (with or without a byte-order mark) or UTF-16 with its byte-order mark.

    Raises
    ------
    InputError
        If the file cannot be read, or as :func:`parse_obj` (messages start
        with the file path and line number).
    """
    p = Path(os.fspath(path))
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read {str(p)!r}: {exc}") from exc
    return parse_obj(_decode(data, str(p)), name=str(p), non_quads=non_quads, unit=unit)


def _decode(data: bytes, name: str) -> str:
    """Text of an OBJ file: UTF-16 when it starts with a UTF-16 byte-order mark, else UTF-8 (BOM dropped)."""
    import codecs

    if data.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        try:
            return data.decode("utf-16")
        except UnicodeDecodeError as exc:
            raise InputError(f"{name}: starts with a UTF-16 byte-order mark but is not UTF-16 ({exc})") from None
    return data.decode("utf-8-sig", errors="replace")
