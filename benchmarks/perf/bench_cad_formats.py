"""Rhino .3dm and DXF unrolls of 10,000 panels, beside peers writing the same mesh.

Backs the speed table of docs/cad.md "Rhino, DXF, OFF and PLY" and the README's .3dm/DXF figures.

Input: a 101 × 101 vertex grid (100 × 100 = 10,000 panels, 1 m spacing, in mm) on a curved height field
whose left half is flattened, so both layers (planar / bilinear) and both DXF colours are used.

Rows (best of ``--repeat`` runs: wall time, the CPU time of this process in that run — closer to the wall
time of an idle machine when other jobs share the cores — and the file size):

- ``save_3dm``: the full .3dm (mesh, 10,000 named surfaces with 8 user-text entries each, 202 structure
  lines, layers), atomically, with the default ``engine="fast"`` (rhino3dm writes the mesh, lines and
  document; the panels' object records are written at once from rhino3dm's own template records) and with
  ``engine="rhino3dm"`` (every panel added through rhino3dm: the previous writer, the same content); then
  without user text, and the mesh alone through rhino3dm.
- ``save_dxf``: the unrolls (unfold + layout + 10,000 polylines and labels) with the default ``engine="fast"``
  and with ``engine="ezdxf"`` (every entity an ezdxf object: the same file, 20× slower).
- peers: meshio writing the same quads as OBJ and PLY, trimesh exporting the (triangulated) mesh as PLY.
- reading back: ``load_3dm``, ``load_ply`` (meshio), ``load_off``.

``--stages`` prints, instead, where the time of ``save_3dm`` (fast engine) goes, stage by stage (CPU time
of this process, best of ``--repeat``).

``--large N`` writes, instead, the .3dm of an N × N vertex grid (the same height field) once and prints its CPU
time, the process's peak memory before and after, and the file size (the panels' records are written in batches,
so the peak should not grow with N beyond the mesh's own arrays).

Run:  python benchmarks/perf/bench_cad_formats.py [--repeat 3] [--stages | --large N]   (about a minute)
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from quadnodes.flatness import planar_panels
from quadnodes.io import load, save_3dm, save_dxf
from quadnodes.mesh import QuadMesh, grid

TOL = "0.01 mm"


def _mesh(n: int = 101) -> QuadMesh:
    y, x = np.meshgrid(np.linspace(-1, 1, n), np.linspace(-1, 1, n), indexing="ij")
    z = 8000.0 * (0.6 * x * x - 0.4 * y * y + 0.2 * np.sin(3 * x) * y)
    z[:, : n // 2 + 1] = 0.0
    return grid(n, n, spacing=1000.0, height=z)


def large(n: int) -> None:
    """One fast-engine .3dm of an n x n vertex grid: CPU time, peak memory, file size."""
    import resource

    mesh = _mesh(n)
    save_3dm(grid(3, 3), Path(tempfile.gettempdir()) / "qn-warm.3dm")
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    with tempfile.TemporaryDirectory() as folder:
        c = time.process_time()
        p = save_3dm(mesh, Path(folder) / "large.3dm", planar_tolerance=TOL)
        cpu = time.process_time() - c
        size = os.path.getsize(p) / 1e6
    after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"| panels | CPU [s] | peak memory before / after [MB] | size [MB] |\n|---:|---:|---:|---:|\n"
          f"| {mesh.n_faces:,} | {cpu:.1f} | {before:.0f} / {after:.0f} | {size:.0f} |")


def _best(repeat: int, fn, *args, **kwargs):
    """Result, best wall time and the CPU time of that run (this process; less disturbed by other jobs)."""
    best = (np.inf, np.inf)
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        out = fn(*args, **kwargs)
        best = min(best, (time.perf_counter() - t, time.process_time() - c))
    return out, best


def _mesh_only_3dm(mesh: QuadMesh, path: Path) -> Path:
    import rhino3dm

    model = rhino3dm.File3dm()
    rm = rhino3dm.Mesh()
    rm.Vertices.UseDoublePrecisionVertices = True
    for p in mesh.vertices.tolist():
        rm.Vertices.AddPoint3d(*p)
    for q in mesh.faces.tolist():
        rm.Faces.AddFace(*q)
    model.Objects.AddMesh(rm)
    model.Write(str(path), 0)
    return path


def _off(mesh: QuadMesh, path: Path) -> Path:
    lines = ["OFF", f"{mesh.n_vertices} {mesh.n_faces} 0"]
    text = "\n".join(lines) + "\n" + ("%r %r %r\n" * mesh.n_vertices) % tuple(mesh.vertices.ravel().tolist())
    text += ("4 %d %d %d %d\n" * mesh.n_faces) % tuple(mesh.faces.ravel().tolist())
    path.write_text(text)
    return path


def stages(mesh: QuadMesh, repeat: int) -> None:
    """CPU time of every stage of ``save_3dm(engine="fast")`` (the same calls, timed one by one)."""
    import io

    from quadnodes.io import rhino
    from quadnodes.io._3dm_records import random_ids, write_records

    best: dict[str, float] = {}

    def timed(label: str, fn, *args, **kwargs):
        c = time.process_time()
        out = fn(*args, **kwargs)
        best[label] = min(best.get(label, np.inf), time.process_time() - c)
        return out

    for _ in range(repeat):
        model, layers, p = timed("checks, planar test, areas, mesh object (rhino3dm)",
                                 rhino._model_without_panels, mesh, TOL, lines=False, user_text=True)
        panels = timed("panel record templates (rhino3dm writes 2 panels)", rhino._templates, layers, p, 8, "x")
        lines = timed("line record template (rhino3dm writes 2 polylines)", rhino._line_template, layers, 8, "x")
        data = timed("File3dm.Encode: document, layers, mesh", rhino._file_bytes, model, 8, "x")
        names, columns = timed("user texts (shortest round-trip numbers)", p.texts, 0, p.n)
        recs = timed("panel records", panels.records, p.flags, p.corners, names, columns, random_ids(p.n))
        points, line_names = rhino._line_points(mesh)
        line_recs = timed("structure-line records", lines.records, points, line_names, random_ids(len(points)))
        timed("splice into the file (memory)", write_records, io.BytesIO(), data, [recs, line_recs], after=1)
    print("| stage of save_3dm (fast engine) | CPU [s] |\n|---|---:|")
    for label, t in best.items():
        print(f"| {label} | {t:.3f} |")
    print(f"| sum | {sum(best.values()):.3f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--stages", action="store_true", help="where the time of save_3dm goes")
    parser.add_argument("--large", type=int, default=0, metavar="N", help="one .3dm of an N x N vertex grid")
    args = parser.parse_args()
    repeat = args.repeat
    if args.large:
        large(args.large)
        return
    if args.stages:
        print(f"save_3dm stages, {_mesh().n_faces:,} panels, best of {repeat}, load average {os.getloadavg()[0]:.1f}\n")
        stages(_mesh(), repeat)
        return
    import meshio
    import trimesh

    mesh = _mesh()
    n_planar = int(planar_panels(mesh, TOL).sum())
    print(f"{mesh.n_faces:,} panels ({n_planar:,} planar within {TOL}), best of {repeat}, "
          f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}\n")
    rows = ["| case | wall [s] | CPU [s] | size [MB] |", "|---|---:|---:|---:|"]

    def row(label: str, path: Path, t: tuple[float, float]) -> None:
        rows.append(f"| {label} | {t[0]:.2f} | {t[1]:.2f} | {os.path.getsize(path) / 1e6:.1f} |")

    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder)
        save_3dm(grid(3, 3), out / "warm.3dm")  # imports outside the timings
        save_dxf(grid(3, 3), out / "warm.dxf")
        p, t = _best(repeat, save_3dm, mesh, out / "a.3dm", planar_tolerance=TOL)
        row("save_3dm: mesh + 10,000 surfaces with user text + lines", p, t)
        q, t = _best(repeat, save_3dm, mesh, out / "r.3dm", planar_tolerance=TOL, engine="rhino3dm")
        row("save_3dm, engine='rhino3dm' (every panel through rhino3dm; before)", q, t)
        q, t = _best(repeat, save_3dm, mesh, out / "b.3dm", planar_tolerance=TOL, user_text=False)
        row("save_3dm, user_text=False", q, t)
        q, t = _best(repeat, save_3dm, mesh, out / "s.3dm", planar_tolerance=TOL, user_text=False, engine="rhino3dm")
        row("save_3dm, user_text=False, engine='rhino3dm'", q, t)
        q, t = _best(repeat, _mesh_only_3dm, mesh, out / "c.3dm")
        row("peer: rhino3dm, the mesh alone", q, t)
        q, t = _best(repeat, save_dxf, mesh, out / "a.dxf", planar_tolerance=TOL)
        row("save_dxf (engine='fast')", q, t)
        q, t = _best(1, save_dxf, mesh, out / "b.dxf", planar_tolerance=TOL, engine="ezdxf")
        row("save_dxf (engine='ezdxf', every entity an ezdxf object; 1 run)", q, t)
        cells = [("quad", mesh.faces)]
        _, t = _best(repeat, meshio.write_points_cells, out / "m.obj", mesh.vertices, cells)
        row("peer: meshio OBJ write (quads)", out / "m.obj", t)
        _, t = _best(repeat, meshio.write_points_cells, out / "m.ply", mesh.vertices, cells, binary=True)
        row("peer: meshio binary PLY write (quads)", out / "m.ply", t)
        tm = trimesh.Trimesh(mesh.vertices, np.concatenate([mesh.faces[:, [0, 1, 2]], mesh.faces[:, [0, 2, 3]]]),
                             process=False)
        q = out / "t.ply"
        _, t = _best(repeat, tm.export, q)
        row("peer: trimesh binary PLY export (triangulated)", q, t)
        _, t = _best(repeat, load, p)
        row("load_3dm (the mesh back)", p, t)
        _, t = _best(repeat, load, out / "m.ply")
        row("load_ply (meshio, quads kept)", out / "m.ply", t)
        o = _off(mesh, out / "m.off")
        _, t = _best(repeat, load, o)
        row("load_off", o, t)
    print("\n".join(rows))


if __name__ == "__main__":
    main()
