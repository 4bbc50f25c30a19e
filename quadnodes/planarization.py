"""Planar panels: move the vertices of a quad mesh until every quad is flat.

Beyond the thesis (which leaves planarity as future work): :func:`planarize`
minimizes, over the vertices that may move,

.. math::

    E(x) = \\frac{w_p}{h^2} \\sum_{f} \\sum_{k=0}^{3} \\| (x_{f_k} - c_f) - q_{f_k} \\|^2
         + w_f \\sum_{\\text{windows}} \\| A x \\|^2
         + \\frac{w_c}{h^2} \\sum_i \\| x_i - t_i \\|^2

- **planarity** (``w_p``): ``c_f`` is the centroid of quad ``f`` and ``q_f`` its
  vertices projected onto the plane through the centroid parallel to both
  diagonals, centred — the closest flat quad up to a translation
  (ShapeUp's projection constraint). That plane leaves both diagonals at equal
  heights, so the projection moves every vertex by half the distance between
  the diagonals, which is exactly the measure of :func:`quadnodes.flatness.diagonal_distance`;
- **fairness** (``w_f``): the thesis's structure-line term (eq. 32) with the
  edge lengths of the input frozen, so straight, evenly spaced lines cost nothing;
- **closeness** (``w_c``): ``t_i`` is the input vertex, or with a ``reference``
  (a build123d face or a mesh) the closest point of ``x_i`` on it, so vertices
  may slide along the design surface.

It alternates a *local* step (project every quad, find closest points) with a
*global* step (one sparse linear solve for x, y and z; the matrix depends only
on the weights, so its factorization is reused while they stay fixed). When
the planarity stops improving before the tolerance is met, the planarity
weight is doubled (and the matrix factorized again). Where that still ends above
the tolerance, ``method="auto"`` continues from there with penalty Gauss–Newton
steps along the vertex normals and a growing planarity weight that never fold a
quad (:func:`_gauss_newton`; alone: ``method="gauss-newton"``), and if that misses
too, Gauss–Newton (SQP) steps from the input with planarity as a hard
constraint (:func:`_newton`). Weights are relative to
the mean edge length ``h`` of the input, so ``planarize(s·P) == s·planarize(P)``.
Fixed vertices never move.
"""

from __future__ import annotations

from collections.abc import Callable

import time
from dataclasses import asdict, dataclass, field, replace
from typing import Any, Literal

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike

from . import _validate
from ._arrays import cross_rows, norm_rows, unique_rows
from .errors import InputError
from .fairing import fairing_matrix
from .mesh import QuadMesh
from .flatness import diagonal_distance, quad_diagonal_distance
from .progress import report_progress
from .reference import Reference, as_reference
from .reference import warm_up as reference_kernel_warm_up
from .linalg import Factorization, QuadraticProblem, factorize, regularization
from .linalg.quadratic import DIRECT_LIMIT
from .topology import adjacency, fixed_vertices
from .flatness import DEFAULT_PLANAR_TOLERANCE, resolve_planar_tolerance

__all__ = ["planarize", "PlanarizeReport", "quad_plane_projection", "kept_shape_projection", "DEFAULT_TOLERANCE"]

#: Default planarity tolerance: diagonal distance / mean diagonal length — the package's one default
#: (:data:`quadnodes.flatness.DEFAULT_PLANAR_TOLERANCE`), which the exporters use too.
DEFAULT_TOLERANCE = DEFAULT_PLANAR_TOLERANCE
#: With a reference surface, a weak pull to the input positions keeps vertices from sliding far along it.
DEFAULT_INPUT_WEIGHT = 0.01
#: ``method="auto"`` tries Gauss–Newton (then Newton) steps after an unconverged local/global run up to this
#: many free vertices (each step factorizes a matrix of that size).
NEWTON_LIMIT = 20000
#: Above ``DIRECT_LIMIT`` free vertices the global step is CG from the current positions, to this relative
#: residual (the next local step projects the result anyway; 1e-8 of the right-hand side is far below the
#: planarity tolerance's scale).
LARGE_RTOL = 1e-8
#: The adaptive planarity weight grows at most this much over its start value.
MAX_WEIGHT_GROWTH = 1e6
#: An edge shorter than this share of its input length counts as collapsed: the result is not converged.
COLLAPSED_EDGE_RATIO = 0.2
#: ``shape="keep"``: the local step keeps every edge at least this share of its input length ...
KEPT_EDGE_RATIO = 0.3
#: ... and every corner of a quad that was convex at least this share of its input height over the chord
#: between its two neighbours (measured in the panel's plane), so no quad becomes a dart or a bow-tie.
KEPT_CORNER_HEIGHT = 0.2

Fix = Literal["none", "corners", "boundary"]
Shape = Literal["keep", "free"]


