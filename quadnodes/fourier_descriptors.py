"""Fourier descriptors (thesis 3.2.1): low-pass the coordinates of closed structure lines.

Each closed structure line (the rings of a cylinder, both families of a torus)
is a periodic signal ``x_k, y_k, z_k``; its discrete Fourier transform (``rfft``)
is cut above harmonic ``keep`` and transformed back — the orthogonal projection
onto the low frequencies, so the line neither shrinks nor drifts. Open lines
have no periodic transform and are left alone (the report counts them).

Where two closed lines cross (a torus), the lines are filtered in rounds of
lines that share no vertex (greedy colouring of the lines' crossings; the two
families of a torus grid are two rounds), each round on the previous one's
result: on a torus grid this is exactly the 2-D low-pass. Lines of one round are
transformed together, grouped by length.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from typing import Literal

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike

from . import _validate
from .mesh import QuadMesh
from .progress import report_progress
from .topology import FIX_MODES, fixed_vertices

__all__ = ["FourierReport", "fourier", "low_pass"]


def low_pass(signal: np.ndarray, keep: int) -> np.ndarray:
    """Keep harmonics ``0 … keep`` of periodic signals along axis 1.

    Parameters
    ----------
    signal : (lines, L, 3) float64
    keep : int

    Returns
    -------
    (lines, L, 3) float64

    Examples
    --------
    >>> t = 2 * np.pi * np.arange(8) / 8
    >>> s = np.stack([np.cos(t), np.sin(t), np.cos(3 * t)], axis=1)[None]
    >>> bool(np.allclose(low_pass(s, 1)[0, :, 2], 0))
    True
    """
    L = signal.shape[1]
    f = np.fft.rfft(signal, axis=1)
    f[:, keep + 1:] = 0.0
    return np.fft.irfft(f, n=L, axis=1)


def _rounds(lines_idx: list[np.ndarray], n: int) -> np.ndarray:
    """A colour per line such that lines of one colour share no vertex (greedy, in line order)."""
    k = len(lines_idx)
    if k == 0:
        return np.zeros(0, dtype=np.int64)
    rows = np.concatenate([np.full(a.size, i) for i, a in enumerate(lines_idx)])
    inc = sp.csr_matrix((np.ones(rows.size), (rows, np.concatenate(lines_idx))), shape=(k, n))
    conflict = (inc @ inc.T).tolil()
    colour = np.full(k, -1, dtype=np.int64)
    for i in range(k):  # a loop over lines (about sqrt(n) of them), not vertices
        used = {int(colour[j]) for j in conflict.rows[i] if j != i and colour[j] >= 0}
        c = 0
        while c in used:
            c += 1
        colour[i] = c
    return colour


@dataclass(frozen=True)
class FourierReport:
    """What :func:`fourier` did: lines filtered and left alone, rounds, energies (removed signal)."""

    keep: int
    fix: str
    n_fixed: int
    closed_lines: int
    open_lines_untouched: int
    rounds: int
    removed_energy: float
    max_displacement: float
    seconds: float
    note: str = ""

    def to_dict(self) -> dict:
        """Plain-Python form (JSON-ready)."""
        return asdict(self)


def fourier(
    mesh: QuadMesh,
    *,
    keep: int = 3,
    fix: Literal["none", "corners", "boundary"] = "none",
    fixed: ArrayLike | None = None,
) -> tuple[QuadMesh, FourierReport]:
    """Smooth the closed structure lines by Fourier descriptors, keeping harmonics ``0 … keep``.

    Parameters
    ----------
    mesh : QuadMesh
    keep : int
        Highest harmonic kept (>= 1: ``keep=1`` keeps each line's best-fitting
        ellipse; harmonics above are removed exactly).
    fix : {"none", "corners", "boundary"}
        Vertices held in place (they keep their input position; the rest of their
        line is filtered).
    fixed : (n,) bool or int indices, optional
        More vertices to hold.

    Returns
    -------
    mesh : QuadMesh
    report : FourierReport
        Says how many open lines were left untouched.

    Raises
    ------
    InputError
        On a bad option.

    Examples
    --------
    >>> from quadnodes.mesh import cylinder
    >>> c = cylinder(3, 16)
    >>> v = c.vertices.copy(); v[:, 0] += 0.05 * np.cos(5 * 2 * np.pi * (np.arange(48) % 16) / 16)
    >>> out, rep = fourier(c.with_vertices(v), keep=2)
    >>> bool(np.allclose(out.vertices, c.vertices)), rep.closed_lines, rep.open_lines_untouched
    (True, 3, 16)
    """
    t0 = time.perf_counter()
    _validate.quad_mesh(mesh)
    keep = _validate.positive_int(keep, "keep")
    fix = _validate.choice(fix, FIX_MODES, "fix")  # type: ignore[assignment]
    hold = fixed_vertices(mesh, fix, fixed)
    lines = mesh.topology.structure_lines
    closed = [lines[i] for i in np.flatnonzero(lines.closed)]
    n_open = int((~lines.closed).sum())
    colour = _rounds(closed, mesh.n_vertices)
    x = mesh.vertices.copy()
    removed = 0.0
    n_rounds = int(colour.max()) + 1 if colour.size else 0
    for r in range(n_rounds):
        members = np.flatnonzero(colour == r)
        lengths = np.array([closed[i].size for i in members])
        for L in np.unique(lengths):  # lines of equal length in one transform
            idx = np.stack([closed[i] for i in members[lengths == L]])
            sig = x[idx]
            low = low_pass(sig, keep)
            removed += float(np.sum((sig - low) ** 2))
            x[idx] = low
        report_progress((r + 1) / n_rounds, f"Fourier descriptors: round {r + 1} of {n_rounds}")
    x[hold] = mesh.vertices[hold]
    disp = float(np.linalg.norm(x - mesh.vertices, axis=1).max())
    note = (f"{n_open} open structure line(s) have no periodic transform and were not filtered"
            if n_open else "")
    if not closed:
        note = "no closed structure lines: nothing filtered (Fourier descriptors need closed lines)"
    return mesh.with_vertices(x), FourierReport(keep, fix, int(hold.sum()), len(closed), n_open, n_rounds, removed,
                                                disp, time.perf_counter() - t0, note)
