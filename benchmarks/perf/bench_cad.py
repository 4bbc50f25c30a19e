"""STEP export of 10,000 panels beside build123d's own export of the same faces; the example graphs at size.

Backs docs/cad.md "Speed: `python benchmarks/perf/bench_cad.py …`" and the README's CAD-out figures.

Part 1 (speed, issue 13 item 11): a 101 × 101 vertex grid (10,000 panels, 1 m spacing, mm) in three
variants — twisted (a saddle: every panel a bilinear patch), almost flat (every panel planar within the default
tolerance 1e-3 but none exactly: the case that used to abort), and a mix — written with
``quadnodes.io.write_step`` in each mode, beside the peer: build123d's own constructors
(``Face.make_bezier_surface`` / ``Face(Wire.make_polygon(...))``) and ``build123d.export_step`` of a
Compound of the same faces (with build123d's default pcurves), in the same run. "build" is the shape
alone, "total" includes writing (quadnodes' default ``pcurves=False``; ``--pcurves`` adds rows with
``pcurves=True``, OCCT's default).

Part 2 (``--examples``): examples/quickstart.toml and examples/planar_panels.toml at 40, 45, 60 and 120 per
side (only the nodes the STEP and CSV need), STEP as a sewn shell: panels, planar, fallbacks, largest
corner move, time.

Run:  python benchmarks/perf/bench_cad.py [--examples] [--modes compound,shell] [--pcurves]
"""

from __future__ import annotations

import argparse
import csv
import os
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

from quadnodes.io.step import step_panels, write_step
from quadnodes.mesh import QuadMesh, grid

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
MODES = ("compound", "shell", "assembly")


def _mesh(kind: str, n: int = 101) -> QuadMesh:
    y, x = np.meshgrid(np.linspace(-1, 1, n), np.linspace(-1, 1, n), indexing="ij")
    if kind == "twisted":  # a saddle on a 100 m square: every panel bilinear (relative distance ~2.6e-3)
        z = 20000.0 * x * y
    elif kind == "almost flat":
        z = 0.3 * (-1.0) ** (np.indices(x.shape).sum(axis=0))  # every panel 0.3 mm out of plane
    else:  # mixed: a flat half and a curved half
        z = np.where(x > 0, 20000.0 * x * y, 0.3 * (-1.0) ** (np.indices(x.shape).sum(axis=0)))
    return grid(n, n, spacing=1000.0, height=z)


def _clock() -> tuple[float, float]:
    return time.perf_counter(), time.process_time()


def _since(start: tuple[float, float]) -> tuple[float, float]:
    """(wall, CPU) seconds since ``start``: on a busy shared machine the CPU time is the fairer number."""
    return time.perf_counter() - start[0], time.process_time() - start[1]


def _peer(mesh: QuadMesh, path: Path) -> tuple[tuple[float, float], tuple[float, float]]:
    """build123d alone: its face constructors and export_step (planar test: the same mask)."""
    from build123d import Compound, Face, Wire, export_step

    from quadnodes.flatness import planar_panels

    t = _clock()
    planar = planar_panels(mesh)
    faces = []
    for k, c in enumerate(mesh.vertices[mesh.faces].tolist()):
        if planar[k]:
            try:
                faces.append(Face(Wire.make_polygon(c, close=True)))
                continue
            except Exception:  # OCCT refuses almost-planar polygons; the peer falls back too
                pass
        faces.append(Face.make_bezier_surface([[c[0], c[3]], [c[1], c[2]]]))
    comp = Compound(faces)
    built = _since(t)
    export_step(comp, str(path))
    return built, _since(t)


def speed(pcurves: bool = False) -> None:
    print("| mesh (10,000 panels) | writer | mode | planar | build wall / CPU [s] | total wall / CPU [s] | size [MB] |")
    print("|---|---|---|---:|---:|---:|---:|")
    step_panels(grid(2, 2))  # warm-up: imports outside the timings
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder)
        for kind in ("twisted", "almost flat", "mixed"):
            mesh = _mesh(kind)
            for mode in MODES:
                for with_pcurves in (False, True) if pcurves else (False,):
                    t = _clock()
                    _, report = step_panels(mesh, mode=mode)
                    build = _since(t)
                    t = _clock()
                    path, report = write_step(mesh, out / "q.step", mode=mode, pcurves=with_pcurves)
                    total = _since(t)
                    label = f"{mode}, pcurves" if with_pcurves else mode
                    print(f"| {kind} | quadnodes | {label} | {report.n_planar} | {_fmt(build)} | {_fmt(total)} | "
                          f"{os.path.getsize(path) / 1e6:.1f} |", flush=True)
            built, total = _peer(mesh, out / "peer.step")
            print(f"| {kind} | build123d (peer) | compound | – | {_fmt(built)} | {_fmt(total)} | "
                  f"{os.path.getsize(out / 'peer.step') / 1e6:.1f} |", flush=True)


def _fmt(t: tuple[float, float]) -> str:
    return f"{t[0]:.1f} / {t[1]:.1f}"


def examples() -> None:
    import quadnodes.nodes  # noqa: F401
    from quadnodes.graph.files import from_dict

    print("| example | per side | panels | planar | fallback | max corner move [mm] | shared edges | time [s] |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for name in ("quickstart.toml", "planar_panels.toml"):
        for n in (40, 45, 60, 120):
            data = tomllib.loads((EXAMPLES / name).read_text())
            keep = {"surface", "clean", "noisy", "fair", "flat", "step", "csv"}
            data["nodes"] = {k: v for k, v in data["nodes"].items() if k in keep}
            data["nodes"]["clean"]["params"].update(nu=n, nv=n)
            with tempfile.TemporaryDirectory() as folder:
                g = from_dict(data, base_dir=folder)
                t = time.perf_counter()
                result = g.run()
                dt = time.perf_counter() - t
                r = result[g["step"].report]
                rows = list(csv.DictReader((Path(folder) / data["nodes"]["csv"]["params"]["path"]).open()))
                assert sum(x["kind"] == "planar" for x in rows) == r.n_planar
            print(f"| {name} | {n} | {r.n_panels} | {r.n_planar} | {len(r.fallback)} | "
                  f"{r.max_corner_move:.4f} | {r.n_shared_edges} | {dt:.1f} |", flush=True)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--examples", action="store_true", help="also run the example graphs at 40 … 120 per side")
    ap.add_argument("--only-examples", action="store_true", help="run only the example graphs")
    ap.add_argument("--modes", default=",".join(MODES), help="STEP modes to time (comma-separated)")
    ap.add_argument("--pcurves", action="store_true", help="also time every mode with pcurves=True")
    args = ap.parse_args()
    MODES = tuple(args.modes.split(","))
    print(f"python {sys.version.split()[0]}, {os.cpu_count()} cores, load average "
          f"{os.getloadavg()[0]:.1f} at the start\n")
    if not args.only_examples:
        speed(args.pcurves)
    if args.examples or args.only_examples:
        print()
        examples()
