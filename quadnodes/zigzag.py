"""Zigzag measures along structure lines (thesis eq. 30) and detection of free vertices."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from . import _validate
from .mesh import QuadMesh
from .linalg import compiled as _compiled, threads as _threads
from .topology import fixed_vertices

__all__ = [
    "window_edges",
    "window_deviation",
    "window_alternation",
    "vertex_deviation",
    "ZigzagReport",
    "detect",
    "DETECTIONS",
    "DEFAULT_DETECTION",
    "DEFAULT_THRESHOLDS",
    "GAPS_MODES",
    "DEFAULT_GAPS",
    "line_gaps",
]

#: The values of ``detection``: ``"alternating"`` (turning that flips side) or ``"thesis"`` (eq. 30).
DETECTIONS: tuple[str, ...] = ("alternating", "thesis")
#: Chosen by measurement (``benchmarks/studies/bench_real_meshes.py``, ``docs/real-meshes.md``).
DEFAULT_DETECTION = "alternating"
#: ``threshold`` when none is given, per detection: the thesis's 0.1 for eq. 30, which is large on steady
#: design bends too; 0.03 for the alternating turning, which is zero on steady bends — the largest on the clean
#: meshes of ``tests/data`` and E1–E4 is 0.019 (``polygon_quads.obj``; 0.0015 elsewhere), and broadband noise
#: below 0.1 is then found too (``docs/fairing.md``, "Thresholds for broadband noise").
DEFAULT_THRESHOLDS: Mapping[str, float] = MappingProxyType({"alternating": 0.03, "thesis": 0.1})


#: The values of ``gaps`` in :func:`quadnodes.fairing.fair`: ``"fair"`` frees a vertex that lies between two
#: found vertices of a line too (:func:`line_gaps`), ``"hold"`` only the found vertices (the thesis).
GAPS_MODES: tuple[str, ...] = ("fair", "hold")
#: ``gaps="auto"`` per detection: the alternating turning is zero at a vertex whose two
#: neighbours turn to the same side, so a jittered vertex between two found ones is found only through them
#: (``"fair"``); eq. 30 is the thesis, which moves only what it finds (``"hold"``) — ``docs/fairing.md``.
DEFAULT_GAPS: Mapping[str, str] = MappingProxyType({"alternating": "fair", "thesis": "hold"})


def line_gaps(free: np.ndarray, windows: np.ndarray, fixed: np.ndarray) -> np.ndarray:
    """``free`` with the gaps filled: a vertex whose two neighbours along a line are free becomes free.

    Within a window ``p0 p1 p2 p3``, ``p1`` is freed when ``p0`` and ``p2`` are, ``p2`` when ``p1`` and
    ``p3`` are. A found region is filled, not grown: a lone spike and the vertices found around it stay
    as they are.

    Parameters
    ----------
    free : (n,) bool
        Found vertices (:attr:`ZigzagReport.free`).
    windows : (w, 4) int64
    fixed : (n,) bool
        Vertices that never become free (:attr:`ZigzagReport.fixed`: held, or the middle of no window).

    Returns
    -------
    (n,) bool
        A new mask, a superset of ``free``.

    Examples
    --------
    >>> w = np.array([[0, 1, 2, 3], [1, 2, 3, 4], [2, 3, 4, 5]])  # one line of 6 vertices
    >>> free = np.array([0, 1, 0, 1, 0, 0], bool)
    >>> line_gaps(free, w, np.array([1, 0, 0, 0, 0, 1], bool)).astype(int).tolist()  # 2 lies between 1 and 3
    [0, 1, 1, 1, 0, 0]
    """
    gap = np.zeros(free.shape[0], dtype=bool)
    gap[windows[free[windows[:, 0]] & free[windows[:, 2]], 1]] = True
    gap[windows[free[windows[:, 1]] & free[windows[:, 3]], 2]] = True
    return free | (gap & ~fixed)


def _threshold(threshold: object, detection: str) -> object:
    """``threshold``, or the detection's default (:data:`DEFAULT_THRESHOLDS`) when it is None."""
    return DEFAULT_THRESHOLDS[detection] if threshold is None else threshold


