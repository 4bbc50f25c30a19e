"""Panel schedule: one CSV row per quad panel, for fabrication and costing.

Every column name that holds a quantity carries its unit: ``<u>`` below is the
mesh's unit (:attr:`quadnodes.mesh.QuadMesh.unit`, e.g. ``mm``), so a mesh in
millimetres gives ``area_mm2``, ``edge_01_mm``, ``planarity_mm``.

``panel``
    Label: ``P_<row>_<col>`` on a grid, else ``P_<face index>`` (the STEP label).
``face``
    Face index in the mesh.
``row``, ``col``
    Grid row and column of the face's cell (smallest row and column of its
    vertices; across the seam of a cylinder or torus grid the last column or row,
    :func:`quadnodes.io.panels.panel_rows_cols`); empty without ``grid_shape``.
``x0_<u>, y0_<u>, z0_<u>, ... x3_<u>, y3_<u>, z3_<u>``
    The four corners in face order (counter-clockwise), as in the mesh.
``area_<u>2``
    Area of the panel's bilinear patch (:func:`quadnodes.io.panels.bilinear_area`),
    the surface the STEP file holds; for a planar convex panel the polygon area.
``edge_01_<u>, edge_12_<u>, edge_23_<u>, edge_30_<u>``
    Edge lengths, from corner ``k`` to corner ``k+1``.
``planarity_rel``
    Distance between the two diagonal lines / mean diagonal length (scale-free,
    0 when planar): what a number ``planar_tolerance`` is compared with.
``planarity_<u>``
    The same distance as a length: what a ``planar_tolerance`` such as
    ``"2 mm"`` is compared with.
``angle_defect_rad``
    The thesis's angle-sum defect in radians (``<= 0``).
``kind``
    The planar flag: ``planar`` when :func:`quadnodes.flatness.planar_panels`
    says so (the test every exporter uses, so the STEP file has a plane face
    exactly for these rows), ``bilinear`` otherwise, ``degenerate`` for a panel
    with a zero-length edge or zero area (no exporter can make a face of it).
``corner_move_<u>``
    How far each corner of the panel moves when an exporter flattens it (half
    its diagonal distance for a planar panel, 0 otherwise), the STEP file's
    corner move.

Extra columns (e.g. an exporter's own per-panel number) are appended with
``extra={"name_<u>": values}``; a name ending in ``_<u>`` or ``_<u>2`` is printed
as a length or area, ``_rel``/``_rad`` with four significant digits.

Numbers are printed for fabrication (``precision="rounded"``, the default):
lengths and areas to 0.001 mm (3 decimals in mm, 6 in m, …), relative values and
angles to four significant digits. ``precision="full"`` prints every number
with Python's shortest round-trip text (exact). Cells that have no value
(``row`` without a grid, planarity of a degenerate panel) are empty.
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from .. import _validate
from ..errors import InputError
from ..flatness import DEFAULT_PLANAR_TOLERANCE, angle_defect, diagonal_distance, planar_panels
from ..mesh import QuadMesh
from ..units import UNITS
from ._atomic import write_text_atomic
from .panels import bilinear_area, corner_moves, degenerate_panels, edge_lengths, panel_labels, panel_rows_cols

__all__ = ["SCHEDULE_COLUMNS", "PRECISIONS", "schedule_columns", "panel_schedule", "schedule_csv", "save_schedule"]

PRECISIONS: tuple[str, ...] = ("rounded", "full")
"""The values of ``precision``."""

_EDGES = ("01", "12", "23", "30")
_RENAMED = {"planar_tol": "planar_tolerance"}


def schedule_columns(unit: str = "mm") -> tuple[str, ...]:
    """Column names of the schedule of a mesh in ``unit``, in order.

    Examples
    --------
    >>> schedule_columns("m")[16:20]
    ('area_m2', 'edge_01_m', 'edge_12_m', 'edge_23_m')
    """
    u = unit
    return (
        ("panel", "face", "row", "col")
        + tuple(f"{a}{k}_{u}" for k in range(4) for a in "xyz")
        + (f"area_{u}2",)
        + tuple(f"edge_{e}_{u}" for e in _EDGES)
        + ("planarity_rel", f"planarity_{u}", "angle_defect_rad", "kind", f"corner_move_{u}")
    )


SCHEDULE_COLUMNS: tuple[str, ...] = schedule_columns("mm")
"""Column names of the schedule of a mesh in millimetres (see :func:`schedule_columns`)."""


def _refuse(renamed: dict[str, Any], where: str) -> None:
    for key in renamed:
        if key in _RENAMED:
            raise InputError(f"{where}: {key!r} was renamed; use {_RENAMED[key]!r}")
        raise InputError(f"{where}: unexpected keyword argument {key!r}")


def panel_schedule(
    mesh: QuadMesh,
    *,
    planar_tolerance: float | str = DEFAULT_PLANAR_TOLERANCE,
    extra: Mapping[str, ArrayLike] | None = None,
    **renamed: Any,
) -> dict[str, list]:
    """The schedule's columns as lists of numbers (full precision; ``None`` for an empty cell).

    Parameters
    ----------
    mesh : QuadMesh
    planar_tolerance : float or str
        Relative diagonal distance (a number, default ``1e-3``) or a length
        (``"2 mm"``) up to which a panel is ``planar``, as in every exporter.
    extra : mapping of str to (m,) array, optional
        Further per-panel columns, appended after the standard ones in order.

    Returns
    -------
    dict
        ``{column: list of m values}`` for every name in
        :func:`schedule_columns` ``(mesh.unit)``, then the ``extra`` names.

    Raises
    ------
    InputError
        On a bad ``planar_tolerance``, an ``extra`` column of the wrong length
        or with a standard column's name, or the old keyword ``planar_tol``.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> s = panel_schedule(grid(2, 3, spacing=2.0, height=[[0, 0, 0], [0, 0, 1]]))
    >>> s["panel"], s["area_mm2"][0], s["kind"]
    (['P_0_0', 'P_0_1'], 4.0, ['planar', 'bilinear'])
    """
    _refuse(renamed, "panel_schedule")
    _validate.quad_mesh(mesh)
    u = mesh.unit
    planar = planar_panels(mesh, planar_tolerance)
    degenerate, _ = degenerate_panels(mesh)
    planar &= ~degenerate
    m = mesh.n_faces
    cols: dict[str, list] = {"panel": panel_labels(mesh), "face": list(range(m))}
    rc = panel_rows_cols(mesh)
    cols["row"] = [None] * m if rc is None else rc[0].tolist()
    cols["col"] = [None] * m if rc is None else rc[1].tolist()
    p = mesh.vertices[mesh.faces]
    for k in range(4):
        for a, axis in zip("xyz", range(3)):
            cols[f"{a}{k}_{u}"] = p[:, k, axis].tolist()
    cols[f"area_{u}2"] = bilinear_area(mesh).tolist()
    edges = edge_lengths(mesh)
    for k, e in enumerate(_EDGES):
        cols[f"edge_{e}_{u}"] = edges[:, k].tolist()
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = diagonal_distance(mesh)
        gap = diagonal_distance(mesh, relative=False)
        defect = angle_defect(mesh)
    for key, values in (("planarity_rel", rel), (f"planarity_{u}", gap), ("angle_defect_rad", defect)):
        ok = np.isfinite(values) & ~degenerate
        cols[key] = [float(v) if good else None for v, good in zip(values.tolist(), ok.tolist())]
    cols["kind"] = np.where(degenerate, "degenerate", np.where(planar, "planar", "bilinear")).tolist()
    cols[f"corner_move_{u}"] = corner_moves(mesh, planar).tolist()
    names = schedule_columns(u)
    out = {key: cols[key] for key in names}
    for key, values in (extra or {}).items():
        if not isinstance(key, str) or not key or key in out:
            raise InputError(f"extra: column name {key!r} is empty, not text, or a standard column's name")
        arr = np.asarray(values)
        if arr.shape != (m,):
            raise InputError(f"extra: column {key!r} must have one value per panel, shape ({m},), got {arr.shape}")
        out[key] = arr.tolist()
    return out


def _decimals(unit: str) -> int:
    """Decimals that resolve 0.001 mm in ``unit`` (mm: 3, cm: 4, m: 6, in: 5, ft: 6)."""
    return max(0, math.ceil(3 + math.log10(UNITS[unit]) - 1e-9))


def _format(name: str, values: list, unit: str, precision: str) -> list:
    """Text of one column: rounded per its unit suffix, or exact (``repr``)."""
    if precision == "full" or not values:
        return values
    if name.endswith((f"_{unit}", f"_{unit}2")):
        d = _decimals(unit)
        return [None if v is None else f"{round(float(v), d) + 0.0:.{d}f}" for v in values]
    if name.endswith(("_rel", "_rad")):
        return [None if v is None else f"{float(v):.4g}" for v in values]
    return values


def schedule_csv(
    mesh: QuadMesh,
    *,
    planar_tolerance: float | str = DEFAULT_PLANAR_TOLERANCE,
    precision: Literal["rounded", "full"] = "rounded",
    extra: Mapping[str, ArrayLike] | None = None,
    **renamed: Any,
) -> str:
    """The panel schedule as CSV text: a header row, then one row per panel.

    Parameters
    ----------
    precision : {"rounded", "full"}
        ``rounded`` (default): lengths to 0.001 mm, relative values and angles to
        four significant digits; ``full``: every number exactly (``repr``).

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> text = schedule_csv(grid(2, 2, spacing=1000.0, height=[[0, 0], [0, 0.5]]))
    >>> text.splitlines()[0].split(",")[:6]
    ['panel', 'face', 'row', 'col', 'x0_mm', 'y0_mm']
    >>> text.splitlines()[1].split(",")[-5:]
    ['0.0001768', '0.250', '-2.5e-07', 'planar', '0.125']
    """
    _refuse(renamed, "schedule_csv")
    precision = _validate.choice(precision, PRECISIONS, "precision")  # type: ignore[assignment]
    cols = panel_schedule(mesh, planar_tolerance=planar_tolerance, extra=extra)
    names = list(cols)
    text_cols = [_format(k, cols[k], mesh.unit, precision) for k in names]
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(names)
    # csv writes floats with repr (exact) and None as an empty cell
    writer.writerows(zip(*text_cols))
    return buf.getvalue()


def save_schedule(
    mesh: QuadMesh,
    path: str | os.PathLike[str],
    *,
    planar_tolerance: float | str = DEFAULT_PLANAR_TOLERANCE,
    precision: Literal["rounded", "full"] = "rounded",
    extra: Mapping[str, ArrayLike] | None = None,
    **renamed: Any,
) -> Path:
    """Write the panel schedule of ``mesh`` to a CSV file atomically (see :func:`schedule_csv`).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        On a bad ``planar_tolerance`` or ``precision``, or an old keyword
        (``planar_tol``), before anything is written.
    ExportError
        If the path is not writable; no partial or temporary file is left.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from quadnodes.mesh import grid
    >>> p = save_schedule(grid(2, 2), pathlib.Path(tempfile.mkdtemp()) / "s.csv")
    >>> p.read_text().count("\\n")
    2
    """
    _refuse(renamed, "save_schedule")
    text = schedule_csv(mesh, planar_tolerance=planar_tolerance, precision=precision, extra=extra)
    return write_text_atomic(path, text)
