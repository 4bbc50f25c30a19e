import numpy as np
import pytest
import scipy.sparse as sp

import quadnodes.linalg.direct as direct
import quadnodes.linalg.inverse as inverse
from quadnodes.errors import InputError
from quadnodes.linalg import factorize, nested_dissection
from quadnodes.linalg.inverse import InverseBlock, inverse_columns


def plate(n, seed=0):
    """A biharmonic-like SPD matrix on an n × n grid (the pattern of fair_web's E2 systems), unevenly weighted."""
    rng = np.random.default_rng(seed)
    L1 = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n))
    L = sp.kron(L1, sp.identity(n)) + sp.kron(sp.identity(n), L1)
    W = sp.diags(rng.uniform(0.5, 2.0, n * n))
    return (L @ W @ L + 1e-3 * sp.identity(n * n)).tocsc()


@pytest.mark.parametrize("kind", ["spd", "symmetric"])
@pytest.mark.parametrize("order", ["minimum_degree", "nested_dissection"])
@pytest.mark.parametrize("compiled", [False, True])
def test_inverse_block_equals_dense_inverse(monkeypatch, kind, order, compiled):
    """Grown in three steps, the block equals the dense inverse's (SuperLU in both orders, sweeps or solves)."""
    monkeypatch.setattr(direct, "_cholmod", lambda: None)
    if not compiled:
        monkeypatch.setattr(inverse, "_kernel", lambda: None)
        monkeypatch.setattr(inverse, "COMPILED_MIN", 1 << 62)
    else:
        monkeypatch.setattr(inverse, "COMPILED_MIN", 0)
        monkeypatch.setattr(inverse, "SWEEP_MIN", 0)
    M = plate(9)
    dense = np.linalg.inv(M.toarray())
    f = factorize(M, kind=kind, order=order if order == "minimum_degree" else nested_dissection(M))
    rng = np.random.default_rng(1)
    S = rng.choice(81, 40, replace=False)
    block = InverseBlock(f)
    for part in (S[:1], S[1:25], S[25:]):
        block.extend(part)
    assert block._sweeps == compiled
    np.testing.assert_array_equal(block.index, S)
    np.testing.assert_allclose(block.block, dense[np.ix_(S, S)], atol=1e-10 * np.abs(dense).max())
    np.testing.assert_allclose(inverse_columns(f, S[:7], S), dense[np.ix_(S, S[:7])],
                               atol=1e-10 * np.abs(dense).max())
    np.testing.assert_allclose(inverse_columns(f, S[:5]), dense[:, S[:5]], atol=1e-10 * np.abs(dense).max())


def test_inverse_block_through_cholmod():
    if not direct.cholmod_available():
        pytest.skip("scikit-sparse not installed")
    M = plate(8)
    f = factorize(M, kind="spd", backend="cholmod")
    block = InverseBlock(f)
    block.extend(np.array([3, 40, 7]))
    block.extend(np.array([63]))
    S = [3, 40, 7, 63]
    np.testing.assert_allclose(block.block, np.linalg.inv(M.toarray())[np.ix_(S, S)], rtol=1e-9, atol=1e-12)


def test_inverse_indices_checked():
    f = factorize(plate(4), kind="spd", what="demo")
    with pytest.raises(InputError, match="demo: indices must be in range"):
        InverseBlock(f).extend(np.array([16]))
    with pytest.raises(InputError, match="demo: cols must be indices"):
        inverse_columns(f, np.array([-1]))
