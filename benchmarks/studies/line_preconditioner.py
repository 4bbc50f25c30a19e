"""Does a line-family preconditioner pay off for the fairing system? (It did not; see docs/fairing.md.)

Backs the line-preconditioner note in docs/fairing.md "Speed".

On a 300×300 grid with every window-middle vertex free, CG on (AᵀA + ωI) x = b (x coordinate),
started from the current positions, with no preconditioner and with the additive row/column
line preconditioner P = S_rows + S_cols, where S_f solves the system restricted to the lines of
one family exactly (banded Cholesky, bandwidth 3, SciPy/LAPACK). Prints steps and wall time.

Run:  python benchmarks/studies/line_preconditioner.py  (about 10 s)
"""

from __future__ import annotations

import time

import numpy as np
from scipy.linalg import cho_solve_banded, cholesky_banded
from scipy.sparse.linalg import LinearOperator, cg

from quadnodes.fairing import FairingSystem
from quadnodes.mesh import grid
from quadnodes.noise import perturb
from quadnodes.zigzag import detect


def main(n: int = 300) -> None:
    m, _ = perturb(grid(n, n, spacing=1 / (n - 1)), tangential=0.2, normal=0.05, seed=0)
    free = detect(m, 0.0).free
    h = m.mean_edge_length
    fi = np.flatnonzero(free)
    k = fi.size
    row_of, col_of = fi // n, fi % n
    print("| ω (normalized) | preconditioner | CG steps | wall time (s) |")
    print("|---:|---|---:|---:|")
    for w in (0.3, 0.01):
        s = FairingSystem(m.vertices, m.topology.windows, free, w / h**2, solver="cg")
        M = s.matrix
        coo = M.tocoo()
        rhs = (s._rhs + s.weight * m.vertices[free])[:, 0]
        x0 = m.vertices[free][:, 0]
        fams = []
        for line, pos in ((row_of, col_of), (col_of, row_of)):
            perm = np.lexsort((pos, line))
            inv = np.empty(k, dtype=np.int64)
            inv[perm] = np.arange(k)
            same = line[coo.row] == line[coo.col]
            pi, pj = inv[coo.row[same]], inv[coo.col[same]]
            low = pi >= pj
            ab = np.zeros((int((pi[low] - pj[low]).max()) + 1, k))
            ab[pi[low] - pj[low], pj[low]] = coo.data[same][low]
            fams.append((perm, cholesky_banded(ab, lower=True)))

        def solve_family(f: int, r: np.ndarray) -> np.ndarray:
            perm, c = fams[f]
            z = np.empty_like(r)
            z[perm] = cho_solve_banded((c, True), r[perm])
            return z

        additive = LinearOperator((k, k), matvec=lambda r: solve_family(0, r) + solve_family(1, r))
        for name, P in (("none", None), ("additive row/column lines", additive)):
            steps = [0]
            t = time.perf_counter()
            cg(M, rhs, x0=x0, rtol=1e-9, M=P, callback=lambda _: steps.__setitem__(0, steps[0] + 1))
            print(f"| {w:g} | {name} | {steps[0]} | {time.perf_counter() - t:.2f} |")


if __name__ == "__main__":
    main()
