"""Panel schedule: one CSV row per quad panel, for fabrication and costing.

Columns (lengths and areas in model units):

``panel``
    Label: ``P_<row>_<col>`` on a grid, else ``P_<face index>`` (the STEP label).
``face``
    Face index in the mesh.
``row``, ``col``
    Grid row and column of the face's cell (smallest row and column of its vertices); empty without ``grid_shape``.
``x0, y0, z0, ... x3, y3, z3``
    The four corners in face order (counter-clockwise).
``area``
    Area of the panel's bilinear patch (:func:`quadnodes.io.panels.bilinear_area`),
    the surface the STEP file holds; for a planar convex panel it is the polygon
    area (not the sum of two triangles, which depends on the diagonal chosen).
``edge01, edge12, edge23, edge30``
    Edge lengths, from corner ``k`` to corner ``k+1``.
``diagonal_distance``
    Relative diagonal distance (scale-free planarity, 0 when planar).
``diagonal_gap``
    The same distance in model units (how far the panel is out of plane).
``angle_defect``
    Angle-sum defect in radians (the thesis's measure, ``<= 0``).
``kind``
    ``planar`` when ``diagonal_distance <= planar_tol`` (the STEP exporter's
    test, same default), else ``bilinear``.

Numbers are written with Python's shortest round-trip text.
"""

from __future__ import annotations

import csv
import io
import os
from pathlib import Path

import numpy as np

from .. import _validate
from ..mesh import QuadMesh
from ..flatness import angle_defect, diagonal_distance
from ._atomic import write_text_atomic
from .panels import DEFAULT_PLANAR_TOL, bilinear_area, edge_lengths, panel_labels, panel_rows_cols

__all__ = ["SCHEDULE_COLUMNS", "panel_schedule", "schedule_csv", "save_schedule"]

SCHEDULE_COLUMNS: tuple[str, ...] = (
    ("panel", "face", "row", "col")
    + tuple(f"{a}{k}" for k in range(4) for a in "xyz")
    + ("area", "edge01", "edge12", "edge23", "edge30")
    + ("diagonal_distance", "diagonal_gap", "angle_defect", "kind")
)
"""Column names of the schedule, in order."""


def panel_schedule(mesh: QuadMesh, *, planar_tol: float = DEFAULT_PLANAR_TOL) -> dict[str, list]:
    """The schedule's columns as lists (``None`` for an empty cell).

    Parameters
    ----------
    mesh : QuadMesh
    planar_tol : float
        Relative diagonal distance up to which a panel is ``planar`` (default
        ``1e-6``, as in :func:`quadnodes.io.step.save_step`).

    Returns
    -------
    dict
        ``{column: list of m values}`` for every name in :data:`SCHEDULE_COLUMNS`.

    Raises
    ------
    InputError
        If ``planar_tol`` is negative or not finite.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> s = panel_schedule(grid(2, 3, spacing=2.0, height=[[0, 0, 0], [0, 0, 1]]))
    >>> s["panel"], s["area"][0], s["kind"]
    (['P_0_0', 'P_0_1'], 4.0, ['planar', 'bilinear'])
    """
    _validate.quad_mesh(mesh)
    tol = _validate.nonnegative_number(planar_tol, "planar_tol")
    m = mesh.n_faces
    cols: dict[str, list] = {"panel": panel_labels(mesh), "face": list(range(m))}
    rc = panel_rows_cols(mesh)
    cols["row"] = [None] * m if rc is None else rc[0].tolist()
    cols["col"] = [None] * m if rc is None else rc[1].tolist()
    p = mesh.vertices[mesh.faces]
    for k in range(4):
        for a, axis in zip("xyz", range(3)):
            cols[f"{a}{k}"] = p[:, k, axis].tolist()
    cols["area"] = bilinear_area(mesh).tolist()
    edges = edge_lengths(mesh)
    for k, key in enumerate(("edge01", "edge12", "edge23", "edge30")):
        cols[key] = edges[:, k].tolist()
    rel = diagonal_distance(mesh)
    cols["diagonal_distance"] = rel.tolist()
    cols["diagonal_gap"] = diagonal_distance(mesh, relative=False).tolist()
    cols["angle_defect"] = angle_defect(mesh).tolist()
    cols["kind"] = np.where(rel <= tol, "planar", "bilinear").tolist()
    return {key: cols[key] for key in SCHEDULE_COLUMNS}


def schedule_csv(mesh: QuadMesh, *, planar_tol: float = DEFAULT_PLANAR_TOL) -> str:
    """The panel schedule as CSV text: a header row, then one row per panel.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> text = schedule_csv(grid(2, 2))
    >>> text.splitlines()[0].split(",")[:6]
    ['panel', 'face', 'row', 'col', 'x0', 'y0']
    >>> text.splitlines()[1].split(",")[-4:]
    ['0.0', '0.0', '0.0', 'planar']
    """
    cols = panel_schedule(mesh, planar_tol=planar_tol)
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(SCHEDULE_COLUMNS)
    # csv writes floats with repr (exact) and None as an empty cell
    writer.writerows(zip(*(cols[key] for key in SCHEDULE_COLUMNS)))
    return buf.getvalue()


def save_schedule(
    mesh: QuadMesh, path: str | os.PathLike[str], *, planar_tol: float = DEFAULT_PLANAR_TOL
) -> Path:
    """Write the panel schedule of ``mesh`` to a CSV file atomically.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        If ``planar_tol`` is negative or not finite.
    ExportError
        If the path is not writable; no partial or temporary file is left.
    """
    return write_text_atomic(path, schedule_csv(mesh, planar_tol=planar_tol))
