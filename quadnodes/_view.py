"""What the two views (PNG in :mod:`quadnodes.viz`, HTML in :mod:`quadnodes.html`) share.

Structure lines are drawn edge by edge, so the views need one deviation per
undirected edge (in the order of ``mesh.topology.edges``) and, for hover texts
and panel colours, one per quad. Both come from the window deviations of
:func:`quadnodes.zigzag.window_deviation` in a few vectorized passes. Both
views also use the same camera frame and the same light, so a PNG and the
initial HTML view of one mesh show it alike.
"""

from __future__ import annotations

import numpy as np

from . import _validate
from .errors import InputError
from .mesh import QuadMesh
from .zigzag import _mesh_window_deviation

__all__ = ["edge_ids", "edge_deviation", "face_edges", "face_deviation", "camera", "light", "face_normals"]


def edge_ids(mesh: QuadMesh, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Index into ``mesh.topology.edges`` of the edges ``(a[k], b[k])``, in either direction.

    Parameters
    ----------
    mesh : QuadMesh
    a, b : (k,) int64
        End vertices of edges of the mesh (not checked: a pair that is not an
        edge gives an arbitrary index).

    Returns
    -------
    (k,) int64

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> m = grid(2, 3)
    >>> e = m.topology.edges[edge_ids(m, np.array([4, 0]), np.array([1, 3]))]
    >>> e.tolist()
    [[1, 4], [0, 3]]
    """
    e = mesh.topology.edges
    n = mesh.n_vertices
    key = e[:, 0] * n + e[:, 1]  # edges are sorted by (low, high), so the keys are too
    a = np.asarray(a, dtype=np.int64)
    b = np.asarray(b, dtype=np.int64)
    return np.searchsorted(key, np.minimum(a, b) * n + np.maximum(a, b))


def edge_deviation(mesh: QuadMesh, *, deviation: np.ndarray | None = None) -> np.ndarray:
    """Zigzag deviation of every edge, for colouring structure lines.

    An edge gets the largest deviation (thesis eq. 30) of the windows whose
    middle edge it is; the first and last edge of an open line are the middle
    of no window and get the largest deviation of the windows they belong to.
    Edges in no window at all (lines of fewer than four vertices) get 0.

    Parameters
    ----------
    mesh : QuadMesh
    deviation : (w,) float64, optional
        Deviation of every window of ``mesh.topology.windows``, when already
        computed (e.g. ``detect(mesh).window_deviation``).

    Returns
    -------
    (E,) float64
        In the order of ``mesh.topology.edges``.

    Raises
    ------
    InputError
        If ``mesh`` is not a QuadMesh or ``deviation`` has the wrong shape.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> z = np.zeros((3, 6)); z[1, 3] = 0.5
    >>> d = edge_deviation(grid(3, 6, height=z))
    >>> d.shape, bool(d.max() > 0.1), float(d.min())
    ((27,), True, 0.0)
    """
    _validate.quad_mesh(mesh)
    topo = mesh.topology
    e, w = topo.edges, topo.windows
    out = np.zeros(len(e))
    if len(w) == 0:
        return out
    if deviation is None:
        wd = _mesh_window_deviation(mesh)
    else:
        wd = np.asarray(deviation, dtype=np.float64)
        if wd.shape != (len(w),):
            raise InputError(f"deviation: expected shape ({len(w)},) (one per window), got {wd.shape}")
    mid = edge_ids(mesh, w[:, 1], w[:, 2])
    np.maximum.at(out, mid, wd)
    side = np.zeros(len(e))
    np.maximum.at(side, edge_ids(mesh, w[:, 0], w[:, 1]), wd)
    np.maximum.at(side, edge_ids(mesh, w[:, 2], w[:, 3]), wd)
    has_mid = np.zeros(len(e), dtype=bool)
    has_mid[mid] = True
    return np.where(has_mid, out, side)


def face_edges(mesh: QuadMesh) -> np.ndarray:
    """Edge index of the four sides of every quad, ``(m, 4) int64``.

    Side ``k`` of face ``f`` runs from ``faces[f, k]`` to ``faces[f, (k + 1) % 4]``.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> m = grid(2, 2)
    >>> m.topology.edges[face_edges(m)[0]].tolist()
    [[0, 1], [1, 3], [2, 3], [0, 2]]
    """
    return mesh.topology.he_edge.reshape(-1, 4)


def face_deviation(mesh: QuadMesh, *, edge_dev: np.ndarray | None = None) -> np.ndarray:
    """Zigzag deviation of every quad: the largest :func:`edge_deviation` of its four sides.

    Parameters
    ----------
    mesh : QuadMesh
    edge_dev : (E,) float64, optional
        From :func:`edge_deviation`, when already computed.

    Returns
    -------
    (m,) float64

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> float(face_deviation(grid(4, 4)).max())
    0.0
    """
    d = edge_deviation(mesh) if edge_dev is None else np.asarray(edge_dev, dtype=np.float64)
    return d[face_edges(mesh)].max(axis=1)


def camera(elev: float, azim: float) -> np.ndarray:
    """Orthographic camera frame for an elevation and azimuth in degrees.

    Returns
    -------
    (3, 3) float64
        Rows: screen right, screen up, towards the viewer (a right-handed frame).

    Examples
    --------
    >>> np.round(camera(90.0, -90.0), 6).tolist()
    [[1.0, 0.0, 0.0], [-0.0, 1.0, 0.0], [0.0, -0.0, 1.0]]
    """
    el, az = np.radians(elev), np.radians(azim)
    eye = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    right = np.array([-np.sin(az), np.cos(az), 0.0])
    return np.stack([right, np.cross(eye, right), eye])


def light(cam: np.ndarray) -> np.ndarray:
    """Unit direction towards the light: upper left, behind the viewer of ``cam``."""
    d = 0.75 * cam[2] + 0.45 * cam[1] - 0.35 * cam[0]
    return d / np.linalg.norm(d)


def face_normals(mesh: QuadMesh) -> np.ndarray:
    """Unit normal of every quad (cross product of its diagonals), zero for degenerate quads, ``(m, 3)``."""
    p = mesh.vertices[mesh.faces]
    n = np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 1])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, length, out=np.zeros_like(n), where=length > 0)
