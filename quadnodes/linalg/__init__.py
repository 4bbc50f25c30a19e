"""Sparse linear algebra that knows nothing of meshes.

``ordering``: nested-dissection orders from the matrix graph (the fill-reducing
order for most large mesh matrices, where minimum degree makes more fill).
``direct``: factorizations that never crash the interpreter — symmetric positive
definite and quasi-definite matrices in a symmetric fill-reducing order without
pivoting (a Cholesky-like factorization that cannot meet a zero pivot), anything
else with pivoting; a singular matrix is an :class:`~quadnodes.errors.InputError`,
never a SuperLU abort.
``threads``: row ranges of a sparse matrix on the solver's own thread pool, BLAS
held to one thread while it runs. ``cg``: conjugate gradients on several
right-hand sides at once, with block-Jacobi preconditioning and diagonal storage.
``grid``: diagonal storage for line operators on structured grids.
``gauss_seidel``: conjugate gradients preconditioned by symmetric Gauss–Seidel in Eisenstat's
form (two compiled sweeps per step, no product), on a grid's diagonal storage or compressed rows.
``multigrid``: the two-grid cycle of a grid, open or closed around (Gauss–Seidel sweeps around a coarse grid
of every 4th row and column, cubic interpolation, the Galerkin coarse matrix factorized once): steps that stop growing
as the weight falls.
``spectral``: a grid's line operator with constant coefficients, inverted exactly by the lines' own eigenvectors
(open lines) and Fourier transforms (closed ones), fixed vertices inside by a capacitance correction: steps that
depend neither on the noise nor on the weight.
``quadratic``: :class:`QuadraticProblem`, "minimize a quadratic energy with some
unknowns fixed (and linear equality constraints), set up once, solve many
right-hand sides"; the energy's definiteness is read back from the factorization's pivots.
An overview with an example: ``docs/linalg.md``.
"""

from __future__ import annotations

from .direct import NESTED_DISSECTION_MIN, Factorization, cholmod_available, factorize, regularization
from .ordering import expand_order, nested_dissection
from .quadratic import QuadraticProblem

__all__ = ["Factorization", "factorize", "regularization", "QuadraticProblem", "nested_dissection",
           "expand_order", "cholmod_available", "NESTED_DISSECTION_MIN"]
