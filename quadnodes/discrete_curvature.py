"""Discrete curvature of a quad mesh (thesis 2.2.3) and the operators the chapter-3 methods share.

A quad mesh has no canonical triangulation, so every triangle-based quantity
here is taken over **both triangulations of every quad** — ``(0, 1, 2) + (0, 2, 3)``
and ``(0, 1, 3) + (1, 2, 3)`` — and the two are averaged (per vertex sums of
areas, angles and cotangent weights are averaged before any division). The
result does not depend on which diagonal a file happens to list first, and on a
planar, convex quad both triangulations give the same angle sums.

- :func:`cotangent_laplacian`: the Laplace–Beltrami (stiffness) matrix
  ``L_ij = −½(cot α_ij + cot β_ij)``, ``L_ii = −Σ_j L_ij``, averaged over the two
  triangulations: mesh edges get weight from both, quad diagonals from one
  (half weight each). Symmetric, rows sum to zero. The thesis's ``S`` (eq. 26–27)
  is ``2 L`` restricted to the inner vertices.
- :func:`curvature`: per vertex mean curvature (cotangent formula with mixed
  areas, Meyer et al.), Gaussian curvature (angle defect over the mixed area,
  ``G(4)``) and the variants ``G(1)``–``G(3)``, principal curvatures
  ``H ± sqrt(max(H² − G, 0))``, principal directions (Moreton–Séquin's fit of
  normal curvatures, eq. 28) and the structure lines' discrete curvature of
  Definition 2.33.

Curvatures at boundary vertices are NaN (a one-sided neighbourhood has no
angle defect and no full cotangent ring).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from . import _validate
from ._arrays import unique_values
from .mesh import QuadMesh

__all__ = [
    "face_normals",
    "vertex_normals",
    "cotangent_laplacian",
    "moreton_sequin",
    "line_curvature",
    "curvature",
    "CURVATURE_KEYS",
]

#: The per-vertex scalar fields of :func:`curvature` (what a view can colour panels by).
CURVATURE_KEYS: tuple[str, ...] = ("mean", "gaussian", "gaussian_1", "gaussian_2", "gaussian_3", "k1", "k2",
                                   "line_max")

# the two triangulations of a quad (corner indices)
_TRIANGULATIONS = (np.array([[0, 1, 2], [0, 2, 3]]), np.array([[0, 1, 3], [1, 2, 3]]))
# a triangle's next corner and the one after (c + 1, c + 2 mod 3)
_NEXT, _AFTER = np.array([1, 2, 0]), np.array([2, 0, 1])


def face_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit normals of the quads (cross product of the diagonals), ``(m, 3)``.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> m = grid(2, 2)
    >>> face_normals(m.vertices, m.faces).tolist()
    [[0.0, 0.0, 1.0]]
    """
    p = vertices[faces]
    fn = np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 1])
    length = np.linalg.norm(fn, axis=1, keepdims=True)
    return np.divide(fn, length, out=np.zeros_like(fn), where=length > 0)


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit vertex normals: the normalized mean of the adjoining faces' unit normals (as Yamada et al.).

    Parameters
    ----------
    vertices : (n, 3) float64
    faces : (m, 4) int64

    Returns
    -------
    (n, 3) float64

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> m = grid(3, 3)
    >>> vertex_normals(m.vertices, m.faces)[4].tolist()
    [0.0, 0.0, 1.0]
    """
    n = vertices.shape[0]
    fn = face_normals(vertices, faces)
    idx = faces.reshape(-1)
    out = np.empty((n, 3))
    for k in range(3):  # three bincounts, not a loop over vertices
        out[:, k] = np.bincount(idx, weights=np.repeat(fn[:, k], 4), minlength=n)
    length = np.linalg.norm(out, axis=1, keepdims=True)
    return np.divide(out, length, out=np.zeros_like(out), where=length > 0)


def _triangles(faces: np.ndarray, which: int) -> np.ndarray:
    return faces[:, _TRIANGULATIONS[which]].reshape(-1, 3)


def _corner_data(x: np.ndarray, tri: np.ndarray, *, full: bool = True) -> dict[str, np.ndarray]:
    """Per triangle corner: cotangent, and with ``full`` the angle, opposite edge length², both edge
    lengths² and the triangle area."""
    p = x[tri]  # (t, 3 corners, 3)
    e1 = p[:, _NEXT] - p  # to the next corner
    e2 = p[:, _AFTER] - p  # to the one after
    dot = np.einsum("tcj,tcj->tc", e1, e2)
    cr = np.linalg.norm(np.cross(e1, e2), axis=2)
    out = {"cot": dot / np.maximum(cr, 1e-300)}
    if full:
        e1sq = np.einsum("tcj,tcj->tc", e1, e1)
        out.update(angle=np.arctan2(cr, dot), opp2=e1sq[:, _NEXT],  # the edge from corner c+1 to c+2
                   e1sq=e1sq, e2sq=np.einsum("tcj,tcj->tc", e2, e2), area=0.5 * cr[:, 0])
    return out


def _cotangent_matrix(n: int, faces: np.ndarray, cots: list[np.ndarray]) -> sp.csr_matrix:
    """:func:`cotangent_laplacian` from the corner cotangents of both triangulations."""
    rows, cols, vals = [], [], []
    for which in (0, 1):  # the two triangulations
        tri = _triangles(faces, which)
        cot = cots[which]
        for c in range(3):
            i, j = tri[:, (c + 1) % 3], tri[:, (c + 2) % 3]
            w = 0.25 * cot[:, c]  # ½ cot, averaged over 2 triangulations
            rows += [i, j]
            cols += [j, i]
            vals += [-w, -w]
    r, c_, v = np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)
    off = sp.csr_matrix((v, (r, c_)), shape=(n, n))
    off.sum_duplicates()
    diag = -np.asarray(off.sum(axis=1)).ravel()
    return (off + sp.diags(diag)).tocsr()


def cotangent_laplacian(mesh: QuadMesh, *, vertices: np.ndarray | None = None) -> sp.csr_matrix:
    """The cotangent Laplace–Beltrami (stiffness) matrix of a quad mesh, averaged over both triangulations.

    ``L_ij = −½ (cot α_ij + cot β_ij)`` for the angles opposite the edge ``ij`` in
    the triangles holding it, summed per triangulation and averaged over the two
    triangulations of every quad; ``L_ii = −Σ_j L_ij``. Quad diagonals appear with
    the weight of the one triangulation that has them (half weight).

    Parameters
    ----------
    mesh : QuadMesh
    vertices : (n, 3) float64, optional
        Positions to measure the angles at (default: the mesh's).

    Returns
    -------
    (n, n) scipy.sparse.csr_matrix
        Symmetric, each row sums to zero; ``L @ x`` is ``−2 A H n`` (area-weighted
        mean-curvature normal) at interior vertices.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> L = cotangent_laplacian(grid(3, 3))
    >>> L[4].toarray().round(3).tolist()
    [[0.0, -1.0, 0.0, -1.0, 4.0, -1.0, 0.0, -1.0, 0.0]]
    """
    _validate.quad_mesh(mesh)
    x = mesh.vertices if vertices is None else np.asarray(vertices, dtype=np.float64)
    cots = [_corner_data(x, _triangles(mesh.faces, w), full=False)["cot"] for w in (0, 1)]
    return _cotangent_matrix(mesh.n_vertices, mesh.faces, cots)


def _areas(mesh: QuadMesh, x: np.ndarray, corners: list[dict[str, np.ndarray]] | None = None
           ) -> dict[str, np.ndarray]:
    """Per-vertex sums over both triangulations (averaged): angle sum, areas, G(2) term.

    ``corners``: :func:`_corner_data` (full) of both triangulations, if the caller has it already.
    """
    n = mesh.n_vertices
    out = {k: np.zeros(n) for k in ("angle", "area", "voronoi", "mixed", "g2")}
    for which in (0, 1):
        tri = _triangles(mesh.faces, which)
        d = _corner_data(x, tri) if corners is None else corners[which]
        area = d["area"][:, None].repeat(3, axis=1)
        cot = d["cot"]
        # Voronoi part of the triangle at corner c: (|e1|² cot(angle at c+2) + |e2|² cot(angle at c+1)) / 8
        vor = (d["e1sq"] * cot[:, _AFTER] + d["e2sq"] * cot[:, _NEXT]) / 8.0
        obtuse_here = cot < 0
        obtuse_any = obtuse_here.any(axis=1, keepdims=True)
        mixed = np.where(obtuse_any, np.where(obtuse_here, area / 2, area / 4), vor)
        idx = tri.reshape(-1)
        out["angle"] += np.bincount(idx, d["angle"].reshape(-1), minlength=n)
        out["area"] += np.bincount(idx, area.reshape(-1), minlength=n)
        out["voronoi"] += np.bincount(idx, vor.reshape(-1), minlength=n)
        out["mixed"] += np.bincount(idx, mixed.reshape(-1), minlength=n)
        out["g2"] += np.bincount(idx, (cot * d["opp2"]).reshape(-1), minlength=n)
    return {k: v / 2.0 for k, v in out.items()}


def _tangent_basis(nrm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors spanning the plane normal to each row of ``nrm``."""
    axis = np.zeros_like(nrm)
    axis[np.arange(len(nrm)), np.argmin(np.abs(nrm), axis=1)] = 1.0
    bx = np.cross(nrm, axis)
    bx /= np.maximum(np.linalg.norm(bx, axis=1, keepdims=True), 1e-300)
    return bx, np.cross(nrm, bx)


def moreton_sequin(mesh: QuadMesh, *, vertices: np.ndarray | None = None,
                   normals: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Moreton–Séquin's least-squares fit of normal curvatures (thesis eq. 28) at every vertex.

    Every neighbour ``q_j`` (along a mesh edge or a quad diagonal) gives a normal
    curvature ``κ_j = 2 <q_j − q, n> / |q_j − q|²`` in the direction ``t_j`` (its
    projection into the tangent plane); Euler's theorem ``κ = t_x² x0 + t_x t_y x1
    + t_y² x2`` is fitted by least squares. The curvatures follow the sign of
    eq. 28: a sphere with outward normals has ``H = −1/R``.

    Returns
    -------
    dict with
        ``"H"`` (n,) — ``(x0 + x2) / 2``; ``"dH_dt"`` (n,) — its derivative when the
        vertex moves by ``t`` along its normal (the linearization of eq. 29);
        ``"tensor"`` (n, 2, 2), ``"basis"`` (n, 2, 3), ``"normals"`` (n, 3) and
        ``"rank_ok"`` (n,) bool (at least three independent directions).

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> fit = moreton_sequin(grid(3, 3))
    >>> float(fit["H"][4])
    0.0
    """
    x = mesh.vertices if vertices is None else vertices
    n = mesh.n_vertices
    nrm = vertex_normals(x, mesh.faces) if normals is None else normals
    # neighbours: mesh edges and quad diagonals (8 for a regular vertex)
    f = mesh.faces
    i = np.concatenate([f[:, k] for k in range(4)] * 3)
    j = np.concatenate([f[:, (k + s) % 4] for s in (1, 2, 3) for k in range(4)])
    key = unique_values(i * n + j)
    i, j = key // n, key % n
    d = x[j] - x[i]
    ni = nrm[i]
    dn = np.einsum("ij,ij->i", d, ni)
    d2 = np.einsum("ij,ij->i", d, d)
    bx, by = _tangent_basis(nrm)
    tx = np.einsum("ij,ij->i", d, bx[i])
    ty = np.einsum("ij,ij->i", d, by[i])
    tl = np.hypot(tx, ty)
    ok = tl > 1e-12 * np.sqrt(d2)
    tx = np.where(ok, tx / np.maximum(tl, 1e-300), 0.0)
    ty = np.where(ok, ty / np.maximum(tl, 1e-300), 0.0)
    a = np.stack([tx * tx, tx * ty, ty * ty], axis=1)
    kappa = 2.0 * dn / d2
    M = np.zeros((n, 3, 3))
    r = np.zeros((n, 3))
    s = np.zeros((n, 3))
    for p in range(3):
        r[:, p] = np.bincount(i, a[:, p] * kappa, minlength=n)
        s[:, p] = np.bincount(i, a[:, p] / d2, minlength=n)
        for q in range(3):
            M[:, p, q] = np.bincount(i, a[:, p] * a[:, q], minlength=n)
    # M is symmetric positive semi-definite: one eigendecomposition gives its singular values (the
    # eigenvalues' magnitudes) and its pseudo-inverse (numpy's pinv cut-off, 1e-15 of the largest)
    w, V = np.linalg.eigh(M)
    sv = np.abs(w)
    top = sv.max(axis=1, keepdims=True)
    rank_ok = sv.min(axis=1) > 1e-8 * np.maximum(top[:, 0], 1e-300)
    winv = np.divide(1.0, w, out=np.zeros_like(w), where=sv > 1e-15 * top)
    Minv = np.einsum("nij,nj,nkj->nik", V, winv, V)
    coef = Minv @ r[:, :, None]
    xs = coef[:, :, 0]
    e = np.array([1.0, 0.0, 1.0])
    u = Minv @ e  # (n, 3): H = ½ u·r
    tensor = np.empty((n, 2, 2))
    tensor[:, 0, 0] = xs[:, 0]
    tensor[:, 0, 1] = tensor[:, 1, 0] = 0.5 * xs[:, 1]
    tensor[:, 1, 1] = xs[:, 2]
    return {
        "H": 0.5 * (xs[:, 0] + xs[:, 2]),
        "dH_dt": -np.einsum("ij,ij->i", u, s),  # κ_j(t) = κ_j − 2 t / |d_j|²
        "tensor": tensor,
        "basis": np.stack([bx, by], axis=1),
        "normals": nrm,
        "rank_ok": rank_ok,
    }


def line_curvature(mesh: QuadMesh, *, vertices: np.ndarray | None = None) -> np.ndarray:
    """Discrete curvature (Definition 2.33) at every vertex of every structure line.

    ``κ_i = 2 |(p_i − p_{i−1}) × (p_{i+1} − p_i)| / (|p_i − p_{i−1}| |p_{i+1} − p_i| |p_{i+1} − p_{i−1}|)``,
    the inverse radius of the circle through three consecutive points (the
    determinant of the planar formula is the cross product's length in 3-D).

    Returns
    -------
    (k,) float64
        Aligned with ``structure_lines(mesh).indices``; NaN at the two ends of an
        open line (closed lines wrap).

    Examples
    --------
    >>> from quadnodes.mesh import cylinder
    >>> k = line_curvature(cylinder(2, 12, radius=2.0))
    >>> bool(np.nanmax(np.abs(k[:12] - 0.5)) < 1e-12)
    True
    """
    x = mesh.vertices if vertices is None else vertices
    lines = mesh.topology.structure_lines
    idx = lines.indices
    off = lines.offsets
    length = np.diff(off)
    line = np.repeat(np.arange(len(length)), length)
    q = np.arange(idx.size) - off[line]
    L = length[line]
    closed = lines.closed[line]
    prev = np.where(closed, off[line] + (q - 1) % L, off[line] + np.maximum(q - 1, 0))
    nxt = np.where(closed, off[line] + (q + 1) % L, off[line] + np.minimum(q + 1, L - 1))
    a = x[idx] - x[idx[prev]]
    b = x[idx[nxt]] - x[idx]
    c = x[idx[nxt]] - x[idx[prev]]
    den = np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1) * np.linalg.norm(c, axis=1)
    num = 2.0 * np.linalg.norm(np.cross(a, b), axis=1)
    out = np.divide(num, den, out=np.full(idx.size, np.nan), where=den > 0)
    ends = ~closed & ((q == 0) | (q == L - 1))
    out[ends] = np.nan
    return out


def curvature(mesh: QuadMesh) -> dict[str, np.ndarray]:
    """Discrete curvatures of a quad mesh (thesis 2.2.3), per vertex and per structure-line vertex.

    Triangle quantities are averaged over both triangulations of every quad (see
    the module docstring). The mean curvature is signed: positive where the
    surface bends away from its normal (a sphere with outward normals, i.e.
    counter-clockwise faces seen from outside, has ``mean = 1/R``); the thesis's
    ``H = ½‖H(x)‖`` is its absolute value.

    Parameters
    ----------
    mesh : QuadMesh

    Returns
    -------
    dict of str to ndarray
        Per vertex, ``(n,)`` float64, NaN on the boundary:

        - ``"mean"``: ``½ <K, n>`` with the mean-curvature normal
          ``K = (1 / A_mixed) Σ_j ½(cot α_ij + cot β_ij)(x_i − x_j)``;
        - ``"gaussian"``: ``G(4) = (2π − Σ γ_i) / A_mixed``;
        - ``"gaussian_1"``: ``G(1) = 3 (2π − Σ γ_i) / A``, ``A`` the one-ring's triangle area;
        - ``"gaussian_2"``: ``G(2) = (2π − Σ γ_i) / (½A − ⅛ Σ cot γ_i d_i²)``;
        - ``"gaussian_3"``: ``G(3) = (2π − Σ γ_i) / A_Voronoi``;
        - ``"k1"``, ``"k2"``: ``H ± sqrt(max(H² − G, 0))`` (the thesis's clamp);
        - ``"line_max"``: the largest Definition-2.33 curvature of the structure
          lines through the vertex (NaN where none passes through it).

        Per vertex, ``(n, 3)``: ``"direction1"``, ``"direction2"`` — unit principal
        directions from Moreton–Séquin's fit (eq. 28), ``direction1`` belonging to
        the larger curvature; ``"normal"`` — the unit vertex normal.

        Per structure-line vertex, ``(k,)``: ``"line"`` — Definition 2.33, aligned
        with ``structure_lines(mesh).indices`` (NaN at open ends).

    Raises
    ------
    InputError
        If ``mesh`` is not a QuadMesh.

    Examples
    --------
    >>> from quadnodes.mesh import cylinder
    >>> c = curvature(cylinder(9, 64, radius=2.0, height=2.0))
    >>> round(float(c["mean"][4 * 64]), 3), round(float(c["gaussian"][4 * 64]), 6)
    (0.25, 0.0)
    """
    _validate.quad_mesh(mesh)
    x = mesh.vertices
    topo = mesh.topology
    n = mesh.n_vertices
    nrm = vertex_normals(x, mesh.faces)
    corners = [_corner_data(x, _triangles(mesh.faces, w)) for w in (0, 1)]  # shared by L and the areas
    L = _cotangent_matrix(n, mesh.faces, [c["cot"] for c in corners])
    A = _areas(mesh, x, corners)
    bnd = topo.boundary_vertices
    K = np.divide(L @ x, A["mixed"][:, None], out=np.full((n, 3), np.nan), where=A["mixed"][:, None] > 0)
    H = 0.5 * np.einsum("ij,ij->i", K, nrm)
    defect = 2 * np.pi - A["angle"]

    def ratio(num: np.ndarray, den: np.ndarray) -> np.ndarray:
        out = np.divide(num, den, out=np.full(n, np.nan), where=np.abs(den) > 0)
        out[bnd] = np.nan
        return out

    H[bnd] = np.nan
    G = ratio(defect, A["mixed"])
    disc = np.sqrt(np.maximum(H * H - G, 0.0))
    fit = moreton_sequin(mesh, vertices=x, normals=nrm)
    # eq. 28's sign is opposite to the cotangent formula's: flip so direction1 goes with k1
    w, v = np.linalg.eigh(-fit["tensor"])
    basis = fit["basis"]
    d1 = np.einsum("nk,nkj->nj", v[:, :, 1], basis)
    d2 = np.einsum("nk,nkj->nj", v[:, :, 0], basis)
    d1[bnd] = np.nan
    d2[bnd] = np.nan
    lines = topo.structure_lines
    lk = line_curvature(mesh, vertices=x)
    lmax = np.full(n, -np.inf)
    np.maximum.at(lmax, lines.indices, np.where(np.isnan(lk), -np.inf, lk))
    lmax[np.isinf(lmax)] = np.nan
    return {
        "mean": H,
        "gaussian": G,
        "gaussian_1": ratio(3.0 * defect, A["area"]),
        "gaussian_2": ratio(defect, 0.5 * A["area"] - A["g2"] / 8.0),
        "gaussian_3": ratio(defect, A["voronoi"]),
        "k1": H + disc,
        "k2": H - disc,
        "direction1": d1,
        "direction2": d2,
        "normal": nrm,
        "line": lk,
        "line_max": lmax,
    }
