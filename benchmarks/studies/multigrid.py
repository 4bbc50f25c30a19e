"""Geometric multigrid for the fairing system: steps that do not grow as the weight falls, and what a step costs.

Backs docs/fairing.md "Multigrid: steps that do not depend on the weight, at a price that does not pay" (issue 15,
part 2: a preconditioner whose steps do not depend on the weight; not in the solver, and why), with ``--solver`` the tables of "The two-grid
path" and, with ``--free fair`` and the ``spectral`` column, of "Exact lines: steps that do not depend on the
weight".

On the bench_core sheet (``benchmarks/_common.py``) with every window-middle vertex free, builds fair()'s
one-iteration normal matrix ``M = AᵀA + ωI`` in the grid's numbering (fixed vertices as identity rows; fair's
default ``line_spacing="fair"``) and solves ``M X = B`` for a seeded right-hand side of x, y and z together to
rtol 1e-9 with conjugate gradients preconditioned by:

- ``none``: plain CG;
- ``SGS``: one symmetric Gauss–Seidel sweep over all rows (what fair's Gauss–Seidel path does on one thread);
- ``MG linear`` / ``MG cubic``: a multigrid V(1,1) cycle, symmetric Gauss–Seidel smoothing (forward before,
  backward after), vertex-centred coarsening by 2 in both directions down to at most 400 vertices (solved
  directly), Galerkin coarse matrices ``PᵀMP``, and a prolongation ``P`` that interpolates along the grid's
  rows and columns with Lagrange polynomials of degree 1 or 3 (``P`` zero at fixed vertices);
- ``MG cubic, K-cycle``: the same levels, each coarse level but the coarsest solved by two steps of flexible CG
  preconditioned by the next level (Notay and Vassilevski's K-cycle; the outer CG flexible too);
- ``two-grid cubic``: the cubic cycle with one coarse level solved exactly (the bound any deeper cycle
  approaches).

The fairing energy of a line does not see a motion that is quadratic along it, so at a small ω the slow
modes are global biquadratics that only ω holds; cubic interpolation carries them to the coarse grid
exactly, linear interpolation does not.

Prints, per weight, each preconditioner's steps, its work per step and in all (the matrix nonzeros read,
counted in products with the fine ``M``: a CG product 1, a sweep over a level its nonzeros (a first sweep
from zero and the product after it half each), a transfer the nonzeros of ``P``, the coarse solve those of
its factors; Gauss–Seidel in Eisenstat's form, as fair runs it, reads each triangle once per step: 1), and
the operator complexity (all levels' nonzeros over the fine matrix's). Wall times of this NumPy/SciPy
prototype are printed too, one thread, but say less than the work: the multigrid's transfers and coarse
products are SciPy's, the sweeps small Numba loops.

``--solver`` measures the solver's own paths instead (``docs/fairing.md``, "The two-grid path"): fair()'s
first-iteration system (``FairingSystem``, all window middles free, ``line_spacing="fair"``, anchor = the noisy
vertices, the compiled kernels loaded before the clock), solved by symmetric Gauss–Seidel (``preconditioner=
"gauss-seidel"``, its stop tightened at tiny weights) and by :class:`quadnodes.linalg.multigrid.TwoGrid`
(``"two-grid"``, at each ``--strides``) and by ``"auto"`` (Gauss–Seidel, switching to the two-grid cycle where it is
slow), each against the direct solve (``--size`` ≤ 450; above, the two-grid cycle to rtol 1e-12): steps, seconds
(set-up and solve, one run), and the largest difference over the sheet's extent. The unknowns are every window
middle (``--free detect``) or as fair() frees them (``--free fair``: ``line_gaps``, fewer fixed vertices, so the
spectral column's correction takes them; its column: ``"spectral"``). ``--fixed`` also fixes a share
of the vertices at random (as a zigzag detection leaves some fixed), one block of rows each; ``--no-guard`` turns
fair's error guard at tiny weights off (``ERROR_GUARD_CONTRAST = inf``: the residual stop alone). ``--mesh cylinder``
(``--size`` rows of ``--size`` vertices around, radius 1, height 2) and ``--mesh torus`` (``--size`` × ``--size``)
take the closed grids' path instead (compressed-row sweeps; the coarse lines closed around), with broadband
noise of 0.2 edge lengths; ``--mesh cube-sphere`` (six ``--size`` × ``--size`` faces, eight valence-3 corners,
the same noise) is no grid: its two-grid cycle is :class:`quadnodes.linalg.multigrid.LineTwoGrid`, on coarse nodes
along the structure lines. The column "two-grid, structure lines" runs that cycle on every mesh (on a grid,
``FairingSystem`` without the grid's topology, as for a mesh that is none), every ``TWO_GRID_LINE_STRIDE``-th
line as the solver keeps them (every 4th above ``TWO_GRID_LINE_STRIDE_MAX`` unknowns); on the cube-sphere
``--strides`` add columns with that many side-by-side steps between kept lines (``line_interpolation``'s
``stride``). ``--mesh real`` prints instead a table of
the tests' meshes that are no grid (``tests/data`` and ``tests/meshes.py``; jitter noise of 0.2 edge lengths,
boundary free and held): Gauss–Seidel against that cycle.
``--coarse-factor`` prints instead the two-grid coarse matrix of the ``--size`` sheet at each weight, factorized by
SuperLU in minimum degree order (the solver's) and in nested dissection order (``factorize``'s default from 20,000
unknowns on), and by CHOLMOD in its AMD order where scikit-sparse is installed (the ``bench`` extra; the solver's
choice then): factor entries, set-up seconds (with the ordering) and a solve of three coordinates.
``--mesh random`` (``--size`` seeded random points triangulated and split four times: extraordinary vertices
every 8 edges, the same noise) is no grid either, with its lines far more tangled than the cube-sphere's and
long, thin faces where the triangles were slivers. ``--stretch S`` scales the mesh's z by ``S`` (a cube-sphere's
faces long and thin on four sides); ``--line-step on``/``off`` forces the structure lines' cycle's line step
(``LineTwoGrid(lines=)``) or leaves it out, where ``auto`` lets the solver choose (``fairing.LINE_SMOOTHING_SHARE``);
on a mesh that is no grid the table's head gives the share of unknowns that choice counts.
``--columns`` picks the columns (``gauss-seidel``, ``two-grid``, ``lines``, ``auto``), e.g. none of Gauss–Seidel where
it would run to its cap. ``--aspect A`` sets the cylinder's radius so that its edges around are ``A`` times those along. The column
"two-grid, its strides" is the solver's own choice (``TWO_GRID_ANISOTROPY``: a stride of 2 along an axis with
much weaker couplings), "two-grid, stride s" forces ``s`` along both axes.

Run:  python benchmarks/studies/multigrid.py [--size 100] [--noise broadband] [--weights 0.001 0.01 0.1 0.3 3]
      python benchmarks/studies/multigrid.py --solver --size 300 --weights 0.3 0.001 0.0001 0.00001 0.000001
      python benchmarks/studies/multigrid.py --solver --size 200 --weights 0.0001 0.000001 --fixed 0 0.1 0.3
      python benchmarks/studies/multigrid.py --solver --mesh torus --size 300 --weights 0.3 0.001 0.0001 0.000001
      python benchmarks/studies/multigrid.py --solver --mesh cube-sphere --size 50 --weights 0.3 0.001 0.0001 0.000001
      python benchmarks/studies/multigrid.py --solver --mesh real --weights 0.001 0.000001
      python benchmarks/studies/multigrid.py --solver --size 1000 --weights 0.000001 --columns two-grid auto
      python benchmarks/studies/multigrid.py --coarse-factor --size 1000 --weights 0.000001
      python benchmarks/studies/multigrid.py --solver --mesh random --size 300 --weights 0.00001 0.000001 --strides 2 4
      python benchmarks/studies/multigrid.py --solver --free fair --mesh cube-sphere --size 120 --stretch 4 \
          --weights 0.0001 0.000001 --columns lines --line-step off
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numba
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import _common  # noqa: E402

from quadnodes.fairing import FairingSystem, even_lengths  # noqa: E402
from quadnodes.zigzag import _window_geometry, detect, line_gaps  # noqa: E402

COARSEST = 400  # vertices at most on the level solved directly


@numba.njit
def _sweep(indptr, indices, data, diag, b, x, forward):  # type: ignore[no-untyped-def]
    """One Gauss–Seidel sweep ``x_i = (b_i − Σ_{j≠i} m_ij x_j) / m_ii`` over every row, in place, on (n, 3)."""
    n = b.shape[0]
    for step in range(n):
        i = step if forward else n - 1 - step
        s0, s1, s2 = b[i, 0], b[i, 1], b[i, 2]
        for k in range(indptr[i], indptr[i + 1]):
            j = indices[k]
            if j != i:
                v = data[k]
                s0 -= v * x[j, 0]
                s1 -= v * x[j, 1]
                s2 -= v * x[j, 2]
        d = diag[i]
        x[i, 0], x[i, 1], x[i, 2] = s0 / d, s1 / d, s2 / d


def prolongation_1d(n: int, degree: int) -> tuple[sp.csr_matrix, int]:
    """``(n, nc)`` interpolation from every other node (and the last) by Lagrange polynomials of ``degree``."""
    coarse = np.arange(0, n, 2)
    if coarse[-1] != n - 1:
        coarse = np.append(coarse, n - 1)
    nc, m = coarse.size, degree + 1
    rows, cols, vals = [], [], []
    at = {int(c): k for k, c in enumerate(coarse)}
    for i in range(n):
        if i in at:
            rows.append(i), cols.append(at[i]), vals.append(1.0)
            continue
        lo = min(max(int(np.searchsorted(coarse, i)) - m // 2, 0), nc - m)
        xs = coarse[lo : lo + m].astype(float)
        for a in range(m):
            w = np.prod([(i - xs[b]) / (xs[a] - xs[b]) for b in range(m) if b != a])
            rows.append(i), cols.append(lo + a), vals.append(w)
    return sp.csr_matrix((vals, (rows, cols)), shape=(n, nc)), nc


class Multigrid:
    """V(ν, ν) or K-cycles on the grid's matrix: Gauss–Seidel smoothing, Galerkin coarse levels, a direct coarsest.

    ``cycle="K"`` (Notay and Vassilevski's K-cycle): each coarse level but the coarsest is solved by two steps
    of flexible CG preconditioned by the next level's cycle, not by one cycle."""

    def __init__(self, M: sp.csr_matrix, size: int, free: np.ndarray, degree: int, levels: int = 99,
                 sweeps: int = 1, cycle: str = "V") -> None:
        self.M, self.P, self.sweeps, self.cycle = [M], [], sweeps, cycle
        side = size
        while side * side > COARSEST and len(self.M) < levels:
            P1, nc = prolongation_1d(side, degree)
            P = sp.kron(P1, P1, format="csr")
            if not self.P:  # nothing moves a fixed vertex
                P = (sp.diags(free.astype(float)) @ P).tocsr()
            C = (P.T @ (self.M[-1] @ P)).tocsr()
            C = (C + sp.diags((C.diagonal() == 0).astype(float))).tocsr()  # a node that moves nothing: identity
            self.P.append(P)
            self.M.append(C)
            side = nc
        for A in self.M:
            A.sort_indices()
        self.diag = [A.diagonal().copy() for A in self.M]
        self.lu = spla.splu(self.M[-1].tocsc())

    def __call__(self, r: np.ndarray) -> np.ndarray:
        return self._cycle(0, r)

    def _cycle(self, level: int, r: np.ndarray) -> np.ndarray:
        if level == len(self.M) - 1:
            return self.lu.solve(r)
        A, d, P = self.M[level], self.diag[level], self.P[level]
        x = np.zeros_like(r)
        for _ in range(self.sweeps):
            _sweep(A.indptr, A.indices, A.data, d, r, x, True)
        coarse = np.ascontiguousarray(P.T @ (r - A @ x))
        inner = self.cycle == "K" and level + 1 < len(self.M) - 1
        x += P @ (self._two_steps(level + 1, coarse) if inner else self._cycle(level + 1, coarse))
        for _ in range(self.sweeps):
            _sweep(A.indptr, A.indices, A.data, d, r, x, False)
        return x

    def _two_steps(self, level: int, r: np.ndarray) -> np.ndarray:
        """Two steps of flexible CG on ``M[level] x = r`` from zero, preconditioned by this level's cycle."""
        A = self.M[level]

        def dot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
            return np.einsum("ij,ij->j", u, v)

        c1 = self._cycle(level, r)
        v1 = A @ c1
        rho1, a1 = dot(c1, v1), dot(c1, r)
        r1 = r - (a1 / rho1) * v1
        c2 = self._cycle(level, r1)
        v2 = A @ c2
        gamma, a2 = dot(c2, v1), dot(c2, r1)
        beta = dot(c2, v2) - gamma * gamma / rho1
        return (a1 / rho1 - gamma * a2 / (rho1 * beta)) * c1 + (a2 / beta) * c2

    def work(self) -> float:
        """Nonzeros one cycle reads, in fine-matrix products (see the module's docstring; a K-cycle's coarse
        levels twice per visit, plus a product each)."""
        total, visits = 0.0, 1.0
        for level, (A, P) in enumerate(zip(self.M[:-1], self.P)):
            total += visits * (A.nnz * (2 * self.sweeps + 1) + 2 * P.nnz)  # 2ν sweeps, 2 products; two at half
            if self.cycle == "K" and level + 1 < len(self.M) - 1:
                visits *= 2
                total += visits * self.M[level + 1].nnz  # (the inner steps' products)
        total += visits * (self.lu.L.nnz + self.lu.U.nnz)
        return total / self.M[0].nnz

    def complexity(self) -> float:
        return sum(A.nnz for A in self.M) / self.M[0].nnz


def symmetric_gauss_seidel(M: sp.csr_matrix):  # type: ignore[no-untyped-def]
    M.sort_indices()
    d = M.diagonal().copy()

    def apply(r: np.ndarray) -> np.ndarray:
        x = np.zeros_like(r)
        _sweep(M.indptr, M.indices, M.data, d, r, x, True)
        _sweep(M.indptr, M.indices, M.data, d, r, x, False)
        return x
    return apply


def pcg(M: sp.csr_matrix, b: np.ndarray, precond, rtol: float = 1e-9, maxiter: int = 5000,  # type: ignore[no-untyped-def]
        flexible: bool = False) -> tuple[np.ndarray, int]:
    """Preconditioned CG on the columns of ``b`` together (per-column scalars), from zero; ``flexible``: the
    Polak–Ribière ``β`` (a preconditioner that is not a fixed linear map, as the K-cycle)."""
    x, r = np.zeros_like(b), b.copy()
    z = precond(r)
    p, rz = z.copy(), np.einsum("ij,ij->j", r, z)
    tol = rtol * np.sqrt(np.einsum("ij,ij->j", b, b))
    for step in range(1, maxiter + 1):
        q = M @ p
        a = rz / np.einsum("ij,ij->j", p, q)
        x += a * p
        r_old = r.copy() if flexible else r
        r -= a * q
        if (np.sqrt(np.einsum("ij,ij->j", r, r)) <= tol).all():
            return x, step
        z = precond(r)
        rz, old = np.einsum("ij,ij->j", r, z), rz
        beta = (rz - np.einsum("ij,ij->j", r_old, z)) / old if flexible else rz / old
        p = z + beta * p
    return x, maxiter


def sheet(n: int, noise: str):  # type: ignore[no-untyped-def]
    """The bench sheet, its window middles (free) and fair's even line lengths (``line_spacing="fair"``)."""
    m = _common.noisy_grid(n, noise)
    t = m.topology
    return m, detect(m, 0.0).free, even_lengths(_window_geometry(m.vertices, t.windows, t.window_walk)[1])


def grid_system(m, free: np.ndarray, inverse: np.ndarray, w: float) -> sp.csr_matrix:  # type: ignore[no-untyped-def]
    """fair()'s normal matrix in the grid's numbering (fixed vertices as identity rows)."""
    t = m.topology
    s = FairingSystem(m.vertices, t.windows, free, w / m.mean_edge_length**2, solver="cg",
                      _inverse_lengths=inverse, _topology=t)
    pattern, coef, fr = s._grid
    offsets, data = pattern.normal_matrix(coef, fr, s.weight)
    return sp.dia_matrix((data, offsets), shape=(m.n_vertices,) * 2).tocsr()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=100)
    ap.add_argument("--noise", choices=_common.NOISES, default="broadband")
    ap.add_argument("--weights", type=float, nargs="+", default=[0.001, 0.01, 0.1, 0.3, 3.0])
    ap.add_argument("--solver", action="store_true", help="the solver's Gauss-Seidel and two-grid paths")
    ap.add_argument("--strides", type=int, nargs="+", default=[4], help="two-grid coarse spacings (--solver)")
    ap.add_argument("--no-guard", action="store_true",
                    help="--solver: without fair's error guard at tiny weights (the residual stop alone)")
    ap.add_argument("--mesh", choices=["sheet", "cylinder", "torus", "cube-sphere", "random", "real"], default="sheet",
                    help="--solver: the bench sheet (open grid), a cylinder or a torus (closed grids), a cube-sphere "
                         "(no grid: six --size × --size faces), a random quad mesh (no grid: --size points "
                         "triangulated, split four times), or the tests' real meshes (a table of their own)")
    ap.add_argument("--aspect", type=float, default=None,
                    help="--mesh cylinder: the edges around this many times those along (default: radius 1)")
    ap.add_argument("--columns", nargs="+", choices=["gauss-seidel", "two-grid", "lines", "spectral", "auto"],
                    default=["gauss-seidel", "two-grid", "lines", "auto"],
                    help="--solver: which columns (e.g. no Gauss–Seidel where it would take its 20,000-step cap)")
    ap.add_argument("--free", choices=["detect", "fair"], default="detect",
                    help="--solver: the unknowns: every window middle (detect at 0) or as fair() frees them (line_gaps)")
    ap.add_argument("--fixed", type=float, nargs="+", default=[0.0],
                    help="--solver: shares of the vertices fixed at random (seeded), one table block each")
    ap.add_argument("--stretch", type=float, default=1.0,
                    help="--solver: the mesh's z scaled by this much after the noise (a cube-sphere's faces long "
                         "and thin on four sides)")
    ap.add_argument("--line-step", choices=["auto", "on", "off"], default="auto",
                    help="--solver: the structure lines' cycle's line step where faces are long and thin: the "
                         "solver's choice (fairing.LINE_SMOOTHING_SHARE), always, or never")
    ap.add_argument("--coarse-factor", action="store_true",
                    help="the two-grid coarse matrix's factorization in minimum degree and nested dissection order")
    args = ap.parse_args()
    if args.coarse_factor:
        return coarse_factor(args)
    if args.solver:
        return real_meshes(args) if args.mesh == "real" else solver_table(args)
    n = args.size
    m, free, inverse = sheet(n, args.noise)
    kinds = {
        "none": lambda M: (lambda r: r, 1.0, 1.0),
        "SGS": lambda M: (symmetric_gauss_seidel(M), 1.0, 1.0),
        "MG linear": lambda M: _mg(M, n, free, 1),
        "MG cubic": lambda M: _mg(M, n, free, 3),
        "MG cubic, K-cycle": lambda M: _mg(M, n, free, 3, cycle="K"),
        "two-grid cubic": lambda M: _mg(M, n, free, 3, levels=2),
    }
    print(f"{n}×{n} sheet, {args.noise} noise, all window middles free; steps to rtol 1e-9 · work per step · "
          f"work in all (fine products) · operator complexity · prototype time (s)\n")
    print("| ω | " + " | ".join(kinds) + " |")
    print("|---:|" + "---:|" * len(kinds))
    warm = sp.identity(16, format="csr")
    _sweep(warm.indptr, warm.indices, warm.data, np.ones(16), np.ones((16, 3)), np.zeros((16, 3)), True)
    for w in args.weights:
        M = grid_system(m, free, inverse, w)
        B = M @ np.random.default_rng(1).normal(size=(m.n_vertices, 3))
        B[~free] = 0.0
        cells = []
        for make in kinds.values():
            t0 = time.perf_counter()
            precond, per_step, complexity = make(M)
            x, steps = pcg(M, B, precond, flexible=getattr(precond, "cycle", "V") == "K")
            seconds = time.perf_counter() - t0
            assert np.abs(M @ x - B).max() <= 1e-6 * np.abs(B).max()
            cells.append(f"{steps} · {per_step:.1f} · {steps * per_step:.0f} · {complexity:.2f} · {seconds:.2f}")
        print(f"| {w:g} | " + " | ".join(cells) + " |", flush=True)


