"""Combinatorics of a quad mesh: edges, boundary, valence, structure lines, windows.

Everything here depends on the faces only and is computed with NumPy and
scipy.sparse in a handful of vectorized passes (no Python loop over vertices).

Tracing convention (see ``DESIGN.md``): an edge is a boundary edge when it lies in
one face. A line arriving at an interior vertex of valence 4 continues along the
edge that shares no face with the arriving edge; at a boundary vertex of valence 3
a boundary line continues along the other boundary edge and the interior line
ends; at every other vertex (corners, reflex and hole corners, extraordinary
vertices) every line ends. A line is closed when its walk comes back to its first
edge in the same direction; its windows wrap. Every edge lies in exactly one line.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components, depth_first_order

from ._arrays import unique_values
from .linalg import compiled as _compiled
from ._validate import grid_cell_base, grid_cells

if TYPE_CHECKING:
    from .mesh import QuadMesh

__all__ = [
    "Topology",
    "StructureLines",
    "structure_lines",
    "windows",
    "boundary_vertices",
    "corner_vertices",
    "adjacency",
    "fixed_vertices",
    "FIX_MODES",
    "CORNER_ANGLE",
    "as_grid",
]

#: A boundary vertex is a corner when the boundary turns by more than this many degrees
#: there, at the scale of one edge and of two edges (see :func:`corner_vertices`).
CORNER_ANGLE = 45.0


@dataclass(frozen=True, eq=False)
class StructureLines:
    """Polylines through a quad mesh, stored flat (CSR style).

    Attributes
    ----------
    indices : (k,) int64
        Vertex indices of all lines, one after the other.
    offsets : (L + 1,) int64
        Line ``i`` is ``indices[offsets[i]:offsets[i+1]]``.
    closed : (L,) bool
        Whether line ``i`` is a closed loop (its last vertex connects to its first;
        the first vertex is not repeated).

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> lines = structure_lines(grid(2, 3))
    >>> [l.tolist() for l in lines]
    [[0, 1, 2], [0, 3], [1, 4], [2, 5], [3, 4, 5]]
    """

    indices: np.ndarray
    offsets: np.ndarray
    closed: np.ndarray

    def __len__(self) -> int:
        return int(self.closed.shape[0])

    def __getitem__(self, i: int) -> np.ndarray:
        if not -len(self) <= i < len(self):
            raise IndexError(f"line {i} out of range for {len(self)} lines")
        i %= len(self)
        return self.indices[self.offsets[i] : self.offsets[i + 1]]

    def __iter__(self) -> Iterator[np.ndarray]:
        return (self[i] for i in range(len(self)))

    @property
    def lengths(self) -> np.ndarray:
        """Number of vertices of every line, ``(L,) int64``."""
        return np.diff(self.offsets)


@dataclass(frozen=True, eq=False)
class Topology:
    """Connectivity of a quad mesh. Build it with :meth:`from_faces`.

    Half-edge ``h = 4*f + k`` runs from ``faces[f, k]`` to ``faces[f, (k+1) % 4]``.
    """

    faces: np.ndarray
    n_vertices: int

    @classmethod
    def from_faces(cls, faces: np.ndarray, n_vertices: int, *, edge_matrix: sp.csr_matrix | None = None) -> Topology:
        """Topology of an already validated ``(m, 4)`` face array.

        ``edge_matrix``: the undirected edges as counted by
        :func:`quadnodes._validate.check_quad_mesh` (upper triangular, canonical),
        so they are not counted twice.
        """
        topo = cls(np.asarray(faces, dtype=np.int64), int(n_vertices))
        if edge_matrix is not None:
            topo.__dict__["_edge_matrix"] = edge_matrix
        return topo

    # --- half-edges -------------------------------------------------------------
    @cached_property
    def he_start(self) -> np.ndarray:
        """Start vertex of every half-edge, ``(4m,)``."""
        return self.faces.reshape(-1)

    @cached_property
    def he_end(self) -> np.ndarray:
        """End vertex of every half-edge, ``(4m,)``."""
        return np.roll(self.faces, -1, axis=1).reshape(-1)

    @cached_property
    def he_next(self) -> np.ndarray:
        """Next half-edge in the same face, ``(4m,)``."""
        h = np.arange(self.faces.size)
        return (h & ~3) | ((h + 1) & 3)

    @cached_property
    def he_twin(self) -> np.ndarray:
        """Opposite half-edge in the neighbouring face, or -1 on the boundary."""
        he_dir, dir_he = self._directed
        return dir_he[he_dir ^ 1]

    @cached_property
    def _directed(self) -> tuple[np.ndarray, np.ndarray]:
        """Directed edge of every half-edge and the half-edge of every directed edge (or -1).

        Directed edge ``2e`` runs ``edges[e, 0] -> edges[e, 1]``, ``2e + 1`` back. A
        consistently oriented mesh (as validated) walks each directed edge at most once.
        """
        he_dir = 2 * self.he_edge + (self.he_start > self.he_end)
        dir_he = np.full(2 * len(self.edges), -1, dtype=np.int64)
        dir_he[he_dir] = np.arange(he_dir.size)
        return he_dir, dir_he

    @cached_property
    def _undirected(self) -> sp.csr_matrix:
        """Upper-triangular canonical CSR of the undirected edges; values: faces per edge."""
        und = self.__dict__.pop("_edge_matrix", None)
        if und is None:
            n = self.n_vertices
            lo = np.minimum(self.he_start, self.he_end)
            hi = np.maximum(self.he_start, self.he_end)
            und = sp.csr_matrix((np.ones(lo.size, dtype=np.int32), (lo, hi)), shape=(n, n))
            und.sum_duplicates()  # canonical: rows and the columns within them sorted
        return und

    @cached_property
    def edges(self) -> np.ndarray:
        """Undirected edges ``(E, 2) int64``, each as ``(low, high)`` vertex index, sorted."""
        if self.grid_shape is not None:  # an open grid: by index arithmetic (each vertex's right, then lower edge)
            rows, cols = self.grid_shape
            node = np.arange(rows * cols, dtype=np.int64).reshape(rows, cols)
            pair = np.full((rows, cols, 2, 2), -1, dtype=np.int64)
            pair[:, :-1, 0, 0], pair[:, :-1, 0, 1] = node[:, :-1], node[:, 1:]
            pair[:-1, :, 1, 0], pair[:-1, :, 1, 1] = node[:-1], node[1:]
            pair = pair.reshape(-1, 2)
            return pair[pair[:, 0] >= 0]
        und = self._undirected
        return np.stack([np.repeat(np.arange(self.n_vertices), np.diff(und.indptr)),
                         und.indices.astype(np.int64)], axis=1)

    @cached_property
    def he_edge(self) -> np.ndarray:
        """Undirected edge id of every half-edge, ``(4m,)``."""
        und, n = self._undirected, self.n_vertices
        ids = sp.csr_matrix((np.arange(1, und.nnz + 1), und.indices, und.indptr), shape=(n, n))
        lo = np.minimum(self.he_start, self.he_end)
        hi = np.maximum(self.he_start, self.he_end)
        return np.asarray(ids[lo, hi]).ravel() - 1

    @cached_property
    def ring(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The edge 1-ring as CSR arrays: ``indptr``, ``indices`` and the edge id of each entry.

        Row ``i`` lists the neighbours of vertex ``i`` along mesh edges (no quad
        diagonals), sorted; each undirected edge appears twice.
        """
        e = self.edges
        E = len(e)
        n = self.n_vertices
        indptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(e[:, 0], minlength=n), out=indptr[1:])
        upper = sp.csr_matrix((np.arange(1, E + 1), e[:, 1], indptr), shape=(n, n))
        a = upper + upper.T.tocsr()  # disjoint patterns: a sorted merge
        return a.indptr, a.indices, a.data - 1

    @cached_property
    def edge_face_count(self) -> np.ndarray:
        """Number of faces (1 or 2) holding each edge, ``(E,)``."""
        return self._undirected.data.astype(np.int64)  # the edges' counts, in edge order

    @cached_property
    def boundary_edges(self) -> np.ndarray:
        """Mask of edges that lie in one face only, ``(E,) bool``."""
        return self.edge_face_count == 1

    # --- vertices ---------------------------------------------------------------
    @cached_property
    def valence(self) -> np.ndarray:
        """Number of edges at every vertex, ``(n,)``."""
        if self.grid_shape is not None:  # an open grid: by index arithmetic, no edge list
            return self._grid_counts(4, 3, 2)
        return np.bincount(self.edges.reshape(-1), minlength=self.n_vertices)

    @cached_property
    def vertex_face_count(self) -> np.ndarray:
        """Number of faces at every vertex, ``(n,)``."""
        if self.grid_shape is not None:
            return self._grid_counts(4, 2, 1)
        return np.bincount(self.faces.reshape(-1), minlength=self.n_vertices)

    def _grid_counts(self, inside: int, side: int, corner: int) -> np.ndarray:
        """An open grid's per-vertex count that is ``inside``, ``side`` or ``corner`` by position, ``(n,) int64``."""
        rows, cols = self.grid_shape  # type: ignore[misc]
        count = np.full((rows, cols), inside, dtype=np.int64)
        count[[0, -1], :] = side
        count[:, [0, -1]] = side
        count[[0, 0, -1, -1], [0, -1, 0, -1]] = corner
        return count.reshape(-1)

    @cached_property
    def boundary_vertices(self) -> np.ndarray:
        """Mask of vertices on a boundary edge, ``(n,) bool``."""
        return self._boundary_count > 0

    @cached_property
    def corner_vertices(self) -> np.ndarray:
        """Boundary vertices that are not regular boundary points, ``(n,) bool``.

        Convex corners (one face), reflex and hole corners (three or more faces)
        and boundary vertices where two boundary arcs touch.
        """
        if self.grid_shape is not None:  # an open vertex grid: its four corners
            rows, cols = self.grid_shape
            mask = np.zeros(self.n_vertices, dtype=bool)
            mask[[0, cols - 1, (rows - 1) * cols, rows * cols - 1]] = True
            return mask
        return self.boundary_vertices & ~self.regular_boundary

    @cached_property
    def _boundary_count(self) -> np.ndarray:
        if self.grid_shape is not None:  # every vertex of the ring has two boundary edges
            return self._grid_counts(0, 2, 2)  # (every vertex of the ring: two boundary edges)
        return np.bincount(
            self.edges[self.boundary_edges].reshape(-1), minlength=self.n_vertices
        )

    @cached_property
    def regular_interior(self) -> np.ndarray:
        """Interior vertices of valence 4 with four faces, ``(n,) bool``."""
        return (self.valence == 4) & (self._boundary_count == 0) & (self.vertex_face_count == 4)

    @cached_property
    def regular_boundary(self) -> np.ndarray:
        """Boundary vertices of valence 3 with two faces and two boundary edges."""
        return (self.valence == 3) & (self._boundary_count == 2) & (self.vertex_face_count == 2)

    @cached_property
    def extraordinary(self) -> np.ndarray:
        """Interior vertices whose valence is not 4, ``(n,) bool`` (vertices in no face are none)."""
        return ~self.boundary_vertices & ~self.regular_interior & (self.vertex_face_count > 0)

    # --- structure lines --------------------------------------------------------
    @cached_property
    def _successor(self) -> np.ndarray:
        """Successor of every directed edge along its structure line, or -1.

        Directed edge ``2e`` runs ``edges[e, 0] -> edges[e, 1]``, ``2e + 1`` back.
        """
        E = len(self.edges)
        he_dir, dir_he = self._directed
        d = np.arange(2 * E)
        e = d >> 1
        end = self.edges[:, ::-1].reshape(-1)  # 2e ends at the high vertex, 2e + 1 at the low one
        succ = np.full(2 * E, -1, dtype=np.int64)

        inner = np.flatnonzero(self.regular_interior[end])
        h = dir_he[inner]  # exists: every edge at an interior vertex has two faces
        h = (h & ~3) | ((h + 1) & 3)  # next in the face (as he_next, without the gather)
        h = dir_he[he_dir[h] ^ 1]  # its twin
        h = (h & ~3) | ((h + 1) & 3)
        succ[inner] = he_dir[h]

        bnd_he = np.flatnonzero(self.he_twin < 0)
        b_in = np.full(self.n_vertices, -1, dtype=np.int64)
        b_out = np.full(self.n_vertices, -1, dtype=np.int64)
        b_in[self.he_end[bnd_he]] = bnd_he
        b_out[self.he_start[bnd_he]] = bnd_he
        along = self.regular_boundary[end] & self.boundary_edges[e]
        da, va = d[along], end[along]
        same = dir_he[da] >= 0  # walking with the boundary half-edge
        succ[da[same]] = he_dir[b_out[va[same]]]
        succ[da[~same]] = he_dir[b_in[va[~same]]] ^ 1
        # a vertex whose faces fold back (two faces sharing both its edges there, a "pillow"): straight through
        # leads back along the arriving edge; no line passes there, it ends
        succ[succ == (d ^ 1)] = -1
        return succ

    @cached_property
    def grid_shape(self) -> tuple[int, int] | None:
        """``(rows, cols)`` when the faces are every cell of a ``rows × cols`` vertex grid, else None.

        Vertex ``i*cols + j`` sits at row ``i``, column ``j`` (the layout of
        :func:`quadnodes.mesh.grid_faces` and of sampled surfaces; faces in any order
        and orientation). Such a mesh's structure lines are its rows and columns.
        """
        return _grid_shape(self.faces, self.n_vertices)

    @cached_property
    def closed_grid(self) -> tuple[int, int, bool, bool] | None:
        """``(rows, cols, wrap_rows, wrap_cols)`` when the faces are every cell of a cylinder or torus grid.

        Vertex ``i*cols + j`` sits at row ``i``, column ``j`` (as :func:`as_grid`
        numbers them and :func:`quadnodes.mesh.cylinder` / ``torus`` make them);
        ``wrap_cols``: the rows are closed (the last column joins column 0),
        ``wrap_rows``: the columns are. None for open grids (:attr:`grid_shape`)
        and everything else.

        Examples
        --------
        >>> from quadnodes.mesh import cylinder, torus
        >>> cylinder(3, 5).topology.closed_grid, torus(4, 6).topology.closed_grid
        ((3, 5, False, True), (4, 6, True, True))
        """
        # an open grid is no closed one: its span count need not be made (0.05–0.09 s on a 1000² grid, where
        # grid_shape is made anyway)
        if self.grid_shape is not None:
            return None
        return _closed_grid(self.faces, self.n_vertices)

    @cached_property
    def structure_lines(self) -> StructureLines:
        """All structure lines, canonically ordered and oriented.

        Open lines run from their smaller end vertex; closed lines start at their
        smallest vertex and go towards its smaller neighbour. Lines are sorted by
        their first two vertices. A complete vertex grid (:attr:`grid_shape`), and a cylinder or torus grid
        (:attr:`closed_grid`) of at least 4 × 4 vertices, gets its rows and columns without tracing (the same
        lines in the same order).
        """
        layout = self._grid_layout
        if layout is not None:
            return _closed_grid_lines(*layout) if any(layout[2:]) else _grid_lines(*layout[:2])
        return _trace_lines(self.edges, self._successor)

    @property
    def _grid_layout(self) -> tuple[int, int, bool, bool] | None:
        """``(rows, cols, wrap_rows, wrap_cols)`` of a grid whose lines, windows and walk are laid out by index
        arithmetic — an open grid (:attr:`grid_shape`), or a cylinder or torus grid (:attr:`closed_grid`) of at least
        4 × 4 vertices (smaller ones are traced) — else None."""
        shape = self.grid_shape
        if shape is not None:
            return shape[0], shape[1], False, False
        closed = self.closed_grid
        return closed if closed is not None and min(closed[:2]) >= 4 else None

    @cached_property
    def windows(self) -> np.ndarray:
        """``(w, 4)`` consecutive vertex quadruples of all structure lines (as :func:`windows`)."""
        layout = self._grid_layout
        if layout is not None:
            return _grid_windows(*layout)
        ext, start = self.window_walk
        return ext[start[:, None] + np.arange(4)]

    @cached_property
    def window_walk(self) -> tuple[np.ndarray, np.ndarray]:
        """The lines as one vertex sequence ``ext`` and every window's start in it.

        Closed lines repeat their first three vertices, so window ``i`` is
        ``ext[start[i] : start[i] + 4]`` and consecutive windows of a line share
        edges: per-edge quantities are computed once per line edge, not per window.
        """
        layout = self._grid_layout
        if layout is not None:
            return _grid_walk(*layout)
        return _window_walk(self.structure_lines)[:2]

    @cached_property
    def window_middle(self) -> np.ndarray:
        """Mask of vertices that are a middle point of at least one window."""
        shape = self.grid_shape
        if shape is not None:  # inside a row of at least 4 nodes, or inside a column of at least 4
            rows, cols = shape
            mask = np.zeros((rows, cols), dtype=bool)
            if cols >= 4:
                mask[:, 1:-1] = True
            if rows >= 4:
                mask[1:-1] = True
            return mask.reshape(-1)
        if self._grid_layout is not None:  # a closed grid: every vertex is on a closed row or a closed column
            return np.ones(self.n_vertices, dtype=bool)
        mask = np.zeros(self.n_vertices, dtype=bool)
        mask[self.windows[:, 1:3].reshape(-1)] = True
        return mask


