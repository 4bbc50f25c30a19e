"""How fast is quadnodes.surfaces.sample? A 1000 × 1000 grid, by evaluation path.

Backs the sampling table in docs/cad.md.

Each row runs in its own subprocess (so memory high-water marks do not mix):

- wall time: best of 3 runs (``time.perf_counter``), after a 3 × 3 warm-up call
  that loads the lazy imports;
- peak RSS: the process's ``resource.getrusage(RUSAGE_SELF).ru_maxrss`` after
  the first timed run minus its resident set size (``/proc/self/status``)
  just before it: what the call added to the process's high-water mark (it
  sees OCCT's C++ allocations too, but a page reused from earlier is not
  counted);
- tracemalloc: the peak of Python/NumPy allocations during one more run
  (``tracemalloc.get_traced_memory``); it does not see OCCT's allocations.

The per-point rows (``Face.position_at`` and the ``occt`` fallback) are timed on
200 × 200 points and extrapolated linearly to 10⁶ points; their memory columns
are for the 200 × 200 run as measured.

Run:  python benchmarks/perf/bench_sampling.py  (about a minute)
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import time
import tracemalloc

import numpy as np

N = 1000  # full grid
N_SLOW = 200  # grid for the per-point paths, extrapolated to N × N

ROWS = {
    "sample, B-spline path (wavy)": "bspline",
    "B-spline evaluation only, no mesh (wavy)": "bspline_eval",
    "QuadMesh construction alone (its input checks), same grid": "quadmesh",
    "sample, closed-form path (torus_patch)": "analytic",
    "scipy NdBSpline at 10⁶ scattered (u, v) (wavy)": "ndbspline",
    "sample, OCCT fallback (wavy, method='occt')": "occt",
    "Face.position_at loop (wavy)": "position_at",
}


def _rss_kib() -> int:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    return 0


def _job(kind: str):
    """Return (callable, number of points it evaluates)."""
    from quadnodes import surfaces

    wavy = surfaces.wavy()
    if kind == "bspline":
        return (lambda: surfaces.sample(wavy, N, N, method="bspline")), N * N
    if kind == "bspline_eval":
        surf = surfaces._geom_surface(wavy)
        s = np.linspace(0.0, 1.0, N)
        return (lambda: surfaces._eval_bspline(surf, s, s)), N * N
    if kind == "quadmesh":
        from quadnodes.mesh import QuadMesh, grid_faces

        pts = surfaces._eval_bspline(surfaces._geom_surface(wavy), np.linspace(0, 1, N), np.linspace(0, 1, N))
        faces = np.ascontiguousarray(grid_faces(N, N)[:, ::-1])
        return (lambda: QuadMesh(pts.reshape(-1, 3), faces, grid_shape=(N, N))), N * N
    if kind == "analytic":
        torus = surfaces.torus_patch()
        return (lambda: surfaces.sample(torus, N, N, method="analytic")), N * N
    if kind == "ndbspline":
        from scipy.interpolate import NdBSpline

        poles, weights, tu, tv, du, dv = surfaces._bspline_data(surfaces._geom_surface(wavy))
        assert weights is None
        spline = NdBSpline((tu, tv), poles, (du, dv))
        xi = np.random.default_rng(0).random((N * N, 2))
        return (lambda: spline(xi)), N * N
    if kind == "occt":
        return (lambda: surfaces.sample(wavy, N_SLOW, N_SLOW, method="occt")), N_SLOW * N_SLOW
    if kind == "position_at":
        s = np.linspace(0.0, 1.0, N_SLOW).tolist()
        return (lambda: np.array([[tuple(wavy.position_at(a, b)) for b in s] for a in s])), N_SLOW * N_SLOW
    raise ValueError(kind)


def run_row(kind: str) -> dict:
    from quadnodes import surfaces

    surfaces.sample(surfaces.wavy(), 3, 3)  # warm-up: lazy imports
    surfaces.sample(surfaces.torus_patch(), 3, 3)
    fn, points = _job(kind)
    times = []
    rss0 = _rss_kib()
    t0 = time.perf_counter()
    fn()
    times.append(time.perf_counter() - t0)
    rss_peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss0
    for _ in range(2):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    tracemalloc.start()
    fn()
    _, traced = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return {"points": points, "seconds": min(times), "rss_kib": rss_peak, "traced_bytes": traced}


def main() -> None:
    print(f"Sampling a {N} × {N} grid (10⁶ points); per-point paths timed on {N_SLOW} × {N_SLOW} and extrapolated.")
    print()
    print("| path | points timed | wall time, 10⁶ points | µs / point | peak RSS added | tracemalloc peak |")
    print("|---|---:|---:|---:|---:|---:|")
    for label, kind in ROWS.items():
        out = subprocess.run(
            [sys.executable, __file__, "--row", kind], capture_output=True, text=True, check=True
        )
        r = json.loads(out.stdout.strip().splitlines()[-1])
        per_point = r["seconds"] / r["points"]
        total = per_point * N * N
        extrap = " (extrapolated)" if r["points"] != N * N else ""
        print(
            f"| {label} | {r['points']:,} | {total:.3g} s{extrap} | {per_point * 1e6:.3g} "
            f"| {r['rss_kib'] / 1024:.0f} MiB | {r['traced_bytes'] / 2**20:.0f} MiB |"
        )
    print()
    print("Peak RSS added: ru_maxrss after the first timed call minus VmRSS before it, in a fresh subprocess.")
    print("tracemalloc peak: Python/NumPy allocations only (OCCT's C++ heap is not traced).")


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--row":
        print(json.dumps(run_row(sys.argv[2])))
    else:
        main()
