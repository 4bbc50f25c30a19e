"""Minimize a quadratic energy with some unknowns fixed: set up once, solve many right-hand sides.

The role of gpytoolbox's / libigl's ``min_quad_with_fixed``::

    minimize   ½ zᵀ Q z + zᵀ B
    subject to z[known] = Y   and   Aeq z = Beq

``Q`` symmetric positive semi-definite (definite on the unknowns), ``B`` one
column per right-hand side. The known unknowns move to the right-hand side
(``Q_uu z_u = −B_u − Q_uk Y``); linear constraints make the symmetric KKT system
``[[Q_uu, A_uᵀ], [A_u, 0]]``. Back-ends, chosen by size and structure:

- ``"direct"``: :func:`~quadnodes.linalg.direct.factorize` — without constraints
  ``Q_uu`` is positive definite and factorized without pivoting in a symmetric
  fill-reducing order (a Cholesky factorization); with constraints the KKT
  matrix is indefinite and factorized with pivoting. Neither can crash.
- ``"cg"``: conjugate gradients on all right-hand sides at once
  (:func:`~quadnodes.linalg.cg.block_cg`, threaded row ranges, BLAS pinned),
  started from a guess, falling back to the direct factorization if it does not
  converge. Without constraints only. Optionally preconditioned (``"jacobi"``:
  the diagonal; ``"block-jacobi"``: exact inverses of 4 × 4 diagonal blocks of
  consecutive unknowns). A matrix with few distinct diagonals (the operator of a
  structured grid: ``Q[i, j] ≠ 0`` only for ``j − i`` in a short list) is kept in
  diagonal storage and multiplied by a compiled kernel from its upper diagonals
  (:class:`~quadnodes.linalg.cg.SymmetricDiagonalBlocks`, about a third of CSR's
  memory traffic): the known unknowns stay in it as identity rows with a zero
  right-hand side, so the iterates are those of the reduced system.

``"auto"`` factorizes up to :data:`DIRECT_LIMIT` unknowns or with constraints,
else uses CG.
"""

from __future__ import annotations

import warnings
from typing import Literal

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike

from ..errors import InputError
from .cg import BlockJacobi, SymmetricDiagonalBlocks, block_cg
from .direct import Factorization, factorize, regularization
from .threads import RowBlocks

__all__ = ["DIRECT_LIMIT", "DIAGONAL_MIN_UNKNOWNS", "MAX_DIAGONALS", "QuadraticProblem"]

#: Unknowns up to which ``method="auto"`` factorizes.
DIRECT_LIMIT = 20000
#: ``storage="auto"`` keeps CG's matrix in diagonal storage from this many rows on (or wherever the
#: compiled kernels are loaded already): loading them costs about a second per process.
DIAGONAL_MIN_UNKNOWNS = 250_000
#: ... if it has at most this many distinct diagonals (a grid's 9-point stencil plus steps of 2 along
#: its lines has 13).
MAX_DIAGONALS = 25


