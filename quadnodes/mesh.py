"""The quad mesh object and its constructors."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from . import _validate
from .errors import InputError
from .units import DEFAULT_UNIT, check_unit

if TYPE_CHECKING:
    from .topology import Topology

__all__ = ["QuadMesh", "grid_faces", "grid", "from_grid_points", "cylinder", "torus"]


@dataclass(frozen=True, eq=False)
class QuadMesh:
    """An immutable quad mesh.

    Parameters
    ----------
    vertices : (n, 3) float64
        Vertex positions. Copied and made read-only.
    faces : (m, 4) int64
        Vertex indices of each quad, counter-clockwise seen from the front side.
        Copied and made read-only.
    grid_shape : (rows, cols) or None
        Set when the mesh is a regular grid whose vertex ``i*cols + j`` sits in
        row ``i`` and column ``j``. The grid may close around (a cylinder or torus
        grid: faces across the seam join the last column or row to the first); see
        :attr:`grid_wrap`.
    unit : str
        Unit of the coordinates, one of :data:`quadnodes.units.UNITS` (default
        ``"mm"``); exporters write it into every file that can carry it.

    Raises
    ------
    InputError
        On non-finite coordinates, out-of-range or repeated indices, zero-length
        edges, an edge in more than two faces, inconsistent orientation, an empty
        mesh, or a ``grid_shape`` that does not match the vertex count.

    Examples
    --------
    >>> m = grid(3, 4)
    >>> m.n_vertices, m.n_faces, m.grid_shape
    (12, 6, (3, 4))
    """

    vertices: np.ndarray
    faces: np.ndarray
    grid_shape: tuple[int, int] | None = field(default=None)
    unit: str = field(default=DEFAULT_UNIT)

    def __post_init__(self) -> None:
        unit = check_unit(self.unit)
        v = _validate.vertices_array(self.vertices)
        f = _validate.faces_array(self.faces, v.shape[0])
        edge_matrix = _validate.check_quad_mesh(v, f)
        gs = self.grid_shape
        if gs is not None:
            gs = (int(gs[0]), int(gs[1]))
            if gs[0] * gs[1] != v.shape[0]:
                raise InputError(
                    f"grid_shape: {gs} holds {gs[0] * gs[1]} vertices, the mesh has {v.shape[0]}"
                )
            wrap = _validate.grid_wrap(f, *gs)
            if wrap is None:
                bad = _validate.grid_cells(f, *gs)
                raise InputError(
                    f"grid_shape: face {bad} {f[bad].tolist()} is not a cell of a {gs[0]} x {gs[1]} vertex grid"
                    " (open, or closed around like a cylinder or torus)"
                )
            self.__dict__["grid_wrap"] = wrap
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "faces", f)
        object.__setattr__(self, "grid_shape", gs)
        object.__setattr__(self, "unit", unit)
        self.__dict__["_edge_matrix"] = edge_matrix  # counted by the validation; topology reuses it

    @property
    def n_vertices(self) -> int:
        """Number of vertices."""
        return int(self.vertices.shape[0])

    @property
    def n_faces(self) -> int:
        """Number of quads."""
        return int(self.faces.shape[0])

    @cached_property
    def grid_wrap(self) -> tuple[bool, bool]:
        """``(wrap_rows, wrap_cols)``: whether the grid closes across its rows / columns.

        ``(False, True)`` is a cylinder grid whose rows are rings, ``(True, True)``
        a torus grid; ``(False, False)`` an open grid and every mesh without
        ``grid_shape``.

        Examples
        --------
        >>> from quadnodes.topology import as_grid
        >>> grid(3, 4).grid_wrap, as_grid(cylinder(3, 5)).grid_wrap, as_grid(torus(3, 4)).grid_wrap
        ((False, False), (False, True), (True, True))
        """
        if self.grid_shape is None:
            return (False, False)
        wrap = _validate.grid_wrap(self.faces, *self.grid_shape)
        return (False, False) if wrap is None else wrap

    @cached_property
    def topology(self) -> Topology:
        """Edges, boundary, valence and structure lines (computed once, shared by copies)."""
        from .topology import Topology

        return Topology.from_faces(self.faces, self.n_vertices, edge_matrix=self.__dict__.pop("_edge_matrix", None))

    @cached_property
    def mean_edge_length(self) -> float:
        """Mean length of the undirected edges."""
        shape = self.topology.grid_shape
        if shape is not None:  # an open grid: its edges by index arithmetic, in the edge list's order
            return float(np.sqrt(_validate.grid_edge_squares(self.vertices, shape)).mean())
        e = self.topology.edges
        d = np.take(self.vertices, e[:, 1], axis=0)
        d -= np.take(self.vertices, e[:, 0], axis=0)
        return float(np.sqrt(np.einsum("ij,ij->i", d, d)).mean())

    def with_unit(self, unit: str) -> QuadMesh:
        """The same mesh with its coordinates converted to ``unit`` (scaled), topology shared.

        The mesh itself when it is already in ``unit`` (a mesh is immutable, so callers
        need not check the unit first).

        Raises
        ------
        InputError
            If ``unit`` is not one of :data:`quadnodes.units.UNITS`.

        Examples
        --------
        >>> m = grid(2, 2, spacing=1000.0)
        >>> m.with_unit("m").vertices[-1].tolist()
        [1.0, 1.0, 0.0]
        >>> m.with_unit("mm") is m
        True
        """
        from .units import to_unit

        if check_unit(unit) == self.unit:
            return self
        factor = to_unit(1.0, self.unit, unit)
        new = self.with_vertices(self.vertices * factor)
        object.__setattr__(new, "unit", unit)
        return new

    def with_vertices(self, vertices: ArrayLike) -> QuadMesh:
        """Return a mesh with the same faces and new vertex positions.

        The topology (edges, structure lines) is shared, not recomputed.

        Raises
        ------
        InputError
            If ``vertices`` has another shape or a non-finite coordinate.
        """
        v = _validate.vertices_array(vertices)
        if v.shape != self.vertices.shape:
            raise InputError(f"vertices: expected shape {self.vertices.shape}, got {v.shape}")
        new = object.__new__(QuadMesh)
        object.__setattr__(new, "vertices", v)
        object.__setattr__(new, "faces", self.faces)
        object.__setattr__(new, "grid_shape", self.grid_shape)
        object.__setattr__(new, "unit", self.unit)
        if "grid_wrap" in self.__dict__:
            new.__dict__["grid_wrap"] = self.grid_wrap
        topo = self.__dict__.get("topology")
        if topo is not None:
            new.__dict__["topology"] = topo
        # the faces are unchanged; only edge lengths may have collapsed
        mean = _validate.check_edge_lengths(v, self.faces, None if topo is None else topo.edges,
                                            grid_shape=None if topo is None else topo.grid_shape)
        if topo is not None and np.isfinite(mean):  # (measured over the edges: the mean edge length itself)
            new.__dict__["mean_edge_length"] = mean
        return new

    def __repr__(self) -> str:
        gs = f", grid_shape={self.grid_shape}" if self.grid_shape else ""
        unit = f", unit={self.unit!r}" if self.unit != DEFAULT_UNIT else ""
        return f"QuadMesh(n_vertices={self.n_vertices}, n_faces={self.n_faces}{gs}{unit})"


def grid_faces(rows: int, cols: int, *, wrap_cols: bool = False, wrap_rows: bool = False) -> np.ndarray:
    """Faces of a ``rows × cols`` vertex grid, vertex ``i*cols + j``.

    Parameters
    ----------
    rows, cols : int
        Vertex counts along the two directions (at least 2, or 3 when wrapped).
    wrap_cols, wrap_rows : bool
        Close the grid around (cylinder in one direction, torus in both).

    Returns
    -------
    faces : (m, 4) int64
        Counter-clockwise when column ``j`` runs along +x and row ``i`` along +y.

    Examples
    --------
    >>> grid_faces(2, 3).tolist()
    [[0, 1, 4, 3], [1, 2, 5, 4]]
    """
    rows = _validate.positive_int(rows, "rows", minimum=3 if wrap_rows else 2)
    cols = _validate.positive_int(cols, "cols", minimum=3 if wrap_cols else 2)
    nr = rows if wrap_rows else rows - 1
    nc = cols if wrap_cols else cols - 1
    i, j = np.meshgrid(np.arange(nr), np.arange(nc), indexing="ij")
    i1 = (i + 1) % rows
    j1 = (j + 1) % cols
    f = np.stack([i * cols + j, i * cols + j1, i1 * cols + j1, i1 * cols + j], axis=-1)
    return f.reshape(-1, 4).astype(np.int64)


def from_grid_points(points: ArrayLike) -> QuadMesh:
    """Mesh a ``(rows, cols, 3)`` array of points as a regular grid.

    Examples
    --------
    >>> p = np.zeros((2, 2, 3)); p[..., 0] = [[0, 1], [0, 1]]; p[..., 1] = [[0, 0], [1, 1]]
    >>> from_grid_points(p).faces.tolist()
    [[0, 1, 3, 2]]
    """
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 3 or p.shape[2] != 3:
        raise InputError(f"points: expected shape (rows, cols, 3), got {p.shape}")
    rows, cols = p.shape[:2]
    return QuadMesh(p.reshape(-1, 3), grid_faces(rows, cols), grid_shape=(rows, cols))


def grid(
    rows: int,
    cols: int,
    *,
    spacing: float | tuple[float, float] = 1.0,
    height: ArrayLike | None = None,
) -> QuadMesh:
    """A flat (or height-field) regular grid in the xy plane.

    Parameters
    ----------
    rows, cols : int
        Vertex counts; row ``i`` lies at ``y = i*dy``, column ``j`` at ``x = j*dx``.
    spacing : float or (dx, dy)
        Grid spacing.
    height : (rows, cols) array, optional
        z coordinate of every vertex (default 0).

    Examples
    --------
    >>> grid(2, 2, spacing=2.0).vertices[-1].tolist()
    [2.0, 2.0, 0.0]
    """
    rows = _validate.positive_int(rows, "rows", minimum=2)
    cols = _validate.positive_int(cols, "cols", minimum=2)
    dx, dy = (spacing, spacing) if np.ndim(spacing) == 0 else spacing  # type: ignore[misc]
    y, x = np.meshgrid(np.arange(rows) * float(dy), np.arange(cols) * float(dx), indexing="ij")
    z = np.zeros((rows, cols)) if height is None else np.asarray(height, dtype=np.float64)
    if z.shape != (rows, cols):
        raise InputError(f"height: expected shape ({rows}, {cols}), got {z.shape}")
    return from_grid_points(np.stack([x, y, z], axis=-1))


def cylinder(rows: int, cols: int, *, radius: float = 1.0, height: float = 1.0) -> QuadMesh:
    """An open cylinder: ``cols`` vertices around (closed rings), ``rows`` along the axis.

    Faces point outwards.

    Examples
    --------
    >>> cylinder(3, 8).n_faces
    16
    """
    rows = _validate.positive_int(rows, "rows", minimum=2)
    cols = _validate.positive_int(cols, "cols", minimum=3)
    t = 2 * np.pi * np.arange(cols) / cols
    z = np.linspace(0.0, height, rows)
    v = np.stack(
        [np.broadcast_to(radius * np.cos(t), (rows, cols)),
         np.broadcast_to(radius * np.sin(t), (rows, cols)),
         np.broadcast_to(z[:, None], (rows, cols))],
        axis=-1,
    ).reshape(-1, 3)
    return QuadMesh(v, grid_faces(rows, cols, wrap_cols=True))


def torus(rows: int, cols: int, *, major: float = 2.0, minor: float = 0.5) -> QuadMesh:
    """A closed torus: ``cols`` vertices around the axis, ``rows`` around the tube.

    Examples
    --------
    >>> torus(6, 12).n_faces
    72
    """
    rows = _validate.positive_int(rows, "rows", minimum=3)
    cols = _validate.positive_int(cols, "cols", minimum=3)
    u = 2 * np.pi * np.arange(cols) / cols
    w = 2 * np.pi * np.arange(rows) / rows
    W, U = np.meshgrid(w, u, indexing="ij")
    r = major + minor * np.cos(W)
    v = np.stack([r * np.cos(U), r * np.sin(U), minor * np.sin(W)], axis=-1).reshape(-1, 3)
    return QuadMesh(v, grid_faces(rows, cols, wrap_cols=True, wrap_rows=True))
