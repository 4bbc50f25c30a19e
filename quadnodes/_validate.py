"""All input checking lives here: shapes, dtypes, indices, finiteness, parameters.

Functions return clean arrays (copies, never views of the caller's data) or raise
:class:`~quadnodes.errors.InputError` with a message that names what was received.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ._arrays import cross_rows, norm_rows
from .errors import InputError

__all__ = [
    "vertices_array",
    "grid_cell_base",
    "grid_wrap",
    "faces_array",
    "check_quad_mesh",
    "check_edge_lengths",
    "grid_edge_squares",
    "corner_turns",
    "vertex_mask",
    "positive_number",
    "nonnegative_number",
    "positive_int",
    "schedule",
    "finite_number",
    "point_grid",
    "unit_parameters",
    "quad_mesh",
    "choice",
    "flag",
    "renamed",
    "iteration_count",
    "grid_cells",
]

#: More iterations than this are refused: no method here needs them, and a typo such as
#: ``10**7`` would otherwise run for hours.
MAX_ITERATIONS = 100_000


def _readonly(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


def vertices_array(vertices: ArrayLike, name: str = "vertices") -> np.ndarray:
    """Return ``vertices`` as a fresh read-only ``(n, 3) float64`` array.

    Raises
    ------
    InputError
        If the array is not ``(n, 3)``, is empty, or holds a non-finite coordinate
        (the message names the first such vertex).
    """
    try:
        v = np.array(vertices, dtype=np.float64, copy=True)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name}: cannot convert to a float array ({exc})") from None
    if v.ndim != 2 or v.shape[1] != 3:
        raise InputError(f"{name}: expected shape (n, 3), got {v.shape}")
    if v.shape[0] == 0:
        raise InputError(f"{name}: the mesh is empty (0 vertices)")
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(
            f"{name}: vertex {i} has a non-finite coordinate {v[i].tolist()} "
            f"({int(bad.sum())} such vertices)"
        )
    return _readonly(v)


def faces_array(faces: ArrayLike, n_vertices: int, name: str = "faces") -> np.ndarray:
    """Return ``faces`` as a fresh read-only ``(m, 4) int64`` array of valid indices.

    Raises
    ------
    InputError
        On a wrong shape, non-integer values, an empty face list, an index out of
        ``[0, n_vertices)``, or a face that repeats a vertex.
    """
    raw = np.asarray(faces)
    if raw.dtype.kind == "f":
        if not np.all(np.isfinite(raw)) or not np.all(raw == np.round(raw)):
            raise InputError(f"{name}: indices must be integers, got dtype {raw.dtype}")
    elif raw.dtype.kind not in "iu" and raw.size:
        raise InputError(f"{name}: indices must be integers, got dtype {raw.dtype}")
    f = np.array(raw, dtype=np.int64, copy=True)
    if f.ndim != 2 or f.shape[1] != 4:
        raise InputError(f"{name}: expected shape (m, 4) for quads, got {f.shape}")
    if f.shape[0] == 0:
        raise InputError(f"{name}: the mesh is empty (0 faces)")
    out = (f < 0) | (f >= n_vertices)
    if out.any():
        fi, k = (int(x) for x in np.argwhere(out)[0])
        raise InputError(
            f"{name}: face {fi} refers to vertex {int(f[fi, k])}, "
            f"outside 0..{n_vertices - 1}"
        )
    s = np.sort(f, axis=1)
    rep = (s[:, 1:] == s[:, :-1]).any(axis=1)
    if rep.any():
        fi = int(np.flatnonzero(rep)[0])
        raise InputError(f"{name}: face {fi} repeats a vertex: {f[fi].tolist()}")
    return _readonly(f)


#: An edge shorter than this fraction of the mean edge length joins two near-duplicate
#: vertices (a weld that failed, a typo in a file): no method can work with it.
MIN_RELATIVE_EDGE = 1e-9


def grid_edge_squares(vertices: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Squared lengths of an open vertex grid's edges, in its edge list's order (each vertex's edge to the
    right, then the one below), by index arithmetic: ``(E,)``.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> grid_edge_squares(grid(2, 3, spacing=2.0).vertices, (2, 3)).tolist()
    [4.0, 4.0, 4.0, 4.0, 4.0, 4.0, 4.0]
    """
    V = vertices.reshape(tuple(shape) + (3,))
    sq = np.full(tuple(shape) + (2,), np.nan)
    for axis, d in enumerate((V[:, 1:] - V[:, :-1], V[1:] - V[:-1])):
        sq[: shape[0] - axis, : shape[1] - 1 + axis, axis] = np.einsum("ijk,ijk->ij", d, d)
    sq = sq.reshape(-1)
    return sq[~np.isnan(sq)]


