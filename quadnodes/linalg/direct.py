"""Direct sparse factorizations that cannot crash: definite matrices unpivoted, the rest pivoted.

SuperLU without pivoting (``diag_pivot_thresh=0``) is the fast way to factorize a
symmetric matrix in a fill-reducing symmetric order, but on a singular matrix it
meets an exact zero pivot, reports "Factor is exactly singular" and may corrupt
its heap — the process dies. So the unpivoted path is taken only for matrices
that are definite by construction: symmetric positive definite (``"spd"``) or
quasi-definite ``[[H, Gᵀ], [G, −D]]`` with ``H`` and ``D`` positive definite
(``"quasi-definite"``; Vanderbei 1995: such a matrix has an LDLᵀ factorization in
every symmetric order). Callers make them so with :func:`regularization`; a
matrix whose diagonal shows it is not (a non-positive pivot candidate) is
refused before SuperLU sees it. Everything else (``"general"``) is factorized
with partial pivoting, where SuperLU raises instead of crashing.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from ..errors import InputError

__all__ = ["Factorization", "factorize", "regularization"]

Kind = Literal["spd", "quasi-definite", "general"]


class Factorization:
    """A factorized sparse matrix: :meth:`solve` for one or many right-hand sides.

    Examples
    --------
    >>> M = sp.csc_matrix(np.array([[4.0, 1.0], [1.0, 3.0]]))
    >>> f = factorize(M, kind="spd", what="example")
    >>> np.round(f.solve(np.array([1.0, 2.0])), 6).tolist()
    [0.090909, 0.636364]
    """

    def __init__(self, lu: object, n: int, what: str, pivoted: bool) -> None:
        self._lu = lu
        self.shape = (n, n)
        self.what = what
        self.pivoted = pivoted

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """Solve for ``rhs`` of shape ``(n,)`` or ``(n, k)``.

        Raises
        ------
        InputError
            If the solution is not finite (a numerically singular system).
        """
        x = self._lu.solve(np.asarray(rhs, dtype=np.float64))  # type: ignore[attr-defined]
        if not np.isfinite(x).all():
            raise InputError(f"{self.what}: the linear system is numerically singular (the solution is not finite)")
        return x


def regularization(M: sp.spmatrix, relative: float = 1e-10) -> float:
    """A diagonal shift ``δ = relative × max |diag(M)|`` that makes a positive semi-definite ``M`` definite.

    Examples
    --------
    >>> regularization(sp.diags([2.0, 0.0]))
    2e-10
    """
    d = np.abs(M.diagonal())
    top = float(d.max()) if d.size else 0.0
    return relative * (top if top > 0 else 1.0)


def factorize(M: sp.spmatrix, *, kind: Kind = "general", what: str = "system",
              negative: int = 0) -> Factorization:
    """Factorize a square sparse matrix once, for many solves, without ever crashing.

    Parameters
    ----------
    M : (n, n) sparse
    kind : {"spd", "quasi-definite", "general"}
        What the caller guarantees: ``"spd"`` symmetric positive definite;
        ``"quasi-definite"`` symmetric with a positive definite leading block
        and a negative definite trailing block of ``negative`` rows. These are
        factorized without pivoting in a symmetric minimum-degree order (fast);
        ``"general"`` with partial pivoting.
    what : str
        Named in error messages (e.g. ``"planarize (Newton step)"``).
    negative : int
        Size of the negative definite trailing block (quasi-definite only).

    Returns
    -------
    Factorization

    Raises
    ------
    InputError
        When the diagonal shows the promised definiteness does not hold (a
        zero or wrong-signed pivot candidate), or SuperLU finds the matrix
        singular — naming ``what``.

    Examples
    --------
    >>> factorize(sp.csc_matrix(np.zeros((2, 2))), kind="spd", what="demo")
    Traceback (most recent call last):
    ...
    quadnodes.errors.InputError: demo: the matrix is not positive definite (diagonal entry 0 is 0); the energy does not determine every unknown
    """
    M = sp.csc_matrix(M)
    n = M.shape[0]
    if M.shape != (n, n):
        raise InputError(f"{what}: expected a square matrix, got shape {M.shape}")
    if kind in ("spd", "quasi-definite"):
        d = M.diagonal()
        k = n - (negative if kind == "quasi-definite" else 0)
        bad = np.flatnonzero(~(d[:k] > 0))
        if bad.size:
            raise InputError(
                f"{what}: the matrix is not positive definite (diagonal entry {int(bad[0])} is "
                f"{d[bad[0]]:.3g}); the energy does not determine every unknown"
            )
        if kind == "quasi-definite":
            bad = np.flatnonzero(~(d[k:] < 0))
            if bad.size:
                raise InputError(
                    f"{what}: the constraint block is not negative definite (entry {int(bad[0]) + k} is "
                    f"{d[k + bad[0]]:.3g})"
                )
        try:
            lu = splu(M, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        except RuntimeError as exc:  # pragma: no cover - definite matrices have no zero pivot
            raise InputError(f"{what}: the matrix could not be factorized ({exc})") from exc
        return Factorization(lu, n, what, pivoted=False)
    if kind != "general":
        raise InputError(f"kind: expected 'spd', 'quasi-definite' or 'general', got {kind!r}")
    try:
        lu = splu(M)
    except RuntimeError as exc:
        raise InputError(f"{what}: the matrix is singular ({exc})") from exc
    return Factorization(lu, n, what, pivoted=True)
