"""Schneider–Kobbelt fairing: ``Δ_B H = 0`` (thesis 3.4, eq. 25–29).

Every iteration factorizes the fourth-order equation into two second-order steps:

1. the Dirichlet problem ``Δ_B H̃ = 0`` on the free vertices, with the
   cotangent Laplace–Beltrami matrix of the current mesh (eq. 26–27, formed on a
   quad mesh as the average over both triangulations of every quad, see
   :func:`quadnodes.discrete_curvature.cotangent_laplacian`) and the mean
   curvature of the fixed vertices next to them as boundary values;
2. every free vertex moves along its normal by the ``t`` that makes its mean
   curvature equal ``H̃`` — Moreton–Séquin's least-squares fit of the normal
   curvatures of eq. 28 (neighbours along edges and quad diagonals), linearized
   in ``t`` (eq. 29).

Inner fairness (the distribution of the vertices within the surface, which
Schneider and Kobbelt keep separate from the outer fairness ``Δ_B H = 0`` and
leave free to choose): by default the tangential part of the umbrella vector
``mean(q_j) − q_i`` — as in the spring model — so that tangential zigzag, which
normal moves cannot touch, is evened out too (``inner=False`` moves along the
normals only, as eq. 29 alone). A normal move is clamped to ``max_move`` local
edge lengths per iteration (a trust region against a wild linearization on
very noisy input; the report counts the clamped moves).

The G1 boundary condition: the fixed vertices (the boundary by default) and the
``ring`` layers of vertices sharing a face with them stay in place, so positions
and tangent planes at the border are kept.

Departure: all free vertices move at once (vectorized), damped by ``step``
(0.5 by default), instead of one after another.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike
from scipy.sparse.csgraph import connected_components

from . import _validate
from .discrete_curvature import cotangent_laplacian, moreton_sequin
from .errors import InputError
from .linalg import NESTED_DISSECTION_MIN, QuadraticProblem, nested_dissection
from .mesh import QuadMesh
from .progress import report_progress
from .topology import FIX_MODES, fixed_vertices

__all__ = ["SchneiderKobbeltReport", "schneider_kobbelt", "grow_ring"]


def grow_ring(mesh: QuadMesh, mask: np.ndarray, rings: int = 1) -> np.ndarray:
    """``mask`` grown by ``rings`` layers of vertices that share a face with it.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> m = grid(5, 5)
    >>> int(grow_ring(m, m.topology.boundary_vertices).sum())
    24
    """
    out = mask.copy()
    for _ in range(rings):
        touched = out[mesh.faces].any(axis=1)
        out[mesh.faces[touched].reshape(-1)] = True
    return out


@dataclass(frozen=True)
class SchneiderKobbeltReport:
    """What :func:`schneider_kobbelt` did.

    ``energy``: ``Σ_free (H − H̃)²``, the residual of the curvature step (0 at a
    solution of ``Δ_B H = 0``); ``history``: the largest move per iteration in
    local edge lengths.
    """

    fix: str
    ring: int
    n_fixed: int
    iterations: int
    converged: bool
    tolerance: float
    step: float
    inner: bool
    clamped: int
    energy_input: float
    energy: float
    max_displacement: float
    seconds: float
    history: list[float] = field(default_factory=list)

    def to_dict(self) -> dict:
        """Plain-Python form (JSON-ready)."""
        return asdict(self)


def schneider_kobbelt(
    mesh: QuadMesh,
    *,
    fix: Literal["none", "corners", "boundary"] = "boundary",
    fixed: ArrayLike | None = None,
    ring: int = 1,
    max_iterations: int = 200,
    tolerance: float = 1e-4,
    step: float = 0.5,
    inner: bool = True,
    max_move: float = 0.25,
) -> tuple[QuadMesh, SchneiderKobbeltReport]:
    """Fair a quad mesh towards ``Δ_B H = 0`` (Schneider–Kobbelt, thesis 3.4).

    Parameters
    ----------
    mesh : QuadMesh
    fix : {"none", "corners", "boundary"}
        Vertices held in place (the boundary by default).
    fixed : (n,) bool or int indices, optional
        More vertices to hold.
    ring : int
        Layers of vertices around the fixed ones also held (>= 0; 1 gives the
        G1 boundary condition).
    max_iterations : int
        Cap on iterations.
    tolerance : float
        Stop when the largest move is below this many local edge lengths.
    step : float
        Damping ``0 < step <= 1`` of the simultaneous normal moves.
    inner : bool
        Also even out the vertices within the surface (tangential umbrella step).
    max_move : float
        Largest normal move per iteration, in local edge lengths (> 0).

    Returns
    -------
    mesh : QuadMesh
    report : SchneiderKobbeltReport

    Raises
    ------
    InputError
        On a bad option; when no vertex is held (the Dirichlet problem needs
        boundary values) or every vertex is.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> z = np.zeros((7, 7)); z[3, 3] = 0.3
    >>> out, rep = schneider_kobbelt(grid(7, 7, height=z))
    >>> bool(abs(out.vertices[24, 2]) < 0.1)
    True
    """
    t0 = time.perf_counter()
    _validate.quad_mesh(mesh)
    fix = _validate.choice(fix, FIX_MODES, "fix")  # type: ignore[assignment]
    ring = _validate.positive_int(ring, "ring", minimum=0)
    max_iterations = _validate.positive_int(max_iterations, "max_iterations")
    tol = _validate.positive_number(tolerance, "tolerance")
    step = _validate.positive_number(step, "step")
    if step > 1:
        raise InputError(f"step: must be in (0, 1], got {step!r}")
    max_move = _validate.positive_number(max_move, "max_move")
    hold0 = fixed_vertices(mesh, fix, fixed)
    if not hold0.any():
        raise InputError("fix: no vertex is held; Δ_B H = 0 needs boundary values (fix='boundary' or fixed=...)")
    hold = grow_ring(mesh, hold0, ring)
    free = np.flatnonzero(~hold)
    if free.size == 0:
        raise InputError(f"fix: the fixed vertices and {ring} ring(s) around them cover the mesh; nothing can move")
    held = np.flatnonzero(hold)
    e = mesh.topology.edges
    val = np.maximum(mesh.topology.valence, 1)
    x = mesh.vertices.copy()
    history: list[float] = []
    e_in = e_now = 0.0
    converged = False
    clamped = 0
    indptr, nbr, _ = mesh.topology.ring
    rows = np.repeat(np.arange(mesh.n_vertices), np.diff(indptr))
    it = 0
    # the Dirichlet matrix keeps its pattern: one check that every part of the free mesh touches a held vertex
    # (then the cotangent stiffness matrix, positive semi-definite, is definite on the free vertices) and one
    # fill-reducing order serve every iteration
    L = cotangent_laplacian(mesh, vertices=x)
    Lff = L[free][:, free]
    ncomp, part = connected_components(Lff, directed=False)
    touches = np.zeros(ncomp, dtype=bool)
    touches[part[np.diff(L[free][:, held].tocsr().indptr) > 0]] = True
    if not touches.all():
        raise InputError("fix: the Laplace–Beltrami system is singular; some part of the mesh holds no fixed "
                         "vertex")
    order = nested_dissection(Lff) if free.size >= NESTED_DISSECTION_MIN else "minimum_degree"
    for it in range(1, max_iterations + 1):
        if it > 1:
            L = cotangent_laplacian(mesh, vertices=x)
        fit = moreton_sequin(mesh, vertices=x)
        H = fit["H"]
        # Δ_B H = 0 with the held vertices' curvature given: the harmonic curvature on the free vertices
        Ht = QuadraticProblem(L, known=held, method="direct", order=order,
                              what="schneider_kobbelt (Laplace–Beltrami system)").solve(
                                  np.zeros(mesh.n_vertices), Y=H[held])[free]
        r = H[free] - Ht
        e_now = float(r @ r)
        if it == 1:
            e_in = e_now
        slope = fit["dH_dt"][free]
        ok = np.abs(slope) > 1e-12 * np.abs(slope).max() if slope.size else slope.astype(bool)
        t = np.where(ok, -r / np.where(ok, slope, 1.0), 0.0) * step
        length = np.linalg.norm(x[e[:, 1]] - x[e[:, 0]], axis=1)
        local = (np.bincount(e.reshape(-1), np.repeat(length, 2), minlength=mesh.n_vertices) / val)[free]
        limit = max_move * local
        clamped += int((np.abs(t) > limit).sum())
        t = np.clip(t, -limit, limit)
        nf = fit["normals"][free]
        move = t[:, None] * nf
        if inner:
            mean = np.stack([np.bincount(rows, x[nbr, k], minlength=mesh.n_vertices) for k in range(3)], axis=1)
            u0 = (mean / val[:, None])[free] - x[free]
            move += step * (u0 - np.einsum("ij,ij->i", u0, nf)[:, None] * nf)
        worst = float((np.linalg.norm(move, axis=1) / local).max())
        history.append(worst)
        x[free] += move
        if it % 5 == 0:
            report_progress(it / max_iterations, f"Schneider–Kobbelt iteration {it}: largest move {worst:.2e}")
        if worst < tol:
            converged = True
            break
    report_progress(1.0, f"Schneider–Kobbelt: {it} iterations")
    return mesh.with_vertices(x), SchneiderKobbeltReport(fix, ring, int(hold.sum()), it, converged, tol, step,
                                                         bool(inner), clamped, e_in, e_now, history[-1], time.perf_counter() - t0,
                                                         history)