def window_edges(vertices: np.ndarray, windows: np.ndarray) -> list[np.ndarray]:
    """The three edge vectors ``p1 − p0, p2 − p1, p3 − p2`` of every window, each ``(w, 3)``.

    Four row gathers (``np.take``, several times faster than fancy indexing of
    an ``(n, 3)`` array) instead of one ``(w, 4, 3)`` array keep the temporaries small.

    Examples
    --------
    >>> v = np.array([[0., 0, 0], [1, 0, 0], [1, 2, 0], [1, 2, 3]])
    >>> [e.tolist() for e in window_edges(v, np.array([[0, 1, 2, 3]]))]
    [[[1.0, 0.0, 0.0]], [[0.0, 2.0, 0.0]], [[0.0, 0.0, 3.0]]]
    """
    p = [np.take(vertices, windows[:, k], axis=0) for k in range(4)]
    for k in (3, 2, 1):
        p[k] -= p[k - 1]
    return p[1:]


def window_deviation(vertices: np.ndarray, windows: np.ndarray) -> np.ndarray:
    """Deviation ``||(u0 + u2)/2 − u1||²`` of every window (thesis eq. 30).

    Parameters
    ----------
    vertices : (n, 3) float64
    windows : (w, 4) int64
        Consecutive vertex quadruples ``p0..p3`` of structure lines.

    Returns
    -------
    (w,) float64
        0 for a straight (or evenly turning) run; at most 4 (a full reversal).

    Examples
    --------
    >>> v = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0], [1, 1, 0], [2, -1, 0.]])
    >>> window_deviation(v, np.array([[0, 1, 2, 3], [0, 4, 5, 3]])).round(3).tolist()
    [0.0, 2.632]
    """
    return _window_geometry(vertices, windows)[0]


def window_alternation(vertices: np.ndarray, windows: np.ndarray) -> np.ndarray:
    """Alternating turning of every window: ``max(0, −t1·t2)`` with ``t1 = u1 − u0``, ``t2 = u2 − u1``.

    ``u0, u1, u2`` are the unit directions of the window's three edges, ``t1`` and
    ``t2`` the turning vectors at its two middle points. Eq. 30 is ``||t2 − t1||²/4``:
    large when the line turns left then right (a zigzag, ``t2 ≈ −t1``) but also at a
    single sharp bend (``t2 ≈ 0``). This measure keeps only the part where the two
    turns point to opposite sides: 0 for a straight line, a steady bend (``t1·t2 > 0``)
    and a single kink (``t2 = 0``); equal to eq. 30 for a symmetric zigzag
    (``t2 = −t1``). Scale-free (unit directions), between 0 and 4.

    Parameters
    ----------
    vertices : (n, 3) float64
    windows : (w, 4) int64

    Returns
    -------
    (w,) float64

    Examples
    --------
    >>> v = np.array([[0, 0, 0], [1, 0, 0], [2, 1, 0], [3, 0, 0], [2, 2, 0], [2, 3, 0.]])
    >>> w = np.array([[0, 1, 2, 3], [0, 1, 2, 4]])  # a zigzag, then a steady left turn
    >>> window_alternation(v, w).round(3).tolist(), window_deviation(v, w).round(3).tolist()
    ([1.0, 0.0], [1.146, 0.086])
    """
    u = window_edges(vertices, windows)
    for d in u:
        d /= np.sqrt(np.einsum("ij,ij->i", d, d))[:, None]
    return np.maximum(0.0, -np.einsum("ij,ij->i", u[1] - u[0], u[2] - u[1]))


