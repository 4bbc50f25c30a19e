"""The spectral preconditioner: ``K_ff⁻¹`` by the lines' eigenvectors and by transforms on open and closed grids."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from quadnodes.linalg import spectral
from quadnodes.linalg.spectral import SpectralPreconditioner, line_laplacian, line_third_differences


def _apply(P, R, columns=True):
    Z = np.full_like(R, np.nan)
    P.apply(R, Z, 0, 0, columns)
    return Z


def _third_differences(n):
    D = np.zeros((max(n - 3, 0), n))
    for i in range(n - 3):
        D[i, i:i + 4] = (-1.0, 3.0, -3.0, 1.0)
    return D.T @ D


@settings(max_examples=80, deadline=None)
@given(rows=st.integers(1, 12), cols=st.integers(1, 12), wrap=st.tuples(st.booleans(), st.booleans()),
       c_r=st.floats(0.0, 5.0), c_c=st.floats(0.0, 5.0), weight=st.floats(0.05, 3.0), seed=st.integers(0, 2**16),
       open_lines=st.sampled_from(["exact", "cosine"]))
def test_it_inverts_the_constant_coefficient_operator(rows, cols, wrap, c_r, c_c, weight, seed, open_lines):
    """``K P⁻¹ r = r`` to single precision, for any shape (one-wide included), open or closed axes."""
    P = SpectralPreconditioner((rows, cols), wrap, c_r, c_c, weight, open_lines=open_lines)
    n = rows * cols
    R = np.random.default_rng(seed).normal(size=(3, n + 4))
    R[:, n:] = 0.0
    Z = _apply(P, R)
    K = P.operator()
    assert np.all(Z[:, n:] == 0.0)
    scale = np.abs(R).max() * (1.0 + (c_r + c_c) * 64.0 / weight)  # (K's condition bounds the rounding)
    assert np.abs(K @ Z[:, :n].T - R[:, :n].T).max() <= 1e-5 * scale
    # (k, c) vectors give the same
    Zt = _apply(P, np.ascontiguousarray(R.T), columns=False)
    np.testing.assert_allclose(Zt.T, Z, rtol=0, atol=1e-6 * np.abs(Z).max())


@settings(max_examples=80, deadline=None)
@given(rows=st.integers(1, 14), cols=st.integers(1, 14), wrap=st.tuples(st.booleans(), st.booleans()),
       ring=st.tuples(*[st.integers(0, 3)] * 4), share=st.floats(0.0, 0.3), weight=st.sampled_from([1.0, 1e-3, 1e-6]),
       seed=st.integers(0, 2**16), open_lines=st.sampled_from(["exact", "cosine"]))
def test_it_inverts_the_operator_on_the_unknowns(rows, cols, wrap, ring, share, weight, seed, open_lines):
    """With fixed nodes (a fixed band along the open sides, up to MAX_CORRECTED scattered inside): ``P⁻¹ = E K_ff⁻¹ Eᵀ``
    exactly, at any weight, ``K`` on the unknowns' box (:func:`spectral.box`); its rows and columns at fixed nodes are
    zero."""
    rng = np.random.default_rng(seed)
    free = np.ones((rows, cols), bool)
    top, bottom, left, right = ring
    if not wrap[0]:
        free[:top] = False
        free[rows - bottom:] = False
    if not wrap[1]:
        free[:, :left] = False
        free[:, cols - right:] = False
    free &= rng.random((rows, cols)) >= share
    free = free.ravel()
    if not free.any():
        free[rng.integers(rows * cols)] = True
    P = SpectralPreconditioner((rows, cols), wrap, 2.0, 1.5, weight, free, open_lines=open_lines)
    n = rows * cols
    R = rng.normal(size=(2, n))
    Z = _apply(P, R)
    assert np.all(Z[:, ~free] == 0.0)
    Kff = P.operator()[free][:, free].toarray()
    expected = np.linalg.solve(Kff, R[:, free].T).T
    # single precision: the error relative to the result's size, amplified by at most K_ff's condition over the
    # near-null modes that the fixed nodes hold (they leave their own ill-conditioned correction)
    assert np.abs(Z[:, free] - expected).max() <= 2e-3 * np.abs(expected).max(), P._correction is not None


def test_the_exact_operator_is_the_lines_third_differences_and_the_cosine_one_the_laplacians_cube():
    """``K = c_r (I ⊗ B_r) + c_c (B_c ⊗ I) + ωI``; ``B = DᵀD`` (periodic where closed: ``L³``), or ``L³`` with cosine."""
    P = SpectralPreconditioner((5, 7), (True, False), 2.0, 3.0, 0.5)
    Lc = line_laplacian(5, closed=True).toarray()
    K = 2.0 * np.kron(np.eye(5), _third_differences(7)) + 3.0 * np.kron(np.linalg.matrix_power(Lc, 3), np.eye(7))
    np.testing.assert_allclose(P.operator().toarray(), K + 0.5 * np.eye(35))
    P = SpectralPreconditioner((5, 7), (True, False), 2.0, 3.0, 0.5, open_lines="cosine")
    Lr = line_laplacian(7).toarray()
    K = 2.0 * np.kron(np.eye(5), np.linalg.matrix_power(Lr, 3)) + 3.0 * np.kron(np.linalg.matrix_power(Lc, 3), np.eye(7))
    np.testing.assert_allclose(P.operator().toarray(), K + 0.5 * np.eye(35))
    # a line of third differences differs from L³ only near its ends
    L3 = np.linalg.matrix_power(line_laplacian(20).toarray(), 3)
    np.testing.assert_allclose(_third_differences(20)[3:-3, 3:-3], L3[3:-3, 3:-3])


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 9, 16])
def test_line_third_differences(n):
    np.testing.assert_allclose(line_third_differences(n).toarray(), _third_differences(n))
    L = line_laplacian(n, closed=True).toarray()
    np.testing.assert_allclose(line_third_differences(n, closed=True).toarray(), np.linalg.matrix_power(L, 3))


@pytest.mark.parametrize("n, lo, hi", [(2, 0, 2), (7, 0, 7), (8, 0, 8), (9, 1, 8), (10, 2, 8), (9, 0, 6), (12, 1, 12)])
def test_the_line_basis_diagonalizes_the_span(n, lo, hi):
    """Even and odd halves where the span is symmetric about the line's middle, one dense basis otherwise."""
    lam, blocks = spectral._line_basis(n, lo, hi)
    size = hi - lo
    assert len(blocks) == (2 if lo == n - hi else 1)
    X = np.eye(size)[None]  # the basis applied to every unit vector: T (forward) with T B Tᵀ = Λ, T Tᵀ = I
    T = np.empty_like(X)
    spectral._exact(X, 2, blocks, True, T)
    T = T[0].T  # (coordinate, node)
    B = _third_differences(n)[lo:hi, lo:hi]
    np.testing.assert_allclose(T @ T.T, np.eye(size), atol=1e-12)
    np.testing.assert_allclose(T @ B @ T.T, np.diag(lam), atol=1e-9 * max(1.0, lam.max()))
    back = np.empty_like(X)
    spectral._exact(T.T[None].copy(), 2, blocks, False, back)  # backward undoes forward
    np.testing.assert_allclose(back[0], np.eye(size), atol=1e-12)


