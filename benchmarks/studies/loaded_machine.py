"""Fairing timings on a loaded machine: BLAS held to one thread inside the solver, or not.

Backs docs/linalg.md "Conjugate gradients and their preconditioners" (issue 15, part 4: timings that stay steady on
a loaded machine). The solver holds BLAS (OpenBLAS here) to one thread for every solve
(:func:`quadnodes.linalg.threads.blas_pinned`, ``threadpoolctl``); without that, OpenBLAS's own threads spin beside
the solver's pool and beside whatever else runs, and a fairing's time swings by orders of magnitude.

For each ``--sizes`` it runs ``fair(iterations=1, threshold=0)`` on the bench sheet with broadband noise
(``_common.noisy_grid``) in ``--repeat`` fresh processes, quiet and then under load (``--load`` busy-looping Python
processes, one per core by default, started before and stopped after the rows), each with BLAS pinned (the
solver as shipped) and unpinned (``blas_pinned`` and CHOLMOD's own limit replaced by no-ops in that process, so
BLAS keeps its default threads), the two in turn after one warm-up process. Prints each row's wall times: the median, the range, and the spread (largest over smallest).

Run:  python benchmarks/studies/loaded_machine.py [--sizes 100 300] [--repeat 7] [--load 2]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import _common  # noqa: E402


def _row(n: int, pinned: bool) -> dict:
    import quadnodes.linalg.cg as cg
    import quadnodes.linalg.direct as direct
    import quadnodes.linalg.threads as threads
    from quadnodes.fairing import fair
    from quadnodes.mesh import QuadMesh

    if not pinned:  # (every module that took the name, the one the others read it from, and CHOLMOD's own limit)
        for module in (threads, cg, direct):
            module.blas_pinned = contextlib.nullcontext
        direct._one_thread = contextlib.nullcontext
    noisy = _common.noisy_grid(n, "broadband")
    m = QuadMesh(noisy.vertices, noisy.faces)
    t = time.perf_counter()
    _, rep = fair(m, iterations=1, threshold=0.0)
    return {"wall_s": time.perf_counter() - t, "steps": rep.iterations[0].cg_iterations}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 300])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--load", type=int, default=os.cpu_count() or 2, help="busy processes of the loaded rows")
    ap.add_argument("--row", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.row:
        print(json.dumps(_row(int(args.row[0]), args.row[1] == "pinned")))
        return

    def one(n: int, mode: str) -> dict:
        out = subprocess.run([sys.executable, __file__, "--row", str(n), mode], capture_output=True, text=True,
                             check=True)
        return json.loads(out.stdout.strip().splitlines()[-1])

    def runs(n: int) -> dict[str, tuple[list[float], int]]:  # (the two modes in turn: no order between them)
        one(n, "pinned")  # (a warm-up process: the first of a run is slow, whatever it runs)
        got: dict[str, tuple[list[float], int]] = {"pinned": ([], 0), "unpinned": ([], 0)}
        for i in range(args.repeat):
            for mode in (("pinned", "unpinned") if i % 2 == 0 else ("unpinned", "pinned")):
                r = one(n, mode)
                got[mode] = (got[mode][0] + [r["wall_s"]], r["steps"])
        return got

    print(f"fair(iterations=1, threshold=0), bench sheet with broadband noise; {args.repeat} fresh processes a row; "
          f"load: {args.load} busy processes on {os.cpu_count()} cores\n")
    print("| mesh | machine | BLAS | CG steps | wall (s), median | range | largest / smallest |")
    print("|---|---|---|---:|---:|---|---:|")
    for loaded in (False, True):
        hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(args.load if loaded else 0)]
        try:
            time.sleep(1.0 if loaded else 0.0)
            for n in args.sizes:
                got = runs(n)
                for mode in ("pinned", "unpinned"):
                    walls, steps = got[mode]
                    w = np.array(walls)
                    print(f"| {n}×{n} | {'loaded' if loaded else 'quiet'} | "
                          f"{'one thread (as shipped)' if mode == 'pinned' else 'its own threads'} | {steps} | "
                          f"{np.median(w):.3f} | {w.min():.3f}–{w.max():.3f} | {w.max() / w.min():.1f} |", flush=True)
        finally:
            for h in hogs:
                h.kill()
                h.wait()


if __name__ == "__main__":
    main()
