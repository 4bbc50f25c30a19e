"""A grid's line operator with constant coefficients (or varying along one axis), inverted by the lines' own
eigenvectors and by transforms.

On a vertex grid the fairing matrix is a sum of per-line operators: every structure line's windows
of four consecutive nodes give ``c Dᵀ D`` (``D`` the line's third differences) with coefficients
``c`` that vary from window to window, plus ``ω`` on the diagonal. With one coefficient per family
(rows, columns) the operator is ``K = c_r (I ⊗ B_r) + c_c (B_c ⊗ I) + ωI``, ``B = DᵀD`` of a grid row or
column, which the lines' eigenvectors diagonalize: along an axis that closes around (a cylinder or torus
grid) ``B`` is the cube of the circulant Laplacian ``L`` and the Fourier transform does it in
``O(n log n)``; along an open axis ``B``'s eigenvectors are dense (``open_lines="exact"``: two matrix
products of half the line's length each way, ``B`` being symmetric about the line's middle), or the
discrete cosine transform diagonalizes the Neumann Laplacian's cube ``L³`` in its place
(``open_lines="cosine"``), which also charges a line's first and last slopes and curvatures.
:class:`SpectralPreconditioner` applies ``K⁻¹`` on the unknowns: a box holding every unknown is
transformed (the fixed lines around it left out, so ``B`` is its principal part there), and the fixed nodes
inside the box are inverted around exactly by a capacitance correction (Woodbury's formula): on an open grid with
exact lines in the lines' coordinates (up to :data:`MAX_CORRECTED_EXACT`, within :data:`CORRECTION_MAX_WORK`),
else by stored columns (up to :data:`MAX_CORRECTED`, within :data:`CORRECTION_MAX_VALUES`); more are only zeroed.

``K`` and the fairing matrix of fair's even spacing are sums of the same windows' terms with other
coefficients, so with the exact lines ``c_min K ≤ A ≤ c_max K`` and preconditioned conjugate gradients
take steps bounded by the coefficients' spread whatever the weight and the grid's size: on 300² sheets
with broadband noise 15–25 from ω = 0.3 to 10⁻⁶ (``benchmarks/studies/cg_weights.py``). With the cosine
lines the ends' mismatch grows as the weight falls, and the steps with it. Where the coefficients vary smoothly
along an open axis (uneven spacing, lines shrinking toward one side) a ``profile`` models that variation exactly
(:class:`SpectralPreconditioner`): on a 300² sheet whose spacing grows tenfold across it 17 steps instead of 110
(``benchmarks/studies/coefficient_profile.py``).

Examples
--------
>>> P = SpectralPreconditioner((4, 5), (False, False), 1.0, 2.0, 0.5)
>>> R = np.zeros((1, 20)); R[0, 7] = 1.0
>>> Z = np.zeros_like(R)
>>> P.apply(R, Z, 0, 20, True)
>>> bool(np.allclose(P.operator() @ Z[0], R[0], atol=1e-5))  # (single precision)
True
"""

from __future__ import annotations

import contextlib
import functools
import sys
from collections.abc import Callable
from types import ModuleType
from typing import Literal

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from . import threads as _threads

__all__ = ["SpectralPreconditioner", "box", "fixed_inside", "inverts_exactly", "line_laplacian",
           "line_third_differences", "loaded", "MAX_CORRECTED", "CORRECTION_MAX_VALUES", "CORRECTION_SINGLE_MAX",
           "MAX_CORRECTED_EXACT", "CORRECTION_MAX_WORK", "EXACT_MAX_SIDE", "PARALLEL_MIN_NODES",
           "EXACT_PARALLEL_MIN_NODES", "FOLD_SLAB_BYTES"]

#: Grids of at least this many nodes transform on the solver's threads; below, one thread is faster (300²: 1.5
#: against 2.3 ms a step, 1000²: 28 against 12 ms, a throwaway timing of ``dctn``/``idctn``).
PARALLEL_MIN_NODES = 250_000
#: ... the exact lines' products (BLAS) from this many (on 300² two threads took 6–9 ms a step against 8–10 ms,
#: on 200² 3.8–5.5 against 3.0–4.1 ms, a throwaway timing of ``apply`` with the capacitance correction's slabs).
EXACT_PARALLEL_MIN_NODES = 50_000
#: The capacitance correction in the lines' coordinates works in slabs of columns whose double-precision copies
#: hold at most this many bytes (:meth:`SpectralPreconditioner._fold_correction`).
FOLD_SLAB_BYTES = 2**19
#: Fixed nodes inside the unknowns' box up to which the preconditioner inverts around them exactly where an axis
#: closes around or its lines are cosine ones (a capacitance correction: ``K⁻¹`` of that many columns at set-up, a
#: product with them per step) ...
MAX_CORRECTED = 64
#: ... while the correction's stored columns (fixed nodes × the box's nodes) stay within this many values ...
CORRECTION_MAX_VALUES = 32_000_000
#: ... and in double precision where ``K``'s condition (its largest eigenvalue over ω) exceeds this: the stored
#: columns' subtraction cancels the near-null modes that the fixed nodes hold (sizes up to ``1/ω``) in the result, so
#: single precision would leave errors of its rounding (6·10⁻⁸) times that condition (already 2.5·10⁻³ at a
#: condition of 2·10⁵ on a small grid, ``tests/linalg/test_spectral.py``); the products cost about twice as much
#: there.
CORRECTION_SINGLE_MAX = 1e6
#: With exact lines on both axes (an open grid) the correction works in the lines' coordinates instead, where a fixed
#: node is the outer product of two columns of the axes' transforms: nothing stored but those, ``2 p N``
#: multiply-adds a step and right-hand side for ``p`` fixed nodes in a box of ``N``, the capacitance matrix in
#: ``p² N`` at set-up, in single precision (its reading of the fixed nodes in double; see
#: :meth:`SpectralPreconditioner._fold_correction`). Up to this many fixed nodes ...
MAX_CORRECTED_EXACT = 1024
#: ... while the set-up's ``p² N`` stays within this many multiply-adds (on one BLAS thread about 1 s: 0.85 s for 141
#: fixed nodes on 1000², a reviewer's timing).
CORRECTION_MAX_WORK = 2e10
#: ``open_lines="exact"`` holds an open line's eigenvectors (dense, half the line's length squared twice) up to
#: this many nodes; a longer line raises (its products cost ``O(n)`` a node each way).
EXACT_MAX_SIDE = 8192