@pytest.mark.parametrize("open_lines", ["exact", "cosine"])
def test_fixed_nodes_get_zero_and_the_preconditioner_is_symmetric_positive_definite(open_lines):
    rng = np.random.default_rng(4)
    for share in (0.2, 0.75):  # (with many fixed nodes, above MAX_CORRECTED at 0.75 of 120, they are only zeroed)
        free = rng.random(120) > share
        P = SpectralPreconditioner((12, 10), (False, True), 1.5, 0.7, 0.2, free, open_lines=open_lines)
        assert (P._correction is not None) == (share < 0.5)
        X, Y = rng.normal(size=(2, 120)), rng.normal(size=(2, 120))
        X[:, ~free] = Y[:, ~free] = 0.0
        PX, PY = _apply(P, X), _apply(P, Y)
        assert np.all(PX[:, ~free] == 0.0)
        # whatever the input holds on fixed rows is ignored
        noisy = X.copy()
        noisy[:, ~free] = rng.normal(size=(2, int((~free).sum())))
        np.testing.assert_allclose(_apply(P, noisy), PX, rtol=0, atol=1e-6 * np.abs(PX).max())
        a, b = np.einsum("ij,ij->i", PX, Y), np.einsum("ij,ij->i", X, PY)
        np.testing.assert_allclose(a, b, rtol=1e-4)
        assert np.all(np.einsum("ij,ij->i", PX, X) > 0)


