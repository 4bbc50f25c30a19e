"""Sparse linear algebra that knows nothing of meshes.

``direct``: factorizations that never crash the interpreter — symmetric positive
definite and quasi-definite matrices in a symmetric fill-reducing order without
pivoting (a Cholesky-like factorization that cannot meet a zero pivot), anything
else with pivoting; a singular matrix is an :class:`~quadnodes.errors.InputError`,
never a SuperLU abort.
"""

from __future__ import annotations

from .direct import Factorization, factorize, regularization

__all__ = ["Factorization", "factorize", "regularization"]