def loaded() -> bool:
    """Whether SciPy's transforms (``scipy.fft``) are imported: using them then costs no import (about 40 ms).

    Returns
    -------
    bool

    Examples
    --------
    >>> import scipy.fft
    >>> loaded()
    True
    """
    return "scipy.fft" in sys.modules


def line_laplacian(n: int, closed: bool = False) -> sp.csr_matrix:
    """The line's Laplacian ``L``: ``−1, 2, −1`` in each row, ``1, −1`` at an open line's ends.

    Parameters
    ----------
    n : int
        Nodes on the line.
    closed : bool
        Whether the line closes around (then ``L`` is circulant).

    Returns
    -------
    (n, n) scipy.sparse.csr_matrix

    Raises
    ------
    ValueError
        If ``n < 1``.

    Examples
    --------
    >>> line_laplacian(3).toarray().tolist()
    [[1.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]]
    >>> line_laplacian(3, closed=True).toarray().tolist()
    [[2.0, -1.0, -1.0], [-1.0, 2.0, -1.0], [-1.0, -1.0, 2.0]]
    """
    if n < 1:
        raise ValueError(f"n: expected at least one node, got {n}")
    if n == 1:
        return sp.csr_matrix((1, 1))
    D = sp.diags([-np.ones(n), np.ones(n - 1)], [0, 1], shape=(n - 1 + closed, n), format="lil")
    if closed:
        D[n - 1, 0] = 1.0
    D = D.tocsr()
    return sp.csr_matrix(D.T @ D)


def line_third_differences(n: int, closed: bool = False, coefficients: np.ndarray | None = None) -> sp.csr_matrix:
    """``B = DᵀD`` of a line's third differences ``D`` (rows ``−1, 3, −3, 1`` on every four consecutive nodes).

    On a closed line of at least four nodes the windows go around and ``B = L³`` (:func:`line_laplacian`); an open
    line of fewer than four nodes has no window (``B = 0``). With ``coefficients`` (an open line's) ``B = Dᵀ C D``,
    ``C`` their diagonal: each window's term weighted.

    Parameters
    ----------
    n : int
        Nodes on the line.
    closed : bool
        Whether the line closes around.
    coefficients : (n − 3,) float, optional
        An open line's window coefficients (``≥ 0``, window ``k`` on nodes ``k … k + 3``); default all 1.

    Returns
    -------
    (n, n) scipy.sparse.csr_matrix

    Raises
    ------
    ValueError
        If ``n < 1``.

    Examples
    --------
    >>> line_third_differences(4).toarray()[0].tolist()
    [1.0, -3.0, 3.0, -1.0]
    >>> bool((line_third_differences(6, closed=True) != line_laplacian(6, closed=True) ** 3).nnz == 0)
    True
    >>> line_third_differences(5, coefficients=np.array([2.0, 0.0])).toarray()[0].tolist()
    [2.0, -6.0, 6.0, -2.0, 0.0]
    """
    if n < 1:
        raise ValueError(f"n: expected at least one node, got {n}")
    if coefficients is not None and (closed or np.shape(coefficients) != (max(n - 3, 0),)):
        raise ValueError(f"coefficients: expected an open line's {max(n - 3, 0)} windows, got shape "
                         f"{np.shape(coefficients)}{' on a closed line' if closed else ''}")
    if closed:
        L = line_laplacian(n, closed=True)
        return sp.csr_matrix(L @ L @ L)
    if n < 4:
        return sp.csr_matrix((n, n))
    D = sp.diags([-1.0, 3.0, -3.0, 1.0], [0, 1, 2, 3], shape=(n - 3, n), format="csr")
    if coefficients is None:
        return sp.csr_matrix(D.T @ D)
    return sp.csr_matrix(D.T @ sp.diags(np.asarray(coefficients, dtype=np.float64)) @ D)


def _line_basis(n: int, lo: int, hi: int, closed: bool = False) -> tuple[np.ndarray, list[np.ndarray]]:
    """The eigenvalues and forward matrices of a line's ``B[lo:hi, lo:hi]`` (:func:`line_third_differences`; a
    closed line whole, its ``B`` circulant and so symmetric about any node too).

    Where the span is symmetric about the line's middle (``B`` persymmetric there) the eigenvectors are even or
    odd about it: with ``h = ⌊len/2⌋``, ``s = x[:h] + x[::-1][:h]`` (and the middle node, for an odd length) and
    ``a = x[:h] − x[::-1][:h]``, the coordinates are ``(s Fₛ, a Fₐ)``, ``F`` the halves' eigenvectors with the
    ``1/√2`` folded in. Otherwise one dense ``F``. Eigenvalues (clipped at 0) in the coordinates' order; float64.
    The span's part of ``B`` depends only on its length and on up to three nodes before and after it (a window
    reaches three nodes on): cached on those (:func:`_span_basis`), so a square grid's two axes and fair's
    iterations share it.
    """
    if closed:
        return _span_basis(-1, n, -1)
    return _span_basis(min(lo, 3), hi - lo, min(n - hi, 3))


@functools.lru_cache(maxsize=4)
def _span_basis(head: int, size: int, tail: int) -> tuple[np.ndarray, list[np.ndarray]]:
    """:func:`_line_basis` of a span of ``size`` nodes with ``head`` and ``tail`` (each at most 3) nodes beside it,
    or of a closed line of ``size`` nodes (``head = tail = -1``)."""
    if head < 0:
        n, lo, hi = size, 0, size
        B = line_third_differences(n, closed=True).toarray()
    else:
        n, lo, hi = head + size + tail, head, head + size
        B = line_third_differences(n)[lo:hi, lo:hi].toarray()
    h = size // 2
    if size >= 2 and lo == n - hi:
        J = B[:h, ::-1][:, :h]  # (B's top-right block, read backwards: the coupling to the mirrored nodes)
        top = B[:h, :h]
        Bs = top + J
        if size % 2:  # the middle node: (x_h) with weight 1, the pairs with 1/√2
            col = B[:h, h] * np.sqrt(2.0)
            Bs = np.block([[Bs, col[:, None]], [col[None, :], B[h:h + 1, h:h + 1]]])
        with _threads.blas_pinned():  # (LAPACK's threads gain nothing here and spin on a loaded machine)
            lam_s, Vs = np.linalg.eigh(Bs)
            lam_a, Va = np.linalg.eigh(top - J)
        scale = np.full(Bs.shape[0], np.sqrt(0.5))
        if size % 2:
            scale[h] = 1.0
        blocks = [Vs * scale[:, None], Va * np.sqrt(0.5)]
        lam = np.concatenate([lam_s, lam_a])
    else:
        with _threads.blas_pinned():
            lam, V = np.linalg.eigh(B)
        blocks = [V]
    return np.maximum(lam, 0.0), blocks


