"""The spectral preconditioner: ``K⁻¹`` by cosine and Fourier transforms on open and closed grids."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from quadnodes.linalg import spectral
from quadnodes.linalg.spectral import SpectralPreconditioner, line_laplacian


def _apply(P, R, columns=True):
    Z = np.full_like(R, np.nan)
    P.apply(R, Z, 0, 0, columns)
    return Z


@settings(max_examples=60, deadline=None)
@given(rows=st.integers(1, 12), cols=st.integers(1, 12), wrap=st.tuples(st.booleans(), st.booleans()),
       c_r=st.floats(0.0, 5.0), c_c=st.floats(0.0, 5.0), weight=st.floats(0.05, 3.0), seed=st.integers(0, 2**16))
def test_it_inverts_the_constant_coefficient_operator(rows, cols, wrap, c_r, c_c, weight, seed):
    """``K P⁻¹ r = r`` to single precision, for any shape (one-wide included), open or closed axes."""
    P = SpectralPreconditioner((rows, cols), wrap, c_r, c_c, weight)
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


def test_the_operator_is_the_line_laplacians_cubed():
    """``K = c_r (I ⊗ L³) + c_c (L³ ⊗ I) + ωI`` with ``L`` the rows' and columns' Laplacians, periodic where closed."""
    P = SpectralPreconditioner((5, 7), (True, False), 2.0, 3.0, 0.5)
    Lr, Lc = line_laplacian(7).toarray(), line_laplacian(5, closed=True).toarray()
    K = 2.0 * np.kron(np.eye(5), np.linalg.matrix_power(Lr, 3)) + 3.0 * np.kron(np.linalg.matrix_power(Lc, 3), np.eye(7))
    np.testing.assert_allclose(P.operator().toarray(), K + 0.5 * np.eye(35))
    # a line of third differences with constant coefficients differs from L³ only near its ends
    D = sp.diags([-1.0, 3.0, -3.0, 1.0], [0, 1, 2, 3], shape=(17, 20)).toarray()
    L3 = np.linalg.matrix_power(line_laplacian(20).toarray(), 3)
    np.testing.assert_allclose((D.T @ D)[3:-3, 3:-3], L3[3:-3, 3:-3])


def test_fixed_nodes_get_zero_and_the_preconditioner_is_symmetric_positive_definite():
    rng = np.random.default_rng(4)
    free = rng.random(48) > 0.2
    P = SpectralPreconditioner((6, 8), (False, True), 1.5, 0.7, 0.2, free)
    X, Y = rng.normal(size=(2, 48)), rng.normal(size=(2, 48))
    X[:, ~free] = Y[:, ~free] = 0.0
    PX, PY = _apply(P, X), _apply(P, Y)
    assert np.all(PX[:, ~free] == 0.0)
    # P⁻¹ = S K⁻¹ S: whatever the input holds on fixed rows is ignored
    noisy = X.copy()
    noisy[:, ~free] = rng.normal(size=(2, int((~free).sum())))
    np.testing.assert_allclose(_apply(P, noisy), PX, rtol=0, atol=1e-6 * np.abs(PX).max())
    a, b = np.einsum("ij,ij->i", PX, Y), np.einsum("ij,ij->i", X, PY)
    np.testing.assert_allclose(a, b, rtol=1e-5)
    assert np.all(np.einsum("ij,ij->i", PX, X) > 0)


@pytest.mark.parametrize("kw, match", [
    (dict(shape=(0, 4)), "shape"),
    (dict(weight=0.0), "weight"),
    (dict(weight=np.nan), "weight"),
    (dict(row_coefficient=-1.0), "row_coefficient"),
    (dict(column_coefficient=np.inf), "column_coefficient"),
    (dict(free=np.ones(5, bool)), "free"),
])
def test_bad_arguments_are_named(kw, match):
    args = dict(shape=(3, 4), wrap=(False, False), row_coefficient=1.0, column_coefficient=1.0, weight=0.3)
    args.update(kw)
    with pytest.raises(ValueError, match=match):
        SpectralPreconditioner(**args)


def test_loaded_says_whether_the_transforms_are_imported():
    """In a fresh interpreter that has not imported them, ``loaded()`` is false; importing them makes it true."""
    import subprocess
    import sys

    code = ("import sys; from quadnodes.linalg import spectral; a = spectral.loaded(); import scipy.fft; "
            "print(a, spectral.loaded(), 'scipy.fft' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["False", "True", "True"]


def test_parallel_transforms_equal_one_thread(monkeypatch):
    from quadnodes.linalg import threads

    P = SpectralPreconditioner((30, 40), (False, True), 1.0, 2.0, 0.3)
    R = np.random.default_rng(1).normal(size=(3, 1200))
    one = _apply(P, R)
    monkeypatch.setattr(spectral, "PARALLEL_MIN_NODES", 10)
    monkeypatch.setattr(threads, "thread_count", lambda: 2)
    np.testing.assert_allclose(_apply(P, R), one, rtol=0, atol=1e-6 * np.abs(one).max())


@pytest.mark.parametrize("units", [1e-30, 1.0, 1e30])
def test_any_units_stay_within_single_precision(units):
    """Coefficients, weight and residual of any magnitude: no overflow or underflow in the float32 transforms."""
    P = SpectralPreconditioner((9, 7), (False, True), 2.0 * units, 3.0 * units, 0.4 * units)
    R = np.random.default_rng(2).normal(size=(3, 63)) * (1.0 / units)
    R[2] = 0.0  # (a converged column)
    Z = _apply(P, R)
    assert np.all(np.isfinite(Z)) and np.all(Z[2] == 0.0)
    K = P.operator()
    assert np.abs(K @ Z[:2].T - R[:2].T).max() <= 1e-4 * np.abs(R).max()
