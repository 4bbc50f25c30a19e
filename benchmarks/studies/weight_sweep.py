"""Which default penalty weight? Fair noisy samples of known surfaces and measure.

Backs the weight table in docs/fairing.md (the default weight 0.3).

For four analytic height fields shaped like the thesis's examples, sample a grid,
add seeded zigzag noise (quadnodes.perturb), fair with each normalized weight and
both thesis schedules, and report the distance of the result to the TRUE surface
(first-order normal distance |z − f(x, y)| / sqrt(1 + |∇f|²)), in mean edge
lengths, and the remaining zigzag.

Run:  python benchmarks/studies/weight_sweep.py  (a few seconds)
"""

from __future__ import annotations

import numpy as np

from quadnodes.fairing import fair
from quadnodes.mesh import grid
from quadnodes.noise import perturb
from quadnodes.metrics import zigzag_stats

# (name, rows, cols, f, grad f) on [0, cols-1] x [0, rows-1] with unit spacing
def _saddle(x, y, r, c):
    u, v = x / (c - 1) - 0.5, y / (r - 1) - 0.5
    return 4.0 * (u * u - v * v), (8.0 * u / (c - 1), -8.0 * v / (r - 1))


def _s_shape(x, y, r, c):
    u = x / (c - 1)
    return 3.0 * np.sin(2 * np.pi * u), (3.0 * 2 * np.pi * np.cos(2 * np.pi * u) / (c - 1), 0 * y)


def _wavy(x, y, r, c):
    u, v = x / (c - 1), y / (r - 1)
    z = 3.0 * np.sin(np.pi * u) * np.cos(1.5 * np.pi * v)
    return z, (3.0 * np.pi * np.cos(np.pi * u) * np.cos(1.5 * np.pi * v) / (c - 1),
               -4.5 * np.pi * np.sin(np.pi * u) * np.sin(1.5 * np.pi * v) / (r - 1))


def _dome(x, y, r, c):
    u, v = x / (c - 1) - 0.5, y / (r - 1) - 0.5
    return 8.0 * (0.5 - u * u - v * v), (-16.0 * u / (c - 1), -16.0 * v / (r - 1))


# name, rows, cols, surface, deviation, iterations, decay, noise (tangential, normal)
CASES = [("E1 saddle 10x10", 10, 10, _saddle, 0.1, 3, 1.0, (0.25, 0.1)),
         ("E2 S-shape 13x13", 13, 13, _s_shape, 0.1, 3, 1.0, (0.25, 0.1)),
         ("E3 wavy 22x41", 22, 41, _wavy, 1.0, 10, 0.5, (0.25, 0.1)),
         ("E4 dome 22x41", 22, 41, _dome, 1.0, 5, 1.0, (0.6, 0.2))]
SEEDS = range(5)
WEIGHTS = [0.001, 0.003, 0.01, 0.03, 0.1, 0.3, 1.0, 3.0, 10.0]


def surface_distance(v: np.ndarray, f, r: int, c: int) -> np.ndarray:
    z, (gx, gy) = f(v[:, 0], v[:, 1], r, c)
    return np.abs(v[:, 2] - z) / np.sqrt(1 + gx * gx + gy * gy)


def main() -> None:
    print("| case | weight ω | mean dist | max dist | zigzag mean | zigzag max |")
    print("|---|---:|---:|---:|---:|---:|")
    summary: dict[float, list[float]] = {w: [] for w in WEIGHTS}
    zmax: dict[float, list[float]] = {w: [] for w in WEIGHTS}
    for name, r, c, f, dev, its, decay, (nt, nn) in CASES:
        y, x = np.meshgrid(np.arange(r, dtype=float), np.arange(c, dtype=float), indexing="ij")
        clean = grid(r, c, height=f(x, y, r, c)[0])
        for seed in SEEDS:
            noisy, _ = perturb(clean, tangential=nt, normal=nn, seed=seed, fix="corners")
            if seed == 0:
                d0 = surface_distance(noisy.vertices, f, r, c)
                z0 = zigzag_stats(noisy)
                print(f"| {name} (noisy input) | – | {d0.mean():.4f} | {d0.max():.4f} | "
                      f"{z0['zigzag_mean']:.4f} | {z0['zigzag_max']:.4f} |")
            for w in WEIGHTS:
                out, _ = fair(noisy, iterations=its, threshold=dev, threshold_decay=decay, weight=w)
                d = surface_distance(out.vertices, f, r, c)
                summary[w].append(d.mean())
                z = zigzag_stats(out)
                zmax[w].append(z["zigzag_max"])
                if seed == 0:
                    print(f"| {name} | {w:g} | {d.mean():.4f} | {d.max():.4f} | "
                          f"{z['zigzag_mean']:.4f} | {z['zigzag_max']:.4f} |")
    print()
    print(f"Over {len(CASES)} cases x {len(SEEDS)} seeds: mean distance to the true surface "
          "(edge lengths) and the worst remaining zigzag:")
    print("| weight ω | mean dist | mean of zigzag max | worst zigzag max |")
    print("|---:|---:|---:|---:|")
    for w in WEIGHTS:
        print(f"| {w:g} | {np.mean(summary[w]):.4f} | {np.mean(zmax[w]):.4f} | {np.max(zmax[w]):.4f} |")


if __name__ == "__main__":
    main()
