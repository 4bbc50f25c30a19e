"""A symmetric alternating-line (ADI-like) preconditioner for the fairing system: steps against plain CG.

Backs the line-preconditioner paragraph in docs/fairing.md "Speed" (issue 15, part 2; not yet in the solver).

On the bench_core sheet (``benchmarks/_common.py``, ``--noise broadband`` by default) with every
window-middle vertex free, the grid's normal matrix ``M = L_rows + L_cols + W`` is split into its
row-window part (offsets ±1..3: banded in the grid's numbering), its column-window part (offsets
±cols..: banded after a transpose) and the weight diagonal ``W``. Both line families are factorized
once by banded Cholesky (LAPACK ``pbtrf`` over all lines at once: the lines are independent blocks
of one band) with a shift ``α = a·ω``, and the preconditioner is the symmetrized product
``P⁻¹ = ½ α [(L_r+α)⁻¹(L_c+α)⁻¹ + (L_c+α)⁻¹(L_r+α)⁻¹]`` (SPD only where the two families nearly
commute: at ``a = 1`` it is not, and CG diverges). Two more variants use exact solves of ``M``'s
row-line and column-line blocks (each with ``M``'s whole diagonal): added (SPD by construction; 58 steps
at 60², 59 at 200², ω = 0.3 — the one now in ``quadnodes.linalg.cg.LinePreconditioner``), or applied
row, column, row (symmetric multiplicative: SPD only where that splitting converges; 522 steps at 60²). SciPy's ``cg`` on the x coordinate, rtol 1e-9,
from the anchor; prints the steps and the wall time of each variant and of plain CG.

Run:  python benchmarks/studies/line_adi.py [--size 100] [--noise broadband] [--weights 0.3 1] [--alphas 1 3 10 30]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.linalg import cho_solve_banded, cholesky_banded
from scipy.sparse.linalg import LinearOperator, cg

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import _common  # noqa: E402

from quadnodes.fairing import grid_pattern, window_coefficients  # noqa: E402
from quadnodes.zigzag import detect  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=100)
    ap.add_argument("--noise", choices=_common.NOISES, default="broadband")
    ap.add_argument("--weights", type=float, nargs="+", default=[0.3, 1.0])
    ap.add_argument("--alphas", type=float, nargs="*", default=[1.0, 3.0, 10.0, 30.0])
    args = ap.parse_args()
    n, noise = args.size, args.noise
    m = _common.noisy_grid(n, noise)
    t = m.topology
    free = detect(m, 0.0).free
    h = m.mean_edge_length
    p = grid_pattern(t)
    coef = window_coefficients(m.vertices, t.windows)
    isrow = (p.ext[p.start + 1] - p.ext[p.start]) == 1
    for w in args.weights:
        om = w / h**2
        off, dr = p.normal_matrix(coef * isrow[:, None], free, 0.0); dr[6] -= ~free
        _, dc = p.normal_matrix(coef * (~isrow)[:, None], free, 0.0); dc[6] -= ~free
        wd = np.where(free, om, 1.0)
        data = dr + dc; data[6] += wd
        N = n * n
        M = sp.dia_matrix((data, off), shape=(N, N)).tocsr()
        rhs = np.zeros((N, 3)); a = m.vertices
        b = wd[:, None] * a  # fairing rhs: ω·anchor (all-free interior; fixed: identity)
        x0 = a.copy()
        # banded forms (upper) of Lr + s and Lc + s
        def banded_rows(d, s_diag):
            ab = np.zeros((4, N))
            ab[3] = d[6] + s_diag
            for k in (1, 2, 3):
                ab[3 - k, k:] = d[6 + k, k:]  # upper: ab[u-k, j] = A[j-k, j]; dia data[6+k, j] = M[j-k, j]
            return ab
        def perm_c(v):  # grid (rows, cols) row-major -> column-major
            return v.reshape(n, n, -1).transpose(1, 0, 2).reshape(N, -1)
        def banded_cols(d, s_diag):
            ab = np.zeros((4, N))
            dd = perm_c(d[6][:, None])[:, 0] + perm_c(s_diag[:, None])[:, 0]
            ab[3] = dd
            for k in (1, 2, 3):
                # M[j - k*n, j] in row-major: data[6+(9+k-6)...] offsets index: -3c,-2c,-c,-3,-2,-1,0,1,2,3,c,2c,3c -> +kc at 9+k
                v = perm_c(d[9 + k][:, None])[:, 0]  # value at column j (row-major) -> column-major position
                ab[3 - k, k:] = v[k:]
            return ab
        for alpha_f in args.alphas:
            alpha = np.where(free, om * alpha_f, 1.0)
            t0 = time.perf_counter()
            Cr = cholesky_banded(banded_rows(dr, alpha), lower=False)
            Cc = cholesky_banded(banded_cols(dc, alpha), lower=False)
            tf = time.perf_counter() - t0
            def Sr(r): return cho_solve_banded((Cr, False), r, check_finite=False)
            def Sc(r): return perm_c(cho_solve_banded((Cc, False), perm_c(r), check_finite=False))
            def apply(r):
                r = r.reshape(N, -1)
                z1 = Sc(alpha[:, None] * Sr(r)); z2 = Sr(alpha[:, None] * Sc(r))
                return (0.5 * (z1 + z2)).reshape(r.shape[0], -1).squeeze()
            P = LinearOperator((N, N), matvec=apply)
            steps = [0]
            t0 = time.perf_counter()
            x, info = cg(M, b[:, 0], x0=x0[:, 0], rtol=1e-9, maxiter=3000, M=P, callback=lambda _: steps.__setitem__(0, steps[0] + 1))
            ts = time.perf_counter() - t0
            err = np.abs(M @ x - b[:, 0]).max()
            print(f"n={n} {noise} w={w} alpha={alpha_f}ω: factor {tf:.2f}s, {steps[0]} steps, {ts:.2f}s (1 coord), info {info}")
        # exact solves of M's row-line and column-line blocks (each with M's whole diagonal), combined
        # additively (SPD by construction) or symmetric-multiplicatively (row, column, row; SPD only if that converges)
        Fr = cholesky_banded(banded_rows(dr, data[6] - dr[6]), lower=False)
        Fc = cholesky_banded(banded_cols(dc, data[6] - dc[6]), lower=False)

        def Br(r): return cho_solve_banded((Fr, False), r, check_finite=False)
        def Bc(r): return perm_c(cho_solve_banded((Fc, False), perm_c(r), check_finite=False)).reshape(r.shape)

        def additive(r):
            return Br(r) + Bc(r)

        def multiplicative(r):
            z = Br(r)
            z = z + Bc(r - M @ z)
            return z + Br(r - M @ z)

        for name, fn in (("additive line blocks", additive), ("symmetric multiplicative line blocks", multiplicative)):
            P = LinearOperator((N, N), matvec=fn)
            steps = [0]
            t0 = time.perf_counter()
            cg(M, b[:, 0], x0=x0[:, 0], rtol=1e-9, maxiter=3000, M=P,
               callback=lambda _: steps.__setitem__(0, steps[0] + 1))
            print(f"n={n} {noise} w={w} {name}: {steps[0]} steps, {time.perf_counter() - t0:.2f}s (1 coord)")
        steps = [0]; t0 = time.perf_counter()
        cg(M, b[:, 0], x0=x0[:, 0], rtol=1e-9, callback=lambda _: steps.__setitem__(0, steps[0] + 1))
        print(f"n={n} {noise} w={w} plain: {steps[0]} steps {time.perf_counter()-t0:.2f}s")


if __name__ == "__main__":
    main()
