"""Speed of the thesis's chapter-2/3 methods beside the thesis's own method (issue 17).

Backs docs/methods.md "Speed" and its sub-tables.

Input (every row but Fourier): the noisy height field of ``bench_core.py`` — an
n × n grid over the unit square, z = 0.3 sin(3x) cos(2y), with seeded noise on every vertex, the boundary too:
``--noise zigzag`` (the default: ``perturb(tangential=0.2, normal=0.05, seed=0)[0]``, the highest frequency)
or ``--noise broadband`` (independent Gaussian offsets of 0.2 edge lengths per coordinate, as a scan
has: ``_common.noisy_grid``'s; on the cylinder 0.2 of its mean edge length). Fourier descriptors need closed lines, so their row runs on an
open cylinder of n rings × n vertices (radius 1, height 1) with the same noise. The table's first line names it.

Rows (settings as named; each in a fresh process, modules imported before the clock):

- ``fair``: the thesis's method, ``fair(iterations=3)`` (defaults), the reference;
- ``fair_web``: E2 of the structure-line network, boundary fixed, no cylinders (one sparse solve);
- ``fair_web_newton`` / ``fair_web_admm`` / ``fair_web_pg``: the same (``--energy``, ``--closeness``) with
  tolerance cylinders and the corners fixed, by the semismooth Newton method (the default; cap 100 steps),
  ADMM or accelerated projected gradient (cap ``--web-cap``, 1,000), to a KKT residual of 1e-5 h (the
  default). ``--cylinders``: ``bench`` radius 0.5 h, half-height 0.2 h (the default); ``small`` 0.1 h /
  0.05 h; ``large`` 2 h / 1 h; ``mixed`` 0.5 h / 0.2 h times a seeded random 0.1, 1 or 10 per vertex.
  The note says converged or not, the process's CPU time (on a loaded machine a steadier measure than the
  wall time), the KKT residual reached, Newton steps after the ADMM warm start (or the contact method's
  working set and rounds, see ``docs/methods.md``), and
  how far the final exact projection moved any vertex; with ``--distance`` also how far the result is from a
  Newton run to 1e-9 h (outside the clock);
- ``spring``: Yamada's spring model, boundary fixed, to tolerance 1e-4 or ``--cap`` iterations;
- ``schneider_kobbelt``: boundary + one ring fixed, to tolerance 1e-4 or ``--cap`` iterations;
- ``curvature``: every field of ``quadnodes.curvature`` once;
- ``fourier``: Fourier descriptors on the cylinder, harmonics 0–3.

``--linalg`` picks the sparse direct back-end of every factorization (``quadnodes.linalg.factorize``):
``auto`` (the default: CHOLMOD when scikit-sparse is importable, nested dissection from 20,000 unknowns),
``superlu`` (SuperLU in the same orders — the default install without scikit-sparse) or ``superlu-md``
(SuperLU in minimum-degree order everywhere: the back-end before nested dissection, to compare in one run).
Every note starts with the process's CPU time for the row.

"per iteration" is the wall time over the iterations the method reports (ADMM /
gradient steps, spring or Schneider–Kobbelt iterations; ``fair``: its 3 outer
iterations). "peak MB": the process's peak resident memory minus its resident
memory after the mesh was built (as in ``bench_core.py``).

Run:  python benchmarks/perf/bench_methods.py [--sizes 100 300] [--only spring fair ...] [--cap 200]
          [--cylinders bench|small|mixed|large] [--energy E2] [--closeness 0] [--web-cap 1000]
          [--linalg auto|superlu|superlu-md] [--noise zigzag|broadband]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import _common  # noqa: E402

ROWS = ("fair", "fair_web", "fair_web_newton", "fair_web_admm", "fair_web_pg",
        "spring", "schneider_kobbelt", "curvature", "fourier")


def _mesh(kind: str, n: int, noise: str = "zigzag"):
    from quadnodes.mesh import QuadMesh, cylinder, grid
    from quadnodes.noise import perturb

    if kind == "fourier":
        base = cylinder(n, n)
    else:
        y, x = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n), indexing="ij")
        base = grid(n, n, spacing=1.0 / (n - 1), height=0.3 * np.sin(3 * x) * np.cos(2 * y))
    if noise == "broadband" and kind != "fourier":
        noisy = _common.noisy_grid(n, "broadband")
    elif noise == "broadband":  # (the cylinder: 0.2 of its mean edge length)
        rng = np.random.default_rng(0)
        noisy = base.with_vertices(base.vertices + rng.normal(scale=0.2 * base.mean_edge_length,
                                                              size=base.vertices.shape))
    else:
        noisy, _ = perturb(base, tangential=0.2, normal=0.05, seed=0)
    return QuadMesh(noisy.vertices, noisy.faces)  # fresh: no cached topology


#: Cylinder sizes of ``--cylinders`` (radius, half-height) in mean edge lengths h.
CYLINDERS = {"bench": (0.5, 0.2), "small": (0.1, 0.05), "large": (2.0, 1.0), "mixed": (0.5, 0.2)}


def _backend(linalg: str) -> None:
    """Hold every factorization of this process to the back-end ``--linalg`` names."""
    import quadnodes.linalg.direct as direct
    import quadnodes.webs as webs

    if linalg in ("superlu", "superlu-md"):
        direct._cholmod = lambda: None  # as if scikit-sparse were not installed
    if linalg == "superlu-md":
        direct.NESTED_DISSECTION_MIN = webs.NESTED_DISSECTION_MIN = 1 << 62


def run_row(kind: str, n: int, cap: int, web: dict | None = None) -> dict:
    import quadnodes as qn

    _backend((web or {}).get("linalg", "auto"))
    m = _mesh(kind, n, (web or {}).get("noise", "zigzag"))
    h = m.mean_edge_length
    base = _common.rss_mb()
    t = time.perf_counter()
    cpu0 = time.process_time()
    if kind == "fair":
        _, rep = qn.fair(m, iterations=3)
        its, note = 3, f"{max(r.n_free for r in rep.iterations)} free"
    elif kind == "fair_web":
        _, rep = qn.fair_web(m)
        its, note = 1, "one sparse solve"
    elif kind in ("fair_web_newton", "fair_web_admm", "fair_web_pg"):
        web = web or {}
        solver = {"fair_web_newton": "newton", "fair_web_admm": "admm", "fair_web_pg": "projected_gradient"}[kind]
        fr, fh = CYLINDERS[web.get("cylinders", "bench")]
        radius, height = fr * h, fh * h
        if web.get("cylinders") == "mixed":
            rng = np.random.default_rng(1)
            radius = radius * rng.choice([0.1, 1.0, 10.0], m.n_vertices)
            height = height * rng.choice([0.1, 1.0, 10.0], m.n_vertices)
        settings = dict(fix="corners", energy=web.get("energy", "E2"), closeness=web.get("closeness", 0.0),
                        cylinder_radius=radius, cylinder_height=height)
        cpu = time.process_time()
        out, rep = qn.fair_web(m, **settings, solver=solver,
                               max_iterations=100 if solver == "newton" else web.get("cap", 1000))
        wall_web, cpu = time.perf_counter() - t, time.process_time() - cpu
        its = rep.iterations
        note = (f"{'converged' if rep.converged else 'NOT converged'}, CPU {cpu:.1f} s, "
                f"KKT {rep.kkt_residual:.1e} h, "
                f"{rep.n_on_cylinder} on cylinder, projection moved {rep.projection_move / h:.0e} h")
        if solver == "newton" and rep.contact_vertices:
            note += f", contact method: {rep.contact_vertices} vertices, {rep.contact_rounds} rounds"
        elif solver == "newton":
            note += f", after {rep.warm_start_iterations} ADMM"
            if getattr(rep, "factorizations", None) is not None:  # (a library before them does not report them)
                note += f", {rep.factorizations} factorizations"
        if web.get("distance"):  # outside the clock: the distance to a tightly converged reference
            ref, _ = qn.fair_web(m, **settings, solver="newton", tolerance=1e-9, max_iterations=200)
            note += f", {np.abs(out.vertices - ref.vertices).max() / h:.1e} h from the 1e-9 h Newton reference"
    elif kind == "spring":
        _, rep = qn.spring(m, max_iterations=cap)
        its, note = rep.iterations, "converged" if rep.converged else f"cap {cap}, last move {rep.max_displacement:.1e} h"
    elif kind == "schneider_kobbelt":
        _, rep = qn.schneider_kobbelt(m, max_iterations=cap)
        its, note = rep.iterations, "converged" if rep.converged else f"cap {cap}, last move {rep.max_displacement:.1e} h"
    elif kind == "curvature":
        qn.curvature(m)
        its, note = 1, ""
    elif kind == "fourier":
        _, rep = qn.fourier(m, keep=3)
        its, note = 1, f"{rep.closed_lines} closed lines"
    else:
        raise SystemExit(f"unknown row {kind!r}")
    wall = time.perf_counter() - t if not kind.startswith("fair_web_") else wall_web
    peak = _common.peak_mb() - base
    if not kind.startswith("fair_web_"):
        note = f"CPU {time.process_time() - cpu0:.1f} s" + (f", {note}" if note else "")
    return {"row": kind, "n": n, "wall_s": wall, "iterations": int(its), "per_iteration_s": wall / max(its, 1),
            "peak_mb": peak, "note": note}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", nargs="+", type=int, default=[100, 300])
    ap.add_argument("--only", nargs="+", choices=ROWS, default=list(ROWS))
    ap.add_argument("--cap", type=int, default=200,
                    help="iteration cap of spring and Schneider-Kobbelt (x25 for the cylinder solvers)")
    ap.add_argument("--cylinders", choices=sorted(CYLINDERS), default="bench", help="cylinder sizes of fair_web_*")
    ap.add_argument("--energy", choices=("E1", "E2", "tension"), default="E2", help="energy of fair_web_*")
    ap.add_argument("--closeness", type=float, default=0.0, help="closeness of fair_web_*")
    ap.add_argument("--web-cap", type=int, default=1000, help="iteration cap of fair_web_admm / fair_web_pg")
    ap.add_argument("--distance", action="store_true",
                    help="fair_web_*: also the largest distance to a Newton run to 1e-9 h (not timed)")
    ap.add_argument("--linalg", choices=("auto", "superlu", "superlu-md"), default="auto",
                    help="sparse direct back-end: auto (CHOLMOD if importable), superlu, superlu-md (minimum degree)")
    ap.add_argument("--noise", choices=("zigzag", "broadband"), default="zigzag",
                    help="the input's noise (see above; the table's first line names it)")
    ap.add_argument("--child", nargs=4, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(json.dumps(run_row(args.child[0], int(args.child[1]), int(args.child[2]), json.loads(args.child[3]))))
        return
    web = {"cylinders": args.cylinders, "energy": args.energy, "closeness": args.closeness, "cap": args.web_cap,
           "distance": args.distance, "linalg": args.linalg, "noise": args.noise}
    if any(k.startswith("fair_web_") for k in args.only):
        print(f"fair_web_*: {args.energy}, closeness {args.closeness}, cylinders {args.cylinders}, corners fixed")
    print(f"noise: {args.noise}; linalg: {args.linalg}")
    print(f"{'method':<20} {'n':>5} {'to convergence':>15} {'iterations':>10} {'per iteration':>14} "
          f"{'peak MB':>8}  note")
    for n in args.sizes:
        for kind in args.only:
            out = subprocess.run([sys.executable, __file__, "--child", kind, str(n), str(args.cap), json.dumps(web)],
                                 capture_output=True, text=True, check=True)
            r = json.loads(out.stdout.strip().splitlines()[-1])
            print(f"{kind:<20} {f'{n}²':>5} {r['wall_s']:>13.3f} s {r['iterations']:>10} "
                  f"{1000 * r['per_iteration_s']:>11.2f} ms {r['peak_mb']:>8.0f}  {r['note']}", flush=True)


if __name__ == "__main__":
    main()
