"""Core benchmark: fairing and Taubin smoothing on square grids, beside trimesh.

Backs the table in docs/fairing.md "Speed: a million vertices" and the README's Benchmarks section.
Every fairing row states its noise: ``zigzag`` (``perturb(tangential=0.2, normal=0.05)``, the
highest frequency, the easiest case for CG) or ``broadband`` (independent Gaussian offsets of
0.2 edge lengths per coordinate, as a scan has); the sheet is ``z = 0.3 sin 3x cos 2y``
(``benchmarks/_common.py``). ``--torus`` adds a closed torus of about n² vertices with broadband
noise (a torus grid: periodic grid diagonals); ``--cylinder`` an n × n cylinder (a tower: rows closed, columns
open) with the same noise; ``--cube-sphere`` a cube-sphere of about n² vertices
(six k × k grids on a sphere, eight valence-3 corners: no grid of any kind, the general CSR path)
with the same noise; ``--graded`` the sheet sampled with uneven spacing (its columns' spacing growing tenfold
across it, ``_common.noisy_graded``) with broadband noise of 0.2 local edge lengths.

Every row runs in fresh subprocesses (``--repeat``, default 3) and the table shows
the median run's wall time (the range in brackets) and memory: "peak MB" is that
process's peak resident memory (ru_maxrss) minus the resident memory right after
the mesh was built and the modules imported — the cost of the operation itself,
not of Python and its imports.

Rows
- structure lines: ``structure_lines`` + ``windows`` on a fresh mesh;
- fair, 1 iteration: ``quadnodes.fair(iterations=1, threshold=0)`` with every
  window-middle vertex free (all but the four corners), default solver (block
  conjugate gradients from the anchor); includes structure lines, detection,
  assembly and solve; the note gives CG steps and the relative residual;
- fair, line_spacing="hold": the same with eq. 32's own edge lengths (the thesis); on broadband
  noise its matrix may have stiff spots (a stretch of a line nearly collapsed), where a grid takes the line
  preconditioner (``fairing.LINES_MIN_STIFFNESS``);
- peers on the default's system (``line_spacing="fair"``; assembly excluded): SciPy SuperLU with its default
  ordering and with MMD(AᵀA+A), quadnodes' own CG with ``preconditioner="none"`` (what the
  default does where the matrix has no stiff spots), and CG preconditioned by pyamg smoothed
  aggregation when pyamg is installed, CHOLMOD when scikit-sparse is (``pip install -e .[bench]``). SuperLU at 1000² takes minutes and
  ~12 GB, and on the torus, the cylinder and the cube-sphere above 100² minutes too, so those rows run only with ``--slow``;
- taubin, 10 steps: ``quadnodes.taubin(iterations=5)`` (5 λ|μ pairs = 10 steps) on the
  quad edge 1-ring, including building the operator;
- trimesh filter_taubin, 10 steps: ``trimesh.smoothing.filter_taubin(iterations=10)``
  (trimesh counts single steps) on the triangulated grid, including its operator.

Run:  python benchmarks/perf/bench_core.py [--sizes 100 300 1000] [--noise zigzag broadband]
            [--only fair taubin ...] [--repeat 3] [--torus] [--cylinder] [--cube-sphere] [--graded] [--warm] [--weight W]
            [--against PATH]
"""

from __future__ import annotations

import argparse
import json
import os
import importlib
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import _common  # noqa: E402


def _mesh(n: int, noise: str = "zigzag"):
    if noise == "torus":
        return _common.noisy_torus(n, n)
    if noise == "cube-sphere":
        return _common.noisy_cube_sphere(max(2, round(n / 6**0.5)))
    if noise == "cylinder":
        return _common.noisy_cylinder(n, n)
    if noise == "graded":
        return _common.noisy_graded(n, 10.0)
    return _common.noisy_grid(n, noise)


