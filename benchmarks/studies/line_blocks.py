"""The additive line-block preconditioner against plain CG: steps and time, per noise, weight and line spacing.

Backs the "line preconditioner" paragraph in docs/fairing.md "Speed" (issue 15, part 2; its table is session 8's,
when "auto" took the line solves where the Gershgorin bound exceeded 1000 ω — since session 10 it takes symmetric
Gauss–Seidel wherever the kernels are used, ``benchmarks/studies/gauss_seidel.py``).

On the bench_core sheet (``benchmarks/_common.py``) with every window-middle vertex free, builds the
one-iteration system as ``fair()`` does (grid diagonal storage), with eq. 32's own edge lengths
(``line_spacing="hold"``) and with fair's default (``"fair"``: each window's mean length), and solves it
with ``FairingSystem(preconditioner="none")`` (plain CG) and ``preconditioner="lines"``
(``quadnodes.linalg.cg.LinePreconditioner``: exact banded solves along every row and every column, added;
the compiled kernels, loaded before the clock), x, y and z together, rtol 1e-9. Prints steps, system +
solve time, what ``"auto"`` picks at this size (plain, lines or gauss-seidel), and the largest difference between the
two solutions relative to the mesh's extent.

Run:  python benchmarks/studies/line_blocks.py [--size 100] [--weights 0.3 1]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import _common  # noqa: E402

from quadnodes.fairing import FairingSystem, even_lengths  # noqa: E402
from quadnodes.zigzag import _window_geometry, detect  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=100)
    ap.add_argument("--weights", type=float, nargs="+", default=[0.3, 1.0])
    args = ap.parse_args()
    n = args.size
    print("| grid | noise | line_spacing | ω | plain: steps | time (s) | lines: steps | time (s) | auto picks | "
          "max difference / extent |")
    print("|---|---|---|---:|---:|---:|---:|---:|---|---:|")
    warm = _common.noisy_grid(20, "broadband")  # load the compiled kernels before any clock
    FairingSystem(warm.vertices, warm.topology.windows, detect(warm, 0.0).free, 1.0, solver="cg",
                  preconditioner="lines", _topology=warm.topology).solve(warm.vertices[detect(warm, 0.0).free])
    for noise in _common.NOISES:
        m = _common.noisy_grid(n, noise)
        t = m.topology
        free = detect(m, 0.0).free
        _, held = _window_geometry(m.vertices, t.windows, t.window_walk)
        for spacing, inverse in (("hold", held), ("fair", even_lengths(held))):
            for w in args.weights:
                row = []
                xs = []
                for pre in ("none", "lines", "auto"):
                    t0 = time.perf_counter()
                    s = FairingSystem(m.vertices, t.windows, free, w / m.mean_edge_length**2, solver="cg",
                                      preconditioner=pre, _inverse_lengths=inverse, _topology=t)
                    if pre == "auto":
                        s._cg_setup()
                        picks = "gauss-seidel" if getattr(s._cg[1], "eisenstat", False) else \
                            "plain" if s._cg[1] is None else "lines"
                        continue
                    xs.append(s.solve(m.vertices[free]))
                    row += [str(s.iterations), f"{time.perf_counter() - t0:.3f}"]
                diff = np.abs(xs[0] - xs[1]).max() / np.ptp(m.vertices, axis=0).max()
                print(f"| {n}×{n} | {noise} | {spacing} | {w:g} | {' | '.join(row)} | {picks} | {diff:.1e} |",
                      flush=True)

if __name__ == "__main__":
    main()
