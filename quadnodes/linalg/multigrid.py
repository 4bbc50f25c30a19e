"""Two-grid preconditioning on a grid: conjugate-gradient steps that do not grow as the weight falls.

At a small weight ω the slow modes of a fairing matrix ``M = AᵀA + ωI`` are smooth: a structure line's
energy does not see a motion that is quadratic along it, so only ω holds the global biquadratic motions
and their neighbours, and Gauss–Seidel's steps grow as 1/√ω (1,168 at ω = 10⁻⁴, 3,910 at 10⁻⁵ on the
300² bench sheet). A coarse grid carries them: every ``stride``-th grid row and column (and the last), a
prolongation ``P`` that interpolates along the grid's rows and columns by cubic Lagrange polynomials
(exact on quadratics, so the coarse grid holds the motions the lines cannot see), the Galerkin coarse
matrix ``C = PᵀMP`` factorized once. One application of :class:`TwoGrid` is the symmetric two-grid
cycle

    ``x = (D + L)⁻¹ r``,  ``x += P C⁻¹ Pᵀ (r − M x)``,  ``x += (D + U)⁻¹ (r − M x)``

(a forward Gauss–Seidel sweep, the coarse correction, a backward sweep): symmetric positive definite,
so CG may use it. On the 300² bench sheet fair's solve takes 77–107 steps with it from ω = 10⁻³ down to 10⁻⁶
(only the solver's error target moves with ω), where Gauss–Seidel's go from 380 to 13,074; a step costs about
ten of Gauss–Seidel's in Eisenstat's form
(about half of it the coarse solve), so it pays below ω ≈ 10⁻⁴
(``python benchmarks/studies/multigrid.py --solver --size 300``; ``docs/fairing.md``, "The two-grid path").

On a cylinder or torus grid (closed lines, the seams' diagonals) the coarse lines close around too: every
``stride``-th node of a closed line (the last interval, across the seam, may be shorter), each fine node
interpolated from the two coarse nodes on each side counted across the seam; the sweeps are then the
compressed rows' (:class:`~quadnodes.linalg.gauss_seidel.CsrGaussSeidel`).

On any other quad mesh (extraordinary vertices, holes, a closed box) the coarse space comes from its
structure lines (:func:`line_interpolation`): every ``stride``-th line, counted side by side from the lines
that bound the grid-like patches, kept; coarse nodes where kept lines cross; cubic interpolation along the kept
lines, then along each other line between them. :class:`LineTwoGrid` is the same cycle on that ``P`` in
compressed rows. On cube-spheres of 15,002 and 101,402 vertices fair's solve takes 38–53 steps with it from
ω = 10⁻³ to 10⁻⁶ (every 3rd line, as fair keeps them up to 450,000 unknowns; every 4th: 75–103), where
Gauss–Seidel's go from 500 to 16,358
(``python benchmarks/studies/multigrid.py --solver --mesh cube-sphere --size 50``, ``--size 130``).
Where faces are long and thin (a vertex tied far more strongly along one of its lines than along the other)
the point sweeps leave error smooth along the strong line and rough across it, which no coarse node carries:
there :class:`LineTwoGrid` takes a damped line step beside each sweep, banded solves along each vertex's most
strongly tied line (``lines``). On 111,873 random quads (Delaunay slivers split four times) the cycle's steps
fell from 140 to 38 at ω = 10⁻⁴ (``--mesh random --size 300 --line-step off``, ``on``; ``docs/fairing.md``).

Examples
--------
>>> import numpy as np
>>> cubic_interpolation(7, 2).toarray()[1].round(4).tolist()  # the fine node between coarse nodes 0 and 1
[0.3125, 0.9375, -0.3125, 0.0625]
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .cg import PathLinePreconditioner
from .direct import Factorization, factorize
from .gauss_seidel import CsrGaussSeidel, SymmetricGaussSeidel, backward_solve, forward_solve, sweep_scratch
from .threads import RowBlocks

__all__ = ["TWO_GRID_STRIDE", "coarse_matrix", "coarse_nodes", "cubic_interpolation", "grid_interpolation",
           "line_interpolation", "line_spectral_radius", "LINE_DAMPING", "TwoGrid", "LineTwoGrid"]

#: Coarse grid spacing, in grid rows and columns. On the 300² sheet from ω = 10⁻³ down: 2 takes 18–23 steps but
#: factorizes a quarter of the unknowns (4.2–6.5 s in all); 4 takes 77–107 steps (1.7–2.4 s); 8 takes 289–650
#: (3.0–5.9 s) (``python benchmarks/studies/multigrid.py --solver --size 300 --strides 2 4 8``).
TWO_GRID_STRIDE = 4


def _per_axis(stride: int | tuple[int, int]) -> tuple[int, int]:
    """``(rows', cols')`` strides from one stride or a pair."""
    if np.ndim(stride) == 0:
        return int(stride), int(stride)  # type: ignore[arg-type]
    sr, sc = stride  # type: ignore[misc]
    return int(sr), int(sc)


def coarse_nodes(n: int, stride: int, closed: bool = False) -> np.ndarray:
    """The coarse nodes of a line of ``n`` nodes: ``0, stride, 2·stride, …`` and ``n − 1`` (closed: without it).

    Parameters
    ----------
    n : int
        Fine nodes (≥ 1).
    stride : int
        Fine nodes per coarse interval (≥ 1).
    closed : bool
        A closed line (node ``n − 1`` beside node 0): no extra last node, the last interval
        wraps around to node 0 (it may be shorter than ``stride``).

    Returns
    -------
    (m,) int64
        The coarse nodes' indices on the fine line, ascending.

    Examples
    --------
    >>> coarse_nodes(10, 4).tolist()
    [0, 4, 8, 9]
    >>> coarse_nodes(10, 4, closed=True).tolist()
    [0, 4, 8]
    """
    coarse = np.arange(0, n, stride)
    return coarse if closed or coarse[-1] == n - 1 else np.append(coarse, n - 1)


def _lagrange(t: np.ndarray, xs: np.ndarray) -> np.ndarray:
    """``(E, taps)`` Lagrange weights at positions ``t`` (``(E,)``) through the nodes ``xs`` (``(E, taps)``)."""
    taps = xs.shape[1]
    weights = np.ones(xs.shape)
    for a in range(taps):
        for b in range(taps):
            if b != a:
                weights[:, a] *= (t - xs[:, b]) / (xs[:, a] - xs[:, b])
    return weights


def cubic_interpolation(n: int, stride: int, closed: bool = False) -> sp.csr_matrix:
    """``(n, m)`` interpolation along a line of ``n`` nodes from its :func:`coarse_nodes`.

    Each fine node takes the Lagrange polynomial of degree ``min(3, m − 1)`` through the
    coarse nodes nearest it (two on each side where there are), so the interpolation is
    exact on polynomials of that degree; a coarse node is copied. On a closed line the
    two coarse nodes on each side are counted across the seam (positions unwrapped), so a
    polynomial in the distance along the line is reproduced at every node.

    Parameters
    ----------
    n : int
        Fine nodes (≥ 2).
    stride : int
        Fine nodes per coarse interval (≥ 2).
    closed : bool
        A closed line (:func:`coarse_nodes`); it needs at least 4 coarse nodes.

    Returns
    -------
    (n, m) scipy.sparse.csr_matrix
        ``m = ⌈(n − 1) / stride⌉ + 1`` coarse nodes (closed: ``⌈n / stride⌉``).

    Raises
    ------
    ValueError
        When ``n < 2`` or ``stride < 2``, or a closed line has fewer than 4 coarse nodes.

    Examples
    --------
    >>> P = cubic_interpolation(10, 4)  # coarse nodes 0, 4, 8 and 9
    >>> P.shape
    (10, 4)
    >>> t = np.arange(10.0)
    >>> bool(np.allclose(P @ (t[[0, 4, 8, 9]] ** 3), t ** 3))
    True
    >>> Q = cubic_interpolation(20, 4, closed=True)  # coarse nodes 0, 4, …, 16; node 18 from 12, 16, 20 ≡ 0, 24 ≡ 4
    >>> Q[18].indices.tolist(), bool(np.isclose(Q[18].sum(), 1.0))
    ([0, 1, 3, 4], True)
    """
    if n < 2 or stride < 2:
        raise ValueError(f"cubic_interpolation: expected n >= 2 and stride >= 2, got n={n}, stride={stride}")
    coarse = coarse_nodes(n, stride, closed)
    m = coarse.size
    if closed and m < 4:
        raise ValueError(f"cubic_interpolation: a closed line of {n} nodes has {m} coarse nodes at stride "
                         f"{stride}; at least 4 are needed")
    knot = np.zeros(n, dtype=bool)
    knot[coarse] = True
    # one line whose knots are the coarse nodes: _along_lines' rule (two on each side, across the seam if closed)
    rows, knots, weights = _along_lines(np.zeros(n, dtype=np.int64), np.arange(n), np.array([n]),
                                        np.array([closed]), knot, ~knot)
    column = np.cumsum(knot) - 1  # (a knot's column; the line's entries are its nodes)
    P = sp.csr_matrix((np.r_[np.ones(m), weights], (np.r_[coarse, rows], np.r_[np.arange(m), column[knots]])),
                      shape=(n, m))
    P.sum_duplicates()
    P.eliminate_zeros()
    return P


def grid_interpolation(rows: int, cols: int, stride: int | tuple[int, int], moving: np.ndarray | None = None,
                       wrap: tuple[bool, bool] = (False, False)) -> sp.csr_matrix:
    """The ``(rows·cols, m)`` tensor-product :func:`cubic_interpolation` of a grid numbered row after row.

    Parameters
    ----------
    rows, cols : int
        The fine grid's shape; vertex ``i·cols + j`` is at row ``i``, column ``j``.
    stride : int or (int, int)
        Fine rows and columns per coarse interval (≥ 2), or one per axis ``(rows', cols')``.
    moving : (rows·cols,) bool, optional
        The vertices a correction may move; the others' rows are zero (a fixed vertex stays put).
    wrap : (bool, bool)
        ``(wrap_rows, wrap_cols)`` as :class:`~quadnodes.linalg.grid.GridPattern`'s: whether row
        ``rows − 1`` lies beside row 0 (the columns close around) and column ``cols − 1`` beside
        column 0 (the rows close around); a cylinder has one, a torus both.

    Returns
    -------
    (rows·cols, m) scipy.sparse.csr_matrix

    Raises
    ------
    ValueError
        When ``rows`` or ``cols`` is below 2 or ``stride`` below 2, or a closed direction has fewer
        than 4 coarse nodes (:func:`cubic_interpolation`).

    Examples
    --------
    >>> grid_interpolation(5, 9, 4).shape  # coarse rows 0, 4; coarse columns 0, 4, 8
    (45, 6)
    """
    sr, sc = _per_axis(stride)
    return _tensor(cubic_interpolation(rows, sr, wrap[0]), cubic_interpolation(cols, sc, wrap[1]), moving)


def _tensor(rows_p: sp.csr_matrix, cols_p: sp.csr_matrix, moving: np.ndarray | None) -> sp.csr_matrix:
    """``rows_p ⊗ cols_p`` with the rows of the vertices that do not move zero."""
    P = sp.kron(rows_p, cols_p, format="csr")
    if moving is not None:
        P = (sp.diags(np.asarray(moving, dtype=np.float64)) @ P).tocsr()
        P.eliminate_zeros()
    return P


def _along_lines(line: np.ndarray, pos: np.ndarray, lengths: np.ndarray, closed: np.ndarray, knot: np.ndarray,
                 target: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Interpolation along lines from their knots: ``(entries, knot entries, weights)``, one triple per tap.

    ``line``, ``pos``: every entry's line and position on it (entries in line order, positions ascending);
    ``knot``, ``target``: ``(S,)`` bool, the entries that are knots and those to interpolate. Each target
    entry takes the Lagrange polynomial through the (up to) four knots of its line nearest it, two on each
    side where there are (as :func:`cubic_interpolation`; on a closed line counted across the seam, and of a
    lower degree where it has fewer than 4 knots; a line without knots gives nothing). An open line's ends
    should be knots (else its ends are extrapolated).
    """
    n_lines = lengths.size
    q = np.bincount(line[knot], minlength=n_lines)  # knots per line
    kentry = np.flatnonzero(knot)
    kstart = np.zeros(n_lines + 1, dtype=np.int64)
    np.cumsum(q, out=kstart[1:])
    left = np.cumsum(knot) - 1 - kstart[line]  # the line's knot at or before each entry (closed: −1 before the first)
    e = np.flatnonzero(target)
    ring = closed[line[e]]
    taps_of = np.minimum(q[line[e]], 4)
    parts = []
    for taps in (1, 2, 3, 4):
        for wrap in (False, True):
            sel = e[(taps_of == taps) & (ring == wrap)]
            if not sel.size:
                continue
            ln = line[sel]
            qq = q[ln][:, None]
            if wrap:
                around = left[sel][:, None] - (taps // 2 - 1) + np.arange(taps)
                knots = kentry[kstart[ln][:, None] + around % qq]
                xs = pos[knots] + lengths[ln][:, None] * np.floor_divide(around, qq)
            else:
                first = np.clip(left[sel] - (taps // 2 - 1), 0, q[ln] - taps)
                knots = kentry[kstart[ln][:, None] + first[:, None] + np.arange(taps)]
                xs = pos[knots]
            weights = _lagrange(pos[sel].astype(np.float64), xs.astype(np.float64))
            parts.append((np.repeat(sel, taps), knots.ravel(), weights.ravel()))
    if not parts:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0)
    return tuple(np.concatenate(a) for a in zip(*parts))  # type: ignore[return-value]


def line_interpolation(indices: np.ndarray, offsets: np.ndarray, closed: np.ndarray, n: int,
                       stride: int = TWO_GRID_STRIDE) -> tuple[sp.csr_matrix, np.ndarray]:
    """A coarse space for nodes on lines that cross (a quad mesh's structure lines): every ``stride``-th line kept.

    The nodes lie on lines (every node on two that cross it, except where lines end); two lines are
    *side by side* where consecutive nodes of a third lie one on each. On a grid this is
    :func:`grid_interpolation` without the grid:

    1. **Kept lines.** A line through a node where another line ends (a boundary's, or one from an
       extraordinary node: the lines that cut the nodes into grid-like patches) is a seed, and so is
       the first line of every family of side-by-side lines without one (a torus's loops). A line
       is kept when its distance from the nearest seed, counted in side-by-side steps, is a multiple
       of ``stride`` (of two such lines side by side at the same distance, where two fronts meet, the
       first), and so is the middle line of a gap of more than ``stride + 1`` lines where fronts meet.
    2. **Coarse nodes.** Where two kept lines cross, a kept line's ends (every extraordinary node and corner:
       their lines are seeds), and enough nodes on each kept line that no two consecutive ones are more than
       ``stride`` apart. (A line's end on no kept line is one too; a quad mesh's lines leave none.)
    3. **Along the kept lines**, every other node is interpolated from the line's coarse nodes by
       the cubic Lagrange polynomial in the position along the line (two coarse nodes on each side;
       :func:`cubic_interpolation`'s rule, with uneven spacing).
    4. **Between them**, a node on no kept line is interpolated the same way along each of its lines
       from the nodes of that line that lie on kept lines (their values from step 3), and the lines'
       results are averaged.

    On an open grid the rows' and the columns' results are the same tensor product, so ``P``
    reproduces every ``iᵃ jᵇ`` (``a, b ≤ 3``) as :func:`grid_interpolation` does; on any mesh each
    row of ``P`` sums to 1 (a node that no line interpolates, on closed lines that no kept line crosses,
    keeps a zero row).

    Parameters
    ----------
    indices : (S,) int64
        The nodes of every line, one line after another (``StructureLines.indices``).
    offsets : (L + 1,) int64
        Line ``i`` is ``indices[offsets[i]:offsets[i + 1]]``.
    closed : (L,) bool
        Whether each line closes around (its last node beside its first).
    n : int
        Number of nodes (every index below it).
    stride : int
        Side-by-side steps between kept lines, and the longest gap between coarse nodes along one (≥ 2).

    Returns
    -------
    P : (n, m) scipy.sparse.csr_matrix
        The prolongation: row ``v`` gives node ``v``'s value from the ``m`` coarse nodes' values.
    coarse : (m,) int64
        The coarse nodes, ascending (``P[coarse]`` is the identity).

    Raises
    ------
    ValueError
        When ``stride`` is below 2 or the lines' arrays disagree.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> from quadnodes.topology import structure_lines
    >>> lines = structure_lines(grid(9, 9))  # 9 × 9 nodes: rows and columns 0, 4 and 8 kept
    >>> P, coarse = line_interpolation(lines.indices, lines.offsets, lines.closed, 81)
    >>> coarse.tolist()
    [0, 4, 8, 36, 40, 44, 72, 76, 80]
    >>> i, j = np.divmod(np.arange(81), 9)
    >>> bool(np.allclose(P @ (i * j**2)[coarse], i * j**2))
    True
    """
    from scipy.sparse.csgraph import connected_components, dijkstra

    if stride < 2:
        raise ValueError(f"line_interpolation: expected stride >= 2, got {stride}")
    indices = np.asarray(indices, dtype=np.int64)
    offsets = np.asarray(offsets, dtype=np.int64)
    closed = np.asarray(closed, dtype=bool)
    lengths = np.diff(offsets)
    n_lines = lengths.size
    if n_lines == 0 or closed.shape != (n_lines,) or offsets[0] != 0 or offsets[-1] != indices.size \
            or (lengths < 1).any() \
            or (indices.size and not 0 <= indices.min() <= indices.max() < n):
        raise ValueError("line_interpolation: indices, offsets and closed do not describe lines of nodes 0 … n − 1")
    S = indices.size
    line = np.repeat(np.arange(n_lines), lengths)
    pos = np.arange(S) - offsets[line]
    ring = closed[line]
    end = ~ring & ((pos == 0) | (pos == lengths[line] - 1))
    lines_at = np.bincount(indices, minlength=n)

    # 1. seeds: lines through a node where another line ends; side-by-side lines from nodes on exactly two lines
    seed = np.zeros(n_lines, dtype=bool)
    seed[line[np.bincount(indices[end], minlength=n)[indices] > end]] = True
    order = np.argsort(indices, kind="stable")
    sorted_nodes = indices[order]
    pair = np.flatnonzero((sorted_nodes[:-1] == sorted_nodes[1:]) & (lines_at[sorted_nodes[:-1]] == 2))
    other = np.full(S, -1, dtype=np.int64)  # the other line through each entry's node
    other[order[pair]], other[order[pair + 1]] = line[order[pair + 1]], line[order[pair]]
    nxt = np.arange(1, S + 1)
    last = pos == lengths[line] - 1
    nxt[last] = offsets[line[last]]  # (a closed line's last node is beside its first; an open one's pair dropped)
    step = ~(last & ~ring) & (other >= 0) & (other[nxt] >= 0)
    a, b = other[step], other[nxt[step]]
    keep_pair = a != b
    G = sp.coo_matrix((np.ones(int(keep_pair.sum())), (a[keep_pair], b[keep_pair])), shape=(n_lines, n_lines)).tocsr()
    G = (G + G.T).tocsr()  # (side by side both ways: the rules below read every neighbour)
    beside_a, beside_b = G.nonzero()
    n_comp, label = connected_components(G, directed=False)
    seeded = np.zeros(n_comp, dtype=bool)
    seeded[label[seed]] = True
    first_line = np.full(n_comp, n_lines)
    np.minimum.at(first_line, label, np.arange(n_lines))
    seed[first_line[~seeded]] = True
    distance = np.rint(dijkstra(G, directed=False, indices=np.flatnonzero(seed), unweighted=True,
                                min_only=True)).astype(np.int64)  # (finite: every family has a seed)
    kept = distance % stride == 0
    # where two fronts meet at the same distance, two kept lines side by side (rows 4 and 5 of 10): the first only
    twin = (kept[beside_a] & kept[beside_b] & (distance[beside_a] == distance[beside_b]) & (beside_b < beside_a)
            & (distance[beside_a] > 0))  # (never a seed: its ends must be coarse)
    kept[beside_a[twin]] = False
    # where they meet farther apart (rows 8 and 15 of 24 at stride 4), a gap of up to 2·stride − 1 lines: keep its
    # middle line where a line lies this far from every kept line (a gap of stride + 2 lines or more; an odd
    # stride's, of stride + 1)
    far = stride // 2 + 1
    while True:
        apart = dijkstra(G, directed=False, indices=np.flatnonzero(kept), unweighted=True, min_only=True)
        ridge = np.isfinite(apart) & (apart >= far)
        if not ridge.any():
            break
        # a ridge line with no ridge neighbour farther out, or as far but numbered lower, is kept (the lowest of
        # the farthest is never beaten, so every pass keeps one more)
        beaten = np.zeros(n_lines, dtype=bool)
        rival = ridge[beside_a] & ridge[beside_b] & ((apart[beside_b] > apart[beside_a])
                                                     | ((apart[beside_b] == apart[beside_a]) & (beside_b < beside_a)))
        beaten[beside_a[rival]] = True
        kept |= ridge & ~beaten

    # 2. coarse nodes
    on_kept = kept[line]
    kept_at = np.bincount(indices[on_kept], minlength=n)
    coarse = kept_at >= 2
    coarse[indices[end & on_kept]] = True
    ends = indices[end]
    coarse[ends[kept_at[ends] == 0]] = True  # (none where the lines are a quad mesh's: their ends lie on seeds)
    lonely = kept & closed & (np.bincount(line[on_kept & coarse[indices]], minlength=n_lines) == 0)
    coarse[indices[offsets[:-1][lonely]]] = True  # (a closed kept line no kept line crosses: its first node)
    ke = np.flatnonzero(on_kept & coarse[indices])  # every kept line's coarse nodes, in line order
    kl, kp = line[ke], pos[ke]
    first_of = np.r_[0, np.cumsum(np.bincount(kl, minlength=n_lines))[:-1]]
    final = np.r_[kl[1:] != kl[:-1], True]
    succ = np.where(final, first_of[kl], np.arange(ke.size) + 1)
    span = np.where(final, kp[succ] + lengths[kl] - kp, kp[succ] - kp)  # to the next coarse node (closed: around)
    long = (~final | closed[kl]) & (span > stride)
    inserts = -(-span[long] // stride) - 1
    g = np.repeat(np.flatnonzero(long), inserts)
    j = np.arange(g.size) - np.repeat(np.cumsum(inserts) - inserts, inserts) + 1
    at = (kp[g] + np.rint(j * span[g] / (np.repeat(inserts, inserts) + 1)).astype(np.int64)) % lengths[kl[g]]
    coarse[indices[offsets[kl[g]] + at]] = True
    nodes = np.flatnonzero(coarse)
    m = nodes.size
    column = np.full(n, -1, dtype=np.int64)
    column[nodes] = np.arange(m)

    # 3. along the kept lines
    rows, knots, w = _along_lines(line, pos, lengths, closed, on_kept & coarse[indices], on_kept & ~coarse[indices])
    P = sp.csr_matrix((np.r_[np.ones(m), w],
                       (np.r_[nodes, indices[rows]], np.r_[np.arange(m), column[indices[knots]]])), shape=(n, m))
    # 4. between them: along every other line from its nodes on kept lines, averaged over the lines
    known = (kept_at > 0) | coarse
    rows, knots, w = _along_lines(line, pos, lengths, closed, ~on_kept & known[indices],
                                  ~on_kept & ~known[indices])
    if rows.size:
        fine = indices[rows]
        lines_used = np.bincount(indices[np.unique(rows)], minlength=n)
        W = sp.csr_matrix((w / lines_used[fine], (fine, indices[knots])), shape=(n, n))
        P = P + W @ P
    P = P.tocsr()
    P.sum_duplicates()
    P.eliminate_zeros()
    return P, nodes


def coarse_matrix(M: sp.spmatrix, P: sp.spmatrix) -> sp.csr_matrix:
    """The two-grid cycle's coarse matrix: the Galerkin product ``PᵀMP`` made definite.

    A coarse node whose every fine node is fixed (a zero column of ``P``) gets an identity row; every diagonal
    entry gains 1e-10 of itself, for coarse nodes that see the same few free vertices (dependent columns of
    ``P`` leave ``PᵀMP`` only semidefinite; a residual restricted by ``Pᵀ`` has no part along them, so the
    shift changes nothing that ``P`` brings back).

    Parameters
    ----------
    M : (n, n) sparse
        Symmetric positive definite.
    P : (n, m) sparse
        The prolongation.

    Returns
    -------
    (m, m) scipy.sparse.csr_matrix

    Examples
    --------
    >>> C = coarse_matrix(sp.identity(3, format="csr"), sp.csr_matrix(np.array([[1.0, 0.0], [1.0, 0.0], [0.0, 0.0]])))
    >>> C.toarray().round(12).tolist()
    [[2.0, 0.0], [0.0, 1.0]]
    """
    P = sp.csr_matrix(P)
    C = (P.T.tocsr() @ (M @ P)).tocsr()
    diagonal = C.diagonal()
    return (C + sp.diags(np.where(diagonal > 0, 1e-10 * diagonal, 1.0))).tocsr()


#: The line step's damping times the largest eigenvalue of ``L⁻¹M`` (a contraction below 2). On a 111,873-vertex
#: random quad mesh at ω = 10⁻⁶ (a throwaway prototype of the cycle): 1.0 took 44 steps, 1.5 39, 1.9 38.
LINE_DAMPING = 1.5
#: Lanczos steps estimating that eigenvalue (:func:`line_spectral_radius`; LINE_DAMPING leaves a margin of a
#: quarter for the estimate, which approaches it from below).
LINE_DAMPING_STEPS = 12


def line_spectral_radius(blocks: object, lines: PathLinePreconditioner, steps: int = LINE_DAMPING_STEPS,
                         seed: int = 0) -> float:
    """The largest eigenvalue of ``L⁻¹M`` (``L⁻¹``: ``lines``' solves), estimated by Lanczos steps.

    ``L⁻¹M`` is self-adjoint in the ``M``-inner product, so Lanczos in that product (one product with ``M`` and one
    line solve a step, as power steps would take) gives a tridiagonal matrix whose largest eigenvalue approaches
    the largest of ``L⁻¹M`` from below. Unlike the power steps' Rayleigh quotient it finds an isolated top
    eigenvalue that the random start barely holds: on a reviewer's throwaway 640,020-unknown matrix built so,
    12 power steps estimated 3.54 for a top of 5.0 (a damping of 1.5 over that makes the cycle indefinite);
    Lanczos found 5.0.

    Parameters
    ----------
    blocks : RowBlocks
        ``M`` (symmetric positive definite; its ``M``).
    lines : PathLinePreconditioner
        Line solves on ``M``.
    steps : int
        Lanczos steps (≥ 1; fewer where a step finds an invariant subspace).
    seed : int
        Seed of the random start.

    Returns
    -------
    float
        The estimate (positive).

    Examples
    --------
    >>> from quadnodes.linalg.cg import PathLinePreconditioner
    >>> M = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(6, 6), format="csr")
    >>> lines = PathLinePreconditioner(M, np.arange(6), np.eye(1, 6, dtype=bool)[0], kd=1)  # one path: L = M
    >>> round(line_spectral_radius(RowBlocks(M, threads=1), lines), 6)
    1.0
    """
    from scipy.linalg import eigvalsh_tridiagonal

    M, n = blocks.M, lines.k  # type: ignore[attr-defined]
    q = np.random.default_rng(seed).normal(size=(n, 1))
    p = M @ q  # (p = M q: the M-inner product; made by a product each step, never by the recurrence, whose
    # rounding blows up where β is small — a reviewer's 15-unknown case estimated up to 4,872 × the top that way)
    scale = float(np.sqrt(q[:, 0] @ p[:, 0]))
    q, p = q / scale, p / scale
    q_before = np.zeros_like(q)
    z = np.empty_like(q)
    alphas: list[float] = []
    betas: list[float] = []
    beta = 0.0
    for _ in range(max(1, steps)):
        lines.apply(p, z, 0, n, False)  # z = L⁻¹ M q
        alpha = float(z[:, 0] @ p[:, 0])  # ⟨L⁻¹Mq, q⟩_M
        alphas.append(alpha)
        w = z - alpha * q - beta * q_before
        Mw = M @ w
        size = float(np.hypot(alpha, beta))
        beta = float(np.sqrt(max(float(w[:, 0] @ Mw[:, 0]), 0.0)))
        if beta <= 1e-8 * size:  # (a nearly invariant subspace: its eigenvalues are the estimate's)
            break
        betas.append(beta)
        q_before = q
        q, p = w / beta, Mw / beta
    if len(betas) == len(alphas):
        betas.pop()
    return float(eigvalsh_tridiagonal(np.array(alphas), np.array(betas))[-1])


class _Cycle:
    """The symmetric two-grid cycle around Gauss–Seidel sweeps (see the module); subclasses give ``P``'s transfers."""

    whole = True  # (block_cg applies it to all rows at once)
    sweeps: SymmetricGaussSeidel | CsrGaussSeidel
    coarse: Factorization
    _n: int
    #: the damped line step beside the sweeps (:class:`LineTwoGrid` with ``lines``): None, or the line
    #: preconditioner and its damping
    line_solves: PathLinePreconditioner | None = None
    damping = 0.0

    def _factorize(self, M: sp.csr_matrix, P: sp.csr_matrix) -> None:
        """``coarse``: :func:`coarse_matrix` factorized; the cycle's vectors made on first use."""
        C = coarse_matrix(M, P)
        # minimum degree at any size: the Galerkin stencil (up to 81 couplings a row) fills less so than in nested
        # dissection (1000² sheet's 63,001 coarse nodes: 51 against 63 million entries, 4.3 against 10.6 s;
        # ``python benchmarks/studies/multigrid.py --coarse-factor --size 1000 --weights 0.000001``)
        self.coarse = factorize(C, kind="spd", what="two-grid coarse matrix", order="minimum_degree")
        self._buffers: dict = {}

    def apply(self, R: np.ndarray, Z: np.ndarray, lo: int, hi: int, columns: bool) -> None:
        """``Z = B⁻¹ R`` on all rows: the two-grid cycle of the module.

        Parameters
        ----------
        R : (c, kp) or (kp, c) float64
            Residuals, zero-padded past ``n`` (``block_cg``'s layout, ``columns``).
        Z : (c, kp) or (kp, c) float64
            Out: the preconditioned residuals (padding stays zero).
        lo, hi : int
            Ignored: applied to all rows at once (``whole``).
        columns : bool
            The layout: ``(c, kp)`` vectors (diagonal storage's, small compressed rows'), else ``(kp, c)``
            (compressed rows' sweeps only).
        """
        if self.sweeps.columns:  # the grid's sweeps take CG's (c, kp) vectors (diagonal storage's only layout)
            if not columns:  # pragma: no cover - diagonal storage always takes (c, k) vectors
                raise ValueError("TwoGrid: the grid's sweeps take (c, k) vectors")
            self._cycle(R, Z, R.shape)
            return
        n = self._n  # compressed rows' sweeps take (n, c) vectors
        if columns:
            Zt = self._cycle(np.ascontiguousarray(R[:, :n].T), None, (n, R.shape[0]))
            Z[:, :n] = Zt.T
            Z[:, n:] = 0.0
        else:  # (CG's (kp, c) vectors: the first n rows are the sweeps' layout)
            Z[:n] = self._cycle(R[:n], None, (n, R.shape[1]))
            Z[n:] = 0.0

    def _cycle(self, R: np.ndarray, Z: np.ndarray | None, shape: tuple[int, int]) -> np.ndarray:
        """The cycle on vectors in the sweeps' layout (``Z`` None: into a buffer of its own, returned)."""
        sw, n = self.sweeps, self._n
        if self._buffers.get("shape") != shape:  # (one set per vector shape: CG applies it every step)
            if sw.columns:  # (c, kp)
                scale = np.zeros(shape[1])
                scale[:n] = sw.scale
                c = shape[0]
            else:  # (n, c)
                scale, c = sw.scale[:, None], shape[1]
            self._buffers = {"shape": shape, "scale": scale,
                             "vectors": [np.zeros(shape) for _ in range(5 if sw.columns else 6)],
                             "scratch": sweep_scratch(sw, c)}
        s = self._buffers["scale"]
        V, X, Y, T, nothing = self._buffers["vectors"][:5]  # (nothing: never written, read as zeros)
        Z = self._buffers["vectors"][5] if Z is None else Z  # (compressed rows: a buffer of its own)
        scratch = self._buffers["scratch"]

        def fine(A: np.ndarray) -> np.ndarray:  # (c, ≥ n) rows of fine vectors: restrict's and prolong's view
            return A if sw.columns else A.T

        def residual() -> None:  # Y = R − M X
            sw.product(X, Y)
            np.subtract(R, Y, out=Y)

        def line_step() -> None:  # x += θ L⁻¹ (r − M x), then Y = r − M x again (compressed rows' (n, c) only)
            self.line_solves.apply(Y, V, 0, n, False)  # type: ignore[union-attr]
            np.multiply(V, self.damping, out=V)
            np.add(X, V, out=X)
            residual()

        np.multiply(R, s, out=V)  # x = (D + L)⁻¹ r = D^{-1/2} (I + L̃)⁻¹ D^{-1/2} r
        forward_solve(sw, V, nothing, T, scratch)
        np.multiply(T, s, out=X)
        residual()
        if self.line_solves is not None:
            line_step()
        self.prolong(self.coarse.solve(self.restrict(fine(Y))), fine(X))
        residual()
        if self.line_solves is not None:
            line_step()
        np.multiply(Y, s, out=V)  # x += (D + U)⁻¹ (r − M x)
        backward_solve(sw, V, Y, T, scratch)  # (Y, spent, takes a copy of V)
        np.multiply(T, s, out=Z)
        Z += X
        return Z

    def restrict(self, Y: np.ndarray) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def prolong(self, E: np.ndarray, X: np.ndarray) -> None:  # pragma: no cover - abstract
        raise NotImplementedError


class TwoGrid(_Cycle):
    """The symmetric two-grid cycle of a grid's matrix in diagonal storage, made once (see the module).

    Passed to :func:`~quadnodes.linalg.cg.block_cg` as ``precond`` (applied to all rows at once);
    the sweeps are :class:`~quadnodes.linalg.gauss_seidel.SymmetricGaussSeidel`'s on an open grid,
    :class:`~quadnodes.linalg.gauss_seidel.CsrGaussSeidel`'s (compressed rows, in the grid's numbering)
    on a cylinder or torus, on the blocks' threads; the coarse matrix a sparse Cholesky-like
    factorization (:func:`~quadnodes.linalg.direct.factorize`).

    Parameters
    ----------
    blocks : SymmetricDiagonalBlocks or DiagonalBlocks
        ``M`` (symmetric positive definite) in the grid's numbering: an open grid's offsets
        ``0, ±1, ±2, ±3, ±cols, ±2·cols, ±3·cols`` (``SymmetricDiagonalBlocks``), a closed grid's with
        the seams' diagonals too (:class:`~quadnodes.linalg.grid.GridPattern`); fixed vertices as
        identity rows.
    shape : (int, int)
        ``(rows, cols)`` of the grid.
    moving : (rows·cols,) bool
        The free vertices (the coarse correction moves no other).
    stride : int or (int, int)
        Coarse grid spacing (:data:`TWO_GRID_STRIDE`), or one per axis ``(rows', cols')``: an
        anisotropic matrix (couplings much weaker along one axis) wants a finer coarse grid along the weak
        axis, where the point sweeps leave the error rough.
    wrap : (bool, bool)
        ``(wrap_rows, wrap_cols)``: whether the grid's columns and its rows close around
        (:func:`grid_interpolation`); the sweeps are then the compressed rows'.

    Attributes
    ----------
    P : (n, m) scipy.sparse.csr_matrix
        The prolongation.
    lines, lines_t : tuple of scipy.sparse.csr_matrix
        ``P``'s factors along the grid's columns and rows (``P = lines[0] ⊗ lines[1]`` at the moving
        vertices) and their transposes: the transfers apply these.
    coarse : Factorization
        ``PᵀMP`` (plus 1e-10 of its diagonal) factorized.
    sweeps : SymmetricGaussSeidel or CsrGaussSeidel
        The smoother.
    strides : (int, int)
        The coarse grid's spacing along the rows' and the columns' axis.
    shape : (int, int)
    moving : (n,) float64
        1 at the free vertices, 0 at the fixed ones.

    Raises
    ------
    ValueError
        When ``shape`` does not match the matrix, or the grid has fewer than two coarse
        nodes per direction (``rows`` or ``cols`` ≤ ``stride``; a closed direction needs 4).
    numpy.linalg.LinAlgError
        When a diagonal entry of ``M`` is not positive.
    quadnodes.errors.InputError
        When the coarse matrix cannot be factorized (it is made definite: not expected).

    Examples
    --------
    >>> from quadnodes.linalg.cg import SymmetricDiagonalBlocks, block_cg
    >>> rows = cols = 24
    >>> offsets = np.array([-3 * cols, -2 * cols, -cols, -3, -2, -1, 0, 1, 2, 3, cols, 2 * cols, 3 * cols])
    >>> stencil = np.array([-1.0, 6.0, -15.0, -1.0, 6.0, -15.0, 40.001, -15.0, 6.0, -1.0, -15.0, 6.0, -1.0])
    >>> data = np.repeat(stencil[:, None], rows * cols, axis=1)
    >>> blocks = SymmetricDiagonalBlocks(offsets, data, threads=1)
    >>> M = blocks.M.tocsr()
    >>> b = np.ones((rows * cols, 3))
    >>> x, steps, res = block_cg(blocks, b, np.zeros_like(b), rtol=1e-10, maxiter=500,
    ...                          precond=TwoGrid(blocks, (rows, cols), np.ones(rows * cols, bool), stride=4))
    >>> bool(np.abs(M @ x - b).max() < 1e-6), steps < 100
    (True, True)
    """

    def __init__(self, blocks: object, shape: tuple[int, int], moving: np.ndarray,
                 stride: int | tuple[int, int] = TWO_GRID_STRIDE, wrap: tuple[bool, bool] = (False, False)) -> None:
        rows, cols = (int(v) for v in shape)
        M = blocks.M.tocsr()  # type: ignore[attr-defined]
        n = M.shape[0]
        if rows * cols != n:
            raise ValueError(f"shape: {rows} × {cols} grid does not match the matrix's {n} rows")
        self.strides = _per_axis(stride)
        if rows <= self.strides[0] or cols <= self.strides[1]:
            raise ValueError(f"shape: a {rows} × {cols} grid has no coarse grid at stride {stride}")
        wrap = (bool(wrap[0]), bool(wrap[1]))
        self.lines = (cubic_interpolation(rows, self.strides[0], wrap[0]),
                      cubic_interpolation(cols, self.strides[1], wrap[1]))
        self.lines_t = tuple(L.T.tocsr() for L in self.lines)
        self.P = _tensor(*self.lines, moving)  # (grid_interpolation's, from the factors already made)
        # the grid's fast sweeps need an open grid's symmetric storage; the seams' diagonals take compressed rows
        fast = not any(wrap) and hasattr(blocks, "upper")
        self.sweeps = SymmetricGaussSeidel(blocks) if fast else CsrGaussSeidel(blocks)
        self.shape = (rows, cols)
        self.moving = np.asarray(moving, dtype=np.float64)
        self._n = n
        self._factorize(M, self.P)

    def restrict(self, Y: np.ndarray) -> np.ndarray:
        """``Pᵀ y`` of every row ``y`` of ``Y``, along the grid's columns, then its rows.

        Parameters
        ----------
        Y : (c, ≥ n) float64
            Fine vectors, one per row (rows past ``n``, padding, are not read).

        Returns
        -------
        (m, c) float64
        """
        (rows, cols), (Lr, Lc), n = self.shape, self.lines_t, self._n
        out = np.empty((Lr.shape[0] * Lc.shape[0], Y.shape[0]))
        for j, y in enumerate(Y):
            along_columns = Lr @ (y[:n] * self.moving).reshape(rows, cols)  # (coarse rows, cols)
            out[:, j] = (Lc @ along_columns.T).T.ravel()
        return out

    def prolong(self, E: np.ndarray, X: np.ndarray) -> None:
        """``X[j] += P e_j`` for every column ``e_j`` of ``E``: along the grid's rows, then its columns.

        Parameters
        ----------
        E : (m, c) float64
            Coarse vectors, one per column.
        X : (c, ≥ n) float64
            Fine vectors, added to in place (rows past ``n`` untouched).
        """
        (Lr, Lc), n = self.lines, self._n
        for j in range(E.shape[1]):
            coarse = E[:, j].reshape(Lr.shape[1], Lc.shape[1])
            fine = Lr @ np.ascontiguousarray((Lc @ coarse.T).T)  # (rows, cols)
            fine = fine.ravel()
            fine *= self.moving
            X[j, :n] += fine


class LineTwoGrid(_Cycle):
    """The symmetric two-grid cycle of any mesh's matrix in compressed rows, on a given prolongation (see the module).

    What :class:`TwoGrid` is on a grid, for unknowns with no grid: ``P`` from the mesh's structure lines
    (:func:`line_interpolation`, its rows at the unknowns), the Galerkin coarse matrix ``PᵀMP``
    factorized once, and :class:`~quadnodes.linalg.gauss_seidel.CsrGaussSeidel`'s sweeps in the
    matrix's own numbering, on the blocks' threads. Passed to :func:`~quadnodes.linalg.cg.block_cg` as
    ``precond`` (applied to all rows at once).

    With ``lines`` (banded solves along the structure lines, :class:`~quadnodes.linalg.cg.PathLinePreconditioner`)
    a damped line step ``x += θ L⁻¹ (r − M x)`` follows the forward sweep and precedes the backward one, so the
    cycle stays symmetric. Where faces are long and thin a vertex is tied far more strongly along one line than
    along the other; Gauss–Seidel's point sweeps leave error that is smooth along the strong line and rough
    across it, which no coarse node between the lines can carry, and the line solves clear it. ``θ`` is
    :data:`LINE_DAMPING` over ``L⁻¹M``'s largest eigenvalue (estimated by :data:`LINE_DAMPING_STEPS` Lanczos steps,
    :func:`line_spectral_radius`): while the estimate is within a quarter of it, ``θ`` is below 2 over it, so the
    step is a contraction in the ``M``-norm and the cycle positive definite.

    Parameters
    ----------
    blocks : RowBlocks
        ``M`` (symmetric positive definite, compressed rows) and its row ranges.
    P : (n, m) sparse
        The prolongation: ``P[i]`` gives unknown ``i``'s correction from the ``m`` coarse values.
    lines : PathLinePreconditioner, optional
        Line solves on ``M`` for the line step (default: none, the point sweeps alone).

    Attributes
    ----------
    P, P_t : scipy.sparse.csr_matrix
        The prolongation and its transpose (the restriction).
    coarse : Factorization
        ``PᵀMP`` (plus 1e-10 of its diagonal) factorized.
    sweeps : CsrGaussSeidel
        The smoother.
    line_solves : PathLinePreconditioner or None
        The line step's solves (``lines``).
    damping : float
        The line step's ``θ`` (0 without ``lines``).

    Raises
    ------
    ValueError
        When ``P`` has not one row per unknown.
    numpy.linalg.LinAlgError
        When a diagonal entry of ``M`` is not positive.
    quadnodes.errors.InputError
        When the coarse matrix cannot be factorized (it is made definite: not expected).

    Examples
    --------
    >>> from quadnodes.linalg.cg import block_cg
    >>> from quadnodes.linalg.threads import RowBlocks
    >>> from quadnodes.mesh import grid
    >>> from quadnodes.topology import structure_lines
    >>> lines = structure_lines(grid(24, 24))
    >>> third = sp.diags([-1.0, 3.0, -3.0, 1.0], [0, 1, 2, 3], shape=(21, 24))  # third differences along a line
    >>> A = sp.vstack([third @ sp.csr_matrix((np.ones(24), (np.arange(24), line)), shape=(24, 576)) for line in lines])
    >>> M = (A.T @ A + 1e-6 * sp.eye(576)).tocsr()  # (a tiny weight: Gauss–Seidel alone takes thousands of steps)
    >>> P, coarse = line_interpolation(lines.indices, lines.offsets, lines.closed, 576)
    >>> b = np.ones((576, 3))
    >>> x, steps, res = block_cg(RowBlocks(M, threads=1), b, np.zeros_like(b), rtol=1e-10, maxiter=500,
    ...                          precond=LineTwoGrid(RowBlocks(M, threads=1), P))
    >>> bool(np.abs(M @ x - b).max() < 1e-6), steps < 100  # (x is about 1e6: b is a motion the lines do not see)
    (True, True)
    """

    def __init__(self, blocks: object, P: sp.spmatrix, lines: PathLinePreconditioner | None = None) -> None:
        M = blocks.M.tocsr()  # type: ignore[attr-defined]
        n = M.shape[0]
        if P.shape[0] != n:
            raise ValueError(f"P: {P.shape[0]} rows for the matrix's {n} unknowns")
        if lines is not None and lines.k != n:
            raise ValueError(f"lines: {lines.k} unknowns for the matrix's {n}")
        self.P = sp.csr_matrix(P)
        self.P_t = self.P.T.tocsr()
        # the transfers on the blocks' threads: rows of P (fine) and of Pᵀ (coarse) in ranges of equal nonzeros
        threads = len(blocks.ranges)  # type: ignore[attr-defined]
        self._prolong_rows = RowBlocks(self.P, threads=threads, columns=False)
        self._restrict_rows = RowBlocks(self.P_t, threads=threads, columns=False)  # (one range below 2 ×
        # PARALLEL_MIN_ROWS coarse nodes: there the restriction is a small part of the cycle)
        self.sweeps = CsrGaussSeidel(blocks)
        self._n = n
        if lines is not None:
            self.line_solves, self.damping = lines, LINE_DAMPING / line_spectral_radius(blocks, lines)
        self._factorize(M, self.P)

    def restrict(self, Y: np.ndarray) -> np.ndarray:
        """``Pᵀ y`` of every row ``y`` of ``Y`` (``(c, ≥ n)``, rows past ``n`` not read): ``(m, c)``."""
        Yt = Y[:, : self._n].T
        if not Yt.flags.c_contiguous:  # (the cycle passes its (n, c) vectors transposed: this never copies there)
            Yt = np.ascontiguousarray(Yt)
        rows = self._restrict_rows
        E = np.empty((self.P_t.shape[0], Y.shape[0]))
        rows.run(lambda lo, hi: rows.matvec(Yt, E, lo, hi))
        return E

    def prolong(self, E: np.ndarray, X: np.ndarray) -> None:
        """``X[j] += P e_j`` for every column ``e_j`` of ``E`` (``(m, c)``; ``X`` ``(c, ≥ n)``, added to in place)."""
        Xt, rows = X[:, : self._n].T, self._prolong_rows
        E = np.ascontiguousarray(E)
        if not Xt.flags.c_contiguous:  # (the cycle passes its (n, c) vectors transposed: never taken there)
            X[:, : self._n] += (self.P @ E).T
            return
        rows.run(lambda lo, hi: rows.matvec(E, Xt, lo, hi, accumulate=True))
