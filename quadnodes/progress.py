"""Progress reporting from inside long-running library functions.

A library function (fairing, sampling, export) calls :func:`report_progress` at
convenient points. Outside a graph run this does nothing and costs one context
variable lookup; inside a run the runner forwards it to the caller's progress
callback as a ``"progress"`` event of the node being executed. The current
reporter lives in a :class:`contextvars.ContextVar`, so threads and asyncio tasks
each see their own.

This module imports only the standard library, so any quadnodes module may use it.
"""

from __future__ import annotations

import contextlib
import contextvars
import math
from collections.abc import Callable, Iterator

__all__ = ["report_progress", "reporting", "part"]

_REPORTER: contextvars.ContextVar[Callable[[float, str], None] | None] = contextvars.ContextVar(
    "quadnodes_progress", default=None
)


def report_progress(fraction: float, message: str = "") -> None:
    """Report that the running node is ``fraction`` (0 to 1) done.

    Parameters
    ----------
    fraction : float
        Clamped to ``[0, 1]``; NaN is ignored.
    message : str
        A short status line, e.g. ``"iteration 3 of 10"``.

    Examples
    --------
    >>> report_progress(0.5, "half way")            # no run active: nothing happens
    >>> seen = []
    >>> with reporting(lambda f, m: seen.append((f, m))):
    ...     report_progress(0.25, "a"); report_progress(7, "b")
    >>> seen
    [(0.25, 'a'), (1.0, 'b')]
    """
    reporter = _REPORTER.get()
    if reporter is None:
        return
    f = float(fraction)
    if math.isnan(f):
        return
    reporter(min(1.0, max(0.0, f)), str(message))


@contextlib.contextmanager
def reporting(callback: Callable[[float, str], None]) -> Iterator[None]:
    """Route :func:`report_progress` calls made inside the block to ``callback(fraction, message)``."""
    token = _REPORTER.set(callback)
    try:
        yield
    finally:
        _REPORTER.reset(token)


@contextlib.contextmanager
def part(start: float, end: float, prefix: str = "") -> Iterator[None]:
    """Map the progress reported inside the block onto ``[start, end]`` of the current one.

    For a long step made of library calls that report their own progress (a
    figure inside a report): their 0..1 becomes ``start..end`` of the caller's,
    and ``prefix`` goes before their messages. Without a current reporter,
    nothing is reported.

    Examples
    --------
    >>> seen = []
    >>> with reporting(lambda f, m: seen.append((f, m))):
    ...     with part(0.5, 1.0, "E1: "):
    ...         report_progress(0.5, "figure")
    >>> seen
    [(0.75, 'E1: figure')]
    """
    outer = _REPORTER.get()
    if outer is None:
        yield
        return
    lo, hi = float(start), float(end)
    with reporting(lambda f, m: outer(lo + (hi - lo) * f, prefix + m)):
        yield