def solver_table(args: argparse.Namespace) -> None:
    """The ``--solver`` table (see the module)."""
    import quadnodes.fairing as fairing
    from quadnodes.linalg import compiled
    from quadnodes.linalg.multigrid import TwoGrid, line_interpolation

    compiled.wait()
    n = args.size
    m = {"sheet": lambda: _common.noisy_grid(n, args.noise), "cylinder": lambda: _common.noisy_cylinder(n, n, aspect=args.aspect),
         "torus": lambda: _common.noisy_torus(n, n), "cube-sphere": lambda: _common.noisy_cube_sphere(n),
         "random": lambda: noisy_random_quads(n)}[args.mesh]()
    if args.stretch != 1.0:
        m = m.with_vertices(m.vertices * np.array([1.0, 1.0, args.stretch]))
    fairing.LINE_SMOOTHING_SHARE = {"auto": fairing.LINE_SMOOTHING_SHARE, "on": -1.0, "off": 1.0}[args.line_step]
    t = m.topology
    inverse = even_lengths(_window_geometry(m.vertices, t.windows, t.window_walk)[1])
    extent = float(np.ptp(m.vertices, axis=0).max())  # (the solver's and the tests' extent: the widest axis)
    if args.no_guard:
        fairing.ERROR_GUARD_CONTRAST = float("inf")
    grid = args.mesh not in ("cube-sphere", "random")
    chosen = set(args.columns)
    kinds = ([("Gauss–Seidel", "gauss-seidel", None)] if "gauss-seidel" in chosen else []) \
        + ([(f"two-grid, stride {s}", "two-grid", s) for s in args.strides] if grid and "two-grid" in chosen else []) \
        + ([("two-grid, its strides", "two-grid", None)] if grid and "two-grid" in chosen else []) \
        + ([("two-grid, structure lines", "two-grid", "lines")] if "lines" in chosen else []) \
        + ([(f"two-grid, structure lines, stride {s}", "two-grid", ("lines", s)) for s in args.strides]
           if not grid and "lines" in chosen else []) \
        + ([("spectral", "spectral", None)] if grid and "spectral" in chosen else []) \
        + ([("auto", "auto", None)] if "auto" in chosen else [])
    if not kinds:
        raise SystemExit(f"--columns {' '.join(args.columns)}: no such column on --mesh {args.mesh} (on a mesh that "
                         "is no grid the two-grid column is 'lines')")
    what = (f"{n}×{n} sheet, {args.noise} noise" if args.mesh == "sheet"
            else f"cube-sphere of six {n}×{n} faces ({m.n_vertices} vertices), broadband noise"
            if args.mesh == "cube-sphere"
            else f"random quad mesh ({n} points split four times, {m.n_vertices} vertices), broadband noise" if not grid
            else f"{n}×{n} {args.mesh}, broadband noise")
    direct = m.n_vertices <= 450**2
    if args.stretch != 1.0:
        what += f", z × {args.stretch:g}"
    print(f"{what}, fair()'s first-iteration system; steps · seconds · max difference "
          f"from the {'direct solve' if direct else 'two-grid solve to rtol 1e-12'} / extent; line step "
          f"{args.line_step}\n")
    found = detect(m, 0.0)
    window_free = line_gaps(found.free, t.windows, found.fixed) if args.free == "fair" else found.free

    def unknowns(share: float) -> np.ndarray:  # (the free vertices, less ``share`` of them held at random, seeded)
        return window_free & (np.random.default_rng(0).random(m.n_vertices) >= share)

    if not grid:  # how long and thin the faces are, and the bound over ω at the first weight
        from quadnodes.fairing import _line_paths
        from quadnodes.linalg.cg import strongest_lines

        w = args.weights[0]
        probe = FairingSystem(m.vertices, t.windows, unknowns(args.fixed[0]), w / m.mean_edge_length**2,
                              _inverse_lengths=inverse, _lines=t.structure_lines)
        ratio = strongest_lines(probe.matrix, *_line_paths(t.structure_lines, probe.free_index, m.n_vertices)[:2])[0]
        print(f"(unknowns tied over {fairing.LINE_SMOOTHING_RATIO:g}× more strongly along one line than along "
              f"the other: {np.mean(ratio > fairing.LINE_SMOOTHING_RATIO):.2%}; Gershgorin bound over ω at ω = "
              f"{w:g}: {fairing._csr_gershgorin(probe.matrix) / probe.weight:.3g})\n")
    print("| fixed | ω | " + " | ".join(k for k, _, _ in kinds) + " |")
    print("|---:|---:|" + "---:|" * len(kinds))
    for share, w in ((share, w) for share in args.fixed for w in args.weights):
        free = unknowns(share)
        def system(lines: bool = False, **kw):  # type: ignore[no-untyped-def]  # (lines: no grid path, as fair() off a grid)
            return FairingSystem(m.vertices, t.windows, free, w / m.mean_edge_length**2, _inverse_lengths=inverse,
                                 _topology=None if lines else t, _lines=t.structure_lines, **kw)

        # (above 450²: the two-grid cycle to rtol 1e-12, whose steps do not grow as ω falls; Gauss–Seidel's would
        # reach its cap at 10⁻⁶ and fall back to a direct solve of the whole mesh)
        exact = system(solver="direct") if direct else system(solver="cg", preconditioner="two-grid", rtol=1e-12,
                                                              lines=not grid)
        anchor = m.vertices[exact.free_index]
        ref = exact.solve(anchor)
        cells = []
        for _, kind, stride in kinds:
            on_lines = stride == "lines" or isinstance(stride, tuple)
            fairing.TwoGrid = TwoGrid if stride is None or on_lines else _strided(TwoGrid, stride)
            # (the lines' stride: the solver's own, TWO_GRID_LINE_STRIDE or TWO_GRID_STRIDE by size, or forced)
            along = stride[1] if isinstance(stride, tuple) else None
            fairing.line_interpolation = lambda *lines, stride, _s=along: line_interpolation(
                *lines, stride=stride if _s is None else _s)
            t0 = time.perf_counter()
            s = system(solver="cg", preconditioner=kind, lines=on_lines)
            x = s.solve(anchor)
            seconds = time.perf_counter() - t0
            cells.append(f"{s.iterations} · {seconds:.2f} · {np.abs(x - ref).max() / extent:.1e}")
        fairing.TwoGrid, fairing.line_interpolation = TwoGrid, line_interpolation
        print(f"| {share:.2%} | {w:g} | " if 0 < share < 0.01 else f"| {share:.0%} | {w:g} | ", end="")
        print(" | ".join(cells) + " |", flush=True)