def check_edge_lengths(vertices: np.ndarray, faces: np.ndarray, edges: np.ndarray | None = None, *,
                       grid_shape: tuple[int, int] | None = None) -> float:
    """Reject a zero-length edge or near-duplicate vertices (an edge below 1e-9 of the mean edge).

    ``edges`` (the mesh's unique edges, when known) halves the work; ``grid_shape`` (an open
    vertex grid's, whose edges ``edges`` then are, in their order) measures them without gathers.
    Returns the mean length of the edges measured: with ``edges`` the mesh's mean edge length as
    :attr:`quadnodes.mesh.QuadMesh.mean_edge_length` computes it (to the bit), without them the
    mean over every face's four sides; inf where lengths overflow, nan for no edge.

    Raises
    ------
    InputError
        Naming the face and the two vertices.
    """
    if edges is not None:
        start, end = edges[:, 0], edges[:, 1]
    else:
        start = faces.reshape(-1)
        end = np.roll(faces, -1, axis=1).reshape(-1)
    if start.size == 0:
        return float("nan")
    with np.errstate(over="ignore", invalid="ignore"):  # coordinates near the float limit
        if grid_shape is not None and edges is not None:
            sq = grid_edge_squares(vertices, grid_shape)
        else:
            d = np.take(vertices, end, axis=0)
            d -= np.take(vertices, start, axis=0)
            sq = np.einsum("ij,ij->i", d, d)
        mean = float(np.sqrt(sq).mean())
    if not np.isfinite(mean):  # lengths overflow: only exact duplicates can be told
        zero = np.ones(start.size, dtype=bool)
        for k in range(3):
            col = np.ascontiguousarray(vertices[:, k])
            zero &= col[start] == col[end]
        sq = np.where(zero, 0.0, np.inf)
        mean = np.inf
    short = sq <= (MIN_RELATIVE_EDGE * mean) ** 2 if np.isfinite(mean) else sq == 0
    if short.any():
        k = int(np.argmax(short))
        a, b = sorted((int(start[k]), int(end[k])))
        hs = np.flatnonzero(((faces == a) | (faces == b)).sum(axis=1) == 2)
        face = int(hs[0]) if hs.size else "?"
        if sq[k] == 0:
            raise InputError(f"faces: face {face} has a zero-length edge between vertices {a} and {b}")
        raise InputError(
            f"faces: face {face} joins near-duplicate vertices {a} and {b} (edge {np.sqrt(sq[k]):.3g}, "
            f"mean edge {mean:.3g}); merge them or remove the face"
        )
    return mean


