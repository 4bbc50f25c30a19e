"""Row ranges of a sparse matrix on a small thread pool, with BLAS held to one thread.

SciPy's sparse kernels and NumPy's array loops release the GIL, so a product or
a vector update cut into row ranges runs in parallel on a few threads. OpenBLAS's
own threads would spin against them (a 100×100 fairing measured 0.06–10.6 s on a
loaded 2-core machine with two BLAS threads, 27–49 ms with one), so every solve
runs inside :func:`blas_pinned`, which limits BLAS to one thread with
``threadpoolctl`` for its duration.
"""

from __future__ import annotations

import contextlib
import importlib.machinery
import os
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import scipy.sparse as sp

try:  # SciPy's own CSR kernels (y += A x on a row range); they release the GIL
    from scipy.sparse._sparsetools import csr_matvec as _csr_matvec, csr_matvecs as _csr_matvecs
except ImportError:  # pragma: no cover - a SciPy that moved them: fall back to row blocks
    _csr_matvec = _csr_matvecs = None

__all__ = [
    "MAX_THREADS",
    "padded",
    "PARALLEL_MIN_ROWS",
    "RANGE_ALIGN",
    "COLUMNS_MAX_NNZ",
    "thread_count",
    "split_ranges",
    "pool",
    "run_tasks",
    "blas_pinned",
    "prime_blas_controller",
    "RowBlocks",
]

#: Threads for the products and updates (capped by the cores available).
MAX_THREADS = 4
#: Rows per thread below which a matrix is applied on one thread.
PARALLEL_MIN_ROWS = 25000
#: Row ranges (threads, preconditioner blocks) start at multiples of this many rows.
RANGE_ALIGN = 64
#: Matrices with at most this many nonzeros (about 24 MB, cache-sized) are applied to
#: the columns one after the other ((c, n) vectors, SciPy's one-vector kernel: 25-30 %
#: faster there); larger ones to all columns in one pass ((n, c) vectors, one read of the matrix).
COLUMNS_MAX_NNZ = 2_000_000


def thread_count() -> int:
    """Cores this process may use (at most :data:`MAX_THREADS`).

    Examples
    --------
    >>> 1 <= thread_count() <= MAX_THREADS
    True
    """
    try:
        n = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        n = os.cpu_count() or 1
    return max(1, min(n, MAX_THREADS))


