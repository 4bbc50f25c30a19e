"""Compiled kernel (Numba) for :mod:`quadnodes.topology`: tracing the structure lines of any quad mesh.

:func:`trace_lines` follows every directed edge's successor (the edge straight across the vertex it ends at) in one
pass: the chains from the edges no edge leads to (open lines, each taken from its smaller first edge), then the
cycles among the edges left (closed lines). The lines it returns are the SciPy tracer's
(``topology._trace_lines``: two depth-first walks and a connected-components pass over the successor graph), up to
each line's direction, starting edge and place in the list — which :func:`quadnodes.topology._canonical` then fixes
for both — in about a twentieth of the time (a 10⁶-vertex cube-sphere: 1.1 s by SciPy).
"""

from __future__ import annotations

import numba as nb
import numpy as np

__all__ = ["trace_lines"]


@nb.njit(cache=True, nogil=True, boundscheck=False)
def _follow(succ: np.ndarray, seen: np.ndarray, order: np.ndarray, k: int, first: int,
            closed: bool) -> int:  # pragma: no cover - compiled
    """Append the line from directed edge ``first`` to ``order[k:]`` (to its end, or round to ``first`` again where
    ``closed``), marking both directions of its edges seen; the new ``k``, or −1 where the walk meets an edge seen
    already, runs off a closed line's end, or overflows ``order``."""
    e = first
    while True:
        if e < 0 or seen[e] or k >= order.size:
            return -1
        seen[e] = True
        seen[e ^ 1] = True
        order[k] = e
        k += 1
        e = succ[e]
        if (e < 0 and not closed) or e == first:
            return k


@nb.njit(cache=True, nogil=True, boundscheck=False)
def trace_lines(succ: np.ndarray, pred: np.ndarray, order: np.ndarray, lengths: np.ndarray,
                closed: np.ndarray) -> int:  # pragma: no cover - compiled
    """Trace the lines of the successor map ``succ`` ``(D,)`` (−1 where a line ends; ``pred`` its inverse, −1
    where a line starts; directed edge ``e``'s reverse is ``e ^ 1``).

    Writes each line's directed edges one line after another into ``order`` (``D // 2`` entries: every undirected
    edge once), each line's edge count into ``lengths`` and whether it closes into ``closed``; returns the number of
    lines, or −1 where ``succ`` is not a set of disjoint chains and cycles (a successor shared, a walk that neither
    ends nor comes back, an edge's reverse on its own line): the caller then traces by SciPy.
    """
    D = succ.size
    seen = np.zeros(D, dtype=np.bool_)
    k = 0
    lines = 0
    for cycles in (False, True):  # open lines from every chain's first edge (the smaller of a line's two), then
        for first in range(D):  # the cycles among the edges left, each from its smallest edge
            if seen[first] or (not cycles and pred[first] >= 0):
                continue
            end = _follow(succ, seen, order, k, first, cycles)
            if end < 0:
                return -1
            lengths[lines] = end - k
            closed[lines] = cycles
            lines += 1
            k = end
    if k != order.size:
        return -1
    return lines
