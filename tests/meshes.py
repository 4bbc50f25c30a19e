"""Small test meshes beyond grids: extraordinary vertices, an L-shape with a hole, random quads with thin faces."""

from __future__ import annotations

import numpy as np

from quadnodes.mesh import QuadMesh, grid_faces


def subdivide(vertices: np.ndarray, polygons: list[list[int]]) -> tuple[np.ndarray, list[list[int]]]:
    """Linear Catmull–Clark-style split: every n-gon becomes n quads around its centroid."""
    verts = [np.asarray(v, dtype=float) for v in vertices]
    edge_point: dict[tuple[int, int], int] = {}

    def mid(a: int, b: int) -> int:
        key = (min(a, b), max(a, b))
        if key not in edge_point:
            edge_point[key] = len(verts)
            verts.append(0.5 * (verts[a] + verts[b]))
        return edge_point[key]

    quads = []
    for poly in polygons:
        c = len(verts)
        verts.append(np.mean([verts[i] for i in poly], axis=0))
        k = len(poly)
        for i in range(k):
            quads.append([poly[i], mid(poly[i], poly[(i + 1) % k]), c, mid(poly[(i - 1) % k], poly[i])])
    return np.array(verts), quads


def extraordinary_mesh(levels: int = 2) -> QuadMesh:
    """A pentagon and a triangle sharing an edge, split ``levels`` times.

    The pentagon's centre is an interior vertex of valence 5, the triangle's of
    valence 3. A gentle bump in z makes the geometry non-planar.
    """
    t = 2 * np.pi * np.arange(5) / 5
    pent = np.stack([np.cos(t), np.sin(t), np.zeros(5)], axis=1) * 2.0
    # triangle on the edge (0, 1), outside the pentagon
    apex = (pent[0] + pent[1]) * 1.4
    v = np.vstack([pent, apex])
    polys = [[0, 1, 2, 3, 4], [1, 0, 5]]
    for _ in range(levels):
        v, polys = subdivide(v, polys)
    v[:, 2] = 0.1 * np.sin(v[:, 0]) * np.cos(v[:, 1])
    return QuadMesh(v, np.array(polys))


def random_quads(points: int, levels: int = 2, seed: int = 0) -> QuadMesh:
    """The Delaunay triangulation of ``points`` seeded random points of the unit square (z a gentle wave), split
    ``levels`` times: extraordinary vertices everywhere, and long thin faces where the triangles are slivers."""
    from scipy.spatial import Delaunay

    xy = np.random.default_rng(seed).random((points, 2))
    v = np.column_stack([xy, 0.05 * np.sin(6 * xy[:, 0]) * np.cos(4 * xy[:, 1])])
    polys = Delaunay(xy).simplices.tolist()
    for _ in range(levels):
        v, polys = subdivide(v, polys)
    return QuadMesh(np.asarray(v), np.array(polys))


def l_shape_with_hole(n: int = 9) -> QuadMesh:
    """An ``n × n`` vertex grid minus its upper-right quarter (an L) with a 2×2-face hole."""
    faces = grid_faces(n, n)
    cells = np.arange(len(faces))
    i, j = divmod(cells, n - 1)
    h = (n - 1) // 2
    keep = ~((i >= h) & (j >= h)) & ~((i >= 1) & (i <= 2) & (j >= 1) & (j <= 2))
    faces = faces[keep]
    used = np.unique(faces)
    remap = np.full(n * n, -1)
    remap[used] = np.arange(used.size)
    y, x = np.divmod(np.arange(n * n), n)
    v = np.stack([x, y, 0.05 * x * y], axis=1).astype(float)[used]
    return QuadMesh(v, remap[faces])
