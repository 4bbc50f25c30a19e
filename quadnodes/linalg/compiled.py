"""Loading the compiled kernels once per process, in the background while other work goes on.

The kernels of :mod:`quadnodes.linalg._kernels` are compiled by Numba and cached on disk,
but loading them still costs about a second per process (importing Numba, setting up
LLVM, reading the cache): more than a whole 300 × 300 fairing solve. :func:`warm_up` starts
that load on a daemon thread and returns at once; a caller that will need the kernels
(a large grid, a long-lived server) starts it early and calls :func:`wait` where it needs
them, so the load overlaps its own set-up (NumPy's array loops and the LLVM calls release
the GIL). :func:`ready` says whether the kernels are loaded and cost nothing more to use:
solvers then take the compiled path at any size.

Examples
--------
>>> ready() in (True, False)  # (warm_up() here would change the paths later doctests take)
True
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable

__all__ = ["warm_up", "wait", "ready", "also_load"]

_LOCK = threading.Lock()
_THREAD: threading.Thread | None = None
_STATE: dict[str, object] = {"ready": False, "error": None}
#: Other modules' kernels to load with these (:func:`also_load`).
_ALSO: list[Callable[[], None]] = []


def _load() -> None:
    try:
        import numpy as np

        from . import _kernels as k

        # the first call of each kernel loads its machine code (about 10 ms each after the first)
        U = np.ones((2, 8))
        off = np.array([0, 1], dtype=np.int64)
        X, Y, Z = np.ones((3, 8)), np.zeros((3, 8)), np.ones((3, 8))
        out = np.zeros(3)
        k.symmetric_diagonal_product(U, off, X, Y, 0, 8)
        k.entries_product(off, off, U[0], X, Y, 0, 2)
        k.row_dots(X, Y, 0, 8, out)
        k.cg_update(Z, Y, X, Y.copy(), out, 0, 8, out.copy())
        k.cg_direction(Z, X, out, 0, 8)
        band = np.ones((4, 8))
        for solve in (k.path_band_solve, k.path_band_solve_xyz):
            solve(band, band[3].copy(), np.arange(8, dtype=np.int64), X.T.copy(), np.zeros((8, 3)),
                  np.empty((8, 3)), 0, 8)
        k.grid_family(np.ones((2, 4)), np.zeros(2, dtype=np.int64), np.ones(8), 2, 4, 0, False, 13, 1.0,
                      np.zeros((13, 8)), 0, 2)
        # the Gauss–Seidel sweeps and their CG step, on a small open grid (both sweeps' fast and row paths)
        from .cg import SymmetricDiagonalBlocks
        from .gauss_seidel import gauss_seidel_cg

        g = 5
        grid_offsets = np.array([0, 1, 2, 3, g, 2 * g, 3 * g, -1, -2, -3, -g, -2 * g, -3 * g])
        grid_data = np.full((13, 10 * g), -0.01)
        grid_data[0] = 1.0
        gauss_seidel_cg(SymmetricDiagonalBlocks(grid_offsets, grid_data, threads=1), np.ones((10 * g, 3)),
                        np.zeros((10 * g, 3)), rtol=1e-6, maxiter=5)
        import scipy.sparse as sp

        from .threads import RowBlocks

        rows = RowBlocks(sp.dia_matrix((grid_data, grid_offsets), shape=(10 * g, 10 * g)).tocsr(), threads=1)
        gauss_seidel_cg(rows, np.ones((10 * g, 3)), np.zeros((10 * g, 3)), rtol=1e-6, maxiter=5)  # (row by row)
        k.csr_separators(rows.M.indptr, rows.M.indices, 0, 5 * g, np.zeros(10 * g, dtype=np.bool_))  # (2+ threads)
        for load in list(_ALSO):  # before "ready": a caller that sees it pays no load time for these either
            load()
        _STATE["ready"] = True
        from .threads import prime_blas_controller

        prime_blas_controller()  # (the solvers' first BLAS limit then costs nothing either)
    except Exception as exc:  # pragma: no cover - Numba missing or broken: the NumPy paths remain
        _STATE["error"] = exc


def _forget_thread() -> None:
    """A forked child has none of the parent's threads: load again there if it was not done."""
    global _THREAD
    if not _STATE["ready"]:
        _THREAD = None


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_thread)


def also_load(load: Callable[[], None]) -> None:
    """Have the background load call ``load`` too, before :func:`ready` turns true.

    For a module of the package with compiled kernels of its own: ``load`` makes each kernel's
    first call (which loads its machine code), so callers that check :func:`ready` use them at
    no load cost. Register at import, before any :func:`warm_up`; registered later, the
    kernel loads on its own first use instead. A ``load`` that raises leaves :func:`ready`
    false (the NumPy paths remain).
    """
    _ALSO.append(load)


def warm_up() -> None:
    """Start loading the compiled kernels on a daemon thread (once per process; returns at once)."""
    global _THREAD
    with _LOCK:
        if _THREAD is None:
            _THREAD = threading.Thread(target=_load, name="quadnodes-kernels", daemon=True)
            _THREAD.start()


def wait() -> bool:
    """Load the kernels (or finish loading them) and say whether they can be used."""
    warm_up()
    assert _THREAD is not None  # set by warm_up
    _THREAD.join()
    return bool(_STATE["ready"])


def ready() -> bool:
    """Whether the kernels are loaded already (using them then costs no load time)."""
    return bool(_STATE["ready"])
