"""Grids with stiff spots: the line preconditioner against symmetric Gauss–Seidel, by the stiffness of the matrix.

Backs ``LINES_MIN_STIFFNESS`` in ``quadnodes/fairing.py`` and the table of docs/fairing.md "The line
preconditioner" (its session-19 paragraph, "stiff spots take the lines again"; issue 15: a solver that is fast on
any noise).

Under eq. 32's own edge lengths (``line_spacing="hold"``, the thesis's method) a window whose edges are much
shorter than the mean gets coefficients of 1/length³: where noise nearly collapses a stretch of a line, a few
unknowns' fairing diagonals are hundreds of times the median one (the "stiffness": the largest over the median,
``fairing._stiffness``). Point sweeps relax such a strongly coupled stretch slowly; the line preconditioner
(banded Cholesky along every row and column line, ``LinePreconditioner``) solves it whole.

Meshes: the bench sheet (``benchmarks/_common.py``, zigzag noise) with further broadband offsets of ``s`` mean edge
lengths per coordinate (``sheet:N:s``), and the bench torus with its broadband noise of 0.2 edge lengths
(``torus:N:0``, or more on top). fair()'s first-iteration system under ``line_spacing="hold"`` (every window middle
free but line gaps, fair's default weight 0.3, anchor = the noisy vertices), the compiled kernels loaded before
the clock, solved to fair's rtol 1e-9 by CG preconditioned by Gauss–Seidel, by the lines, and by "auto":
steps and seconds (set-up and solve, one run each, in one process), and the stiffness.

Run:  python benchmarks/studies/stiff_lines.py [sheet:300:0.1 sheet:300:0.2 ... torus:300:0]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import _common  # noqa: E402

DEFAULT = ["sheet:300:0.1", "sheet:300:0.2", "sheet:300:0.3", "sheet:300:0.4", "torus:300:0", "torus:300:0.1",
           "sheet:600:0.2", "sheet:600:0.3", "sheet:1000:0.2", "torus:1000:0"]


def mesh(kind: str, n: int, scale: float):  # type: ignore[no-untyped-def]
    """The sheet with zigzag noise or the torus with broadband noise, plus broadband offsets of ``scale`` h."""
    m = _common.noisy_grid(n, "zigzag") if kind == "sheet" else _common.noisy_torus(n, n)
    if scale:
        rng = np.random.default_rng(1)
        m = m.with_vertices(m.vertices + rng.normal(scale=scale * m.mean_edge_length, size=m.vertices.shape))
    return m


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("cases", nargs="*", default=DEFAULT, help="kind:size:extra-noise (kind sheet or torus)")
    args = ap.parse_args()
    from quadnodes.fairing import DEFAULT_WEIGHT, FairingSystem
    from quadnodes.linalg import compiled
    from quadnodes.zigzag import _window_geometry, detect, line_gaps

    compiled.wait()
    print("fair()'s first-iteration system, line_spacing=\"hold\", weight 0.3, kernels loaded; steps · seconds\n")
    print("| mesh | extra noise (h) | stiffness | Gauss–Seidel | lines | auto (its choice) |")
    print("|---|---:|---:|---:|---:|---|")
    for case in args.cases:
        kind, size, scale = case.split(":")
        m = mesh(kind, int(size), float(scale))
        t = m.topology
        hold = _window_geometry(m.vertices, t.windows, t.window_walk)[1]
        found = detect(m, 0.0)
        free = line_gaps(found.free, t.windows, found.fixed)
        weight = DEFAULT_WEIGHT / m.mean_edge_length**2
        cells, stiffness = [], 0.0
        for pre in ("gauss-seidel", "lines", "auto"):
            t0 = time.perf_counter()
            s = FairingSystem(m.vertices, t.windows, free, weight, solver="cg", preconditioner=pre,
                              _inverse_lengths=hold, _topology=t)
            s.solve(m.vertices[free])
            seconds = time.perf_counter() - t0
            cell = f"{s.iterations} · {seconds:.2f}"
            if pre == "auto":
                cell += f" ({type(s._cg[1]).__name__})"
                d = s.matrix.diagonal() - s.weight  # (fairing._stiffness's measure, on the free unknowns' rows)
                stiffness = float(d.max() / np.median(d))
            cells.append(cell)
        print(f"| {kind} {size}² | {float(scale):g} | {stiffness:.0f} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