def test_many_fixed_nodes_are_zeroed_not_corrected(monkeypatch):
    """An open grid with exact lines corrects in the lines' coordinates (up to MAX_CORRECTED_EXACT), any other by
    stored columns (up to MAX_CORRECTED); above, the fixed nodes are only zeroed."""
    free = np.ones(100, bool)
    free[np.arange(11, 89, 7)] = False  # 12 inside the box
    exact = SpectralPreconditioner((10, 10), (False, False), 1.0, 1.0, 0.1, free)
    assert exact._factored is not None and exact._correction is None and not exact.blas_free
    torus = SpectralPreconditioner((10, 10), (True, True), 1.0, 1.0, 0.1, free)
    assert torus._correction is not None and torus._factored is None and torus.blas_free
    assert spectral.inverts_exactly(free.reshape(10, 10), (False, False))
    monkeypatch.setattr(spectral, "MAX_CORRECTED_EXACT", 11)
    monkeypatch.setattr(spectral, "MAX_CORRECTED", 11)
    assert not spectral.inverts_exactly(free.reshape(10, 10), (False, False))
    P = SpectralPreconditioner((10, 10), (False, False), 1.0, 1.0, 0.1, free)
    assert P._correction is None and P._factored is None and P.blas_free is False  # (exact lines: BLAS products)
    torus = SpectralPreconditioner((10, 10), (True, True), 1.0, 1.0, 0.1, free)
    assert torus.blas_free and torus._correction is None  # (12 fixed nodes inside, above the 11 allowed: zeroed)
    cosine = SpectralPreconditioner((10, 10), (False, False), 1.0, 1.0, 0.1, free, open_lines="cosine")
    assert cosine.blas_free and cosine._correction is None


@pytest.mark.parametrize("wrap", [(True, False), (False, True), (True, True)])
@pytest.mark.parametrize("weight", [1.0, 1e-6])
def test_closed_axes_take_their_exact_basis_where_stored_columns_would_not_do(monkeypatch, wrap, weight):
    """More fixed nodes inside a cylinder's or torus's box than the stored columns take: the closed axes take their
    exact (dense) basis too, the correction works in the lines' coordinates, and P⁻¹ = K_ff⁻¹."""
    monkeypatch.setattr(spectral, "MAX_CORRECTED", 5)
    rng = np.random.default_rng(11)
    rows, cols = 13, 10
    free = np.ones(rows * cols, bool)
    free[rng.choice(rows * cols, 20, replace=False)] = False
    P = SpectralPreconditioner((rows, cols), wrap, 2.0, 1.5, weight, free)
    assert [ax.kind for ax in P._axes] == ["exact", "exact"] and P._factored is not None
    assert spectral.inverts_exactly(free.reshape(rows, cols), wrap)
    assert not spectral.inverts_exactly(free.reshape(rows, cols), wrap, "cosine")
    R = rng.normal(size=(2, rows * cols))
    Z = _apply(P, R)
    Kff = P.operator()[free][:, free].toarray()
    expected = np.linalg.solve(Kff, R[:, free].T).T
    assert np.all(Z[:, ~free] == 0.0)
    assert np.abs(Z[:, free] - expected).max() <= 1e-5 * np.abs(expected).max()
    # (with few enough, the Fourier transforms and stored columns, as before)
    monkeypatch.setattr(spectral, "MAX_CORRECTED", 64)
    assert "exact" not in [ax.kind for ax, closed in zip(SpectralPreconditioner(
        (rows, cols), wrap, 2.0, 1.5, weight, free)._axes, wrap) if closed]