def noisy_random_quads(points: int, seed: int = 0):  # type: ignore[no-untyped-def]
    """A quad mesh with extraordinary vertices everywhere: the Delaunay triangulation of ``points`` seeded random
    points of the unit square (z a gentle wave), split four times (each triangle into three quads, then each quad
    into four: patches 8 edges wide between valence-3 to valence-9 vertices), plus broadband noise of 0.2 edge
    lengths."""
    from scipy.spatial import Delaunay

    from quadnodes.mesh import QuadMesh

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))
    from meshes import subdivide

    rng = np.random.default_rng(seed)
    xy = rng.random((points, 2))
    v = np.column_stack([xy, 0.05 * np.sin(6 * xy[:, 0]) * np.cos(4 * xy[:, 1])])
    polys = Delaunay(xy).simplices.tolist()
    for _ in range(4):
        v, polys = subdivide(v, polys)
    m = QuadMesh(np.asarray(v), np.array(polys))
    return m.with_vertices(m.vertices + rng.normal(scale=0.2 * m.mean_edge_length, size=m.vertices.shape))


def coarse_factor(args: argparse.Namespace) -> None:
    """The ``--coarse-factor`` table (see the module)."""
    from quadnodes.linalg.direct import cholmod_available, factorize
    from quadnodes.linalg.multigrid import coarse_matrix, grid_interpolation

    n = args.size
    m, free, inverse = sheet(n, args.noise)
    print(f"{n}×{n} sheet, {args.noise} noise: the two-grid coarse matrix PᵀMP (stride 4); factor entries as L + U "
          f"(CHOLMOD's L counted twice, less the diagonal)\n")
    print("| ω | coarse nodes | couplings a row | order | factor entries (L + U) | factorize (s) | "
          "solve of 3 coordinates (ms) |")
    print("|---:|---:|---:|---|---:|---:|---:|")
    for w in args.weights:
        M = grid_system(m, free, inverse, w)
        C = coarse_matrix(M, grid_interpolation(n, n, 4, free))  # (as the solver makes it)
        B = np.random.default_rng(0).normal(size=(C.shape[0], 3))
        for backend, order in [("superlu", "minimum_degree"), ("superlu", "nested_dissection")] + (
                [("cholmod", "minimum_degree")] if cholmod_available() else []):
            t0 = time.perf_counter()
            f = factorize(C, kind="spd", order=order, backend=backend)
            seconds = time.perf_counter() - t0
            t0 = time.perf_counter()
            for _ in range(5):
                f.solve(B)
            solve = (time.perf_counter() - t0) / 5
            lu = f._lu
            entries = (lu.L.nnz + lu.U.nnz if backend == "superlu"  # (CHOLMOD: L alone, its AMD order)
                       else 2 * lu.L().nnz - C.shape[0])  # type: ignore[operator]
            print(f"| {w:g} | {C.shape[0]} | {C.nnz / C.shape[0]:.1f} | {backend}, {order.replace('_', ' ')} | "
                  f"{entries / 1e6:.1f} M | {seconds:.2f} | {1e3 * solve:.0f} |", flush=True)


