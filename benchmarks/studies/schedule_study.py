"""Threshold schedules compared: how close does each one bring the vertices to the clean grid?

The example script's surface (build123d wavy sheet 4000×8000 mm, amplitude 500,
sampled 22×41), seeded zigzag noise (tangential 0.25, normal 0.1 edge lengths,
seed 7), then fairing with several schedules at the default weight, and the
baselines. Distances are in mean edge lengths from each vertex to its clean
position. Backs the table in docs/fairing.md "Thresholds: free the whole zigzag region at once".

Run:  python benchmarks/studies/schedule_study.py  (a few seconds)
"""

from __future__ import annotations

import numpy as np

import quadnodes as qn
from quadnodes import surfaces


def main() -> None:
    face = surfaces.wavy(width=4000.0, depth=8000.0, amplitude=500.0)
    clean = surfaces.sample(face, 22, 41)
    noisy, _ = qn.perturb(clean, tangential=0.25, normal=0.1, seed=7, fix="corners")
    h = clean.mean_edge_length

    def row(name: str, m: qn.QuadMesh) -> None:
        d = np.linalg.norm(m.vertices - clean.vertices, axis=1) / h
        z = qn.compare(noisy, m)["zigzag_max"]
        print(f"| {name} | {d.mean():.3f} / {d.max():.3f} | {z:.4f} |")

    print("| method | mean / max distance to the clean grid (edge lengths) | zigzag max |")
    print("|---|---:|---:|")
    row("noisy input", noisy)
    for name, kw in [
        ("fair: deviation 1 halved, 10 iterations (thesis example 3)", dict(iterations=10, threshold=1.0, threshold_decay=0.5)),
        ("fair: deviation 0.1, 1 iteration (default threshold)", dict(iterations=1, threshold=0.1)),
        ("fair: deviation 0.1, 3 iterations", dict(iterations=3, threshold=0.1)),
        ("fair: deviation 0, 3 iterations (all window-middle vertices free)", dict(iterations=3, threshold=0.0)),
    ]:
        row(name, qn.fair(noisy, **kw)[0])
    row("Laplacian, 4 steps", qn.laplacian(noisy, iterations=4)[0])
    row("Taubin, 50 iterations", qn.taubin(noisy, iterations=50)[0])


if __name__ == "__main__":
    main()
