"""Fairing with NumPy's transparent huge pages on, or off inside the solver (the default since session 23).

Backs docs/linalg.md "Memory: the heap reused, in small pages" and the sentence in ``quadnodes/linalg/heap.py``.
NumPy asks the kernel for transparent huge pages (``madvise(MADV_HUGEPAGE)``) on every array of 4 MB or more;
:func:`quadnodes.linalg.heap.reused_heap` — which ``fair()`` enters on meshes of 10,000 vertices or more — switches
that off while it lasts and serves large blocks from a reused heap. A user who sets ``NUMPY_MADVISE_HUGEPAGE`` keeps
their choice, so ``NUMPY_MADVISE_HUGEPAGE=1`` in a process's environment gives the behaviour before the change.

For each mesh it runs ``fair(iterations=1, threshold=0)`` (broadband noise, ``_common``'s meshes) in ``--repeat``
fresh processes of each kind, in turn: as shipped, and with ``NUMPY_MADVISE_HUGEPAGE=1``; the kernels loaded
before the clock starts. Prints the median wall time (the range), the median CG time inside it and the peak
resident memory above the mesh, with the machine's THP settings.

Run:  python benchmarks/studies/huge_pages.py [--sizes 300 1000] [--meshes sheet torus cylinder] [--repeat 5]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import _common  # noqa: E402

MESHES = ("sheet", "torus", "cylinder", "cube-sphere")


def _mesh(kind: str, n: int):
    if kind == "sheet":
        return _common.noisy_grid(n, "broadband")
    if kind == "torus":
        return _common.noisy_torus(n, n)
    if kind == "cylinder":
        return _common.noisy_cylinder(n, n)
    return _common.noisy_cube_sphere(max(2, round((n * n / 6) ** 0.5)))


def _row(kind: str, n: int) -> dict:
    import quadnodes.fairing as F
    from quadnodes.linalg import compiled

    mesh = _mesh(kind, n)
    compiled.wait()
    spent = {"cg": 0.0}
    block_cg = F.block_cg

    def timed(*args, **kwargs):
        t = time.perf_counter()
        try:
            return block_cg(*args, **kwargs)
        finally:
            spent["cg"] += time.perf_counter() - t

    F.block_cg = timed
    base = _common.rss_mb()
    t = time.perf_counter()
    _, rep = F.fair(mesh, iterations=1, threshold=0.0)
    return {"wall_s": time.perf_counter() - t, "cg_s": spent["cg"], "steps": rep.iterations[0].cg_iterations,
            "peak_mb": max(_common.peak_mb() - base, 0.0), "vertices": mesh.n_vertices}


def _thp() -> str:
    out = []
    for name in ("enabled", "defrag"):
        try:
            out.append(f"{name}: {Path('/sys/kernel/mm/transparent_hugepage', name).read_text().strip()}")
        except OSError:
            out.append(f"{name}: (not readable)")
    return "; ".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[300, 1000])
    ap.add_argument("--meshes", nargs="+", choices=MESHES, default=["sheet", "torus", "cylinder"])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--row", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.row:
        print(json.dumps(_row(args.row[0], int(args.row[1]))))
        return
    env = {k: v for k, v in os.environ.items() if k != "NUMPY_MADVISE_HUGEPAGE"}
    kinds = (("small pages inside fair (as shipped)", env), ("huge pages (NUMPY_MADVISE_HUGEPAGE=1)",
                                                              dict(env, NUMPY_MADVISE_HUGEPAGE="1")))
    print(f"Transparent huge pages: {_thp()}\n")
    print("| mesh | vertices | NumPy's pages | fair, 1 iteration (s), median (range) | CG inside it (s) | CG steps "
          "| peak MB above the mesh |")
    print("|---|---:|---|---:|---:|---:|---:|")
    for n in args.sizes:
        for kind in args.meshes:
            runs: list[list[dict]] = [[], []]
            for _ in range(max(1, args.repeat)):
                for side, (_, e) in enumerate(kinds):
                    out = subprocess.run([sys.executable, __file__, "--row", kind, str(n)], capture_output=True,
                                         text=True, check=True, env=e)
                    runs[side].append(json.loads(out.stdout.strip().splitlines()[-1]))
            for (label, _), side in zip(kinds, runs):
                walls = sorted(r["wall_s"] for r in side)
                med = side[[r["wall_s"] for r in side].index(walls[len(walls) // 2])]
                name = kind if kind == "cube-sphere" else f"{kind} {n}×{n}"
                print(f"| {name} | {med['vertices']:,} | {label} | {med['wall_s']:.3f}{_common.spread(walls)} "
                      f"| {med['cg_s']:.3f} | {med['steps']} | {med['peak_mb']:.0f} |", flush=True)


if __name__ == "__main__":
    main()