def run_row(kind: str, n: int, noise: str = "zigzag") -> dict:
    from quadnodes.mesh import QuadMesh

    noisy = _mesh(n, noise)
    m = QuadMesh(noisy.vertices, noisy.faces)  # fresh: no cached topology
    if kind == "trimesh":
        import trimesh
        import trimesh.smoothing

        f = m.faces
        tm = trimesh.Trimesh(m.vertices.copy(), np.concatenate([f[:, [0, 1, 2]], f[:, [0, 2, 3]]]), process=False)
    # the row's own module is loaded before the clock starts, and only it: a pipeline that re-runs has it. (Loading
    # more would load more of SciPy before the clock: quadnodes.smoothing imports scipy.optimize and with it
    # scipy.fft, which fair's spectral preconditioner otherwise imports inside the clock, as a fresh script does.)
    if os.environ.get("QUADNODES_BENCH_WARM"):  # --warm: the compiled kernels too, as a server or watch has them
        from quadnodes.linalg import compiled

        compiled.wait()
    if kind in ("fair", "fair_hold"):
        from quadnodes.fairing import fair
    elif kind == "taubin":
        from quadnodes.smoothing import taubin
    elif kind == "lines":
        from quadnodes.topology import windows

    base = _common.rss_mb()
    t = time.perf_counter()
    extra = ""
    if kind == "lines":
        w = windows(m.topology.structure_lines)
        extra = f"{len(w)} windows"
    elif kind in ("fair", "fair_hold"):
        weight = {"weight": float(os.environ["QUADNODES_BENCH_WEIGHT"])} if os.environ.get("QUADNODES_BENCH_WEIGHT") else {}
        _, rep = fair(m, iterations=1, threshold=0.0, line_spacing="hold" if kind == "fair_hold" else "fair", **weight)
        r = rep.iterations[0]
        extra = f"{r.n_free} free, {r.solver} {r.cg_iterations} steps, residual {r.residual:.0e}"
    elif kind in ("superlu", "superlu_mmd", "pyamg", "plain", "cholmod"):
        wall, extra = _peer(kind, m)
        return {"wall_s": wall, "peak_mb": _common.peak_mb() - base,
                "note": extra}
    elif kind == "taubin":
        taubin(m, iterations=5)
    elif kind == "trimesh":
        trimesh.smoothing.filter_taubin(tm, iterations=10)
    wall = time.perf_counter() - t
    return {"wall_s": wall, "peak_mb": max(_common.peak_mb() - base, 0.0), "note": extra}


def _peer(kind: str, m) -> tuple[float, str]:
    """Solve the same one-iteration system with a peer solver; returns (seconds, note)."""
    from quadnodes.fairing import DEFAULT_WEIGHT, FairingSystem, even_lengths
    from quadnodes.zigzag import detect, window_edges

    free = detect(m, 0.0).free
    # fair()'s own system: its default line_spacing="fair" (every window's edges at their mean length)
    inverse = even_lengths(1.0 / np.sqrt(np.stack(
        [np.einsum("ij,ij->i", d, d) for d in window_edges(m.vertices, m.topology.windows)], axis=1)))
    if kind == "plain":  # quadnodes' own CG on the grid's storage, no preconditioner
        s = FairingSystem(m.vertices, m.topology.windows, free, DEFAULT_WEIGHT / m.mean_edge_length**2,
                          solver="cg", preconditioner="none", _topology=m.topology, _inverse_lengths=inverse)
        t = time.perf_counter()
        s.solve(m.vertices[free])
        return time.perf_counter() - t, f"cg {s.iterations} steps, residual {s.residual:.0e}"
    s = FairingSystem(m.vertices, m.topology.windows, free, DEFAULT_WEIGHT / m.mean_edge_length**2, solver="cg",
                      _inverse_lengths=inverse)
    M = s.matrix
    rhs = s._rhs + s.weight * m.vertices[free]
    t = time.perf_counter()
    x = _common.peer_solve(kind, M, rhs, m.vertices[free], 1e-9)
    wall = time.perf_counter() - t
    res = np.linalg.norm(rhs - M @ x, axis=0) / np.linalg.norm(rhs, axis=0)
    return wall, f"residual {res.max():.0e}"


LABELS = {
    "lines": "quadnodes structure lines + windows",
    "fair": "quadnodes fair, 1 iteration, all free (block CG)",
    "fair_hold": "quadnodes fair as above, line_spacing=\"hold\" (eq. 32's own lengths)",
    "plain": "quadnodes CG, no preconditioner (solve only)",
    "superlu": "peer: SciPy SuperLU, default ordering (solve only)",
    "superlu_mmd": "peer: SciPy SuperLU, MMD(AᵀA+A) (solve only)",
    "pyamg": "peer: CG + pyamg smoothed aggregation (solve only)",
    "cholmod": "peer: CHOLMOD (scikit-sparse), supernodal Cholesky (solve only)",
    "taubin": "quadnodes taubin, 10 steps (quad 1-ring)",
    "trimesh": "trimesh filter_taubin, 10 steps (triangulated)",
}


