"""Seeded noise that makes real zigzags in quad meshes.

Three kinds, each with an amplitude in units of the local edge length (the mean
length of the edges at the vertex), so the same settings work at any scale:

- ``tangential``: along every structure line, consecutive vertices are pushed to
  alternate sides of the line within the surface (the zigzag of sampled or
  remeshed surfaces);
- ``normal``: vertices alternate above and below the surface (a checkerboard by
  graph distance);
- ``jitter``: isotropic Gaussian noise.

Random magnitudes come from ``numpy.random.default_rng(seed)``; the same
arguments give the same bytes.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike
from scipy.sparse.csgraph import connected_components, dijkstra

from . import _validate
from .errors import InputError
from .mesh import QuadMesh
from .topology import fixed_vertices

__all__ = ["NoiseReport", "vertex_normals", "local_edge_length", "checkerboard", "perturb"]


@dataclass(frozen=True)
class NoiseReport:
    """What :func:`perturb` did: its settings, how many vertices moved and how far (in the mesh's unit)."""

    tangential: float
    normal: float
    jitter: float
    seed: int
    fix: str
    n_fixed: int
    n_moved: int
    moved_max: float
    moved_mean: float
    seconds: float
    unit: str = "mm"

    def to_dict(self) -> dict:
        """Plain-Python form (JSON-ready)."""
        return asdict(self)


def vertex_normals(mesh: QuadMesh) -> np.ndarray:
    """Unit vertex normals, area-weighted from the quads' diagonal cross products.

    Returns
    -------
    (n, 3) float64

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> vertex_normals(grid(2, 2))[0].tolist()
    [0.0, 0.0, 1.0]
    """
    p = mesh.vertices[mesh.faces]
    fn = 0.5 * np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 1])
    n = np.zeros_like(mesh.vertices)
    for k in range(3):
        n[:, k] = np.bincount(mesh.faces.reshape(-1), weights=np.repeat(fn[:, k], 4), minlength=mesh.n_vertices)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, length, out=np.zeros_like(n), where=length > 0)


def local_edge_length(mesh: QuadMesh) -> np.ndarray:
    """Mean length of the edges at every vertex, ``(n,)``."""
    e = mesh.topology.edges
    length = np.linalg.norm(mesh.vertices[e[:, 1]] - mesh.vertices[e[:, 0]], axis=1)
    total = np.bincount(e.reshape(-1), weights=np.repeat(length, 2), minlength=mesh.n_vertices)
    return total / np.maximum(mesh.topology.valence, 1)


def checkerboard(mesh: QuadMesh) -> np.ndarray:
    """Parity (0/1) of the edge-graph distance from the smallest vertex of each component.

    On a grid this is the checkerboard ``(i + j) % 2``.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> checkerboard(grid(2, 3)).tolist()
    [0, 1, 0, 1, 0, 1]
    """
    from .topology import adjacency

    a = adjacency(mesh)
    ncomp, label = connected_components(a, directed=False)
    roots = np.full(ncomp, mesh.n_vertices)
    np.minimum.at(roots, label, np.arange(mesh.n_vertices))
    d = dijkstra(a, directed=False, indices=roots, unweighted=True, min_only=True)
    return (d.astype(np.int64) % 2)


