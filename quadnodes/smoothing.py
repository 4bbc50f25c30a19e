"""Laplacian and Taubin smoothing on the quad mesh's own edge 1-ring (thesis 3.2.2–3.2.5).

The neighbours of a vertex are the vertices it shares an *edge* with — quad
diagonals are not neighbours (trimesh's filters work on the triangulation, where
they are; that is not what the thesis compares).

One Laplacian step is ``x' = x + λ L x`` with ``L = W − I`` and ``W`` the
row-normalized edge weights; a Taubin iteration is a ``λ`` step followed by a ``μ``
step with ``μ = 1 / (k_PB − 1/λ)`` (eq. 19). Fixed vertices get an empty
neighbourhood (a zero row), so they never move — Taubin's interpolatory constraint.
"""

from __future__ import annotations

from functools import partial
from typing import Literal

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike
from scipy.optimize import brentq

from . import _validate
from .errors import InputError
from .fairing import _RowBlocks
from .mesh import QuadMesh

__all__ = ["laplacian_operator", "taubin_lambda", "fixed_mask", "laplacian", "taubin"]

Weights = Literal["uniform", "inverse_length"]
Fix = Literal["none", "corners", "boundary"]


def _weights(mesh: QuadMesh, weights: Weights, vertices: np.ndarray | None, fixed: np.ndarray | None) -> sp.csr_matrix:
    """Row-normalized edge weights ``W`` (rows of fixed vertices empty)."""
    if weights not in ("uniform", "inverse_length"):
        raise InputError(f"weights: expected 'uniform' or 'inverse_length', got {weights!r}")
    n = mesh.n_vertices
    indptr, indices, edge_id = mesh.topology.ring
    counts = np.diff(indptr)
    if weights == "uniform":
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
    total = np.add.reduceat(c, indptr[:-1]) if c.size else np.zeros(n)
    total = np.where(counts > 0, total, 0.0)
    scale = np.divide(1.0, total, out=np.zeros(n), where=total > 0)
    return sp.csr_matrix((c * scale[row], indices, indptr), shape=(n, n))


