"""Conjugate gradients across weights: plain CG (free-index CSR, and the grid's diagonal storage)
against block-Jacobi CG on the same system.

Backs the table in docs/fairing.md "Speed" (small weights: block-Jacobi preconditioning).

On an n×n grid (the bench_core surface, ``benchmarks/_common.py``; ``--noise zigzag`` — tangential 0.2 and normal 0.05 — or ``broadband``) with
every window-middle vertex free, builds the one-iteration system at normalized weights 0.001 … 10 and
solves it (x, y, z together, rtol 1e-9, from the anchor) three ways: plain CG on the free-index CSR
matrix (any mesh), plain CG on the 13 diagonals in the grid's numbering (complete vertex grids), and
block-Jacobi CG (``quadnodes.fairing.BLOCK_JACOBI_RATIO`` and ``GRID_BLOCK_JACOBI_RATIO``). Prints steps and the wall time of system +
solve (best of ``--repeat`` runs), and which one the default rule picks for this grid. Also checks that
all three agree to 1e-8 of the mesh's extent.

Run:  python benchmarks/studies/cg_weights.py [--size 300] [--noise zigzag|broadband] [--repeat 3]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from quadnodes import fairing
from quadnodes.fairing import FairingSystem
from quadnodes.linalg.cg import DiagonalBlocks
from quadnodes.zigzag import detect

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import _common  # noqa: E402

WEIGHTS = (0.001, 0.003, 0.01, 0.03, 0.1, 0.3, 1.0, 3.0, 10.0)


def _run(m, free, w, ratio, repeat, grid=False):
    default = fairing.BLOCK_JACOBI_RATIO, fairing.GRID_BLOCK_JACOBI_RATIO
    fairing.BLOCK_JACOBI_RATIO = fairing.GRID_BLOCK_JACOBI_RATIO = ratio
    try:
        best, x, s = np.inf, None, None
        for _ in range(repeat):
            t = time.perf_counter()
            s = FairingSystem(m.vertices, m.topology.windows, free, w / m.mean_edge_length**2, solver="cg",
                              _topology=m.topology if grid else None)
            x = s.solve(m.vertices[free])
            best = min(best, time.perf_counter() - t)
        return best, s.iterations, x
    finally:
        fairing.BLOCK_JACOBI_RATIO, fairing.GRID_BLOCK_JACOBI_RATIO = default


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=300)
    ap.add_argument("--noise", choices=_common.NOISES, default="zigzag")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    m = _common.noisy_grid(args.size, args.noise)
    free = detect(m, 0.0).free
    extent = np.ptp(m.vertices, axis=0).max()
    print(f"{args.size}×{args.size} grid, {int(free.sum())} free vertices")
    print("| ω (normalized) | plain CG: steps | CSR time (s) | grid diagonals time (s) "
          "| block-Jacobi CG: steps | time (s) | default picks |")
    print("|---:|---:|---:|---:|---:|---:|---|")
    m.topology.window_walk  # (topology and grid pattern outside the clock, as in a pipeline's later runs)
    for w in WEIGHTS:
        tp, sp_, xp = _run(m, free, w, np.inf, args.repeat)
        tg, sg, xg = _run(m, free, w, np.inf, args.repeat, grid=True)
        tb, sb, xb = _run(m, free, w, 0.0, args.repeat)
        assert sg == sp_ and np.abs(xp - xb).max() <= 1e-8 * extent and np.abs(xp - xg).max() <= 1e-8 * extent
        s = FairingSystem(m.vertices, m.topology.windows, free, w / m.mean_edge_length**2, solver="cg",
                          _topology=m.topology)
        blocks, precond, _ = s._cg_setup()
        pick = ("block-Jacobi" if precond is not None else
                "grid diagonals" if isinstance(blocks, DiagonalBlocks) else "plain CSR")
        print(f"| {w:g} | {sp_} | {tp:.3f} | {tg:.3f} | {sb} | {tb:.3f} | {pick} |", flush=True)


if __name__ == "__main__":
    main()
