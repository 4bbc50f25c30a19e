"""The thesis's chapter-5 comparison as numbers: E1–E4, every method on the same noisy input.

For each example (clean surface from quadnodes.surfaces.example, seeded noise as in
examples/make_thesis_graphs.py) run: Laplacian and Taubin with the thesis's step counts (boundary free, as
in the thesis, corners fixed, and boundary fixed), and the new method with the thesis's parameters (its weights read as
normalized weights) and with the documented default weight 0.3. Prints one Markdown table per example;
distances are in mean edge lengths of the clean mesh.

Run:  python benchmarks/thesis_comparison.py   (about 10 s)
"""

from __future__ import annotations

import numpy as np

import quadnodes as qn
from quadnodes.surfaces import example

# name, laplace steps, taubin iterations, thesis fair settings, noise (tangential, normal)
EXAMPLES = [
    ("E1", 3, 40, dict(iterations=3, deviation=0.1, weight=0.001), (0.25, 0.1)),
    ("E2", 1, 20, dict(iterations=3, deviation=0.1, weight=0.005), (0.25, 0.1)),
    ("E3", 4, 50, dict(iterations=10, deviation=1.0, deviation_decay=0.5, weight=0.001), (0.25, 0.1)),
    ("E4", 4, 30, dict(iterations=5, deviation=1.0, weight=0.0005), (0.6, 0.2)),
]


def main() -> None:
    for name, lap, tau, thesis, (nt, nn) in EXAMPLES:
        clean = example(name)
        noisy = qn.perturb(clean, tangential=nt, normal=nn, seed=7, fix="corners")
        h = clean.mean_edge_length
        default = {k: v for k, v in thesis.items() if k != "weight"}
        runs = {
            "noisy input": noisy,
            f"Laplacian {lap}": qn.laplacian(noisy, iterations=lap),
            f"Laplacian {lap}, corners fixed": qn.laplacian(noisy, iterations=lap, fix="corners"),
            f"Laplacian {lap}, boundary fixed": qn.laplacian(noisy, iterations=lap, fix="boundary"),
            f"Taubin {tau}": qn.taubin(noisy, iterations=tau),
            f"Taubin {tau}, corners fixed": qn.taubin(noisy, iterations=tau, fix="corners"),
            f"Taubin {tau}, boundary fixed": qn.taubin(noisy, iterations=tau, fix="boundary"),
            f"new, thesis ω={thesis['weight']:g}": qn.fair(noisy, **thesis)[0],
            "new, default ω=0.3": qn.fair(noisy, **default)[0],
        }
        print(f"\n### {name} ({clean.grid_shape[0]}×{clean.grid_shape[1]}, noise {nt}/{nn})\n")
        print("| method | zigzag mean | zigzag max | >0.1 | >0.01 | disp. max | boundary moved | bbox % "
              "| to clean surface mean/max | to clean grid mean | planarity max |")
        print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        for label, m in runs.items():
            c = qn.compare(noisy, m, reference=clean)
            print(f"| {label} | {c['zigzag_mean']:.4f} | {c['zigzag_max']:.4f} | {c['vertices_above_0.1']} | "
                  f"{c['vertices_above_0.01']} | {c['displacement_max'] / h:.3f} | "
                  f"{c['boundary_displacement_max'] / h:.3f} | {c['bbox_diagonal_change_pct']:+.2f} | "
                  f"{c['reference_mean'] / h:.3f}/{c['reference_max'] / h:.3f} | "
                  f"{c['reference_vertex_mean'] / h:.3f} | {c['planarity_max']:.4f} |")


if __name__ == "__main__":
    np.set_printoptions(precision=4)
    main()
