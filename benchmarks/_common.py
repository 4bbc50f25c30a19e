"""Shared helpers of the benchmark scripts: noisy grids, resident memory, medians of fresh processes.

Scripts in ``benchmarks/perf/`` (speed tables) and ``benchmarks/studies/`` (studies that justify a
default) import this module after putting ``benchmarks/`` on ``sys.path``::

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    import _common
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
from pathlib import Path

import numpy as np

#: The noises a speed table can state: perturb's alternating zigzag (the highest frequency, the easiest
#: case for CG) and broadband (independent Gaussian offsets of 0.2 edge lengths per coordinate).
NOISES = ("zigzag", "broadband")


def rss_mb() -> float:
    """Resident memory of this process now, in MB."""
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * resource.getpagesize() / 2**20


def peak_mb() -> float:
    """Peak resident memory of this process so far, in MB."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def noisy_grid(n: int, noise: str = "zigzag", seed: int = 0):
    """The benchmark sheet ``z = 0.3 sin 3x cos 2y`` on an ``n × n`` unit grid, with noise.

    ``"zigzag"``: ``perturb(tangential=0.2, normal=0.05, seed)``; ``"broadband"``:
    ``rng.normal(scale=0.2 h, size=(n², 3))`` added to every vertex (h = 1/(n−1)).
    """
    from quadnodes.mesh import grid
    from quadnodes.noise import perturb

    y, x = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n), indexing="ij")
    clean = grid(n, n, spacing=1.0 / (n - 1), height=0.3 * np.sin(3 * x) * np.cos(2 * y))
    if noise == "zigzag":
        return perturb(clean, tangential=0.2, normal=0.05, seed=seed)[0]
    if noise == "broadband":
        rng = np.random.default_rng(seed)
        return clean.with_vertices(clean.vertices + rng.normal(scale=0.2 / (n - 1), size=(n * n, 3)))
    raise ValueError(f"noise: expected one of {NOISES}, got {noise!r}")


def noisy_graded(n: int, ratio: float = 10.0, seed: int = 0, rows_ratio: float = 1.0):
    """The benchmark sheet (:func:`noisy_grid`'s surface) on an ``n × n`` grid whose columns' spacing grows
    geometrically by ``ratio`` from the first column to the last (a design surface sampled at even parameters where
    its parametrization is uneven) and its rows' by ``rows_ratio``, with broadband noise of 0.2 local edge lengths
    (the smaller of the two spacings at each vertex)."""
    from quadnodes.mesh import QuadMesh, grid

    u = np.linspace(0, 1, n)
    x = u if ratio == 1 else (ratio**u - 1) / (ratio - 1)
    y = u if rows_ratio == 1 else (rows_ratio**u - 1) / (rows_ratio - 1)
    yy, xx = np.meshgrid(y, x, indexing="ij")
    m = grid(n, n, spacing=1.0 / (n - 1), height=0.3 * np.sin(3 * xx) * np.cos(2 * yy))
    v = m.vertices.copy()
    v[:, 0], v[:, 1] = xx.ravel(), yy.ravel()
    along_y = np.full(n, 1.0 / (n - 1)) if rows_ratio == 1 else np.gradient(y)
    local = np.minimum(np.gradient(x)[None, :], along_y[:, None]).ravel()
    rng = np.random.default_rng(seed)
    v += rng.normal(size=v.shape) * (0.2 * local)[:, None]
    return QuadMesh(v, m.faces)


def noisy_tower(n: int, taper: float = 3.0, seed: int = 0):
    """An open cylinder of ``n`` rings of ``n`` vertices (height 2π: square cells at its base) whose radius shrinks
    linearly by ``taper`` from the first ring to the last (a tapering tower), with broadband noise of 0.2 local
    edge lengths."""
    from quadnodes.mesh import QuadMesh, cylinder

    c = cylinder(n, n, radius=1.0, height=2 * np.pi)
    v = c.vertices.copy()
    r = 1.0 + (1.0 / taper - 1.0) * v[:, 2] / v[:, 2].max()
    v[:, :2] *= r[:, None]
    rng = np.random.default_rng(seed)
    v += rng.normal(size=v.shape) * (0.2 * 2 * np.pi / n * r)[:, None]
    return QuadMesh(v, c.faces)


def noisy_torus(rings: int, segments: int, seed: int = 0):
    """A torus (a closed mesh: lines wrap around; a grid closed both ways, with the seams' diagonals) with broadband
    noise of 0.2 edge lengths."""
    from quadnodes.mesh import torus

    t = torus(rings, segments)
    h = t.mean_edge_length
    rng = np.random.default_rng(seed)
    return t.with_vertices(t.vertices + rng.normal(scale=0.2 * h, size=t.vertices.shape))


