"""Per-panel facts shared by the exporters: labels, area, edges, degenerate panels, corner moves.

Which panels are planar is decided in one place for every exporter and the
schedule: :func:`quadnodes.flatness.planar_panels`. The STEP exporter and the
panel schedule use these functions too, so a panel listed as ``planar`` in the
schedule is exactly a panel written as a plane in the STEP file, and the
schedule's corner move is the STEP file's.
"""

from __future__ import annotations

import numpy as np

from .. import _validate
from ..mesh import QuadMesh
from ..flatness import diagonal_distance

__all__ = [
    "panel_labels",
    "panel_rows_cols",
    "bilinear_area",
    "edge_lengths",
    "degenerate_panels",
    "check_panels",
    "corner_moves",
]

_GAUSS_N = 8
_GX, _GW = np.polynomial.legendre.leggauss(_GAUSS_N)
_GX = 0.5 * (_GX + 1.0)  # nodes on [0, 1]
_GW = 0.5 * _GW


def panel_rows_cols(mesh: QuadMesh) -> tuple[np.ndarray, np.ndarray] | None:
    """Row and column of every panel's grid cell, or ``None`` without ``grid_shape``.

    The cell of a quad is the row and column of its corner ``(i, j)`` whose
    neighbours in the quad are ``(i, j+1)`` and ``(i+1, j)`` (on an open grid the
    smallest row and column among its four vertices; across the seam of a cylinder
    or torus grid the last column or row), so the label does not depend on where
    the face's vertex list starts or which way it turns.

    Returns
    -------
    (rows, cols) : two (m,) int64 arrays, or None

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> r, c = panel_rows_cols(grid(3, 3))
    >>> r.tolist(), c.tolist()
    ([0, 0, 1, 1], [0, 1, 0, 1])
    >>> from quadnodes.mesh import cylinder
    >>> from quadnodes.topology import as_grid
    >>> panel_rows_cols(as_grid(cylinder(2, 3)))[1].tolist()  # the last cell closes the ring
    [0, 1, 2]
    """
    _validate.quad_mesh(mesh)
    if mesh.grid_shape is None:
        return None
    if mesh.grid_wrap == (False, False):
        rows, cols = np.divmod(mesh.faces, mesh.grid_shape[1])
        return rows.min(axis=1), cols.min(axis=1)
    wrap_rows, wrap_cols = mesh.grid_wrap
    base = _validate.grid_cell_base(mesh.faces, *mesh.grid_shape, wrap_rows=wrap_rows, wrap_cols=wrap_cols)
    return np.divmod(base, mesh.grid_shape[1])


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


def degenerate_panels(mesh: QuadMesh) -> tuple[np.ndarray, list[str]]:
    """Panels no CAD kernel can build: an edge of (almost) zero length, or zero area.

    An edge is zero when it is shorter than ``1e-12`` times the panel's longest
    edge; the area is zero when the bilinear patch's area
    (:func:`bilinear_area`) is below ``1e-12`` times the longest edge squared
    (all four corners on one line).

    Returns
    -------
    mask : (m,) bool
    reasons : list of str
        One reason per degenerate panel, in face order.

    Examples
    --------
    >>> v = np.array([[0., 0, 0], [1, 0, 0], [2, 1, 0], [3, 0, 0], [0, 1, 0]])
    >>> m = QuadMesh(v, [[0, 1, 2, 3], [4, 1, 0, 2]])
    >>> v[2, 1] = 0.0  # processing moved corner 2 onto the line of the others (QuadMesh() refuses that)
    >>> mask, why = degenerate_panels(m.with_vertices(v))
    >>> mask.tolist(), why
    ([True, False], ['zero area (all four corners on one line)'])
    """
    _validate.quad_mesh(mesh)
    with np.errstate(over="ignore"):
        edges = edge_lengths(mesh)
    longest = edges.max(axis=1)
    short = edges <= 1e-12 * longest[:, None]
    with np.errstate(over="ignore", invalid="ignore"):
        area = bilinear_area(mesh)
    # sizes beyond about 1e76 overflow the area (1e154 the squared lengths): not a zero edge, a mesh too large
    huge = ~np.isfinite(edges).all(axis=1) | ~np.isfinite(area)
    flat = area <= 1e-12 * longest * longest
    mask = short.any(axis=1) | flat | ~(longest > 0) | huge
    reasons = []
    for k in np.flatnonzero(mask).tolist():
        if huge[k]:
            reasons.append("its size overflows double precision (an edge length or its area is infinite; "
                           "scale the mesh down)")
        elif short[k].any():
            e = int(np.flatnonzero(short[k])[0])
            reasons.append(f"edge {e}-{(e + 1) % 4} has zero length")
        else:
            reasons.append("zero area (all four corners on one line)")
    return mask, reasons


