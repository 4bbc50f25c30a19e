"""Planar panels: quadnodes ``planarize`` beside libigl's ``planarize_quad_mesh`` on the same meshes.

Backs the tables in docs/planarize.md and the README's planarization line.

Meshes: the four thesis examples E1–E4 (``quadnodes.surfaces.example``) with the
noise of ``quadnodes.report.THESIS_EXAMPLES`` (``perturb(clean, tangential=t,
normal=n, seed=7, fix="corners")``: 0.25/0.1 for E1–E3, 0.6/0.2 for E4), then
``fair(noisy, iterations=3)`` (default weight); and "F100", a 100×100 sample of a
free-form B-spline face, ``surfaces.wavy(10000, 10000, 400, waves_u=0.5,
waves_v=1.0)`` (bicubic, built by ``surfaces.from_points``), perturbed 0.25/0.1
and faired the same way. Every method starts from that faired mesh.

Rows
- input (faired): the faired mesh itself, for the "before" numbers;
- quadnodes, reference = clean mesh: ``planarize(faired, reference=clean)`` with
  every other setting at its default (tolerance 1e-3, corners fixed, Anderson 5,
  adaptive planarity weight); the reference is the clean sampled mesh (its quads
  split in two triangles);
- quadnodes, reference = face: the same with ``reference=`` the build123d face
  (sampled 4× finer inside ``planarize``; the sampling is part of the time);
- quadnodes, no reference: ``planarize(faired)`` — closeness to the input vertices;
- quadnodes Gauss–Newton: ``planarize(faired, reference=clean, method="gauss-newton")``
  — 10 local/global steps, then penalty Gauss–Newton steps along the vertex normals
  with a growing planarity weight (issue 15); the iterations column gives both counts
  and the factorizations;
- quadnodes Newton: ``planarize(faired, reference=clean, method="newton")`` —
  planarity as a hard constraint, Gauss–Newton/SQP steps (one KKT factorization
  each); on F100 only with ``--slow``. (The default ``method="auto"`` rows above
  fall back to Newton steps only where local/global misses the tolerance with
  at most 20,000 free vertices; the iterations column then says so);
- libigl default: ``igl.planarize_quad_mesh(V, F, 100, 0.005)`` (ShapeUp
  projection, planarity only, mean re-centred at the end, nothing held fixed);
- libigl at our tolerance: ``igl.planarize_quad_mesh(V, F, 1000, 1e-3)``.
  libigl's per-iteration cost grows with (number of quads × number of vertices)
  (it builds a selector matrix as wide as the mesh for every quad): about 2.7 s
  per iteration at 100×100, so this row runs on F100 only with ``--slow`` (up to
  1000 iterations: most of an hour). The default row stops after a few
  iterations there (~7 s) and always runs.

Columns
- planarity max / mean: ``quadnodes.flatness.diagonal_distance`` (distance between
  the diagonals over their mean length); the script checks on every row that it
  equals ``|igl.quad_planarity|`` (libigl's measure is the same number with a sign)
  and prints the largest difference under each table;
- to clean surface max / mean (h): ``quadnodes.metrics.distance_to_mesh`` from every
  vertex to the clean face sampled 4× finer (as ``quadnodes.report``), in mean edge
  lengths h of the clean mesh;
- moved max (h): largest vertex displacement from the faired input;
- zigzag mean: mean window deviation (thesis eq. 30) of all structure-line windows;
- iterations: quadnodes' local/global iterations (with the number of matrix
  factorizations, i.e. planarity-weight doublings + 1, and whether the tolerance was
  met); libigl does not report its count: "100 (cap)" when the result is still above
  its threshold, "≤ 100" when it stopped at the threshold;
- edge ratio min: the shortest edge relative to its length in the faired input;
  folded: quads convex in the faired input that are darts or bow-ties in the
  result (``quadnodes.flatness.nonconvex_panels``) — a sound result has none;
- CPU time: this process's CPU time during the call (the machine is shared: wall time
  grows with the load, CPU time much less);
- wall time: the planarization call only (mesh construction, noise, fairing, the
  mesh's structure lines and module imports excluded); peak MB: that row's subprocess peak resident memory (ru_maxrss) minus
  its resident memory just before the call.

quadnodes rows use ``shape="keep"`` (the default) unless ``--shape free`` is given
(the plain projection, as before issue 16).

``--shapes``: instead of the tables, every quadnodes row (E1–E4, and F100 without
``--quick``; the Newton row on F100 only with ``--slow``) with ``shape="free"``
and ``shape="keep"`` one after the other in one process, so both see the same
machine load, and whether the two results are bit-identical.

``--iteration``: instead of the tables, one local/global iteration (wall, CPU, set-up,
peak memory) on the F100 recipe at 100×100, and with ``--big`` at 1000×1000 (built
without the 4× finer sample; 1–6 min to build on 2 cores, so ``--cache`` keeps both meshes in
``out/bench-cache/`` and reuses them): see :func:`run_iteration`.
Above 20,000 free vertices the global step is conjugate gradients started from the
current positions instead of a factorization.

``--noise broadband``: every case's noise is independent Gaussian offsets of 0.2 mean edge lengths per
coordinate (corners kept) instead of ``perturb``'s zigzag, before the same ``fair()``: the inputs a scan gives.

Run:  python benchmarks/perf/bench_planarize.py [--quick] [--slow] [--shape keep|free] [--shapes] [--noise broadband]
      python benchmarks/perf/bench_planarize.py --iteration [--big] [--cache]
      (--quick: E1–E4 only, ~1.5 min; the default adds F100, ~3 min on 2 cores;
      --slow adds libigl at threshold 1e-3 and quadnodes Newton on F100)
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import _common  # noqa: E402

EXAMPLES = ("E1", "E2", "E3", "E4")
FREEFORM = "F100"
KINDS = ("input", "qn_mesh", "qn_face", "qn_none", "qn_gn", "qn_newton", "igl_default", "igl_tol")
LABELS = {
    "input": "input (faired)",
    "qn_mesh": "quadnodes, reference = clean mesh",
    "qn_face": "quadnodes, reference = face",
    "qn_none": "quadnodes, no reference",
    "qn_gn": "quadnodes Gauss–Newton, reference = clean mesh",
    "qn_newton": "quadnodes Newton, reference = clean mesh",
    "igl_default": "libigl, maxIter 100, threshold 5e-3 (default)",
    "igl_tol": "libigl, maxIter 1000, threshold 1e-3",
}



def _case(name: str, noise: str = "zigzag"):
    """(face, clean mesh, 4× finer sample of the face, faired noisy mesh) of one benchmark case
    (``_common.planarize_case``'s recipe)."""
    from quadnodes import surfaces

    face, clean, faired = _common.planarize_case(name, noise)
    rows, cols = clean.grid_shape
    fine = surfaces.sample(face, 4 * (rows - 1) + 1, 4 * (cols - 1) + 1)
    return face, clean, fine, faired


def run_row(name: str, kind: str, shape: str = "keep", noise: str = "zigzag") -> dict:
    import igl

    from quadnodes.metrics import distance_to_mesh
    from quadnodes.flatness import diagonal_distance
    from quadnodes.planarization import planarize
    from quadnodes.zigzag import window_deviation

    face, clean, fine, faired = _case(name, noise)
    import trimesh.triangles  # noqa: F401  (imported lazily by the closest-point search: keep it out of the time)

    _ = faired.topology.windows  # built before timing, like the input of a graph node (cached on the mesh)
    base = _common.rss_mb()
    t = time.perf_counter()
    cpu = time.process_time()
    iters = "—"
    if kind == "input":
        out = faired
    elif kind.startswith("qn_"):
        ref = {"qn_mesh": clean, "qn_face": face, "qn_none": None, "qn_newton": clean, "qn_gn": clean}[kind]
        method = {"qn_newton": "newton", "qn_gn": "gauss-newton"}.get(kind, "auto")
        out, rep = planarize(faired, reference=ref, method=method, shape=shape)
        met = "met" if rep.converged else "NOT met"
        if rep.method == "newton" and kind != "qn_newton":
            iters = f"{rep.iterations} + {rep.newton_steps} Newton ({met})"
        elif rep.method == "newton":
            iters = f"{rep.newton_steps} Newton steps ({met})"
        elif rep.method == "gauss-newton":
            iters = f"{rep.iterations} + {rep.newton_steps} Gauss–Newton ({rep.factorizations} fact., {met})"
        else:
            iters = f"{rep.iterations} ({rep.factorizations} fact., {met})"
    else:
        max_iter, thr = (100, 0.005) if kind == "igl_default" else (1000, 1e-3)
        v = igl.planarize_quad_mesh(faired.vertices, faired.faces, max_iter, thr)
        out = faired.with_vertices(np.ascontiguousarray(v, dtype=np.float64))
    wall = time.perf_counter() - t
    cpu = time.process_time() - cpu
    peak = max(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024 - base, 0.0)
    h = clean.mean_edge_length
    pl = diagonal_distance(out)
    pl_igl = np.abs(np.asarray(igl.quad_planarity(out.vertices, out.faces), dtype=np.float64).ravel())
    if kind.startswith("igl_"):
        iters = f"{max_iter} (cap)" if pl.max() >= thr else f"≤ {max_iter}"
    ds = distance_to_mesh(out.vertices, fine) / h
    moved = np.linalg.norm(out.vertices - faired.vertices, axis=1) / h
    zz = window_deviation(out.vertices, out.topology.windows)
    from quadnodes.flatness import nonconvex_panels

    e = faired.topology.edges
    ratio = (np.linalg.norm(out.vertices[e[:, 1]] - out.vertices[e[:, 0]], axis=1)
             / np.linalg.norm(faired.vertices[e[:, 1]] - faired.vertices[e[:, 0]], axis=1))
    folded = int((nonconvex_panels(out) & ~nonconvex_panels(faired)).sum())
    return {
        "edge_ratio_min": float(ratio.min()), "folded": folded,
        "planarity_max": float(pl.max()), "planarity_mean": float(pl.mean()),
        "igl_measure_diff": float(np.abs(pl - pl_igl).max()),
        "surface_max_h": float(ds.max()), "surface_mean_h": float(ds.mean()),
        "moved_max_h": float(moved.max()), "zigzag_mean": float(zz.mean()),
        "iterations": iters, "wall_s": None if kind == "input" else wall,
        "cpu_s": None if kind == "input" else cpu,
        "peak_mb": None if kind == "input" else peak,
        "size": f"{clean.grid_shape[0]}×{clean.grid_shape[1]}",
    }


def run_iteration(size: int, cache: bool = False) -> dict:
    """Local/global iterations on the F100 recipe at ``size × size``, reference = clean mesh.

    ``planarize(faired, reference=clean, method="local-global", adapt=False)`` with
    ``max_iterations`` 11 (100×100) or 3 (1000×1000). Every iteration ends with one call of
    ``quad_diagonal_distance`` (the stop test, in this and in earlier versions of the module),
    so the time between consecutive calls is one iteration: the median of those differences
    (wall and CPU) is reported; set-up is the time to the first call minus one iteration (matrices,
    the reference's search structure, the first factorization or CG set-up). Peak MB: this
    process's peak resident memory above its memory before the call.
    """
    import quadnodes.planarization as P

    clean, faired = _common.planarize_big_case(size, cache)
    _ = faired.topology.windows
    stamps: list[tuple[float, float]] = []
    measure = P.quad_diagonal_distance

    def stamped(*args, **kwargs):
        out = measure(*args, **kwargs)
        stamps.append((time.perf_counter(), time.process_time()))
        return out

    P.quad_diagonal_distance = stamped
    base = _common.rss_mb()
    t, c = time.perf_counter(), time.process_time()
    _, rep = P.planarize(faired, reference=clean, method="local-global", adapt=False,
                         max_iterations=11 if size <= 300 else 3)
    P.quad_diagonal_distance = measure
    st = np.array(stamps)
    step_wall, step_cpu = np.median(np.diff(st[:, 0])), np.median(np.diff(st[:, 1]))
    return {"size": f"{size}×{size}", "free": int(faired.n_vertices - rep.n_fixed), "iterations": len(stamps),
            "iteration_wall_s": float(step_wall), "iteration_cpu_s": float(step_cpu),
            "setup_wall_s": float(st[0, 0] - t - step_wall), "setup_cpu_s": float(st[0, 1] - c - step_cpu),
            "planarity_after": rep.planarity_max, "peak_mb": max(_common.peak_mb() - base, 0.0)}


def _iteration_table(sizes: list[int], cache: bool = False) -> None:
    print("| mesh | free vertices | global step | iterations | one iteration wall (s) | one iteration CPU (s) "
          "| set-up wall (s) | set-up CPU (s) | planarity after | peak MB |")
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|")
    for size in sizes:
        out = subprocess.run([sys.executable, __file__, "--iteration-row", str(size)] + (["--cache"] if cache else []),
                             capture_output=True, text=True, check=True)
        r = json.loads(out.stdout.strip().splitlines()[-1])
        solver = "SuperLU, factorized once" if r["free"] <= 20000 else "CG from the current positions"
        print(f"| F{size} ({r['size']}) | {r['free']} | {solver} | {r['iterations']} | {r['iteration_wall_s']:.3f} "
              f"| {r['iteration_cpu_s']:.3f} | {r['setup_wall_s']:.2f} | {r['setup_cpu_s']:.2f} "
              f"| {r['planarity_after']:.2e} | {r['peak_mb']:.0f} |", flush=True)


HEADER = ("| method | planarity max | planarity mean | to clean surface max (h) | to clean surface mean (h) "
          "| moved max (h) | zigzag mean | edge ratio min | folded | iterations | wall time (s) | CPU time (s) | peak MB |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="only E1–E4 (skip the 100×100 free-form surface)")
    ap.add_argument("--slow", action="store_true",
                    help="also run libigl at threshold 1e-3 on the 100×100 surface (up to an hour)")
    ap.add_argument("--shape", choices=("keep", "free"), default="keep",
                    help="planarize's shape setting for the quadnodes rows (default keep)")
    ap.add_argument("--shapes", action="store_true",
                    help="compare shape='free' and shape='keep' on every quadnodes row (one table)")
    ap.add_argument("--iteration", action="store_true",
                    help="instead of the tables: one local/global iteration on the F100 recipe at 100×100 and "
                         "(with --big) 1000×1000, wall and CPU time, peak memory")
    ap.add_argument("--big", action="store_true", help="with --iteration: add 1000×1000 (~6 min to build)")
    ap.add_argument("--cache", action="store_true",
                    help="with --iteration: keep the built inputs in out/bench-cache/ and reuse them")
    ap.add_argument("--noise", choices=_common.NOISES, default="zigzag",
                    help="the noise before fair(): perturb's zigzag (the tables' default) or broadband offsets of "
                         "0.2 h (the inputs a scan gives)")
    ap.add_argument("--row", nargs=2, help=argparse.SUPPRESS)
    ap.add_argument("--iteration-row", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.row:
        print(json.dumps(run_row(args.row[0], args.row[1], args.shape, args.noise)))
        return
    if args.iteration_row:
        print(json.dumps(run_iteration(args.iteration_row, args.cache)))
        return
    if args.iteration:
        _iteration_table([100] + ([1000] if args.big else []), args.cache)
        return
    cases = list(EXAMPLES) + ([] if args.quick else [FREEFORM])
    if args.shapes:
        _compare_shapes(cases, args.slow)
        return
    for name in cases:
        worst = 0.0
        lines = []
        for kind in KINDS:
            if name == FREEFORM and kind in ("igl_tol", "qn_newton") and not args.slow:
                continue
            out = subprocess.run([sys.executable, __file__, "--row", name, kind, "--shape", args.shape,
                                  "--noise", args.noise],
                                 capture_output=True, text=True, check=True)
            r = json.loads(out.stdout.strip().splitlines()[-1])
            worst = max(worst, r["igl_measure_diff"])
            wall = "—" if r["wall_s"] is None else f"{r['wall_s']:.2f}"
            cpu = "—" if r["cpu_s"] is None else f"{r['cpu_s']:.2f}"
            peak = "—" if r["peak_mb"] is None else f"{r['peak_mb']:.0f}"
            lines.append(f"| {LABELS[kind]} | {r['planarity_max']:.2e} | {r['planarity_mean']:.2e} "
                         f"| {r['surface_max_h']:.3f} | {r['surface_mean_h']:.3f} | {r['moved_max_h']:.3f} "
                         f"| {r['zigzag_mean']:.2e} | {r['edge_ratio_min']:.3f} | {r['folded']} "
                         f"| {r['iterations']} | {wall} | {cpu} | {peak} |")
            if len(lines) == 1:
                print(f"\n### {name} ({r['size']}, {args.noise} noise)\n\n{HEADER}\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|")
            print(lines[-1], flush=True)
        if name == FREEFORM and not args.slow:
            print("\n(libigl at threshold 1e-3 skipped on this mesh: run with --slow)")
        print(f"\nLargest |diagonal_distance − |igl.quad_planarity|| over these rows: {worst:.1e}", flush=True)


def _compare_shapes(cases: list[str], slow: bool) -> None:
    """One table: each quadnodes row with shape="free" (before issue 16) and shape="keep" (the default).

    Both runs of a row happen in one process on the same faired mesh (its structure lines built
    beforehand), free first; "same result" says whether the two meshes are bit-identical.
    """
    from quadnodes.planarization import planarize

    print("| mesh | method | planarity max free / keep | folded free / keep | edge ratio min free / keep "
          "| same result | returned by | wall time free / keep (s) |")
    print("|---|---|---|---|---|---|---|---|")
    for name in cases:
        face, clean, _, faired = _case(name)
        _ = faired.topology.windows
        for kind in ("qn_mesh", "qn_face", "qn_none", "qn_newton"):
            if name == FREEFORM and kind == "qn_newton" and not slow:
                continue
            ref = {"qn_mesh": clean, "qn_face": face, "qn_none": None, "qn_newton": clean}[kind]
            runs = []
            for shape in ("free", "keep"):
                t = time.perf_counter()
                out, rep = planarize(faired, reference=ref, method="newton" if kind == "qn_newton" else "auto",
                                     shape=shape)
                runs.append((out, rep, time.perf_counter() - t))
            (a, ra, ta), (b, rb, tb) = runs
            same = "yes" if np.array_equal(a.vertices, b.vertices) else "no"
            print(f"| {name} | {LABELS[kind].removeprefix('quadnodes').strip(', ')} "
                  f"| {ra.planarity_max:.2e} / {rb.planarity_max:.2e} | {len(ra.nonconvex)} / {len(rb.nonconvex)} "
                  f"| {ra.edge_length_ratio_min:.3f} / {rb.edge_length_ratio_min:.3f} | {same} "
                  f"| {ra.method} / {rb.method} | {ta:.2f} / {tb:.2f} |", flush=True)


if __name__ == "__main__":
    main()