def _renumbered_faces(faces: np.ndarray, order: np.ndarray, n: int) -> np.ndarray | None:
    """``faces`` in the numbering where vertex ``order[i]`` becomes ``i``; None unless ``order`` holds every vertex."""
    new_index = np.full(n, -1, dtype=np.int64)
    new_index[order] = np.arange(n)
    if (new_index < 0).any():
        return None
    return new_index[faces]


def _grid_shape(faces: np.ndarray, n: int) -> tuple[int, int] | None:
    """``(rows, cols)`` if ``faces`` are the ``(rows-1)(cols-1)`` distinct unit cells of a vertex grid."""
    if len(faces) == 0:
        return None
    f0 = faces[0]
    cols = int(f0.max() - f0.min()) - 1  # a unit cell spans (i, j) .. (i+1, j+1)
    if cols < 2 or n % cols:
        return None
    rows = n // cols
    if rows < 2 or (rows - 1) * (cols - 1) != len(faces):
        return None
    # the common case first: the faces of grid_faces (or its reverse orientation), cell by cell in order
    base = (np.arange(rows - 1, dtype=np.int64)[:, None] * cols + np.arange(cols - 1)).reshape(-1, 1)
    rel = faces - base
    if (rel == (0, 1, cols + 1, cols)).all() or (rel == (0, cols, cols + 1, 1)).all():
        return rows, cols
    if grid_cells(faces, rows, cols) >= 0 or np.bincount(faces.min(axis=1), minlength=n).max() > 1:
        return None  # not all unit cells, or one cell twice
    return rows, cols