def split_ranges(count: int, *, parts: int | None = None, min_size: int = 1, align: int = 1) -> list[tuple[int, int]]:
    """``range(count)`` cut into consecutive ``(lo, hi)`` ranges of about equal size, one per thread.

    Range ``i`` starts at ``count * i // parts`` rounded down to a multiple of ``align``
    (integer arithmetic, so the cuts are the same on every machine); the last ends at
    ``count``. Ranges that the rounding leaves empty are dropped, so the result has at
    most ``parts`` ranges (exactly ``min(parts, count)`` with ``align = 1``).

    Parameters
    ----------
    count : int
        Items to share (>= 0).
    parts : int, optional
        Ranges wanted (at most ``count``). Default: :func:`thread_count`, but at
        most one per ``min_size`` items (and at least one).
    min_size : int
        Items per range below which fewer ranges are made (only when ``parts`` is None).
    align : int
        Every cut but the end is a multiple of this.

    Returns
    -------
    list of (int, int)
        Covering ``0 .. count`` in order, none empty; ``[(0, 0)]`` when ``count`` is 0.

    Raises
    ------
    ValueError
        On a negative ``count`` or a ``parts``, ``min_size`` or ``align`` below 1.

    Examples
    --------
    >>> split_ranges(10, parts=3)
    [(0, 3), (3, 6), (6, 10)]
    >>> split_ranges(100, parts=4, align=16)
    [(0, 16), (16, 48), (48, 64), (64, 100)]
    >>> split_ranges(1000, min_size=600)
    [(0, 1000)]
    """
    if count < 0 or (parts is not None and parts < 1) or min_size < 1 or align < 1:
        raise ValueError(f"split_ranges: count {count} >= 0, parts {parts}, min_size {min_size}, align {align} >= 1")
    if parts is None:
        parts = min(thread_count(), max(1, count // min_size))
    parts = max(1, min(parts, count))
    cuts = [count * i // parts // align * align for i in range(parts)] + [count]
    ranges = [(lo, hi) for lo, hi in zip(cuts[:-1], cuts[1:]) if hi > lo]
    return ranges or [(0, 0)]


_POOL: ThreadPoolExecutor | None = None


def pool() -> ThreadPoolExecutor:
    """The process's solver pool (``MAX_THREADS - 1`` workers; the caller is the first thread).

    Examples
    --------
    >>> pool().submit(sum, [1, 2]).result()
    3
    """
    global _POOL
    if _POOL is None:
        _POOL = ThreadPoolExecutor(max_workers=MAX_THREADS - 1, thread_name_prefix="quadnodes")
    return _POOL


def padded(a: np.ndarray | None, rows: int, c: int, *, columns: bool) -> np.ndarray:
    """Zeros of ``rows`` rows (a multiple of :data:`RANGE_ALIGN`, past ``a``'s) for ``c`` vectors, holding ``a``.

    ``a`` is ``(k, c)`` or None; the result is ``(c, rows)`` with ``columns`` (one vector per
    row), else ``(rows, c)``.

    Examples
    --------
    >>> padded(np.ones((2, 3)), 4, 3, columns=True).tolist()
    [[1.0, 1.0, 0.0, 0.0], [1.0, 1.0, 0.0, 0.0], [1.0, 1.0, 0.0, 0.0]]
    """
    out = np.zeros((c, rows) if columns else (rows, c))
    if a is not None:
        if columns:
            out[:, : a.shape[0]] = a.T
        else:
            out[: a.shape[0]] = a
    return out


def run_tasks(fn: Callable[..., object], tasks: Sequence[tuple]) -> list:
    """``fn(*task)`` for every task, the first on the calling thread and the others on :func:`pool`; the results in order.

    For kernels that release the GIL (Numba's ``nogil``, SciPy's sparse kernels, NumPy's loops) on ranges of rows.

    Examples
    --------
    >>> run_tasks(lambda lo, hi: sum(range(lo, hi)), [(0, 3), (3, 5)])
    [3, 7]
    """
    if len(tasks) == 1:
        return [fn(*tasks[0])]
    futures = [pool().submit(fn, *task) for task in tasks[1:]]
    first = fn(*tasks[0])
    return [first] + [f.result() for f in futures]


def _forget_pool() -> None:
    """A forked child has none of the parent's threads: start a new pool there."""
    global _POOL
    _POOL = None


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_pool)

_CONTROLLER: object | None = None


def _library_count() -> int:
    """How many extension modules the process has imported: a BLAS arrives with one (NumPy's, SciPy's, or a
    library's own), so a new one is the cue to scan for BLAS libraries again.

    Counted from ``sys.modules`` (the modules whose spec's origin is a shared object), again only when its
    size changed: O(1) between imports, about a millisecond after one. Not by ``dl_iterate_phdr`` through
    ctypes, as it was: its callback into Python runs under glibc's loader lock and needs the GIL, while a
    thread that imports an extension module calls ``dlopen`` holding the GIL and waits for that lock — a
    deadlock (``tests/linalg/test_threads.py``; threadpoolctl #239), which hung ``quadnodes watch`` when the
    kernel loader's scan met the first fair's imports. A BLAS loaded by hand (``ctypes.CDLL``) is seen at the
    next extension module's import.
    """
    with _COUNT_LOCK:
        size = len(sys.modules)
        if size != _COUNTED[0]:
            _COUNTED[:] = [size, sum(1 for m in list(sys.modules.values()) if _is_extension(m))]
        return _COUNTED[1]


def _is_extension(module: object) -> bool:
    """Whether ``module`` was loaded from a shared object (its spec's origin ends in an extension suffix)."""
    try:
        origin = getattr(getattr(module, "__spec__", None), "origin", None)
    except Exception:  # (a lazy module that imports on attribute access: not a loaded shared object)
        return False
    return isinstance(origin, str) and origin.endswith(_EXTENSION_SUFFIXES)


_EXTENSION_SUFFIXES = tuple(importlib.machinery.EXTENSION_SUFFIXES)
_COUNT_LOCK = threading.Lock()
_COUNTED = [-1, 0]  # (len(sys.modules) at the last count, the count)


def prime_blas_controller() -> None:
    """Find the loaded BLAS libraries now (``threadpoolctl``'s scan, about 20 ms), so the first
    :func:`blas_pinned` does not (:func:`quadnodes.linalg.compiled.warm_up` calls it)."""
    _controller()


def _controller() -> object | None:
    """``threadpoolctl``'s controller of the loaded libraries, scanned again when a shared object was
    loaded since (None without ``threadpoolctl``). Only scans: no limit is set here."""
    global _CONTROLLER
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:  # pragma: no cover - an optional speed-up
        return None
    import scipy.linalg.blas  # noqa: F401 - load SciPy's BLAS before looking for it

    count = _library_count()
    if _CONTROLLER is None or _CONTROLLER[0] != count:  # type: ignore[index]
        _CONTROLLER = (count, ThreadpoolController())
    return _CONTROLLER[1]  # type: ignore[index]


@contextlib.contextmanager
def blas_pinned() -> Iterator[None]:
    """Hold BLAS (OpenBLAS, MKL, BLIS) to one thread for the duration of a solve.

    The limit is process-wide while it lasts (BLAS libraries keep one setting)
    and is restored afterwards; without ``threadpoolctl`` nothing is limited.

    Examples
    --------
    >>> with blas_pinned():
    ...     float(np.ones(3) @ np.ones(3))
    3.0
    """
    controller = _controller()
    if controller is None:  # pragma: no cover - an optional speed-up
        yield
        return
    with controller.limit(limits=1, user_api="blas"):  # type: ignore[attr-defined]
        yield


class RowBlocks:
    """A CSR matrix cut into row ranges of about equal work, one per thread.

    ``run(fn)`` calls ``fn(lo, hi)`` for every range — on the calling thread
    when there is one range, else in parallel (SciPy's sparse kernels and NumPy's
    array loops release the GIL) — and returns the results in order.
    ``matvec(X, Y, lo, hi)`` writes rows ``lo:hi`` of ``M @ X`` into ``Y``; the
    vectors are ``(c, n)`` arrays (one vector per row) when ``columns`` (small
    matrices, see :data:`COLUMNS_MAX_NNZ`; or as the keyword says), else C-ordered ``(n, c)`` arrays.
    """

    def __init__(self, M: sp.spmatrix, *, threads: int | None = None, columns: bool | None = None) -> None:
        M = M.tocsr()
        rows = M.shape[0]
        t = thread_count() if threads is None else max(1, int(threads))
        t = max(1, min(t, rows // PARALLEL_MIN_ROWS))
        # equal nonzeros per range, cut at multiples of RANGE_ALIGN rows
        cuts = np.searchsorted(M.indptr, np.arange(1, t) * (M.nnz / t)) // RANGE_ALIGN * RANGE_ALIGN
        self.ranges = list(zip(np.r_[0, cuts].tolist(), np.r_[cuts, rows].tolist()))
        self.M = M
        self.columns = M.nnz <= COLUMNS_MAX_NNZ if columns is None else bool(columns)
        idx = np.result_type(M.indptr, M.indices)
        self._indptr = M.indptr.astype(idx, copy=False)
        self._indices = M.indices.astype(idx, copy=False)

    def run(self, fn: Callable[[int, int], object]) -> list:
        return run_tasks(fn, self.ranges)

    def matvec(self, X: np.ndarray, Y: np.ndarray, lo: int, hi: int, *, data: np.ndarray | None = None,
               accumulate: bool = False) -> None:
        """``Y[lo:hi] (+)= (M @ X)[lo:hi]`` in the layout of :attr:`columns`.

        ``data`` replaces the matrix's values (same pattern); ``hi`` may exceed the
        matrix's rows (padding rows of ``Y`` are left alone).
        """
        M = self.M
        data = M.data if data is None else data
        hi = min(hi, M.shape[0])
        if _csr_matvec is None:  # pragma: no cover - SciPy without the private kernels
            a, b = int(self._indptr[lo]), int(self._indptr[hi])
            part = sp.csr_matrix((data[a:b], self._indices[a:b], self._indptr[lo : hi + 1] - a),
                                 shape=(hi - lo, M.shape[1]))
            if self.columns:
                part = (part @ X[:, : M.shape[1]].T).T
                y = Y[:, lo:hi]
            else:
                part = part @ X[: M.shape[1]]
                y = Y[lo:hi]
            if accumulate:
                y += part
            else:
                y[...] = part
            return
        indptr = self._indptr[lo : hi + 1]
        if not self.columns:
            y = Y[lo:hi]
            if not accumulate:
                y.fill(0.0)  # the kernels accumulate
            _csr_matvecs(hi - lo, M.shape[1], X.shape[1], indptr, self._indices, data, X.reshape(-1),
                         y.reshape(-1))
            return
        for x, y in zip(X, Y):
            y = y[lo:hi]
            if not accumulate:
                y.fill(0.0)
            _csr_matvec(hi - lo, M.shape[1], indptr, self._indices, data, x, y)


