"""A fairness term for the vertices that are no window's middle: line ends and short lines (beyond the thesis).

The thesis's energy (eq. 32) has one term per *window* of four consecutive vertices of a structure line.
A vertex that is the middle of no window — an extraordinary vertex, where lines end, or the middle
vertex of a line of three vertices between two of them — has no term of its own and is never moved.
On meshes made mostly of short lines (a Catmull–Clark subdivided polygon mesh: 464 of its 528 lines have
three vertices) that is most of the mesh.

The term here is the structure-line energy carried to the edge 1-ring. The **mean turning** of a vertex
``v`` with ``k`` arms (the edges along which lines leave it; on the boundary the two boundary edges) is

    t_v = (2/k) Σ_j (p_j − p_v) / l_v

with ``l_v`` the mean length of its arms (``line_spacing="fair"``) or each arm's own length
(``"hold"``), frozen at the current iterate, so ``t`` is linear in the points. At a vertex inside one
line (``k = 2``, own lengths) it is the line's turning vector ``u1 − u0``; at a regular vertex the mean
of its two lines' turning vectors; at a symmetric star of any valence it is zero. Eq. 30's window
term is half the *change* of turning between the window's two middle points, ``(t2 − t1)/2``; the term
here is the same along every arm ``(v, j)`` of a vertex ``v`` that is no window's middle::

    f_vj = s · (t_v − t_j) / 2,        s = RING_SCALE

Like the window term it vanishes on evenly turning runs (a straight line, a circle's arc, a sphere's
regular star) and is dimensionless; unlike the pseudo-windows of
:func:`quadnodes.fairing.extraordinary_windows` it asks no line to go straight on through a vertex of
valence 3 or 5, so a regular extraordinary vertex costs nothing.

Detection follows the same rule as along the lines (:mod:`quadnodes.zigzag`): with
``detection="alternating"`` an arm's measure is ``max(0, −t_v · t_j)`` (the turnings of neighbours
pointing to opposite sides: a zigzag), with ``"thesis"`` eq. 30's ``||t_v − t_j||²/4``; both of its
vertices count, as both middle points of a window do. It is compared with ``LINE_END_MARGIN ×
threshold`` (clean designs turn unevenly at their stars), and a line end is freed with a free
neighbour along its arms too, so that the ring a freed vertex is faired against can move with it
(:func:`line_end_free`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from . import _validate
from ._arrays import unique_rows

__all__ = ["RING_SCALE", "LINE_END_MARGIN", "ring_arms", "turning_matrix", "line_end_arms", "line_end_rows",
           "line_end_energy", "line_end_measure", "line_end_free"]

#: Scale ``s`` of the rows (energy: ``s²``) relative to a window's, measured on ``polygon_quads.obj``
#: (0.2, 0.3, 0.5, 0.75, 1 with every vertex free; ``docs/fairing.md``, "Line ends and short lines").
RING_SCALE = 0.5
#: A line end is found when its measure exceeds ``LINE_END_MARGIN × threshold``: the mean turnings of
#: neighbours of different valence differ on clean designs by their uneven stars — on the clean meshes of
#: ``tests/data`` up to 0.088 (alternating) and 0.29 (eq. 30), on ``polygon_quads.obj``, against 0.019 and
#: 0.1+ along its lines — so 4 × the default thresholds (0.12, 0.4) leaves every clean mesh untouched,
#: while noise of 0.2 h gives medians of 0.15–0.6 (``docs/fairing.md``, "Line ends and short lines").
LINE_END_MARGIN = 4.0


def ring_arms(topology: object, where: np.ndarray | None = None) -> np.ndarray:
    """Directed arms ``(v, j)``: every edge at an interior vertex, the boundary edges at a boundary vertex.

    Parameters
    ----------
    topology : quadnodes.topology.Topology
    where : (n,) bool or int indices, optional
        Only the arms of these vertices (the rows of the whole ring whose ``v`` is one), made from the
        edges at them alone, so their cost follows the selection, not the mesh: fairing asks for the few
        vertices that are no window's middle.

    Returns
    -------
    (a, 2) int64
        Sorted by ``v``, then ``j``; each interior edge appears once per direction.

    Raises
    ------
    InputError
        On a malformed ``where`` (as ``fixed`` in :func:`quadnodes.topology.fixed_vertices`).

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> ring_arms(grid(2, 2).topology).tolist()  # a single quad: every vertex is on the boundary
    [[0, 1], [0, 2], [1, 0], [1, 3], [2, 0], [2, 3], [3, 1], [3, 2]]
    >>> t = grid(3, 3).topology
    >>> ring_arms(t, t.vertex_face_count == 4).tolist()  # the centre's four arms
    [[4, 1], [4, 3], [4, 5], [4, 7]]
    >>> ring_arms(t, [1]).tolist()  # an edge middle: its two boundary edges
    [[1, 0], [1, 2]]
    """
    if where is not None:
        where = _validate.vertex_mask(where, topology.n_vertices, "where")  # type: ignore[attr-defined]
    e = topology.edges  # type: ignore[attr-defined]
    be = topology.boundary_edges  # type: ignore[attr-defined]
    bnd = topology.boundary_vertices  # type: ignore[attr-defined]
    if where is not None:  # (two gathers over the edges; the sort below then sees only the marked vertices' arms)
        at = where[e[:, 0]] | where[e[:, 1]]
        e, be = e[at], be[at]
    d = np.concatenate([e, e[:, ::-1]])
    on_b = np.concatenate([be, be])
    keep = ~bnd[d[:, 0]] | on_b
    if where is not None:
        keep &= where[d[:, 0]]
    arm = d[keep]
    return arm[np.lexsort((arm[:, 1], arm[:, 0]))]


def _arms_of(topology: object, pairs: np.ndarray) -> np.ndarray:
    """The arms of the vertices of ``pairs`` only: the rows of ``T`` that the line-end rows use."""
    used = np.zeros(topology.n_vertices, dtype=bool)  # type: ignore[attr-defined]
    used[pairs.reshape(-1)] = True
    return ring_arms(topology, used)


def turning_matrix(vertices: np.ndarray, arms: np.ndarray, *, line_spacing: str = "fair") -> sp.csr_matrix:
    """The ``(n, n)`` matrix ``T`` with ``(T @ P)[v]`` = the mean turning ``t_v`` of vertex ``v``.

    Parameters
    ----------
    vertices : (n, 3) float64
        Positions the arm lengths are frozen at.
    arms : (a, 2) int64
        From :func:`ring_arms`.
    line_spacing : {"fair", "hold"}
        ``"fair"``: every arm of ``v`` divided by the mean arm length at ``v`` (so a vertex slid
        along an arm is seen); ``"hold"``: each arm by its own length.

    Returns
    -------
    (n, n) scipy.sparse.csr_matrix
        Each row sums to zero (translation invariant); rows of vertices without arms are empty.

    Examples
    --------
    >>> v = np.array([[0., 0, 0], [1, 0, 0], [3, 0, 0]])
    >>> arms = np.array([[1, 0], [1, 2]])
    >>> (turning_matrix(v, arms, line_spacing="hold") @ v)[1].tolist()  # straight: no turning
    [0.0, 0.0, 0.0]
    >>> (turning_matrix(v, arms) @ v)[1].round(6).tolist()  # uneven spacing is seen with the mean length 1.5
    [0.666667, 0.0, 0.0]
    """
    line_spacing = _validate.choice(line_spacing, ("fair", "hold"), "line_spacing")
    n = vertices.shape[0]
    v, j = arms[:, 0], arms[:, 1]
    length = np.linalg.norm(np.take(vertices, j, axis=0) - np.take(vertices, v, axis=0), axis=1)
    k = np.bincount(v, minlength=n)
    if line_spacing == "fair":
        mean = np.bincount(v, weights=length, minlength=n) / np.maximum(k, 1)
        length = mean[v]
    w = 2.0 / (k[v] * length)
    diag = -np.bincount(v, weights=w, minlength=n)
    rows = np.concatenate([v, np.arange(n)])
    return sp.csr_matrix((np.concatenate([w, diag]), (rows, np.concatenate([j, np.arange(n)]))), shape=(n, n))


def line_end_arms(topology: object, where: np.ndarray) -> np.ndarray:
    """The undirected arms ``(v, j)`` that get a term: those of the vertices ``where`` (each edge once).

    Arms with an end at a boundary corner (:attr:`~quadnodes.topology.Topology.corner_vertices`: a
    boundary vertex with one face or more than two) are left out: the boundary's turning there is the
    corner's designed kink, not a zigzag, as a line continued through an extraordinary vertex would be.

    Parameters
    ----------
    topology : quadnodes.topology.Topology
    where : (n,) bool or int indices
        The vertices whose arms get a term (in :func:`quadnodes.fairing.fair`: the middle of no window).

    Returns
    -------
    (r, 2) int64

    Raises
    ------
    InputError
        On a malformed ``where`` (as in :func:`ring_arms`).

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> t = grid(3, 3).topology
    >>> line_end_arms(t, ~t.window_middle).tolist()  # the centre's arms (the edge middles' lead to corners)
    [[1, 4], [3, 4], [4, 5], [4, 7]]
    """
    arms = ring_arms(topology, where)
    corner = topology.corner_vertices  # type: ignore[attr-defined]
    a = arms[~corner[arms].any(axis=1)]
    if len(a) == 0:
        return np.empty((0, 2), dtype=np.int64)
    return unique_rows(np.sort(a, axis=1)).astype(np.int64)


def line_end_rows(vertices: np.ndarray, topology: object, pairs: np.ndarray, *, scale: float | None = None,
                  line_spacing: str = "fair") -> sp.csr_matrix:
    """The ``(r, n)`` matrix of the rows ``s (t_v − t_j)/2`` for the arms ``pairs``, lengths frozen at ``vertices``.

    Parameters
    ----------
    vertices : (n, 3) float64
    topology : quadnodes.topology.Topology
    pairs : (r, 2) int64
        From :func:`line_end_arms`.
    scale : float, optional
        ``s``; default :data:`RING_SCALE`.
    line_spacing : {"fair", "hold"}
        See :func:`turning_matrix`.

    Returns
    -------
    (r, n) scipy.sparse.csr_matrix
        Each row sums to zero.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> m = grid(3, 3)
    >>> t = m.topology
    >>> R = line_end_rows(m.vertices, t, line_end_arms(t, ~t.window_middle))
    >>> float(abs(R @ m.vertices).max())  # a flat regular grid: every turning is zero
    0.0
    """
    n = vertices.shape[0]
    scale = RING_SCALE if scale is None else scale
    T = turning_matrix(vertices, _arms_of(topology, pairs), line_spacing=line_spacing)
    r = len(pairs)
    half = 0.5 * scale
    S = sp.csr_matrix((np.r_[np.full(r, half), np.full(r, -half)], (np.r_[np.arange(r), np.arange(r)],
                                                                      np.r_[pairs[:, 0], pairs[:, 1]])), shape=(r, n))
    return (S @ T).tocsr()


def line_end_energy(vertices: np.ndarray, topology: object, pairs: np.ndarray, *,
                    lengths_from: np.ndarray | None = None, scale: float | None = None,
                    line_spacing: str = "fair") -> float:
    """``Σ ||f_vj||²`` of the arms ``pairs`` at ``vertices``, lengths frozen at ``lengths_from`` (default: ``vertices``).

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> m = grid(3, 3)
    >>> t = m.topology
    >>> line_end_energy(m.vertices, t, line_end_arms(t, ~t.window_middle))
    0.0
    """
    ref = vertices if lengths_from is None else lengths_from
    f = line_end_rows(ref, topology, pairs, scale=scale, line_spacing=line_spacing) @ vertices
    return float(np.einsum("ij,ij->", f, f))


def line_end_measure(vertices: np.ndarray, topology: object, pairs: np.ndarray, *, detection: str = "alternating",
                     line_spacing: str = "fair") -> np.ndarray:
    """Per-vertex zigzag measure of the arms ``pairs``: the maximum over the arms at each vertex, ``(n,)``.

    ``"alternating"``: ``max(0, −t_v · t_j)``; ``"thesis"``: ``||t_v − t_j||²/4`` (eq. 30 with the mean
    turnings in place of a line's). Both ends of an arm get its value; vertices on no arm get 0.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> z = np.zeros((3, 3)); z[1, 1] = 0.5; z[0, 1] = z[2, 1] = -0.5
    >>> m = grid(3, 3, height=z)  # the centre up, two edge middles down: the turnings alternate
    >>> t = m.topology
    >>> pairs = line_end_arms(t, ~t.window_middle)
    >>> a = line_end_measure(m.vertices, t, pairs)
    >>> a[[1, 4, 7]].round(3).tolist(), float(a[[0, 2, 3, 5, 6, 8]].max())
    ([1.06, 1.06, 1.06], 0.0)
    >>> line_end_measure(m.vertices, t, pairs, detection="thesis")[[1, 4, 7]].round(3).tolist()
    [1.081, 1.081, 1.081]
    """
    detection = _validate.choice(detection, ("alternating", "thesis"), "detection")
    n = vertices.shape[0]
    t = turning_matrix(vertices, _arms_of(topology, pairs), line_spacing=line_spacing) @ vertices
    a, b = t[pairs[:, 0]], t[pairs[:, 1]]
    if detection == "alternating":
        val = np.maximum(0.0, -np.einsum("ij,ij->i", a, b))
    else:
        d = a - b
        val = 0.25 * np.einsum("ij,ij->i", d, d)
    out = np.zeros(n)
    np.maximum.at(out, pairs.reshape(-1), np.repeat(val, 2))
    return out


def line_end_free(vertices: np.ndarray, topology: object, pairs: np.ndarray, free: np.ndarray, held: np.ndarray,
                  threshold: float, *, detection: str = "alternating", line_spacing: str = "fair") -> np.ndarray:
    """``free`` with the line ends added: measure above ``LINE_END_MARGIN × threshold``, or a free arm neighbour.

    Parameters
    ----------
    vertices : (n, 3) float64
    topology : quadnodes.topology.Topology
    pairs : (r, 2) int64
        From :func:`line_end_arms`.
    free : (n,) bool
        The vertices found along the lines (:func:`quadnodes.zigzag.detect`).
    held : (n,) bool
        Vertices that never move.
    threshold : float
    detection, line_spacing : str
        See :func:`line_end_measure`.

    Returns
    -------
    (n,) bool
        A new mask; ``held`` vertices are never in it (unless already in ``free``).

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> z = np.zeros((3, 3)); z[1, 1] = 0.5; z[0, 1] = z[2, 1] = -0.5
    >>> m = grid(3, 3, height=z)
    >>> t = m.topology
    >>> none = np.zeros(9, bool)
    >>> line_end_free(m.vertices, t, line_end_arms(t, ~t.window_middle), none, none, 0.03).astype(int).tolist()
    [0, 1, 0, 1, 1, 1, 0, 1, 0]
    """
    found = line_end_measure(vertices, topology, pairs, detection=detection, line_spacing=line_spacing)
    out = free | ((found > LINE_END_MARGIN * threshold) & ~held)
    near = np.zeros(out.shape[0], dtype=bool)
    near[pairs[:, 0][out[pairs[:, 1]]]] = True
    near[pairs[:, 1][out[pairs[:, 0]]]] = True
    return out | (near & ~held)