def quad_plane_projection(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Each quad's vertices projected onto its diagonal mid-plane, relative to the quad's centroid.

    The plane passes through the centroid and is parallel to both diagonals; the
    four projected points form a flat quad. For a quad whose diagonals are parallel
    (degenerate), the vertices are returned unprojected (centred).

    Parameters
    ----------
    vertices : (n, 3) float64
    faces : (m, 4) int64

    Returns
    -------
    (m, 4, 3) float64
        Centred, projected corner positions (each quad's rows sum to zero).

    Examples
    --------
    >>> v = np.array([[0., 0, 0], [1, 0, 0], [1, 1, 1], [0, 1, 0]])
    >>> q = quad_plane_projection(v, np.array([[0, 1, 2, 3]]))
    >>> np.round(q[0], 3).tolist()
    [[-0.5, -0.5, -0.5], [0.5, -0.5, 0.0], [0.5, 0.5, 0.5], [-0.5, 0.5, 0.0]]
    """
    X = np.ascontiguousarray(np.asarray(vertices, dtype=np.float64).T)  # (3, n): contiguous passes
    F = np.ascontiguousarray(np.asarray(faces).T)
    p = [np.take(X, F[k], axis=1) for k in range(4)]
    c = p[0] + p[1]  # (the mean's order: the same bits as before, as _ShapeKeeper.project's)
    c += p[2]
    c += p[3]
    c /= 4.0
    n = cross_rows(p[2] - p[0], p[3] - p[1])
    nn = norm_rows(n)
    n = np.divide(n, nn, out=np.zeros_like(n), where=nn > 0)
    q = np.empty((F.shape[1], 4, 3))
    for k in range(4):
        r = p[k] - c
        t = r[0] * n[0]
        t += r[2] * n[2]  # (np.einsum's order on rows of 3)
        t += r[1] * n[1]
        q[:, k, :] = (r - t * n).T
    return q


def _panel_coordinates(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, ...]:
    """Every quad projected onto its diagonal mid-plane, as complex in-plane coordinates.

    Returns ``(z, e1, e2, ok)``: ``z (m, 4) complex`` the centred corners in the
    orthonormal frame ``e1`` (along ``p2 − p0``), ``e2`` (``n × e1``, with ``n`` along
    the vector area ``(p2 − p0) × (p3 − p1)``, so a convex quad is counter-clockwise);
    ``ok`` is False where the diagonals are parallel (no plane).
    """
    p = vertices[faces]
    r = p - p.mean(axis=1, keepdims=True)
    d1 = p[:, 2] - p[:, 0]
    n = np.cross(d1, p[:, 3] - p[:, 1])
    nn = np.linalg.norm(n, axis=1, keepdims=True)
    l1 = np.linalg.norm(d1, axis=1, keepdims=True)
    ok = (nn[:, 0] > 0) & (l1[:, 0] > 0)
    n = np.divide(n, nn, out=np.zeros_like(n), where=nn > 0)
    e1 = np.divide(d1, l1, out=np.zeros_like(d1), where=l1 > 0)
    e2 = np.cross(n, e1)
    z = np.einsum("mkj,mj->mk", r, e1) + 1j * np.einsum("mkj,mj->mk", r, e2)
    return z, e1, e2, ok


def _corner_heights(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Height of every corner over the chord between its two neighbours (> 0: convex), and the chord's outward normal."""
    prv, nxt = np.roll(z, 1, axis=1), np.roll(z, -1, axis=1)
    d = nxt - prv
    ad = np.abs(d)
    out = np.divide(-1j * d, ad, out=np.zeros_like(d), where=ad > 0)  # right of prv -> nxt: outside a ccw quad
    return np.real(np.conj(out) * (z - 0.5 * (prv + nxt))), out


class _ShapeKeeper:
    """The local step of ``shape="keep"``: the closest planar quad, then the least change that keeps its shape.

    Built once from the input: every edge's least length (:data:`KEPT_EDGE_RATIO`
    of its input length) and, for a quad convex in the input, every corner's
    least height over the chord of its neighbours (:data:`KEPT_CORNER_HEIGHT` of its
    input height, in the quad's own mid-plane). :meth:`project` projects every quad
    onto its diagonal mid-plane (:func:`quad_plane_projection`); where that planar
    quad breaks a bound, a few Gauss–Seidel sweeps over its edges and corners move
    it, in its plane, to the nearest quad that keeps them (each bound is a
    least-norm correction: a short edge is stretched about its midpoint, a low
    corner lifted outwards while its neighbours give way). The result is planar by
    construction. Quads that keep their bounds get exactly the plain projection.
    """

    sweeps = 4

    def __init__(self, rest: np.ndarray, faces: np.ndarray) -> None:
        p = rest[faces]
        z, _, _, ok = _panel_coordinates(rest, faces)
        h, _ = _corner_heights(z)
        convex = ok & (h > 0).all(axis=1)
        self.faces = faces
        self.min_height = np.where(convex[:, None], KEPT_CORNER_HEIGHT * h, -np.inf)
        self.min_length = KEPT_EDGE_RATIO * np.linalg.norm(np.roll(p, -1, axis=1) - p, axis=2)
        # the same, corners as rows (project() works on (3, m) coordinate rows per corner)
        self._corners = np.ascontiguousarray(faces.T)
        self._min_height_rows = np.ascontiguousarray(self.min_height.T)
        self._min_length_rows = np.ascontiguousarray(self.min_length.T)

    def project(self, x: np.ndarray) -> tuple[np.ndarray, int]:
        """Centred target corners ``(m, 4, 3)`` and how many quads the bounds changed."""
        # the arithmetic of quad_plane_projection (bit for bit), sharing its normal with the bound check, on
        # (3, m) coordinate rows per corner: contiguous passes (NumPy's cross products, norms and einsums over
        # an inner dimension of 3 are several times slower); every sum in the order NumPy takes it there
        X = np.ascontiguousarray(x.T)
        p = [np.take(X, self._corners[k], axis=1) for k in range(4)]
        c = p[0] + p[1]
        c += p[2]
        c += p[3]
        c /= 4.0
        r = [pk - c for pk in p]
        d1 = p[2] - p[0]
        n = cross_rows(d1, p[3] - p[1])
        nn = norm_rows(n)
        n = np.divide(n, nn, out=np.zeros_like(n), where=nn > 0)
        l1 = norm_rows(d1)
        e1 = np.divide(d1, l1, out=np.zeros_like(d1), where=l1 > 0)
        e2 = cross_rows(n, e1)

        def along(v: np.ndarray, e: np.ndarray) -> np.ndarray:  # (the order of np.einsum("mkj,mj->mk"))
            out = v[0] * e[0]
            out += v[2] * e[2]
            out += v[1] * e[1]
            return out

        q = np.empty((len(nn), 4, 3))
        for k in range(4):
            q[:, k, :] = (r[k] - along(r[k], n) * n).T
        u = [along(rk, e1) for rk in r]  # in-plane coordinates (r and q differ only along n)
        w = [along(rk, e2) for rk in r]
        # a corner's height over its neighbours' chord d = z[k+1] − z[k−1], outwards: −(d × (z[k] − z[k−1]))/|d|
        bad = np.zeros(len(nn), dtype=bool)
        for k in range(4):
            kp, km = (k + 1) % 4, (k - 1) % 4
            du, dw = u[kp] - u[km], w[kp] - w[km]
            cross = du * (w[k] - w[km]) - dw * (u[k] - u[km])
            bad |= -cross < self._min_height_rows[k] * np.hypot(du, dw)
            bad |= np.hypot(u[kp] - u[k], w[kp] - w[k]) < self._min_length_rows[k]
        bad &= (nn > 0) & (l1 > 0)
        if not bad.any():
            return q, 0
        v = np.flatnonzero(bad)
        zk = self._repair(np.stack([u[k][v] + 1j * w[k][v] for k in range(4)], axis=1), self.min_length[v],
                          self.min_height[v])
        q[v] = zk.real[:, :, None] * e1[:, v].T[:, None, :] + zk.imag[:, :, None] * e2[:, v].T[:, None, :]
        return q, int(v.size)

    def _repair(self, z: np.ndarray, lmin: np.ndarray, hmin: np.ndarray) -> np.ndarray:
        z = z.copy()
        for _ in range(self.sweeps):
            for k in range(4):
                k1 = (k + 1) % 4
                e = z[:, k1] - z[:, k]
                le = np.abs(e)
                u = np.divide(e, le, out=np.ones_like(e), where=le > 0)
                dz = 0.5 * np.maximum(lmin[:, k] - le, 0.0) * u
                z[:, k1] += dz
                z[:, k] -= dz
            for k in range(4):
                km, kp = (k - 1) % 4, (k + 1) % 4
                d = z[:, kp] - z[:, km]
                ad = np.abs(d)
                out = np.divide(-1j * d, ad, out=np.zeros_like(d), where=ad > 0)
                lift = np.maximum(hmin[:, k] - np.real(np.conj(out) * (z[:, k] - 0.5 * (z[:, km] + z[:, kp]))), 0.0)
                # least-norm change meeting the corner's height: the corner moves 2/3, each neighbour 1/3 back
                z[:, k] += out * lift * (2.0 / 3.0)
                z[:, km] -= out * lift / 3.0
                z[:, kp] -= out * lift / 3.0
        return z - z.mean(axis=1, keepdims=True)


def kept_shape_projection(vertices: np.ndarray, faces: np.ndarray, *, rest: np.ndarray) -> np.ndarray:
    """Each quad's closest planar quad that keeps its shape bounds against ``rest`` (the local step of ``shape="keep"``).

    Like :func:`quad_plane_projection`, then, for a quad where that planar quad has
    an edge shorter than :data:`KEPT_EDGE_RATIO` of its length in ``rest`` or (if the
    quad is convex in ``rest``) a corner lower than :data:`KEPT_CORNER_HEIGHT` of its
    height there over the chord between its neighbours, moved in its plane until it
    (nearly) keeps them. Scale- and translation-equivariant.

    Parameters
    ----------
    vertices : (n, 3) float64
    faces : (m, 4) int64
    rest : (n, 3) float64
        The positions the bounds are measured on (the input of :func:`planarize`).

    Returns
    -------
    (m, 4, 3) float64
        Centred, planar target corners.

    Raises
    ------
    InputError
        On vertex or face arrays of the wrong shape or with bad indices, or ``rest``
        not shaped like ``vertices``.

    Examples
    --------
    >>> rest = np.array([[0., 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    >>> dart = rest.copy(); dart[2] = [0.2, 0.2, 0.1]   # corner 2 pushed inside the quad
    >>> q = kept_shape_projection(dart, np.array([[0, 1, 2, 3]]), rest=rest)
    >>> from quadnodes.flatness import nonconvex_panels
    >>> bool(nonconvex_panels(QuadMesh(q[0], [[0, 1, 2, 3]]))[0])
    False
    """
    x = _validate.vertices_array(vertices)
    r = _validate.vertices_array(rest, "rest")
    if r.shape != x.shape:
        raise InputError(f"rest: expected the shape of vertices {x.shape}, got {r.shape}")
    f = _validate.faces_array(faces, len(x))
    return _ShapeKeeper(r, f).project(x)[0]


@dataclass(frozen=True)
class PlanarizeReport:
    """What :func:`planarize` did.

    Planarity is the diagonal distance over the mean diagonal length (per quad);
    ``planarity_max_length`` the largest diagonal distance in ``unit``; distances
    are in the mesh's unit; ``history`` holds the largest planarity after every
    iteration, measured as the tolerance is (relative, or a length);
    ``tolerance`` is the tolerance in that measure. ``regularized``: the closeness
    weights were 0, so a damping far below the energy's scale kept the systems
    definite.

    ``converged`` means every quad meets the tolerance **and** the mesh is not
    wrecked: no edge shorter than :data:`COLLAPSED_EDGE_RATIO` of its input length
    and no quad non-convex (a dart or a bow-tie) that was convex in the input;
    otherwise ``failure`` says why, naming the quads (``nonconvex``) or edges.
    Quality figures: ``edge_length_ratio_min``/``_max`` (output over input length,
    over all edges), ``nonconvex`` (quad ids), ``moved_max``. ``methods_tried``
    lists every method run, in order (``method`` is the one whose result is returned).
    ``shape`` is the setting; ``guarded`` how many quads the shape bounds of
    ``shape="keep"`` changed in the last local step (planarity fought the bounds there).
    """

    converged: bool
    iterations: int
    planar_tolerance: float | str
    tolerance_kind: str
    tolerance: float
    planarity_max_before: float
    planarity_max: float
    planarity_mean: float
    moved_max: float
    moved_mean: float
    reference: str
    reference_distance_max: float
    reference_distance_mean: float
    weight_planarity_final: float
    factorizations: int
    seconds: float
    length_scale: float
    history: list[float] = field(default_factory=list)
    method: str = "local-global"
    newton_steps: int = 0
    planarity_max_length: float = 0.0
    unit: str = "mm"
    fix: str = "corners"
    n_fixed: int = 0
    regularized: bool = False
    methods_tried: list[str] = field(default_factory=list)
    edge_length_ratio_min: float = 1.0
    edge_length_ratio_max: float = 1.0
    nonconvex: list[int] = field(default_factory=list)
    collapsed_edges: int = 0
    failure: str = ""
    held_off_reference: float = 0.0
    shape: str = "keep"
    guarded: int = 0

    def notes(self) -> list[str]:
        """Short sentences for the user: not converged, held vertices far off the reference.

        Examples
        --------
        >>> from quadnodes.mesh import grid
        >>> planarize(grid(3, 3))[1].notes()
        []
        """
        out: list[str] = []
        if self.failure:
            out.append(self.failure)
        if not self.converged and self.guarded and self.shape == "keep":
            out.append(f"{self.guarded} quads needed the shape bounds to stay convex with edges of at least "
                       f"{KEPT_EDGE_RATIO:g} of their length: planar panels here would fold or collapse them. "
                       f"Hold fewer vertices (fix={self.fix!r}: try fix='none'), loosen planar_tolerance, or "
                       "shape='free' to see the folded result")
        if not self.converged and not self.failure:
            out.append(f"not converged: planarity {self.planarity_max:.3g} (relative) after {self.iterations} "
                       f"iterations ({self.method}); the tolerance {self.planar_tolerance!r} was not met")
        if self.held_off_reference > 0.1 * self.length_scale:
            out.append(f"held vertices (fix={self.fix!r} or fixed) lie up to {self.held_off_reference:.3g} "
                       f"{self.unit} off the reference surface; they were not moved")
        return out

    def to_dict(self) -> dict:
        """Plain-Python form (JSON-ready), with :meth:`notes`."""
        return {**asdict(self), "notes": self.notes()}


def _centering_matrix(faces: np.ndarray, n: int) -> sp.csr_matrix:
    """``Σ_f S_fᵀ (I − J/4) S_f``: the planarity term's normal matrix (``S_f`` picks quad ``f``)."""
    a = np.repeat(faces, 4, axis=1).reshape(-1)
    b = np.tile(faces, (1, 4)).reshape(-1)
    val = np.tile((np.eye(4) - 0.25).reshape(-1), len(faces))
    return sp.csr_matrix((val, (a, b)), shape=(n, n))


class _Anderson:
    """Anderson acceleration (type II) of a fixed-point iteration ``x <- g(x)``, with a residual safeguard.

    When the fixed-point residual ``||g(x) − x||`` grew since the last call, the
    history is dropped and this call returns the plain step ``g(x)``.
    """

    def __init__(self, m: int) -> None:
        self.m = m
        self.reset()

    def reset(self) -> None:
        self.F: list[np.ndarray] = []
        self.G: list[np.ndarray] = []
        self.last_norm = np.inf

    def update(self, x: np.ndarray, g: np.ndarray) -> np.ndarray:
        f = (g - x).reshape(-1)
        norm = float(np.linalg.norm(f))
        if norm > self.last_norm:  # the last (accelerated) step made things worse: restart with a plain step
            self.reset()
        self.last_norm = norm
        self.F.append(f)
        self.G.append(g.reshape(-1))
        if len(self.F) > self.m + 1:
            self.F.pop(0)
            self.G.pop(0)
        if len(self.F) < 2:
            return g
        dF = np.diff(np.array(self.F), axis=0).T
        dG = np.diff(np.array(self.G), axis=0).T
        gamma, *_ = np.linalg.lstsq(dF, f, rcond=None)
        return (g.reshape(-1) - dG @ gamma).reshape(g.shape)


def _planarity_constraints(x: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Signed, normalized planarity ``c_f`` of every quad and its gradient ``(m, 4, 3)``.

    ``c_f = det(p1 − p0, p2 − p0, p3 − p0) / s_f`` with ``s_f = |d1 × d2| · mean diagonal``;
    ``|c_f|`` equals the relative diagonal distance, and ``s_f`` is held fixed when
    differentiating (the Gauss–Newton linearization).
    """
    p = x[faces]
    a, b, e = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]
    d2 = p[:, 3] - p[:, 1]
    s = np.linalg.norm(np.cross(b, d2), axis=1) * 0.5 * (np.linalg.norm(b, axis=1) + np.linalg.norm(d2, axis=1))
    s = np.maximum(s, 1e-300)
    g1, g2, g3 = np.cross(b, e), np.cross(e, a), np.cross(a, b)
    c = np.einsum("ij,ij->i", a, g1) / s
    grad = np.stack([-(g1 + g2 + g3), g1, g2, g3], axis=1) / s[:, None, None]
    return c, grad


def _soundness(X0: np.ndarray, faces: np.ndarray) -> Callable[[np.ndarray], bool]:
    """The test the Newton-type steps keep to with ``shape="keep"``: no edge below
    :data:`KEPT_EDGE_RATIO` of its length in ``X0``, no quad convex in ``X0`` turned non-convex."""
    edges = unique_rows(np.sort(np.stack([faces, np.roll(faces, -1, axis=1)], axis=2).reshape(-1, 2), axis=1))
    min_len = KEPT_EDGE_RATIO * np.linalg.norm(X0[edges[:, 1]] - X0[edges[:, 0]], axis=1)
    convex0 = _validate.corner_turns(X0, faces)[0] == 0

    def sound(Y: np.ndarray) -> bool:
        if (np.linalg.norm(Y[edges[:, 1]] - Y[edges[:, 0]], axis=1) < min_len).any():
            return False
        return not (convex0 & (_validate.corner_turns(Y, faces)[0] > 0)).any()

    return sound


def _scaled_free_system(x0: np.ndarray, fi: np.ndarray, F: sp.spmatrix, h: float) -> tuple:
    """The Newton-type steps' common set-up, in units of the mean edge length ``h`` about the centroid:
    ``(centre, X0, k, free, col, F, Fff, Ffx)`` — scaled input, the free mask and index map, and the
    fairness matrix (AᵀA scaled by ``h²``: its coefficients go as 1/length) with its free-free and
    free-held blocks."""
    n = len(x0)
    centre = x0.mean(axis=0)
    X0 = (x0 - centre) / h
    k = fi.size
    free = np.zeros(n, dtype=bool)
    free[fi] = True
    col = np.full(n, -1, dtype=np.int64)
    col[fi] = np.arange(k)
    F = (F * h**2).tocsr()
    return centre, X0, k, free, col, F, F[fi][:, fi].tocsr(), F[fi][:, ~free]


def _newton(
    x0: np.ndarray, faces: np.ndarray, fi: np.ndarray, F: sp.csr_matrix, weights: tuple[float, float, float],
    h: float, closest: Any, tol: float, max_steps: int, relative: bool = True, keep: bool = False,
    start: np.ndarray | None = None,
) -> tuple[np.ndarray, list[float], int]:
    """Planarity as a hard constraint: Gauss–Newton (SQP) steps on the fairness and closeness energy.

    Each step minimizes the quadratic energy subject to the linearized constraints
    ``c + G Δ = 0`` (one sparse KKT solve for x, y and z together), then halves the
    step until the constraint norm decreases (at most 6 times). With ``keep``
    (``shape="keep"``) the result must be sound — no quad convex in ``x0`` turned
    non-convex, no edge below :data:`KEPT_EDGE_RATIO` of its length: the iterates may
    pass through unsound positions (a fold that later opens again), but if the last
    one is unsound, the last sound iterate is returned (its planarity is the
    history's last entry). Works in units of
    the mean edge length ``h`` about the centroid, so the system is well scaled.
    Returns the positions, the maximum planarity after every step and the number of steps.
    """
    w_f, w_c, w_i = weights
    centre, X0, k, free, col, F, Fff, Ffx = _scaled_free_system(x0, fi, F, h)
    H0 = (w_f * Fff + (w_c + w_i) * sp.identity(k)).tocsr()
    # a Levenberg–Marquardt damping far below the energy's scale keeps H positive definite even where
    # the energy leaves some motion free (closeness 0, nothing held on a torus): the KKT matrix is then
    # quasi-definite, so the unpivoted symmetric factorization cannot meet a zero pivot
    H0 = H0 + regularization(H0, 1e-8) * sp.identity(k, format="csr")
    H = sp.kron(H0, sp.identity(3), format="csr")
    fixed_F = w_f * (Ffx @ X0[~free]) if Ffx.shape[1] else np.zeros((k, 3))
    cols = col[faces]
    active = (cols >= 0).any(axis=1)
    fa, ca = faces[active], cols[active]
    m = len(fa)
    rr = np.broadcast_to(np.arange(m)[:, None, None], (m, 4, 3))
    cc = 3 * ca[:, :, None] + np.arange(3)
    use = np.broadcast_to((ca >= 0)[:, :, None], (m, 4, 3))
    X = X0.copy() if start is None else (start - centre) / h
    history: list[float] = []
    steps = 0
    if keep:
        sound = _soundness(X0, faces)

        last_sound, last_sound_p = X.copy(), float(quad_diagonal_distance(X, faces, relative=relative).max()) * (
            1.0 if relative else h)
    for steps in range(1, max_steps + 1):
        target = (closest(X * h + centre)[0] - centre) / h
        b = (w_c * target[fi] + w_i * X0[fi] - fixed_F).reshape(-1)
        grad_e = H @ X[fi].reshape(-1) - b
        c, grad = _planarity_constraints(X, fa)
        G = sp.csr_matrix((grad[use], (rr[use], cc[use])), shape=(m, 3 * k))
        # min ½ ΔᵀHΔ + ∇eᵀΔ subject to c + GΔ = 0, the constraint block regularized by −εI: the
        # KKT matrix is quasi-definite (H positive definite), factorized without pivoting in a
        # fill-reducing symmetric order (4× faster than COLAMD with pivoting at 100 × 100)
        step = QuadraticProblem(H, Aeq=G, method="direct", constraint_shift=1e-9, what="planarize (Newton step)")
        sol = step.solve(grad_e, Beq=-c)
        D = sol.reshape(k, 3)
        norm0 = float(np.linalg.norm(c))
        t = 1.0
        for _ in range(7):
            Xt = X.copy()
            Xt[fi] += t * D
            if float(np.linalg.norm(_planarity_constraints(Xt, fa)[0])) < norm0:
                break
            t *= 0.5
        X = Xt
        # X is in units of h: a length tolerance compares the diagonal distance times h
        pmax = float(quad_diagonal_distance(X, faces, relative=relative).max()) * (1.0 if relative else h)
        history.append(pmax)
        report_progress(min(steps / max_steps, 1.0), f"Newton step {steps}: planarity max {pmax:.2e}")
        if keep and sound(X):
            last_sound, last_sound_p = X.copy(), pmax
        if pmax <= tol:
            break
    if keep and last_sound is not X and not sound(X):
        X = last_sound  # the end folds a quad or collapses an edge: back to the last sound iterate
        history.append(last_sound_p)
    out = x0.copy()  # fixed vertices exactly as given (no round trip through the scaled frame)
    out[fi] = X[fi] * h + centre
    return out, history, steps


#: Gauss–Newton (``method="gauss-newton"``): the planarity weight it starts at (in units where the mean edge is 1,
#: the weight of the squared signed relative planarity of every quad) and its growth when a weight is settled.
GN_START_WEIGHT = 1e3
GN_WEIGHT_GROWTH = 4.0
#: ... when an accepted step lowers the energy by less than this share (the weight is settled).
GN_SETTLED = 1e-2
#: ``method="gauss-newton"`` starts from this many local/global iterations at the starting planarity weight.
GN_WARMUP = 10
#: Gauss–Newton returns no mesh where a structure-line window turns more than this many times the most any
#: window turned in the input (thesis eq. 30) ...
GN_LINE_GROWTH = 2.0
#: ... or than this, if larger: a tenth of the thesis's zigzag threshold (eq. 30 deviation 0.1), about a 6° kink.
GN_LINE_FLOOR = 0.01


#: With a reference and at least this many vertices, planarize loads the compiled kernels, the closest-point
#: test among them, on a second thread at its start (:func:`quadnodes.reference.warm_up`, about 1.5 s of CPU): at 100 × 100 the
#: NumPy test is most of a local/global iteration (0.13 → 0.09 s of CPU with the compiled one).
REFERENCE_KERNEL_MIN_VERTICES = 5000

#: ``method="auto"`` tries Gauss–Newton early when the local/global iteration stagnates: the last
#: :data:`STALL_DOUBLINGS` doublings of the planarity weight (8× the weight) together lowered the maximum
#: planarity by less than :data:`STALL_PROGRESS` (5 %). On E1–E4 three doublings always gain ≥ 13 %,
#: on F100 3 % from the first doubling on (``benchmarks/studies/planarize_stall.py``).
STALL_DOUBLINGS = 3
STALL_PROGRESS = 0.05
#: ... with at most this many Gauss–Newton steps (F100 meets the tolerance in 12, a 50 × 50 sample of its face
#: in 8; a miss costs the attempt, since local/global then goes on as if it had not been made).
GN_EARLY_STEPS = 15


#: Gauss–Newton solves: conjugate gradients preconditioned by the last factorization, to this relative
#: residual in at most this many steps, else the matrix is factorized anew.
GN_CG_RTOL = 1e-4
GN_CG_STEPS = 25


def _pcg(K: sp.csr_matrix, b: np.ndarray, precondition: Any, rtol: float, maxiter: int) -> tuple[np.ndarray, bool]:
    """Preconditioned conjugate gradients for ``K z = b`` from ``z = 0``; whether ``||r|| ≤ rtol ||b||``."""
    z = np.zeros_like(b)
    r = b.copy()
    nb = float(np.linalg.norm(b))
    if nb == 0.0:
        return z, True
    y = precondition(r)
    d = y.copy()
    ry = float(r @ y)
    for _ in range(maxiter):
        Kd = K @ d
        dKd = float(d @ Kd)
        if not dKd > 0:
            return z, False
        a = ry / dKd
        z += a * d
        r -= a * Kd
        if float(np.linalg.norm(r)) <= rtol * nb:
            return z, True
        y = precondition(r)
        ry, ry_old = float(r @ y), ry
        d = y + (ry / ry_old) * d
    return z, False


def _vertex_normals(X: np.ndarray, faces: np.ndarray, gather: sp.csr_matrix) -> np.ndarray:
    """Unit vertex normals: the sum of the vector areas of the quads around each vertex."""
    p = X[faces]
    a = np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 1])
    v = gather @ np.repeat(a, 4, axis=0)
    nv = np.linalg.norm(v, axis=1, keepdims=True)
    return np.divide(v, nv, out=np.zeros_like(v), where=nv > 0)


def _gauss_newton(
    x0: np.ndarray, faces: np.ndarray, fi: np.ndarray, F: sp.csr_matrix, weights: tuple[float, float, float],
    h: float, closest: Any, tol: float, max_steps: int, relative: bool = True, keep: bool = True,
    start: np.ndarray | None = None, windows: np.ndarray | None = None,
) -> tuple[np.ndarray, list[float], int, float, int]:
    """Planarity by penalty: Gauss–Newton steps along the vertex normals with a growing weight and a trust region.

    Minimizes ``E = w_f ||A x||² + w_c ||x − t||² + w_i ||x − x⁰||² + W Σ_f c_f(x)²`` (units of the
    mean edge length ``h``; ``c_f`` the signed relative planarity of :func:`_planarity_constraints`,
    ``t`` the closest points, held during a step) over moves ``Δ_i = δ_i n_i`` of the free vertices
    along their normals: one scalar unknown per vertex, so each step is one sparse symmetric positive
    definite solve of the size of the local/global matrix,
    ``(Nᵀ H N + W (G N)ᵀ(G N) + μ D) δ = −Nᵀ ∇E`` (Levenberg–Marquardt damping ``μ``, ``D`` the
    matrix's diagonal).
    A step is taken only if it lowers ``E`` and — with ``keep`` — leaves the mesh sound (no quad
    convex in ``x0`` non-convex, no edge below :data:`KEPT_EDGE_RATIO` of its length in ``x0``); else
    ``μ`` grows ×4 and the step is solved again (a trust region). When a step lowers ``E`` by less than 1 %,
    the weight at hand is settled and ``W`` grows by :data:`GN_WEIGHT_GROWTH` (continuation from
    :data:`GN_START_WEIGHT`), until every quad meets ``tol`` and no structure-line window (``windows``)
    bends more than :data:`GN_LINE_GROWTH` times the most one bent in ``x0`` (or
    :data:`GN_LINE_FLOOR`, if larger). The iterates may pass through such a kink; if the last one
    has one, the last iterate without is returned (or the start). Tangential moves are left to the
    local/global iteration that provides ``start``.

    Returns the positions, the maximum planarity after every step, the number of steps, the final
    weight ``W`` and the number of factorizations.
    """
    w_f, w_c, w_i = weights
    centre, X0, k, free, col, F, Fff, Ffx = _scaled_free_system(x0, fi, F, h)
    H0 = (w_f * Fff + (w_c + w_i) * sp.identity(k)).tocoo()
    H0 = sp.coo_matrix((H0.data, (H0.row, H0.col)), shape=(k, k))
    fixed_F = w_f * (Ffx @ X0[~free]) if Ffx.shape[1] else np.zeros((k, 3))
    cols = col[faces]
    active = (cols >= 0).any(axis=1)
    fa, ca = faces[active], cols[active]
    m = len(fa)
    use = ca >= 0
    g_rows = np.broadcast_to(np.arange(m)[:, None], (m, 4))[use]
    g_cols = ca[use]
    m4 = faces.size
    gather = sp.csr_matrix((np.ones(m4), (faces.reshape(-1), np.arange(m4))), shape=(len(x0), m4))
    # sums the (m, 4) per-corner values of the active quads into the free unknowns
    gather_free = sp.csr_matrix((np.ones(g_cols.size), (g_cols, np.flatnonzero(use.reshape(-1)))), shape=(k, 4 * m))
    X = X0.copy() if start is None else (start - centre) / h
    scale = 1.0 if relative else h

    def planarity(Y: np.ndarray) -> float:
        return float(quad_diagonal_distance(Y, faces, relative=relative).max()) * scale

    sound = _soundness(X0, faces)

    # the structure lines may not kink: no window may turn more than GN_LINE_GROWTH times the most any
    # window turned in the input, or GN_LINE_FLOOR (Gauss–Newton can buy planarity with a
    # sharp bend where a quad has a single free corner, which the fairness energy alone, against a growing
    # W, does not stop)
    if windows is not None and len(windows):
        from .zigzag import window_deviation

        line_bound = max(GN_LINE_GROWTH * float(window_deviation(X0, windows).max()), GN_LINE_FLOOR)

        def lines_ok(Y: np.ndarray) -> bool:
            return bool(window_deviation(Y, windows).max() <= line_bound)
    else:
        def lines_ok(Y: np.ndarray) -> bool:
            return True

    guard = keep and sound(X)  # an unsound start (shape="free") is not held to the bounds

    def target(Y: np.ndarray) -> np.ndarray:
        return (closest(Y * h + centre)[0] - centre) / h

    def energy(Y: np.ndarray, T: np.ndarray, W: float) -> float:
        Yf = Y[fi]
        c = _planarity_constraints(Y, fa)[0]
        return float(w_f * np.sum(Y * (F @ Y)) + w_c * np.sum((Yf - T[fi]) ** 2)
                     + w_i * np.sum((Yf - X0[fi]) ** 2) + W * np.sum(c * c))

    lu: Factorization | None = None

    def solve(K: sp.csr_matrix, b: np.ndarray) -> np.ndarray:
        """``K⁻¹ b``: conjugate gradients preconditioned by the last factorization, else a new one.

        Between steps ``K`` changes a little (normals, gradients, damping, a weight ×4), so the last
        factorization is a close preconditioner; a Gauss–Newton step needs no exact solve.
        """
        nonlocal lu, facts
        if lu is not None:
            z, ok = _pcg(K, b, lu.solve, GN_CG_RTOL, GN_CG_STEPS)
            if ok:
                return z
        lu = factorize(K, kind="spd", what="planarize (Gauss-Newton step)")
        facts += 1
        return lu.solve(b)

    W = GN_START_WEIGHT
    mu = 1e-3
    last_fair, last_fair_p = X, planarity(X)
    T = target(X)
    E = energy(X, T, W)
    history: list[float] = []
    steps = facts = 0
    # unknowns: one per free vertex (its move along its normal), three (x, y, z) for the free corners of
    # quads with two or more held corners — along a held boundary a move along the normal alone flattens
    # such a quad only by twisting its neighbours (their rows of G cancel), so it needs to slide
    near_held = ~free
    near_held[faces[(~free)[faces].sum(axis=1) >= 2]] = True
    three = near_held[fi]
    width = np.where(three, 3, 1)
    first = np.concatenate([[0], np.cumsum(width)[:-1]])
    dof = int(width.sum())
    k3, k1 = np.flatnonzero(three), np.flatnonzero(~three)
    b_rows = np.concatenate([(3 * k1[:, None] + np.arange(3)).ravel(), (3 * k3[:, None] + np.arange(3)).ravel()])
    b_cols = np.concatenate([np.repeat(first[k1], 3), (first[k3][:, None] + np.arange(3)).ravel()])
    Hk = sp.kron(sp.csr_matrix(H0), sp.identity(3), format="csr")
    rr = np.broadcast_to(np.arange(m)[:, None, None], (m, 4, 3))
    cc = 3 * ca[:, :, None] + np.arange(3)
    use3 = np.broadcast_to(use[:, :, None], (m, 4, 3))
    for steps in range(1, max_steps + 1):
        c, grad = _planarity_constraints(X, fa)
        nv = _vertex_normals(X, faces, gather)[fi]
        B = sp.csr_matrix((np.concatenate([nv[k1].ravel(), np.ones(3 * k3.size)]), (b_rows, b_cols)),
                          shape=(3 * k, dof))
        GB = (sp.csr_matrix((grad[use3], (rr[use3], cc[use3])), shape=(m, 3 * k)) @ B).tocsr()
        Xf = X[fi]
        g3 = w_f * (Fff @ Xf) + fixed_F + w_c * (Xf - T[fi]) + w_i * (Xf - X0[fi])
        g3 += W * (gather_free @ (grad * c[:, None, None]).reshape(-1, 3))
        gr = B.T @ g3.reshape(-1)
        M = (B.T @ Hk @ B + W * (GB.T @ GB)).tocsr()
        # Marquardt's damping μ·diag(M), plus a floor far below the matrix's scale (an unknown the energy
        # leaves free, e.g. a vertex whose quads' areas cancel): definite at every weight
        diag, floor = M.diagonal(), regularization(M, 1e-10)
        accepted = False
        while mu <= 1e8:
            Y = X.copy()
            try:
                Y[fi] -= (B @ solve((M + sp.diags(mu * diag + floor)).tocsr(), gr)).reshape(k, 3)
            except InputError:  # numerically singular even so: stop where we are
                break
            if not guard or sound(Y):
                TY = target(Y)
                EY = energy(Y, TY, W)
                if EY < E:
                    accepted = True
                    break
            mu *= 4.0
        if not accepted:
            break  # no sound step lowers the energy at any damping: stop where we are
        drop = (E - EY) / max(abs(E), 1e-300)
        X, T, E = Y, TY, EY
        mu = max(mu / 3.0, 1e-6)
        pmax = planarity(X)
        history.append(pmax)
        report_progress(min(steps / max_steps, 1.0), f"Gauss-Newton step {steps}: planarity max {pmax:.2e}")
        fair_now = lines_ok(X)
        if fair_now:
            last_fair, last_fair_p = X, pmax
        if pmax <= tol and fair_now:
            break
        if drop < GN_SETTLED:
            W *= GN_WEIGHT_GROWTH
            E = energy(X, T, W)
    if last_fair is not X:  # the last steps bent a line too far: back to the last iterate that did not
        X = last_fair
        history.append(last_fair_p)
    out = x0.copy()  # fixed vertices exactly as given
    out[fi] = X[fi] * h + centre
    return out, history, steps, W, facts


@_validate.renamed(tolerance="planar_tolerance")
def planarize(
    mesh: QuadMesh,
    *,
    reference: Any = None,
    planar_tolerance: float | str = DEFAULT_TOLERANCE,
    max_iterations: int = 2000,
    planarity_weight: float = 1.0,
    fairness_weight: float = 0.1,
    closeness_weight: float = 0.1,
    input_weight: float | None = None,
    fix: Fix = "corners",
    fixed: ArrayLike | None = None,
    reference_samples: int = 4,
    adapt: bool = True,
    anderson: int = 5,
    method: Literal["auto", "local-global", "gauss-newton", "newton"] = "auto",
    newton_steps: int = 30,
    shape: Shape = "keep",
) -> tuple[QuadMesh, PlanarizeReport]:
    """Make every quad planar while keeping structure lines fair and the mesh on its design surface.

    Parameters
    ----------
    mesh : QuadMesh
    reference : build123d Face, QuadMesh or Reference, optional
        Design surface the vertices stay close to (and may slide along). Without
        it, vertices stay close to their input positions.
    planar_tolerance : float or str
        Stop when every quad is planar within this: a number (> 0) is relative
        (diagonal distance / mean diagonal); text such as ``"2 mm"`` is the diagonal
        distance as a length (converted to the mesh's unit). The same setting as
        the exporters'.
    max_iterations : int
        Cap on local/global iterations (>= 1).
    planarity_weight, fairness_weight, closeness_weight : float
        ``w_p`` (> 0), ``w_f`` (>= 0), ``w_c`` (>= 0) of the energy in the module
        text; dimensionless. ``w_p`` is the starting value when ``adapt`` is on
        (it grows at most :data:`MAX_WEIGHT_GROWTH`-fold; past that the run stops
        unconverged).
    input_weight : float, optional
        Weight (>= 0) of an extra pull to the input positions, in the units of
        ``w_c``. Default: 0 without a reference, :data:`DEFAULT_INPUT_WEIGHT` with
        one — the fairness term (lengths frozen) rewards shrinking, and without this
        pull the vertices could slide inwards along the surface.
    fix : {"none", "corners", "boundary"}
        Vertices held in place, besides ``fixed``.
    fixed : (n,) bool or int indices, optional
        More vertices that never move.
    reference_samples : int
        For a face: fine samples per mesh edge (see :func:`quadnodes.reference.as_reference`).
    adapt : bool
        Double ``w_p`` whenever the maximum planarity improved by less than 1 %
        over 9 iterations (at most every 10 iterations, while the tolerance is not met).
    anderson : int
        History length of the Anderson acceleration of the local/global
        iteration (0: plain iteration). When an accelerated step made the
        fixed-point residual grow, the history restarts with a plain step.
    method : {"auto", "local-global", "gauss-newton", "newton"}
        ``"local-global"``: the projection iteration above. ``"gauss-newton"``:
        :data:`GN_WARMUP` local/global steps at the starting weight, then
        penalty Gauss–Newton steps (:func:`_gauss_newton`): the planarity of every
        quad as a squared penalty whose weight grows until the tolerance is met,
        moves along the vertex normals (all three coordinates next to held
        vertices), one sparse solve of the local/global matrix's size per step, a
        step taken only if it lowers the energy and — with ``shape="keep"`` —
        folds no quad and shortens no edge below the shape bounds. ``"newton"``:
        planarity as a hard constraint, Gauss–Newton (SQP) steps on the fairness
        and closeness energy from the input, one sparse KKT factorization per step
        (``w_p`` and ``adapt`` unused). ``"auto"`` (default): local/global — where
        it stagnates (:data:`STALL_DOUBLINGS` weight doublings gained less than
        :data:`STALL_PROGRESS`), one Gauss–Newton attempt of at most
        :data:`GN_EARLY_STEPS` steps from its iterate, returned if it converges,
        else local/global goes on unchanged — and
        when it ends above the tolerance with at most :data:`NEWTON_LIMIT` free
        vertices, Gauss–Newton from its result, then (if that misses too) Newton
        from the input; the converged result (else the sound one, else the
        flatter) is returned, local/global first among equals.
    newton_steps : int
        Cap on Newton and on Gauss–Newton steps (>= 1).
    shape : {"keep", "free"}
        ``"keep"`` (default): no quad convex in the input may turn into a dart or a
        bow-tie, and no edge may shrink below :data:`KEPT_EDGE_RATIO` of its input
        length. The local step projects each quad onto the closest planar quad
        that keeps these bounds (:func:`kept_shape_projection`), and Newton steps
        are shortened so that they keep them. Where planarity can only be had by
        breaking them (e.g. corners held on a surface whose grid is far from a
        conjugate net), the result stays sound and is reported unconverged.
        ``"free"``: the plain projection (quads may fold; such a result is reported,
        never ``converged``).

    Returns
    -------
    mesh : QuadMesh
        The planarized mesh (the input itself if it already meets the tolerance).
    report : PlanarizeReport

    Raises
    ------
    InputError
        On bad weights, tolerance, iteration cap, fixing option or reference; if
        every vertex is fixed while some quad is not planar; if closeness and
        fairness are both zero and nothing is fixed (the problem has no unique
        solution).

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> z = np.array([[0.0, 0, 0], [0, 0.3, 0], [0, 0, 0]])
    >>> flat, rep = planarize(grid(3, 3, height=z))
    >>> rep.converged, rep.planarity_max <= 1e-3
    (True, True)
    """
    t0 = time.perf_counter()
    _validate.quad_mesh(mesh)
    tol_kind, tol = resolve_planar_tolerance(planar_tolerance, mesh.unit)
    if tol <= 0:
        raise InputError(f"planar_tolerance: must be > 0, got {planar_tolerance!r}")
    relative = tol_kind == "relative"
    max_iterations = _validate.positive_int(max_iterations, "max_iterations")
    w_p = _validate.positive_number(planarity_weight, "planarity_weight")
    w_f = _validate.finite_number(fairness_weight, "fairness_weight")
    w_c = _validate.finite_number(closeness_weight, "closeness_weight")
    if input_weight is None:
        input_weight = 0.0 if reference is None else DEFAULT_INPUT_WEIGHT
    w_i = _validate.finite_number(input_weight, "input_weight")
    for value, name in ((w_f, "fairness_weight"), (w_c, "closeness_weight"), (w_i, "input_weight")):
        if value < 0:
            raise InputError(f"{name}: expected a number >= 0, got {value!r}")
    method = _validate.choice(method, ("auto", "local-global", "gauss-newton", "newton"), "method")
    newton_steps = _validate.positive_int(newton_steps, "newton_steps")
    shape = _validate.choice(shape, ("keep", "free"), "shape")
    if not isinstance(adapt, (bool, np.bool_)):
        raise InputError(f"adapt: expected True or False, got {adapt!r}")
    held = fixed_vertices(mesh, fix, fixed)
    ref: Reference | None = None
    if reference is not None:
        if mesh.n_vertices >= REFERENCE_KERNEL_MIN_VERTICES:
            reference_kernel_warm_up()  # hundreds of closest-point calls ahead: load the compiled test meanwhile
        ref = as_reference(reference, mesh, samples=reference_samples)
    if w_c == 0 and w_i == 0:
        # only the held vertices pin the mesh: every connected piece needs one, else it may slide freely
        from scipy.sparse.csgraph import connected_components

        _, label = connected_components(adjacency(mesh), directed=False)
        pinned = np.zeros(label.max() + 1, dtype=bool)
        pinned[label[held]] = True
        loose = np.flatnonzero(~pinned[label] & (np.diff(mesh.topology.ring[0]) > 0))
        if loose.size:
            raise InputError(
                f"closeness_weight=0, input_weight=0, fix={fix!r}: nothing holds the piece of the mesh with "
                f"vertex {int(loose[0])} in place (it could slide anywhere); give closeness_weight > 0 or "
                "hold a vertex there (fix, fixed)"
            )

    x0 = mesh.vertices
    n = mesh.n_vertices
    h = mesh.mean_edge_length
    free = ~held
    fi = np.flatnonzero(free)
    plan0 = diagonal_distance(mesh, relative=relative)
    p_before = float(plan0.max()) if len(plan0) else 0.0

    def closest(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if ref is None:
            return x0, np.linalg.norm(x - x0, axis=1)
        return ref.closest(x)

    def finish(x: np.ndarray, converged: bool, its: int, history: list[float], w_p_now: float, facts: int,
               used: str = "local-global", n_steps: int = 0, guarded: int = 0):
        out = mesh if x is x0 else mesh.with_vertices(x)
        quality = _quality(mesh, out)
        met = converged
        converged = bool(converged and not quality["failure"])
        failure = quality["failure"] if met else ("the planar tolerance was not reached; " + quality["failure"]
                                                  if quality["failure"] else "the planar tolerance was not reached")
        quality["failure"] = failure
        pl = diagonal_distance(out)
        pl_len = diagonal_distance(out, relative=False)
        moved = np.linalg.norm(x - x0, axis=1)
        _, dist = closest(x)
        return out, PlanarizeReport(
            converged=converged, iterations=its, planar_tolerance=planar_tolerance, tolerance_kind=tol_kind,
            tolerance=tol, planarity_max_before=p_before,
            planarity_max_length=float(pl_len.max()) if len(pl_len) else 0.0, unit=mesh.unit,
            fix=fix, n_fixed=int(held.sum()), regularized=bool(w_c == 0 and w_i == 0),
            held_off_reference=float(dist[held].max()) if held.any() else 0.0,
            planarity_max=float(pl.max()) if len(pl) else 0.0, planarity_mean=float(pl.mean()) if len(pl) else 0.0,
            moved_max=float(moved.max()), moved_mean=float(moved.mean()),
            reference="none" if ref is None else ref.source,
            reference_distance_max=float(dist.max()), reference_distance_mean=float(dist.mean()),
            weight_planarity_final=w_p_now, factorizations=facts, seconds=time.perf_counter() - t0,
            length_scale=h, history=history, method=used, newton_steps=n_steps, methods_tried=[used], **quality,
            shape=shape, guarded=guarded,
        )

    if p_before <= tol:
        return finish(x0, True, 0, [], w_p, 0)
    if fi.size == 0:
        raise InputError(
            f"fixed: every vertex is fixed but quad {int(np.argmax(plan0))} has planarity {p_before:.3g} "
            f"> planar_tolerance {planar_tolerance!r}; free some vertices"
        )

    stuck = np.flatnonzero(held[mesh.faces].all(axis=1) & (plan0 > tol))
    if stuck.size:
        worst = float(plan0[stuck].max())
        ids = ", ".join(str(int(i)) for i in stuck[:12]) + (" …" if stuck.size > 12 else "")
        raise InputError(
            f"fix={fix!r}, fixed: {stuck.size} quad{'s' if stuck.size > 1 else ''} ({ids}) "
            f"{'have' if stuck.size > 1 else 'has'} all four corners "
            f"held and are non-planar beyond planar_tolerance {planar_tolerance!r} (up to {worst:.3g}): the "
            "tolerance cannot be reached. Free a vertex of each (fix='none', or fewer fixed vertices) or "
            f"raise planar_tolerance to at least {worst:.3g}"
        )

    faces = mesh.faces
    w = mesh.topology.windows
    if len(w) and w_f > 0:
        A = fairing_matrix(x0, w)
        F = (A.T @ A).tocsr()
    else:
        F = sp.csr_matrix((n, n))
    def run_newton(its: int, history: list[float], facts: int) -> tuple[QuadMesh, PlanarizeReport]:
        x, steps_h, steps = _newton(x0, faces, fi, F, (w_f, w_c, w_i), h, closest, tol, newton_steps, relative,
                                    keep=shape == "keep")
        met = bool(steps_h) and steps_h[-1] <= tol
        return finish(x, met, its, history + steps_h, w_p, facts + len(steps_h), "newton", steps)

    def run_gauss_newton(start: np.ndarray, its: int, history: list[float], facts: int,
                         guarded: int, cap: int = newton_steps) -> tuple[QuadMesh, PlanarizeReport]:
        x, steps_h, steps, weight, f_gn = _gauss_newton(x0, faces, fi, F, (w_f, w_c, w_i), h, closest, tol,
                                                        cap, relative, keep=shape == "keep", start=start,
                                                        windows=w if len(w) else None)
        met = bool(steps_h) and steps_h[-1] <= tol
        return finish(x, met, its, history + steps_h, weight, facts + f_gn, "gauss-newton", steps, guarded=guarded)

    if method == "newton":
        return run_newton(0, [], 0)
    C = _centering_matrix(faces, n) / h**2
    I = sp.identity(n, format="csr") / h**2
    known = np.flatnonzero(~free)
    xfix = x0[known]

    def factor(wp: float) -> QuadraticProblem:
        # ½ xᵀQx − xᵀ(...): the held vertices move to the right-hand side inside the engine;
        # only the held vertices pin the mesh when w_c + w_i == 0 (checked above): kept definite by a shift
        Q = (wp * C + w_f * F + (w_c + w_i) * I).tocsr()
        return QuadraticProblem(Q, known=known, method="cg" if large else "direct", rtol=LARGE_RTOL,
                                shift=1e-10 if w_c + w_i == 0 else 0.0, what="planarize (local/global step)")

    # above DIRECT_LIMIT free vertices the global step is conjugate gradients started from the current
    # positions (a factorization of a million unknowns takes minutes); below it, one factorization per weight
    large = fi.size > DIRECT_LIMIT

    lu = factor(w_p)
    facts = 1

    # sums each vertex's projected corner positions over its quads: (n, 4m) of ones
    m4 = faces.size
    gather = sp.csr_matrix((np.ones(m4), (faces.reshape(-1), np.arange(m4))), shape=(n, m4))

    keeper = _ShapeKeeper(x0, faces) if shape == "keep" else None
    guarded = 0

    def step(x: np.ndarray) -> np.ndarray:
        """One local/global step from positions ``x``: new free positions (the fixed-point map)."""
        nonlocal guarded
        if keeper is None:
            q = quad_plane_projection(x, faces)
        else:
            q, guarded = keeper.project(x)
        qv = gather @ q.reshape(-1, 3)
        target, _ = closest(x)
        lin = -((w_p / h**2) * qv + (w_c / h**2) * target + (w_i / h**2) * x0)
        return lu.solve(lin, Y=xfix, guess=x[fi] if large else None)[fi]

    # method="gauss-newton": a few plain local/global steps at the starting weight (fair, near the
    # surface, the noise's zigzags out), then the Gauss–Newton continuation takes over
    lg_cap = min(max_iterations, GN_WARMUP) if method == "gauss-newton" else max_iterations
    x = x0.copy()
    xf = x0[fi]
    acc = _Anderson(anderson) if anderson else None
    history: list[float] = []
    converged = False
    it = last_change = 0
    # method="auto": the maximum planarity at every weight doubling, for the stagnation test; one early
    # Gauss–Newton attempt at most (if it misses, local/global goes on exactly where it was)
    at_doubling: list[float] = []
    early = method == "auto" and fi.size <= NEWTON_LIMIT
    tried = ["local-global"]
    for it in range(1, lg_cap + 1):
        g = step(x)
        xf = acc.update(xf, g) if acc is not None else g
        x[fi] = xf
        pmax = float(quad_diagonal_distance(x, faces, relative=relative).max())
        history.append(pmax)
        if it % 10 == 0:
            report_progress(min(it / max_iterations, 1.0), f"iteration {it}: planarity max {pmax:.2e}")
        if pmax <= tol:
            converged = True
            break
        if method == "gauss-newton":
            continue
        if adapt and it - last_change >= 10 and pmax > 0.99 * history[-10]:
            at_doubling.append(pmax)
            if (early and len(at_doubling) > STALL_DOUBLINGS
                    and pmax > (1.0 - STALL_PROGRESS) * at_doubling[-1 - STALL_DOUBLINGS]):
                # stagnating: a mesh-wide deformation the projections reach only slowly (F100), which
                # Gauss–Newton's second-order steps reach in a few; kept only if it meets the tolerance
                early = False
                tried.append("gauss-newton")
                attempt = run_gauss_newton(x.copy(), it, history, facts, guarded,
                                           min(newton_steps, GN_EARLY_STEPS))
                if attempt[1].converged:
                    return attempt[0], replace(attempt[1], methods_tried=tried)
                tried.append("local-global")
            if w_p * 2.0 > MAX_WEIGHT_GROWTH * planarity_weight:
                break  # stalled at the largest weight: the tolerance is out of reach with these constraints
            w_p *= 2.0
            lu = factor(w_p)
            facts += 1
            last_change = it
            if acc is not None:
                acc.reset()
    result = finish(x, converged, it, history, w_p, facts, guarded=guarded)
    if converged or method == "local-global" or (method == "auto" and fi.size > NEWTON_LIMIT):
        return result[0], replace(result[1], methods_tried=tried)
    tried.append("gauss-newton")
    results = [result, run_gauss_newton(x, it, history, facts, guarded)]
    if method == "auto" and not results[-1][1].converged:
        results.append(run_newton(it, history, facts))
        tried.append("newton")

    def rank(r: PlanarizeReport) -> tuple[bool, bool, float]:
        # converged first, then a sound mesh (nothing folded or collapsed), then the flatter
        return (not r.converged, bool(r.nonconvex or r.collapsed_edges), r.planarity_max)

    chosen = min(results, key=lambda r: rank(r[1]))  # the first of equals: local/global before the others
    return chosen[0], replace(chosen[1], methods_tried=tried)


def _quality(before: QuadMesh, after: QuadMesh) -> dict[str, Any]:
    """Edge-length ratio range, newly non-convex quads, collapsed edges and the failure they make."""
    e = before.topology.edges
    l0 = np.linalg.norm(before.vertices[e[:, 1]] - before.vertices[e[:, 0]], axis=1)
    l1 = np.linalg.norm(after.vertices[e[:, 1]] - after.vertices[e[:, 0]], axis=1)
    ratio = l1 / l0
    collapsed = np.flatnonzero(ratio < COLLAPSED_EDGE_RATIO)
    from .flatness import nonconvex_panels

    bad = np.flatnonzero(nonconvex_panels(after) & ~nonconvex_panels(before))
    parts = []
    if bad.size:
        ids = ", ".join(str(int(i)) for i in bad[:12]) + (" …" if bad.size > 12 else "")
        parts.append(f"{bad.size} quad{'s' if bad.size > 1 else ''} became non-convex or folded ({ids})")
    if collapsed.size:
        k = int(collapsed[np.argmin(ratio[collapsed])])
        parts.append(f"{collapsed.size} edge{'s' if collapsed.size > 1 else ''} collapsed below "
                     f"{COLLAPSED_EDGE_RATIO:g} of their length (edge {int(e[k, 0])}-{int(e[k, 1])} to "
                     f"{ratio[k]:.2g})")
    return {
        "edge_length_ratio_min": float(ratio.min()) if ratio.size else 1.0,
        "edge_length_ratio_max": float(ratio.max()) if ratio.size else 1.0,
        "nonconvex": bad.tolist(),
        "collapsed_edges": int(collapsed.size),
        "failure": "; ".join(parts),
    }
