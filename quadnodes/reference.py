"""Closest points on a design surface: a build123d face or a reference quad mesh.

:func:`quadnodes.planarization.planarize` and :func:`quadnodes.fairing.fair` (option
``reference``) pull vertices towards the design surface rather than towards
their old positions, so that they may slide along it. Both ask a
:class:`Reference` for the closest surface point of many points at once.

A face is sampled once on a fine grid of its parameters (the vectorized B-spline
or closed-form path of :func:`quadnodes.surfaces.sample`) and handled like a
reference mesh. Each quad is split into two triangles; a point's closest point
is searched among the triangles around its nearest reference vertex (a k-d
tree query, then one vectorized point-triangle region test for all candidates,
:func:`_triangle_coordinates`, with each triangle's own dot products computed
once; points in blocks of :data:`CHUNK`) — exact whenever the foot point lies in a quad around that vertex,
which holds for points within about an edge length of a smooth, evenly sampled
surface (the tests compare with trimesh's exhaustive search), and about 10×
faster than that search. The answer is the closest point on the piecewise-flat fine
mesh: its distance from the true surface is the chord error of the sampling,
about ``κ s² / 8`` for curvature ``κ`` and sample spacing ``s`` (4 samples per
mesh edge by default: 1/128 of the chord error of the mesh itself).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from . import _validate
from .errors import InputError
from .linalg import compiled as _compiled
from .mesh import QuadMesh

__all__ = ["Reference", "as_reference", "warm_up"]

#: Nearest reference vertices whose quads are searched for each point.
NEAREST = 1
#: Points handled at once by :meth:`Reference.closest` (bounds its temporary arrays).
CHUNK = 16384
#: From this many points on (or once :func:`warm_up` has loaded it), the region test runs compiled
#: (:mod:`quadnodes._reference_kernels`, the same closest points) on the solver's threads: loading Numba
#: costs about a second per process, more than the NumPy path takes for one call below this.
COMPILED_MIN_POINTS = 250_000


class Reference:
    """A surface to find closest points on, from a quad mesh (see the module text).

    Parameters
    ----------
    mesh : QuadMesh
        The reference surface, as quads (each split into two triangles along ``p0p2``).
    source : str
        What it was made from, for reports (``"mesh"`` or ``"face"``).

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> ref = Reference(grid(3, 3))
    >>> p, d = ref.closest(np.array([[0.5, 0.5, 2.0], [3.0, 1.0, 0.0]]))
    >>> p.tolist(), d.tolist()
    ([[0.5, 0.5, 0.0], [2.0, 1.0, 0.0]], [2.0, 1.0])
    """

    def __init__(self, mesh: QuadMesh, *, source: str = "mesh") -> None:
        from scipy.spatial import cKDTree

        self.mesh = _validate.quad_mesh(mesh, "reference")
        self.source = source
        f = mesh.faces
        # faces around each vertex, padded with -1 (rows of a ragged incidence list)
        m = len(f)
        flat = f.reshape(-1)
        order = np.argsort(flat, kind="stable")
        counts = np.bincount(flat, minlength=mesh.n_vertices)
        start = np.concatenate([[0], np.cumsum(counts)[:-1]])
        slot = np.arange(flat.size) - np.repeat(start, counts)
        table = np.full((mesh.n_vertices, max(int(counts.max()), 1)), -1, dtype=np.int64)
        table[flat[order], slot] = order // 4
        self._faces_of = table
        self._m = m
        self._tree = cKDTree(mesh.vertices)
        # per triangle: corner a, edges ab and ac, and their dot products (the point-independent part of
        # the closest-point test, computed once)
        tri = np.concatenate([f[:, [0, 1, 2]], f[:, [0, 2, 3]]])  # (2m, 3): each quad split along p0p2
        v = mesh.vertices
        self._a = v[tri[:, 0]]
        self._ab = v[tri[:, 1]] - self._a
        self._ac = v[tri[:, 2]] - self._a
        self._gram = np.stack([np.einsum("ij,ij->i", self._ab, self._ab), np.einsum("ij,ij->i", self._ab, self._ac),
                               np.einsum("ij,ij->i", self._ac, self._ac)], axis=1)

    @classmethod
    def from_face(cls, face: Any, nu: int, nv: int) -> Reference:
        """Sample a build123d face on an ``nu × nv`` grid (see :func:`quadnodes.surfaces.sample`)."""
        from . import surfaces

        return cls(surfaces.sample(face, nu, nv), source="face")

    def closest(self, points: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Closest point on the reference and the distance to it, for every point.

        Parameters
        ----------
        points : (k, 3) float64

        Returns
        -------
        closest : (k, 3) float64
        distance : (k,) float64
        """
        p = np.asarray(points, dtype=np.float64)
        if p.ndim != 2 or p.shape[1] != 3:
            raise InputError(f"points: expected shape (k, 3), got {p.shape}")
        out = np.empty_like(p)
        kernel = _compiled_kernel(len(p))
        if kernel is not None:
            self._closest_compiled(p, out, kernel)
        else:
            for lo in range(0, len(p), CHUNK):  # blocks of points: the candidate arrays stay in cache
                out[lo:lo + CHUNK] = self._closest(p[lo:lo + CHUNK])
        return out, np.linalg.norm(out - p, axis=1)

    def _closest_compiled(self, p: np.ndarray, out: np.ndarray, kernel: Any) -> None:
        """:meth:`_closest` for all points at once: the k-d tree and the compiled test on the pool's threads."""
        from .linalg.threads import run_tasks, split_ranges

        ranges = split_ranges(len(p), min_size=CHUNK)
        k = min(NEAREST, self.mesh.n_vertices)
        _, near = self._tree.query(p, k=k, workers=len(ranges))
        cand = self._faces_of[near.reshape(len(p), k)].reshape(len(p), -1)
        args = (p, self._a, self._ab, self._ac, self._gram, cand, self._m, out)
        run_tasks(kernel, [args + r for r in ranges])

    def _closest(self, p: np.ndarray) -> np.ndarray:
        k = min(NEAREST, self.mesh.n_vertices)
        _, near = self._tree.query(p, k=k)
        near = near.reshape(len(p), k)
        faces = self._faces_of[near].reshape(len(p), -1)  # (k_pts, NEAREST*valence), -1 padded
        # the same face may come from several near vertices: harmless, it just repeats
        valid = faces >= 0
        cand = np.where(valid, faces, 0)
        tri = np.concatenate([cand, cand + self._m], axis=1)  # both triangles of each quad
        v, w, d2 = _triangle_coordinates(p, self._a, self._ab, self._ac, self._gram, tri)
        d2[~np.concatenate([valid, valid], axis=1)] = np.inf
        best = np.argmin(d2, axis=1)
        rows = np.arange(len(p))
        t = tri[rows, best]
        return self._a[t] + v[rows, best, None] * self._ab[t] + w[rows, best, None] * self._ac[t]


