"""Per-panel facts shared by the exporters: labels, planar-or-bilinear, area, edges.

The STEP exporter and the panel schedule use the same functions, so a panel
listed as ``planar`` in the schedule is exactly a panel written as a plane in
the STEP file.
"""

from __future__ import annotations

import numpy as np

from .. import _validate
from ..mesh import QuadMesh
from ..flatness import diagonal_distance

__all__ = [
    "DEFAULT_PLANAR_TOL",
    "panel_labels",
    "panel_rows_cols",
    "planar_mask",
    "bilinear_area",
    "edge_lengths",
]

DEFAULT_PLANAR_TOL: float = 1e-6
"""Default planarity tolerance: relative diagonal distance (distance between the
two diagonal lines divided by the mean diagonal length, see
:func:`quadnodes.flatness.diagonal_distance`)."""

_GAUSS_N = 8
_GX, _GW = np.polynomial.legendre.leggauss(_GAUSS_N)
_GX = 0.5 * (_GX + 1.0)  # nodes on [0, 1]
_GW = 0.5 * _GW


def panel_rows_cols(mesh: QuadMesh) -> tuple[np.ndarray, np.ndarray] | None:
    """Row and column of every panel's grid cell, or ``None`` without ``grid_shape``.

    The cell of a quad is the smallest row and the smallest column among its four
    vertices, so the label does not depend on where the face's vertex list starts
    or which way it turns.

    Returns
    -------
    (rows, cols) : two (m,) int64 arrays, or None

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> r, c = panel_rows_cols(grid(3, 3))
    >>> r.tolist(), c.tolist()
    ([0, 0, 1, 1], [0, 1, 0, 1])
    """
    _validate.quad_mesh(mesh)
    if mesh.grid_shape is None:
        return None
    rows, cols = np.divmod(mesh.faces, mesh.grid_shape[1])
    return rows.min(axis=1), cols.min(axis=1)


def panel_labels(mesh: QuadMesh) -> list[str]:
    """A label for every panel.

    ``P_<row>_<col>`` (row and column of the face's grid cell) when the mesh
    has a ``grid_shape``, else ``P_<face index>``.

    Returns
    -------
    list of str, length m

    Examples
    --------
    >>> from quadnodes.mesh import grid, QuadMesh
    >>> panel_labels(grid(2, 3))
    ['P_0_0', 'P_0_1']
    >>> m = grid(2, 3)
    >>> panel_labels(QuadMesh(m.vertices, m.faces))
    ['P_0', 'P_1']
    """
    rc = panel_rows_cols(mesh)
    if rc is None:
        return [f"P_{k}" for k in range(mesh.n_faces)]
    return [f"P_{i}_{j}" for i, j in zip(rc[0].tolist(), rc[1].tolist())]


def planar_mask(mesh: QuadMesh, *, planar_tol: float = DEFAULT_PLANAR_TOL) -> np.ndarray:
    """Which panels are made as planar faces (the others as bilinear patches).

    Parameters
    ----------
    mesh : QuadMesh
    planar_tol : float
        Largest relative diagonal distance (default ``1e-6``) of a panel that is
        treated as planar. ``0`` keeps only exactly planar quads.

    Returns
    -------
    (m,) bool

    Raises
    ------
    InputError
        If ``planar_tol`` is negative or not finite.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> planar_mask(grid(2, 3, height=[[0, 0, 0], [0, 0, 1]])).tolist()
    [True, False]
    """
    _validate.quad_mesh(mesh)
    tol = _validate.nonnegative_number(planar_tol, "planar_tol")
    return diagonal_distance(mesh) <= tol


def bilinear_area(mesh: QuadMesh) -> np.ndarray:
    """Area of every panel's bilinear patch.

    The patch ``S(u, v) = (1-u)(1-v) p0 + u(1-v) p1 + uv p2 + (1-u)v p3`` is the
    surface the STEP exporter writes for a non-planar panel; for a planar convex
    quad it is the quad itself, so the value equals the polygon area. The
    integral of ``|S_u × S_v|`` over the unit square is evaluated with 8×8-point
    Gauss–Legendre quadrature: exact for planar convex quads up to rounding,
    within about ``1e-9`` relative of adaptive quadrature for twisted panels,
    and equal to OCCT's area of the exported face to about ``1e-15``. A patch
    that folds over (its normal vanishes inside, e.g. a bow-tie) is integrated
    less accurately, ``1e-5`` or so; such a panel cannot be built anyway.

    Returns
    -------
    (m,) float64, in squared model units

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> bilinear_area(grid(2, 2, spacing=(2.0, 3.0))).tolist()
    [6.0]
    """
    _validate.quad_mesh(mesh)
    p = mesh.vertices[mesh.faces]
    a = p[:, 1] - p[:, 0]  # S_u at v = 0
    b = p[:, 2] - p[:, 3]  # S_u at v = 1
    c = p[:, 3] - p[:, 0]  # S_v at u = 0
    d = p[:, 2] - p[:, 1]  # S_v at u = 1
    area = np.zeros(mesh.n_faces)
    for u, wu in zip(_GX, _GW):
        sv = (1.0 - u) * c + u * d
        for v, wv in zip(_GX, _GW):
            su = (1.0 - v) * a + v * b
            area += (wu * wv) * np.linalg.norm(np.cross(su, sv), axis=1)
    return area


def edge_lengths(mesh: QuadMesh) -> np.ndarray:
    """Lengths of the four edges of every panel.

    Column ``k`` is the edge from corner ``k`` to corner ``k+1`` (mod 4).

    Returns
    -------
    (m, 4) float64

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> edge_lengths(grid(2, 2, spacing=(2.0, 3.0))).tolist()
    [[2.0, 3.0, 2.0, 3.0]]
    """
    _validate.quad_mesh(mesh)
    p = mesh.vertices[mesh.faces]
    return np.linalg.norm(np.roll(p, -1, axis=1) - p, axis=2)