def real_meshes(args: argparse.Namespace) -> None:
    """The ``--solver --mesh real`` table: the two-grid cycle on the structure lines of meshes that are no grid."""
    from quadnodes.io import load
    from quadnodes.linalg import compiled
    from quadnodes.noise import perturb

    compiled.wait()
    tests = Path(__file__).resolve().parents[2] / "tests"
    sys.path.insert(0, str(tests))
    from meshes import extraordinary_mesh, l_shape_with_hole

    cases = [("extraordinary_mesh(4)", extraordinary_mesh(4)), ("l_shape_with_hole(60)", l_shape_with_hole(60))]
    cases += [(name, load(tests / "data" / f"{name}.obj"))
              for name in ("polygon_quads", "quadmesh_hole", "rounded_box", "staircase_saddle")]
    print("the tests' meshes, perturb(jitter=0.2, seed=1), window middles free (\"boundary held\": but the boundary), "
          "fair()'s first-iteration system; steps · seconds · max difference from the direct solve / extent\n")
    print("| mesh | vertices | held | free | ω | Gauss–Seidel | two-grid, structure lines |")
    print("|---|---:|---|---:|---:|---:|---:|")
    for name, clean in cases:
        m = perturb(clean, jitter=0.2, seed=1, fix="none")[0]
        t = m.topology
        inverse = even_lengths(_window_geometry(m.vertices, t.windows, t.window_walk)[1])
        for held in ("none", "boundary"):
            free = detect(m, 0.0).free & ~(t.boundary_vertices if held == "boundary" else False)
            for w in args.weights:
                def system(**kw):  # type: ignore[no-untyped-def]
                    return FairingSystem(m.vertices, t.windows, free, w / m.mean_edge_length**2,
                                         _inverse_lengths=inverse, _lines=t.structure_lines, **kw)
                exact = system(solver="direct")
                anchor = m.vertices[exact.free_index]
                ref, extent = exact.solve(anchor), float(np.ptp(anchor, axis=0).max())
                cells = []
                for kind in ("gauss-seidel", "two-grid"):
                    t0 = time.perf_counter()
                    s = system(solver="cg", preconditioner=kind)
                    x = s.solve(anchor)
                    cells.append(f"{s.iterations} · {time.perf_counter() - t0:.2f} · "
                                 f"{np.abs(x - ref).max() / extent:.0e}")
                print(f"| {name} | {m.n_vertices} | {held} | {free.sum()} | {w:g} | " + " | ".join(cells) + " |",
                      flush=True)


def _strided(base: type, stride: int) -> type:
    """``base`` (TwoGrid) at ``stride``, as fair() constructs it (a subclass, so fair's type checks still hold)."""
    given = stride

    class Strided(base):  # type: ignore[valid-type, misc]
        def __init__(self, blocks, shape, moving, stride=None, wrap=(False, False)):  # type: ignore[no-untyped-def]
            super().__init__(blocks, shape, moving, stride=given, wrap=wrap)  # (the solver's choice replaced)
    return Strided


def _mg(M: sp.csr_matrix, n: int, free: np.ndarray, degree: int, levels: int = 99, cycle: str = "V"):  # type: ignore[no-untyped-def]
    mg = Multigrid(M, n, free, degree, levels, cycle=cycle)
    return mg, 1.0 + mg.work(), mg.complexity()


if __name__ == "__main__":
    main()