def _closed_grid(faces: np.ndarray, n: int) -> tuple[int, int, bool, bool] | None:
    """``(rows, cols, wrap_rows, wrap_cols)`` if ``faces`` are all cells, once each, of a closed vertex grid."""
    if len(faces) == 0:
        return None
    span = np.bincount(faces.max(axis=1) - faces.min(axis=1))  # cols + 1 for every cell off the seams
    cols = int(np.argmax(span)) - 1
    if cols < 3 or n % cols:
        return None
    rows = n // cols
    for wrap in ((False, True), (True, False), (True, True)):
        count = (rows - (not wrap[0])) * (cols - (not wrap[1]))
        if rows < (3 if wrap[0] else 2) or count != len(faces):
            continue
        if _closed_cells_in_order(faces, rows, cols, *wrap):  # (the common case: as cylinder() and torus() make them)
            return rows, cols, wrap[0], wrap[1]
        base = grid_cell_base(faces, rows, cols, wrap_rows=wrap[0], wrap_cols=wrap[1])
        if (base >= 0).all() and np.bincount(base, minlength=n).max() == 1:  # (every cell once)
            return rows, cols, wrap[0], wrap[1]
    return None


def _closed_cells_in_order(faces: np.ndarray, rows: int, cols: int, wrap_rows: bool, wrap_cols: bool) -> bool:
    """Whether ``faces`` are :func:`quadnodes.mesh.grid_faces`' cells of this closed grid, in its order, in either
    orientation."""
    from .mesh import grid_faces

    expected = grid_faces(rows, cols, wrap_cols=wrap_cols, wrap_rows=wrap_rows)
    return np.array_equal(faces, expected) or np.array_equal(faces, expected[:, [0, 3, 2, 1]])