def corner_turns(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """How many corners of each quad turn against its vector area, and which quads have no area.

    A quad's vector area is ``A = (p2 − p0) × (p3 − p1) / 2``. Seen along ``A``, a
    convex quad turns the same way at every corner (the corner normal
    ``(p_next − p) × (p_prev − p)`` points along ``A``); a non-convex (dart) quad has
    one corner against it, a bow-tie two or more. For a flat panel this reading is
    exact; a strongly twisted panel is a bilinear patch whatever its outline seen
    from one side (see :func:`quadnodes.flatness.folded_panels`).

    Returns
    -------
    against : (m,) int64
        Corners turning against ``A`` (0 convex, 1 dart, >= 2 crossed).
    no_area : (m,) bool
        Quads whose diagonals are parallel (``A = 0``): no area, nothing to build.

    Examples
    --------
    >>> v = np.array([[0., 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0], [2, 1, 0]])
    >>> against, no_area = corner_turns(v, np.array([[0, 1, 2, 3], [0, 2, 1, 3], [1, 4, 5, 2]]))
    >>> against.tolist(), no_area.tolist()
    ([0, 4, 0], [False, True, False])
    """
    # coordinates as rows, (3, m) per corner: contiguous passes (NumPy's cross products and norms over an
    # inner dimension of 3 are several times slower); the same operations in the same order as before
    X = np.ascontiguousarray(np.asarray(vertices, dtype=np.float64).T)
    F = np.ascontiguousarray(np.asarray(faces).T)
    p = [np.take(X, F[k], axis=1) for k in range(4)]
    against = np.zeros(F.shape[1], dtype=np.int64)
    finite = np.ones(F.shape[1], dtype=bool)
    with np.errstate(over="ignore", invalid="ignore"):  # coordinates near the float limit: not judged
        d02, d13 = p[2] - p[0], p[3] - p[1]
        area = cross_rows(d02, d13)
        size = norm_rows(area)
        for k in range(4):
            corner = cross_rows(p[(k + 1) % 4] - p[k], p[k - 1] - p[k])
            dot = corner[0] * area[0]
            dot += corner[2] * area[2]  # (np.einsum's order on rows of 3, which this replaced: same bits)
            dot += corner[1] * area[1]
            scale = norm_rows(corner)
            scale *= size
            scale *= 1e-12
            against += dot <= scale
            finite &= np.isfinite(dot)
        diag = norm_rows(d02)
        diag += norm_rows(d13)
        diag *= 0.5
        no_area = size <= 1e-12 * diag**2
    finite &= np.isfinite(diag)
    return np.where(finite, against, 0), no_area & finite



def check_quad_mesh(vertices: np.ndarray, faces: np.ndarray) -> Any:
    """Check the combinatorics and geometry that single arrays cannot show.

    Zero-length edges and near-duplicate vertices, faces without area, edges shared by more than two faces, and neighbouring faces
    with inconsistent orientation (an edge walked the same way by both faces); a face listed twice is named as such.
    Counting uses SciPy's linear-time COO→CSR conversion; the offending faces are
    looked up only when there is an error.

    Returns
    -------
    scipy.sparse.csr_matrix
        The undirected edges as an upper-triangular ``(n, n)`` matrix in canonical
        form, holding the number of faces at each edge — the mesh's topology starts
        from it instead of counting the edges again.

    Raises
    ------
    InputError
        Naming the first offending face(s) and edge.
    """
    import scipy.sparse as sp

    check_edge_lengths(vertices, faces)
    _, no_area = corner_turns(vertices, faces)
    if no_area.any():
        fi = int(np.argmax(no_area))
        raise InputError(
            f"faces: face {fi} {faces[fi].tolist()} has no area (its diagonals are parallel: a collapsed or "
            "crossed panel); reorder its corners around the panel or remove it"
        )
    n = int(vertices.shape[0])
    start = faces.reshape(-1)
    end = np.roll(faces, -1, axis=1).reshape(-1)
    ones = np.ones(start.size, dtype=np.int32)
    lo, hi = np.minimum(start, end), np.maximum(start, end)
    und = sp.csr_matrix((ones, (lo, hi)), shape=(n, n))
    und.sum_duplicates()
    if und.nnz and und.data.max() > 2:
        k = int(np.argmax(und.data > 2))
        a = int(np.searchsorted(und.indptr, k, side="right") - 1)
        b = int(und.indices[k])
        hs = np.flatnonzero((lo == a) & (hi == b))
        _refuse_duplicate_faces(faces, hs // 4)
        raise InputError(
            f"faces: edge ({a}, {b}) is shared by {hs.size} faces {sorted(int(h // 4) for h in hs)}; "
            "at most two faces may share an edge"
        )
    # a directed edge used twice means two faces walk a shared edge the same way
    directed = sp.csr_matrix((ones, (start, end)), shape=(n, n))
    directed.sum_duplicates()
    if directed.nnz and directed.data.max() > 1:
        k = int(np.argmax(directed.data > 1))
        a = int(np.searchsorted(directed.indptr, k, side="right") - 1)
        b = int(directed.indices[k])
        hs = np.flatnonzero((start == a) & (end == b))
        _refuse_duplicate_faces(faces, hs // 4)
        raise InputError(
            f"faces: faces {int(hs[0] // 4)} and {int(hs[1] // 4)} both run "
            f"along edge {a}->{b} in the same direction (inconsistent orientation); "
            "flip one of them"
        )
    # a panel listed twice, once reversed, passes both counts when it stands alone (a closed two-faced pillow);
    # its corners are then interior vertices with two edges, which a sound mesh rarely has: look only there
    suspect = (np.diff(und.indptr) + np.bincount(und.indices, minlength=n)) == 2
    if suspect.any():  # (a grid's corners: boundary vertices, which one pass over the boundary edges clears)
        edge = np.flatnonzero(und.data == 1)
        suspect[np.searchsorted(und.indptr, edge, side="right") - 1] = False
        suspect[und.indices[edge]] = False
        if suspect.any():
            _refuse_duplicate_faces(faces, np.flatnonzero(suspect[faces].any(axis=1)))
    return und


def _refuse_duplicate_faces(faces: np.ndarray, candidates: np.ndarray) -> None:
    """Raise when two of the ``candidates`` (face indices) are the same panel: the same four vertices.

    Raises
    ------
    InputError
        Naming the two faces and the panel's vertices.

    Examples
    --------
    >>> _refuse_duplicate_faces(np.array([[0, 1, 2, 3], [1, 4, 5, 2], [2, 1, 0, 3]]), np.array([0, 1, 2]))
    Traceback (most recent call last):
    ...
    quadnodes.errors.InputError: faces: faces 0 and 2 are the same panel (vertices [0, 1, 2, 3]) listed twice; remove one
    """
    candidates = np.unique(candidates)
    if candidates.size < 2:
        return
    key = np.sort(faces[candidates], axis=1)
    order = np.lexsort(key.T[::-1])
    same = np.flatnonzero((key[order[1:]] == key[order[:-1]]).all(axis=1))
    if same.size:
        i, j = sorted((int(candidates[order[same[0]]]), int(candidates[order[same[0] + 1]])))
        raise InputError(
            f"faces: faces {i} and {j} are the same panel (vertices {faces[i].tolist()}) listed twice; remove one"
        )


def vertex_mask(mask: ArrayLike | None, n: int, name: str = "fixed") -> np.ndarray:
    """Return a boolean ``(n,)`` mask from a boolean mask or an index list.

    ``None`` gives all False. Integer input is read as vertex indices. An
    integer array of length ``n`` holding only 0 and 1 (``mask.astype(int)``) is
    ambiguous — a 0/1 mask or the indices 0 and 1 — and refused.

    Raises
    ------
    InputError
        On a wrong length, an index out of range, an ambiguous 0/1 integer array,
        or an unusable dtype.
    """
    out = np.zeros(n, dtype=bool)
    if mask is None:
        return out
    a = np.asarray(mask)
    if a.dtype == bool:
        if a.shape != (n,):
            raise InputError(f"{name}: boolean mask must have shape ({n},), got {a.shape}")
        out[:] = a
        return out
    if a.size == 0:
        return out
    if a.dtype.kind not in "iu":
        raise InputError(f"{name}: expected a boolean mask or vertex indices, got dtype {a.dtype}")
    a = a.reshape(-1).astype(np.int64)
    if n > 2 and a.size == n and np.isin(a, (0, 1)).all():
        raise InputError(
            f"{name}: an integer array of {n} zeros and ones looks like a 0/1 mask; pass a boolean "
            f"mask (e.g. mask.astype(bool)) or a list of vertex indices"
        )
    bad = (a < 0) | (a >= n)
    if bad.any():
        raise InputError(f"{name}: vertex index {int(a[bad][0])} is outside 0..{n - 1}")
    out[a] = True
    return out


def finite_number(value: Any, name: str) -> float:
    """Return ``value`` as a finite float of any sign, or raise :class:`InputError`."""
    if isinstance(value, (bool, np.bool_)):
        raise InputError(f"{name}: expected a number, got {value!r}")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected a number, got {value!r}") from None
    if not np.isfinite(x):
        raise InputError(f"{name}: must be finite, got {value!r}")
    return x


def positive_number(value: Any, name: str) -> float:
    """Return ``value`` as a finite float > 0, or raise :class:`InputError`."""
    x = finite_number(value, name)
    if x <= 0:
        raise InputError(f"{name}: must be > 0, got {value!r}")
    return x


def nonnegative_number(value: Any, name: str) -> float:
    """Return ``value`` as a finite float >= 0, or raise :class:`InputError`."""
    x = finite_number(value, name)
    if x < 0:
        raise InputError(f"{name}: must be >= 0, got {value!r}")
    return x


def positive_int(value: Any, name: str, *, minimum: int = 1) -> int:
    """Return ``value`` as an int >= ``minimum``, or raise :class:`InputError`."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise InputError(f"{name}: expected an integer, got {value!r}")
    if value < minimum:
        raise InputError(f"{name}: must be >= {minimum}, got {value!r}")
    return int(value)


def schedule(
    value: float | Sequence[float],
    iterations: int,
    name: str,
    *,
    decay: float = 1.0,
    positive: bool = False,
) -> np.ndarray:
    """Expand a per-iteration parameter into an ``(iterations,)`` float array.

    Parameters
    ----------
    value : float or sequence of float
        One number (used every iteration, multiplied by ``decay**k`` in iteration
        ``k``) or one value per iteration (longer lists are cut to ``iterations``).
    iterations : int
        Number of iterations.
    name : str
        Parameter name for error messages.
    decay : float
        Factor applied per iteration to a single number; must be > 0.
    positive : bool
        Require every value to be > 0 (otherwise >= 0).

    Raises
    ------
    InputError
        On a list shorter than ``iterations``, or a negative, zero (when
        ``positive``) or non-finite value.

    Examples
    --------
    >>> schedule(1.0, 3, "deviation", decay=0.5).tolist()
    [1.0, 0.5, 0.25]
    """
    check = positive_number if positive else nonnegative_number
    if isinstance(value, (str, bytes)):
        raise InputError(f"{name}: expected a number or a list of numbers, got {value!r}")
    if np.ndim(value) == 0:
        base = check(value, name)
        d = positive_number(decay, f"{name} decay")
        return base * d ** np.arange(iterations, dtype=np.float64)
    seq = list(value)  # type: ignore[arg-type]
    if decay != 1.0:
        raise InputError(f"{name}: a decay factor applies to a single number, not to a list")
    if len(seq) < iterations:
        raise InputError(
            f"{name}: the schedule has {len(seq)} values but {iterations} iterations were asked for"
        )
    return np.array([check(v, f"{name}[{k}]") for k, v in enumerate(seq[:iterations])])


def point_grid(points: ArrayLike) -> np.ndarray:
    """Return a fresh ``(rows, cols, 3)`` float grid of finite points, rows and cols >= 2.

    Raises
    ------
    InputError
        On a wrong shape or a non-finite coordinate (naming the point).
    """
    try:
        p = np.array(points, dtype=np.float64, copy=True)
    except (TypeError, ValueError) as exc:
        raise InputError(f"points: cannot convert to a float array ({exc})") from None
    if p.ndim != 3 or p.shape[2] != 3 or p.shape[0] < 2 or p.shape[1] < 2:
        raise InputError(f"points: expected shape (rows, cols, 3) with rows, cols >= 2, got {p.shape}")
    bad = ~np.isfinite(p).all(axis=2)
    if bad.any():
        i, j = (int(k) for k in np.argwhere(bad)[0])
        raise InputError(f"points: point [{i}, {j}] has a non-finite coordinate {p[i, j].tolist()}")
    return p


def unit_parameters(values: ArrayLike, name: str) -> np.ndarray:
    """Return a strictly increasing 1-D float array in [0, 1] with at least 2 entries.

    Raises
    ------
    InputError
        On a wrong shape, values outside [0, 1], or a non-increasing step.
    """
    try:
        a = np.array(values, dtype=np.float64, copy=True)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name}: cannot convert to a float array ({exc})") from None
    if a.ndim != 1 or a.size < 2:
        raise InputError(f"{name}: expected a 1-D array of at least 2 parameters, got shape {a.shape}")
    if not np.isfinite(a).all():
        raise InputError(f"{name}: parameters must be finite")
    if a.min() < 0.0 or a.max() > 1.0:
        raise InputError(
            f"{name}: normalized parameters must lie in [0, 1], got range [{a.min():g}, {a.max():g}]"
        )
    step = np.diff(a)
    if (step <= 0).any():
        k = int(np.flatnonzero(step <= 0)[0])
        raise InputError(
            f"{name}: parameters must be strictly increasing, got {a[k]!r} then {a[k + 1]!r} at index {k}"
        )
    return a


def _QuadMesh() -> type:
    from .mesh import QuadMesh  # mesh imports this module

    return QuadMesh


def quad_mesh(mesh: Any, name: str = "mesh") -> Any:
    """Return ``mesh`` if it is a :class:`QuadMesh`, else raise :class:`InputError`.

    The message says how to get a mesh from what was passed (a build123d face,
    an array of points, a file path).

    Examples
    --------
    >>> quad_mesh(None)
    Traceback (most recent call last):
    ...
    quadnodes.errors.InputError: mesh: expected a QuadMesh, got None
    """
    if isinstance(mesh, _QuadMesh()):
        return mesh
    got = "None" if mesh is None else type(mesh).__name__
    hint = ""
    if hasattr(mesh, "wrapped") and type(mesh).__module__.startswith("build123d"):
        hint = " (a build123d shape: sample it first, e.g. quadnodes.surfaces.sample(face, nu, nv))"
    elif isinstance(mesh, np.ndarray):
        hint = " (an array: build a mesh with QuadMesh(vertices, faces) or quadnodes.from_grid_points(points))"
    elif isinstance(mesh, (str, bytes)) or hasattr(mesh, "__fspath__"):
        hint = " (a file name: read it with quadnodes.io.load(path))"
    elif isinstance(mesh, tuple) and mesh and isinstance(mesh[0], _QuadMesh()):
        hint = " (a (mesh, report) pair: unpack it, e.g. mesh, report = quadnodes.fair(...))"
    raise InputError(f"{name}: expected a QuadMesh, got {got}{hint}")


def quad_meshes(meshes: Any, name: str = "meshes") -> list[Any]:
    """A QuadMesh or a non-empty sequence of them as a list, else raise :class:`InputError`."""
    if isinstance(meshes, _QuadMesh()):
        return [meshes]
    if isinstance(meshes, (str, bytes)) or not isinstance(meshes, Sequence):
        raise InputError(f"{name}: expected a QuadMesh or a sequence of them, got {type(meshes).__name__}")
    if len(meshes) == 0:
        raise InputError(f"{name}: got an empty sequence, nothing to show")
    return [quad_mesh(m, f"{name}[{i}]") for i, m in enumerate(meshes)]


def choice(value: Any, options: Iterable[str], name: str) -> str:
    """Return ``value`` if it is exactly one of ``options``, else raise :class:`InputError`.

    The one rule for every choice setting in quadnodes: exact, case-sensitive
    match (choices are lower-case); a near miss is named in the message.

    Examples
    --------
    >>> choice("newton", ("auto", "newton"), "method")
    'newton'
    >>> choice("NEWTON", ("auto", "newton"), "method")
    Traceback (most recent call last):
    ...
    quadnodes.errors.InputError: method: expected one of 'auto', 'newton', got 'NEWTON' (did you mean 'newton'?)
    """
    opts = tuple(options)
    if isinstance(value, str) and value in opts:
        return value
    hint = ""
    if isinstance(value, str):
        import difflib

        near = [o for o in opts if o == value.lower().strip()] or difflib.get_close_matches(value, opts, n=1)
        if near:
            hint = f" (did you mean {near[0]!r}?)"
    raise InputError(f"{name}: expected one of {', '.join(map(repr, opts))}, got {value!r}{hint}")


def flag(value: Any, name: str) -> bool:
    """Return ``value`` if it is a bool, else raise :class:`InputError` (``"no"`` is not False).

    Examples
    --------
    >>> flag(np.bool_(True), "adapt")
    True
    >>> flag("no", "adapt")
    Traceback (most recent call last):
    ...
    quadnodes.errors.InputError: adapt: expected true or false, got 'no'
    """
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise InputError(f"{name}: expected true or false, got {value!r}")


def iteration_count(value: Any, name: str = "iterations", *, maximum: int = MAX_ITERATIONS) -> int:
    """An iteration count in ``1 .. maximum``, else :class:`InputError`.

    Examples
    --------
    >>> iteration_count(3)
    3
    >>> iteration_count(10**7)
    Traceback (most recent call last):
    ...
    quadnodes.errors.InputError: iterations: at most 100000, got 10000000
    """
    n = positive_int(value, name)
    if n > maximum:
        raise InputError(f"{name}: at most {maximum}, got {value!r}")
    return n


def renamed(**old_to_new: str) -> Any:
    """Decorator: refuse keyword arguments that were renamed, saying the new name.

    ``old_to_new`` maps an old keyword to how to say it now (e.g.
    ``deviation="threshold"`` or ``fix_boundary="fix='boundary'"``). The map is kept
    as ``func.renamed_settings`` so graph nodes can give the same message for
    an old setting name in a graph file.

    Examples
    --------
    >>> @renamed(deviation="threshold")
    ... def f(*, threshold=0.1):
    ...     return threshold
    >>> f(deviation=0.2)
    Traceback (most recent call last):
    ...
    quadnodes.errors.InputError: f: 'deviation' was renamed: use threshold
    """
    import functools

    def decorate(func: Any) -> Any:
        @functools.wraps(func)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            for old, new in old_to_new.items():
                if old in kwargs:
                    raise InputError(f"{func.__name__}: {old!r} was renamed: use {new}")
            return func(*args, **kwargs)

        wrapper.renamed_settings = dict(old_to_new)  # type: ignore[attr-defined]
        return wrapper

    return decorate


def grid_cells(faces: np.ndarray, rows: int, cols: int, *, wrap_rows: bool = False, wrap_cols: bool = False) -> int:
    """Index of the first face that is not a unit cell of a ``rows × cols`` vertex grid, or -1.

    A unit cell has its four vertices at ``(i, j), (i, j+1), (i+1, j+1), (i+1, j)``
    (vertex ``i*cols + j``), walked around the cell in either direction from any
    corner. With ``wrap_cols`` (``wrap_rows``) the column (row) after the last is
    column (row) 0: the cells of a cylinder or torus grid (see :func:`grid_cell_base`).

    Examples
    --------
    >>> grid_cells(np.array([[0, 1, 4, 3], [4, 5, 2, 1]]), 2, 3)
    -1
    >>> grid_cells(np.array([[0, 1, 4, 3], [0, 2, 5, 3]]), 2, 3)
    1
    >>> grid_cells(np.array([[0, 1, 4, 3], [0, 2, 5, 3]]), 2, 3, wrap_cols=True)  # around the seam
    -1
    >>> grid_cells(np.array([[0, 1, 3, 4]]), 2, 3)  # the cell's corners, crossed
    0
    """
    faces = np.asarray(faces, dtype=np.int64)
    if wrap_rows or wrap_cols:
        bad = np.flatnonzero(grid_cell_base(faces, rows, cols, wrap_rows=wrap_rows, wrap_cols=wrap_cols) < 0)
        return int(bad[0]) if bad.size else -1
    if len(faces) and (rows < 2 or cols < 2):
        return 0  # a grid of one row or column has no cells
    low = faces.min(axis=1)
    d = faces - low[:, None]  # a cell's corners sit at low + {0, 1, cols, cols + 1}
    code = (d == 0).astype(np.int8) + 2 * (d == 1) + 4 * (d == cols) + 8 * (d == cols + 1)
    ok = code.sum(axis=1) == 15  # each of the four corners exactly once
    ok &= (d[:, 0] + d[:, 2] == cols + 1) & (d[:, 1] + d[:, 3] == cols + 1)  # diagonals opposite
    ok &= (low % cols != cols - 1) & (low + cols + 1 < rows * cols)
    bad = np.flatnonzero(~ok)
    return int(bad[0]) if bad.size else -1


def grid_cell_base(faces: np.ndarray, rows: int, cols: int, *, wrap_rows: bool = False,
                   wrap_cols: bool = False) -> np.ndarray:
    """The vertex ``(i, j)`` of every face that is the cell ``(i, j)..(i+1, j+1)`` of a vertex grid, or -1.

    Vertex ``i*cols + j`` sits at row ``i``, column ``j``; with ``wrap_cols``
    (``wrap_rows``) column ``cols`` (row ``rows``) is column (row) 0 again, which
    needs at least 3 columns (rows). The base of a cell across the seam is in the
    last column (row), so ``divmod(base, cols)`` names the cell in every case.

    Parameters
    ----------
    faces : (m, 4) int64
    rows, cols : int
    wrap_rows, wrap_cols : bool

    Returns
    -------
    base : (m,) int64
        -1 for a face that is no such cell.

    Examples
    --------
    >>> grid_cell_base(np.array([[2, 0, 3, 5], [0, 1, 4, 3], [0, 2, 4, 1]]), 2, 3, wrap_cols=True).tolist()
    [2, 0, -1]
    """
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 4)
    base = np.full(len(faces), -1, dtype=np.int64)
    if rows < (3 if wrap_rows else 2) or cols < (3 if wrap_cols else 2) or not len(faces):
        return base
    if faces.min() < 0 or faces.max() >= rows * cols:
        return base
    i, j = np.divmod(faces, cols)
    right_j, down_i = j + 1, i + 1
    ok_r = np.ones(faces.shape, dtype=bool) if wrap_cols else right_j < cols
    ok_d = np.ones(faces.shape, dtype=bool) if wrap_rows else down_i < rows
    right_j %= cols
    down_i %= rows
    right = i * cols + right_j
    down = down_i * cols + j
    diag = down_i * cols + right_j
    nxt, opp, prv = (np.roll(faces, -k, axis=1) for k in (1, 2, 3))
    hit = ok_r & ok_d & (opp == diag) & (((nxt == right) & (prv == down)) | ((nxt == down) & (prv == right)))
    found = hit.any(axis=1)
    base[found] = faces[found, np.argmax(hit[found], axis=1)]
    return base


def grid_wrap(faces: np.ndarray, rows: int, cols: int) -> tuple[bool, bool] | None:
    """``(wrap_rows, wrap_cols)`` of the least closed vertex grid whose cells the faces all are, or None.

    An open grid first, then closed across the columns (a cylinder whose rows are
    rings), across the rows, and both (a torus): see :func:`grid_cell_base`.

    Examples
    --------
    >>> grid_wrap(np.array([[0, 1, 4, 3], [2, 0, 3, 5]]), 2, 3)
    (False, True)
    >>> grid_wrap(np.array([[0, 1, 3, 4]]), 2, 3) is None
    True
    """
    for wrap in ((False, False), (False, True), (True, False), (True, True)):
        if grid_cells(faces, rows, cols, wrap_rows=wrap[0], wrap_cols=wrap[1]) < 0:
            return wrap
    return None