@pytest.mark.parametrize("weight", [1e-4, 1e-8, 1e-10])
def test_the_exact_lines_correction_keeps_single_precision_at_tiny_weights(weight):
    """The correction in the exact lines' coordinates reads the fixed nodes' values from the coordinates in double
    precision: the result is K_ff⁻¹ to single precision's relative error (a residual perturbed by its rounding),
    however small the weight, with 200 fixed nodes (far more than the near-null modes they hold)."""
    rng = np.random.default_rng(7)
    rows, cols = 40, 36
    free = np.ones((rows, cols), bool)
    free[0] = False  # (a fixed row: off the box)
    free.ravel()[rng.choice(rows * cols, 200, replace=False)] = False
    free = free.ravel()
    P = SpectralPreconditioner((rows, cols), (False, False), 2.0, 1.0, weight, free)
    assert P._factored is not None and P._dtype == np.float32
    R = rng.normal(size=(3, rows * cols))
    Z = _apply(P, R)
    Kff = P.operator()[free][:, free].toarray()
    # the comparison: K_ff applied to the result gives back the residual (a backward error), in double precision
    back = Kff @ Z[:, free].T
    assert np.abs(back - R[:, free].T).max() <= 1e-3 * np.abs(R).max()


@pytest.mark.parametrize("kw, match", [
    (dict(shape=(0, 4)), "shape"),
    (dict(weight=0.0), "weight"),
    (dict(weight=np.nan), "weight"),
    (dict(row_coefficient=-1.0), "row_coefficient"),
    (dict(column_coefficient=np.inf), "column_coefficient"),
    (dict(free=np.ones(5, bool)), "free"),
    (dict(free=np.zeros(12, bool)), "at least one unknown"),
    (dict(open_lines="dense"), "open_lines"),
    (dict(profile=(2, np.ones(1), np.ones(4))), "axis 0 or 1"),
    (dict(profile=(1, np.ones(1))), "expected \\(axis, windows, lines"),
    (dict(profile=(0, np.ones(1), np.ones(3))), "4 to"),  # (3 rows: no window)
    (dict(profile=(1, np.ones(2), np.ones(4))), "1 finite window coefficients"),
    (dict(profile=(1, np.array([-1.0]), np.ones(4))), "window coefficients >= 0"),
    (dict(profile=(1, np.ones(1), np.array([1.0, 0.0, 1.0, 1.0]))), "line coefficients > 0"),
    (dict(profile=(1, np.ones(1), np.ones(4)), wrap=(False, True)), "closes around"),
    (dict(profile=(1, np.ones(1), np.ones(4), np.ones(1), np.ones(1))), "expected \\(axis, windows, lines"),
    (dict(shape=(5, 4), profile=(1, np.ones(1), np.ones(4), np.ones(1))), "2 finite across coefficients"),
    (dict(shape=(5, 4), profile=(1, np.ones(1), np.ones(4), np.ones(2)), wrap=(True, False)), "across needs an open"),
])
def test_bad_arguments_are_named(kw, match):
    args = dict(shape=(3, 4), wrap=(False, False), row_coefficient=1.0, column_coefficient=1.0, weight=0.3)
    args.update(kw)
    with pytest.raises(ValueError, match=match):
        SpectralPreconditioner(**args)