def _checked_profile(profile: tuple, shape: tuple[int, int],
                     wrap: tuple[bool, bool]) -> tuple[int, np.ndarray, np.ndarray, np.ndarray | None]:
    """:class:`SpectralPreconditioner`'s ``profile``, checked: ``(axis, windows, lines, across)`` as float64 arrays
    (``across`` None where not given)."""
    try:
        axis, windows, lines, *rest = profile
        if len(rest) > 1:
            raise ValueError
    except (TypeError, ValueError):
        raise ValueError(f"profile: expected (axis, windows, lines[, across]), got {profile!r}") from None
    if axis not in (0, 1):
        raise ValueError(f"profile: expected axis 0 or 1, got {axis!r}")
    n = shape[axis]
    if wrap[axis]:
        raise ValueError(f"profile: axis {axis} closes around; coefficients may vary only along an open axis")
    if not 4 <= n <= EXACT_MAX_SIDE:
        raise ValueError(f"profile: expected 4 to {EXACT_MAX_SIDE} nodes along axis {axis}, got {n}")
    windows = np.asarray(windows, dtype=np.float64)
    lines = np.asarray(lines, dtype=np.float64)
    if windows.shape != (n - 3,) or not (np.isfinite(windows).all() and (windows >= 0).all()):
        raise ValueError(f"profile: expected {n - 3} finite window coefficients >= 0, got shape {windows.shape}")
    if lines.shape != (n,) or not (np.isfinite(lines).all() and (lines > 0).all()):
        raise ValueError(f"profile: expected {n} finite line coefficients > 0, got shape {lines.shape}")
    across = None if not rest or rest[0] is None else np.asarray(rest[0], dtype=np.float64)
    if across is not None:
        other = shape[1 - axis]
        if wrap[1 - axis]:
            raise ValueError(f"profile: axis {1 - axis} closes around; across needs an open axis")
        if not 4 <= other <= EXACT_MAX_SIDE:
            raise ValueError(f"profile: expected 4 to {EXACT_MAX_SIDE} nodes along axis {1 - axis}, got {other}")
        if across.shape != (other - 3,) or not (np.isfinite(across).all() and (across >= 0).all()):
            raise ValueError(f"profile: expected {other - 3} finite across coefficients >= 0, got shape "
                             f"{across.shape}")
    return int(axis), windows, lines, across


def _pencil_basis(n: int, lo: int, hi: int, windows: np.ndarray, scale: np.ndarray,
                  weight: float) -> tuple[np.ndarray, list[np.ndarray]]:
    """The varying axis's basis (:class:`SpectralPreconditioner`'s ``profile``): ``X`` and ``θ`` with
    ``(B + ωI) X = S X Θ`` and ``Xᵀ S X = I`` over the span ``lo:hi`` of an open line of ``n`` nodes, ``B`` its
    third differences weighted by ``windows`` (:func:`line_third_differences`), ``S = diag(scale)`` (the span's, at
    most 1). Returned as ``θ − ω`` (``≥ 0``: ``S ≤ I``) and ``[X]``, ``X`` the forward matrix (``Xᵀ`` forward,
    ``X`` back): for every mode ``μ`` of the other axis ``μ S + B + ωI = X⁻ᵀ (μ + Θ) X⁻¹``. Float64, one dense
    block. ``ω/S`` joins ``B``'s scale before the decomposition, so where it falls below double precision's rounding
    of ``B`` the near-null modes come from rounding: with window coefficients spread 10⁴-fold the application's
    relative error was 10⁻⁴ at ω = 10⁻¹⁰ of ``B``'s scale, 10⁶-fold 1.4·10⁻² (a reviewer's measurement; a spread of
    100 gave 4·10⁻⁶) — it only steers CG's directions there."""
    B = line_third_differences(n, coefficients=windows)[lo:hi, lo:hi].toarray()
    root = 1.0 / np.sqrt(scale)
    M = root[:, None] * B * root[None, :]
    M[np.diag_indices_from(M)] += weight / scale
    with _threads.blas_pinned():
        theta, Y = np.linalg.eigh(0.5 * (M + M.T))
    return np.maximum(theta - weight, 0.0), [root[:, None] * Y]


def box(free: np.ndarray, wrap: tuple[bool, bool]) -> tuple[tuple[int, int], tuple[int, int]]:
    """The box the preconditioner transforms: along each open axis the span of the unknowns, a closed axis whole.

    Parameters
    ----------
    free : (rows, cols) bool
        The unknowns, at least one.
    wrap : (bool, bool)
        Whether each axis closes around.

    Returns
    -------
    ((int, int), (int, int))
        ``(lo, hi)`` of the rows and of the columns.

    Examples
    --------
    >>> free = np.zeros((5, 6), bool); free[1:4, 1:5] = True; free[2, 2] = False
    >>> box(free, (False, False)), box(free, (True, False))
    (((1, 4), (1, 5)), ((0, 5), (1, 5)))
    """
    spans = []
    for axis, closed in enumerate(wrap):
        held = np.flatnonzero(free.any(axis=1 - axis))
        spans.append((0, free.shape[axis]) if closed else (int(held[0]), int(held[-1]) + 1))
    return spans[0], spans[1]


def fixed_inside(free: np.ndarray, wrap: tuple[bool, bool]) -> int:
    """Fixed nodes inside :func:`box`: those that the capacitance correction (or, above :data:`MAX_CORRECTED`, the
    zeroing) handles.

    Examples
    --------
    >>> free = np.zeros((5, 6), bool); free[1:4, 1:5] = True; free[2, 2] = False
    >>> fixed_inside(free, (False, False)), fixed_inside(free, (True, False))
    (1, 9)
    """
    (r0, r1), (c0, c1) = box(free, wrap)
    return int(np.count_nonzero(~free[r0:r1, c0:c1]))


