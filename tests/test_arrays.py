"""quadnodes._arrays: sorted unique values and rows equal NumPy's np.unique exactly."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from quadnodes._arrays import unique_rows, unique_values


@settings(max_examples=60, deadline=None)
@given(hnp.arrays(np.int64, st.integers(0, 60), elements=st.integers(-2**40, 2**40)))
def test_unique_values_is_np_unique(a):
    np.testing.assert_array_equal(unique_values(a), np.unique(a))


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 4), st.integers(0, 50), st.integers(0, 2**31 + 5), st.booleans(), st.integers(0, 2**31))
def test_unique_rows_is_np_unique_axis0(k, m, top, negative, seed):
    """Packed keys (two non-negative columns below 2³¹) and lexsort (other widths, negatives, large values)."""
    rng = np.random.default_rng(seed)
    low = -top if negative else 0
    a = rng.integers(low, top + 1, size=(m, k)).astype(np.int64)
    if m > 3:
        a[m // 2 :] = a[: m - m // 2]  # repeats
    for dtype in (np.int64, np.int32) if top < 2**31 else (np.int64,):
        b = a.astype(dtype)
        got = unique_rows(b)
        assert got.dtype == b.dtype
        np.testing.assert_array_equal(got, np.unique(b, axis=0).reshape(-1, k))


def test_unique_rows_refuses_other_shapes():
    with pytest.raises(ValueError, match="2-D"):
        unique_rows(np.arange(4))


@settings(max_examples=40, deadline=None)
@given(hnp.arrays(np.float64, st.tuples(st.integers(0, 30), st.just(3)),
                  elements=st.floats(-1e150, 1e150, allow_nan=False)),
       hnp.arrays(np.float64, st.tuples(st.integers(0, 30), st.just(3)),
                  elements=st.floats(-1e150, 1e150, allow_nan=False)))
def test_cross_and_norm_rows_are_numpys_to_the_bit(a, b):
    """Coordinates as rows: the same numbers as np.cross and np.linalg.norm of (m, 3) arrays."""
    from quadnodes._arrays import cross_rows, norm_rows

    m = min(len(a), len(b))
    a, b = a[:m], b[:m]
    with np.errstate(over="ignore", invalid="ignore"):
        np.testing.assert_array_equal(cross_rows(a.T.copy(), b.T.copy()).T, np.cross(a, b) if m else a)
        np.testing.assert_array_equal(norm_rows(a.T.copy()), np.linalg.norm(a, axis=1))
