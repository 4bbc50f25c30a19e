"""Laplacian and Taubin smoothing on the quad mesh's own edge 1-ring (thesis 3.2.2–3.2.5).

The neighbours of a vertex are the vertices it shares an *edge* with — quad
diagonals are not neighbours (trimesh's filters work on the triangulation, where
they are; that is not what the thesis compares).

One Laplacian step is ``x' = x + λ L x`` with ``L = W − I`` and ``W`` the
row-normalized edge weights; a Taubin iteration is a ``λ`` step followed by a ``μ``
step with ``μ = 1 / (k_PB − 1/λ)`` (eq. 19). Fixed vertices get an empty
neighbourhood (a zero row), so they never move — Taubin's interpolatory constraint.

The eigenvalues ``k`` of ``I − W`` lie in ``[0, 2]`` (W is a random walk on the
edge graph with symmetric weights), so a step pair scales frequency ``k`` by
``f(k) = (1 − λk)(1 − μk)``. A pair with ``|f(k)| > 1`` somewhere in ``[0, 2]``
amplifies that frequency every iteration and blows the mesh up (``λ = 1`` with
Taubin's μ does: ``f(2) ≈ −3.2``); such factors are refused, naming the
frequency and the gain.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from functools import partial
from typing import Literal

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike
from scipy.optimize import brentq

from . import _validate
from .errors import InputError
from .linalg.threads import RowBlocks
from .mesh import QuadMesh
from .topology import fixed_vertices

__all__ = ["SmoothingReport", "laplacian_operator", "taubin_lambda", "step_gain", "laplacian", "taubin"]

Weighting = Literal["uniform", "inverse_length"]
Fix = Literal["none", "corners", "boundary"]
WEIGHTINGS = ("uniform", "inverse_length")


@dataclass(frozen=True)
class SmoothingReport:
    """What :func:`laplacian` or :func:`taubin` did (lengths in the mesh's unit)."""

    method: str
    iterations: int
    lam: float
    mu: float | None
    weighting: str
    fix: str
    n_fixed: int
    moved_max: float
    moved_mean: float
    gain_max: float
    seconds: float
    unit: str = "mm"

    def to_dict(self) -> dict:
        """Plain-Python form (JSON-ready)."""
        return asdict(self)


def step_gain(factors: list[float], low: float = 0.0) -> tuple[float, float]:
    """Largest ``|Π (1 − f k)|`` over ``k ∈ [low, 2]`` for one pass of the step ``factors``, and where.

    Examples
    --------
    >>> gain, k = step_gain([1.0, 1.0 / (0.1 - 1.0)], low=0.1)
    >>> round(gain, 2), k
    (3.22, 2.0)
    >>> step_gain([0.5])[0] <= 1
    True
    """
    k = np.linspace(min(low, 2.0), 2.0, 2001)
    f = np.ones_like(k)
    for a in factors:
        f *= 1.0 - a * k
    i = int(np.argmax(np.abs(f)))
    return float(abs(f[i])), float(k[i])


def _weights(mesh: QuadMesh, weighting: Weighting, vertices: np.ndarray | None, fixed: np.ndarray | None) -> sp.csr_matrix:
    """Row-normalized edge weights ``W`` (rows of fixed vertices empty)."""
    weighting = _validate.choice(weighting, WEIGHTINGS, "weighting")  # type: ignore[assignment]
    n = mesh.n_vertices
    indptr, indices, edge_id = mesh.topology.ring
    counts = np.diff(indptr)
    if weighting == "uniform":
        # 1 / valence on every entry of a row; fixed rows hold zeros
        w = np.divide(1.0, counts, out=np.zeros(n), where=counts > 0)
        if fixed is not None:
            w[fixed] = 0.0
        return sp.csr_matrix((np.repeat(w, counts), indices, indptr), shape=(n, n))
    else:
        x = mesh.vertices if vertices is None else vertices
        e = mesh.topology.edges
        d = np.take(x, e[:, 1], axis=0)
        d -= np.take(x, e[:, 0], axis=0)
        c = (1.0 / np.sqrt(np.einsum("ij,ij->i", d, d)))[edge_id]
    row = np.repeat(np.arange(n), counts)
    if fixed is not None:
        c = np.where(fixed[row], 0.0, c)
    total = np.bincount(row, weights=c, minlength=n)  # per row; unused vertices have none
    scale = np.divide(1.0, total, out=np.zeros(n), where=total > 0)
    return sp.csr_matrix((c * scale[row], indices, indptr), shape=(n, n))


@_validate.renamed(weights="weighting")
def laplacian_operator(
    mesh: QuadMesh,
    *,
    weighting: Weighting = "uniform",
    vertices: np.ndarray | None = None,
    fixed: np.ndarray | None = None,
) -> sp.csr_matrix:
    """The ``(n, n)`` matrix ``L = W − I`` over the edge 1-ring.

    Parameters
    ----------
    mesh : QuadMesh
    weighting : {"uniform", "inverse_length"}
        Equal weights, or Fujiwara weights ``1/||x_i − x_j||`` (thesis 3.2.5).
    vertices : (n, 3) float64, optional
        Positions for the edge lengths (default: the mesh's).
    fixed : (n,) bool, optional
        Vertices whose row is zero (they do not move).

    Returns
    -------
    scipy.sparse.csr_matrix
        Each row sums to zero.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> L = laplacian_operator(grid(3, 3))
    >>> L[4].toarray().round(2).tolist()
    [[0.0, 0.25, 0.0, 0.25, -1.0, 0.25, 0.0, 0.25, 0.0]]
    """
    _validate.quad_mesh(mesh)
    if fixed is not None:
        fixed = _validate.vertex_mask(fixed, mesh.n_vertices, "fixed")
    W = _weights(mesh, weighting, vertices, fixed)
    moving = np.diff(W.indptr) > 0
    if fixed is not None:
        moving &= ~fixed
    return (W - sp.diags(moving.astype(np.float64))).tocsr()


def taubin_lambda(k_pb: float) -> float:
    """The largest stable ``λ`` for a pass-band ``k_PB``, from Taubin's ``f(1) = −f(2)``.

    Examples
    --------
    >>> round(taubin_lambda(0.1), 4)
    0.6314
    """
    k_pb = _validate.positive_number(k_pb, "k_pb")
    if k_pb >= 1:
        raise InputError(f"k_pb: must be < 1 for this rule, got {k_pb!r}")

    def g(lam: float) -> float:
        mu = 1.0 / (k_pb - 1.0 / lam)
        return (1 - lam) * (1 - mu) + (1 - 2 * lam) * (1 - 2 * mu)

    return float(brentq(g, 1e-6, 1.0 / k_pb - 1e-9))


def _smooth(mesh: QuadMesh, factors: list[float], weighting: Weighting, fixed: np.ndarray) -> QuadMesh:
    """Run the steps ``x' = x + f L x`` for every factor ``f`` in turn; ``fixed`` rows never move."""
    x = mesh.vertices.copy()
    # x' = x + f (W x − x) on moving vertices; fixed ones (empty rows) keep their place
    moving = (np.diff(mesh.topology.ring[0]) > 0) & ~fixed
    if weighting != "uniform":
        mask = moving.astype(np.float64)[:, None]
        for f in factors:
            step = _weights(mesh, weighting, x, fixed) @ x
            step -= x
            step *= mask
            step *= f
            x += step
        return mesh.with_vertices(x)
    # the operator is fixed: x' = (1 − f·moving) x + (f W) x, one product per step,
    # written row range by row range (in parallel on large meshes) into a second buffer;
    # small meshes store the coordinates as (3, n), see linalg.threads.COLUMNS_MAX_NNZ
    W = _weights(mesh, weighting, None, fixed)
    blocks = RowBlocks(W)
    scaled = {f: W.data * f for f in set(factors)}
    still = np.flatnonzero(~moving)  # rows that keep their position (f·W is empty there)
    if blocks.columns:
        x = np.array(x.T)
    y = np.empty_like(x)

    def step(src: np.ndarray, dst: np.ndarray, f: float, lo: int, hi: int) -> None:
        s = still[np.searchsorted(still, lo) : np.searchsorted(still, hi)]
        if blocks.columns:
            np.multiply(src[:, lo:hi], 1.0 - f, out=dst[:, lo:hi])
            dst[:, s] = src[:, s]
        else:
            np.multiply(src[lo:hi], 1.0 - f, out=dst[lo:hi])  # a scalar: no (n, 1) broadcast
            dst[s] = src[s]
        blocks.matvec(src, dst, lo, hi, data=scaled[f], accumulate=True)

    for f in factors:
        blocks.run(partial(step, x, y, f))
        x, y = y, x
    return mesh.with_vertices(x.T if blocks.columns else x)


def _finish(mesh: QuadMesh, out: QuadMesh, method: str, iterations: int, lam: float, mu: float | None,
            weighting: str, fix: str, fixed: np.ndarray, gain: float, t0: float) -> tuple[QuadMesh, SmoothingReport]:
    moved = np.linalg.norm(out.vertices - mesh.vertices, axis=1)
    return out, SmoothingReport(
        method=method, iterations=iterations, lam=lam, mu=mu, weighting=weighting, fix=fix,
        n_fixed=int(fixed.sum()), moved_max=float(moved.max()), moved_mean=float(moved.mean()),
        gain_max=gain, seconds=time.perf_counter() - t0, unit=mesh.unit,
    )


@_validate.renamed(weights="weighting")
def laplacian(
    mesh: QuadMesh,
    *,
    iterations: int = 1,
    lam: float = 0.5,
    weighting: Weighting = "uniform",
    fix: Fix = "none",
    fixed: ArrayLike | None = None,
) -> tuple[QuadMesh, SmoothingReport]:
    """Laplacian smoothing ``x' = x + λ L x``, repeated ``iterations`` times.

    Parameters
    ----------
    mesh : QuadMesh
    iterations : int
        Number of steps (1 … 100,000).
    lam : float
        Scale factor ``0 < λ <= 1`` (1 moves each vertex onto its neighbours'
        barycenter).
    weighting : {"uniform", "inverse_length"}
        Equal weights, or Fujiwara weights recomputed every step.
    fix : {"none", "corners", "boundary"}
        Vertices that do not move (:func:`quadnodes.topology.fixed_vertices`); the
        thesis fixes none.
    fixed : (n,) bool or int indices, optional
        More vertices that do not move.

    Returns
    -------
    mesh : QuadMesh
    report : SmoothingReport

    Raises
    ------
    InputError
        On something other than a mesh, a bad iteration count, ``λ`` outside
        (0, 1], or an unknown option.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> z = np.zeros((3, 3)); z[1, 1] = 1.0
    >>> out, rep = laplacian(grid(3, 3, height=z), lam=0.5, fix="boundary")
    >>> float(out.vertices[4, 2]), rep.n_fixed
    (0.5, 8)
    """
    t0 = time.perf_counter()
    _validate.quad_mesh(mesh)
    iterations = _validate.iteration_count(iterations, "iterations")
    lam = _validate.positive_number(lam, "lam")
    if lam > 1:
        raise InputError(f"lam: must be in (0, 1], got {lam!r} (a larger step overshoots and the mesh oscillates)")
    weighting = _validate.choice(weighting, WEIGHTINGS, "weighting")  # type: ignore[assignment]
    held = fixed_vertices(mesh, fix, fixed)
    out = _smooth(mesh, [lam] * iterations, weighting, held)
    return _finish(mesh, out, "laplacian", iterations, lam, None, weighting, fix, held, step_gain([lam])[0], t0)


@_validate.renamed(weights="weighting")
def taubin(
    mesh: QuadMesh,
    *,
    iterations: int = 1,
    lam: float | None = None,
    k_pb: float = 0.1,
    mu: float | None = None,
    weighting: Weighting = "uniform",
    fix: Fix = "none",
    fixed: ArrayLike | None = None,
) -> tuple[QuadMesh, SmoothingReport]:
    """Taubin λ|μ smoothing: each iteration is a ``λ`` step then a ``μ`` step.

    Parameters
    ----------
    mesh : QuadMesh
    iterations : int
        Number of λ|μ pairs (1 … 100,000).
    lam : float, optional
        Positive scale factor; default from Taubin's rule ``f(1) = −f(2)`` for
        ``k_pb`` (λ = 0.6314, μ = −0.6740 for ``k_pb = 0.1``; Taubin quotes the rounded 0.6307).
    k_pb : float
        Pass-band frequency; ``μ = 1 / (k_PB − 1/λ)``.
    mu : float, optional
        Give ``μ`` directly instead (must satisfy ``μ < −λ``).
    weighting, fix, fixed
        As in :func:`laplacian`.

    Returns
    -------
    mesh : QuadMesh
    report : SmoothingReport

    Raises
    ------
    InputError
        On bad counts or factors: ``μ`` must be negative with ``|μ| > λ``, and
        the pair must not amplify any frequency it should smooth (``|(1 − λk)(1 − μk)| <= 1`` for
        ``k`` above the pass band ``1/λ + 1/μ``; the message names the frequency and the gain).

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> m, rep = taubin(grid(4, 4), iterations=3)
    >>> bool(np.allclose(m.vertices[:, 2], 0)), round(rep.mu, 4)
    (True, -0.674)
    >>> taubin(grid(4, 4), lam=1.0)
    Traceback (most recent call last):
    ...
    quadnodes.errors.InputError: lam=1, mu=-1.111: each iteration multiplies frequency k=2 (of 0..2) by 3.22, so the mesh would grow without bound; use lam <= 0.7 (the default 0.6314 for k_pb=0.1)
    """
    t0 = time.perf_counter()
    _validate.quad_mesh(mesh)
    iterations = _validate.iteration_count(iterations, "iterations")
    lam = taubin_lambda(k_pb) if lam is None else _validate.positive_number(lam, "lam")
    if mu is None:
        k_pb = _validate.positive_number(k_pb, "k_pb")
        if k_pb >= 1.0 / lam:
            raise InputError(f"k_pb: must be < 1/lam = {1 / lam:.4g}, got {k_pb!r}")
        mu = 1.0 / (k_pb - 1.0 / lam)
    else:
        mu = _validate.finite_number(mu, "mu")
    if not mu < -lam:
        raise InputError(f"mu: must be negative with |mu| > lam = {lam:.4g}, got {mu!r}")
    # Taubin's pass band k < k_pb = 1/λ + 1/μ is kept (gained very slightly on purpose); above it no
    # frequency may grow, or the mesh grows without bound there
    band = 1.0 / lam + 1.0 / mu
    gain, k = step_gain([lam, mu], low=band)
    if band >= 2.0 or gain > 1.0 + 1e-9:
        raise InputError(
            f"lam={lam:.4g}, mu={mu:.4g}: each iteration multiplies frequency k={k:.3g} (of 0..2) by {gain:.3g}, "
            "so the mesh would grow without bound; use lam <= 0.7 (the default 0.6314 for k_pb=0.1)"
        )
    weighting = _validate.choice(weighting, WEIGHTINGS, "weighting")  # type: ignore[assignment]
    held = fixed_vertices(mesh, fix, fixed)
    out = _smooth(mesh, [lam, mu] * iterations, weighting, held)
    return _finish(mesh, out, "taubin", iterations, lam, mu, weighting, fix, held, gain, t0)