def _correction_form(free: np.ndarray, wrap: tuple[bool, bool], open_lines: str) -> str | None:
    """How the fixed nodes inside :func:`box` are inverted around: ``"coordinates"`` (exact lines on both axes, a
    closed one's too where the stored columns would not do), ``"columns"`` (stored), or None (none inside, or too
    many: then only zeroed)."""
    (r0, r1), (c0, c1) = box(free, wrap)
    p, size = int(np.count_nonzero(~free[r0:r1, c0:c1])), (r1 - r0) * (c1 - c0)
    if p == 0:
        return None
    coordinates = (open_lines == "exact" and all(n <= EXACT_MAX_SIDE for n in free.shape)
                   and p <= MAX_CORRECTED_EXACT and p * p * size <= CORRECTION_MAX_WORK)
    if coordinates and not any(wrap):
        return "coordinates"
    if p <= MAX_CORRECTED and p * size <= CORRECTION_MAX_VALUES:
        return "columns"
    return "coordinates" if coordinates else None


def inverts_exactly(free: np.ndarray, wrap: tuple[bool, bool],
                    open_lines: Literal["exact", "cosine"] = "exact") -> bool:
    """Whether the preconditioner is ``K_ff⁻¹`` on these unknowns: its fixed nodes inside :func:`box` corrected — by
    stored columns up to :data:`MAX_CORRECTED` within :data:`CORRECTION_MAX_VALUES`, or with exact lines (on a closed
    axis too, where the stored columns would not do) in the lines' coordinates up to :data:`MAX_CORRECTED_EXACT`
    within :data:`CORRECTION_MAX_WORK` (a correction whose Cholesky factorization fails, which rounding alone could
    cause, falls back to zeroing them).

    Parameters
    ----------
    free : (rows, cols) bool
        The unknowns, at least one.
    wrap : (bool, bool)
        Whether each axis closes around.
    open_lines : {"exact", "cosine"}
        As :class:`SpectralPreconditioner`'s.

    Returns
    -------
    bool

    Examples
    --------
    A fixed first row is off the box of an open grid, and inside a closed one's (50 more fixed nodes there: 75, more
    than the stored columns take, so only exact lines, a closed axis's too, invert around them):

    >>> free = np.ones((40, 50), bool); free[0] = False; free[20, ::2] = False
    >>> inverts_exactly(free, (False, False)), inverts_exactly(free, (True, False))
    (True, True)
    >>> inverts_exactly(free, (True, False), "cosine")
    False
    """
    return fixed_inside(free, wrap) == 0 or _correction_form(free, wrap, open_lines) is not None


