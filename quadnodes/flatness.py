"""Per-quad planarity measures."""

from __future__ import annotations

import numpy as np

from . import _validate
from ._arrays import cross_rows, norm_rows
from .errors import InputError
from .mesh import QuadMesh
from .units import parse_length

__all__ = [
    "diagonal_distance",
    "quad_diagonal_distance",
    "angle_defect",
    "planarity",
    "summary",
    "resolve_planar_tolerance",
    "planar_panels",
    "folded_panels",
    "nonconvex_panels",
    "simple_panels",
    "DEFAULT_PLANAR_TOLERANCE",
]

DEFAULT_PLANAR_TOLERANCE: float = 1e-3
"""The package's one default ``planar_tolerance``: relative diagonal distance
``1e-3`` (e.g. 1.4 mm across a 1 m × 1 m panel). It is the planarize target, so a
mesh planarized with the defaults is written as plane faces by every exporter
(see docs/design-notes.md, session 5)."""


def diagonal_distance(mesh: QuadMesh, *, relative: bool = True) -> np.ndarray:
    """Distance between the two diagonal lines of every quad.

    A quad is planar exactly when its diagonals ``p0p2`` and ``p1p3`` intersect,
    i.e. when the distance between the two (infinite) diagonal lines is zero.

    Parameters
    ----------
    mesh : QuadMesh
    relative : bool
        Divide by the mean diagonal length of the quad (default), which makes the
        measure scale-free; otherwise return the distance in model units.

    Returns
    -------
    (m,) float64
        Non-negative, 0 for a planar quad.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> float(diagonal_distance(grid(3, 3)).max())
    0.0
    >>> m = grid(2, 2, height=[[0, 0], [0, 1]])
    >>> round(float(diagonal_distance(m)[0]), 4)  # one lifted corner
    0.2595
    """
    _validate.quad_mesh(mesh)
    return quad_diagonal_distance(mesh.vertices, mesh.faces, relative=relative)


def quad_diagonal_distance(vertices: np.ndarray, faces: np.ndarray, *, relative: bool = True) -> np.ndarray:
    """:func:`diagonal_distance` from plain arrays (no :class:`QuadMesh` checks), for inner loops.

    Examples
    --------
    >>> v = np.array([[0., 0, 0], [1, 0, 0], [1, 1, 1], [0, 1, 0]])
    >>> round(float(quad_diagonal_distance(v, np.array([[0, 1, 2, 3]]))[0]), 4)
    0.2595
    """
    # coordinates as rows, (3, m): every pass below runs on contiguous rows (NumPy's cross product and
    # norms over an inner dimension of 3 are several times slower); the same operations in the same order
    X = np.ascontiguousarray(np.asarray(vertices, dtype=np.float64).T)
    F = np.ascontiguousarray(np.asarray(faces).T)
    p0, p1, p2, p3 = (np.take(X, F[k], axis=1) for k in range(4))
    d1, d2 = p2 - p0, p3 - p1
    n = cross_rows(d1, d2)
    nn, l1, l2 = norm_rows(n), norm_rows(d1), norm_rows(d2)
    w = p1 - p0
    skew = nn > 1e-12 * l1 * l2
    dot = w[0] * n[0]
    dot += w[2] * n[2]  # (the order of np.einsum("ij,ij->i") on rows of 3, which this replaced: same bits)
    dot += w[1] * n[1]
    with np.errstate(divide="ignore", invalid="ignore"):
        dist = np.abs(dot) / nn
    # parallel diagonals (degenerate quad): distance between the parallel lines
    par = ~skew
    if par.any():
        dist[par] = norm_rows(cross_rows(w[:, par], d1[:, par])) / np.maximum(l1[par], 1e-300)
    if relative:
        dist = dist / (0.5 * (l1 + l2))
    return dist


def angle_defect(mesh: QuadMesh) -> np.ndarray:
    """The thesis's angle-sum defect ``φ1 + φ2 + φ3 + φ4 − 2π`` of every quad.

    ``φk`` is the angle at corner ``k`` between its two edges. A planar convex quad
    has defect 0; a skew quad has a negative defect.

    Returns
    -------
    (m,) float64, radians

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> abs(float(angle_defect(grid(2, 2))[0])) < 1e-12
    True
    """
    _validate.quad_mesh(mesh)
    _validate.quad_mesh(mesh)
    p = mesh.vertices[mesh.faces]
    a = np.roll(p, 1, axis=1) - p
    b = np.roll(p, -1, axis=1) - p
    cos = np.einsum("fkj,fkj->fk", a, b) / (np.linalg.norm(a, axis=2) * np.linalg.norm(b, axis=2))
    return np.arccos(np.clip(cos, -1.0, 1.0)).sum(axis=1) - 2 * np.pi


def planarity(mesh: QuadMesh) -> dict[str, np.ndarray]:
    """Both planarity measures of every quad.

    Returns
    -------
    dict
        ``"diagonal"``: relative diagonal distance ``(m,)``; ``"angle_defect"``:
        angle-sum defect in radians ``(m,)``.
    """
    _validate.quad_mesh(mesh)
    return {"diagonal": diagonal_distance(mesh), "angle_defect": angle_defect(mesh)}


def summary(values: np.ndarray) -> dict[str, float]:
    """Mean, median, 95th percentile and max of ``|values|``.

    Examples
    --------
    >>> summary(np.array([0.0, -1.0, 3.0]))["max"]
    3.0
    """
    a = np.abs(np.asarray(values, dtype=np.float64))
    if a.size == 0:
        return {"mean": 0.0, "median": 0.0, "p95": 0.0, "max": 0.0}
    return {
        "mean": float(a.mean()),
        "median": float(np.median(a)),
        "p95": float(np.percentile(a, 95)),
        "max": float(a.max()),
    }


