"""Why fair() assembles its own reduced system instead of handing the whole mesh's energy to QuadraticProblem.

Backs the note on ``FairingSystem`` in ../shared/DESIGN.md ("Style", example 2) and docs/design-notes.md
"Session 19" (issue 15, item 1).

Input: the bench sheet (``benchmarks/_common.py``) with broadband noise, every window middle free, fair's default
weight. Two set-ups of the same first-iteration system, each in a fresh process, timed with its peak memory
above the mesh's:

- ``fairing``: ``FairingSystem`` as fair() builds it — ``A``'s free columns straight from the windows (the fixed
  vertices' part moved to the right-hand side on the way), and the grid's diagonal storage with its
  preconditioner (``_cg_setup``): everything before the first CG step;
- ``quadratic``: what the generic route needs before :class:`~quadnodes.linalg.QuadraticProblem` can even choose
  its storage — ``A`` over all vertices, the whole mesh's ``Q = AᵀA + ωI``, and its unknowns' blocks ``Q_uu`` and
  ``Q_uk`` (no diagonal storage, no preconditioner yet).

Run:  python benchmarks/studies/quadratic_route.py [--size 1000]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import _common  # noqa: E402


def one(size: int, route: str) -> dict:
    from quadnodes.fairing import DEFAULT_WEIGHT, FairingSystem, window_coefficients
    from quadnodes.zigzag import detect

    m = _common.noisy_grid(size, "broadband")
    t = m.topology
    windows = t.windows
    free = detect(m, 0.0).free
    weight = DEFAULT_WEIGHT / m.mean_edge_length**2
    base = _common.rss_mb()
    t0 = time.perf_counter()
    if route == "fairing":
        s = FairingSystem(m.vertices, windows, free, weight, solver="cg", _topology=t)
        s._cg_setup()
    else:
        coef = window_coefficients(m.vertices, windows)  # (fairing_matrix's A, built without its COO sort)
        A = sp.csr_matrix((coef.reshape(-1), windows.reshape(-1), np.arange(0, 4 * len(windows) + 1, 4)),
                          shape=(len(windows), m.n_vertices))
        Q = (A.T.tocsr() @ A + weight * sp.identity(m.n_vertices, format="csr")).tocsr()
        unknown = np.flatnonzero(free)
        rows = Q[unknown]
        rows[:, unknown].tocsr(), rows[:, ~free].tocsr()
    return {"seconds": time.perf_counter() - t0, "peak_mb": _common.peak_mb() - base}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=1000)
    ap.add_argument("--route", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.route:
        print(json.dumps(one(args.size, args.route)))
        return
    print(f"{args.size}×{args.size} sheet, broadband noise, fair's first-iteration system; fresh processes\n")
    print("| route | set-up (s) | peak memory above the mesh (MB) |")
    print("|---|---:|---:|")
    for route in ("fairing", "quadratic"):
        out = subprocess.run([sys.executable, __file__, "--size", str(args.size), "--route", route],
                             capture_output=True, text=True, check=True).stdout
        r = json.loads(out.strip().splitlines()[-1])
        print(f"| {route} | {r['seconds']:.2f} | {r['peak_mb']:.0f} |", flush=True)


if __name__ == "__main__":
    main()