def noisy_cylinder(rows: int, segments: int, seed: int = 0, aspect: float | None = None):
    """An open cylinder (its rows closed around, its columns open; radius 1, height 2) with broadband noise of
    0.2 edge lengths; ``aspect``: the radius instead that makes the edges around ``aspect`` times those along."""
    from quadnodes.mesh import cylinder

    radius = 1.0 if aspect is None else aspect * 2.0 / (rows - 1) * segments / (2 * np.pi)
    c = cylinder(rows, segments, radius=radius, height=2.0)
    h = c.mean_edge_length
    rng = np.random.default_rng(seed)
    return c.with_vertices(c.vertices + rng.normal(scale=0.2 * h, size=c.vertices.shape))


def cube_sphere(k: int):
    """A cube-sphere: the six faces of a cube, each a ``k × k`` grid of quads, on the unit sphere.

    ``6k² + 2`` vertices; the eight cube corners have valence 3 (extraordinary), so the mesh is
    no grid of any kind and fairs on the general (free-index CSR) path. Faces point outwards.
    """
    from quadnodes.mesh import QuadMesh

    i, j = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    i, j = i.reshape(-1), j.reshape(-1)
    corners = np.stack([np.stack([i, j]), np.stack([i + 1, j]), np.stack([i + 1, j + 1]), np.stack([i, j + 1])])
    pts = []  # (6, 4, m, 3) integer lattice corners of every quad, face by face
    for axis in range(3):
        for side in (0, k):
            a, b = [d for d in range(3) if d != axis]
            q = np.zeros((4, i.size, 3), dtype=np.int64)
            q[:, :, axis] = side
            q[:, :, a] = corners[:, 0]
            q[:, :, b] = corners[:, 1]
            if (side == k) != ((axis % 2) == 0) ^ (axis == 1) ^ True:
                q = q[::-1]
            pts.append(q.transpose(1, 0, 2))
    lattice = np.concatenate(pts).reshape(-1, 3)
    key = (lattice[:, 0] * (k + 1) + lattice[:, 1]) * (k + 1) + lattice[:, 2]  # one integer per lattice point
    ukey, faces = np.unique(key, return_inverse=True)
    faces = faces.reshape(-1, 4)
    uniq = np.stack([ukey // (k + 1) ** 2, ukey // (k + 1) % (k + 1), ukey % (k + 1)], axis=1)
    v = uniq - k / 2.0
    v /= np.linalg.norm(v, axis=1)[:, None]
    # orient every face outwards: its normal against its centroid
    p = v[faces]
    nrm = np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 1])
    flip = np.einsum("ij,ij->i", nrm, p.mean(axis=1)) < 0
    faces[flip] = faces[flip][:, ::-1]
    return QuadMesh(v, faces)


def noisy_cube_sphere(k: int, seed: int = 0):
    """:func:`cube_sphere` with broadband noise of 0.2 edge lengths (independent Gaussian per coordinate)."""
    c = cube_sphere(k)
    rng = np.random.default_rng(seed)
    return c.with_vertices(c.vertices + rng.normal(scale=0.2 * c.mean_edge_length, size=c.vertices.shape))


def peer_solve(kind: str, M, rhs: np.ndarray, x0: np.ndarray, rtol: float) -> np.ndarray:
    """``M X = rhs`` (every column) by one of issue 15's peers, set-up included: ``"cholmod"`` (scikit-sparse's
    supernodal Cholesky), ``"pyamg"`` (SciPy's CG from ``x0`` to ``rtol``, preconditioned by pyamg's smoothed
    aggregation V-cycle), ``"superlu"`` (SciPy's SuperLU, COLAMD) or ``"superlu_mmd"`` (MMD(AᵀA + A))."""
    from scipy.sparse.linalg import cg, splu

    if kind == "cholmod":
        from sksparse.cholmod import cholesky

        return cholesky(M.tocsc())(rhs)
    if kind == "pyamg":
        import pyamg

        P = pyamg.smoothed_aggregation_solver(M).aspreconditioner(cycle="V")
        return np.stack([cg(M, rhs[:, k], x0=x0[:, k], rtol=rtol, M=P)[0] for k in range(rhs.shape[1])], axis=1)
    if kind in ("superlu", "superlu_mmd"):
        return splu(M.tocsc(), permc_spec="MMD_AT_PLUS_A" if kind == "superlu_mmd" else "COLAMD").solve(rhs)
    raise ValueError(f"peer_solve: unknown peer {kind!r}")