def _walk_alternation(vertices: np.ndarray, walk: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """:func:`window_alternation` of the topology's windows along its window walk (each edge once)."""
    ext, start = walk
    e, _ = _walk_edges(vertices, ext, unit=True)
    return _alternation(e, start)


def _walk_edges(vertices: np.ndarray, ext: np.ndarray, *, unit: bool = False,
                transposed: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Edge vectors ``(3, m - 1)`` along the walk ``ext`` (coordinates as rows: every pass below runs on
    contiguous rows, NumPy is several times slower on an inner dimension of 3) and their inverse lengths;
    ``unit``: the edges divided by their lengths; ``transposed``: ``vertices`` given as ``(3, n)`` rows already."""
    g = np.take(vertices if transposed else np.ascontiguousarray(vertices.T), ext, axis=1)
    e = g[:, 1:] - g[:, :-1]  # ext[j] -> ext[j+1]; where two lines meet, a meaningless edge
    g = g[:, 1:]
    np.multiply(e, e, out=g)
    length2 = g[0] + g[1]
    length2 += g[2]
    with np.errstate(divide="ignore", invalid="ignore"):  # (that may have length 0)
        inv = 1.0 / np.sqrt(length2, out=length2)
        if unit:
            e *= inv
    return e, inv


def _alternation(u: np.ndarray, start: np.ndarray) -> np.ndarray:
    """:func:`window_alternation` from the unit edge directions ``u`` ``(3, m - 1)`` along a walk."""
    t = u[:, 1:] - u[:, :-1]
    p = t[:, :-1] * t[:, 1:]
    a = p[0] + p[1]
    a += p[2]
    return np.maximum(0.0, -np.take(a, start))


def _window_geometry(
    vertices: np.ndarray, windows: np.ndarray, walk: tuple[np.ndarray, np.ndarray] | None = None,
    *, alternation: bool = False, even: bool = False,
) -> tuple[np.ndarray, ...]:
    """Deviation ``(w,)`` of every window and the inverse lengths ``(w, 3)`` of its edges.

    One pass serves detection and the fairing coefficients (which freeze these lengths).
    With the topology's ``walk`` (:attr:`quadnodes.topology.Topology.window_walk`, whose
    windows are ``windows``) every line edge is measured once instead of in each of
    the up to three windows that hold it; ``alternation`` (with ``walk``) adds
    :func:`window_alternation` ``(w,)`` from the same unit directions; ``even`` (with
    ``walk``) adds, last, the windows' even inverse lengths ``(w, 3)``
    (:func:`quadnodes.fairing.even_lengths` of the inverse lengths) and the window energies
    ``(w,)`` with them (``line_spacing="fair"``'s terms, as ``quadnodes.fairing._window_energy``
    computes them, to the last bit).
    """
    if walk is not None:
        ext, start = walk
        if _compiled.ready():  # (loaded by a server, a watch, a large grid's fair: one pass, the same numbers)
            return _compiled_window_geometry(vertices, ext, start, alternation, even)
        count = len(start)
        if count <= 2 * _WALK_CHUNK:
            return _walk_geometry(vertices, ext, start, alternation, even, transposed=False)
        # in pieces of windows whose temporaries stay in the cache (twice as fast on 300²; the same numbers), into
        # arrays laid out as one pass makes them (the inverse lengths a (3, w) array's transpose)
        rows = np.ascontiguousarray(vertices.T)
        out = [np.empty(count), np.empty((3, count)).T] + ([np.empty(count)] if alternation else []) \
            + ([np.empty((count, 3)), np.empty(count)] if even else [])
        for lo in range(0, count, _WALK_CHUNK):
            hi = min(count, lo + _WALK_CHUNK)
            starts = start[lo:hi]
            first, last = int(starts.min()), int(starts.max()) + 4  # (the stretch of the walk these windows reach)
            piece = _walk_geometry(rows, ext[first:last], starts - first, alternation, even, transposed=True)
            for whole, part in zip(out, piece):
                whole[lo:hi] = part
        return tuple(out)
    u = window_edges(vertices, windows)
    inverse = np.empty((len(windows), 3))
    for k, d in enumerate(u):
        length = np.sqrt(np.einsum("ij,ij->i", d, d))
        np.divide(1.0, length, out=inverse[:, k])
        d /= length[:, None]
    r = u[0]
    r += u[2]
    r *= 0.5
    r -= u[1]
    return np.einsum("ij,ij->i", r, r), inverse


#: Windows per piece of :func:`_window_geometry`'s NumPy pass along the window walk.
_WALK_CHUNK = 8192


def _walk_geometry(vertices: np.ndarray, ext: np.ndarray, start: np.ndarray, alternation: bool, even: bool, *,
                   transposed: bool) -> tuple[np.ndarray, ...]:
    """:func:`_window_geometry` of the windows starting at the walk positions ``start`` of ``ext``, by NumPy."""
    e, inv = _walk_edges(vertices, ext, transposed=transposed)
    with np.errstate(divide="ignore", invalid="ignore"):  # (an edge of length 0: its window's is nan)
        extra: tuple[np.ndarray, ...] = ()
        if even:
            # a window's mean length 3 / (l0 + l1 + l2) at every walk position (garbage where no window starts)
            length = 1.0 / inv
            mean = length[:-2] + length[1:-1]
            mean += length[2:]
            np.divide(3.0, mean, out=mean)
            half = 0.5 * mean
            f = e[:, :-2] * half
            f += e[:, 2:] * half
            f -= e[:, 1:-1] * mean
            f *= f
            energy = f[0] + f[1]
            energy += f[2]
            m = np.take(mean, start)
            extra = (np.repeat(m[:, None], 3, axis=1), np.take(energy, start))
        e *= inv
        r = e[:, :-2] + e[:, 2:]
        r *= 0.5
        r -= e[:, 1:-1]
        r *= r
        dev = r[0] + r[1]
        dev += r[2]
        inverse = np.empty((3, len(start)))  # (NumPy buffers a take into an out= unless mode="clip")
        for k in range(3):
            np.take(inv[k:], start, out=inverse[k], mode="clip")  # (start + k is inside inv)
        out = (np.take(dev, start), inverse.T)
        return out + ((_alternation(e, start),) if alternation else ()) + extra


#: Windows per thread below which the compiled geometry runs on one thread.
_PARALLEL_MIN_WINDOWS = 40_000


def _compiled_window_geometry(vertices: np.ndarray, ext: np.ndarray, start: np.ndarray, alternation: bool,
                              even: bool) -> tuple[np.ndarray, ...]:
    """:func:`_window_geometry` along a walk by :func:`quadnodes._window_kernels.window_geometry` (to the bit)."""
    from ._window_kernels import window_geometry

    V = np.ascontiguousarray(vertices, dtype=np.float64)
    ext, start = np.asarray(ext, dtype=np.int64), np.asarray(start, dtype=np.int64)  # (one compiled signature)
    w = len(start)
    dev, inverse = np.empty(w), np.empty((3, w))
    alt = np.empty(w if alternation else 0)
    mean, energy = (np.empty((w, 3)), np.empty(w)) if even else (np.empty((0, 3)), np.empty(0))
    args = (V, ext, start, dev, inverse, alt, mean, energy, alternation, even)
    ranges = _threads.split_ranges(w, min_size=_PARALLEL_MIN_WINDOWS)
    _threads.run_tasks(window_geometry, [args + r for r in ranges])
    out: tuple[np.ndarray, ...] = (dev, inverse.T)
    return out + ((alt,) if alternation else ()) + ((mean, energy) if even else ())


def _load_kernels() -> None:
    """First calls of the compiled window kernels (load their machine code; :func:`quadnodes.linalg.compiled.also_load`)."""
    from ._window_kernels import window_coefficients

    V = np.zeros((5, 3))
    V[:, 0] = np.arange(5.0)
    ext, start = np.arange(5, dtype=np.int64), np.array([0, 1], dtype=np.int64)
    ro = [a.copy() for a in (V, ext, start)]
    for a in ro:
        a.flags.writeable = False  # (a mesh's vertices and its topology's walk are read-only: Numba types them apart)
    for args in ((V, ext, start), tuple(ro), (V, ro[1], ro[2])):  # the input mesh's, and a faired iterate's
        _compiled_window_geometry(*args, True, True)
    for cols in ((V[:, 0], V[:, 1], V[:, 2]), tuple(np.ascontiguousarray(V.T))):  # strided and contiguous columns
        window_coefficients(*cols, np.empty((5, 4)), 0, 5)


_compiled.also_load(_load_kernels)


def _mesh_window_deviation(mesh: QuadMesh) -> np.ndarray:
    """:func:`window_deviation` of ``mesh.topology.windows`` along the topology's window walk
    (the numbers that :func:`detect` and :func:`quadnodes.fairing.fair` use, to the last bit)."""
    topo = mesh.topology
    return _window_geometry(mesh.vertices, topo.windows, topo.window_walk)[0]


def vertex_deviation(deviation: np.ndarray, windows: np.ndarray, n: int) -> np.ndarray:
    """Per-vertex maximum of the deviation over windows where it is a middle point.

    Parameters
    ----------
    deviation : (w,) float64
        From :func:`window_deviation`.
    windows : (w, 4) int64
    n : int
        Number of vertices.

    Returns
    -------
    (n,) float64
        0 for vertices that are a middle point of no window.

    Examples
    --------
    >>> vertex_deviation(np.array([0.5, 2.0]), np.array([[0, 1, 2, 3], [1, 2, 3, 4]]), 5).tolist()
    [0.0, 0.5, 2.0, 2.0, 0.0]
    """
    out = np.zeros(n)
    mid = windows[:, 1:3].reshape(-1)
    np.maximum.at(out, mid, np.repeat(deviation, 2))
    return out


@dataclass(frozen=True, eq=False)
class ZigzagReport:
    """What :func:`detect` found.

    Attributes
    ----------
    threshold : float
        A vertex is free when its deviation is strictly greater.
    window_deviation : (w,) float64
        Deviation of every window of ``windows``.
    windows : (w, 4) int64
        The windows of the mesh's structure lines.
    vertex_deviation : (n,) float64
        Max deviation over the windows in which the vertex is a middle point.
    fixed : (n,) bool
        Vertices held in place: on no window's middle, user-fixed, or boundary
        when asked.
    free : (n,) bool
        The measure of ``detection`` above ``threshold``, and not ``fixed`` — the zigzag vertices to fair.
    detection : {"alternating", "thesis"}
        The measure compared with ``threshold``: eq. 30 (``vertex_deviation``,
        ``"thesis"``) or the alternating turning (``vertex_alternation``).
    vertex_alternation : (n,) float64 or None
        Per-vertex maximum of :func:`window_alternation` (``"alternating"`` only).
    """

    threshold: float
    windows: np.ndarray
    window_deviation: np.ndarray
    vertex_deviation: np.ndarray
    fixed: np.ndarray
    free: np.ndarray
    fix: str = "corners"
    detection: str = "thesis"
    vertex_alternation: np.ndarray | None = None

    @property
    def n_free(self) -> int:
        """Number of free (zigzag) vertices."""
        return int(self.free.sum())

    @property
    def n_fixed(self) -> int:
        """Number of vertices held in place."""
        return int(self.fixed.sum())

    def to_dict(self) -> dict:
        """Plain-Python summary (JSON-ready): threshold, fixing, counts and deviation statistics."""
        return {"threshold": self.threshold, "detection": self.detection, "fix": self.fix, "n_fixed": self.n_fixed,
                **self.summary()}

    def summary(self) -> dict[str, float]:
        """Mean and max window deviation and the number of free vertices."""
        wd = self.window_deviation
        return {
            "deviation_mean": float(wd.mean()) if wd.size else 0.0,
            "deviation_max": float(wd.max()) if wd.size else 0.0,
            "n_free": float(self.n_free),
        }


@_validate.renamed(fix_boundary="fix='boundary'")
def detect(
    mesh: QuadMesh,
    threshold: float | None = None,
    *,
    fix: Literal["none", "corners", "boundary"] = "corners",
    fixed: ArrayLike | None = None,
    detection: Literal["alternating", "thesis"] = DEFAULT_DETECTION,
) -> ZigzagReport:
    """Find the zigzag vertices of a quad mesh.

    A vertex is free ("to be faired") when the deviation of some window in which
    it is one of the two middle points is strictly greater than ``threshold``.
    Vertices on no window's middle (corners, line ends at extraordinary vertices)
    are always fixed.

    Parameters
    ----------
    mesh : QuadMesh
    threshold : float, optional
        Deviation threshold (>= 0); the thesis uses 0.1 and, for strong noise, 1.
        Default: :data:`DEFAULT_THRESHOLDS` of the ``detection`` (0.03 alternating,
        0.1 thesis).
    fix : {"none", "corners", "boundary"}
        Vertices held in place (see :func:`quadnodes.topology.fixed_vertices`);
        corners lie in no window's middle, so they are never free anyway.
    fixed : (n,) bool or int indices, optional
        More vertices to hold in place.
    detection : {"alternating", "thesis"}
        ``"thesis"``: a window counts when its eq. 30 deviation exceeds ``threshold``
        (the thesis exactly). ``"alternating"`` (default): when its alternating
        turning (:func:`window_alternation`) does — a zigzag is found as by eq. 30,
        a steady sharp bend (a design feature) is not.

    Returns
    -------
    ZigzagReport

    Raises
    ------
    InputError
        On a negative or non-finite threshold, an unknown ``fix`` or a malformed ``fixed``.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> m = grid(3, 6, height=[[0, 0, 0, 0, 0, 0], [0, 0, 1, 0, 0, 0], [0] * 6])
    >>> detect(m, 0.1, detection="thesis").free.reshape(3, 6).astype(int).tolist()
    [[0, 0, 0, 0, 0, 0], [0, 1, 1, 1, 1, 0], [0, 0, 0, 0, 0, 0]]
    >>> detect(m, 0.1).free.reshape(3, 6).astype(int).tolist()  # vertex 10 lies on a straight run
    [[0, 0, 0, 0, 0, 0], [0, 1, 1, 1, 0, 0], [0, 0, 0, 0, 0, 0]]
    """
    _validate.quad_mesh(mesh)
    detection = _validate.choice(detection, DETECTIONS, "detection")
    threshold = _validate.nonnegative_number(_threshold(threshold, detection), "threshold")
    held = fixed_vertices(mesh, fix, fixed)
    alt = _walk_alternation(mesh.vertices, mesh.topology.window_walk) if detection == "alternating" else None
    return _detect(mesh, threshold, held, _mesh_window_deviation(mesh), fix, alt)


def _detect(mesh: QuadMesh, threshold: float, held: np.ndarray, wd: np.ndarray, fix: str = "corners",
            alternation: np.ndarray | None = None) -> ZigzagReport:
    """:func:`detect` with checked arguments: ``held`` the resolved fixed mask, ``wd`` the windows' deviation,
    ``alternation`` the windows' alternating turning when that is the detection (else eq. 30 decides)."""
    n = mesh.n_vertices
    topo = mesh.topology
    w = topo.windows
    vd = vertex_deviation(wd, w, n)
    va = None if alternation is None else vertex_deviation(alternation, w, n)
    fixed = held | ~topo.window_middle
    free = ((vd if va is None else va) > threshold) & ~fixed
    for a in (wd, vd, fixed, free) + (() if va is None else (va,)):
        a.setflags(write=False)
    return ZigzagReport(float(threshold), w, wd, vd, fixed, free, fix,
                        "thesis" if alternation is None else "alternating", va)
