"""The additive line-block preconditioner in the solver: CG steps and time against the default, per noise and weight.

Backs the "line preconditioner" paragraph in docs/fairing.md "Speed" (issue 15, part 2).

On the bench_core sheet (``benchmarks/_common.py``) with every window-middle vertex free, builds the
one-iteration system as ``fair()`` does (grid diagonal storage) and solves it with
``FairingSystem(preconditioner="auto")`` (today's default: plain CG at these weights) and
``preconditioner="lines"`` (``quadnodes.linalg.cg.LinePreconditioner``: exact banded solves along every
row and every column, added), x, y and z together, rtol 1e-9. Prints steps, system + solve time and
the largest difference between the two, relative to the mesh's extent.

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

from quadnodes.fairing import FairingSystem  # noqa: E402
from quadnodes.zigzag import _window_geometry, detect  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=100)
    ap.add_argument("--weights", type=float, nargs="+", default=[0.3, 1.0])
    args = ap.parse_args()
    n = args.size
    print("| grid | noise | ω | default: steps | time (s) | lines: steps | time (s) | max difference / extent |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for noise in _common.NOISES:
        m = _common.noisy_grid(n, noise)
        t = m.topology
        free = detect(m, 0.0).free
        _, inverse = _window_geometry(m.vertices, t.windows, t.window_walk)
        for w in args.weights:
            row = []
            xs = []
            for pre in ("auto", "lines"):
                t0 = time.perf_counter()
                s = FairingSystem(m.vertices, t.windows, free, w / m.mean_edge_length**2, solver="cg",
                                  preconditioner=pre, _inverse_lengths=inverse, _topology=t)
                xs.append(s.solve(m.vertices[free]))
                row += [str(s.iterations), f"{time.perf_counter() - t0:.3f}"]
            diff = np.abs(xs[0] - xs[1]).max() / np.ptp(m.vertices, axis=0).max()
            print(f"| {n}×{n} | {noise} | {w:g} | {' | '.join(row)} | {diff:.1e} |", flush=True)


if __name__ == "__main__":
    main()
