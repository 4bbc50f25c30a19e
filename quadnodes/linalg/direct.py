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
refused before SuperLU sees it. Where definiteness is the caller's input's property rather than the
construction's (:class:`~quadnodes.linalg.quadratic.QuadraticProblem`'s energy), ``check=True`` reads it back from
the pivots: a matrix singular or indefinite to working precision factorizes without complaint (a graph
Laplacian's last pivot comes out 10⁻¹⁶–10⁻¹³ of its diagonal, positive or negative, by rounding alone) and would
give a meaningless solution, so a pivot within ``n·ε`` of its diagonal entry, or of the wrong sign, is refused
naming its unknown. A symmetric matrix that may be singular (``"symmetric"``) is
factorized in a symmetric order with diagonal pivots preferred but pivoting
left on (threshold 1e-3), so it is fast and a singular matrix raises; everything
else (``"general"``) with partial pivoting, where SuperLU raises instead of
crashing.

The order of a definite factorization (``order=``): large matrices
(:data:`NESTED_DISSECTION_MIN` unknowns or more) are factorized in a
nested-dissection order (:func:`~quadnodes.linalg.ordering.nested_dissection`,
SuperLU then told to keep it: ``permc_spec="NATURAL"`` on the permuted
matrix), small ones in SuperLU's minimum-degree order; a caller that factorizes
many matrices of one pattern computes the order once and passes it. On a
300 × 300 fair-web Newton system (177k unknowns, most vertices constrained)
minimum degree took 24 s of CPU and 77 M LU entries, nested dissection 9 s and
66 M; minimum degree stays better for matrices that are a few loosely joined
copies of one mesh matrix (``docs/methods.md``, ``benchmarks/perf/bench_direct.py``).
When scikit-sparse is importable (the optional ``bench`` extra) a ``"spd"``
matrix goes to CHOLMOD's supernodal Cholesky in the same order
(``backend="auto"``; ``"minimum_degree"`` becomes CHOLMOD's AMD), 2–6× faster
than SuperLU; without it SuperLU is used, and the results agree to round-off.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any, Literal

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from ..errors import InputError
from .ordering import nested_dissection
from .threads import blas_pinned

__all__ = ["Factorization", "factorize", "regularization", "cholmod_available", "NESTED_DISSECTION_MIN"]

Kind = Literal["spd", "quasi-definite", "symmetric", "general"]
#: Definite matrices with at least this many unknowns are factorized in a nested-dissection order by default
#: (below it SuperLU's minimum degree is as good and costs nothing to compute).
NESTED_DISSECTION_MIN = 20000
_ORDERS = ("auto", "nested_dissection", "minimum_degree")
_BACKENDS = ("auto", "superlu", "cholmod")


_THREADS: Any = None  # a threadpoolctl controller made after CHOLMOD's BLAS and OpenMP were loaded


def _cholmod() -> Any:
    """scikit-sparse's CHOLMOD module, or None when it is not installed (it is optional)."""
    try:
        from sksparse import cholmod
    except ImportError:
        return None
    return cholmod


@contextmanager
def _one_thread() -> Iterator[None]:
    """CHOLMOD's BLAS and OpenMP held to one thread while it runs (as :func:`~quadnodes.linalg.threads.blas_pinned`
    holds SciPy's, SuperLU's included): on a shared machine their spinning threads cost more CPU than they save."""
    global _THREADS
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:  # pragma: no cover - an optional speed-up
        yield
        return
    if _THREADS is None:
        _THREADS = ThreadpoolController()
    with _THREADS.limit(limits=1):  # type: ignore[attr-defined]
        yield


def cholmod_available() -> bool:
    """Whether scikit-sparse's CHOLMOD is importable (then ``backend="auto"`` uses it for SPD matrices).

    Examples
    --------
    >>> isinstance(cholmod_available(), bool)
    True
    """
    return _cholmod() is not None


class Factorization:
    """A factorized sparse matrix: :meth:`solve` for one or many right-hand sides.

    Examples
    --------
    >>> M = sp.csc_matrix(np.array([[4.0, 1.0], [1.0, 3.0]]))
    >>> f = factorize(M, kind="spd", what="example")
    >>> np.round(f.solve(np.array([1.0, 2.0])), 6).tolist()
    [0.090909, 0.636364]
    """

    def __init__(self, lu: object, n: int, what: str, pivoted: bool, *, perm: np.ndarray | None = None,
                 backend: str = "superlu", order: str = "minimum_degree") -> None:
        self._lu = lu
        self._perm = perm
        self.shape = (n, n)
        self.what = what
        self.pivoted = pivoted
        #: ``"superlu"`` or ``"cholmod"``.
        self.backend = backend
        #: ``"minimum_degree"``, ``"nested_dissection"``, ``"given"`` or ``"pivoting"``.
        self.order = order

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """Solve for ``rhs`` of shape ``(n,)`` or ``(n, k)``.

        Raises
        ------
        InputError
            If the solution is not finite (a numerically singular system).
        """
        b = np.asarray(rhs, dtype=np.float64)
        if b.shape[:1] != self.shape[:1]:
            raise InputError(f"{self.what}: the right-hand side has {b.shape[0] if b.ndim else 0} rows, "
                             f"the matrix {self.shape[0]}")
        p = self._perm
        if self.backend == "cholmod":
            with _one_thread():
                y = self._lu(b if p is None else b[p])  # type: ignore[operator]
        else:
            with blas_pinned():
                y = self._lu.solve(b if p is None else b[p])  # type: ignore[attr-defined]
        if p is None:
            x = y
        else:
            x = np.empty_like(y)
            x[p] = y
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
              negative: int = 0, order: str | np.ndarray = "auto", backend: str = "auto",
              check: bool = False, labels: np.ndarray | None = None) -> Factorization:
    """Factorize a square sparse matrix once, for many solves, without ever crashing.

    Parameters
    ----------
    M : (n, n) sparse
    kind : {"spd", "quasi-definite", "general"}
        What the caller guarantees: ``"spd"`` symmetric positive definite;
        ``"quasi-definite"`` symmetric with a positive definite leading block
        and a negative definite trailing block of ``negative`` rows. These are
        factorized without pivoting in a symmetric fill-reducing order (fast);
        ``"symmetric"`` (symmetric, maybe singular or indefinite) in a
        symmetric order with threshold pivoting that prefers the diagonal;
        ``"general"`` with partial pivoting.
    what : str
        Named in error messages (e.g. ``"planarize (Newton step)"``).
    negative : int
        Size of the negative definite trailing block (quasi-definite only).
    order : {"auto", "nested_dissection", "minimum_degree"} or (n,) int
        The symmetric fill-reducing order of a definite matrix: ``"auto"``
        nested dissection from :data:`NESTED_DISSECTION_MIN` unknowns on,
        minimum degree below; or a permutation (``M[p][:, p]`` is factorized,
        e.g. :func:`~quadnodes.linalg.ordering.nested_dissection` computed once
        for many matrices of one pattern). Ignored for ``"general"``.
    backend : {"auto", "superlu", "cholmod"}
        ``"auto"``: CHOLMOD (scikit-sparse, optional) for ``"spd"`` when it is
        importable, SuperLU otherwise; ``"cholmod"`` raises when it is not.
    check : bool
        ``"spd"`` and ``"quasi-definite"``: verify the promised definiteness from the pivots (each
        pivot of the positive block above ``n·ε`` times its diagonal entry, each of the negative block
        below ``−n·ε`` times its magnitude). For matrices whose definiteness the caller cannot
        guarantee by construction; costs a copy of the triangular factor.
    labels : (n,) int, optional
        The numbers error messages give the rows (e.g. their indices in a larger problem); default
        ``0 … n − 1``.

    Returns
    -------
    Factorization

    Raises
    ------
    InputError
        When the diagonal shows the promised definiteness does not hold (a
        zero or wrong-signed pivot candidate), with ``check`` when a pivot
        shows it, or SuperLU finds the matrix singular — naming ``what``.

    Examples
    --------
    >>> factorize(sp.csc_matrix(np.zeros((2, 2))), kind="spd", what="demo")
    Traceback (most recent call last):
    ...
    quadnodes.errors.InputError: demo: the matrix is not positive definite (diagonal entry 0 is 0); the energy does not determine every unknown

    A singular matrix with a positive diagonal (a chain of springs with no end held) passes the diagonal test.
    Here SuperLU meets an exact zero pivot; on larger such matrices rounding leaves a tiny one of either sign
    instead, which ``check`` finds (``docs/linalg.md``):

    >>> chain = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(4, 4)).tolil()
    >>> chain[0, 0] = chain[3, 3] = 1.0
    >>> factorize(chain.tocsc(), kind="spd", what="demo", check=True, backend="superlu")
    Traceback (most recent call last):
    ...
    quadnodes.errors.InputError: demo: the matrix is singular (Factor is exactly singular)
    """
    M = sp.csc_matrix(M)
    n = M.shape[0]
    if M.shape != (n, n):
        raise InputError(f"{what}: expected a square matrix, got shape {M.shape}")
    if not np.isfinite(M.data).all():
        raise InputError(f"{what}: the matrix has entries that are not finite (NaN or infinite)")
    if isinstance(backend, str) and backend not in _BACKENDS:
        raise InputError(f"backend: expected one of {', '.join(map(repr, _BACKENDS))}, got {backend!r}")
    if kind == "general":
        try:
            with blas_pinned():
                lu = splu(M)
        except RuntimeError as exc:
            raise InputError(f"{what}: the matrix is singular ({exc})") from exc
        return Factorization(lu, n, what, pivoted=True, order="pivoting")
    if kind == "symmetric":
        perm, how = _order(M, order)
        try:
            with blas_pinned():
                if perm is None:
                    lu = splu(M, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=1e-3, options={"SymmetricMode": True})
                else:
                    lu = splu(M[perm][:, perm].tocsc(), permc_spec="NATURAL", diag_pivot_thresh=1e-3,
                              options={"SymmetricMode": True})
        except RuntimeError as exc:
            raise InputError(f"{what}: the matrix is singular ({exc})") from exc
        return Factorization(lu, n, what, pivoted=True, perm=perm, order=how)
    if kind not in ("spd", "quasi-definite"):
        raise InputError(f"kind: expected 'spd', 'quasi-definite', 'symmetric' or 'general', got {kind!r}")
    name = np.arange(n) if labels is None else np.asarray(labels)
    if name.shape != (n,):
        raise InputError(f"labels: expected {n} numbers, got shape {name.shape}")
    d = M.diagonal()
    k = n - (negative if kind == "quasi-definite" else 0)
    bad = np.flatnonzero(~(d[:k] > 0))
    if bad.size:
        raise InputError(
            f"{what}: the matrix is not positive definite (diagonal entry {int(name[bad[0]])} is "
            f"{d[bad[0]]:.3g}); the energy does not determine every unknown"
        )
    if kind == "quasi-definite":
        bad = np.flatnonzero(~(d[k:] < 0))
        if bad.size:
            raise InputError(
                f"{what}: the constraint block is not negative definite (entry {int(name[bad[0] + k])} is "
                f"{d[k + bad[0]]:.3g})"
            )
    perm, how = _order(M, order)
    Mp = M if perm is None else M[perm][:, perm].tocsc()
    chol = _cholmod() if kind == "spd" and backend != "superlu" else None
    if backend == "cholmod" and chol is None:
        raise InputError("backend: 'cholmod' needs scikit-sparse (pip install scikit-sparse), which is not "
                         "importable" + ("" if kind == "spd" else f", and serves only kind='spd', not {kind!r}"))
    if chol is not None:
        try:
            with _one_thread():
                if perm is None:  # minimum degree asked for: CHOLMOD's own (AMD)
                    factor = chol.cholesky(Mp, ordering_method="amd", mode="supernodal")
                else:
                    factor = chol.analyze(Mp, ordering_method="natural", mode="supernodal")
                    factor.cholesky_inplace(Mp)
        except chol.CholmodError as exc:
            raise InputError(f"{what}: the matrix is not positive definite ({exc})") from exc
        if check:  # (LLᵀ of Mp[q][:, q]: the pivots are L's diagonal squared)
            pivots = np.empty(n)
            pivots[factor.P()] = factor.L().diagonal() ** 2
            _check_pivots(pivots, Mp.diagonal(), k, perm, name, what)
        return Factorization(factor, n, what, pivoted=False, perm=perm, backend="cholmod", order=how)
    try:
        with blas_pinned():  # (SuperLU's small dense blocks gain nothing from more BLAS threads)
            if perm is None:
                lu = splu(M, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
            else:
                lu = splu(Mp, permc_spec="NATURAL", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    except RuntimeError as exc:  # an exact zero pivot: a singular matrix with a positive diagonal
        raise InputError(f"{what}: the matrix is singular ({exc})") from exc
    if check:  # (Pr·Mp·Pc = LU with the row order the column order: column j's pivot is U[perm_c[j]])
        if not np.array_equal(lu.perm_r, lu.perm_c):  # an exact zero met on the diagonal: SuperLU pivoted off it
            j = int(np.flatnonzero(lu.perm_r != lu.perm_c)[0])
            raise InputError(f"{what}: the matrix is not positive definite (an exact zero pivot at unknown "
                             f"{int(name[j if perm is None else perm[j]])}); the energy does not determine every "
                             "unknown")
        _check_pivots(lu.U.diagonal()[lu.perm_c], Mp.diagonal(), k, perm, name, what)
    return Factorization(lu, n, what, pivoted=False, perm=perm, order=how)


def _check_pivots(pivots: np.ndarray, diagonal: np.ndarray, k: int, perm: np.ndarray | None, labels: np.ndarray,
                  what: str) -> None:
    """Refuse a factorization whose pivots (of the factorized matrix ``M[perm][:, perm]``, its diagonal beside
    them) show ``M`` singular or indefinite to working precision: the pivots of ``M``'s first ``k`` rows must
    exceed ``n·ε`` times their diagonal entry, the rest (a quasi-definite matrix's negative block) be below
    ``−n·ε`` times theirs. Errors name ``M``'s rows by ``labels``."""
    n = pivots.size
    row = np.arange(n) if perm is None else perm  # (M's row of each factorized row)
    tol = n * np.finfo(np.float64).eps
    ratio = pivots / np.abs(diagonal)
    ratio[row >= k] *= -1
    bad = np.flatnonzero(~(ratio > tol))
    if bad.size:
        i = int(bad[np.argmin(ratio[bad])])
        if row[i] < k:
            raise InputError(f"{what}: the matrix is not positive definite to working precision (the pivot of "
                             f"unknown {int(labels[row[i]])} is {ratio[i]:.1e} times its diagonal entry, at most "
                             f"n·ε = {tol:.1e}); the energy does not determine every unknown")
        raise InputError(f"{what}: the constraint block is not negative definite to working precision (the pivot "
                         f"of constraint {int(labels[row[i]])})")


def _order(M: sp.csc_matrix, order: str | np.ndarray) -> tuple[np.ndarray | None, str]:
    """The permutation to factorize in (None: SuperLU's minimum degree) and its name."""
    n = M.shape[0]
    if isinstance(order, str):
        if order not in _ORDERS:
            raise InputError(f"order: expected one of {', '.join(map(repr, _ORDERS))} or a permutation, "
                             f"got {order!r}")
        if order == "minimum_degree" or (order == "auto" and n < NESTED_DISSECTION_MIN):
            return None, "minimum_degree"
        return nested_dissection(M), "nested_dissection"
    p = np.asarray(order)
    if p.shape != (n,) or p.dtype.kind not in "iu" or not np.array_equal(np.sort(p), np.arange(n)):
        raise InputError(f"order: expected a permutation of range({n}) (an integer array), got "
                         f"{'shape ' + str(p.shape) if p.shape != (n,) else 'another array'}")
    return p.astype(np.int64), "given"