def _grid_lines(rows: int, cols: int) -> StructureLines:
    """The rows and columns of a ``rows × cols`` vertex grid in canonical order.

    Sorted by their first two vertices: row 0 ``(0, 1, …)``, column 0 ``(0, cols, …)``,
    columns ``1 … cols-1``, then rows ``1 … rows-1``.

    Examples
    --------
    >>> [l.tolist() for l in _grid_lines(2, 3)]
    [[0, 1, 2], [0, 3], [1, 4], [2, 5], [3, 4, 5]]
    """
    n = rows * cols
    ids = np.arange(n, dtype=np.int64)
    flat = np.concatenate([ids[:cols], ids.reshape(rows, cols).T.reshape(-1), ids[cols:]])
    lengths = np.r_[cols, np.full(cols, rows), np.full(rows - 1, cols)]
    offsets = np.r_[0, np.cumsum(lengths)].astype(np.int64)
    closed = np.zeros(rows + cols, dtype=bool)
    for a in (flat, offsets, closed):
        a.setflags(write=False)
    return StructureLines(flat, offsets, closed)


def _closed_grid_lines(rows: int, cols: int, wrap_rows: bool, wrap_cols: bool) -> StructureLines:
    """The rows and columns of a cylinder or torus grid (:attr:`Topology.closed_grid`), in canonical order.

    Its rows are closed where ``wrap_cols``, its columns where ``wrap_rows``: every vertex inside the grid has
    valence 4, so tracing would follow exactly these lines; :func:`_canonical` orients and orders them as it
    orders traced ones (one gather, no walk: a 1000 × 1000 torus's lines in milliseconds, not seconds).

    Examples
    --------
    >>> lines = _closed_grid_lines(4, 5, False, True)  # a cylinder: 4 closed rings of 5, 5 open columns of 4
    >>> [l.tolist() for l in lines][:3], int(lines.closed.sum())
    ([[0, 1, 2, 3, 4], [0, 5, 10, 15], [1, 6, 11, 16]], 4)
    """
    n = rows * cols
    ids = np.arange(n, dtype=np.int64)
    flat = np.concatenate([ids, ids.reshape(rows, cols).T.reshape(-1)])
    offsets = np.r_[np.arange(rows + 1) * cols, n + rows * np.arange(1, cols + 1)].astype(np.int64)
    closed = np.r_[np.full(rows, wrap_cols), np.full(cols, wrap_rows)]
    return _canonical(flat, offsets, closed)


def _grid_windows(rows: int, cols: int, wrap_rows: bool = False, wrap_cols: bool = False) -> np.ndarray:
    """The windows of :func:`_grid_lines`' lines in order, built by index arithmetic (no gather).

    On a cylinder or torus grid (``wrap_cols``: its rows closed, ``wrap_rows``: its columns, as
    :attr:`Topology.closed_grid`; at least 4 × 4), those of :func:`_closed_grid_lines`' lines — in the same order
    (row 0, the columns, rows 1 …), a closed line of ``L`` giving ``L`` windows from each of its vertices on.

    Examples
    --------
    >>> _grid_windows(4, 5).tolist()  # row 0, then the columns, then rows 1 … 3
    [[0, 1, 2, 3], [1, 2, 3, 4], [0, 5, 10, 15], [1, 6, 11, 16], [2, 7, 12, 17], [3, 8, 13, 18], [4, 9, 14, 19], [5, 6, 7, 8], [6, 7, 8, 9], [10, 11, 12, 13], [11, 12, 13, 14], [15, 16, 17, 18], [16, 17, 18, 19]]
    >>> _grid_windows(4, 4, wrap_cols=True)[:5].tolist()  # a ring of 4: its windows wrap around
    [[0, 1, 2, 3], [1, 2, 3, 0], [2, 3, 0, 1], [3, 0, 1, 2], [0, 4, 8, 12]]
    """
    kr = cols if wrap_cols else max(cols - 3, 0)
    kc = rows if wrap_rows else max(rows - 3, 0)
    along_row = (np.arange(kr, dtype=np.int64)[:, None] + np.arange(4)) % cols  # a row's windows, from node 0
    along_col = (np.arange(kc, dtype=np.int64)[:, None] + np.arange(4)) % rows * cols
    out = np.empty((rows * kr + cols * kc, 4), dtype=np.int64)
    out[:kr] = along_row
    out[kr : kr + cols * kc].reshape(cols, kc, 4)[...] = np.arange(cols, dtype=np.int64)[:, None, None] + along_col
    out[kr + cols * kc :].reshape(rows - 1, kr, 4)[...] = (cols * np.arange(1, rows, dtype=np.int64))[:, None, None] \
        + along_row
    return out