def _load_kernel() -> None:
    """First call of the compiled region test (loads its machine code; :func:`quadnodes.linalg.compiled.also_load`)."""
    from ._reference_kernels import closest_on_candidates

    z = np.zeros((1, 3))  # the first call loads (or, the first time ever, compiles) the machine code
    closest_on_candidates(z, z, z, z, z, np.zeros((1, 1), dtype=np.int64), 1, np.empty((1, 3)), 0, 1)


_compiled.also_load(_load_kernel)


def warm_up() -> None:
    """Start loading the compiled kernels, this module's closest-point test among them, on a daemon thread
    (:func:`quadnodes.linalg.compiled.warm_up`: once per process; returns at once).

    A caller that will ask for many closest points in many calls (``planarize`` on a large mesh)
    starts it early; :meth:`Reference.closest` uses the kernel as soon as it is loaded.

    Examples
    --------
    >>> from quadnodes.linalg import compiled
    >>> compiled.ready() in (True, False)  # (not started here: later doctests' paths stay)
    True
    """
    _compiled.warm_up()


def _compiled_kernel(points: int) -> Any:
    """The compiled region test if the kernels are loaded, or loaded now for ``points`` ≥ :data:`COMPILED_MIN_POINTS`; else None."""
    if not _compiled.ready() and points >= COMPILED_MIN_POINTS:
        _compiled.wait()
    if not _compiled.ready():
        return None
    from ._reference_kernels import closest_on_candidates

    return closest_on_candidates