def laplacian_operator(
    mesh: QuadMesh,
    *,
    weights: Weights = "uniform",
    vertices: np.ndarray | None = None,
    fixed: np.ndarray | None = None,
) -> sp.csr_matrix:
    """The ``(n, n)`` matrix ``L = W − I`` over the edge 1-ring.

    Parameters
    ----------
    mesh : QuadMesh
    weights : {"uniform", "inverse_length"}
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
    W = _weights(mesh, weights, vertices, fixed)
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


def fixed_mask(mesh: QuadMesh, fix: Fix | ArrayLike) -> np.ndarray:
    """Resolve a fixing option to a boolean ``(n,)`` mask.

    ``"none"`` (as in the thesis), ``"corners"`` (boundary corners), ``"boundary"``,
    or a boolean mask / index list.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> int(fixed_mask(grid(4, 4), "boundary").sum())
    12
    """
    n = mesh.n_vertices
    if isinstance(fix, str):
        if fix == "none":
            return np.zeros(n, dtype=bool)
        if fix == "corners":
            return mesh.topology.corner_vertices.copy()
        if fix == "boundary":
            return mesh.topology.boundary_vertices.copy()
        raise InputError(f"fix: expected 'none', 'corners', 'boundary' or a mask, got {fix!r}")
    return _validate.vertex_mask(fix, n, "fix")


def _smooth(mesh: QuadMesh, factors: list[float], weights: Weights, fix: Fix | ArrayLike) -> QuadMesh:
    fixed = fixed_mask(mesh, fix)
    x = mesh.vertices.copy()
    # x' = x + f (W x − x) on moving vertices; fixed ones (empty rows) keep their place
    moving = (np.diff(mesh.topology.ring[0]) > 0) & ~fixed
    if weights != "uniform":
        mask = moving.astype(np.float64)[:, None]
        for f in factors:
            step = _weights(mesh, weights, x, fixed) @ x
            step -= x
            step *= mask
            step *= f
            x += step
        return mesh.with_vertices(x)
    # the operator is fixed: x' = (1 − f·moving) x + (f W) x, one product per step,
    # written row range by row range (in parallel on large meshes) into a second buffer;
    # small meshes store the coordinates as (3, n), see fairing.COLUMNS_MAX_NNZ
    W = _weights(mesh, weights, None, fixed)
    blocks = _RowBlocks(W)
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


def laplacian(
    mesh: QuadMesh,
    *,
    iterations: int = 1,
    lam: float = 0.5,
    weights: Weights = "uniform",
    fix: Fix | ArrayLike = "none",
) -> QuadMesh:
    """Laplacian smoothing ``x' = x + λ L x``, repeated ``iterations`` times.

    Parameters
    ----------
    mesh : QuadMesh
    iterations : int
        Number of steps (>= 1).
    lam : float
        Scale factor ``0 < λ < 1`` (1 would move each vertex onto its neighbours'
        barycenter).
    weights : {"uniform", "inverse_length"}
        Inverse-length (Fujiwara) weights are recomputed every step.
    fix : {"none", "corners", "boundary"} or mask
        Vertices that do not move; the thesis fixes none.

    Returns
    -------
    QuadMesh

    Raises
    ------
    InputError
        On a non-positive iteration count, ``λ`` outside (0, 1], or a bad option.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> z = np.zeros((3, 3)); z[1, 1] = 1.0
    >>> float(laplacian(grid(3, 3, height=z), lam=0.5, fix="boundary").vertices[4, 2])
    0.5
    """
    iterations = _validate.positive_int(iterations, "iterations")
    lam = _validate.positive_number(lam, "lam")
    if lam > 1:
        raise InputError(f"lam: must be in (0, 1], got {lam!r}")
    return _smooth(mesh, [lam] * iterations, weights, fix)


def taubin(
    mesh: QuadMesh,
    *,
    iterations: int = 1,
    lam: float | None = None,
    k_pb: float = 0.1,
    mu: float | None = None,
    weights: Weights = "uniform",
    fix: Fix | ArrayLike = "none",
) -> QuadMesh:
    """Taubin λ|μ smoothing: each iteration is a ``λ`` step then a ``μ`` step.

    Parameters
    ----------
    mesh : QuadMesh
    iterations : int
        Number of λ|μ pairs (>= 1).
    lam : float, optional
        Positive scale factor; default from Taubin's rule ``f(1) = −f(2)`` for
        ``k_pb`` (λ = 0.6314, μ = −0.6740 for ``k_pb = 0.1``; Taubin quotes the rounded 0.6307).
    k_pb : float
        Pass-band frequency; ``μ = 1 / (k_PB − 1/λ)``.
    mu : float, optional
        Give ``μ`` directly instead (must satisfy ``μ < −λ``).
    weights, fix
        As in :func:`laplacian`.

    Returns
    -------
    QuadMesh

    Raises
    ------
    InputError
        On bad counts or factors (``μ`` must be negative with ``|μ| > λ``).

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> m = taubin(grid(4, 4), iterations=3)
    >>> bool(np.allclose(m.vertices[:, 2], 0))
    True
    """
    iterations = _validate.positive_int(iterations, "iterations")
    lam = taubin_lambda(k_pb) if lam is None else _validate.positive_number(lam, "lam")
    if mu is None:
        k_pb = _validate.positive_number(k_pb, "k_pb")
        if k_pb >= 1.0 / lam:
            raise InputError(f"k_pb: must be < 1/lam = {1 / lam:.4g}, got {k_pb!r}")
        mu = 1.0 / (k_pb - 1.0 / lam)
    else:
        mu = float(mu)
    if not (np.isfinite(mu) and mu < -lam):
        raise InputError(f"mu: must be negative with |mu| > lam = {lam:.4g}, got {mu!r}")
    return _smooth(mesh, [lam, mu] * iterations, weights, fix)
