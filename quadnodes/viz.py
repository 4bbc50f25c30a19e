"""Pictures of quad meshes: structure lines coloured by zigzag deviation (matplotlib, headless)."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .io._atomic import write_atomic
from .mesh import QuadMesh
from .zigzag import detect

__all__ = ["render_png"]


def _segments(mesh: QuadMesh) -> tuple[np.ndarray, np.ndarray]:
    """Edge segments ``(E, 2, 3)`` and the deviation of each edge (max of its windows)."""
    t = mesh.topology
    e = t.edges
    rep = detect(mesh, 0.0)
    w = t.windows
    # deviation per edge: max over windows whose middle edge is this edge
    key = np.minimum(w[:, 1], w[:, 2]) * mesh.n_vertices + np.maximum(w[:, 1], w[:, 2])
    ekey = e[:, 0] * mesh.n_vertices + e[:, 1]
    pos = np.searchsorted(ekey, key)
    dev = np.zeros(len(e))
    np.maximum.at(dev, pos, rep.window_deviation)
    return mesh.vertices[e], dev


def render_png(
    meshes: QuadMesh | Sequence[QuadMesh],
    path: str | os.PathLike,
    *,
    titles: Sequence[str] | None = None,
    vmin: float = 1e-4,
    vmax: float = 1.0,
    elev: float = 35.0,
    azim: float = -60.0,
    size_px: int = 1200,
) -> Path:
    """Render one or more meshes side by side to a PNG, written atomically.

    Faces are shaded light grey; edges are coloured by the zigzag deviation of the
    windows they are the middle edge of, on one shared logarithmic colour scale
    ``vmin..vmax`` (edges in no window, or below ``vmin``, get the lowest colour).
    All panels share the same axes limits so shapes can be compared.

    Parameters
    ----------
    meshes : QuadMesh or sequence of QuadMesh
    path : path-like
        Output file (``.png``).
    titles : sequence of str, optional
    vmin, vmax : float
        Range of the logarithmic deviation colour scale.
    elev, azim : float
        Camera angles in degrees.
    size_px : int
        Width of the image in pixels.

    Returns
    -------
    Path

    Raises
    ------
    ExportError
        If the file cannot be written.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    ms = [meshes] if isinstance(meshes, QuadMesh) else list(meshes)
    k = len(ms)
    allv = np.vstack([m.vertices for m in ms])
    lo, hi = allv.min(axis=0), allv.max(axis=0)
    ext = np.maximum(hi - lo, 0.15 * (hi - lo).max())
    mid = 0.5 * (lo + hi)
    ncols = min(k, 2)
    nrows = -(-k // ncols)
    dpi = 100
    w_in = size_px / dpi
    fig = plt.figure(figsize=(w_in, w_in / ncols * 0.75 * nrows + 0.8), dpi=dpi)
    cmap = plt.get_cmap("turbo")
    norm = LogNorm(vmin, vmax, clip=True)
    for i, m in enumerate(ms):
        ax = fig.add_subplot(nrows, ncols, i + 1, projection="3d")
        ax.add_collection3d(Poly3DCollection(m.vertices[m.faces], facecolor=(0.85, 0.85, 0.88, 0.6),
                                             edgecolor="none"))
        seg, dev = _segments(m)
        lc = Line3DCollection(seg, colors=cmap(norm(np.maximum(dev, vmin))), linewidths=1.2)
        ax.add_collection3d(lc)
        for setlim, c, e in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), mid, ext):
            setlim(c - 0.5 * e, c + 0.5 * e)
        ax.set_box_aspect(tuple(ext), zoom=1.0)
        ax.view_init(elev=elev, azim=azim)
        ax.set_axis_off()
        if titles is not None:
            ax.set_title(titles[i])
    fig.subplots_adjust(left=0, right=1, top=0.95, bottom=0.12, wspace=0, hspace=0.05)
    sm = plt.cm.ScalarMappable(cmap=cmap, norm=norm)
    cax = fig.add_axes((0.3, 0.07, 0.4, 0.015))
    fig.colorbar(sm, cax=cax, orientation="horizontal",
                 label="zigzag deviation ||(u0+u2)/2 - u1||²")
    try:
        return write_atomic(path, lambda tmp: fig.savefig(tmp, format="png", dpi=dpi))
    finally:
        plt.close(fig)
