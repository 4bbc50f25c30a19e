"""Coefficients that vary along an axis: the spectral preconditioner with their profile against constant ones.

Backs ``PROFILE_MIN_SPREAD`` in ``quadnodes/fairing.py`` and the table of docs/fairing.md "Varying coefficients"
(issue 15: a solver whose steps do not depend on the input).

The transforms' preconditioner models the fairing matrix with one coefficient per family of lines. Where the
window coefficients vary smoothly along an axis — a surface sampled at even parameters where its parametrization
is uneven, a tower whose rings shrink toward the top — its steps grow with that variation. With a profile
(``SpectralPreconditioner(profile=…)``: the windows' coefficients by position along the axis, the other family's
by line) it inverts that variation exactly. Meshes, all with broadband noise of 0.2 local edge lengths:
``graded:N:r`` the bench sheet whose columns' spacing grows geometrically by ``r`` across it
(``_common.noisy_graded``), ``both:N:r`` its rows' spacing too, ``tower:N:t`` an open cylinder tapering by ``t``
(``_common.noisy_tower``), and ``surface:N:name`` a design surface of ``quadnodes.surfaces`` sampled at N × N even
parameters (which imports SciPy's transforms, as a graph run has them). One all-free fair() iteration (default
weight unless the case adds ``:w``), fresh processes (median of ``--repeat``, clock
around fair() alone, compiled kernels not loaded: the spectral path of a fresh process): the rule
(``PROFILE_MIN_SPREAD``), constant coefficients, and the profile always; steps and seconds; "spread" is the
profile's (the larger of its two medians' largest over smallest, on the axis the rule would take).

Run:  python benchmarks/studies/coefficient_profile.py [--repeat 3] [graded:300:10 tower:300:3 ...]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import _common  # noqa: E402

DEFAULT = ["graded:300:1", "graded:300:1.5", "graded:300:2", "graded:300:3", "graded:300:10", "graded:300:30",
           "graded:300:10:0.001", "both:300:3", "both:300:10", "tower:300:1", "tower:300:3", "surface:300:saddle",
           "surface:300:s_shape", "surface:300:dome", "surface:300:torus_patch", "graded:1000:10:0.0001"]
MODES = {"rule": None, "constant": "inf", "always": "1"}


def mesh(case: str):  # type: ignore[no-untyped-def]
    kind, n, what = case.split(":")[:3]
    if kind == "graded":
        return _common.noisy_graded(int(n), float(what))
    if kind == "both":
        return _common.noisy_graded(int(n), float(what), rows_ratio=float(what))
    if kind == "tower":
        return _common.noisy_tower(int(n), float(what))
    from quadnodes import surfaces
    from quadnodes.mesh import QuadMesh

    m = surfaces.sample(getattr(surfaces, what)(), int(n), int(n))
    rng = np.random.default_rng(0)
    return QuadMesh(m.vertices + rng.normal(scale=0.2 * m.mean_edge_length, size=m.vertices.shape), m.faces)


def row(case: str, mode: str) -> dict:
    import quadnodes.fairing as fairing

    m = mesh(case)
    if MODES[mode] is not None:
        fairing.PROFILE_MIN_SPREAD = float(MODES[mode])
    seen: list = []
    profile = fairing._coefficient_profile

    def spy(*args):  # type: ignore[no-untyped-def]
        rule = fairing.PROFILE_MIN_SPREAD
        fairing.PROFILE_MIN_SPREAD = 0.0  # (the spread whatever the rule)
        found = profile(*args)
        fairing.PROFILE_MIN_SPREAD = rule
        if found is not None:
            _, w, s, across = found
            seen.append(max([float(a.max() / a.min()) for a in (w, s, across) if a is not None]))
        return profile(*args)

    fairing._coefficient_profile = spy
    weight = {"weight": float(case.split(":")[3])} if case.count(":") == 3 else {}
    t = time.perf_counter()
    _, rep = fairing.fair(m, iterations=1, threshold=0.0, **weight)
    wall = time.perf_counter() - t
    r = rep.iterations[0]
    return {"wall_s": wall, "steps": r.cg_iterations, "spread": seen[0] if seen else float("nan"),
            "residual": r.residual}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("cases", nargs="*", default=DEFAULT,
                    help="graded:N:ratio[:weight], both:N:ratio, tower:N:taper, surface:N:name")
    ap.add_argument("--repeat", type=int, default=3, help="fresh processes per cell (median)")
    ap.add_argument("--row", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.row:
        print(json.dumps(row(*args.row)))
        return
    print("One all-free fair() iteration, broadband noise, fresh processes (median); steps · seconds\n")
    print("| mesh | weight | spread | rule | constant coefficients | profile always |")
    print("|---|---:|---:|---:|---:|---:|")
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    for case in args.cases:
        cells, spread = [], float("nan")
        for mode in MODES:
            runs = []
            for _ in range(max(1, args.repeat)):
                out = subprocess.run([sys.executable, __file__, "--row", case, mode], capture_output=True, text=True,
                                     check=True, env=env)
                runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
            runs.sort(key=lambda r: r["wall_s"])
            mid = runs[len(runs) // 2]
            spread = mid["spread"] if np.isfinite(mid["spread"]) else spread
            cells.append(f"{mid['steps']} · {mid['wall_s']:.3f} s")
        weight = case.split(":")[3] if case.count(":") == 3 else "0.3"
        print(f"| {case.rsplit(':', 1)[0] if case.count(':') == 3 else case} | {weight} | {spread:.2f} | "
              + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
