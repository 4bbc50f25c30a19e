"""Reading and writing quad meshes and their panels.

Each format has a pure function that builds the content and a thin one that
writes it atomically (temporary file in the target folder, then ``os.replace``),
returning the path:

- ``obj``: :func:`~.obj.obj_text` / :func:`~.obj.save_obj`; read with :func:`~.obj.load_obj`.
- ``json``: :func:`~.json_mesh.mesh_to_json` / :func:`~.json_mesh.save_json`; read with
  :func:`~.json_mesh.load_json`.
- ``csv`` (panel schedule, write only): :func:`~.schedule.schedule_csv` /
  :func:`~.schedule.save_schedule`.
- ``step`` / ``stp`` (write only; read with ``build123d.import_step``):
  :func:`~.step.step_panels` / :func:`~.step.save_step` (:func:`~.step.write_step`
  also returns a :class:`~.step.StepReport`).
- ``3dm`` (Rhino): :func:`~.rhino.model_3dm` / :func:`~.rhino.save_3dm`; read with :func:`~.rhino.load_3dm`.
- ``dxf`` (flat unrolls, write only): :func:`~.dxf.dxf_document` / :func:`~.dxf.save_dxf`.
- ``off``, ``ply`` (read only): :func:`~.off.load_off`, :func:`~.ply.load_ply`.

Which panels are planar is :func:`quadnodes.flatness.planar_panels` for every
writer (one ``planar_tolerance``: relative, or a length such as ``"2 mm"``).

:func:`save` and :func:`load` pick the format from the file extension (or an
explicit ``file_type``) through the :data:`EXPORTERS` and :data:`LOADERS`
tables. build123d is imported only when a STEP file is written.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..mesh import QuadMesh
from .json_mesh import load_json, mesh_to_json, save_json
from .obj import load_obj, obj_text, parse_obj, save_obj
from .panels import panel_labels
from .schedule import panel_schedule, save_schedule, schedule_csv
from .step import StepReport, save_step, step_panels, step_shape, write_step
from .dxf import dxf_report, panel_distortion, save_dxf, unfold
from .off import load_off
from .ply import load_ply
from .rhino import load_3dm, model_3dm, save_3dm

__all__ = [
    "EXPORTERS",
    "LOADERS",
    "save",
    "load",
    "save_obj",
    "load_obj",
    "save_json",
    "load_json",
    "save_schedule",
    "save_step",
    "step_shape",
    "step_panels",
    "write_step",
    "StepReport",
    "obj_text",
    "parse_obj",
    "mesh_to_json",
    "schedule_csv",
    "panel_schedule",
    "panel_labels",
    "save_3dm",
    "load_3dm",
    "model_3dm",
    "save_dxf",
    "dxf_report",
    "unfold",
    "panel_distortion",
    "load_off",
    "load_ply",
]

EXPORTERS: dict[str, Callable[..., Path]] = {
    "obj": save_obj,
    "json": save_json,
    "csv": save_schedule,
    "step": save_step,
    "stp": save_step,
    "3dm": save_3dm,
    "dxf": save_dxf,
}
"""File type -> writer ``f(mesh, path, **options) -> Path``."""

LOADERS: dict[str, Callable[..., QuadMesh]] = {
    "obj": load_obj,
    "json": load_json,
    "3dm": load_3dm,
    "off": load_off,
    "ply": load_ply,
}
"""File type -> reader ``f(path, **options) -> QuadMesh``."""


def _file_type(path: str | os.PathLike[str], file_type: str | None, table: dict[str, Any], what: str) -> str:
    if file_type is None:
        suffix = Path(os.fspath(path)).suffix
        if not suffix:
            raise InputError(f"file_type: {str(path)!r} has no extension; pass file_type= one of {sorted(table)}")
        file_type = suffix[1:]
    key = str(file_type).lower().lstrip(".")
    if key not in table:
        raise InputError(f"file_type: cannot {what} {key!r} files; known types: {', '.join(sorted(table))}")
    return key


def save(mesh: QuadMesh, path: str | os.PathLike[str], *, file_type: str | None = None, **options: Any) -> Path:
    """Write ``mesh`` in the format named by ``file_type`` or the extension of ``path``.

    Parameters
    ----------
    mesh : QuadMesh
    path : str or path-like
    file_type : str, optional
        One of :data:`EXPORTERS` (``obj``, ``json``, ``csv``, ``step``, ``stp``, ``3dm``, ``dxf``);
        default: the extension of ``path``.
    **options
        Passed to the writer, e.g. ``mode="assembly"`` for STEP.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        On an unknown file type or option.
    ExportError
        As the writer (nothing is left behind on failure).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from quadnodes.mesh import grid
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> load(save(grid(3, 3), folder / "g.json")).n_faces
    4
    >>> save(grid(3, 3), folder / "g.ply")
    Traceback (most recent call last):
      ...
    quadnodes.errors.InputError: file_type: cannot write 'ply' files; known types: 3dm, csv, dxf, json, obj, step, stp
    """
    key = _file_type(path, file_type, EXPORTERS, "write")
    try:
        return EXPORTERS[key](mesh, path, **options)
    except TypeError as exc:
        if "unexpected keyword argument" in str(exc):
            raise InputError(f"{key} writer: {exc}") from None
        raise


def load(path: str | os.PathLike[str], *, file_type: str | None = None, renumber_grid: bool = True,
         **options: Any) -> QuadMesh:
    """Read a mesh in the format named by ``file_type`` or the extension of ``path``.

    Parameters
    ----------
    path : str or path-like
    file_type : str, optional
        One of :data:`LOADERS` (``obj``, ``json``, ``3dm``, ``off``, ``ply``); default: the extension.
    renumber_grid : bool
        A mesh whose connectivity is a vertex grid but whose faces and vertices come
        in any order (Rhino, COMPAS) is renumbered row by row and gets its
        ``grid_shape`` (:func:`quadnodes.topology.as_grid`); False keeps the file's numbering.
    **options
        Passed to the reader, e.g. ``non_quads="drop"`` for OBJ.

    Raises
    ------
    InputError
        On an unknown file type or option, or as the reader (naming file and line).
    """
    key = _file_type(path, file_type, LOADERS, "read")
    if not isinstance(renumber_grid, bool):
        raise InputError(f"renumber_grid: expected True or False, got {renumber_grid!r}")
    try:
        mesh = LOADERS[key](path, **options)
        if renumber_grid:
            from ..topology import as_grid

            mesh = as_grid(mesh) or mesh
        return mesh
    except TypeError as exc:
        if "unexpected keyword argument" in str(exc):
            raise InputError(f"{key} reader: {exc}") from None
        raise
