"""The NumPy/SciPy kernel choices behind the fairing solver, timed on the bench_core grids.

Backs the kernel table in docs/fairing.md "Speed".

For each size (the bench_core surface, every window-middle vertex free, ω = 0.3):
- gather of (n, 3) rows: fancy indexing ``V[idx]`` against ``np.take(V, idx, axis=0)``;
- per-coordinate scalar times a vector: ``(k, 3) * (3,)`` against the ``(k/64, 192)`` view and the
  ``(3, k)`` layout;
- the matrix applied to x, y and z: SciPy's multi-vector kernel on ``(k, 3)`` (one pass over the matrix)
  against its one-vector kernel three times on ``(3, k)``, and the first with float32 values and vectors;
  last, the grid path: the 13-diagonal matrix in the grid's numbering with SciPy's ``dia_matvec``
  three times on ``(3, n)``;
- BLAS level 1 against NumPy for the CG update ``x += α p; r -= α q`` on ``(3, k)`` vectors.

Best of 20 runs each, one thread, in milliseconds.

Run:  python benchmarks/perf/kernels.py [--sizes 100 300 1000]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # one thread, as the fairing's serial CG runs BLAS

import numpy as np  # noqa: E402
from scipy.linalg.blas import daxpy
from scipy.sparse._sparsetools import csr_matvec, csr_matvecs, dia_matvec

from quadnodes.fairing import FairingSystem, grid_pattern, window_coefficients
from quadnodes.zigzag import detect

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import _common  # noqa: E402


def _best(f, reps: int = 20) -> float:
    f()
    best = np.inf
    for _ in range(reps):
        t = time.perf_counter()
        f()
        best = min(best, time.perf_counter() - t)
    return best * 1e3


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 300, 1000])
    args = ap.parse_args()
    print("| grid | gather V[idx] | np.take | α·(k,3) | α·(k/64,192) | α·(3,k) | matvecs (k,3) | "
          "3× matvec (3,k) | matvecs float32 | 3× dia_matvec (3,n) | update NumPy | update BLAS |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for n in args.sizes:
        m = _common.noisy_grid(n)
        free = detect(m, 0.0).free
        s = FairingSystem(m.vertices, m.topology.windows, free, 0.3 / m.mean_edge_length**2, solver="cg")
        M = s.matrix
        k = M.shape[0]
        V, idx = m.vertices, np.ascontiguousarray(m.topology.windows[:, 1])
        kp = -(-k // 64) * 64
        P, T = np.random.rand(kp, 3), np.empty((kp, 3))
        PT, TT = np.ascontiguousarray(P.T), np.empty((3, kp))
        a = np.random.rand(3)
        aw, ac = np.tile(a, 64), a[:, None]
        X, Y = np.random.rand(k, 3), np.zeros((k, 3))
        XT, YT = np.ascontiguousarray(X.T), np.zeros((3, k))
        M32, X32, Y32 = M.data.astype(np.float32), X.astype(np.float32), Y.astype(np.float32)
        t = m.topology
        offsets, data = grid_pattern(t).normal_matrix(window_coefficients(V, t.windows), free, s.weight)
        offsets = offsets.astype(np.int32)
        nv = m.n_vertices
        XN, YN = np.random.rand(3, nv), np.zeros((3, nv))
        R, Q = np.random.rand(3, kp), np.random.rand(3, kp)

        def numpy_update():
            np.multiply(PT, ac, out=TT)
            R.__iadd__(TT)
            np.multiply(Q, ac, out=TT)
            R.__isub__(TT)

        def blas_update():
            for i in range(3):
                daxpy(PT[i], R[i], a=a[i])
                daxpy(Q[i], R[i], a=-a[i])
        row = [
            _best(lambda: V[idx]),
            _best(lambda: np.take(V, idx, axis=0)),
            _best(lambda: np.multiply(P, a, out=T)),
            _best(lambda: np.multiply(P.reshape(-1, 192), aw, out=T.reshape(-1, 192))),
            _best(lambda: np.multiply(PT, ac, out=TT)),
            _best(lambda: csr_matvecs(k, k, 3, M.indptr, M.indices, M.data, X.reshape(-1), Y.reshape(-1))),
            _best(lambda: [csr_matvec(k, k, M.indptr, M.indices, M.data, XT[i], YT[i]) for i in range(3)]),
            _best(lambda: csr_matvecs(k, k, 3, M.indptr, M.indices, M32, X32.reshape(-1), Y32.reshape(-1))),
            _best(lambda: [dia_matvec(nv, nv, 13, nv, offsets, data, XN[i], YN[i]) for i in range(3)]),
            _best(numpy_update),
            _best(blas_update),
        ]
        print(f"| {n}×{n} | " + " | ".join(f"{t:.3f}" for t in row) + " |", flush=True)


if __name__ == "__main__":
    main()