def resolve_planar_tolerance(planar_tolerance: float | str, unit: str = "mm") -> tuple[str, float]:
    """Read a ``planar_tolerance`` setting: relative (a number) or a length (text such as ``"2 mm"``).

    Parameters
    ----------
    planar_tolerance : float or str
        A number (>= 0) is relative: diagonal distance / mean diagonal of the
        panel. Text ``"<number> <unit>"`` is the diagonal distance as a length.
    unit : str
        The mesh's unit, into which a length is converted.

    Returns
    -------
    kind : {"relative", "length"}
    value : float
        The relative tolerance, or the length in ``unit``.

    Raises
    ------
    InputError
        On a negative, non-finite or unreadable value, naming ``planar_tolerance``.

    Examples
    --------
    >>> resolve_planar_tolerance(1e-3)
    ('relative', 0.001)
    >>> resolve_planar_tolerance("2 mm", "m")
    ('length', 0.002)
    """
    if isinstance(planar_tolerance, str):
        kind, value = "length", parse_length(planar_tolerance, unit, "planar_tolerance")
    else:
        kind, value = "relative", _validate.finite_number(planar_tolerance, "planar_tolerance")
    if value < 0:
        raise InputError(f"planar_tolerance: must be >= 0, got {planar_tolerance!r}")
    return kind, value


def simple_panels(mesh: QuadMesh) -> np.ndarray:
    """Which quads are simple polygons in their own plane: neither folded (bow-tie) nor degenerate.

    The plane of a quad is the mid-plane of its two diagonal lines (normal
    ``(p2 - p0) × (p3 - p1)``); seen along that normal a convex quad turns the
    same way at all four corners, a dart (one reflex corner) at three, a bow-tie
    at two. A quad with parallel diagonals (zero vector area) is not simple.

    Returns
    -------
    (m,) bool

    Examples
    --------
    >>> square, dart, bowtie = [0, 1, 2, 3], [0, 1, 4, 3], [0, 5, 1, 3]
    >>> v = np.array([[0., 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.2, 0.2, 0], [2, 1.5, 0]])
    >>> [bool(simple_panels(QuadMesh(v, [f]))[0]) for f in (square, dart, bowtie)]
    [True, True, False]
    """
    p = mesh.vertices[mesh.faces]
    n = np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 1])
    nn = np.linalg.norm(n, axis=1)
    e = np.roll(p, -1, axis=1) - p  # edge k: corner k -> k+1
    turn = np.einsum("fkj,fj->fk", np.cross(np.roll(e, 1, axis=1), e), n)  # at corner k
    scale = np.linalg.norm(e, axis=2).max(axis=1)
    nonzero = nn > 1e-12 * scale * scale
    return nonzero & ((turn < 0).sum(axis=1) <= 1)


def planar_panels(mesh: QuadMesh, planar_tolerance: float | str = DEFAULT_PLANAR_TOLERANCE) -> np.ndarray:
    """Which panels are planar within ``planar_tolerance`` (relative, or a length such as ``"2 mm"``).

    The one test every exporter and the panel schedule use, so they agree on
    which panels are planar. A panel is planar when its diagonal distance
    (:func:`diagonal_distance`, relative or as a length) is at most the
    tolerance **and** it is a simple polygon in its plane (:func:`simple_panels`;
    a folded or degenerate quad cannot be a plane face whatever its distance).
    Its corners then lie exactly half the diagonal distance from that plane,
    the most any corner moves when an exporter flattens it.

    Returns
    -------
    (m,) bool

    Raises
    ------
    InputError
        On a negative, non-finite or unreadable ``planar_tolerance``.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> m = grid(2, 3, spacing=1000.0, height=[[0, 0, 0], [0, 0, 1]])  # mm, one corner up 1 mm
    >>> planar_panels(m, "2 mm").tolist(), planar_panels(m, 1e-4).tolist()
    ([True, True], [True, False])
    """
    kind, value = resolve_planar_tolerance(planar_tolerance, mesh.unit)
    return (diagonal_distance(mesh, relative=(kind == "relative")) <= value) & simple_panels(mesh)


def folded_panels(mesh: QuadMesh, planar_tolerance: float | str) -> np.ndarray:
    """Flat panels (within ``planar_tolerance``) whose outline crosses itself: bow-ties, ``(m,) bool``.

    Such a panel is neither a plane face (its edges intersect) nor a sound
    bilinear patch (the patch folds over itself); every exporter refuses it,
    naming the panel (see :func:`simple_panels`).

    Examples
    --------
    >>> from quadnodes.mesh import QuadMesh
    >>> v = np.array([[0., 0, 0], [2, 1, 0], [2, 0, 0], [0, 2, 0]])  # p0p1 crosses p2p3
    >>> folded_panels(QuadMesh(v, [[0, 1, 2, 3]]), 1e-3).tolist()
    [True]
    """
    kind, value = resolve_planar_tolerance(planar_tolerance, mesh.unit)
    flat = diagonal_distance(mesh, relative=(kind == "relative")) <= value
    against, no_area = _validate.corner_turns(mesh.vertices, mesh.faces)
    return flat & (against >= 2) & ~no_area


def nonconvex_panels(mesh: QuadMesh) -> np.ndarray:
    """Panels with a corner turning against the others (darts and bow-ties), ``(m,) bool``.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> nonconvex_panels(grid(3, 3)).any()
    np.False_
    """
    against, _ = _validate.corner_turns(mesh.vertices, mesh.faces)
    return against >= 1