def _triangle_coordinates(p: np.ndarray, a: np.ndarray, ab: np.ndarray, ac: np.ndarray, gram: np.ndarray,
                          tri: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Barycentric coordinates ``(v, w)`` of the closest point of ``p[i]`` on triangle ``tri[i, j]``, and its squared distance.

    Ericson's region test (*Real-Time Collision Detection*, 5.1.5) for every
    point–candidate pair at once: only the two dot products ``ab·ap`` and ``ac·ap``
    depend on the point; the triangle's own dot products (``gram``: ``ab·ab``,
    ``ab·ac``, ``ac·ac``) are computed once. The closest point is ``a + v ab + w ac``.

    Parameters
    ----------
    p : (k, 3) float64
    a, ab, ac : (t, 3) float64
        Each triangle's first corner and its two edges from it.
    gram : (t, 3) float64
    tri : (k, c) int64
        Candidate triangles of each point.

    Returns
    -------
    v, w, d2 : (k, c) float64
    """
    ap = p[:, None, :] - a[tri]
    e1, e2 = ab[tri], ac[tri]
    d1 = np.einsum("kcj,kcj->kc", e1, ap)
    d2 = np.einsum("kcj,kcj->kc", e2, ap)
    g = gram[tri]
    bb, bc, cc = g[..., 0], g[..., 1], g[..., 2]
    d3, d4 = d1 - bb, d2 - bc  # ab·bp, ac·bp
    d5, d6 = d1 - bc, d2 - cc  # ab·cp, ac·cp
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        inside_v, inside_w = vb / denom, vc / denom
        t_ab = d1 / (d1 - d3)
        t_ac = d2 / (d2 - d6)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
    conds = [
        (d1 <= 0) & (d2 <= 0),                              # vertex a
        (d3 >= 0) & (d4 <= d3),                             # vertex b
        (vc <= 0) & (d1 >= 0) & (d3 <= 0),                  # edge ab
        (d6 >= 0) & (d5 <= d6),                             # vertex c
        (vb <= 0) & (d2 >= 0) & (d6 <= 0),                  # edge ac
        (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0),        # edge bc
    ]
    zero, one = np.zeros_like(d1), np.ones_like(d1)
    v = np.select(conds, [zero, one, t_ab, zero, zero, 1.0 - t_bc], inside_v)
    w = np.select(conds, [zero, zero, zero, one, t_ac, t_bc], inside_w)
    # a degenerate (zero-area) triangle leaves no finite interior answer: fall back to its corner a
    bad = ~(np.isfinite(v) & np.isfinite(w))
    v[bad] = 0.0
    w[bad] = 0.0
    r = ap - v[..., None] * e1 - w[..., None] * e2
    return v, w, np.einsum("kcj,kcj->kc", r, r)


def as_reference(reference: Any, like: QuadMesh, *, samples: int = 4, name: str = "reference") -> Reference:
    """A :class:`Reference` from a Reference, a QuadMesh or a build123d face.

    Parameters
    ----------
    reference : Reference, QuadMesh or build123d Face
    like : QuadMesh
        The mesh that will be pulled to it; a reference mesh in another unit is
        converted to ``like.unit``. A face is sampled ``samples`` times
        as finely as ``like`` (its grid shape, or ``√n × √n`` without one), and
        at least 64 × 64.
    samples : int
        Samples per mesh edge for a face (>= 1).
    name : str
        Parameter name for error messages.

    Raises
    ------
    InputError
        If ``reference`` is none of the above.
    """
    if isinstance(reference, Reference):
        if reference.mesh.unit != like.unit:  # the same surface in the mesh's unit (a declared unit: exact)
            return Reference(reference.mesh.with_unit(like.unit), source=reference.source)
        return reference
    if isinstance(reference, QuadMesh):
        return Reference(reference.with_unit(like.unit))
    samples = _validate.positive_int(samples, f"{name}_samples")
    try:
        from build123d import Face
    except ImportError:  # pragma: no cover - build123d is a dependency
        Face = ()  # type: ignore[assignment]
    if isinstance(reference, Face):
        if like.grid_shape is not None:
            nu, nv = like.grid_shape
        else:
            nu = nv = int(np.ceil(np.sqrt(like.n_vertices)))
        return Reference.from_face(reference, max(64, samples * (nu - 1) + 1), max(64, samples * (nv - 1) + 1))
    raise InputError(
        f"{name}: expected a QuadMesh, a build123d Face or a Reference, got {type(reference).__name__}"
    )