def perturb(
    mesh: QuadMesh,
    *,
    tangential: float = 0.0,
    normal: float = 0.0,
    jitter: float = 0.0,
    seed: int = 0,
    fix: Literal["none", "corners", "boundary"] = "corners",
    fixed: ArrayLike | None = None,
    region: ArrayLike | None = None,
) -> tuple[QuadMesh, NoiseReport]:
    """Add seeded zigzag noise to a quad mesh.

    Parameters
    ----------
    mesh : QuadMesh
    tangential : float
        Sideways zigzag amplitude along structure lines, in local edge lengths
        (each offset is ``amplitude × U(0.5, 1)``).
    normal : float
        Alternating normal offset amplitude, in local edge lengths.
    jitter : float
        Standard deviation of isotropic noise, in local edge lengths.
    seed : int
        Seed of ``numpy.random.default_rng`` (``>= 0``).
    fix : {"none", "corners", "boundary"}
        Vertices left untouched (:func:`quadnodes.topology.fixed_vertices`). The
        default ``"corners"`` agrees with fairing and planarizing, which hold the
        corners: noise there could never be removed.
    fixed : (n,) bool or int indices, optional
        More vertices left untouched.
    region : (n,) bool or int indices, optional
        Only these vertices move (default: all).

    Returns
    -------
    mesh : QuadMesh
    report : NoiseReport

    Raises
    ------
    InputError
        On negative or non-finite amplitudes, a negative seed, a bad mask, or noise so strong that
        an edge collapses to zero length.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> from quadnodes.zigzag import detect
    >>> noisy, report = perturb(grid(8, 8), tangential=0.2, seed=1)
    >>> detect(noisy, 0.01).n_free > 0, report.n_fixed
    (True, 4)
    """
    t0 = time.perf_counter()
    _validate.quad_mesh(mesh)
    amp_t = _validate.nonnegative_number(tangential, "tangential")
    amp_n = _validate.nonnegative_number(normal, "normal")
    amp_j = _validate.nonnegative_number(jitter, "jitter")
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool):
        raise InputError(f"seed: expected an integer, got {seed!r}")
    if seed < 0:  # numpy.random.default_rng would say only "expected non-negative integer"
        raise InputError(f"seed: expected an integer >= 0, got {int(seed)}")
    n = mesh.n_vertices
    held = fixed_vertices(mesh, fix, fixed)
    moving = ~held
    if region is not None:
        moving &= _validate.vertex_mask(region, n, "region")
    rng = np.random.default_rng(int(seed))
    x = mesh.vertices
    h = local_edge_length(mesh)
    nrm = vertex_normals(mesh)
    lines = mesh.topology.structure_lines

    # tangential: one random magnitude per (line, vertex) entry, alternating sign
    idx = lines.indices
    line = np.repeat(np.arange(len(lines)), lines.lengths)
    pos = np.arange(idx.size) - lines.offsets[line]
    length = lines.lengths[line]
    closed = lines.closed[line]
    start = lines.offsets[line]
    nxt = np.where(closed, start + (pos + 1) % length, start + np.minimum(pos + 1, length - 1))
    prv = np.where(closed, start + (pos - 1) % length, start + np.maximum(pos - 1, 0))
    tangent = x[idx[nxt]] - x[idx[prv]]
    side = np.cross(nrm[idx], tangent)
    s_len = np.linalg.norm(side, axis=1, keepdims=True)
    side = np.divide(side, s_len, out=np.zeros_like(side), where=s_len > 0)
    mag_t = rng.uniform(0.5, 1.0, idx.size)
    sign = np.where(pos % 2 == 0, 1.0, -1.0)
    contrib = (amp_t * mag_t * sign)[:, None] * side
    d = np.zeros_like(x)
    for k in range(3):
        d[:, k] = np.bincount(idx, weights=contrib[:, k], minlength=n)

    mag_n = rng.uniform(0.5, 1.0, n)
    d += (amp_n * mag_n * np.where(checkerboard(mesh) == 0, 1.0, -1.0))[:, None] * nrm
    d += amp_j * rng.standard_normal((n, 3)) / np.sqrt(3.0)

    d *= h[:, None]
    d[~moving] = 0.0
    out = mesh.with_vertices(x + d)
    moved = np.linalg.norm(d, axis=1)
    return out, NoiseReport(
        tangential=amp_t, normal=amp_n, jitter=amp_j, seed=int(seed), fix=fix, n_fixed=int(held.sum()),
        n_moved=int((moved > 0).sum()), moved_max=float(moved.max()), moved_mean=float(moved.mean()),
        seconds=time.perf_counter() - t0, unit=mesh.unit,
    )
