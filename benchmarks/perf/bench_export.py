"""How long do the exporters take on architectural sizes, and how big are the files?

Backs the export table in docs/cad.md.

- STEP: 10,000 panels (a 101 × 101 vertex grid, 1 m spacing in mm) on a curved
  height field (every panel a bilinear patch) and on a flat one (every panel a
  plane), in each mode (compound, shell, assembly). "build" is
  :func:`quadnodes.io.step.step_shape` alone (OCP faces, sewing, wrappers);
  "total" is :func:`quadnodes.io.step.save_step` (build + OCCT STEP writer +
  atomic rename).
- OBJ: write and read a 1000 × 1000 vertex grid (998,001 quads).

Prints a markdown table. Run:  python benchmarks/perf/bench_export.py  (about a minute)
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

import numpy as np

from quadnodes.io import load_obj, save_obj, save_step, step_shape
from quadnodes.flatness import planar_panels as planar_mask
from quadnodes.mesh import QuadMesh, grid


def _timed(fn, *args, **kwargs):
    t = time.perf_counter()
    out = fn(*args, **kwargs)
    return out, time.perf_counter() - t


def _height_grid(rows: int, cols: int, *, curved: bool, spacing: float = 1000.0) -> QuadMesh:
    y, x = np.meshgrid(np.linspace(-1, 1, rows), np.linspace(-1, 1, cols), indexing="ij")
    z = 8000.0 * (0.6 * x * x - 0.4 * y * y + 0.2 * np.sin(3 * x) * y) if curved else np.zeros_like(x)
    return grid(rows, cols, spacing=spacing, height=z)


def _mb(path: Path) -> str:
    return f"{os.path.getsize(path) / 1e6:.1f}"


def main() -> None:
    rows = ["| case | panels | build [s] | total [s] | size [MB] |", "|---|---:|---:|---:|---:|"]
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder)
        step_shape(grid(2, 2))  # warm-up: import build123d / OCP outside the timings
        for surface in ("curved", "flat"):
            mesh = _height_grid(101, 101, curved=surface == "curved")
            n_planar = int(planar_mask(mesh).sum())
            label = f"{surface} ({n_planar} planar)"
            for mode in ("compound", "shell", "assembly"):
                _, t_build = _timed(step_shape, mesh, mode=mode)
                path, t_total = _timed(save_step, mesh, out / f"{surface}_{mode}.step", mode=mode)
                rows.append(
                    f"| STEP {mode}, {label} | {mesh.n_faces:,} | {t_build:.2f} | {t_total:.2f} | {_mb(path)} |"
                )
                path.unlink()
        big = _height_grid(1000, 1000, curved=True, spacing=100.0)
        path, t_write = _timed(save_obj, big, out / "big.obj")
        rows.append(f"| OBJ write 1000×1000 | {big.n_faces:,} | – | {t_write:.2f} | {_mb(path)} |")
        back, t_read = _timed(load_obj, path)
        assert np.array_equal(back.vertices, big.vertices) and back.grid_shape == big.grid_shape
        rows.append(f"| OBJ read 1000×1000 (exact round trip) | {back.n_faces:,} | – | {t_read:.2f} | {_mb(path)} |")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