def _grid_walk(rows: int, cols: int, wrap_rows: bool = False, wrap_cols: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """:attr:`Topology.window_walk` of a grid (open, or a cylinder or torus of at least 4 × 4), by index arithmetic:
    its lines in :func:`_grid_lines`' order, a closed one followed by its first three vertices again; windows start
    at each open line's first ``L − 3`` nodes and at every node of a closed one.

    Examples
    --------
    >>> ext, start = _grid_walk(4, 4, False, True)  # rings of 4 (each laid out as 7), open columns of 4
    >>> ext[:11].tolist(), start[:6].tolist()
    ([0, 1, 2, 3, 0, 1, 2, 0, 4, 8, 12], [0, 1, 2, 3, 7, 11])
    """
    ids = np.arange(rows * cols, dtype=np.int64).reshape(rows, cols)
    row_walk = np.concatenate([ids, ids[:, :3]], axis=1) if wrap_cols else ids
    col_walk = np.concatenate([ids.T, ids.T[:, :3]], axis=1) if wrap_rows else ids.T
    ext = np.concatenate([row_walk[0], col_walk.reshape(-1), row_walk[1:].reshape(-1)])
    (_, rw), (_, cw) = row_walk.shape, col_walk.shape
    kr = cols if wrap_cols else max(cols - 3, 0)
    kc = rows if wrap_rows else max(rows - 3, 0)
    start = np.concatenate([np.arange(kr, dtype=np.int64),
                            (rw + cw * np.arange(cols, dtype=np.int64)[:, None] + np.arange(kc)).reshape(-1),
                            (rw + cols * cw + rw * np.arange(rows - 1, dtype=np.int64)[:, None]
                             + np.arange(kr)).reshape(-1)])
    for a in (ext, start):
        a.setflags(write=False)
    return ext, start


def _trace_lines(edges: np.ndarray, succ: np.ndarray) -> StructureLines:
    """The structure lines of the successor map ``succ`` (directed edge ``2e`` runs along ``edges[e]``, ``2e + 1``
    back), by the compiled kernel where it is loaded (:func:`quadnodes._topology_kernels.trace_lines`), else by
    SciPy's graph walks; :func:`_canonical` orders and orients them, so both give the same lines."""
    D = succ.size
    dstart = edges.reshape(-1)  # directed edge 2e starts at edges[e,0], 2e+1 at edges[e,1]
    dend = edges[:, ::-1].reshape(-1)
    has = succ >= 0
    src = np.flatnonzero(has)
    dst = succ[src]
    pred = np.full(D, -1, dtype=np.int64)
    pred[dst] = src
    traced = _compiled_trace(succ, pred) if D >= _COMPILED_MIN_EDGES and _compiled.ready() else None
    order, n_edges, closed = traced if traced is not None else _scipy_trace(succ, pred, src, dst)
    return _lines_from_edges(order, n_edges, closed, dstart, dend)


#: Directed edges from which :func:`_trace_lines` takes the compiled kernel where it is loaded (below, SciPy's walks
#: take a millisecond or two).
_COMPILED_MIN_EDGES = 20_000


def _compiled_trace(succ: np.ndarray, pred: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """``(order, edges per line, closed)`` by :func:`quadnodes._topology_kernels.trace_lines`; None where it
    refuses the map (then SciPy traces it)."""
    from ._topology_kernels import trace_lines

    D = succ.size
    order = np.empty(D // 2, dtype=np.int64)
    lengths = np.empty(D // 2, dtype=np.int64)
    closed = np.empty(D // 2, dtype=np.bool_)
    count = trace_lines(np.ascontiguousarray(succ, dtype=np.int64), pred, order, lengths, closed)
    if count < 0:
        return None
    return order, lengths[:count], closed[:count]


def _load_kernel() -> None:
    """First call of the compiled tracer (loads its machine code; :func:`quadnodes.linalg.compiled.also_load`)."""
    succ = np.array([2, -1, -1, 1], dtype=np.int64)  # one open line of two edges, 0 then 2
    pred = np.array([-1, 3, 0, -1], dtype=np.int64)
    _compiled_trace(succ, pred)


_compiled.also_load(_load_kernel)


def _scipy_trace(succ: np.ndarray, pred: np.ndarray, src: np.ndarray,
                 dst: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(order, edges per line, closed)`` of :func:`_trace_lines` by SciPy's depth-first walks."""
    D = succ.size
    # open lines: a depth-first walk from a virtual root joined to every chain's first
    # edge visits the chains (each line in both directions) one after the other, whole
    heads = np.flatnonzero(pred < 0)
    order = _walk(src, dst, heads, D)
    seg = np.flatnonzero(pred[order] < 0)
    seg_len = np.diff(np.r_[seg, order.size])
    # keep one direction of each line: the one whose first edge has the smaller id
    # than the reverse's first edge (the reverse of its last edge)
    keep = order[seg] < (order[seg + seg_len - 1] ^ 1)
    order = order[np.repeat(keep, seg_len)]
    n_edges = seg_len[keep]
    closed = np.zeros(n_edges.size, dtype=bool)

    # closed lines: the edges no chain reached lie on cycles (both directions of each)
    seen = np.zeros(D, dtype=bool)
    seen[order] = True
    seen[order ^ 1] = True
    cyc = np.flatnonzero(~seen)
    if cyc.size:
        local = np.full(D, -1, dtype=np.int64)
        local[cyc] = np.arange(cyc.size)
        g = sp.csr_matrix((np.ones(cyc.size, dtype=np.int8), (np.arange(cyc.size), local[succ[cyc]])),
                          shape=(cyc.size, cyc.size))
        _, comp = connected_components(g, directed=True, connection="weak")
        kept = comp < comp[local[cyc ^ 1]]  # one direction of each cycle
        cut = np.full(int(comp.max()) + 1, D, dtype=np.int64)
        np.minimum.at(cut, comp[kept], cyc[kept])  # broken at its smallest directed edge
        cut = cut[cut < D]
        is_cut = np.zeros(D, dtype=bool)
        is_cut[cut] = True
        nodes = cyc[kept]
        nodes = nodes[~is_cut[succ[nodes]]]
        loops = _walk(nodes, succ[nodes], np.sort(cut), D)
        starts = np.flatnonzero(is_cut[loops])
        order = np.r_[order, loops]
        n_edges = np.r_[n_edges, np.diff(np.r_[starts, loops.size])]
        closed = np.r_[closed, np.ones(starts.size, dtype=bool)]
    return order, n_edges, closed


def _lines_from_edges(order: np.ndarray, n_edges: np.ndarray, closed: np.ndarray, dstart: np.ndarray,
                      dend: np.ndarray) -> StructureLines:
    """The lines whose directed edges ``order`` lists line after line (``n_edges`` each), as vertex sequences in
    canonical order (:func:`_canonical`)."""
    starts = np.r_[0, np.cumsum(n_edges)[:-1]].astype(np.int64)
    n_vert = n_edges + (~closed)
    offsets = np.r_[0, np.cumsum(n_vert)].astype(np.int64)
    # an open line has one vertex more than edges: shift the later lines by one each
    shift = np.zeros(order.size, dtype=np.int64)
    shift[starts[1:]] = ~closed[:-1]
    np.cumsum(shift, out=shift)
    shift += np.arange(order.size)
    flat = np.empty(offsets[-1], dtype=np.int64)
    flat[shift] = dstart[order]
    last = starts + n_edges - 1
    flat[offsets[1:][~closed] - 1] = dend[order[last[~closed]]]
    return _canonical(flat, offsets, closed)


def _walk(src: np.ndarray, dst: np.ndarray, first: np.ndarray, D: int) -> np.ndarray:
    """Depth-first order of the chains ``src -> dst`` from a virtual root joined to ``first``."""
    walk = sp.csr_matrix(
        (np.ones(src.size + first.size, dtype=np.int8),
         (np.r_[src, np.full(first.size, D)], np.r_[dst, first])),
        shape=(D + 1, D + 1),
    )
    return depth_first_order(walk, D, directed=True, return_predecessors=False)[1:]


def _canonical(flat: np.ndarray, offsets: np.ndarray, closed: np.ndarray) -> StructureLines:
    """Orient and order lines deterministically, independent of edge numbering.

    Open lines run from their smaller end vertex; closed lines start at their
    smallest vertex and go towards its smaller neighbour; lines are sorted by
    their first two vertices. Everything is decided per line, then one gather
    writes the result.
    """
    L = closed.size
    if L == 0:
        return StructureLines(flat, offsets, closed)
    n = np.diff(offsets)
    start = offsets[:-1]
    first, last = flat[start], flat[offsets[1:] - 1]
    # closed: rotate to the (first) smallest vertex
    shift = np.zeros(L, dtype=np.int64)
    ci = np.flatnonzero(closed)
    if ci.size:
        cn = n[ci]
        coff = np.r_[0, np.cumsum(cn)]
        cl = np.repeat(np.arange(ci.size), cn)
        cpos = np.arange(coff[-1]) - coff[cl]
        cflat = flat[start[ci][cl] + cpos]
        cmin = np.minimum.reduceat(cflat, coff[:-1])
        shift[ci] = np.minimum.reduceat(np.where(cflat == cmin[cl], cpos, np.iinfo(np.int64).max), coff[:-1])
    nxt = flat[start + (shift + 1) % n]
    prv = flat[start + (shift - 1) % n]
    flip = np.where(closed, prv < nxt, first > last)
    one = np.minimum(1, n - 1)
    head = np.where(closed, flat[start + shift], np.where(flip, last, first))
    second = np.where(closed, np.where(flip, prv, nxt),
                      np.where(flip, flat[offsets[1:] - 1 - one], flat[start + one]))
    order = np.lexsort((second, head))
    # source position of output entry q of output line j (= input line order[j]):
    # base + sign * q, taken modulo the length for closed lines
    base = np.where(closed, shift, np.where(flip, n - 1, 0))[order]
    sign = np.where(flip, -1, 1)[order]
    new_len = n[order]
    new_off = np.r_[0, np.cumsum(new_len)].astype(np.int64)
    new_line = np.repeat(np.arange(L), new_len)
    q = np.arange(flat.size) - new_off[new_line]
    pos = base[new_line] + sign[new_line] * q
    cl_entries = np.flatnonzero(closed[order][new_line]) if ci.size else np.empty(0, dtype=np.int64)
    pos[cl_entries] %= new_len[new_line[cl_entries]]
    pos += start[order][new_line]
    flat = flat[pos]
    for a in (flat, new_off):
        a.setflags(write=False)
    closed = closed[order].copy()
    closed.setflags(write=False)
    return StructureLines(flat, new_off, closed)


def windows(lines: StructureLines, *, return_line: bool = False) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Consecutive vertex quadruples ``(p0, p1, p2, p3)`` of every structure line.

    An open line of ``L`` vertices gives ``L - 3`` windows; a closed line of ``L``
    vertices gives ``L`` windows that wrap around.

    Parameters
    ----------
    lines : StructureLines
        From :func:`structure_lines`.
    return_line : bool
        Also return the line index of every window.

    Returns
    -------
    windows : (w, 4) int64
    line : (w,) int64, only if ``return_line``

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> windows(structure_lines(grid(1 + 1, 5))).tolist()
    [[0, 1, 2, 3], [1, 2, 3, 4], [5, 6, 7, 8], [6, 7, 8, 9]]
    """
    ext, start, count = _window_walk(lines)
    w = ext[start[:, None] + np.arange(4)]
    return (w, np.repeat(np.arange(len(count)), count)) if return_line else w


def _window_walk(lines: StructureLines) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(ext, start)`` of :attr:`Topology.window_walk`, and the number of windows of every line."""
    n = lines.lengths
    closed = lines.closed
    wraps = closed & (n >= 3)
    ext_len = n + 3 * wraps
    ext_off = np.r_[0, np.cumsum(ext_len)].astype(np.int64)
    line = np.repeat(np.arange(len(n)), ext_len)
    q = np.arange(ext_off[-1], dtype=np.int64) - ext_off[line]
    nl = n[line]
    q[q >= nl] -= nl[q >= nl]  # the repeated head of a closed line
    ext = lines.indices[lines.offsets[:-1][line] + q]
    count = np.where(closed, np.where(n >= 3, n, 0), np.maximum(n - 3, 0))
    first = np.cumsum(count) - count
    start = np.repeat(ext_off[:-1] - first, count) + np.arange(count.sum(), dtype=np.int64)
    for a in (ext, start):
        a.setflags(write=False)
    return ext, start, count


def structure_lines(mesh: QuadMesh) -> StructureLines:
    """Structure lines of both families through a quad mesh.

    See the module docstring for the tracing convention. Cached on the mesh's
    topology, so calling it again is free.

    Examples
    --------
    >>> from quadnodes.mesh import cylinder
    >>> lines = structure_lines(cylinder(3, 5))
    >>> int(lines.closed.sum()), len(lines)
    (3, 8)
    """
    from . import _validate

    return _validate.quad_mesh(mesh).topology.structure_lines


def boundary_vertices(mesh: QuadMesh) -> np.ndarray:
    """Mask of vertices on the boundary, ``(n,) bool``."""
    from . import _validate

    return _validate.quad_mesh(mesh).topology.boundary_vertices.copy()


def corner_vertices(mesh: QuadMesh, *, angle: float = CORNER_ANGLE) -> np.ndarray:
    """Mask of boundary corners: where the boundary turns, ``(n,) bool``.

    A boundary vertex ``v`` that is not a regular boundary point (valence ≠ 3 or
    not two faces: convex, reflex and hole corners — :attr:`Topology.corner_vertices`),
    with boundary neighbours ``a`` (before) and ``b`` (after) and the boundary
    vertices ``a2``, ``b2`` two steps away, is a corner when

    - the boundary turns by more than ``angle`` degrees at ``v``: the angle between
      ``v − a`` and ``b − v`` exceeds ``angle``, **and**
    - it still turns by more than ``angle`` across two edges: the angle between
      ``v − a2`` and ``b2 − v`` exceeds ``angle``;

    or when two boundary arcs touch at ``v`` (more than two boundary edges). The
    second condition tells a real corner (the end of a side: both scales turn
    by about 90°) from a step of a staircase boundary (an MIQ-like mesh whose
    boundary steps left and right along the quads: 90° at every step vertex, about
    0° across two edges), whose vertices are then not corners and may move. Valence
    alone would hold every step; the angle alone would make noise on a smooth
    boundary into corners: both are asked. On a rectangular grid the corners are
    its four corner vertices, as by valence.

    Parameters
    ----------
    mesh : QuadMesh
    angle : float
        Turning angle in degrees (0 < angle < 180), default :data:`CORNER_ANGLE`.

    Returns
    -------
    (n,) bool

    Raises
    ------
    InputError
        On an angle outside (0, 180).

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> np.flatnonzero(corner_vertices(grid(3, 3))).tolist()
    [0, 2, 6, 8]
    >>> from quadnodes.mesh import QuadMesh
    >>> v = [[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0], [1, 1, 0], [2, 1, 0], [1, 2, 0], [2, 2, 0]]
    >>> stair = QuadMesh(np.array(v, float), np.array([[0, 1, 4, 3], [1, 2, 5, 4], [4, 5, 7, 6]]))
    >>> np.flatnonzero(corner_vertices(stair)).tolist()  # vertex 4, the step, turns 90° but is no corner
    [0, 2, 3, 6, 7]
    """
    from . import _validate
    _validate.quad_mesh(mesh)
    from .errors import InputError

    angle = _validate.finite_number(angle, "angle")
    if not 0 < angle < 180:
        raise InputError(f"angle: expected degrees between 0 and 180, got {angle!r}")
    topo = mesh.topology
    n = mesh.n_vertices
    x = mesh.vertices
    if topo.closed_grid is not None:  # a cylinder's boundary is its two end rings, regular throughout; a torus has none
        return np.zeros(n, dtype=bool)
    if topo.grid_shape is not None:  # the boundary loop by index arithmetic (the test below is the
        rows, cols = topo.grid_shape  # same walked either way round)
        ids = np.arange(n, dtype=np.int64).reshape(rows, cols)
        start = np.concatenate([ids[0, :-1], ids[:-1, -1], ids[-1, :0:-1], ids[:0:-1, 0]])
        end = np.roll(start, -1)
    else:
        bnd_he = np.flatnonzero(topo.he_twin < 0)
        start, end = topo.he_start[bnd_he], topo.he_end[bnd_he]
    nxt = np.full(n, -1, dtype=np.int64)
    prv = np.full(n, -1, dtype=np.int64)
    nxt[start] = end
    prv[end] = start
    touching = topo._boundary_count > 2
    v = np.flatnonzero(topo.corner_vertices & ~touching)
    a, b = prv[v], nxt[v]
    a2, b2 = prv[a], nxt[b]
    cos_max = np.cos(np.radians(angle))

    def turns(p: np.ndarray, q: np.ndarray) -> np.ndarray:
        u, w = x[v] - x[p], x[q] - x[v]
        nu = np.linalg.norm(u, axis=1)
        nw = np.linalg.norm(w, axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            c = np.einsum("ij,ij->i", u, w) / (nu * nw)
        return ~(c >= cos_max)  # degenerate (0/0) counts as a turn

    mask = touching & topo.boundary_vertices
    mask[v] = turns(a, b) & turns(a2, b2)
    return mask


def adjacency(mesh: QuadMesh) -> sp.csr_matrix:
    """Symmetric vertex adjacency along mesh edges (no quad diagonals), ``(n, n)``."""
    indptr, indices, _ = mesh.topology.ring
    n = mesh.n_vertices
    return sp.csr_matrix((np.ones(indices.size), indices, indptr), shape=(n, n))


#: The names of the fixing modes accepted by every method (``fix=``).
FIX_MODES: tuple[str, ...] = ("none", "corners", "boundary")


def fixed_vertices(mesh: QuadMesh, fix: str = "none", fixed: object = None) -> np.ndarray:
    """The vertices a method holds in place: a fixing mode plus the user's own selection.

    The one fixing vocabulary of quadnodes: every method, node and report takes
    ``fix`` (a mode) and ``fixed`` (more vertices) and resolves them here.

    Parameters
    ----------
    mesh : QuadMesh
    fix : {"none", "corners", "boundary"}
        ``"corners"``: the boundary corners, where the boundary turns (:func:`corner_vertices`);
        ``"boundary"``: every boundary vertex.
    fixed : (n,) bool or int indices, optional
        More vertices to hold (a boolean mask or a list of indices; an integer
        array of zeros and ones of length ``n`` is refused as ambiguous).
        A vertex in no face (an OBJ's unreferenced vertex) is always held.

    Returns
    -------
    (n,) bool
        A new array.

    Raises
    ------
    InputError
        On an unknown mode or a malformed ``fixed``.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> int(fixed_vertices(grid(4, 4), "boundary").sum())
    12
    >>> np.flatnonzero(fixed_vertices(grid(3, 3), "corners", fixed=[4])).tolist()
    [0, 2, 4, 6, 8]
    """
    from . import _validate

    _validate.quad_mesh(mesh)
    mode = _validate.choice(fix, FIX_MODES, "fix")
    n = mesh.n_vertices
    mask = _validate.vertex_mask(fixed, n, "fixed")
    if mode == "corners":
        mask |= corner_vertices(mesh)
    elif mode == "boundary":
        mask |= mesh.topology.boundary_vertices
    mask |= mesh.topology.vertex_face_count == 0  # a vertex in no face: no energy acts on it, so every method holds it
    return mask


def as_grid(mesh: QuadMesh) -> QuadMesh | None:
    """The mesh renumbered as a ``rows × cols`` vertex grid when its connectivity is one, else None.

    Recognizes a topological grid from the faces alone, whatever the order of its
    faces and the numbering of its vertices (as Rhino or COMPAS write OBJ files):
    a disk with four corners of valence 2, every other boundary vertex of valence 3
    and every interior vertex of valence 4. The corner with the smallest index becomes
    vertex 0; row 0 runs along the corner's boundary line whose next vertex has the
    smaller index; vertex ``i*cols + j`` is then row ``i``, column ``j``, faces are
    listed row by row (orientation kept) and ``grid_shape`` is set, so panels are
    labelled ``P_<row>_<col>`` and fairing takes its grid path. Vertex numbers
    change (a ``fixed`` list in the file's numbering must be mapped by position).

    A cylinder grid (every interior vertex of valence 4, two boundary loops of
    valence-3 vertices) and a torus grid (every vertex of valence 4, no boundary)
    are recognized too, by their structure lines: the rows are closed lines, the
    columns the lines of the other family, each crossing every row once.
    Row 0 is, on a cylinder, the boundary loop holding the smallest boundary
    vertex, on a torus the closed line through the smallest vertex whose next
    vertex has the smaller index; it starts at that vertex (column 0) and runs
    towards that smaller neighbour; column 0 runs from it towards row 1 in the
    direction of its smaller neighbour (on a cylinder: away from the boundary).
    The seam lies between the last column (row) and column (row) 0, and
    ``grid_wrap`` says which way the grid closes: ``(False, True)`` for a
    cylinder, ``(True, True)`` for a torus. A line that runs around more than
    once (a torus glued with a shift, whose columns are helices) is no grid: None.
    On a torus grid whose rows and columns have the same length the two
    families are interchangeable; the rule above picks one, from the vertex
    numbering.

    Parameters
    ----------
    mesh : QuadMesh

    Returns
    -------
    QuadMesh or None
        ``mesh`` itself when it already has a ``grid_shape``; a renumbered copy
        (same unit) when it is a grid; None otherwise.

    Examples
    --------
    >>> from quadnodes.mesh import grid, QuadMesh
    >>> g = grid(3, 4)
    >>> rng = np.random.default_rng(0)
    >>> p = rng.permutation(12)
    >>> inv = np.argsort(p)
    >>> shuffled = QuadMesh(g.vertices[p], inv[g.faces][rng.permutation(6)])
    >>> shuffled.grid_shape is None, as_grid(shuffled).grid_shape
    (True, (4, 3))
    """
    from .mesh import QuadMesh as _QuadMesh

    if mesh.grid_shape is not None:
        return mesh
    topo = mesh.topology
    n = mesh.n_vertices
    if topo.grid_shape is not None:
        return _QuadMesh(mesh.vertices, mesh.faces, grid_shape=topo.grid_shape, unit=mesh.unit)
    bnd = topo.boundary_vertices
    if not (topo.valence == 2).any() and np.array_equal(bnd, topo.regular_boundary) \
            and np.array_equal(~bnd, topo.regular_interior):
        return _as_closed_grid(mesh)
    corner = bnd & (topo.valence == 2) & (topo.vertex_face_count == 1)
    if (int(corner.sum()) != 4 or not np.array_equal(bnd, corner | topo.regular_boundary)
            or not np.array_equal(~bnd, topo.regular_interior)):
        return None
    lines = topo.structure_lines
    if lines.closed.any():
        return None
    c0 = int(np.flatnonzero(corner)[0])
    first = lines.indices[lines.offsets[:-1]]
    last = lines.indices[lines.offsets[1:] - 1]
    at_c0 = np.flatnonzero((first == c0) | (last == c0))
    if at_c0.size != 2:
        return None

    def oriented(i: int, head: int) -> np.ndarray:
        line = lines[i]
        return line if line[0] == head else line[::-1]

    a, b = (oriented(int(i), c0) for i in at_c0)
    row0, col0 = (a, b) if a[1] < b[1] else (b, a)
    cols = row0.size
    # the other line ending at every vertex of row 0 is a column
    on_row0 = np.full(n, -1, dtype=np.int64)
    on_row0[row0] = np.arange(cols)
    row0_line = at_c0[0] if np.array_equal(oriented(int(at_c0[0]), c0), row0) else at_c0[1]
    is_col = ((on_row0[first] >= 0) | (on_row0[last] >= 0)) & (np.arange(len(lines)) != row0_line)
    col_ids = np.flatnonzero(is_col)
    lengths = lines.lengths[col_ids]
    rows = col0.size
    if col_ids.size != cols or not (lengths == rows).all() or rows * cols != n or rows < 2 or cols < 2:
        return None
    seq = lines.indices[lines.offsets[col_ids][:, None] + np.arange(rows)]  # (cols, rows)
    flip = on_row0[seq[:, 0]] < 0
    seq[flip] = seq[flip, ::-1]
    j = on_row0[seq[:, 0]]
    if (j < 0).any() or unique_values(j).size != cols:
        return None
    G = np.empty((rows, cols), dtype=np.int64)
    G[:, j] = seq.T
    order = G.reshape(-1)
    faces = _renumbered_faces(mesh.faces, order, n)
    if faces is None:
        return None
    faces = faces[np.argsort(faces.min(axis=1), kind="stable")]
    if _grid_shape(faces, n) != (rows, cols):
        return None
    return _QuadMesh(mesh.vertices[order], faces, grid_shape=(rows, cols), unit=mesh.unit)


def _as_closed_grid(mesh: QuadMesh) -> QuadMesh | None:
    """:func:`as_grid` for a cylinder or torus grid (every line through a regular vertex), else None."""
    from .mesh import QuadMesh as _QuadMesh

    topo = mesh.topology
    n = mesh.n_vertices
    used = topo.vertex_face_count > 0
    if not used.all():
        return None
    lines = topo.structure_lines
    bnd = topo.boundary_vertices
    ln = lines.lengths
    L = len(ln)
    line_of = np.repeat(np.arange(L), ln)
    pos = np.arange(lines.indices.size) - lines.offsets[:-1][line_of]
    # every vertex on exactly two lines (one of each family), never twice on one
    per_vertex = np.bincount(lines.indices, minlength=n)
    if (per_vertex != 2).any() or unique_values(lines.indices * L + line_of).size != lines.indices.size:
        return None
    # the two lines at every vertex, and the vertex's place on each
    by_vertex = np.argsort(lines.indices, kind="stable").reshape(n, 2)
    at_line, at_pos = line_of[by_vertex], pos[by_vertex]
    is_cylinder = bool(bnd.any())
    if is_cylinder:  # the rows are the closed lines, two of them the boundary loops
        v0 = int(np.flatnonzero(bnd)[0])
        if int(lines.closed[unique_values(line_of[lines.indices == v0])].sum()) != 1:
            return None
        k = int(np.flatnonzero(lines.closed[at_line[v0]])[0])
    else:  # torus: of the two lines through the smallest vertex, row 0 turns to the smaller neighbour
        v0 = 0
        if not lines.closed.all():
            return None
        k = int(np.argmin([lines[int(li)][1] for li in at_line[v0]]))
    row0_line = int(at_line[v0, k])
    row0 = np.roll(lines[row0_line], -int(at_pos[v0, k]))  # canonical: starts at v0 when v0 is its smallest
    if row0[0] != v0:
        return None
    if row0.size > 2 and lines.closed[row0_line] and row0[1] > row0[-1]:
        row0 = np.r_[row0[:1], row0[:0:-1]]
    cols = row0.size
    # the other line through every vertex of row 0 is its column
    other = np.where(at_line[row0, 0] == row0_line, 1, 0)
    col_line = at_line[row0, other]
    col_pos = at_pos[row0, other]
    if unique_values(col_line).size != cols or (col_line == row0_line).any():
        return None
    rows = int(ln[col_line[0]])
    if (ln[col_line] != rows).any() or rows * cols != n or rows < 2 or cols < 3:
        return None
    closed_cols = lines.closed[col_line]
    if is_cylinder:  # columns: open lines from one boundary loop to the other
        if closed_cols.any() or int(lines.closed.sum()) != rows:
            return None
        step = np.where(col_pos == 0, 1, -1)
    else:
        if not closed_cols.all() or L != rows + cols or rows < 3:
            return None
        # column 0 runs towards its smaller neighbour; the others keep to the same side of row 0:
        # their next vertex lies on row 1, the line through column 0's next vertex
        c0 = lines[int(col_line[0])]
        p0 = int(col_pos[0])
        ahead, back = int(c0[(p0 + 1) % rows]), int(c0[(p0 - 1) % rows])
        w = min(ahead, back)
        row1 = at_line[w, 1] if at_line[w, 0] == col_line[0] else at_line[w, 0]
        nxt = lines.indices[lines.offsets[col_line] + (col_pos + 1) % rows]
        step = np.where(_on_line(lines, row1, nxt, n), 1, -1)
    q = (col_pos[:, None] + step[:, None] * np.arange(rows)) % rows  # (cols, rows)
    G = lines.indices[lines.offsets[col_line][:, None] + q].T  # (rows, cols)
    order = G.reshape(-1)
    faces = _renumbered_faces(mesh.faces, order, n)
    if faces is None:
        return None
    wrap = (not is_cylinder, True)
    base = grid_cell_base(faces, rows, cols, wrap_rows=wrap[0], wrap_cols=wrap[1])
    if (base < 0).any():
        return None
    faces = faces[np.argsort(base, kind="stable")]
    out = _QuadMesh(mesh.vertices[order], faces, grid_shape=(rows, cols), unit=mesh.unit)
    return out if out.grid_wrap == wrap else None


def _on_line(lines: StructureLines, line: int, vertices: np.ndarray, n: int) -> np.ndarray:
    """Whether each of ``vertices`` lies on structure line ``line``, ``(k,) bool``."""
    on = np.zeros(n, dtype=bool)
    on[lines[int(line)]] = True
    return on[vertices]