def fresh_runs(script: str, args: list[str], repeat: int) -> tuple[dict, list[float]]:
    """Run ``script --row ARGS`` in ``repeat`` fresh processes; the median run's JSON and all wall times."""
    runs = []
    for _ in range(max(1, repeat)):
        out = subprocess.run([sys.executable, script, "--row", *args], capture_output=True, text=True, check=True)
        runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
    walls = sorted(r["wall_s"] for r in runs)
    median = runs[[r["wall_s"] for r in runs].index(walls[len(walls) // 2])]
    return median, walls


def interleaved_runs(script: str, args: list[str], repeat: int, against: str) -> tuple[tuple, tuple]:
    """``fresh_runs`` of this checkout and of the package at ``against`` (a checkout's root, put first on
    ``PYTHONPATH``), one process of each in turn: on a machine whose speed drifts, both see the same drift.
    Returns ``((median, walls), (median, walls))``, this checkout's first."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [against, os.environ.get("PYTHONPATH")])))
    runs: tuple[list, list] = ([], [])
    for _ in range(max(1, repeat)):
        for side, extra in ((0, None), (1, env)):
            out = subprocess.run([sys.executable, script, "--row", *args], capture_output=True, text=True, check=True,
                                 env=extra)
            runs[side].append(json.loads(out.stdout.strip().splitlines()[-1]))
    result = []
    for side in runs:
        walls = sorted(r["wall_s"] for r in side)
        result.append((side[[r["wall_s"] for r in side].index(walls[len(walls) // 2])], walls))
    return result[0], result[1]


def spread(walls: list[float]) -> str:
    """`` (lo–hi)`` for more than one run."""
    return f" ({walls[0]:.3f}–{walls[-1]:.3f})" if len(walls) > 1 else ""


def planarize_case(name: str, noise: str = "zigzag"):
    """(face, clean mesh, faired noisy mesh) of a planarize benchmark case: "E1"–"E4" or "F100".

    ``noise="broadband"`` replaces ``perturb`` by independent Gaussian offsets of 0.2 mean edge lengths per
    coordinate (seed 7, the corners kept), as :func:`noisy_grid` has them.

    The recipe of ``benchmarks/perf/bench_planarize.py``: the thesis example (or F100, a 100 × 100
    sample of ``surfaces.wavy(10000, 10000, 400, waves_u=0.5, waves_v=1.0)``), ``perturb`` with its
    tangential/normal noise (F100: 0.25/0.1), seed 7, corners fixed, then ``fair(noisy, iterations=3)`` with
    ``line_curvature="fair"``, the single solve the planarize tables of docs/planarize.md were measured with
    (the default ``"auto"`` holds 36 windows on E2's first iteration and changes its input; F100, E1, E3, E4 are
    the same with either).
    """
    from quadnodes import surfaces
    from quadnodes.fairing import fair
    from quadnodes.noise import perturb
    from quadnodes.topology import fixed_vertices

    if name == "F100":
        face = surfaces.wavy(10000.0, 10000.0, 400.0, waves_u=0.5, waves_v=1.0)
        rows, cols, amount = 100, 100, (0.25, 0.1)
    else:
        from quadnodes.report import THESIS_EXAMPLES

        ex = THESIS_EXAMPLES[name]
        face = getattr(surfaces, ex.surface)()
        rows, cols, amount = ex.rows, ex.cols, ex.noise
    clean = surfaces.sample(face, rows, cols)
    if noise == "broadband":
        offsets = np.random.default_rng(7).normal(scale=0.2 * clean.mean_edge_length, size=clean.vertices.shape)
        offsets[fixed_vertices(clean, "corners")] = 0.0  # (held as perturb holds them)
        noisy = clean.with_vertices(clean.vertices + offsets)
    elif noise == "zigzag":
        noisy, _ = perturb(clean, tangential=amount[0], normal=amount[1], seed=7, fix="corners")
    else:
        raise ValueError(f"noise: expected one of {NOISES}, got {noise!r}")
    faired, _ = fair(noisy, iterations=3, line_curvature="fair")
    return face, clean, faired


#: ``--cache`` (bench_planarize.py's ``--iteration`` rows, studies/planarize_cg.py): the inputs are kept
#: here (``out/`` is not committed)
CACHE = Path(__file__).resolve().parents[1] / "out" / "bench-cache"


def planarize_big_case(size: int, cache: bool = False):
    """(clean, faired) of the F100 recipe at ``size × size`` (no 4× finer sample: 16 M points at 1000).

    With ``cache``, the two vertex arrays are read from (or, the first time, written to)
    ``out/bench-cache/planarize-F{size}.npz``: the same meshes without the ~6 min build at 1000×1000.
    Delete the file after a change to ``surfaces``, ``perturb`` or ``fair``.
    """
    from quadnodes import surfaces
    from quadnodes.mesh import QuadMesh, grid_faces

    path = CACHE / f"planarize-F{size}.npz"
    if cache and path.exists():
        data = np.load(path)
        faces = grid_faces(size, size)
        return (QuadMesh(data["clean"], faces, grid_shape=(size, size)),
                QuadMesh(data["faired"], faces, grid_shape=(size, size)))
    from quadnodes.fairing import fair
    from quadnodes.noise import perturb

    face = surfaces.wavy(10000.0, 10000.0, 400.0, waves_u=0.5, waves_v=1.0)
    clean = surfaces.sample(face, size, size)
    noisy, _ = perturb(clean, tangential=0.25, normal=0.1, seed=7, fix="corners")
    faired, _ = fair(noisy, iterations=3)
    if cache:
        CACHE.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp.npz")
        np.savez(tmp, clean=clean.vertices, faired=faired.vertices)
        tmp.replace(path)
    return clean, faired
