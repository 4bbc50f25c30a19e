"""Smoothed aggregation (pyamg) on a mesh that is no grid: which near-null candidates keep the steps from growing.

Backs the "no grid" paragraph of docs/design-notes.md, session 13 (issue 15, part 2: a preconditioner whose
steps do not depend on the weight, "and keep what works on irregular meshes too"; not in the solver, and why).

On a cube-sphere (``benchmarks/_common.py``: six ``k × k`` grids on the unit sphere, eight valence-3 corners,
broadband noise of 0.2 edge lengths; all window middles free, fair's default ``line_spacing="fair"``), builds
fair()'s first-iteration system and solves each coordinate to rtol 1e-10 from the anchor with:

- ``Gauss–Seidel``: ``FairingSystem(preconditioner="gauss-seidel")``, what "auto" runs there (compressed rows);
- CG preconditioned by a pyamg smoothed-aggregation V-cycle (symmetric Gauss–Seidel smoothing, coarsest
  ≤ 2,000 unknowns) whose near-null candidates ``B`` are the constant (``B=1``), the constant and the vertices'
  centred coordinates (``B=1,xyz``), or those and their ten products up to degree 2 (``B=quadratic``).

The line energy does not see motions that are quadratic along the lines, so at a small weight the slow modes are
smooth; candidates that span them keep the steps flat, at the price of the coarse levels' size (operator
complexity: all levels' nonzeros over the fine matrix's).

Prints per weight: steps (the worst coordinate) · set-up + solve seconds · operator complexity · largest
difference from Gauss–Seidel's solution over the extent. Needs pyamg (``pip install -e .[bench]``).

Run:  python benchmarks/studies/amg_candidates.py [--k 50] [--weights 0.3 0.001 0.0001 0.000001]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import _common  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--k", type=int, default=50, help="vertices along each face of the cube-sphere (6k² + 2 in all)")
    ap.add_argument("--weights", type=float, nargs="+", default=[0.3, 0.001, 0.0001, 0.000001])
    args = ap.parse_args()
    import pyamg

    from quadnodes.fairing import FairingSystem, even_lengths
    from quadnodes.linalg import compiled
    from quadnodes.zigzag import _window_geometry, detect

    compiled.wait()
    m = _common.noisy_cube_sphere(args.k)
    t = m.topology
    free = detect(m, 0.0).free
    inverse = even_lengths(_window_geometry(m.vertices, t.windows, t.window_walk)[1])
    kinds = ("B=1", "B=1,xyz", "B=quadratic")
    print(f"cube-sphere, {m.n_vertices} vertices, broadband noise, fair()'s first-iteration system; steps · seconds "
          "(set-up + solve) · operator complexity · max difference from Gauss–Seidel / extent\n")
    print("| ω | Gauss–Seidel | " + " | ".join(kinds) + " |")
    print("|---:|---:|" + "---:|" * len(kinds))
    for w in args.weights:
        s = FairingSystem(m.vertices, t.windows, free, w / m.mean_edge_length**2, _inverse_lengths=inverse,
                          solver="cg", preconditioner="gauss-seidel")
        a = m.vertices[s.free_index]
        t0 = time.perf_counter()
        ref = s.solve(a)
        cells = [f"{s.iterations} · {time.perf_counter() - t0:.2f}"]
        M, b = s.matrix.tocsr(), s._rhs + s.weight * a
        extent = float(np.ptp(a, axis=0).max())
        pos = (a - a.mean(axis=0)) / np.abs(a - a.mean(axis=0)).max()
        ones = np.ones((len(a), 1))
        products = [pos[:, [i]] * pos[:, [j]] for i in range(3) for j in range(i, 3)]
        for B in (ones, np.hstack([ones, pos]), np.hstack([ones, pos, *products])):
            t0 = time.perf_counter()
            ml = pyamg.smoothed_aggregation_solver(
                M, B=B, symmetry="symmetric", max_coarse=2000,
                presmoother=("gauss_seidel", {"sweep": "symmetric"}),
                postsmoother=("gauss_seidel", {"sweep": "symmetric"}))
            X, steps = np.empty_like(b), 0
            for c in range(3):
                history: list[float] = []
                X[:, c] = ml.solve(b[:, c], x0=a[:, c], tol=1e-10, accel="cg", maxiter=5000, residuals=history)
                steps = max(steps, len(history) - 1)
            seconds = time.perf_counter() - t0
            cells.append(f"{steps} · {seconds:.2f} · {ml.operator_complexity():.2f} · "
                         f"{np.abs(X - ref).max() / extent:.0e}")
        print(f"| {w:g} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