def corner_moves(mesh: QuadMesh, planar: np.ndarray) -> np.ndarray:
    """How far the corners of every panel move when the planar ones are flattened.

    A planar panel (``planar[k]``, from :func:`quadnodes.flatness.planar_panels`)
    is made on the mid-plane of its two diagonal lines; each of its four corners
    lies exactly half the diagonal distance from that plane and is moved onto it
    along the normal. Bilinear panels keep their corners (move 0).

    Parameters
    ----------
    mesh : QuadMesh
    planar : (m,) bool

    Returns
    -------
    (m,) float64, in the mesh's unit

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> m = grid(2, 2, spacing=1000.0, height=[[0, 0], [0, 0.4]])
    >>> round(float(corner_moves(m, np.array([True]))[0]), 6)
    0.1
    """
    _validate.quad_mesh(mesh)
    gap = diagonal_distance(mesh, relative=False)
    return np.where(np.asarray(planar, dtype=bool), 0.5 * gap, 0.0)


def check_panels(mesh: QuadMesh, planar_tolerance: float | str, fmt: str) -> None:
    """The one check every geometry exporter makes before writing anything.

    Refuses a degenerate panel (:func:`degenerate_panels`) and a flat panel whose
    outline crosses itself (a bow-tie, :func:`quadnodes.flatness.folded_panels`:
    neither a plane face nor a sound bilinear patch can be made from it).

    Raises
    ------
    ExportError
        Naming the first such panel (face index and label), why, and how many
        there are; nothing has been written.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> check_panels(grid(3, 3), 1e-3, "step")
    >>> v = np.array([[0., 0, 0], [2, 1, 0], [2, 0, 0], [0, 2, 0]])
    >>> check_panels(QuadMesh(v, [[0, 1, 2, 3]]), 1e-3, "dxf")
    Traceback (most recent call last):
    ...
    quadnodes.errors.ExportError: dxf: panel 0 (P_0) is folded: its edges cross (a bow-tie) while it is flat within planar_tolerance 0.001; reorder its corners or repair the mesh, nothing was written
    """
    from ..errors import ExportError
    from ..flatness import folded_panels

    labels = None
    mask, reasons = degenerate_panels(mesh)
    if mask.any():
        bad = np.flatnonzero(mask)
        k = int(bad[0])
        labels = panel_labels(mesh)
        more = f" ({bad.size - 1} more such panels)" if bad.size > 1 else ""
        raise ExportError(
            f"{fmt}: panel {k} ({labels[k]}) is degenerate: {reasons[0]}{more}; no CAD face can be built from it "
            "(merge or remove such panels first), nothing was written"
        )
    folded = folded_panels(mesh, planar_tolerance)
    if folded.any():
        bad = np.flatnonzero(folded)
        k = int(bad[0])
        labels = panel_labels(mesh)
        more = f" ({bad.size - 1} more such panels)" if bad.size > 1 else ""
        raise ExportError(
            f"{fmt}: panel {k} ({labels[k]}) is folded: its edges cross (a bow-tie) while it is flat within "
            f"planar_tolerance {planar_tolerance!r}{more}; reorder its corners or repair the mesh, nothing was written"
        )
