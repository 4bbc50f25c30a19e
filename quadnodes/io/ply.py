"""Polygon File Format (PLY, ASCII or binary) read with the quads kept, through meshio.

meshio keeps every face with its own number of corners (blocks of ``quad``,
``triangle`` and ``polygon`` cells in file order), so no quad is triangulated.
PLY states no unit; pass ``unit=``.
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

__all__ = ["load_ply"]


def load_ply(
    path: str | os.PathLike[str],
    *,
    non_quads: Literal["error", "drop", "split"] = "error",
    unit: str = DEFAULT_UNIT,
) -> QuadMesh:
    """Read a quad mesh from a PLY file (ASCII, binary little- or big-endian).

    Parameters
    ----------
    path : str or path-like
    non_quads : {"error", "drop", "split"}
        What to do with a face that is not a quad, as in :func:`quadnodes.io.obj.parse_obj`;
        faces are numbered in file order in messages.
    unit : str
        The unit of the coordinates, one of :data:`quadnodes.units.UNITS`.

    Returns
    -------
    QuadMesh
        Coordinates as float64 (a ``float`` PLY gives the float32 values exactly).

    Raises
    ------
    InputError
        If the file is missing or not a PLY meshio can read (the message names
        the file and meshio's reason), has no faces, or a face that is not a quad.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "q.ply"
    >>> _ = p.write_text("ply\\nformat ascii 1.0\\nelement vertex 4\\nproperty double x\\nproperty double y\\n"
    ...     "property double z\\nelement face 1\\nproperty list uchar int vertex_indices\\nend_header\\n"
    ...     "0 0 0\\n1 0 0\\n1 1 0\\n0 1 0\\n4 0 1 2 3\\n")
    >>> load_ply(p).faces.tolist()
    [[0, 1, 2, 3]]
    """
    import meshio

    unit = check_unit(unit)
    p = Path(os.fspath(path))
    if not p.is_file():
        raise InputError(f"cannot read {str(p)!r}: no such file")
    try:
        data = meshio.read(p, file_format="ply")
    except SystemExit as exc:  # meshio ends the process on some unreadable files
        raise InputError(f"{p}: not a PLY file meshio can read (meshio stopped with exit status {exc.code})") from None
    except Exception as exc:  # meshio raises many kinds (ReadError, IndexError, ValueError, ...)
        raise InputError(f"{p}: not a PLY file meshio can read ({type(exc).__name__}: {exc})") from exc
    points = np.asarray(data.points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] < 3:
        raise InputError(f"{p}: vertices need x, y and z (got {points.shape[1] if points.ndim == 2 else 0} coordinates)")
    blocks = []
    start = 0
    for cell in data.cells:
        c = np.asarray(cell.data, dtype=np.int64)
        if cell.type not in ("triangle", "quad", "polygon", "line", "vertex"):
            raise InputError(f"{p}: unexpected cell type {cell.type!r}")
        c = c.reshape(len(c), -1)
        blocks.append((c, start + np.arange(len(c))))
        start += len(c)
    if start == 0:
        raise InputError(f"{p}: no faces found ({len(points)} vertices)")
    faces = quads_from_blocks(blocks, non_quads=non_quads, name=str(p))
    if len(faces) == 0:
        raise InputError(f"{p}: no quad faces found ({len(points)} vertices)")
    if faces.min() < 0 or faces.max() >= len(points):
        bad = int(np.argmax((faces < 0).any(axis=1) | (faces >= len(points)).any(axis=1)))
        raise InputError(f"{p}: quad {bad} has a vertex index out of range (the file has {len(points)} vertices)")
    try:
        return QuadMesh(points[:, :3], faces, unit=unit)
    except InputError as exc:
        raise InputError(f"{p}: {exc}") from None