FAIR_KINDS = ("fair", "fair_hold", "plain", "superlu", "superlu_mmd", "pyamg", "cholmod")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 300, 1000])
    ap.add_argument("--noise", nargs="+", choices=_common.NOISES, default=list(_common.NOISES),
                    help="noises of the fairing rows (default: both)")
    ap.add_argument("--torus", action="store_true", help="also fair a noisy torus of about n² vertices")
    ap.add_argument("--cylinder", action="store_true",
                    help="also fair a noisy cylinder of n × n vertices (a tower: its rows closed rings, its columns "
                         "open)")
    ap.add_argument("--cube-sphere", action="store_true",
                    help="also fair a noisy cube-sphere of about n² vertices (irregular: no grid)")
    ap.add_argument("--graded", action="store_true",
                    help="also fair the sheet sampled with uneven spacing: its columns' spacing growing tenfold "
                         "across it, broadband noise of 0.2 local edge lengths")
    ap.add_argument("--warm", action="store_true",
                    help="load the compiled kernels before the clock, as `quadnodes serve`/`watch` and a second "
                         "run in one process have them (the rows say 'kernels loaded')")
    ap.add_argument("--weight", type=float,
                    help="fair rows: this weight (normalized) instead of fair's default; the rows say so")
    ap.add_argument("--slow", action="store_true",
                    help="also run SuperLU at sizes above 300 (on the torus, the cylinder and the cube-sphere above 100)")
    ap.add_argument("--only", nargs="+", choices=list(LABELS), help="run only these rows")
    ap.add_argument("--repeat", type=int, default=3,
                    help="fresh processes per row; the table shows the median time (default 3)")
    ap.add_argument("--against", metavar="PATH",
                    help="also run every row with the package at PATH (another checkout's root, e.g. a git worktree "
                         "of an older commit) on PYTHONPATH, one process of each in turn, and print its row below")
    ap.add_argument("--row", nargs=3, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.row:
        print(json.dumps(run_row(args.row[0], int(args.row[1]), args.row[2])))
        return
    if args.warm:
        os.environ["QUADNODES_BENCH_WARM"] = "1"
    if args.weight is not None:
        os.environ["QUADNODES_BENCH_WEIGHT"] = repr(args.weight)
    print("| mesh | noise | operation | wall time (s), median (range) | peak memory above baseline (MB) | note |")
    print("|---|---|---|---:|---:|---|")
    have = {}
    for kind, module in (("pyamg", "pyamg"), ("cholmod", "sksparse.cholmod")):
        try:
            importlib.import_module(module)
            have[kind] = True
        except ImportError:
            have[kind] = False
    for n in args.sizes:
        for kind in args.only or LABELS:
            if kind.startswith("superlu") and n > 300 and not args.slow:
                continue
            if kind in have and not have[kind]:
                continue
            noises = list(args.noise) if kind in FAIR_KINDS else ["zigzag"]
            if args.torus and kind in FAIR_KINDS:
                noises.append("torus")
            if args.cylinder and kind in FAIR_KINDS:
                noises.append("cylinder")
            if args.cube_sphere and kind in FAIR_KINDS:
                noises.append("cube-sphere")
            if args.graded and kind in FAIR_KINDS:
                noises.append("graded")
            for noise in noises:
                if kind.startswith("superlu") and noise in ("torus", "cylinder", "cube-sphere") and n > 100 \
                        and not args.slow:
                    continue  # (a torus's fill: SuperLU in MMD order ran over 8 minutes and 4 GB at 300²)
                row = [kind, str(n), noise]
                if args.against:
                    results = _common.interleaved_runs(__file__, row, args.repeat, args.against)
                else:
                    results = (_common.fresh_runs(__file__, row, args.repeat),)
                mesh = {"torus": f"torus {n}×{n}", "cylinder": f"cylinder {n}×{n}", "cube-sphere": f"cube-sphere ~{n}²",
                        "graded": f"{n}×{n}, spacing ×10 across"}.get(noise, f"{n}×{n}")
                label = "broadband" if noise in ("torus", "cylinder", "cube-sphere", "graded") else noise
                label += ", kernels loaded" if args.warm else ""
                label += f", weight {args.weight:g}" if args.weight is not None else ""
                for (r, walls), who in zip(results, ("", f" [{args.against}]")):
                    print(f"| {mesh} | {label} | {LABELS[kind]}{who} | {r['wall_s']:.3f}{_common.spread(walls)} | "
                          f"{r['peak_mb']:.0f} | {r['note']} |", flush=True)


if __name__ == "__main__":
    main()
