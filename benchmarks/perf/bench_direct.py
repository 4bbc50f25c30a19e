"""The direct back-end of ``quadnodes.linalg.factorize``: orders and back-ends on mesh matrices (issue 15/17).

Backs docs/methods.md "After nested dissection and CHOLMOD (branch direct-order)".

Matrices (all SPD, from an n × n grid, no mesh noise needed — only the pattern and conditioning matter):

- ``vertex``: the fair-web E2 system of the free vertices (corners fixed) plus 1e-6·max diag (the shape of
  ADMM's ``P + ρI`` and of one coordinate of the unconstrained solve);
- ``newton-1%`` / ``newton-50%`` / ``newton-100%``: a fair-web Newton system's shape: x, y, z of every vertex
  (``kron(P, I₃)``), the coordinates of a seeded random 1 %, 50 % or 100 % of the vertices turned into a
  random orthonormal frame (as an active cylinder constraint does), plus 1e-12·max diag;
- ``laplace``: the cotangent Laplacian of the grid's interior vertices (Schneider–Kobbelt's Dirichlet system).

Every matrix is factorized by ``factorize(kind="spd")`` with each ``--linalg`` back-end and order:
SuperLU in minimum-degree order (``superlu-md``, the back-end before nested dissection), SuperLU in
quadnodes' nested-dissection order (``superlu-nd``; for the Newton systems the vertex order, each vertex's
coordinates together — ``expand_order``), and, when scikit-sparse is importable, CHOLMOD with its AMD order
(``cholmod-md``) and with the same nested dissection (``cholmod-nd``). Printed: CPU seconds of the
order, of the factorization and of one solve with 3 right-hand sides, the factor's entries (L, or (L + U)/2
for SuperLU's LU), and the relative residual. CPU time (this process) is the steadier measure on a shared
machine; every row is measured in the same run.

Run:  python benchmarks/perf/bench_direct.py [--n 300] [--only vertex newton-1% ...]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import scipy.sparse as sp

MATRICES = ("vertex", "newton-1%", "newton-50%", "newton-100%", "laplace")


def _vertex_system(n: int) -> sp.csc_matrix:
    from quadnodes.mesh import grid
    from quadnodes.webs import _quadratic, line_differences

    m = grid(n, n, spacing=1.0 / (n - 1))
    D1, D2 = line_differences(m)
    Q = _quadratic(D1, D2, "E2", 0.0)
    corners = np.array([0, n - 1, n * (n - 1), n * n - 1])
    free = np.setdiff1d(np.arange(n * n), corners)
    return Q[free][:, free].tocsc()


def _newton_system(P: sp.csc_matrix, fraction: float) -> tuple[sp.csc_matrix, np.ndarray]:
    """``Zᵀ kron(P, I₃) Z`` with Z a random frame at ``fraction`` of the vertices, the identity elsewhere."""
    k = P.shape[0]
    rng = np.random.default_rng(0)
    frames = np.tile(np.eye(3), (k, 1, 1))
    chosen = rng.random(k) < fraction
    q, _ = np.linalg.qr(rng.normal(size=(int(chosen.sum()), 3, 3)))
    frames[chosen] = q
    blocks = sp.block_diag(list(frames), format="csr")
    A = (blocks.T @ sp.kron(P, sp.identity(3), format="csr") @ blocks).tocsc()
    A = (A + 1e-12 * float(A.diagonal().max()) * sp.identity(3 * k, format="csc")).tocsc()
    return A, np.repeat(np.arange(k), 3)


def _laplace(n: int) -> sp.csc_matrix:
    from quadnodes.discrete_curvature import cotangent_laplacian
    from quadnodes.mesh import grid

    y, x = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n), indexing="ij")
    m = grid(n, n, spacing=1.0 / (n - 1), height=0.3 * np.sin(3 * x) * np.cos(2 * y))
    L = cotangent_laplacian(m)
    inner = np.flatnonzero(~m.topology.boundary_vertices)
    return L[inner][:, inner].tocsc()


def _entries(f) -> int:
    lu = f._lu
    if f.backend == "cholmod":
        return int(lu.L().nnz)
    return int((lu.L.nnz + lu.U.nnz) // 2)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=300)
    ap.add_argument("--only", nargs="+", choices=MATRICES, default=list(MATRICES))
    args = ap.parse_args()
    from quadnodes.linalg import cholmod_available, expand_order, factorize, nested_dissection

    n = args.n
    P = _vertex_system(n)
    P_def = (P + 1e-6 * float(P.diagonal().max()) * sp.identity(P.shape[0], format="csc")).tocsc()
    c = time.process_time()
    nd_vertex = nested_dissection(P)
    nd_cpu = time.process_time() - c
    print(f"n = {n}: vertex system {P.shape[0]} unknowns; its nested dissection {nd_cpu:.2f} s CPU")
    print(f"{'matrix':<12} {'unknowns':>9} {'back-end':<11} {'order s':>8} {'factor s':>9} {'solve s':>8} "
          f"{'entries':>11} {'residual':>9}")
    backends = ["superlu-md", "superlu-nd"] + (["cholmod-md", "cholmod-nd"] if cholmod_available() else [])
    for name in args.only:
        group = None
        if name == "vertex":
            A = P_def
        elif name == "laplace":
            A = _laplace(n)
        else:
            A, group = _newton_system(P, float(name.split("-")[1].rstrip("%")) / 100)
        rhs = np.random.default_rng(1).random((A.shape[0], 3))
        c = time.process_time()
        if name == "vertex":
            nd = nd_vertex
        elif group is not None:
            nd = expand_order(nd_vertex, group)
        else:
            nd = nested_dissection(A)
        order_cpu = time.process_time() - c + (nd_cpu if group is not None else 0.0)
        for be in backends:
            backend, how = be.split("-")
            order = "minimum_degree" if how == "md" else nd
            c = time.process_time()
            f = factorize(A, kind="spd", order=order, backend=backend)
            fcpu = time.process_time() - c
            c = time.process_time()
            x = f.solve(rhs)
            scpu = time.process_time() - c
            res = float(np.abs(A @ x - rhs).max() / np.abs(rhs).max())
            print(f"{name:<12} {A.shape[0]:>9} {be:<11} {order_cpu if how == 'nd' else 0.0:>8.2f} {fcpu:>9.2f} "
                  f"{scpu:>8.3f} {_entries(f):>11,} {res:>9.1e}", flush=True)


if __name__ == "__main__":
    main()
