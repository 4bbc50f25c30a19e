"""Planarize on the real meshes of issue 16: shape="free" (the plain projection) against shape="keep".

Backs the table in docs/real-meshes.md "Planarizing" (and docs/planarize.md "Feasibility and quality
(issue 16)"). Meshes from ``tests/data`` (sources and
licences in its README), each as shipped ("clean") or perturbed and faired ("faired":
``perturb(mesh, tangential=0.2, normal=0.1, seed=3)`` then ``fair(noisy, iterations=3)``, as in
``tests/test_real_meshes.py``). Every row is ``planarize`` with its defaults (tolerance 1e-3,
``method="auto"``) except the setting named:

- ``corners held``: the default ``fix="corners"``;
- ``reference = input``: ``reference=`` the mesh itself (vertices slide along it), corners held;
- ``fix="none"``: nothing held.

Columns: planarity max (relative diagonal distance); edge ratio min–max (output over input edge
length); folded: quads convex in the input that are darts or bow-ties in the result; converged
(the tolerance met and nothing folded or collapsed); moved max in mean edge lengths h; the method
whose result was returned (``method="auto"`` may try Newton after local/global); wall time of the call.

Run:  python benchmarks/studies/planarize_shape.py
"""

from __future__ import annotations

import time
from pathlib import Path

DATA = Path(__file__).resolve().parents[2] / "tests" / "data"
CASES = [
    ("compas/hypar.obj", "clean", "corners held"),
    ("compas/hypar.obj", "clean", "reference = input"),
    ("compas/hypar.obj", "clean", 'fix="none"'),
    ("staircase_saddle.obj", "clean", "corners held"),
    ("staircase_saddle.obj", "clean", "reference = input"),
    ("staircase_saddle.obj", "faired", 'fix="none"'),
    ("rounded_box.obj", "faired", "corners held"),
    ("polygon_quads.obj", "clean", 'fix="none"'),
    ("polygon_quads.obj", "faired", "corners held"),
    ("polygon_quads.obj", "faired", "reference = input"),
]


def main() -> None:
    from quadnodes.fairing import fair
    from quadnodes.io import load
    from quadnodes.noise import perturb
    from quadnodes.planarization import planarize

    print("| mesh | input | setting | shape | planarity max | edge ratio min–max | folded | converged "
          "| moved max (h) | method | wall time (s) |")
    print("|---|---|---|---|---:|---|---:|---|---:|---|---:|")
    for name, kind, setting in CASES:
        mesh = load(DATA / name)
        if kind == "faired":
            mesh, _ = fair(perturb(mesh, tangential=0.2, normal=0.1, seed=3)[0], iterations=3)
        kw = {"corners held": {}, "reference = input": {"reference": mesh}, 'fix="none"': {"fix": "none"}}[setting]
        for shape in ("free", "keep"):
            t = time.perf_counter()
            _, rep = planarize(mesh, shape=shape, **kw)
            wall = time.perf_counter() - t
            print(f"| {name} | {kind} | {setting} | {shape} | {rep.planarity_max:.2e} "
                  f"| {rep.edge_length_ratio_min:.3f}–{rep.edge_length_ratio_max:.2f} | {len(rep.nonconvex)} "
                  f"| {'yes' if rep.converged else 'no'} | {rep.moved_max / rep.length_scale:.2f} "
                  f"| {rep.method} | {wall:.2f} |", flush=True)


if __name__ == "__main__":
    main()