def test_a_side_longer_than_the_exact_limit_is_named(monkeypatch):
    monkeypatch.setattr(spectral, "EXACT_MAX_SIDE", 8)
    with pytest.raises(ValueError, match="at most 8 nodes"):
        SpectralPreconditioner((9, 4), (False, False), 1.0, 1.0, 0.3)
    SpectralPreconditioner((9, 4), (True, False), 1.0, 1.0, 0.3)  # (a closed axis: the Fourier transform)
    SpectralPreconditioner((9, 4), (False, False), 1.0, 1.0, 0.3, open_lines="cosine")


def test_loaded_says_whether_the_transforms_are_imported():
    """In a fresh interpreter that has not imported them, ``loaded()`` is false; importing them makes it true."""
    import subprocess
    import sys

    code = ("import sys; from quadnodes.linalg import spectral; a = spectral.loaded(); import scipy.fft; "
            "print(a, spectral.loaded(), 'scipy.fft' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["False", "True", "True"]


@pytest.mark.parametrize("wrap", [(False, True), (False, False), (True, True)])
def test_parallel_transforms_equal_one_thread(monkeypatch, wrap):
    """The transforms and the correction in the lines' coordinates on two threads, and the correction in slabs
    (several per thread), give what one thread and one slab give."""
    from quadnodes.linalg import threads

    free = np.ones(1200, bool)
    free[[0, 1, 500, 777]] = False
    P = SpectralPreconditioner((30, 40), wrap, 1.0, 2.0, 0.3, free)
    assert (P._factored is not None) == (wrap == (False, False))
    R = np.random.default_rng(1).normal(size=(3, 1200))
    one = _apply(P, R)
    monkeypatch.setattr(spectral, "PARALLEL_MIN_NODES", 10)
    monkeypatch.setattr(spectral, "EXACT_PARALLEL_MIN_NODES", 10)
    monkeypatch.setattr(threads, "thread_count", lambda: 2)
    np.testing.assert_allclose(_apply(P, R), one, rtol=0, atol=1e-6 * np.abs(one).max())
    monkeypatch.setattr(spectral, "FOLD_SLAB_BYTES", 3 * 30 * 8 * 3)  # (slabs of 3 columns: 14 of them, 7 a thread)
    np.testing.assert_allclose(_apply(P, R), one, rtol=0, atol=1e-6 * np.abs(one).max())


@pytest.mark.parametrize("open_lines", ["exact", "cosine"])
@pytest.mark.parametrize("units", [1e-30, 1.0, 1e30])
def test_any_units_stay_within_single_precision(units, open_lines):
    """Coefficients, weight and residual of any magnitude: no overflow or underflow in the float32 transforms."""
    free = np.ones(63, bool)
    free[[10, 20]] = False
    P = SpectralPreconditioner((9, 7), (False, True), 2.0 * units, 3.0 * units, 0.4 * units, free,
                               open_lines=open_lines)
    R = np.random.default_rng(2).normal(size=(3, 63)) * (1.0 / units)
    R[2] = 0.0  # (a converged column)
    R[:, ~free] = 0.0
    Z = _apply(P, R)
    assert np.all(np.isfinite(Z)) and np.all(Z[2] == 0.0)
    Kff = P.operator()[free][:, free]
    assert np.abs(Kff @ Z[:2, free].T - R[:2, free].T).max() <= 1e-4 * np.abs(R).max()


def _weighted_third_differences(n, windows):
    D = np.zeros((n - 3, n))
    for i in range(n - 3):
        D[i, i:i + 4] = (-1.0, 3.0, -3.0, 1.0)
    return D.T @ np.diag(windows) @ D


@pytest.mark.parametrize("with_across", [False, True])
def test_a_profile_operator_is_each_familys_own_sum(with_across):
    """With coefficients varying along the columns' axis (1): every row's windows weighted by position, every column
    scaled by its own coefficient (and, with ``across``, its windows weighted by position along it) — built here
    window by window."""
    rows, cols, weight = 6, 7, 0.2
    windows, lines = np.linspace(0.5, 2.0, cols - 3), np.linspace(1.0, 3.0, cols)
    across = np.array([0.5, 4.0, 1.5]) if with_across else None
    P = SpectralPreconditioner((rows, cols), (False, False), 9.0, 9.0, weight, profile=(1, windows, lines, across))
    K = weight * np.eye(rows * cols)
    idx = np.arange(rows * cols).reshape(rows, cols)
    for i in range(rows):  # a row's windows: their own coefficients
        K[np.ix_(idx[i], idx[i])] += _weighted_third_differences(cols, windows)
    column = _third_differences(rows) if across is None else _weighted_third_differences(rows, across)
    for j in range(cols):  # a column: its line's coefficient
        K[np.ix_(idx[:, j], idx[:, j])] += lines[j] * column
    np.testing.assert_allclose(P.operator().toarray(), K, atol=1e-12)


@settings(max_examples=80, deadline=None)
@given(rows=st.integers(4, 12), cols=st.integers(4, 12), axis=st.sampled_from([0, 1]),
       other=st.sampled_from(["open", "closed", "across"]), spread=st.floats(1.0, 100.0), share=st.floats(0.0, 0.3),
       weight=st.sampled_from([1.0, 1e-3, 1e-6]), seed=st.integers(0, 2**16),
       open_lines=st.sampled_from(["exact", "cosine"]))
def test_a_profile_inverts_the_varying_operator_on_the_unknowns(rows, cols, axis, other, spread, share, weight, seed,
                                                               open_lines):
    """Coefficients varying along an open axis by up to ``spread`` (the other axis open or closed, fixed nodes
    inside up to MAX_CORRECTED): ``P⁻¹ = E K_ff⁻¹ Eᵀ`` to single precision down to ω = 10⁻⁶, ``K`` the varying
    operator (see ``_pencil_basis`` for smaller weights with larger spreads)."""
    rng = np.random.default_rng(seed)
    closed = other == "closed"
    wrap = (False, closed) if axis == 0 else (closed, False)
    n_a, n_o = (rows, cols)[axis], (rows, cols)[1 - axis]
    windows = spread ** rng.random(n_a - 3)
    lines = spread ** rng.random(n_a)
    across = spread ** rng.random(n_o - 3) if other == "across" else None
    free = (rng.random((rows, cols)) >= share).ravel()
    if not free.any():
        free[rng.integers(rows * cols)] = True
    P = SpectralPreconditioner((rows, cols), wrap, 1.0, 1.0, weight, free, open_lines=open_lines,
                               profile=(axis, windows, lines, across))
    R = rng.normal(size=(2, rows * cols))
    Z = _apply(P, R)
    assert np.all(Z[:, ~free] == 0.0)
    Kff = P.operator()[free][:, free].toarray()
    expected = np.linalg.solve(Kff, R[:, free].T).T
    assert np.abs(Z[:, free] - expected).max() <= 2e-3 * np.abs(expected).max()


@pytest.mark.parametrize("lo, hi", [(0, 9), (2, 7), (1, 9)])
def test_the_pencil_basis_diagonalizes_both_parts(lo, hi):
    """``Xᵀ S X = I`` and ``Xᵀ (B + ωI) X = Θ`` over the span, ``B`` the weighted third differences' part there."""
    n, weight = 9, 0.05
    windows = np.array([0.3, 1.0, 2.0, 4.0, 0.7, 1.5])
    scale = np.linspace(0.2, 1.0, hi - lo)
    lam, (X,) = spectral._pencil_basis(n, lo, hi, windows, scale, weight)
    B = _weighted_third_differences(n, windows)[lo:hi, lo:hi]
    np.testing.assert_allclose(X.T @ np.diag(scale) @ X, np.eye(hi - lo), atol=1e-10)
    np.testing.assert_allclose(X.T @ (B + weight * np.eye(hi - lo)) @ X, np.diag(lam + weight), atol=1e-8)
    assert np.all(lam >= 0.0)
