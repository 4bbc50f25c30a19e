"""Why CG stops at a relative residual of 1e-9: the error against the direct solve per stopping rule.

Backs the CG tolerance table in docs/fairing.md "Speed" (the default rtol 1e-9).

For the meshes of ``tests/test_fairing.py`` (a 40×50 grid, a mesh with extraordinary vertices, a
cylinder; all moved far from the origin) and the bench_core grids, with every window-middle vertex
free, solves one fairing iteration directly (SuperLU) and by CG stopped at relative residuals 1e-6 …
1e-9, and prints the CG steps and the largest coordinate error relative to the mesh's extent. The
target is 1e-8.

Run:  python benchmarks/studies/cg_tolerance.py  (about a minute)
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from quadnodes.fairing import FairingSystem
from quadnodes.mesh import cylinder, grid
from quadnodes.noise import perturb
from quadnodes.zigzag import detect

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import _common  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))
from meshes import extraordinary_mesh  # noqa: E402

RTOLS = (1e-6, 1e-7, 1e-8, 1e-9)


def main() -> None:
    cases = {
        "grid 40×50": perturb(grid(40, 50, spacing=25.0), tangential=0.25, normal=0.1, seed=3)[0],
        "extraordinary": perturb(extraordinary_mesh(3), tangential=0.2, seed=4)[0],
        "cylinder 30×40": perturb(cylinder(30, 40), tangential=0.2, seed=5)[0],
        "bench 100×100": _common.noisy_grid(100),
        "bench 300×300": _common.noisy_grid(300),
    }
    print("| mesh | ω | " + " | ".join(f"rtol {r:.0e}: steps, error" for r in RTOLS) + " |")
    print("|---|---:|" + "---:|" * len(RTOLS))
    for name, m in cases.items():
        m = m.with_vertices(m.vertices + [4000.0, -2500.0, 300.0])
        free = detect(m, 0.0).free
        h = m.mean_edge_length
        a = m.vertices[free]
        extent = np.ptp(m.vertices, axis=0).max()
        for w in ([0.3] if "300" in name else [0.001, 0.3, 10.0]):
            xd = FairingSystem(m.vertices, m.topology.windows, free, w / h**2, solver="direct").solve(a)
            cells = []
            for rt in RTOLS:
                s = FairingSystem(m.vertices, m.topology.windows, free, w / h**2, solver="cg", rtol=rt)
                x = s.solve(a)
                cells.append(f"{s.iterations}, {np.abs(x - xd).max() / extent:.1e}")
            print(f"| {name} | {w:g} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
