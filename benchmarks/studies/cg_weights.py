"""Conjugate gradients across weights: plain CG (free-index CSR, and the grid's diagonal storage)
against block-Jacobi CG and the spectral preconditioner (exact lines, and cosine lines) on the same system.

Backs the tables in docs/fairing.md "Speed" (small weights: block-Jacobi preconditioning), "The spectral
preconditioner" (``fairing.SPECTRAL_MIN_WORK``) and "Exact lines" (exact against cosine lines:
``fairing.SPECTRAL_EXACT_CONTRAST``).

On an n×n grid (the bench_core surface, ``benchmarks/_common.py``; ``--noise zigzag`` — tangential 0.2 and normal 0.05 — or ``broadband``) with
every window-middle vertex free, builds the one-iteration system at normalized weights 0.001 … 10 and
solves it (x, y, z together, rtol 1e-9, from the anchor) three ways: plain CG on the free-index CSR
matrix (any mesh), plain CG on the 13 diagonals in the grid's numbering (complete vertex grids), and
block-Jacobi CG (``quadnodes.fairing.BLOCK_JACOBI_RATIO`` and ``GRID_BLOCK_JACOBI_RATIO``), and CG preconditioned by
``quadnodes.linalg.spectral.SpectralPreconditioner`` on the grid's diagonals, with its exact lines (the solver's) and
with cosine lines (``open_lines="cosine"``). Prints steps and the wall time of
system + solve (best of ``--repeat`` runs; SciPy's transforms imported before the clock, so the spectral
column leaves out their import, about 40 ms once per process), and which one the default rule picks for this
grid in a fresh process without the compiled kernels. Checks that the column the default picks is within 1e-8
of the mesh's extent of plain CG solved to rtol 1e-13, and notes any other column that is not. ``--spacing``
picks the window lengths: ``fair`` (fair's default ``line_spacing="fair"``, each window's mean length) or
``hold`` (eq. 32's own lengths); the header gives the stiffest unknown's fairing diagonal over the median's
(``fairing._stiffness``, against ``SPECTRAL_MAX_STIFFNESS``).

Run:  python benchmarks/studies/cg_weights.py [--size 300] [--noise zigzag|broadband] [--spacing fair|hold] [--repeat 3]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from quadnodes import fairing
from quadnodes.fairing import FairingSystem
from quadnodes.linalg import compiled as kernels
from quadnodes.linalg import spectral
from quadnodes.linalg.cg import DiagonalBlocks
from quadnodes.zigzag import _window_geometry, detect, line_gaps

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import _common  # noqa: E402

WEIGHTS = (0.001, 0.003, 0.01, 0.03, 0.1, 0.3, 1.0, 3.0, 10.0)


def _run(m, free, w, ratio, repeat, grid=False, inverse=None, preconditioner="auto", open_lines="exact"):
    default = fairing.BLOCK_JACOBI_RATIO, fairing.GRID_BLOCK_JACOBI_RATIO
    fairing.BLOCK_JACOBI_RATIO = fairing.GRID_BLOCK_JACOBI_RATIO = ratio
    made = fairing.spectral.SpectralPreconditioner
    fairing.spectral.SpectralPreconditioner = lambda *a, **kw: made(*a, **{**kw, "open_lines": open_lines})
    try:
        best, x, s = np.inf, None, None
        for _ in range(repeat):
            t = time.perf_counter()
            s = FairingSystem(m.vertices, m.topology.windows, free, w / m.mean_edge_length**2, solver="cg",
                              _topology=m.topology if grid else None, _inverse_lengths=inverse,
                              preconditioner=preconditioner)
            x = s.solve(m.vertices[free])
            best = min(best, time.perf_counter() - t)
        return best, s.iterations, x
    finally:
        fairing.BLOCK_JACOBI_RATIO, fairing.GRID_BLOCK_JACOBI_RATIO = default
        fairing.spectral.SpectralPreconditioner = made


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=300)
    ap.add_argument("--noise", choices=_common.NOISES, default="zigzag")
    ap.add_argument("--spacing", choices=("fair", "hold"), default="fair")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    import scipy.fft  # noqa: F401  (the transforms' import outside the clock, as in a pipeline's later runs)

    m = _common.noisy_grid(args.size, args.noise)
    zz = detect(m, 0.0)
    free = line_gaps(zz.free, m.topology.windows, zz.fixed)  # as fair() frees them (its default gaps="fair")
    extent = np.ptp(m.vertices, axis=0).max()
    t = m.topology
    inverse = _window_geometry(m.vertices, t.windows, t.window_walk, even=args.spacing == "fair")[
        -2 if args.spacing == "fair" else 1]
    probe = FairingSystem(m.vertices, t.windows, free, 0.3 / m.mean_edge_length**2, solver="cg", _topology=t,
                          _inverse_lengths=inverse)
    stiffness = fairing._stiffness(*probe._grid[0].normal_matrix(probe._grid[1], probe._grid[2], probe.weight),
                                   probe._grid[2], probe.weight)
    print(f"{args.size}×{args.size} grid, {args.noise} noise, line_spacing={args.spacing!r}, "
          f"{int(free.sum())} free vertices; stiffest diagonal / median {stiffness:.1f}; windows are scaled third "
          f"differences: {probe._third_differences}")
    print("| ω (normalized) | plain CG: steps | CSR time (s) | grid diagonals time (s) "
          "| block-Jacobi CG: steps | time (s) | spectral CG: steps | time (s) | cosine lines: steps | time (s) "
          "| default picks (fresh process) |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|")
    late: list[str] = []
    for w in WEIGHTS:
        tp, sp_, xp = _run(m, free, w, np.inf, args.repeat, inverse=inverse, preconditioner="none")
        tg, sg, xg = _run(m, free, w, np.inf, args.repeat, grid=True, inverse=inverse, preconditioner="none")
        tb, sb, xb = _run(m, free, w, 0.0, args.repeat, inverse=inverse)
        ts, ss, xs = _run(m, free, w, np.inf, args.repeat, grid=True, inverse=inverse, preconditioner="spectral")
        tc, sc, xc = _run(m, free, w, np.inf, args.repeat, grid=True, inverse=inverse, preconditioner="spectral",
                          open_lines="cosine")
        # each within 1e-8 of the extent of a reference solved to rtol 1e-13
        ref = FairingSystem(m.vertices, t.windows, free, w / m.mean_edge_length**2, solver="cg", _topology=t,
                            _inverse_lengths=inverse, preconditioner="none", rtol=1e-13).solve(m.vertices[free])
        errors = dict(zip(("plain CSR", "grid diagonals", "block-Jacobi", "spectral", "cosine lines"),
                          (np.abs(x - ref).max() / extent for x in (xp, xg, xb, xs, xc))))
        asked = []  # (the rule as in a fresh process: nothing loaded; the kernels' load only noted, not done)
        saved = (kernels.ready, kernels.wait, spectral.loaded)
        kernels.ready, spectral.loaded = (lambda: False), (lambda: False)
        kernels.wait = lambda: asked.append(1) or False
        try:
            s = FairingSystem(m.vertices, t.windows, free, w / m.mean_edge_length**2, solver="cg", _topology=t,
                              _inverse_lengths=inverse)
            blocks, precond, _ = s._cg_setup()
        finally:
            kernels.ready, kernels.wait, spectral.loaded = saved
        pick = (type(precond).__name__ if precond is not None else
                "grid diagonals" if isinstance(blocks, DiagonalBlocks) else "plain CSR")
        pick = {"BlockJacobi": "block-Jacobi", "SpectralPreconditioner": "spectral"}.get(pick, pick)
        if asked:  # a fresh process loads the compiled kernels here: Gauss–Seidel (or the two-grid cycle) where the
            # bound exceeds GAUSS_SEIDEL_CONTRAST ω, else plain CG on the compiled product
            pick = ("Gauss–Seidel (loads the kernels)" if s._contrast > fairing.GAUSS_SEIDEL_CONTRAST
                    else "plain CG (loads the kernels)")
        # the default's column keeps to 1e-8 of the extent; a column off the default may not (a residual of
        # rtol leaves more error where the preconditioner ends on smooth modes), noted below the table
        assert errors.get(pick, 0.0) <= 1e-8, (pick, errors)
        late += [f"ω = {w:g}: {k} ended {e:.1e} of the extent from the reference" for k, e in errors.items() if e > 1e-8]
        steps = str(sp_) if sg == sp_ else f"{sp_} (grid {sg})"  # (rounding: the two orders may differ by a step)
        print(f"| {w:g} | {steps} | {tp:.3f} | {tg:.3f} | {sb} | {tb:.3f} | {ss} | {ts:.3f} | {sc} | {tc:.3f} "
              f"| {pick} |", flush=True)
    for line in late:
        print(line)


if __name__ == "__main__":
    main()
