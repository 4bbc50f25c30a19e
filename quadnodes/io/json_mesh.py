"""JSON round trip of a :class:`~quadnodes.mesh.QuadMesh`.

The document is an object with a format tag and version first, then the mesh::

    {
      "format": "quadnodes.QuadMesh",
      "version": 1,
      "grid_shape": [rows, cols] or null,
      "unit": "mm" (optional; one of quadnodes.units.UNITS),
      "vertices": [
        [x, y, z],
        ...
      ],
      "faces": [
        [a, b, c, d],
        ...
      ]
    }

One vertex or face per line, so files diff well. Floats are written with
Python's shortest round-trip text (``repr``), so a mesh reads back bit for bit.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..mesh import QuadMesh
from ..units import DEFAULT_UNIT
from .. import _validate
from ._atomic import write_text_atomic

__all__ = ["JSON_FORMAT", "JSON_VERSION", "mesh_to_json", "save_json", "mesh_from_json", "load_json"]

JSON_FORMAT = "quadnodes.QuadMesh"
"""Value of the ``"format"`` key."""
JSON_VERSION = 1
"""Current value of the ``"version"`` key; readers accept this version and older."""


def mesh_to_json(mesh: QuadMesh) -> str:
    """The JSON text of ``mesh``.

    Returns
    -------
    str
        A JSON object (see the module documentation), ``\\n``-terminated.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> print(mesh_to_json(grid(2, 2, spacing=0.1)), end="")
    {
      "format": "quadnodes.QuadMesh",
      "version": 1,
      "grid_shape": [2, 2],
      "unit": "mm",
      "vertices": [
        [0.0, 0.0, 0.0],
        [0.1, 0.0, 0.0],
        [0.0, 0.1, 0.0],
        [0.1, 0.1, 0.0]
      ],
      "faces": [
        [0, 1, 3, 2]
      ]
    }
    """
    _validate.quad_mesh(mesh)
    gs = "null" if mesh.grid_shape is None else f"[{mesh.grid_shape[0]}, {mesh.grid_shape[1]}]"
    # The mesh guarantees finite floats, whose repr is valid JSON.
    verts = ",\n".join(("    [%r, %r, %r]",) * mesh.n_vertices) % tuple(mesh.vertices.ravel().tolist())
    faces = ",\n".join(("    [%d, %d, %d, %d]",) * mesh.n_faces) % tuple(mesh.faces.ravel().tolist())
    return (
        "{\n"
        f'  "format": {json.dumps(JSON_FORMAT)},\n'
        f'  "version": {JSON_VERSION},\n'
        f'  "grid_shape": {gs},\n'
        f'  "unit": {json.dumps(mesh.unit)},\n'
        f'  "vertices": [\n{verts}\n  ],\n'
        f'  "faces": [\n{faces}\n  ]\n'
        "}\n"
    )


def save_json(mesh: QuadMesh, path: str | os.PathLike[str]) -> Path:
    """Write ``mesh`` to a JSON file atomically (see :func:`mesh_to_json`).

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
    >>> m = grid(3, 4, height=[[0.1] * 4] * 3)
    >>> back = load_json(save_json(m, pathlib.Path(tempfile.mkdtemp()) / "m.json"))
    >>> bool((back.vertices == m.vertices).all()), back.grid_shape
    (True, (3, 4))
    """
    return write_text_atomic(path, mesh_to_json(mesh))


def mesh_from_json(text: str, *, name: str = "<string>") -> QuadMesh:
    """Read a mesh from the JSON text written by :func:`mesh_to_json`.

    Parameters
    ----------
    text : str
    name : str
        What to call the source in error messages (a file name).

    Raises
    ------
    InputError
        Naming ``name``: invalid JSON (with line and column), not a quadnodes
        mesh document, a version newer than :data:`JSON_VERSION`, a missing or
        malformed key, or a mesh that :class:`QuadMesh` rejects.

    Examples
    --------
    >>> mesh_from_json('{"format": "quadnodes.QuadMesh", "version": 1,\\n"vertices": [}', name="m.json")
    Traceback (most recent call last):
      ...
    quadnodes.errors.InputError: m.json, line 2 column 14: invalid JSON: Expecting value
    """
    try:
        doc: Any = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"{name}, line {exc.lineno} column {exc.colno}: invalid JSON: {exc.msg}") from None
    if not isinstance(doc, dict) or doc.get("format") != JSON_FORMAT:
        got = doc.get("format") if isinstance(doc, dict) else type(doc).__name__
        raise InputError(f"{name}: not a quadnodes mesh (expected \"format\": {JSON_FORMAT!r}, got {got!r})")
    version = doc.get("version")
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise InputError(f"{name}: \"version\" must be a positive integer, got {version!r}")
    if version > JSON_VERSION:
        raise InputError(
            f"{name}: format version {version} is newer than this reader ({JSON_VERSION}); "
            "update quadnodes"
        )
    for key in ("vertices", "faces"):
        if not isinstance(doc.get(key), list):
            raise InputError(f"{name}: \"{key}\" must be a list, got {type(doc.get(key)).__name__}")
    gs = doc.get("grid_shape")
    if gs is not None and not (
        isinstance(gs, list) and len(gs) == 2 and all(isinstance(x, int) and not isinstance(x, bool) for x in gs)
    ):
        raise InputError(f"{name}: \"grid_shape\" must be null or [rows, cols], got {gs!r}")
    try:
        return QuadMesh(doc["vertices"], doc["faces"], grid_shape=None if gs is None else tuple(gs),
                        unit=doc.get("unit", DEFAULT_UNIT))
    except InputError as exc:
        raise InputError(f"{name}: {exc}") from None


def load_json(path: str | os.PathLike[str]) -> QuadMesh:
    """Read a mesh from a JSON file written by :func:`save_json`.

    Raises
    ------
    InputError
        If the file cannot be read, or as :func:`mesh_from_json` (messages
        start with the file path).
    """
    p = Path(os.fspath(path))
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read {str(p)!r}: {exc}") from exc
    return mesh_from_json(text, name=str(p))
