"""Fair webs (thesis 3.1.1, eq. 5–11): energy-minimizing polygon networks with tolerance cylinders.

The polygon network is the mesh's structure lines (the same lines, closed ones
wrapping, that the thesis method's windows are built from). With ``Δ`` the
forward difference along a line (eq. 1)::

    E1 = Σ_lines Σ_k ||p_{k+1} − p_k||²                 (eq. 5, every line edge once)
    E2 = Σ_lines Σ_k ||p_{k−1} − 2 p_k + p_{k+1}||²     (eq. 6/11, every interior line vertex once)
    Eτ = E2 + τ E1                                       (eq. 7)

plus an optional closeness term ``c Σ ||p − p⁰||²`` (``c = 0`` as in eq. 11).
All are quadratic with the same matrix for x, y and z. Fixed vertices move to
the right-hand side. Optional **tolerance cylinders** (Fig. 3.1, option 1) keep
every free vertex inside a cylinder centred on its input position, axis along
the input's vertex normal, radius ``r`` (tangential) and half-height ``h``
(normal): a convex set, so the constrained problem is a convex QP with a unique
minimizer. It is solved as one — by default by a semismooth Newton method
(primal-dual active set on the KKT conditions). Where few vertices end on their
cylinder it runs in the space of the contact forces (the *contact method*,
:func:`_contacts`: from the unconstrained minimizer, adding the vertices
farthest outside round by round, each Newton step one dense solve of the active
constraints' size with ``P⁻¹`` on the contact vertices); where many touch it
gives way to the primal method (warm-started by ADMM: each step one sparse
positive definite solve on the coordinates the active constraints leave free,
by a factorization or, while few constraints switch, by conjugate gradients
preconditioned by the last one).
ADMM alone (``Q + ρI`` factorized once per ρ; the z-step is
the exact projection onto each cylinder) or accelerated projected gradient
(FISTA, step ``1/L`` from a Gershgorin bound). All stop on the KKT residual
(see ``tolerance``) and end with the exact projection. When the unconstrained
minimizer already lies inside every cylinder it is the answer (and is returned
as is).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from typing import Any, Literal

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from numpy.typing import ArrayLike
from scipy.sparse.csgraph import connected_components
from .linalg import NESTED_DISSECTION_MIN, expand_order, factorize, nested_dissection
from .linalg.inverse import InverseBlock
from .linalg.threads import blas_pinned

from . import _validate
from .discrete_curvature import vertex_normals
from .errors import InputError
from .mesh import QuadMesh
from .progress import report_progress
from .topology import FIX_MODES, fixed_vertices

__all__ = ["line_differences", "web_energy", "project_to_cylinders", "WebReport", "fair_web", "ENERGIES"]

#: Energies of :func:`fair_web`.
ENERGIES: tuple[str, ...] = ("E1", "E2", "tension")
_SOLVERS = ("newton", "admm", "projected_gradient")
#: ADMM over-relaxation factor α (1 = plain ADMM; 1.5-1.8 usually converges faster).
_RELAX = 1.6
#: ADMM iterations that start the Newton method (they stop early when ADMM alone converges).
_WARM = 200


def line_differences(mesh: QuadMesh) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """First and second difference matrices of all structure lines.

    Returns
    -------
    D1 : (e, n) csr_matrix
        One row ``p_{k+1} − p_k`` per line edge (closed lines wrap).
    D2 : (t, n) csr_matrix
        One row ``p_{k−1} − 2 p_k + p_{k+1}`` per interior line vertex (every
        vertex of a closed line).

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> D1, D2 = line_differences(grid(3, 4))
    >>> D1.shape, D2.shape
    ((17, 12), (10, 12))
    """
    lines = mesh.topology.structure_lines
    idx, off = lines.indices, lines.offsets
    length = np.diff(off)
    line = np.repeat(np.arange(len(length)), length)
    q = np.arange(idx.size) - off[line]
    L = length[line]
    closed = lines.closed[line]
    nxt = off[line] + np.where(closed, (q + 1) % L, np.minimum(q + 1, L - 1))
    prv = off[line] + np.where(closed, (q - 1) % L, np.maximum(q - 1, 0))
    n = mesh.n_vertices
    e = np.flatnonzero(closed | (q < L - 1))
    D1 = sp.csr_matrix(
        (np.tile([-1.0, 1.0], e.size), (np.repeat(np.arange(e.size), 2), np.column_stack([idx[e], idx[nxt[e]]]).ravel())),
        shape=(e.size, n),
    )
    t = np.flatnonzero((closed & (L >= 3)) | ((q > 0) & (q < L - 1)))
    D2 = sp.csr_matrix(
        (np.tile([1.0, -2.0, 1.0], t.size),
         (np.repeat(np.arange(t.size), 3), np.column_stack([idx[prv[t]], idx[t], idx[nxt[t]]]).ravel())),
        shape=(t.size, n),
    )
    return D1, D2


def _quadratic(D1: sp.csr_matrix, D2: sp.csr_matrix, energy: str, tension: float) -> sp.csr_matrix:
    if energy == "E1":
        return (D1.T @ D1).tocsr()
    Q = D2.T @ D2
    if energy == "tension" and tension > 0:
        Q = Q + tension * (D1.T @ D1)
    return Q.tocsr()


def web_energy(mesh: QuadMesh, *, vertices: np.ndarray | None = None) -> dict[str, float]:
    """``E1`` and ``E2`` of the structure-line network (eq. 5, 6) at ``vertices`` (default: the mesh's).

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> web_energy(grid(3, 3))
    {'E1': 12.0, 'E2': 0.0}
    """
    x = mesh.vertices if vertices is None else vertices
    D1, D2 = line_differences(mesh)
    a, b = D1 @ x, D2 @ x
    return {"E1": float(np.einsum("ij,ij->", a, a)), "E2": float(np.einsum("ij,ij->", b, b))}


def project_to_cylinders(points: np.ndarray, centres: np.ndarray, axes: np.ndarray, radius: np.ndarray,
                         height: np.ndarray) -> np.ndarray:
    """Exact Euclidean projection of every point onto its tolerance cylinder.

    The cylinder of point ``i`` is ``{c + a n + t : |a| <= h, t ⊥ n, |t| <= r}``;
    its projection clips the axial part to ``[−h, h]`` and the radial part to
    ``r`` independently (the set is a product in orthogonal coordinates).

    Parameters
    ----------
    points, centres, axes : (k, 3) float64
        ``axes`` are unit vectors.
    radius, height : (k,) float64
        Radius and half-height (``inf`` for no bound).

    Returns
    -------
    (k, 3) float64

    Examples
    --------
    >>> project_to_cylinders(np.array([[3.0, 0, 5]]), np.zeros((1, 3)), np.array([[0, 0, 1.0]]),
    ...                      np.array([1.0]), np.array([2.0])).tolist()
    [[1.0, 0.0, 2.0]]
    """
    d = points - centres
    a = np.einsum("ij,ij->i", d, axes)
    t = d - a[:, None] * axes
    tl = np.sqrt(np.einsum("ij,ij->i", t, t))
    s = np.divide(radius, tl, out=np.ones_like(tl), where=tl > radius)
    ac = np.clip(a, -height, height)
    inside = (tl <= radius) & (np.abs(a) <= height)  # returned exactly as given
    return np.where(inside[:, None], points, centres + ac[:, None] * axes + s[:, None] * t)


def _lengths(value: Any, n: int, unit: str, name: str) -> np.ndarray:
    """A cylinder size: None (unbounded), a number or a length text (one for all), or an (n,) array."""
    if value is None:
        return np.full(n, np.inf)
    if isinstance(value, (str, int, float)) and not isinstance(value, bool):
        from .units import parse_length

        v = parse_length(value, unit, name)
        if v < 0:
            raise InputError(f"{name}: must be >= 0, got {value!r}")
        return np.full(n, v)
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected a number, a length such as '2 mm' or {n} numbers, got {value!r}") from None
    if a.shape == ():
        a = np.full(n, float(a))  # a NumPy scalar
    if a.shape != (n,):
        raise InputError(f"{name}: expected one number or an array of shape ({n},), got shape {a.shape}")
    bad = np.flatnonzero(np.isnan(a) | (a < 0))
    if bad.size:
        raise InputError(f"{name}: must be >= 0 (inf for no bound), got {a[bad[0]]!r} at vertex {int(bad[0])}")
    return a


@dataclass(frozen=True)
class WebReport:
    """What :func:`fair_web` did.

    Energies are ``E2 + τ E1 + c Σ||p − p⁰||²`` as minimized (``energy_input`` at
    the input, ``energy_unconstrained`` at the unconstrained minimizer — None
    when that is not unique — and ``energy`` at the result), plus ``E1``/``E2`` of
    the result. ``n_on_cylinder``: free vertices on their cylinder's surface
    (active constraints); ``max_outside``: the largest distance of a vertex
    outside its cylinder (0 up to rounding). ``kkt_residual``: the KKT residual
    of the result in mean edge lengths h (how far one projected Jacobi step
    would move a vertex; 0 at the exact constrained minimizer, ``tolerance`` or
    less when ``converged``, which also needs the solver's estimate of the
    distance to the minimizer below ``tolerance``); ``projection_move``: how
    far (mesh unit) the final exact projection onto the cylinders moved any
    vertex of the solver's last iterate; ``warm_start_iterations``: the ADMM iterations before the Newton
    steps (``iterations``) of ``solver="newton"``; ``contact_vertices`` / ``contact_rounds``: the working set
    and rounds of the contact method (0 when the primal Newton method solved it; its ``iterations`` are then
    the dense Newton steps in the space of the contact forces, summed over the rounds); ``factorizations``:
    the sparse factorizations the primal Newton steps made (the other steps solved by conjugate gradients
    preconditioned by the last one; 0 on the other paths).
    """

    energy_kind: str
    tension: float
    closeness: float
    solver: str
    fix: str
    n_fixed: int
    n_free: int
    iterations: int
    converged: bool
    energy_input: float
    energy_unconstrained: float | None
    energy: float
    E1: float
    E2: float
    cylinders: bool
    n_on_cylinder: int
    max_outside: float
    seconds: float
    kkt_residual: float = 0.0
    projection_move: float = 0.0
    warm_start_iterations: int = 0
    contact_vertices: int = 0
    contact_rounds: int = 0
    factorizations: int = 0

    def to_dict(self) -> dict:
        """Plain-Python form (JSON-ready)."""
        return asdict(self)


def fair_web(
    mesh: QuadMesh,
    *,
    energy: Literal["E1", "E2", "tension"] = "E2",
    tension: float = 1.0,
    closeness: float = 0.0,
    cylinder_radius: Any = None,
    cylinder_height: Any = None,
    fix: Literal["none", "corners", "boundary"] = "boundary",
    fixed: ArrayLike | None = None,
    solver: Literal["newton", "admm", "projected_gradient"] = "newton",
    max_iterations: int = 5000,
    tolerance: float = 1e-5,
    rho: float | None = None,
) -> tuple[QuadMesh, WebReport]:
    """Minimize E1, E2 or Eτ of the structure-line network (thesis 3.1.1), optionally inside tolerance cylinders.

    Parameters
    ----------
    mesh : QuadMesh
    energy : {"E1", "E2", "tension"}
        ``E1`` (eq. 5, membrane), ``E2`` (eq. 6/11, the linearized bending energy
        the thesis's network energy eq. 11 uses) or ``Eτ = E2 + τ E1`` (eq. 7).
    tension : float
        ``τ >= 0`` for ``energy="tension"``.
    closeness : float
        ``c >= 0``: adds ``c Σ ||p − p⁰||²`` (0 as in eq. 11). Dimensionless like
        ``τ`` (both multiply squared lengths), so the result scales with the mesh.
    cylinder_radius, cylinder_height : number, length text, (n,) array or None
        Tolerance cylinders (hard constraints): radius across and half-height
        along the input's vertex normal (mean of the adjoining faces' normals),
        in the mesh's unit (text such as ``"20 mm"`` is converted). ``None`` (the
        default) leaves that direction unbounded; both None: no cylinders.
    fix : {"none", "corners", "boundary"}
        Vertices held in place (:func:`quadnodes.topology.fixed_vertices`); the
        default keeps the boundary, as fair webs constrained by their border.
    fixed : (n,) bool or int indices, optional
        More vertices to hold.
    solver : {"newton", "admm", "projected_gradient"}
        For the constrained problem (see the module docstring): ``"newton"``
        (the default) converged in every measured case (small to large
        cylinders, 100² and 300² grids): with few vertices touching by the
        contact method (300², bench cylinders: about 11 s of CPU), with many by 2-3 primal
        steps after an ADMM warm start, the first a sparse factorization of the free
        coordinates (up to 3n), the later ones mostly conjugate gradients preconditioned
        by it; the two
        first-order methods are cheap per step but need very many steps on
        large networks (E2's matrix has condition number ~ n⁴) and are for
        small ones.
    max_iterations : int
        Cap on Newton steps / ADMM / projected-gradient iterations (and on the
        contact method's rounds).
    tolerance : float
        Stop when the KKT residual is below ``tolerance`` mean edge lengths h
        (one projected Jacobi step ``x − Π(x − (Px − b) / max diag P)`` moves no
        vertex farther) and so is the estimated distance to the minimizer: the
        last Newton step; for ADMM and projected gradient the change over 10
        iterations extrapolated at its observed linear rate (ADMM also needs its
        primal residual ``|x − z|`` below it). The default 1e-5 h is 0.01 mm on
        a 1 m panel edge.
    rho : float, optional
        A fixed ADMM penalty (default: adaptive, see ``_admm``).

    Returns
    -------
    mesh : QuadMesh
    report : WebReport

    Raises
    ------
    InputError
        On a bad option; when the minimizer is not unique (no vertex of some part
        of the network is fixed, ``closeness`` is 0 and there are no cylinders).

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> z = np.zeros((5, 5)); z[2, 2] = 1.0
    >>> out, rep = fair_web(grid(5, 5, height=z), cylinder_height=0.5)
    >>> round(float(out.vertices[12, 2]), 3), rep.n_on_cylinder
    (0.5, 1)
    """
    t0 = time.perf_counter()
    _validate.quad_mesh(mesh)
    energy = _validate.choice(energy, ENERGIES, "energy")  # type: ignore[assignment]
    solver = _validate.choice(solver, _SOLVERS, "solver")  # type: ignore[assignment]
    fix = _validate.choice(fix, FIX_MODES, "fix")  # type: ignore[assignment]
    tau = _validate.nonnegative_number(tension, "tension")
    c = _validate.nonnegative_number(closeness, "closeness")
    max_iterations = _validate.positive_int(max_iterations, "max_iterations")
    tol = _validate.positive_number(tolerance, "tolerance")
    n = mesh.n_vertices
    hold = fixed_vertices(mesh, fix, fixed)
    radius = _lengths(cylinder_radius, n, mesh.unit, "cylinder_radius")
    height = _lengths(cylinder_height, n, mesh.unit, "cylinder_height")
    has_cyl = bool(np.isfinite(radius[~hold]).any() or np.isfinite(height[~hold]).any())
    x0 = mesh.vertices
    hlen = mesh.mean_edge_length
    D1, D2 = line_differences(mesh)
    Q = _quadratic(D1, D2, energy, tau)
    if c > 0:
        Q = (Q + c * sp.identity(n, format="csr")).tocsr()
    free = np.flatnonzero(~hold)

    def total(x: np.ndarray) -> float:
        # xᵀQx holds c·|x|²; completing the square gives c·|x − x⁰|²
        value = np.einsum("ij,ij->", x, Q @ x)
        if c > 0:
            value += c * (np.einsum("ij,ij->", x0, x0) - 2 * np.einsum("ij,ij->", x0, x))
        return float(value)

    e_in = total(x0)
    if free.size == 0:
        raise InputError(f"fix: every vertex is fixed (fix={fix!r}); nothing can move")
    P = Q[free][:, free].tocsc()
    b = c * x0[free] - Q[free][:, hold] @ x0[hold]
    # unique minimizer without cylinders? every part of the network needs an anchor
    unique = c > 0 or _anchored(Q, hold)
    if not unique and not has_cyl:
        raise InputError(
            "fix: some part of the structure-line network has no fixed vertex, so its energy has no unique "
            "minimum; fix vertices (fix='boundary' or 'corners', or fixed=...), give closeness > 0 or "
            "tolerance cylinders"
        )
    x_unc, lu_unc = None, None
    contacts, rounds, factorizations = 0, 0, 0
    iterations = 0
    converged = True
    # one nested-dissection order of the free vertices serves every factorization below (P, P + ρI, and the
    # Newton systems, whose unknowns are coordinates of these vertices); small systems use minimum degree
    nd = nested_dissection(P) if (3 if has_cyl else 1) * free.size >= NESTED_DISSECTION_MIN else None
    if unique:
        try:  # symmetric order, diagonal pivots preferred (fast); pivoting left on: a singular P raises
            lu_unc = factorize(P, kind="symmetric", what="fair_web", order=_order(nd, free.size))
            x_unc = lu_unc.solve(b)
            res = np.abs(P @ x_unc - b).max() / max(np.abs(b).max(), np.abs(P).max() * hlen, 1e-300)
        except InputError:  # singular, or a solution that is not finite
            x_unc, res = None, np.inf
        if x_unc is None or not np.isfinite(x_unc).all() or res > 1e-6:
            raise InputError("fix: the energy has no unique minimum with these fixed vertices (e.g. E2 with a "
                             "single fixed vertex per line); fix more vertices or give closeness > 0")
    cen, ax = x0[free], vertex_normals(x0, mesh.faces)[free]
    r_f, h_f = radius[free], height[free]
    x_free = x_unc
    kkt, moved, warm, ran = 0.0, 0.0, 0, False
    if has_cyl:
        inside = x_unc is not None and np.array_equal(project_to_cylinders(x_unc, cen, ax, r_f, h_f), x_unc)
        if not inside:
            start = cen if x_unc is None else project_to_cylinders(x_unc, cen, ax, r_f, h_f)
            ran = True
            with blas_pinned():  # one BLAS thread: SuperLU's small dense blocks gain nothing from more
                found = None
                if solver == "newton" and lu_unc is not None:
                    found = _contacts(lu_unc, P, b, x_unc, cen, ax, r_f, h_f, tol * hlen, max_iterations)
                if found is not None:
                    x_it, iterations, converged, kkt, contacts, rounds = found
                else:
                    x_it, iterations, converged, kkt, warm, factorizations = _constrained(
                        solver, P, b, start, cen, ax, r_f, h_f, tol * hlen, max_iterations, rho, nd)
            # never a point outside a cylinder: the exact projection last (a no-op on the solvers' iterates,
            # which are projections already; reported)
            x_free = project_to_cylinders(x_it, cen, ax, r_f, h_f)
            moved = float(np.sqrt(np.einsum("ij,ij->i", x_free - x_it, x_free - x_it)).max())
    x = x0.copy()
    x[free] = x_free
    out = mesh.with_vertices(x)
    e_unc = None
    if x_unc is not None:
        xu = x0.copy()
        xu[free] = x_unc
        e_unc = total(xu)
    we = web_energy(mesh, vertices=x)
    on = 0
    outside = 0.0
    if has_cyl:
        proj = project_to_cylinders(x_free, cen, ax, r_f, h_f)
        outside = float(np.linalg.norm(x_free - proj, axis=1).max())
        d = x_free - cen
        a = np.abs(np.einsum("ij,ij->i", d, ax))
        rad = np.linalg.norm(d - np.einsum("ij,ij->i", d, ax)[:, None] * ax, axis=1)
        eps = 1e-9 * hlen
        on = int(((a >= h_f - eps) | (rad >= r_f - eps)).sum())
    report_progress(1.0, f"fair web: {iterations} iterations")
    rep = WebReport(energy, tau, c, solver if ran else "direct", fix, int(hold.sum()),
                    int(free.size), iterations, bool(converged), e_in, e_unc, total(x), we["E1"], we["E2"],
                    has_cyl, on, outside, time.perf_counter() - t0, kkt / hlen, moved,
                    warm, contacts, rounds, factorizations)
    return out, rep


def _constrained(solver: str, P: sp.csc_matrix, b: np.ndarray, start: np.ndarray, cen: np.ndarray,
                 ax: np.ndarray, r: np.ndarray, h: np.ndarray, tol: float, max_it: int, rho: float | None,
                 nd: np.ndarray | None) -> tuple[np.ndarray, int, bool, float, int, int]:
    """Run one constrained solver: (point, iterations, converged, KKT residual, warm-start iterations,
    Newton factorizations).

    ``nd``: a nested-dissection order of the free vertices (None: minimum degree everywhere).
    """
    if solver == "newton":
        return _newton(P, b, start, cen, ax, r, h, tol, max_it, nd)
    if solver == "admm":
        return (*_admm(P, b, start, cen, ax, r, h, tol, max_it, rho, nd), 0, 0)
    return (*_fista(P, b, start, cen, ax, r, h, tol, max_it), 0, 0)


def _order(nd: np.ndarray | None, size: int, group: np.ndarray | None = None, coupled: float = 1.0
           ) -> np.ndarray | str:
    """The order to factorize a system of ``size`` unknowns in: the vertices' nested dissection (each
    vertex's unknowns together, ``group`` the vertex of every unknown) when it is large, else minimum degree.

    A Newton system whose vertices are mostly free of active constraints (``coupled``, the fraction with
    one, below ½) is three copies of the vertex system (x, y, z) joined at a few vertices: minimum degree
    keeps the copies apart, a vertex order joins them in every separator above a coupled vertex (at 100²
    with 1 % coupled: 2.3 M factor entries against 4.8 M, 0.8 s against 1.4 s of CPU).
    """
    if nd is None or size < NESTED_DISSECTION_MIN or coupled < 0.5:
        return "minimum_degree"
    return nd if group is None else expand_order(nd, group)


def _anchored(Q: sp.csr_matrix, hold: np.ndarray) -> bool:
    """Whether every connected part of the network holds at least one fixed vertex."""
    ncomp, label = connected_components(Q, directed=False)
    has = np.zeros(ncomp, dtype=bool)
    has[label[hold]] = True
    return bool(has.all())


def _natural_residual(x: np.ndarray, P: sp.csr_matrix, b: np.ndarray, gamma: float, cen: np.ndarray,
                      ax: np.ndarray, r: np.ndarray, h: np.ndarray) -> float:
    """KKT residual ``max |x − Π(x − γ(Px − b))|`` of a point (0 exactly at the constrained minimizer).

    The natural residual of the variational inequality: how far one projected
    gradient step with step ``γ = 1 / max diag(P)`` (a Jacobi step) moves any
    vertex. It is zero exactly when ``x`` satisfies the KKT conditions.
    """
    return float(np.abs(x - project_to_cylinders(x - gamma * (P @ x - b), cen, ax, r, h)).max())


def _distance_estimate(change: float, previous: float) -> float:
    """Distance to the limit of a linearly converging sequence: ``c q / (1 − q)``, ``q`` the ratio of its last two
    changes ``c`` (taken 10 iterations apart); ``inf`` while the changes do not shrink.

    The KKT residual alone understates the distance on badly conditioned problems (a Jacobi step barely moves
    the smooth modes: ADMM at 100² stood 0.34 h from the minimizer with a KKT residual of 1.4e-5 h), so the
    first-order methods also need this estimate below the tolerance.
    """
    q = change / previous if previous > 0 else (0.0 if change == 0 else 1.0)
    return change * q / (1.0 - q) if q < 1.0 else np.inf


def _admm(P: sp.csc_matrix, b: np.ndarray, start: np.ndarray, cen: np.ndarray, ax: np.ndarray, r: np.ndarray,
          h: np.ndarray, tol: float, max_it: int, rho: float | None, nd: np.ndarray | None = None, *,
          progress: bool = True) -> tuple[np.ndarray, int, bool, float]:
    """min ½xᵀPx − bᵀx s.t. x in the cylinders: x-step (P + ρI)x = b + ρ(z − u), z-step a projection.

    Over-relaxed (α = 1.6). Every 10 iterations: stop when the primal residual
    ``|x − z|``, the KKT residual of ``z`` (:func:`_natural_residual`) and the
    distance estimate (:func:`_distance_estimate`) are below ``tol``; without a
    given ``rho`` rebalance it OSQP-style, ``ρ ← ρ √(primal / dual)`` (relative
    residuals) when that changes ρ more than 5× (at most 12 refactorizations of
    ``P + ρI``). Returns the last ``z`` (inside every cylinder), the iterations,
    whether it converged, the KKT residual.
    """
    k = P.shape[0]
    Pr = P.tocsr()
    gamma = 1.0 / float(P.diagonal().max())
    adaptive = rho is None
    rho_ = float(P.diagonal().mean()) / 60.0 if adaptive else _validate.positive_number(rho, "rho")
    eye = sp.identity(k, format="csc")

    def factor(value: float) -> Any:
        return factorize((P + value * eye).tocsc(), kind="spd", what="fair_web (ADMM step)", order=_order(nd, k))

    lu = factor(rho_)
    changes = 0
    z = start.copy()
    u = np.zeros_like(z)
    kkt = np.inf
    z_check, moved = z.copy(), 0.0
    for it in range(1, max_it + 1):
        x = lu.solve(b + rho_ * (z - u))
        xr = _RELAX * x + (1.0 - _RELAX) * z  # over-relaxation (Boyd et al. §3.4.3)
        z = project_to_cylinders(xr + u, cen, ax, r, h)
        u += xr - z
        if it % 10 and it != max_it:
            continue
        primal = float(np.abs(x - z).max())
        kkt = _natural_residual(z, Pr, b, gamma, cen, ax, r, h)
        moved, before = float(np.abs(z - z_check).max()), moved
        z_check = z.copy()
        if primal < tol and kkt < tol and _distance_estimate(moved, before) < tol:
            return z, it, True, kkt
        if adaptive and changes < 12:
            grad = Pr @ x - b
            y = rho_ * u
            dual = np.abs(grad + y).max() / max(np.abs(Pr @ x).max(), np.abs(y).max(), np.abs(b).max(), 1e-300)
            prim = primal / max(np.abs(x).max(), np.abs(z).max(), 1e-300)
            scale = float(np.sqrt(prim / max(dual, 1e-300)))
            if scale > 5.0 or scale < 0.2:
                rho_ *= scale
                u /= scale  # the scaled dual variable follows ρ
                lu = factor(rho_)
                changes += 1
        if progress and it % 50 == 0:
            report_progress(it / max_it, f"ADMM iteration {it}: KKT residual {kkt:.2e}")
    return z, max_it, False, kkt


def _active_set(d: np.ndarray, g: np.ndarray, ax: np.ndarray, r: np.ndarray,
                h: np.ndarray) -> tuple[np.ndarray, ...]:
    """The active constraints read from ``d = w − c`` (``w = x − γ∇E``), as both Newton methods read them.

    Returns the normal coordinate ``a`` (k,), the active slabs ``|a| ≥ h`` and disks (tangential part
    at least ``r``) (k,) bool, the radial and circumferential directions ``er``, ``ec`` (k, 3), and the
    disks' multipliers ``μ = max(0, −e_r·g)`` (0 where the disk is not active).
    """
    a = np.einsum("ij,ij->i", d, ax)
    t = d - a[:, None] * ax
    tl = np.sqrt(np.einsum("ij,ij->i", t, t))
    slab = np.abs(a) >= h
    disk = tl >= r
    er, ec = _frames(ax, t)
    mu = np.where(disk, np.maximum(0.0, -np.einsum("ij,ij->i", g, er)), 0.0)
    return a, slab, disk, er, ec, mu


def _frames(ax: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit radial ``e_r`` (along ``t``, any tangent when ``t = 0``) and circumferential ``e_c = n × e_r``."""
    tl = np.sqrt(np.einsum("ij,ij->i", t, t))
    alt = np.where(np.abs(ax[:, [0]]) < 0.9, np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
    alt = alt - np.einsum("ij,ij->i", alt, ax)[:, None] * ax
    alt /= np.sqrt(np.einsum("ij,ij->i", alt, alt))[:, None]
    er = np.where((tl > 0)[:, None], t / np.where(tl > 0, tl, 1.0)[:, None], alt)
    return er, np.cross(ax, er)


def _newton(P: sp.csc_matrix, b: np.ndarray, start: np.ndarray, cen: np.ndarray, ax: np.ndarray, r: np.ndarray,
            h: np.ndarray, tol: float, max_it: int, nd: np.ndarray | None = None
            ) -> tuple[np.ndarray, int, bool, float, int, int]:
    """Semismooth Newton (primal-dual active set) on the KKT conditions, warm-started by ADMM.

    The KKT conditions are ``F(x) = x − Π(x − γ(Px − b)) = 0`` (γ = 1 / max diag P).
    Each step takes the active set from ``w = x − γ(Px − b)``: a vertex's slab is
    active when ``|n·(w − c)| >= h`` (its normal coordinate is then held at ±h),
    its disk when the tangential part of ``w − c`` is longer than ``r`` (its
    radial coordinate is held at ``r`` along that direction, the disk's tangent
    line, and the Lagrangian's curvature ``μ/r`` with ``μ = −e_r·∇`` is added
    across). The rest is one sparse symmetric positive definite solve for all
    free coordinates (the x, y, z of a vertex couple through its frame), so the
    smooth, badly conditioned modes of E2 are solved exactly — which first-order
    methods cannot do. A factorization is reused by the next steps while it
    preconditions their systems well (:class:`_StepSolver`: the late steps,
    which switch few constraints, cost a few solves instead of a factorization).
    Up to 200 ADMM iterations first give the active set a good start.
    Converged: the KKT residual and the last step (which bounds the distance to
    the minimizer once the convergence is superlinear) are below ``tol``.
    Returns the projected result, Newton steps, converged, KKT residual, the
    ADMM warm-start iterations and the sparse factorizations.
    """
    k = P.shape[0]
    Pr = P.tocsr()
    dmax = float(P.diagonal().max())
    gamma = 1.0 / dmax
    x, warm, done, kkt = _admm(P, b, start, cen, ax, r, h, tol, _WARM, None, nd, progress=False)
    if done:
        return x, 0, True, kkt, warm, 0
    P3 = sp.kron(Pr, sp.identity(3), format="csr")
    delta = 1e-12 * dmax  # a proximal term δ|x − x_k|²: keeps the step definite where the energy is flat
    best, best_kkt = x, kkt
    z_last = x
    blk = 3 * np.arange(k)
    ii = (blk[:, None, None] + np.arange(3)[None, :, None] + np.zeros(3, dtype=np.int64)).ravel()
    jj = (blk[:, None, None] + np.zeros(3, dtype=np.int64)[:, None] + np.arange(3)[None, None, :]).ravel()
    steps = _StepSolver(nd, 1e-3 * tol)
    for it in range(1, max_it + 1):
        g = Pr @ x - b
        a, slab, disk, er, ec, mu = _active_set(x - gamma * g - cen, g, ax, r, h)
        pin = disk & (r == 0)  # a zero radius holds the circumferential direction too (no curvature term)
        curv = np.where(disk & ~pin, mu / np.where(disk & ~pin, r, 1.0), 0.0)
        # free directions of every vertex: the normal (slab inactive), the radial (disk inactive), the circumferential
        use = np.column_stack([~slab, ~disk, ~pin])
        vi, di = np.nonzero(use)
        # a vertex with no active constraint keeps x, y, z: its coordinates then couple only through P, which
        # keeps the factorization near that of three separate systems when few constraints are active
        dirs = np.where((slab | disk)[:, None, None], np.stack([ax, er, ec], axis=1), np.eye(3))
        Z = sp.csr_matrix((dirs[vi, di].ravel(), ((3 * vi[:, None] + np.arange(3)).ravel(),
                                                  np.repeat(np.arange(vi.size), 3))), shape=(3 * k, vi.size))
        H = sp.csr_matrix((np.einsum("i,ij,ik->ijk", curv, ec, ec).ravel(), (ii, jj)), shape=(3 * k, 3 * k))
        held = cen + np.where(slab, np.sign(a) * h, 0.0)[:, None] * ax + np.where(disk, r, 0.0)[:, None] * er
        A = (Z.T @ (P3 + H) @ Z).tocsc() + delta * sp.identity(vi.size, format="csc")
        A.eliminate_zeros()
        rhs = Z.T @ (b.ravel() - P3 @ held.ravel() + delta * (x - held).ravel())
        y = steps.solve(A, rhs, 3 * vi + di, vi, float((slab | disk).mean()), Z.T @ (x - held).ravel())
        x = held + (Z @ y).reshape(k, 3)  # the next active set is read from this point, not its projection
        z = project_to_cylinders(x, cen, ax, r, h)
        step, z_last = float(np.abs(z - z_last).max()), z
        kkt = _natural_residual(z, Pr, b, gamma, cen, ax, r, h)
        if kkt < best_kkt:
            best, best_kkt = z, kkt
        report_progress(min(it / 30, 0.99), f"Newton step {it}: KKT residual {kkt:.2e}, "
                                            f"{int(slab.sum())} slabs and {int(disk.sum())} disks active")
        if kkt < tol and step < tol:  # Newton converges superlinearly: its last step bounds the distance
            return z, it, True, kkt, warm, steps.factorizations
    return best, max_it, False, best_kkt, warm, steps.factorizations


#: Conjugate-gradient iterations a primal Newton step may take, preconditioned by an earlier step's factorization,
#: before it factorizes its own system instead.
_REUSE_CG = 40
#: ... and gives up after this many when the error estimate has neither fallen tenfold nor come within 100 × the
#: accuracy asked for (300², mixed cylinders: from 1.5e-6 to 2.7e-8 in 10 iterations, to the accuracy in 26 —
#: 6 s of CPU, against 13–17 s for the factorization).
_REUSE_CHECK = 10
#: ... and is not tried when more unknowns than this switched (a held coordinate freed or a free one held) since
#: that factorization: each one is a rank-one change, about one CG iteration more (300², small cylinders: with
#: 46 switched slabs CG was still above the accuracy after 40 iterations, 7 s; mixed: 12 switched, 26 iterations).
_REUSE_SWITCHES = 16


class _StepSolver:
    """The sparse solves of the primal Newton steps: a factorization is reused while it preconditions well.

    Late Newton steps change the system little (a few slabs switch, the active disks' frames turn by the
    last step's angle), so conjugate gradients preconditioned by the last factorization solve them in a
    few iterations — each one a solve with that factorization — instead of a new factorization (at 300² a
    2n system: about 8 s of CPU with SuperLU). The unknowns are matched by their key ``3 × vertex +
    direction`` (normal, radial, circumferential; x, y, z for a vertex without an active constraint); an
    unknown the factorized system lacks is preconditioned by its diagonal, and more than
    :data:`_REUSE_SWITCHES` of them (or of its unknowns the new system lacks) make it factorize at once.
    CG stops when the preconditioned residual, which estimates the error of every coordinate, is below
    ``accuracy`` (a length; the caller passes a thousandth of the tolerance, so the Newton step is exact
    to that), and gives up — factorizing the step's own system — after :data:`_REUSE_CG` iterations, or
    after :data:`_REUSE_CHECK` when that estimate has neither fallen tenfold nor come within 100 ×
    ``accuracy``. CG starts from the current iterate's coordinates, which late steps change little.
    """

    def __init__(self, nd: np.ndarray | None, accuracy: float) -> None:
        self.nd, self.accuracy = nd, accuracy
        self.factor: Any = None
        self.keys = np.zeros(0, dtype=np.int64)
        self.factorizations = 0
        self.cg_iterations = 0

    def solve(self, A: sp.csc_matrix, rhs: np.ndarray, keys: np.ndarray, group: np.ndarray,
              coupled: float, guess: np.ndarray) -> np.ndarray:
        """``A⁻¹ rhs`` for a Newton system whose unknowns have the (sorted) ``keys``; ``group``: their vertices;
        ``guess``: where CG starts (the current iterate's coordinates: late steps move little)."""
        if self.factor is not None:
            y = self._pcg(A, rhs, keys, guess)
            if y is not None:
                return y
            self.factor = None  # never two factorizations held at once
        order = _order(self.nd, A.shape[0], group, coupled)
        self.factor = factorize(A, kind="spd", what="fair_web (Newton step)", order=order)
        self.keys = keys
        self.factorizations += 1
        return self.factor.solve(rhs)

    def _pcg(self, A: sp.csc_matrix, rhs: np.ndarray, keys: np.ndarray, guess: np.ndarray) -> np.ndarray | None:
        m0 = self.keys.size
        pos = np.minimum(np.searchsorted(self.keys, keys), m0 - 1)
        common = self.keys[pos] == keys
        if m0 + keys.size - 2 * int(common.sum()) > _REUSE_SWITCHES:
            return None  # CG needs about one iteration more per switched unknown: a factorization is cheaper
        at = pos[common]
        diag = A.diagonal()

        def precondition(res: np.ndarray) -> np.ndarray:
            t = np.zeros(m0)
            t[at] = res[common]
            out = res / diag
            out[common] = self.factor.solve(t)[at]
            return out

        Ar = A.tocsr()
        y = guess.copy()
        res = rhs - Ar @ y
        z = precondition(res)
        first = float(np.abs(z).max())
        if first < self.accuracy:
            return y + z
        p, rz = z.copy(), float(res @ z)
        for i in range(1, _REUSE_CG + 1):
            q = Ar @ p
            pq = float(p @ q)
            if not pq > 0:
                return None
            alpha = rz / pq
            y += alpha * p
            res -= alpha * q
            z = precondition(res)
            self.cg_iterations += 1
            err = float(np.abs(z).max())
            if err < self.accuracy:
                return y
            if i == _REUSE_CHECK and err > max(0.1 * first, 100 * self.accuracy):
                return None  # too slow: the system has changed too much since the factorization
            rz_new = float(res @ z)
            p = z + (rz_new / rz) * p
            rz = rz_new
        return None


def _fista(P: sp.csc_matrix, b: np.ndarray, start: np.ndarray, cen: np.ndarray, ax: np.ndarray, r: np.ndarray,
           h: np.ndarray, tol: float, max_it: int) -> tuple[np.ndarray, int, bool, float]:
    """Accelerated projected gradient on ½xᵀPx − bᵀx, step 1/L, L >= λmax(P) (Gershgorin).

    Stops when the KKT residual (:func:`_natural_residual`, checked every 10 steps) and the distance estimate
    (:func:`_distance_estimate`) are below ``tol``.
    """
    P = P.tocsr()
    gamma = 1.0 / float(P.diagonal().max())
    lip = float(np.abs(P).sum(axis=1).max())  # Gershgorin bound on λmax
    x = start.copy()
    y = x.copy()
    t = 1.0
    kkt = np.inf
    x_check, moved = x.copy(), 0.0
    for it in range(1, max_it + 1):
        x_new = project_to_cylinders(y - (1.0 / lip) * (P @ y - b), cen, ax, r, h)
        t_new = 0.5 * (1 + np.sqrt(1 + 4 * t * t))
        y = x_new + ((t - 1) / t_new) * (x_new - x)
        x, t = x_new, t_new
        if it % 10 == 0 or it == max_it:
            kkt = _natural_residual(x, P, b, gamma, cen, ax, r, h)
            moved, before = float(np.abs(x - x_check).max()), moved
            x_check = x.copy()
            if kkt < tol and _distance_estimate(moved, before) < tol:
                return x, it, True, kkt
        if it % 200 == 0:
            report_progress(it / max_it, f"projected gradient iteration {it}: KKT residual {kkt:.2e}")
    return x, max_it, False, kkt


#: The contact method gives way to the primal Newton method when its working set would pass this many vertices
#: (its dense matrices are that size squared: 3,000 vertices are 72 MB) or this fraction of the free vertices.
_CONTACT_MAX = 3000
_CONTACT_FRACTION = 0.25
#: Rounds of the contact method (each adds vertices to the working set) before it gives way.
_CONTACT_ROUNDS = 60
#: Newton steps within one round of the contact method before it gives way.
_CONTACT_STEPS = 60
#: A round adds only vertices at least this share as far outside as the farthest (the others usually come
#: inside once those touch).
_CONTACT_SHARE = 0.1
#: ... and are the farthest outside within this many steps in the energy's graph (a supported plate touches at
#: separated points; at 100² bench cylinders 1, 2 and 4 steps gave working sets of 476, 248 and 185 vertices for
#: the 152 that end touching).
_CONTACT_HOPS = 4
#: The method gives way when the number of vertices outside their cylinder has fallen by less than 10 % over two
#: rounds (from round 5, while it exceeds the working set): every vertex will touch, the primal method's case.
_CONTACT_STALL = 0.9


def _contact_step(G: np.ndarray, u: np.ndarray, y: np.ndarray, g: np.ndarray, cen: np.ndarray, ax: np.ndarray,
                  r: np.ndarray, h: np.ndarray, gamma: float) -> tuple[np.ndarray, int, int]:
    """One semismooth Newton step of the contact method, in the space of the contact forces.

    On the working set ``S`` the energy's minimizer under forces ``F`` at ``S`` is ``y = u − G F``
    (``G = P⁻¹[S, S]``, ``u`` the unconstrained minimizer there). The active set is read from
    ``w = y − γ g`` exactly as in :func:`_newton`; every active constraint is a row ``c·y = d`` (slab:
    the normal, disk: the radial direction) and every active disk adds the Lagrangian's curvature
    ``κ = μ/r`` across (a row ``e_c·(y − c) = s/κ``). With ``B`` those directions the forces ``F = B φ``
    solve ``(Bᵀ G B + diag(0, 1/κ)) φ = Bᵀ u − d``: one dense SPD system of the active constraints'
    size — the primal Newton step of :func:`_newton` restricted to ``S``, without its 3n factorization.
    Returns the forces ``F`` (|S|, 3) (the gradient of the energy on ``S`` is ``−F``) and the numbers of
    active slabs and disks.
    """
    a, slab, disk, er, ec, mu = _active_set(y - gamma * g - cen, g, ax, r, h)
    vs, vd = np.flatnonzero(slab), np.flatnonzero(disk)
    vk = np.flatnonzero(disk & ((mu > 0) | (r == 0)))  # r = 0: the circumferential direction is held too
    vert = np.concatenate([vs, vd, vk])
    vec = np.concatenate([ax[vs], er[vd], ec[vk]])
    rel = u[vert] - cen[vert]
    bound = np.concatenate([np.sign(a[vs]) * h[vs], r[vd], np.zeros(vk.size)])
    rhs = np.einsum("ij,ij->i", vec, rel) - bound
    F = np.zeros_like(y)
    if vert.size:
        K = G[np.ix_(vert, vert)] * (vec @ vec.T)
        K[np.arange(vs.size + vd.size, vert.size), np.arange(vs.size + vd.size, vert.size)] += (
            r[vk] / np.where(mu[vk] > 0, mu[vk], 1.0))
        phi = sla.cho_solve(sla.cho_factor(K, lower=True, check_finite=False), rhs, check_finite=False)
        np.add.at(F, vert, phi[:, None] * vec)
    return F, int(slab.sum()), int(disk.sum())


def _contacts(lu: Any, P: sp.csc_matrix, b: np.ndarray, x_unc: np.ndarray, cen: np.ndarray, ax: np.ndarray,
              r: np.ndarray, h: np.ndarray, tol: float, max_it: int
              ) -> tuple[np.ndarray, int, bool, float, int, int] | None:
    """The constrained minimizer from the unconstrained one, by adding contact vertices (a range-space method).

    The minimizer is ``x = x_unc − P⁻¹F`` with the cylinders' forces ``F`` nonzero only where a vertex
    touches its cylinder. Starting from ``x_unc`` (factorization ``lu`` of ``P``, already made), every round
    adds to the working set ``S`` the vertices outside their cylinder whose distance outside is largest
    within ``_CONTACT_HOPS`` steps in ``P``'s graph (and at least ``_CONTACT_SHARE`` of the farthest), extends
    ``P⁻¹[S][:, S]`` by them (:class:`~quadnodes.linalg.inverse.InverseBlock`: sparse sweeps, no whole columns),
    and solves the problem restricted to ``S`` — forces only on ``S``, every vertex of ``S`` inside its
    cylinder — by the semismooth Newton steps of :func:`_contact_step` (dense, the size of the active
    constraints). Then ``x`` follows from one solve with three right-hand sides. It stops when no vertex
    is outside its cylinder, the KKT residual of the whole problem at the projected point and the change
    the last Newton step made to any vertex are below ``tol``: the rule of :func:`_newton`. Where many
    vertices touch (small cylinders) the working set grows past ``_CONTACT_MAX`` / ``_CONTACT_FRACTION``
    and it returns None: the primal method (:func:`_newton`, one sparse factorization per step) is then
    the cheaper one.

    Returns ``(x, Newton steps, converged, KKT residual, |S|, rounds)`` or None.
    """
    k = P.shape[0]
    Pr = P.tocsr()
    gamma = 1.0 / float(P.diagonal().max())
    cap = min(_CONTACT_MAX, max(16, int(_CONTACT_FRACTION * k)))
    ptr, nbr = Pr.indptr, Pr.indices
    S = np.zeros(0, dtype=np.int64)
    inverse = InverseBlock(lu)  # P⁻¹[S][:, S], grown with S
    F = np.zeros((0, 3))
    x = x_unc
    steps = 0
    outside: list[int] = []
    for rnd in range(1, min(_CONTACT_ROUNDS, max_it) + 1):
        out = np.sqrt(np.einsum("ij,ij->i", x - project_to_cylinders(x, cen, ax, r, h),
                                x - project_to_cylinders(x, cen, ax, r, h)))
        out[S] = 0.0
        # the vertices farthest outside among their neighbours: a supported plate touches at separated points
        near = out
        for _ in range(_CONTACT_HOPS):
            near = np.maximum.reduceat(near[nbr], ptr[:-1]) if nbr.size else near
        new = np.flatnonzero((out > max(0.1 * tol, _CONTACT_SHARE * out.max())) & (out >= near))
        if new.size == 0:
            if rnd == 1:
                return None  # nothing outside: the caller has returned x_unc already
            break
        outside.append(int((out > tol).sum()))
        # many vertices touch (small cylinders): the vertices outside stop falling while the working set grows
        stalled = rnd >= 5 and outside[-1] >= _CONTACT_STALL * outside[-3] and outside[-1] > S.size
        if S.size + new.size > cap or stalled:
            return None
        inverse.extend(new)
        S = inverse.index
        G = 0.5 * (inverse.block + inverse.block.T)
        F = np.concatenate([F, np.zeros((new.size, 3))])
        u, cS, aS, rS, hS = x_unc[S], cen[S], ax[S], r[S], h[S]
        y = u - G @ F
        g = -F
        z_last = project_to_cylinders(y, cS, aS, rS, hS)
        for _ in range(_CONTACT_STEPS):
            F_prev = F
            try:
                F, n_slab, n_disk = _contact_step(G, u, y, g, cS, aS, rS, hS, gamma)
            except (np.linalg.LinAlgError, ValueError):
                return None
            y, g = u - G @ F, -F
            steps += 1
            z = project_to_cylinders(y, cS, aS, rS, hS)
            step, z_last = float(np.abs(z - z_last).max()), z
            res = float(np.abs(y - project_to_cylinders(y - gamma * g, cS, aS, rS, hS)).max())
            report_progress(min(steps / 30, 0.99), f"contact round {rnd}, Newton step {steps}: "
                                                   f"{S.size} contact vertices, {n_slab} slabs and {n_disk} disks "
                                                   f"active, residual {res:.2e}")
            if res < 0.1 * tol and step < 0.1 * tol:
                break
        else:
            return None
        Fs = np.zeros_like(x_unc)
        Fs[S] = F
        x = x_unc - lu.solve(Fs)
    else:
        return None
    z = project_to_cylinders(x, cen, ax, r, h)
    kkt = _natural_residual(z, Pr, b, gamma, cen, ax, r, h)
    # the distance estimate of the Newton rule: how far the last step moved any vertex (not only those of S)
    dF = np.zeros_like(x_unc)
    dF[S] = F - F_prev
    last = float(np.abs(lu.solve(dF)).max())
    if not (kkt < tol and last < tol):
        return None
    return z, steps, True, kkt, int(S.size), rnd