def _fourier_eigenvalues(n: int, transform: str) -> np.ndarray:
    """``L``'s eigenvalues in the order of a transform along the axis: ``"dct"`` (the Neumann ``L``), ``"rfft"``
    or ``"fft"`` (the circulant ``L``)."""
    if transform == "dct":
        return 2.0 - 2.0 * np.cos(np.pi * np.arange(n) / n)
    k = np.arange(n // 2 + 1 if transform == "rfft" else n)
    return 2.0 - 2.0 * np.cos(2.0 * np.pi * k / n)


class _Axis:
    """One axis's transform: ``kind`` (``"exact"``, ``"dct"``, ``"rfft"``, ``"fft"``), the span ``lo:hi`` of nodes it
    transforms, ``B``'s eigenvalues in the transform's order, and for ``"exact"`` the forward matrices in float32
    (:func:`_line_basis`)."""

    def __init__(self, kind: str, n: int, lo: int, hi: int, closed: bool = False,
                 pencil: tuple[np.ndarray, np.ndarray, float] | None = None) -> None:
        self.kind, self.n, self.lo, self.hi, self.closed = kind, n, lo, hi, closed
        self.blocks32: list[np.ndarray] = []
        self.blocks64: list[np.ndarray] = []
        if pencil is not None:  # (the varying axis: windows over the whole line, the span's scale, ω)
            lam, self.blocks64 = _pencil_basis(n, lo, hi, *pencil)
            self.blocks32 = [F.astype(np.float32) for F in self.blocks64]
            self.eigenvalues = lam
        elif kind == "exact":
            lam, self.blocks64 = _line_basis(n, lo, hi, closed)
            self.blocks32 = [F.astype(np.float32) for F in self.blocks64]
            self.eigenvalues = lam
        else:
            self.eigenvalues = _fourier_eigenvalues(hi - lo, kind) ** 3

    @property
    def size(self) -> int:
        return self.hi - self.lo

    def columns(self, nodes: np.ndarray) -> np.ndarray:
        """An exact axis's forward transform of unit vectors at ``nodes`` (span numbering): ``(size, len(nodes))``
        float64, the columns of its orthogonal matrix."""
        units = np.zeros((1, nodes.size, self.size))
        units[0, np.arange(nodes.size), nodes] = 1.0
        out = np.empty_like(units)
        _exact(units, 2, self.blocks64, True, out)
        return out[0].T.copy()


def _exact(G: np.ndarray, axis: int, blocks: list[np.ndarray], forward: bool, out: np.ndarray) -> None:
    """``out = G`` transformed along ``axis`` (1 or 2 of a ``(c, rows, cols)`` array) by an exact axis's ``blocks``
    (forward: into its coordinates; backward: back to the nodes)."""
    size = G.shape[axis]

    def cut(a: np.ndarray, s: slice) -> np.ndarray:
        return a[:, s] if axis == 1 else a[:, :, s]

    def times(a: np.ndarray, F: np.ndarray, transpose: bool, o: np.ndarray) -> None:
        if axis == 2:
            np.matmul(a, F.T if transpose else F, out=o)
        else:
            np.matmul(F if transpose else F.T, a, out=o)

    if len(blocks) == 1:
        times(G, blocks[0], not forward, out)
        return
    h = size // 2
    ns = blocks[0].shape[0]  # h, or h + 1 with the middle node
    mirrored = slice(size - 1, size - 1 - h, -1)  # (the last h nodes backwards; size − 1 − h ≥ 0 as size ≥ 2)
    if forward:
        top, bottom = cut(G, slice(0, h)), cut(G, mirrored)
        s = np.empty(cut(G, slice(0, ns)).shape, G.dtype)
        np.add(top, bottom, out=cut(s, slice(0, h)))
        if ns > h:  # (the middle node of an odd length)
            cut(s, slice(h, ns))[...] = cut(G, slice(h, ns))
        times(s, blocks[0], False, cut(out, slice(0, ns)))
        times(top - bottom, blocks[1], False, cut(out, slice(ns, size)))
    else:
        us = np.empty(cut(G, slice(0, ns)).shape, G.dtype)
        ua = np.empty(cut(G, slice(ns, size)).shape, G.dtype)
        times(cut(G, slice(0, ns)), blocks[0], True, us)
        times(cut(G, slice(ns, size)), blocks[1], True, ua)
        ush = cut(us, slice(0, h))
        np.add(ush, ua, out=cut(out, slice(0, h)))
        np.subtract(ush, ua, out=cut(out, mirrored))
        if ns > h:
            cut(out, slice(h, ns))[...] = cut(us, slice(h, ns))


class SpectralPreconditioner:
    """``P⁻¹ = E K_ff⁻¹ Eᵀ`` on a ``rows × cols`` grid in row-major order, by transforms (see the module).

    ``K = c_r (I ⊗ B_r) + c_c (B_c ⊗ I) + ωI`` with ``B`` a grid row's (``cols`` nodes, coefficient ``c_r``) or
    column's (``rows`` nodes, ``c_c``) third differences' ``DᵀD`` (:func:`line_third_differences`; with
    ``open_lines="cosine"`` the cube of an open line's Laplacian, :func:`line_laplacian`), periodic where the axis
    closes around; ``E`` selects the unknowns (``free``) and ``K_ff`` is ``K``'s part on them. Exact where the
    unknowns fill a box (the nodes off it fixed: e.g. a fixed boundary) but for fixed nodes inside it that the
    correction takes (:func:`inverts_exactly`: with exact lines on an open grid up to :data:`MAX_CORRECTED_EXACT`,
    else up to :data:`MAX_CORRECTED`); with more, ``P⁻¹ = E (K_box⁻¹)_ff Eᵀ``, their rows only zeroed (still
    symmetric positive definite, less close to ``K_ff⁻¹``). Applied to all columns of the residual at once
    (``whole``), in single precision (double where stored columns meet a large condition,
    :data:`CORRECTION_SINGLE_MAX`): it only steers the search directions; the exact lines' products on the
    solver's threads (BLAS held to one thread each, as everywhere in the solver).

    With a ``profile`` the coefficients vary along one open axis ``a`` (a grid sampled with uneven spacing, a
    surface whose lines shrink toward one side): the family of lines along ``a`` has a coefficient per window,
    the same on every line (``B_a = Dᵀ C D``), the other family one coefficient per line, by the line's position
    along ``a`` (``S``). For ``a = 1``: ``K = B_c ⊗ S + I ⊗ B_a + ωI``. The other axis transforms as before (or, its
    windows varying along it too, ``across``, by the eigenvectors of ``B_c = Dᵀ diag(across) D``); along ``a`` the
    pencil ``(B_a + ωI, S)``'s eigenvectors ``X`` (dense, :func:`_pencil_basis`) take every mode ``μ`` of the other
    axis at once, as ``μ S + B_a + ωI = X⁻ᵀ (μ + Θ) X⁻¹``. Still exact, fixed nodes corrected as above, at one dense
    product each way along a varying axis instead of two of half the length.

    Parameters
    ----------
    shape : (int, int)
        ``(rows, cols)`` of the grid.
    wrap : (bool, bool)
        Whether the columns (the row index) and the rows (the column index) close around — as
        :attr:`quadnodes.linalg.grid.GridPattern.wrap`.
    row_coefficient, column_coefficient : float
        ``c_r``, ``c_c``: each family's window coefficient, ``≥ 0`` (the magnitude of the matrix's
        ``±3`` and ``±3·cols`` diagonals).
    weight : float
        ``ω > 0``.
    free : (rows · cols,) bool, optional
        The unknowns; default all. At least one.
    open_lines : {"exact", "cosine"}
        An open axis's line operator: its third differences (dense eigenvectors, up to :data:`EXACT_MAX_SIDE`
        nodes) or the Neumann Laplacian's cube (the cosine transform). Either way the box is cut to the
        unknowns' span along an open axis.
    profile : (int, (n_a − 3,) float, (n_a,) float[, (n_o − 3,) float]), optional
        ``(a, windows, lines[, across])``: coefficients that vary along the open axis ``a`` (0: the row index, 1:
        the column index; ``n_a`` nodes, at least 4, up to :data:`EXACT_MAX_SIDE`) — the window coefficients
        (``≥ 0``) of the family of lines along ``a``, and the coefficient (``> 0``) of each line of the other
        family; ``across`` (the other axis open, ``n_o`` nodes): that family's windows also vary along their own
        axis, window ``k`` of the line at ``p`` weighing ``across[k] · lines[p]`` (``B_o = Dᵀ diag(across) D``, one
        dense basis along that axis too). They replace both ``row_coefficient`` and ``column_coefficient``.

    Raises
    ------
    ValueError
        If the shape, coefficients, weight, unknowns, ``open_lines`` or ``profile`` are out of range.

    Examples
    --------
    On a closed 6 × 4 grid (rows periodic) ``P⁻¹`` inverts ``K``:

    >>> P = SpectralPreconditioner((6, 4), (True, False), 3.0, 1.0, 0.1)
    >>> x = np.random.default_rng(0).normal(size=(2, 24))
    >>> Z = np.zeros_like(x)
    >>> P.apply(x @ P.operator().toarray(), Z, 0, 24, True)
    >>> bool(np.allclose(Z, x, atol=1e-4))
    True
    """

    whole = True  # applied once per step to every row (block_cg)
    #: Whether it calls no BLAS (only SciPy's transforms; the stored columns' correction by NumPy's own loop, and
    #: its p × p Cholesky solve too small for BLAS's threads): then block_cg need not pin BLAS (whose first pin
    #: scans the process's libraries, some 20 ms). The exact lines' products are BLAS calls (on the solver's
    #: threads, one BLAS thread each).
    blas_free = True

    def __init__(self, shape: tuple[int, int], wrap: tuple[bool, bool], row_coefficient: float,
                 column_coefficient: float, weight: float, free: np.ndarray | None = None,
                 open_lines: Literal["exact", "cosine"] = "exact",
                 profile: tuple[int, np.ndarray, np.ndarray] | tuple[int, np.ndarray, np.ndarray, np.ndarray | None]
                 | None = None) -> None:
        rows, cols = (int(s) for s in shape)
        if rows < 1 or cols < 1:
            raise ValueError(f"shape: expected positive sides, got {shape}")
        if not (np.isfinite(weight) and weight > 0):
            raise ValueError(f"weight: expected a positive finite number, got {weight}")
        for name, c in (("row_coefficient", row_coefficient), ("column_coefficient", column_coefficient)):
            if not (np.isfinite(c) and c >= 0):
                raise ValueError(f"{name}: expected a finite number >= 0, got {c}")
        if open_lines not in ("exact", "cosine"):
            raise ValueError(f"open_lines: expected 'exact' or 'cosine', got {open_lines!r}")
        if free is not None and np.asarray(free).shape != (rows * cols,):
            raise ValueError(f"free: expected shape ({rows * cols},), got {np.asarray(free).shape}")
        mask = np.ones((rows, cols), bool) if free is None else np.asarray(free, dtype=bool).reshape(rows, cols)
        if not mask.any():
            raise ValueError("free: expected at least one unknown")
        self.shape = (rows, cols)
        self.wrap = (bool(wrap[0]), bool(wrap[1]))
        self.coefficients = (float(row_coefficient), float(column_coefficient))
        self.profile = None if profile is None else _checked_profile(profile, self.shape, self.wrap)
        self.weight = float(weight)
        self.open_lines = open_lines
        # each axis's kind over the box's span: an open one exact or cosine; along a closed one (never cut) the real
        # Fourier transform where it is the only closed one or the rows', the full one on the other
        spans = box(mask, self.wrap)
        # (a closed axis takes its exact basis too, dense as an open one's, where the correction works in the lines'
        # coordinates: more fixed nodes inside than the stored columns take)
        form = _correction_form(mask, self.wrap, open_lines)
        axes = []
        varying = -1 if self.profile is None else self.profile[0]
        scale = 1.0  # (the other family's largest line coefficient over the span: S ≤ I)
        for axis, (n, closed, (lo, hi)) in enumerate(zip(self.shape, self.wrap, spans)):
            if axis == varying:
                _, windows, line_coefficients, _ = self.profile  # type: ignore[misc]
                scale = float(line_coefficients[lo:hi].max())
                axes.append(_Axis("exact", n, lo, hi, pencil=(windows, line_coefficients[lo:hi] / scale, self.weight)))
            elif varying >= 0 and self.profile[3] is not None:  # type: ignore[index]
                # (the other family's windows vary along this axis too: their own orthonormal basis, S = I, ω = 0)
                across = self.profile[3]  # type: ignore[index]
                axes.append(_Axis("exact", n, lo, hi, pencil=(across, np.ones(hi - lo), 0.0)))
            elif closed and form == "coordinates":
                axes.append(_Axis("exact", n, lo, hi, closed=True))
            elif closed:
                axes.append(_Axis("rfft" if axis == 1 or not self.wrap[1] else "fft", n, lo, hi))
            elif open_lines == "exact":
                if n > EXACT_MAX_SIDE:
                    raise ValueError(f"open_lines='exact': at most {EXACT_MAX_SIDE} nodes along an open axis, "
                                     f"got {n}; use 'cosine'")
                axes.append(_Axis("exact", n, lo, hi))
            else:
                axes.append(_Axis("dct", n, lo, hi))
        self._axes = axes
        inside = mask[axes[0].lo:axes[0].hi, axes[1].lo:axes[1].hi]
        self._box_shape = inside.shape
        c_r, c_c = self.coefficients  # (with a profile: the varying axis's θ − ω as they are, the other's μ scaled)
        if varying >= 0:
            c_r, c_c = (scale, 1.0) if varying == 0 else (1.0, scale)
        eig = c_c * axes[0].eigenvalues[:, None] + c_r * axes[1].eigenvalues[None, :] + self.weight
        # 1/eig in single precision as ω/eig ∈ (0, 1] (no underflow whatever the units), 1/ω applied in double;
        # the unnormalized forward and inverse FFTs' scales cancel
        self._inverse64 = self.weight / eig
        self._inverse = self._inverse64.astype(np.float32)
        self._inner = np.flatnonzero(~inside.ravel())  # fixed nodes inside the box (box numbering)
        self._correction: tuple[np.ndarray, tuple] | None = None  # (stored columns W, C's Cholesky factor)
        self._factored: tuple[np.ndarray, np.ndarray, tuple] | None = None  # (U, V, C's Cholesky factor)
        self._dtype: type = np.float32
        if form == "coordinates":
            self._correct_factored()
        elif form == "columns":
            if float(eig.max()) / self.weight > CORRECTION_SINGLE_MAX:
                self._dtype = np.float64
            self._correct()
        self.blas_free = all(a.kind != "exact" for a in axes)

    def _correct_factored(self) -> None:
        """Set up the correction in the exact lines' coordinates: ``U``, ``V`` the axes' transforms' columns at the
        fixed nodes (a fixed node's coordinates are ``U[:, i] ⊗ V[:, i]``) and ``C = ω Eᵀ K⁻¹ E``,
        ``C_ij = Σ_kl U_ki U_kj (ω/λ_kl) V_li V_lj`` (float64; in chunks of rows of about 4·10⁶ values)."""
        m, n = self._box_shape
        rows, cols = np.divmod(self._inner, n)
        U, V = self._axes[0].columns(rows), self._axes[1].columns(cols)
        p = U.shape[1]
        C = np.empty((p, p))
        step = max(1, int(4e6 // (p * max(m, n))))
        with _threads.blas_pinned():  # (the products on BLAS's one thread, as every solve)
            for lo in range(0, p, step):
                hi = min(p, lo + step)
                M = self._inverse64 @ (V[:, lo:hi, None] * V[:, None, :]).reshape(n, -1)  # (m, q·p)
                C[lo:hi] = np.einsum("kx,kx->x", (U[:, lo:hi, None] * U[:, None, :]).reshape(m, -1), M).reshape(-1, p)
        try:
            with _threads.blas_pinned():
                factor = sla.cho_factor(0.5 * (C + C.T))
        except np.linalg.LinAlgError:  # (rounding made it indefinite: the fixed rows are only zeroed)
            return
        self._factored = (U, V, factor)

    def _fold_correction(self, G: np.ndarray, workers: int = 1) -> np.ndarray:
        """``ẑ = ŷ − (ω/λ) ⊙ Σ_i μ_i U_i ⊗ V_i`` with ``μ = C⁻¹ y_x``: the exact lines' correction on ``ŷ = ω K⁻¹ r``
        in their coordinates (a ``(c, m, n)`` float32 array), in double precision: ``y_x`` (``ŷ`` at the fixed
        nodes) is read exactly from ``ŷ``, so the result is ``K_ff⁻¹`` of a residual perturbed by single
        precision's rounding of ``ŷ``, however large the near-null modes that the fixed nodes hold (a
        subtraction of them in single precision would not be). Down to ``ω`` about 10⁻¹⁰ of ``K``'s largest
        eigenvalue: ``C`` holds parts of size ``ω`` beside ones of size 1, so double precision's own rounding
        then shows (a reviewer measured 2·10⁻⁷–6·10⁻⁷ relative error at 1–10⁻¹⁰, 1.6·10⁻⁴ at 10⁻¹², and the
        Cholesky factorization failing at 10⁻¹⁶, where the fixed nodes are then only zeroed). On ``workers`` threads,
        in slabs of columns whose double-precision copies stay within :data:`FOLD_SLAB_BYTES` (one slab of the whole
        300² grid took five times as long as two halves, a throwaway timing: its copies left the cache)."""
        U, V, factor = self._factored  # type: ignore[misc]
        cols = G.shape[2]
        count = min(cols, max(workers, -(-G.size * 8 // FOLD_SLAB_BYTES)))
        slabs = [(k, lo, hi) for k, (lo, hi) in enumerate(_threads.split_ranges(cols, parts=count))]
        shares = [slabs[k::workers] for k in range(min(workers, len(slabs)))]  # (each thread's slabs, in turn)
        read: list[np.ndarray] = [np.empty(0)] * len(slabs)

        def values(k: int, lo: int, hi: int) -> None:  # the slab's share of y_x: (c, p)
            read[k] = np.einsum("cpn,np->cp", np.matmul(U.T, G[:, :, lo:hi].astype(np.float64)), V[lo:hi])

        def each(share: list[tuple[int, int, int]], fn: Callable[[int, int, int], None]) -> None:
            for slab in share:
                fn(*slab)

        _threads.run_tasks(each, [(share, values) for share in shares])
        mu = sla.cho_solve(factor, sum(read[1:], read[0]).T)  # (p, c)
        A = U[None] * mu.T[:, None, :]  # (c, m, p)
        out = np.empty_like(G)

        def subtract(k: int, lo: int, hi: int) -> None:  # (in double, rounded once into out: as a double copy would)
            correction = np.matmul(A, V[lo:hi].T)  # (c, m, p) @ (p, hi − lo)
            correction *= self._inverse64[:, lo:hi]
            np.subtract(G[:, :, lo:hi], correction, out=out[:, :, lo:hi], casting="same_kind")

        _threads.run_tasks(each, [(share, subtract) for share in shares])
        return out

    def _correct(self) -> None:
        """Set up the capacitance correction by stored columns: ``W = ω K_box⁻¹ E_x`` and ``C = W_x``, in the apply's
        precision (single, or double at a large condition: :data:`CORRECTION_SINGLE_MAX`)."""
        p = self._inner.size
        E = np.zeros((p,) + self._box_shape)
        E.reshape(p, -1)[np.arange(p), self._inner] = 1.0
        exact = any(a.kind == "exact" for a in self._axes)
        # (an exact line's products on the solver's threads with BLAS on one thread each, as in block_cg)
        with _threads.blas_pinned() if exact else contextlib.nullcontext():
            W = self._solve_box(E.astype(self._dtype), self._dtype).reshape(p, -1)
        C = W[:, self._inner].astype(np.float64)
        try:
            with _threads.blas_pinned():
                factor = sla.cho_factor(0.5 * (C + C.T))
        except np.linalg.LinAlgError:  # (rounding made it indefinite: the fixed rows are only zeroed)
            return
        self._correction = (W.astype(self._dtype), factor)

    def operator(self) -> sp.csr_matrix:
        """``K`` on the box, ``ωI`` off it, in the grid's row-major order (``P⁻¹`` inverts its part on the unknowns
        where exact).

        On the box ``K = c_r (I ⊗ B_r) + c_c (B_c ⊗ I) + ωI`` with each axis's ``B`` over the box's span: the
        principal part of :func:`line_third_differences` (exact), the span's own ``L³`` (cosine), the whole closed
        line's ``L³``. With exact lines that is the whole grid's ``K``'s part on the box.

        Returns
        -------
        (rows · cols, rows · cols) scipy.sparse.csr_matrix

        Examples
        --------
        >>> SpectralPreconditioner((2, 4), (False, False), 1.0, 0.0, 0.5).operator()[0, :4].toarray().tolist()
        [[1.5, -3.0, 3.0, -1.0]]
        """
        rows, cols = self.shape
        (m, n) = self._box_shape
        # each family's coefficient per line: the rows' lines (one per row) and the columns' (one per column)
        scales = [sp.eye(m) * self.coefficients[0], sp.eye(n) * self.coefficients[1]]
        windows = None
        if self.profile is not None:  # the family along a by its windows, the other's lines one by one along a
            a, windows, line_coefficients, across = self.profile
            ax = self._axes[a]
            scales[1 - a] = sp.eye(self._box_shape[1 - a])
            scales[a] = sp.diags(line_coefficients[ax.lo:ax.hi])
        lines = []
        for axis, (ax, closed) in enumerate(zip(self._axes, self.wrap)):
            if ax.kind == "exact":
                w = None if self.profile is None else windows if axis == self.profile[0] else across
                lines.append(line_third_differences(ax.n, ax.closed, w)[ax.lo:ax.hi, ax.lo:ax.hi])
            else:
                L = line_laplacian(ax.size, closed)
                lines.append(L @ L @ L)
        Bc, Br = lines
        K = sp.kron(scales[0], Br) + sp.kron(Bc, scales[1])
        nodes = np.arange(rows * cols).reshape(rows, cols)[self._axes[0].lo:self._axes[0].hi,
                                                           self._axes[1].lo:self._axes[1].hi].ravel()
        K = sp.coo_matrix(K)
        embedded = sp.csr_matrix((K.data, (nodes[K.row], nodes[K.col])), shape=(rows * cols, rows * cols))
        return sp.csr_matrix(embedded + self.weight * sp.eye(rows * cols))

    def apply(self, R: np.ndarray, Z: np.ndarray, lo: int, hi: int, columns: bool) -> None:
        """``Z = P⁻¹ R`` on every row (``lo``, ``hi`` are ignored: the transforms need the whole grid).

        ``R``, ``Z``: ``(c, k)`` arrays (``columns``) or ``(k, c)``, ``k ≥ rows · cols`` (rows past the
        grid, the CG vectors' padding, get zeros).
        """
        rows, cols = self.shape
        n = rows * cols
        (r0, r1), (c0, c1) = (self._axes[0].lo, self._axes[0].hi), (self._axes[1].lo, self._axes[1].hi)
        X = R[:, :n] if columns else R[:n].T  # (c, n)
        Xb = X.reshape(-1, rows, cols)[:, r0:r1, c0:c1]
        # each column scaled to at most 1 in single precision (no overflow or underflow whatever the units),
        # the scales and the eigenvalues' put back on the way out
        scale = np.maximum(Xb.max(axis=(1, 2)), -Xb.min(axis=(1, 2)))  # (two reductions: no |X| temporary)
        scale[~(np.isfinite(scale) & (scale > 0))] = 1.0
        G = np.empty(Xb.shape, dtype=self._dtype)
        np.multiply(Xb, (1.0 / scale)[:, None, None], out=G, casting="same_kind")
        inner = self._inner
        G.reshape(G.shape[0], -1)[:, inner] = 0.0  # (E on the way in too: whatever R holds there)
        G = np.ascontiguousarray(self._solve_box(G, self._dtype, fold=True))  # (so that flat is a view of G)
        flat = G.reshape(G.shape[0], -1)
        if self._correction is not None:  # Woodbury: K_ff⁻¹ = K⁻¹ − K⁻¹E (EᵀK⁻¹E)⁻¹ EᵀK⁻¹ on the unknowns
            W, factor = self._correction
            mu = sla.cho_solve(factor, flat[:, inner].T.astype(np.float64)).astype(flat.dtype)  # (p, c)
            flat -= np.einsum("pc,pn->cn", mu, W)  # (NumPy's own loop, no BLAS: see blas_free)
        flat[:, inner] = 0.0
        out = Z[:, :n] if columns else Z[:n].T  # (c, n), a view of Z either way
        if (r1 - r0, c1 - c0) != self.shape:
            out[...] = 0.0
        np.multiply(G, (scale / self.weight)[:, None, None], out=out.reshape(-1, rows, cols)[:, r0:r1, c0:c1])
        (Z[:, n:] if columns else Z[n:])[...] = 0.0

    def _solve_box(self, G: np.ndarray, dtype: type, fold: bool = False) -> np.ndarray:
        """``ω K_box⁻¹ G`` for a ``(c, box rows, box cols)`` array (overwritten) in ``dtype``; with ``fold`` (and
        exact lines' correction) ``ω K_ff⁻¹ G`` on the unknowns (:meth:`_fold_correction`)."""
        axes = self._axes
        fft: ModuleType | None = None
        if any(a.kind != "exact" for a in axes):  # (importing SciPy's transforms costs about 40 ms: only if used)
            import scipy.fft as fft
        workers = _threads.thread_count() if G[0].size >= PARALLEL_MIN_NODES else 1  # (SciPy's transforms)
        exact_workers = _threads.thread_count() if G[0].size >= EXACT_PARALLEL_MIN_NODES else 1  # (BLAS products)
        # the real transforms first (exact products and cosine transforms keep real data), then rfft, then fft
        order = sorted((1, 2), key=lambda a: ("exact", "dct", "rfft", "fft").index(axes[a - 1].kind))
        def on(axis: int) -> int:
            return exact_workers if axes[axis - 1].kind == "exact" else workers

        for axis in order:
            G = self._transform(G, axis, True, fft, on(axis), dtype)
        G *= self._inverse if dtype == np.float32 else self._inverse64
        if fold and self._factored is not None:
            G = self._fold_correction(G, exact_workers)
        for axis in order[::-1]:
            G = self._transform(G, axis, False, fft, on(axis), dtype)
        return G

    def _transform(self, G: np.ndarray, axis: int, forward: bool, fft: ModuleType | None, workers: int,
                   dtype: type) -> np.ndarray:
        ax = self._axes[axis - 1]
        if ax.kind == "exact":
            blocks = ax.blocks32 if dtype == np.float32 else ax.blocks64
            out = np.empty_like(G)
            parts = _threads.split_ranges(G.shape[3 - axis], parts=workers)  # (the other axis, cut per thread)

            def task(lo: int, hi: int) -> None:
                cut = (slice(None), slice(lo, hi)) if axis == 2 else (slice(None), slice(None), slice(lo, hi))
                _exact(G[cut], axis, blocks, forward, out[cut])

            _threads.run_tasks(task, parts)
            return out
        assert fft is not None  # (imported by _solve_box wherever an axis is not exact)
        if ax.kind == "dct":
            f = fft.dct if forward else fft.idct
            return f(G, type=2, axis=axis, norm="ortho", overwrite_x=True, workers=workers)
        if ax.kind == "rfft":
            if forward:
                return fft.rfft(G, axis=axis, overwrite_x=True, workers=workers)
            return fft.irfft(G, n=ax.size, axis=axis, overwrite_x=True, workers=workers)
        return (fft.fft if forward else fft.ifft)(G, axis=axis, overwrite_x=True, workers=workers)
