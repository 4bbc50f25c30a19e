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
    cap = order.size
    for first in range(D):  # open lines: from every chain's first edge, the smaller of a line's two
        if pred[first] >= 0 or seen[first]:
            continue
        e = first
        count = 0
        while e >= 0:
            if seen[e] or k >= cap:
                return -1
            seen[e] = True
            seen[e ^ 1] = True
            order[k] = e
            k += 1
            count += 1
            e = succ[e]
        lengths[lines] = count
        closed[lines] = False
        lines += 1
    for first in range(D):  # closed lines: the edges left lie on cycles, each taken from its smallest edge
        if seen[first]:
            continue
        e = first
        count = 0
        while True:
            if e < 0 or seen[e] or k >= cap:
                return -1
            seen[e] = True
            seen[e ^ 1] = True
            order[k] = e
            k += 1
            count += 1
            e = succ[e]
            if e == first:
                break
        lengths[lines] = count
        closed[lines] = True
        lines += 1
    if k != cap:
        return -1
    return lines
