"""Large temporaries from the heap, in small pages, while a big solve runs, instead of fresh pages each time.

glibc's ``malloc`` hands out every block above its mmap threshold (at most 32 MB) as new
pages from the kernel and gives them back on ``free``; NumPy's temporaries of a
million-vertex mesh (``(3, 2·10⁶)`` float64: 48 MB) then cost a page fault per 4 KB on
every allocation: about a third of the time of a pass over them
(``np.empty`` + ``fill`` of 48 MB: 29 ms fresh, 16 ms from the heap on this machine). Inside
:func:`reused_heap` such blocks come from the heap and are reused; on leaving, the free
heap memory goes back to the kernel (``malloc_trim``) and glibc's thresholds return to what
its own adaptation reaches (blocks up to 32 MB from the heap). With another C library or on another system the
heap is left as it is.

Inside it NumPy also stops asking the kernel for transparent huge pages (``madvise(MADV_HUGEPAGE)`` on every
array of 4 MB or more, its default on Linux): the first touch of such an array then faults in 2 MB pages, which
on this project's machines (virtual ones, THP ``defrag=madvise``) cost more than the small pages they replace —
a 1000 × 1000 fairing 1.83 → 1.63 s, the torus 3.75 → 3.00 s (``python benchmarks/studies/huge_pages.py``, its
table in docs/linalg.md). A user's
own choice (the ``NUMPY_MADVISE_HUGEPAGE`` environment variable) is left alone, and NumPy's setting is restored
on leaving.

Examples
--------
>>> import numpy as np
>>> with reused_heap():
...     float(np.ones(10).sum())
10.0
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import importlib
import os
import sys
import threading
from collections.abc import Callable, Iterator

__all__ = ["reused_heap"]

_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD, _M_MMAP_MAX = -1, -3, -4
#: After a use: what glibc's own dynamic thresholds reach in a process that has freed large
#: blocks (blocks up to 32 MB from the heap, 64 MB of free heap kept) — any mallopt call
#: switches that adaptation off for good, so it is set explicitly instead.
_AFTER_MMAP_THRESHOLD, _AFTER_TRIM, _DEFAULT_MMAP_MAX = 32 * 1024 * 1024, 64 * 1024 * 1024, 65536
_LOCK = threading.Lock()
_DEPTH = 0
_HUGE_PAGES: list[bool] = []  # NumPy's setting when the first use entered (restored by the last to leave)


def _libc() -> object | None:
    if not sys.platform.startswith("linux"):
        return None
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        libc.mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
        libc.malloc_trim.argtypes = [ctypes.c_size_t]
        return libc
    except (OSError, AttributeError):  # pragma: no cover - not glibc (musl has no mallopt)
        return None


_LIBC = _libc()


def _numpy_huge_pages() -> Callable[[bool], bool] | None:
    """NumPy's switch of ``madvise(MADV_HUGEPAGE)`` (it returns the previous setting), or None where the user set
    ``NUMPY_MADVISE_HUGEPAGE`` or NumPy has no such switch."""
    if "NUMPY_MADVISE_HUGEPAGE" in os.environ:
        return None
    for name in ("numpy._core.multiarray", "numpy.core.multiarray"):
        try:
            module = importlib.import_module(name)
        except ImportError:  # pragma: no cover - the other NumPy major version
            continue
        switch = getattr(module, "_set_madvise_hugepage", None)
        if callable(switch):
            return switch
    return None  # pragma: no cover - a NumPy without the switch


_NUMPY_HUGE_PAGES = _numpy_huge_pages()


@contextlib.contextmanager
def reused_heap() -> Iterator[None]:
    """Serve large blocks from the heap (no mmap), in small pages, for the duration; trim and restore after.

    Nested and concurrent uses share one setting: the first to enter sets it, the last
    to leave restores glibc's defaults and NumPy's huge-page setting, and returns free memory to the kernel.
    """
    global _DEPTH
    if _LIBC is None and _NUMPY_HUGE_PAGES is None:
        yield
        return
    with _LOCK:
        _DEPTH += 1
        try:
            if _DEPTH == 1:
                if _NUMPY_HUGE_PAGES is not None:
                    _HUGE_PAGES.append(_NUMPY_HUGE_PAGES(False))
                if _LIBC is not None:
                    _LIBC.mallopt(_M_TRIM_THRESHOLD, 2**31 - 1)  # type: ignore[attr-defined]
                    _LIBC.mallopt(_M_MMAP_MAX, 0)  # type: ignore[attr-defined]
        except BaseException:  # (a setting refused: this use never entered)
            _DEPTH -= 1
            if _DEPTH == 0 and _HUGE_PAGES:
                _NUMPY_HUGE_PAGES(_HUGE_PAGES.pop())  # type: ignore[misc]
            raise
    try:
        yield
    finally:
        with _LOCK:
            _DEPTH -= 1
            if _DEPTH == 0:
                if _HUGE_PAGES:
                    _NUMPY_HUGE_PAGES(_HUGE_PAGES.pop())  # type: ignore[misc]
                if _LIBC is not None:
                    _LIBC.mallopt(_M_MMAP_MAX, _DEFAULT_MMAP_MAX)  # type: ignore[attr-defined]
                    _LIBC.mallopt(_M_MMAP_THRESHOLD, _AFTER_MMAP_THRESHOLD)  # type: ignore[attr-defined]
                    _LIBC.mallopt(_M_TRIM_THRESHOLD, _AFTER_TRIM)  # type: ignore[attr-defined]
                    _LIBC.malloc_trim(0)  # type: ignore[attr-defined]
