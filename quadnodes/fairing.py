"""The thesis's structure-line fairing (chapter 4, eq. 32–34).

For every window ``p0..p3`` of every structure line, the deviation of three
consecutive unit directions is linearized by freezing the edge lengths
``l0, l1, l2`` at the current iterate::

    f = -p0/(2 l0) + (1/(2 l0) + 1/l1) p1 - (1/l1 + 1/(2 l2)) p2 + p3/(2 l2)

and the energy ``Σ_windows ||f||² + ω Σ_free ||p − anchor||²`` is minimized over
the free (zigzag) vertices, fixed vertices moving to the right-hand side. The
matrix ``AᵀA + ω I`` is the same for x, y and z: it is factorized once and solved
for three right-hand sides.

The weight is dimensionless by default: ``ω_eff = ω / h²`` with ``h`` the mean edge
length of the input, so the result does not depend on the unit of the model.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Literal

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike
from scipy.sparse.linalg import splu

from . import _validate
from .errors import InputError
from .progress import report_progress
from .mesh import QuadMesh
from .zigzag import detect, window_deviation

__all__ = [
    "DEFAULT_WEIGHT",
    "window_coefficients",
    "fairing_matrix",
    "fairing_energy",
    "FairingSystem",
    "IterationReport",
    "FairingReport",
    "fair",
]

#: Default dimensionless penalty weight (in units of the mean edge length).
#: Chosen from ``benchmarks/weight_sweep.py``; see ``docs/fairing.md``.
DEFAULT_WEIGHT = 0.3


def window_coefficients(vertices: np.ndarray, windows: np.ndarray) -> np.ndarray:
    """Coefficients ``(a0, a1, a2, a3)`` of eq. 32 for every window.

    Lengths are taken from ``vertices`` (frozen). Each row sums to zero, so the
    term is invariant under translation.

    Parameters
    ----------
    vertices : (n, 3) float64
    windows : (w, 4) int64

    Returns
    -------
    (w, 4) float64

    Examples
    --------
    >>> v = np.array([[0., 0, 0], [1, 0, 0], [3, 0, 0], [4, 0, 0]])
    >>> window_coefficients(v, np.array([[0, 1, 2, 3]])).tolist()
    [[-0.5, 1.0, -1.0, 0.5]]
    """
    p = vertices[windows]
    inv = 1.0 / np.linalg.norm(np.diff(p, axis=1), axis=2)  # 1/l0, 1/l1, 1/l2
    return np.stack(
        [-0.5 * inv[:, 0], 0.5 * inv[:, 0] + inv[:, 1], -inv[:, 1] - 0.5 * inv[:, 2], 0.5 * inv[:, 2]],
        axis=1,
    )


def fairing_matrix(vertices: np.ndarray, windows: np.ndarray) -> sp.csr_matrix:
    """The ``(w, n)`` matrix ``A`` with ``(A @ P)[i]`` = the linearized term of window ``i``.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> m = grid(2, 5)
    >>> A = fairing_matrix(m.vertices, m.topology.windows)
    >>> A.shape, float(abs(A @ m.vertices).max())
    ((4, 10), 0.0)
    """
    n = vertices.shape[0]
    c = window_coefficients(vertices, windows)
    rows = np.repeat(np.arange(len(windows)), 4)
    return sp.csr_matrix((c.reshape(-1), (rows, windows.reshape(-1))), shape=(len(windows), n))


def fairing_energy(
    vertices: np.ndarray, windows: np.ndarray, *, lengths_from: np.ndarray | None = None
) -> float:
    """Linearized fairness energy ``Σ ||f_i||²`` with lengths frozen at ``lengths_from``.

    ``lengths_from`` defaults to ``vertices``; then ``||f_i||²`` equals the
    window's deviation (eq. 30) exactly.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> m = grid(3, 5)
    >>> fairing_energy(m.vertices, m.topology.windows)
    0.0
    """
    ref = vertices if lengths_from is None else lengths_from
    c = window_coefficients(ref, windows)
    f = np.einsum("wk,wkj->wj", c, vertices[windows])
    return float(np.einsum("ij,ij->", f, f))


class FairingSystem:
    """One fairing iteration's least-squares system, factorized once.

    Unknowns are the free vertices only; every window with at least one free
    vertex contributes a row; fixed vertices move to the right-hand side. The
    normal matrix ``AᵀA + ω I`` is factorized on construction and reused by
    :meth:`solve` for any anchor (three right-hand sides per solve).

    Parameters
    ----------
    vertices : (n, 3) float64
        Current positions; lengths are frozen from them, fixed vertices stay here.
    windows : (w, 4) int64
        Windows of the mesh's structure lines.
    free : (n,) bool
        Vertices to move; must contain at least one vertex.
    weight : float
        Effective penalty weight ``ω`` (> 0), in the model's units (``1/length²``).

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> m = grid(3, 5, height=[[0] * 5, [0, 0, 1, 0, 0], [0] * 5])
    >>> free = np.zeros(15, bool); free[7] = True
    >>> s = FairingSystem(m.vertices, m.topology.windows, free, weight=1.0)
    >>> s.solve(m.vertices[free]).round(3).tolist()
    [[2.0, 1.0, 0.308]]
    """

    def __init__(self, vertices: np.ndarray, windows: np.ndarray, free: np.ndarray, weight: float) -> None:
        weight = _validate.positive_number(weight, "weight")
        free = np.asarray(free, dtype=bool)
        n = vertices.shape[0]
        self.free_index = np.flatnonzero(free)
        k = self.free_index.size
        if k == 0:
            raise InputError("free: no vertex is free; nothing to solve")
        is_free = free[windows]
        active = is_free.any(axis=1)
        win = windows[active]
        is_free = is_free[active]
        coef = window_coefficients(vertices, win)
        col = np.full(n, -1, dtype=np.int64)
        col[self.free_index] = np.arange(k)
        rows = np.broadcast_to(np.arange(len(win))[:, None], win.shape)
        A = sp.csr_matrix((coef[is_free], (rows[is_free], col[win][is_free])), shape=(len(win), k))
        # fixed vertices' contribution to every active row
        b = np.einsum("wk,wkj->wj", np.where(is_free, 0.0, coef), vertices[win])
        self.weight = weight
        self.A = A
        self.b = b
        self.matrix = (A.T @ A + weight * sp.identity(k, format="csr")).tocsc()
        self._rhs = -(A.T @ b)
        self._lu = splu(
            self.matrix,
            permc_spec="MMD_AT_PLUS_A",
            diag_pivot_thresh=0.0,
            options={"SymmetricMode": True},
        )

    @property
    def n_free(self) -> int:
        """Number of unknown vertices."""
        return int(self.free_index.size)

    def solve(self, anchor: ArrayLike) -> np.ndarray:
        """Minimize ``||A x + b||² + ω ||x − anchor||²``.

        Parameters
        ----------
        anchor : (k, 3) float64
            Penalty targets of the free vertices, in ``free_index`` order.

        Returns
        -------
        (k, 3) float64
            New positions of the free vertices.
        """
        a = np.asarray(anchor, dtype=np.float64)
        if a.shape != (self.n_free, 3):
            raise InputError(f"anchor: expected shape ({self.n_free}, 3), got {a.shape}")
        return self._lu.solve(self._rhs + self.weight * a)

    def objective(self, x: np.ndarray, anchor: np.ndarray) -> float:
        """Value of ``||A x + b||² + ω ||x − anchor||²`` for free positions ``x``."""
        r = self.A @ x + self.b
        d = x - anchor
        return float(np.einsum("ij,ij->", r, r) + self.weight * np.einsum("ij,ij->", d, d))


@dataclass(frozen=True)
class IterationReport:
    """What one fairing iteration did.

    ``energy_before``/``energy_after`` are the linearized energy (eq. 32) of the
    whole mesh with lengths frozen at the iterate's start; ``deviation_*`` the
    exact eq. 30 sums.
    """

    iteration: int
    threshold: float
    weight: float
    weight_effective: float
    n_free: int
    energy_before: float
    energy_after: float
    deviation_before: float
    deviation_after: float
    max_displacement: float


@dataclass(frozen=True)
class FairingReport:
    """Per-iteration reports of :func:`fair` and the length scale used."""

    iterations: list[IterationReport] = field(default_factory=list)
    length_scale: float = 1.0
    weight_scale: str = "normalized"

    def to_dict(self) -> dict:
        """Plain-Python form (JSON-ready)."""
        return {
            "length_scale": self.length_scale,
            "weight_scale": self.weight_scale,
            "iterations": [asdict(r) for r in self.iterations],
        }


def fair(
    mesh: QuadMesh,
    *,
    iterations: int = 1,
    deviation: float | Sequence[float] = 0.1,
    deviation_decay: float = 1.0,
    weight: float | Sequence[float] = DEFAULT_WEIGHT,
    weight_decay: float = 1.0,
    weight_scale: Literal["normalized", "raw"] = "normalized",
    anchor: Literal["current", "input"] = "current",
    fixed: ArrayLike | None = None,
    fix_boundary: bool = False,
) -> tuple[QuadMesh, FairingReport]:
    """Fair the zigzag structure lines of a quad mesh (thesis chapter 4).

    Each iteration detects the free vertices (deviation above the iteration's
    threshold, see :func:`quadnodes.zigzag.detect`), freezes edge lengths, and
    solves one sparse least-squares problem for the free vertices.

    Parameters
    ----------
    mesh : QuadMesh
    iterations : int
        Number of iterations (>= 1).
    deviation : float or sequence of float
        Deviation threshold per iteration: one number, or one value per iteration.
    deviation_decay : float
        Factor applied to a single ``deviation`` each iteration (the thesis's
        example 3 uses ``deviation=1, deviation_decay=0.5``).
    weight : float or sequence of float
        Penalty weight ω (> 0) per iteration, like ``deviation``.
    weight_decay : float
        Factor applied to a single ``weight`` each iteration.
    weight_scale : {"normalized", "raw"}
        ``"normalized"`` (default): ``ω_eff = ω / h²`` with ``h`` the input's mean
        edge length, so ``fair(s·P) == s·fair(P)``. ``"raw"``: the thesis's ω as is
        (its effect then depends on the model's unit).
    anchor : {"current", "input"}
        Penalize the distance to the current iterate (default) or to the input.
    fixed : (n,) bool or int indices, optional
        Vertices that never move (corners always stay).
    fix_boundary : bool
        Keep every boundary vertex in place.

    Returns
    -------
    mesh : QuadMesh
        The faired mesh (the input itself when no vertex was free).
    report : FairingReport

    Raises
    ------
    InputError
        On a non-positive or NaN weight, a negative threshold, a schedule shorter
        than ``iterations``, an unknown option, or when the fixing leaves no vertex
        that could move.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> z = np.zeros((5, 7)); z[2, 3] = 0.5
    >>> out, rep = fair(grid(5, 7, height=z), iterations=2, deviation=0.01)
    >>> [r.n_free for r in rep.iterations], round(float(out.vertices[17, 2]), 3)
    ([7, 0], 0.032)
    """
    iterations = _validate.positive_int(iterations, "iterations")
    thresholds = _validate.schedule(deviation, iterations, "deviation", decay=deviation_decay)
    weights = _validate.schedule(weight, iterations, "weight", decay=weight_decay, positive=True)
    if weight_scale not in ("normalized", "raw"):
        raise InputError(f"weight_scale: expected 'normalized' or 'raw', got {weight_scale!r}")
    if anchor not in ("current", "input"):
        raise InputError(f"anchor: expected 'current' or 'input', got {anchor!r}")
    n = mesh.n_vertices
    user = _validate.vertex_mask(fixed, n, "fixed")
    topo = mesh.topology
    movable = topo.window_middle & ~user
    if fix_boundary:
        movable &= ~topo.boundary_vertices
    if topo.window_middle.any() and not movable.any():
        raise InputError(
            "fixed: every vertex that lies inside a structure line is fixed; nothing can be faired"
        )
    h = mesh.mean_edge_length
    scale = 1.0 / h**2 if weight_scale == "normalized" else 1.0
    w = topo.windows
    x0 = mesh.vertices
    x = x0
    reports: list[IterationReport] = []
    for it in range(iterations):
        current = mesh if x is x0 else mesh.with_vertices(x)
        zz = detect(current, float(thresholds[it]), fixed=user, fix_boundary=fix_boundary)
        dev_before = float(zz.window_deviation.sum())
        e_before = fairing_energy(x, w)
        if zz.n_free == 0:
            reports.append(
                IterationReport(it, float(thresholds[it]), float(weights[it]), float(weights[it] * scale),
                                0, e_before, e_before, dev_before, dev_before, 0.0)
            )
            report_progress((it + 1) / iterations, f"iteration {it + 1}/{iterations}: no zigzag above {thresholds[it]:g}")
            continue
        w_eff = float(weights[it] * scale)
        system = FairingSystem(x, w, zz.free, w_eff)
        target = (x if anchor == "current" else x0)[system.free_index]
        new_free = system.solve(target)
        x_new = x.copy()
        x_new[system.free_index] = new_free
        disp = np.linalg.norm(new_free - x[system.free_index], axis=1)
        reports.append(
            IterationReport(
                iteration=it,
                threshold=float(thresholds[it]),
                weight=float(weights[it]),
                weight_effective=w_eff,
                n_free=system.n_free,
                energy_before=e_before,
                energy_after=fairing_energy(x_new, w, lengths_from=x),
                deviation_before=dev_before,
                deviation_after=float(window_deviation(x_new, w).sum()),
                max_displacement=float(disp.max()),
            )
        )
        x = x_new
        report_progress((it + 1) / iterations, f"iteration {it + 1}/{iterations}: {system.n_free} free vertices")
    out = mesh if x is x0 else mesh.with_vertices(x)
    return out, FairingReport(reports, length_scale=h, weight_scale=weight_scale)
