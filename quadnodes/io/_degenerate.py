"""The one check every panel exporter makes before writing: no panel without area."""

from __future__ import annotations

import numpy as np

from ..errors import ExportError
from ..mesh import QuadMesh
from .panels import bilinear_area, edge_lengths, panel_labels

__all__ = ["DEGENERATE_AREA", "check_panel_areas"]

DEGENERATE_AREA: float = 1e-12
"""A panel whose area is at most this times the square of its longest edge has no area to make."""


def check_panel_areas(mesh: QuadMesh, fmt: str) -> tuple[np.ndarray, np.ndarray]:
    """Area and edge lengths of every panel; refuse a panel without area.

    Returns
    -------
    area : (m,) float64
    edges : (m, 4) float64

    Raises
    ------
    ExportError
        Naming the first degenerate panel (label and face index), its area and
        its longest edge, and how many there are.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> check_panel_areas(grid(2, 2), "dxf")[0].tolist()
    [1.0]
    """
    area = bilinear_area(mesh)
    edges = edge_lengths(mesh)
    longest = edges.max(axis=1)
    bad = np.flatnonzero(~(area > DEGENERATE_AREA * longest**2))
    if bad.size:
        k = int(bad[0])
        raise ExportError(
            f"{fmt}: panel {panel_labels(mesh)[k]} (face {k}) is degenerate: area {area[k]:.3g} {mesh.unit}² "
            f"with a longest edge of {longest[k]:.6g} {mesh.unit} ({bad.size} such panel"
            f"{'s' if bad.size != 1 else ''}); remove or repair it before exporting, nothing was written"
        )
    return area, edges