class QuadraticProblem:
    """``min ½ zᵀQz + zᵀB`` with ``z[known] = Y`` and ``Aeq z = Beq``, prepared once.

    Parameters
    ----------
    Q : (n, n) sparse, symmetric
        Positive definite on the unknowns (after ``shift``), else the problem is
        refused (:class:`~quadnodes.errors.InputError`).
    known : (n,) bool or int indices, optional
        Unknowns whose value is given at :meth:`solve`.
    Aeq : (m, n) sparse, optional
        Linear equality constraints (full row rank on the unknowns).
    method : {"auto", "direct", "cg"}
    rtol : float
        CG stopping rule (relative residual of every right-hand side).
    shift : float
        Relative diagonal shift (:func:`~quadnodes.linalg.direct.regularization`)
        added to ``Q_uu``, for energies that leave some motion free.
    constraint_shift : float
        With ``Aeq``: ``ε > 0`` solves the regularized system ``[[Q_uu, Aᵀ], [A, −εI]]``
        (constraints met up to ``ε`` times their multipliers, as in a
        Gauss–Newton/SQP step), which is quasi-definite when ``Q_uu`` is positive
        definite, so it is factorized in a fill-reducing symmetric order without
        pivoting (several times faster than the pivoted factorization of the exact
        system, which is used when ``ε = 0``).
    preconditioner : {"none", "jacobi", "block-jacobi"}
        For CG: none, the diagonal, or exact inverses of the ``4 × 4`` diagonal
        blocks of consecutive unknowns.
    storage : {"auto", "csr", "diagonal"}
        CG's matrix: compressed rows, or diagonal storage with a compiled product
        (``Q`` with at most :data:`MAX_DIAGONALS` distinct diagonals; ``"auto"``
        takes it from :data:`DIAGONAL_MIN_UNKNOWNS` rows on or where the compiled
        kernels are loaded already).
    order : {"auto", "nested_dissection", "minimum_degree"} or (k,) int
        The direct back-end's fill-reducing order of ``Q_uu`` (without constraints), as in
        :func:`~quadnodes.linalg.direct.factorize`: e.g. one nested-dissection order computed
        once for many problems of one pattern.
    what : str
        Named in error messages.

    Attributes
    ----------
    unknown : (k,) int64
        Indices of the unknowns that are solved for.
    method : str
        The back-end in use (``"direct"`` or ``"cg"``).
    iterations : int
        CG steps of the last solve (0 when factorized).
    storage : str
        CG's matrix storage in use (``"csr"`` or ``"diagonal"``; ``"csr"`` when factorized).

    Raises
    ------
    InputError
        On shapes that do not fit, an unknown method, CG with constraints, or a
        matrix that is not positive definite on the unknowns: a zero or negative
        diagonal entry, or (the direct back-end, which reads the factorization's
        pivots back) a pivot within ``n·ε`` of its diagonal entry or below it —
        an energy that leaves a motion free or has a saddle, named by an unknown.
        (With ``constraint_shift``, a motion that the energy and the constraints
        both leave free is held by the shift instead, and not detected: keep
        ``Q_uu`` definite there, e.g. by ``shift``.)

    Examples
    --------
    A chain of 5 springs with both ends held: the middle goes to the mean.

    >>> L = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(5, 5)).tocsr()
    >>> p = QuadraticProblem(L, known=[0, 4])
    >>> p.solve(np.zeros(5), Y=[0.0, 4.0]).round(12).tolist()
    [0.0, 1.0, 2.0, 3.0, 4.0]
    >>> q = QuadraticProblem(L, known=[0], Aeq=sp.csr_matrix(np.ones((1, 5))))  # and the sum held
    >>> q.solve(np.zeros(5), Y=[0.0], Beq=[5.0]).round(12).tolist()
    [0.0, 1.0, 1.5, 1.5, 1.0]
    >>> c = QuadraticProblem(L, known=[0, 4], method="cg", preconditioner="jacobi", storage="diagonal")
    >>> c.storage, c.solve(np.zeros(5), Y=[0.0, 4.0]).round(8).tolist()
    ('diagonal', [0.0, 1.0, 2.0, 3.0, 4.0])
    """

    def __init__(
        self,
        Q: sp.spmatrix,
        *,
        known: ArrayLike | None = None,
        Aeq: sp.spmatrix | None = None,
        method: Literal["auto", "direct", "cg"] = "auto",
        rtol: float = 1e-10,
        shift: float = 0.0,
        constraint_shift: float = 0.0,
        preconditioner: Literal["none", "jacobi", "block-jacobi"] = "none",
        storage: Literal["auto", "csr", "diagonal"] = "auto",
        order: str | np.ndarray = "auto",
        what: str = "quadratic problem",
    ) -> None:
        Q = sp.csr_matrix(Q)
        n = Q.shape[0]
        if Q.shape != (n, n):
            raise InputError(f"{what}: Q must be square, got shape {Q.shape}")
        is_known = np.zeros(n, dtype=bool)
        if known is not None:
            kn = np.asarray(known)
            if kn.dtype == bool:
                if kn.shape != (n,):
                    raise InputError(f"{what}: known mask has shape {kn.shape}, expected ({n},)")
                is_known = kn.copy()
            else:
                kn = kn.astype(np.int64).reshape(-1)
                if kn.size and (kn.min() < 0 or kn.max() >= n):
                    raise InputError(f"{what}: known index {int(kn[(kn < 0) | (kn >= n)][0])} is not in 0..{n - 1}")
                is_known[kn] = True
        if method not in ("auto", "direct", "cg"):
            raise InputError(f"method: expected 'auto', 'direct' or 'cg', got {method!r}")
        if preconditioner not in ("none", "jacobi", "block-jacobi"):
            raise InputError(f"preconditioner: expected 'none', 'jacobi' or 'block-jacobi', got {preconditioner!r}")
        if storage not in ("auto", "csr", "diagonal"):
            raise InputError(f"storage: expected 'auto', 'csr' or 'diagonal', got {storage!r}")
        self.n = n
        self.known = np.flatnonzero(is_known)
        self.unknown = np.flatnonzero(~is_known)
        k = self.unknown.size
        if k == 0:
            raise InputError(f"{what}: every unknown is known; nothing to solve")
        Qu = Q[self.unknown]
        self._Quu = Qu[:, self.unknown].tocsr()
        if shift > 0:
            self._Quu = (self._Quu + regularization(self._Quu, shift) * sp.identity(k, format="csr")).tocsr()
        self._Quk = Qu[:, self.known].tocsr()
        self._Aeq = None
        self._Aeq_k = None
        if Aeq is not None:
            Aeq = sp.csr_matrix(Aeq)
            if Aeq.shape[1] != n:
                raise InputError(f"{what}: Aeq has {Aeq.shape[1]} columns, expected {n}")
            self._Aeq = Aeq[:, self.unknown].tocsr()
            self._Aeq_k = Aeq[:, self.known].tocsr()
            if method == "cg":
                raise InputError(f"{what}: method='cg' takes no linear constraints; use 'direct' or 'auto'")
        if method == "auto":
            method = "direct" if (Aeq is not None or k <= DIRECT_LIMIT) else "cg"
        self.method = method
        self.constraint_shift = float(constraint_shift)
        if not self.constraint_shift >= 0:
            raise InputError(f"{what}: constraint_shift must be ≥ 0, got {constraint_shift!r}")
        self.rtol = float(rtol)
        self.what = what
        self._order = order
        self.iterations = 0
        self.residual = 0.0
        self._factor: Factorization | None = None
        self._blocks: RowBlocks | None = None
        self._precond: object | None = None
        self.storage = "csr"
        self.preconditioner = preconditioner
        if method == "direct":
            self._factorize()
        else:
            d = self._Quu.diagonal()
            bad = np.flatnonzero(~(d > 0))
            if bad.size:
                raise InputError(f"{what}: the matrix is not positive definite (diagonal entry "
                                 f"{int(self.unknown[bad[0]])} is {d[bad[0]]:.3g}); the energy does not determine "
                                 "every unknown")
            M = self._Quu
            if storage != "csr":
                M = self._diagonal_storage(Q, d, forced=storage == "diagonal")
            if M is None or M is self._Quu:
                self._blocks = RowBlocks(self._Quu)
                M = self._Quu
            if preconditioner != "none":
                self._precond = BlockJacobi(sp.csr_matrix(M), 1 if preconditioner == "jacobi" else 4)

    def _diagonal_storage(self, Q: sp.csr_matrix, d_unknown: np.ndarray, *, forced: bool) -> sp.spmatrix | None:
        """Set up :class:`SymmetricDiagonalBlocks` for the whole ``Q`` (known rows as identity rows).

        Returns that matrix (for a preconditioner) or None where diagonal storage does not apply
        (too many diagonals, not worth loading the kernels, kernels missing) and is not ``forced``.
        One pass over ``Q``'s entries: no sort, no format conversion.
        """
        from . import compiled

        n, k = self.n, self.unknown.size
        row = np.repeat(np.arange(n, dtype=np.int64), np.diff(Q.indptr))
        col = Q.indices.astype(np.int64)
        off = col - row
        keep = off != 0  # (the diagonal is set below: the unknowns' from Q_uu, with its shift)
        if self.known.size:
            is_known = np.zeros(n, dtype=bool)
            is_known[self.known] = True
            keep &= ~(is_known[row] | is_known[col])
        counts = np.bincount(off[keep] + n, minlength=2 * n + 1)
        counts[n] = 1
        offsets = np.flatnonzero(counts) - n
        fits = offsets.size <= MAX_DIAGONALS and np.array_equal(offsets, -offsets[::-1])
        if not (forced or (fits and (k >= DIAGONAL_MIN_UNKNOWNS or compiled.ready()))):
            return None
        if not fits:
            raise InputError(f"{self.what}: storage='diagonal' needs a symmetric matrix with at most {MAX_DIAGONALS} "
                             f"distinct diagonals, this one has {offsets.size}; use 'auto' or 'csr'")
        if not compiled.wait():  # pragma: no cover - Numba missing: compressed rows
            if forced:
                raise InputError(f"{self.what}: storage='diagonal' needs the compiled kernels (Numba)")
            return None
        slot = np.zeros(2 * n + 1, dtype=np.int64)
        slot[offsets + n] = np.arange(offsets.size)
        data = np.zeros((offsets.size, n))  # data[d, j] = M[j - offsets[d], j] (SciPy's diagonal storage)
        if not Q.has_canonical_format:  # (repeated entries: summed, as Q means)
            Q = Q.copy()
            Q.sum_duplicates()
            return self._diagonal_storage(Q, d_unknown, forced=forced)
        sel = np.flatnonzero(keep)
        data.reshape(-1)[slot[off[sel] + n] * n + col[sel]] = Q.data[sel]
        main = data[slot[n]]
        main[:] = 1.0  # known unknowns: identity rows (their right-hand side and start are 0 in solve())
        main[self.unknown] = d_unknown
        self._blocks = SymmetricDiagonalBlocks(offsets, data)
        self.storage = "diagonal"
        return self._blocks.M

    def _factorize(self) -> Factorization:
        if self._factor is None:
            # (the energy is the caller's: its definiteness is read back from the pivots, check=True)
            if self._Aeq is None:
                self._factor = factorize(self._Quu, kind="spd", what=self.what, check=True, labels=self.unknown,
                                         order=self._order)
            else:
                m = self._Aeq.shape[0]
                eps = self.constraint_shift
                C = -eps * sp.identity(m, format="csr") if eps > 0 else sp.csr_matrix((m, m))
                K = sp.bmat([[self._Quu, self._Aeq.T], [self._Aeq, C]], format="csc")
                if eps > 0:
                    self._factor = factorize(K, kind="quasi-definite", negative=m, what=self.what, check=True,
                                             labels=np.concatenate([self.unknown, np.arange(m)]))
                else:
                    self._factor = factorize(K, kind="general", what=self.what)
        return self._factor

    def solve(self, B: ArrayLike, *, Y: ArrayLike | None = None, Beq: ArrayLike | None = None,
              guess: ArrayLike | None = None) -> np.ndarray:
        """The minimizer for a linear term ``B``, known values ``Y`` and constraint values ``Beq``.

        Parameters
        ----------
        B : (n,) or (n, c) float64
            Linear term of the energy (rows of known unknowns are ignored).
        Y : (n_known,) or (n_known, c) float64, optional
            Values of the known unknowns, in the order of :attr:`known` (zero if omitted).
        Beq : (m,) or (m, c) float64, optional
            Right-hand sides of the constraints (zero if omitted).
        guess : (k,) or (k, c) float64, optional
            CG's starting point for the unknowns (zero if omitted).

        Returns
        -------
        (n,) or (n, c) float64
            ``z`` with ``z[known] = Y``.

        Raises
        ------
        InputError
            On shapes that do not fit, or a numerically singular system.
        """
        B = np.asarray(B, dtype=np.float64)
        vector = B.ndim == 1
        B2 = B.reshape(self.n, -1) if B.shape[:1] == (self.n,) else None
        if B2 is None or B.ndim > 2:
            raise InputError(f"{self.what}: B has shape {B.shape}, expected ({self.n},) or ({self.n}, c)")
        c = B2.shape[1]
        nk = self.known.size
        Yv = np.zeros((nk, c)) if Y is None else np.asarray(Y, dtype=np.float64)
        if Yv.shape == (nk,) and c == 1:
            Yv = Yv.reshape(nk, 1)
        if Yv.shape != (nk, c):
            raise InputError(f"{self.what}: Y has shape {np.shape(Y)}, expected ({nk},) or ({nk}, {c})")
        rhs = -B2[self.unknown]
        if nk:
            rhs -= self._Quk @ Yv
        if self._Aeq is not None:
            m = self._Aeq.shape[0]
            bq = np.zeros((m, c)) if Beq is None else np.asarray(Beq, dtype=np.float64)
            if bq.shape == (m,) and c == 1:
                bq = bq.reshape(m, 1)
            if bq.shape != (m, c):
                raise InputError(f"{self.what}: Beq has shape {np.shape(Beq)}, expected ({m},) or ({m}, {c})")
            if nk:
                bq = bq - self._Aeq_k @ Yv
            zu = self._factorize().solve(np.vstack([rhs, bq]))[: self.unknown.size]
        elif self.method == "cg":
            x0 = np.zeros_like(rhs) if guess is None else np.asarray(guess, dtype=np.float64).reshape(rhs.shape)
            if self.storage == "diagonal":  # the whole vector, the known rows 0 (identity rows, zero right side)
                full_rhs, full_x0 = np.zeros((self.n, c)), np.zeros((self.n, c))
                full_rhs[self.unknown], full_x0[self.unknown] = rhs, x0
                zf, its, res = block_cg(self._blocks, full_rhs, full_x0, rtol=self.rtol, maxiter=20000,  # type: ignore[arg-type]
                                        precond=self._precond)
                zu = zf[self.unknown]
            else:
                zu, its, res = block_cg(self._blocks, rhs, x0, rtol=self.rtol, maxiter=20000,  # type: ignore[arg-type]
                                        precond=self._precond)
            self.iterations, self.residual = its, res
            if not res <= self.rtol:
                warnings.warn(f"{self.what}: conjugate gradients reached a relative residual of {res:.1e} after "
                              f"{its} steps; falling back to the direct solver", UserWarning, stacklevel=2)
                zu = self._factorize().solve(rhs)
                self.iterations = 0
        else:
            zu = self._factorize().solve(rhs)
        z = np.empty((self.n, c))
        z[self.unknown] = np.asarray(zu).reshape(-1, c)
        z[self.known] = Yv
        return z[:, 0] if vector else z
