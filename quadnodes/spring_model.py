"""The spring model of Yamada et al. (thesis 3.3, eq. 20–24).

A linear spring along the normal line of every node: for neighbours ``i, j`` with
unit normals ``n_i, n_j`` (``<n_i, n_j> > 0``) the normal lines meet (or pass
closest) at ``H``, and node ``i`` is displaced so that its spring length
``|p_i − H|`` equals node ``j``'s (eq. 22–23)::

    dp_ij = <p_j − p_i, n_i + n_j> / (1 + <n_i, n_j>) · n_i

which needs no ``H`` and reduces to ``<p_j − p_i, n> n`` for parallel normals. The
displacements are averaged with weights ``1 / |p_i − p_j|`` (eq. 24), and a
tangential regularizing component — the part of the umbrella vector
``mean(p_j) − p_i`` perpendicular to ``n_i`` — keeps the nodes evenly spread.
Normals are the normalized mean of the adjoining faces' unit normals, recomputed
every iteration. Iterations stop when the largest displacement, divided by the
node's mean edge length, is below ``tolerance`` (the thesis's termination rule).

Departure: the paper moves nodes one after another (Gauss–Seidel). Here all
nodes move at once (vectorized, no loop over vertices), damped by ``step``
(0.5 by default): an undamped simultaneous update would let the checkerboard
(zigzag) mode of a quad grid oscillate instead of decay.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from . import _validate
from .discrete_curvature import vertex_normals
from .errors import InputError
from .mesh import QuadMesh
from .progress import report_progress
from .topology import FIX_MODES, fixed_vertices

__all__ = ["spring_displacement", "SpringReport", "spring"]


def spring_displacement(mesh: QuadMesh, vertices: np.ndarray, *, tangential: bool = True,
                        normals: np.ndarray | None = None, constrained: np.ndarray | None = None
                        ) -> tuple[np.ndarray, np.ndarray, float, int]:
    """One evaluation of the spring model at ``vertices``.

    ``normals`` (n, 3) with a mask ``constrained``: normal constraints — those
    vertices use the given unit normals instead of the faces' mean.

    Returns
    -------
    normal_part : (n, 3) float64
        ``dp_i`` of eq. 24 (along ``n_i``).
    tangential_part : (n, 3) float64
        ``dp_u,i`` (perpendicular to ``n_i``; zeros without ``tangential``).
    energy : float
        ``Σ_edges (t_j − t_i)²``, the squared spring-length differences (0 on a sphere).
    skipped : int
        Neighbour pairs with ``<n_i, n_j> <= 0`` (left out of the average).

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> m = grid(3, 3)
    >>> dn, dt, e, s = spring_displacement(m, m.vertices)
    >>> float(abs(dn).max()), e, s
    (0.0, 0.0, 0)
    """
    n = mesh.n_vertices
    indptr, j, _ = mesh.topology.ring
    i = np.repeat(np.arange(n), np.diff(indptr))
    nrm = vertex_normals(vertices, mesh.faces)
    if normals is not None and constrained is not None:
        nrm[constrained] = normals[constrained]
    ni, nj = nrm[i], nrm[j]
    d = vertices[j] - vertices[i]
    cdot = np.einsum("ij,ij->i", ni, nj)
    ok = cdot > 1e-9
    tdiff = np.where(ok, np.einsum("ij,ij->i", d, ni + nj) / np.where(ok, 1.0 + cdot, 1.0), 0.0)
    w = np.where(ok, 1.0 / np.linalg.norm(d, axis=1), 0.0)
    wsum = np.bincount(i, w, minlength=n)
    s = np.divide(np.bincount(i, w * tdiff, minlength=n), wsum, out=np.zeros(n), where=wsum > 0)
    normal_part = s[:, None] * nrm
    if tangential:
        count = np.diff(indptr)
        mean = np.stack([np.bincount(i, vertices[j, k], minlength=n) for k in range(3)], axis=1)
        u0 = np.divide(mean, count[:, None], out=np.zeros_like(mean), where=count[:, None] > 0) - vertices
        u0[count == 0] = 0.0
        tang = u0 - np.einsum("ij,ij->i", u0, nrm)[:, None] * nrm
    else:
        tang = np.zeros_like(vertices)
    return normal_part, tang, 0.5 * float(np.sum(tdiff[ok] ** 2)), int((~ok).sum() // 2)


@dataclass(frozen=True)
class SpringReport:
    """What :func:`spring` did: iterations, convergence, energies (squared spring-length differences)."""

    fix: str
    n_fixed: int
    iterations: int
    converged: bool
    tolerance: float
    step: float
    energy_input: float
    energy: float
    max_displacement: float
    skipped_pairs: int
    seconds: float
    history: list[float] = field(default_factory=list)

    def to_dict(self) -> dict:
        """Plain-Python form (JSON-ready)."""
        return asdict(self)


def spring(
    mesh: QuadMesh,
    *,
    fix: Literal["none", "corners", "boundary"] = "boundary",
    fixed: ArrayLike | None = None,
    max_iterations: int = 500,
    tolerance: float = 1e-4,
    step: float = 0.5,
    tangential: bool = True,
    normals: ArrayLike | None = None,
) -> tuple[QuadMesh, SpringReport]:
    """Fair a quad mesh with Yamada et al.'s spring model (thesis 3.3).

    Parameters
    ----------
    mesh : QuadMesh
    fix : {"none", "corners", "boundary"}
        Positional constraints; the boundary by default, as the thesis requires
        for an open surface.
    fixed : (n,) bool or int indices, optional
        More vertices to hold.
    max_iterations : int
        Cap on iterations.
    tolerance : float
        Stop when the largest displacement over the node's mean edge length is below it.
    step : float
        Damping ``0 < step <= 1`` of the simultaneous update (see the module docstring).
    tangential : bool
        Apply the tangential regularizing component.
    normals : (n, 3) float64, optional
        Normal constraints (thesis 3.3): the fixed vertices keep these unit
        normals instead of the mean of their faces' normals, which at a boundary
        sees one side only and tilts by about half an edge's turn — enough to bend
        the whole surface, since every spring length is matched to its
        neighbours'. Give the design surface's normals there (a G1 boundary).

    Returns
    -------
    mesh : QuadMesh
    report : SpringReport
        ``history``: the largest normalized displacement of every iteration.

    Raises
    ------
    InputError
        On a bad option, or when every vertex is fixed.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> z = np.zeros((5, 5)); z[2, 2] = 0.3
    >>> out, rep = spring(grid(5, 5, height=z))
    >>> rep.converged, bool(abs(out.vertices[12, 2]) < 0.05)
    (True, True)
    """
    t0 = time.perf_counter()
    _validate.quad_mesh(mesh)
    fix = _validate.choice(fix, FIX_MODES, "fix")  # type: ignore[assignment]
    max_iterations = _validate.positive_int(max_iterations, "max_iterations")
    tol = _validate.positive_number(tolerance, "tolerance")
    step = _validate.positive_number(step, "step")
    if step > 1:
        raise InputError(f"step: must be in (0, 1], got {step!r}")
    hold = fixed_vertices(mesh, fix, fixed)
    if hold.all():
        raise InputError(f"fix: every vertex is fixed (fix={fix!r}); nothing can move")
    movable = (~hold).astype(np.float64)[:, None]
    given = None
    if normals is not None:
        given = np.asarray(normals, dtype=np.float64)
        if given.shape != mesh.vertices.shape or not np.isfinite(given).all():
            raise InputError(f"normals: expected finite unit vectors of shape {mesh.vertices.shape}, got "
                             f"shape {given.shape}")
        length = np.linalg.norm(given, axis=1, keepdims=True)
        bad = np.flatnonzero(hold & (length[:, 0] < 1e-12))
        if bad.size:
            raise InputError(f"normals: zero normal at fixed vertex {int(bad[0])}")
        given = given / np.maximum(length, 1e-300)
    e = mesh.topology.edges
    val = np.maximum(mesh.topology.valence, 1)
    x = mesh.vertices.copy()
    history: list[float] = []
    e_in = e_now = None
    skipped = 0
    converged = False
    it = 0
    for it in range(1, max_iterations + 1):
        dn, dt, e_now, skipped = spring_displacement(mesh, x, tangential=bool(tangential), normals=given,
                                                       constrained=hold)
        if e_in is None:
            e_in = e_now
        move = step * (dn + dt) * movable
        length = np.linalg.norm(x[e[:, 1]] - x[e[:, 0]], axis=1)
        local = np.bincount(e.reshape(-1), np.repeat(length, 2), minlength=mesh.n_vertices) / val
        worst = float((np.linalg.norm(move, axis=1) / np.maximum(local, 1e-300)).max())  # (a vertex in no face: 0)
        history.append(worst)
        x += move
        if it % 10 == 0:
            report_progress(it / max_iterations, f"spring iteration {it}: largest move {worst:.2e} edge lengths")
        if worst < tol:
            converged = True
            break
    _, _, e_now, skipped = spring_displacement(mesh, x, tangential=False, normals=given, constrained=hold)
    report_progress(1.0, f"spring: {it} iterations")
    return mesh.with_vertices(x), SpringReport(fix, int(hold.sum()), it, converged, tol, step, float(e_in),
                                               float(e_now), history[-1], skipped, time.perf_counter() - t0,
                                               history)
