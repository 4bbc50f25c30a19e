"""Pictures of quad meshes as PNG files (matplotlib, headless).

:func:`render_png` draws one or more meshes side by side, each as a shaded
surface under its structure lines, every edge coloured by zigzag deviation
(thesis eq. 30) on one logarithmic scale shared by all panels. On request it
marks the vertices a method freed and the ones it held fixed, shows a clean
reference surface faintly (its boundary as a dashed line, so shrinking, growing
and moved boundaries are visible), and colours the faces by planarity instead
of shading them.

The panels are drawn with an orthographic camera of its own rather than
matplotlib's 3-D axes: faces and lines are projected once, sorted back to
front (painter's algorithm, lines drawn just in front of the faces they
bound) and drawn in plain 2-D axes with equal aspect. So every panel has the
same camera, the same scale and the same limits (the union of everything
drawn), and no space is lost to empty 3-D boxes.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from . import _validate
from .errors import InputError
from .io._atomic import write_atomic
from .mesh import QuadMesh
from .progress import report_progress
from ._view import camera, edge_deviation, face_normals, light
from .zigzag import ZigzagReport

__all__ = ["render_png", "edge_deviation"]

_DPI = 100
_FACE_RGB = np.array([0.80, 0.82, 0.86])  # light blue-grey: dark turbo lines stay readable
_REF_RGBA = (0.30, 0.30, 0.30, 0.30)
_REF_BOUNDARY_RGBA = (0.12, 0.12, 0.12, 0.85)


# ----------------------------------------------------------------------------
# option checking (per-panel values)
# ----------------------------------------------------------------------------


def _per_panel(value: Any, k: int, name: str, single: tuple[type, ...]) -> list[Any]:
    """One value for every panel: ``None``, a single value for all, or a list/tuple of ``k``."""
    if value is None or isinstance(value, single):
        return [value] * k
    if isinstance(value, (list, tuple)):
        if len(value) != k:
            raise InputError(f"{name}: {len(value)} values for {k} meshes (give one per mesh, or one for all)")
        return list(value)
    raise InputError(f"{name}: expected one value or a list with one per mesh, got {type(value).__name__}")


def _texts(value: Sequence[str] | None, k: int, name: str) -> list[str]:
    if value is None:
        return [""] * k
    if isinstance(value, str) or not isinstance(value, Sequence):
        raise InputError(f"{name}: expected a list of strings, one per mesh, got {value!r}")
    if len(value) != k:
        raise InputError(f"{name}: {len(value)} {name} for {k} meshes")
    return [str(t) for t in value]


def _masks(value: Any, meshes: list[QuadMesh], name: str) -> list[np.ndarray | None]:
    """Per-panel vertex masks from masks, index arrays or ZigzagReports (``free`` or ``fixed``)."""
    items = _per_panel(value, len(meshes), name, (np.ndarray, ZigzagReport))
    out: list[np.ndarray | None] = []
    for i, (item, m) in enumerate(zip(items, meshes)):
        label = name if not isinstance(value, (list, tuple)) else f"{name}[{i}]"
        if item is None:
            out.append(None)
        elif isinstance(item, ZigzagReport):
            mask = item.free if name == "free" else item.fixed
            if mask.shape != (m.n_vertices,):
                raise InputError(
                    f"{label}: the ZigzagReport is for {mask.shape[0]} vertices, the mesh has {m.n_vertices}"
                )
            out.append(np.asarray(mask, dtype=bool))
        else:
            out.append(_validate.vertex_mask(item, m.n_vertices, label))
    return out


# ----------------------------------------------------------------------------
# camera and drawing
# ----------------------------------------------------------------------------


class _Items:
    """Polygons (faces) and segments (lines) collected for one back-to-front draw."""

    def __init__(self) -> None:
        self.polys: list[np.ndarray] = []
        self.depth: list[np.ndarray] = []
        self.face: list[np.ndarray] = []
        self.edge: list[np.ndarray] = []
        self.width: list[np.ndarray] = []

    def add(self, polys: np.ndarray, depth: np.ndarray, face: np.ndarray, edge: np.ndarray, width: float) -> None:
        k = len(polys)
        if k == 0:
            return
        self.polys.extend(polys)
        self.depth.append(depth)
        self.face.append(np.broadcast_to(face, (k, 4)))
        self.edge.append(np.broadcast_to(edge, (k, 4)))
        self.width.append(np.full(k, width))

    def collection(self) -> Any:
        from matplotlib.collections import PolyCollection

        order = np.argsort(np.concatenate(self.depth), kind="stable")
        face, edge = np.concatenate(self.face)[order], np.concatenate(self.edge)[order]
        return PolyCollection([self.polys[i] for i in order], facecolors=face, edgecolors=edge,
                              linewidths=np.concatenate(self.width)[order], antialiaseds=True,
                              joinstyle="round", capstyle="round")


def _shade(mesh: QuadMesh, cam: np.ndarray) -> np.ndarray:
    """Lambert intensity per face (two-sided), light from upper left behind the viewer."""
    return 0.50 + 0.50 * np.abs(face_normals(mesh) @ light(cam))


def _boundary_segments(mesh: QuadMesh) -> np.ndarray:
    t = mesh.topology
    return mesh.vertices[t.edges[t.boundary_edges]]


def render_png(
    meshes: QuadMesh | Sequence[QuadMesh],
    path: str | os.PathLike[str],
    *,
    titles: Sequence[str] | None = None,
    notes: Sequence[str] | None = None,
    free: Any = None,
    fixed: Any = None,
    reference: QuadMesh | Sequence[QuadMesh | None] | None = None,
    planarity: bool | str | Sequence[bool | str] = False,
    vmin: float = 1e-4,
    vmax: float = 1.0,
    planarity_range: tuple[float, float] | None = None,
    elev: float = 35.0,
    azim: float = -60.0,
    ncols: int | None = None,
    size_px: int = 1200,
    palette: int | None = None,
    color_by: Any = None,
) -> Path:
    """Render meshes side by side to a PNG, written atomically.

    Every panel shows a shaded surface with its edges coloured by zigzag
    deviation (see :func:`edge_deviation`) on one logarithmic colour scale
    ``vmin..vmax`` shared by all panels (values outside are clipped to its
    ends). All panels use the same orthographic camera, equal axes and the same
    limits, so sizes and positions can be compared between them.

    Parameters
    ----------
    meshes : QuadMesh or sequence of QuadMesh
        One panel per mesh.
    path : path-like
        Output file (PNG; its folder must exist).
    titles : sequence of str, optional
        One title per panel.
    notes : sequence of str, optional
        One smaller line of text under each title (may contain ``\\n``), e.g. key numbers.
    free : (n,) bool or int indices, ZigzagReport, or a list with one per mesh, optional
        Vertices to mark as freed (small black dots): a mask, vertex indices, or
        a :class:`~quadnodes.zigzag.ZigzagReport` (its ``free`` mask). One value is
        used for every panel; a list gives one (or ``None``) per mesh.
    fixed : same forms as ``free``, optional
        Vertices to mark as held fixed (open squares). When not given and
        ``free`` is a ZigzagReport, that report's ``fixed`` mask is marked.
    reference : QuadMesh or list of (QuadMesh or None), optional
        A clean reference surface drawn faintly in every panel (or per panel):
        its edges in light grey, hidden where the mesh covers them, and its
        boundary as a dark dashed line on top.
    planarity : bool, {"relative", "length"} or a sequence of them
        Colour the faces by planarity instead of shading them, on a logarithmic
        scale shared by these panels, with its own colour bar: ``True`` or
        ``"relative"`` the distance between the diagonals over the mean diagonal
        (:func:`quadnodes.flatness.diagonal_distance`); ``"length"`` that
        distance in the mesh's unit (the bar says which unit).
    vmin, vmax : float
        Range of the deviation colour scale (``0 < vmin < vmax``).
    planarity_range : (float, float), optional
        Range of the planarity colour scale; default from the data.
    elev, azim : float
        Camera elevation above the xy plane and azimuth about z, in degrees
        (as in matplotlib).
    ncols : int, optional
        Panels per row (default: 1 or 2; 3 for three panels).
    size_px : int
        Width of the image in pixels (>= 200); the height follows from the
        panels' shape.
    palette : int, optional
        Save an indexed PNG with at most this many colours (2..256): a file about
        a third the size, for documentation. Default: full colour.
    color_by : str, array or a list with one per mesh, optional
        Colour the faces by a scalar instead of shading them: the name of a
        field of :func:`quadnodes.discrete_curvature.curvature` (``"mean"``,
        ``"gaussian"``, ``"gaussian_1"`` … ``"gaussian_3"``, ``"k1"``, ``"k2"``,
        ``"line_max"``; per panel the mean over its corners that have a value), a per-vertex
        ``(n,)`` or per-panel ``(m,)`` array. One colour scale for all panels
        (diverging around 0 for signed values); NaN (e.g. curvature on the
        boundary) in grey. Takes precedence over ``planarity``.

    Returns
    -------
    Path

    Raises
    ------
    InputError
        On a non-mesh input, a list of titles, notes, masks, references or
        planarity flags whose length is not the number of meshes, a mask of the
        wrong length, or a bad number; the message names the parameter.
    ExportError
        If the file cannot be written.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from quadnodes.mesh import grid
    >>> from quadnodes.noise import perturb
    >>> from quadnodes.zigzag import detect
    >>> noisy, _ = perturb(grid(6, 8), tangential=0.2, seed=1)
    >>> p = render_png([noisy, noisy], pathlib.Path(tempfile.mkdtemp()) / "a.png",
    ...                titles=["noisy", "noisy again"], free=detect(noisy, 0.1), size_px=400)
    >>> p.stat().st_size > 5000
    True
    """
    ms = _validate.quad_meshes(meshes)
    k = len(ms)
    titles_ = _texts(titles, k, "titles")
    notes_ = _texts(notes, k, "notes")
    free_ = _masks(free, ms, "free")
    if fixed is None and isinstance(free, ZigzagReport):
        fixed = free
    elif fixed is None and isinstance(free, (list, tuple)):
        fixed = [f if isinstance(f, ZigzagReport) else None for f in free]
    fixed_ = _masks(fixed, ms, "fixed")
    refs = _per_panel(reference, k, "reference", (QuadMesh,))
    for i, r in enumerate(refs):
        if r is not None:
            _validate.quad_mesh(r, "reference" if isinstance(reference, QuadMesh) else f"reference[{i}]")
    # one camera and one scale bar: every mesh in the first one's unit
    ms = [m.with_unit(ms[0].unit) for m in ms]
    refs = [None if r is None else r.with_unit(ms[0].unit) for r in refs]
    plan = _per_panel(planarity, k, "planarity", (bool, np.bool_, str))
    for i, p in enumerate(plan):
        if isinstance(p, str):
            plan[i] = _validate.choice(p, ("relative", "length"), f"planarity[{i}]" if k > 1 else "planarity")
        elif isinstance(p, (bool, np.bool_)):
            plan[i] = "relative" if p else False
        else:
            raise InputError(f"planarity[{i}]: expected true, false, 'relative' or 'length', got {p!r}")
    kinds = {p for p in plan if p}
    if len(kinds) > 1:
        raise InputError("planarity: one colour scale for all panels: all 'relative' or all 'length'")
    vmin_ = _validate.positive_number(vmin, "vmin")
    vmax_ = _validate.positive_number(vmax, "vmax")
    if vmin_ >= vmax_:
        raise InputError(f"vmin: must be less than vmax = {vmax_:g}, got {vmin!r}")
    elev_ = _validate.finite_number(elev, "elev")
    azim_ = _validate.finite_number(azim, "azim")
    size = _validate.positive_int(size_px, "size_px", minimum=200)
    if palette is not None:
        palette = _validate.positive_int(palette, "palette", minimum=2)
        if palette > 256:
            raise InputError(f"palette: at most 256 colours, got {palette}")
    cols = (3 if k == 3 else min(k, 2)) if ncols is None else min(_validate.positive_int(ncols, "ncols"), k)
    cb_values, cb_label = _color_values(color_by, ms)
    if cb_values is not None:
        plan = [False] * k
    pl_values = [_planarity_values(m, p == "relative") if p else None for m, p in zip(ms, plan)]
    pl_norm = _planarity_norm(pl_values, planarity_range) if any(plan) else None

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection
    from matplotlib.colors import LogNorm
    from matplotlib.lines import Line2D

    cam = camera(elev_, azim_)
    # shared limits: everything drawn in any panel
    pts = [m.vertices[m.topology.vertex_face_count > 0] @ cam[:2].T for m in ms]  # (a vertex in no face is not drawn)
    pts += [r.vertices[r.topology.vertex_face_count > 0] @ cam[:2].T for r in refs if r is not None]
    allp = np.vstack(pts)
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    span = np.maximum(hi - lo, 1e-9 * max(float((hi - lo).max()), 1e-300))
    lo, hi = lo - 0.04 * span.max(), hi + 0.04 * span.max()
    span = hi - lo
    aspect = min(float(span[1] / span[0]), 1.4)

    # layout in pixels
    nrows = -(-k // cols)
    margin, gap = 12, 16
    pw = (size - 2 * margin - gap * (cols - 1)) / cols
    ph = pw * aspect
    note_lines = max((n.count("\n") + 1 if n else 0) for n in notes_)
    fs_title = float(np.clip(pw / 45, 9.0, 13.0))
    fs_note = max(fs_title - 3.0, 8.0)
    fs_foot = 11.0 if size >= 800 else 9.0
    head = (fs_title * 2.1 + 2 if any(titles_) else 6) + fs_note * 1.75 * note_lines
    # the footer: colour bars (side by side when there is room) and a legend (one row when it fits)
    labels = []
    if any(f is not None and f.any() for f in free_):
        labels.append("freed vertex (moved)")
    if any(f is not None and f.any() for f in fixed_):
        labels.append("fixed vertex")
    if any(r is not None for r in refs):
        labels.append("clean reference (boundary dashed, edges faint)")
    char_px = 0.6 * fs_foot * _DPI / 72
    one_row = sum(len(t) * char_px + 50 for t in labels) <= size - 2 * margin
    legend_rows = (1 if one_row else len(labels)) if labels else 0
    legend_h = 6 + legend_rows * 2.0 * fs_foot * _DPI / 72 if labels else 0
    n_bars = 2 if (pl_norm is not None or cb_values is not None) else 1
    side = n_bars == 1 or size >= 1000
    bar_rows = 1 if side else n_bars
    bar_block = 14 + 4.2 * fs_foot * _DPI / 72
    foot = legend_h + bar_rows * bar_block + 8
    height = int(round(margin + nrows * (head + ph) + (nrows - 1) * gap + foot))
    fig = plt.figure(figsize=(size / _DPI, height / _DPI), dpi=_DPI)
    scale = pw / span[0]  # pixels per model unit (aspect capped: the axes keep equal scale)
    if aspect < span[1] / span[0]:
        scale = ph / span[1]
    h_model = float(np.mean([m.mean_edge_length for m in ms]))
    edge_px = h_model * scale
    lw = float(np.clip(0.10 * edge_px, 1.0, 2.8)) * 72 / _DPI  # points
    dot = float(np.clip(0.20 * edge_px, 3.0, 7.0))
    square = float(np.clip(0.40 * edge_px, 6.0, 12.0))
    dense_fixed = max((int(f.sum()) for f in fixed_ if f is not None), default=0) > 40
    if dense_fixed:  # e.g. a whole fixed boundary: smaller, so the lines under them stay visible
        square = float(np.clip(0.30 * edge_px, 4.5, 9.0))

    cmap = plt.get_cmap("turbo")
    norm = LogNorm(vmin_, vmax_, clip=True)
    pl_cmap = _planarity_cmap()
    thinned: list[int] = []
    unit = ms[0].unit
    if cb_values is not None:
        cb_norm, cb_cmap = _color_norm(cb_values)
    for i, m in enumerate(ms):
        report_progress(0.8 * i / len(ms), f"drawing mesh {i + 1}/{len(ms)} ({m.n_faces} panels)")
        r, c = divmod(i, cols)
        x0 = margin + c * (pw + gap)
        top = margin + r * (head + ph + gap)
        ax = fig.add_axes((x0 / size, 1 - (top + head + ph) / height, pw / size, ph / height))
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal", adjustable="box", anchor="C")
        ax.set_axis_off()
        cx = (x0 + pw / 2) / size
        if titles_[i]:
            fig.text(cx, 1 - (top + 4) / height, titles_[i], ha="center", va="top", fontsize=fs_title)
        if notes_[i]:
            y = top + (fs_title * 2.1 - 2 if titles_[i] else 4)
            fig.text(cx, 1 - y / height, notes_[i], ha="center", va="top", fontsize=fs_note, color="0.25",
                     linespacing=1.25)
        items = _Items()
        # faces
        fv = m.vertices[m.faces]
        proj = fv @ cam[:2].T
        depth = (fv @ cam[2]).mean(axis=1)
        if cb_values is not None:
            val = cb_values[i]
            rgb = cb_cmap(cb_norm(np.nan_to_num(val)))[:, :3]
            rgb[np.isnan(val)] = 0.6
            rgb = rgb * (0.80 + 0.20 * _shade(m, cam))[:, None]
        elif pl_values[i] is not None:
            rgb = pl_cmap(pl_norm(np.maximum(pl_values[i], pl_norm.vmin)))[:, :3]
            rgb = rgb * (0.80 + 0.20 * _shade(m, cam))[:, None]
        else:
            rgb = _FACE_RGB[None, :] * _shade(m, cam)[:, None]
        items.add(proj, depth, np.column_stack([rgb, np.ones(len(rgb))]), np.zeros(4), 0.0)
        # structure-line edges, just in front of the faces they bound; on a dense mesh only every
        # step-th structure line, so the picture shows lines instead of a moiré of edges
        e = m.topology.edges
        dev = edge_deviation(m)
        step = _line_step(m.mean_edge_length * scale)
        keep = _every_kth_line(m, step) if step > 1 else slice(None)
        seg = m.vertices[e[keep]]
        items.add(seg @ cam[:2].T, (seg @ cam[2]).mean(axis=1) + 0.6 * m.mean_edge_length,
                  np.zeros(4), cmap(norm(np.clip(dev[keep], vmin_, vmax_))), lw)
        if step > 1:
            thinned.append(step)
        ref = refs[i]
        if ref is not None:
            rs = ref.vertices[ref.topology.edges]
            items.add(rs @ cam[:2].T, (rs @ cam[2]).mean(axis=1) + 0.3 * ref.mean_edge_length,
                      np.zeros(4), np.array(_REF_RGBA), 0.6 * lw)
        ax.add_collection(items.collection())
        if ref is not None:
            rb = _boundary_segments(ref) @ cam[:2].T
            ax.add_collection(LineCollection(rb, colors=[_REF_BOUNDARY_RGBA], linewidths=0.9 * lw,
                                             linestyles=(0, (3, 2)), zorder=3))
        p2 = m.vertices @ cam[:2].T
        if free_[i] is not None and free_[i].any():
            q = p2[free_[i]]
            ax.scatter(q[:, 0], q[:, 1], s=dot**2 * (72 / _DPI) ** 2, c="black", marker="o",
                       linewidths=0, zorder=4, clip_on=False)
        if fixed_[i] is not None and fixed_[i].any():
            q = p2[fixed_[i]]
            ax.scatter(q[:, 0], q[:, 1], s=square**2 * (72 / _DPI) ** 2, facecolors="none", marker="s",
                       edgecolors="black", linewidths=1.1, zorder=5, clip_on=False)

    # a scale bar in the mesh's unit in the first panel (the views have no axes)
    length = _nice_length(0.2 * float(span[0]))
    bar_px = length * scale
    ybar = 1 - (margin + head + 6) / height  # top left of the first panel, under its title
    x_left = (margin + 6) / size
    fig.add_artist(Line2D([x_left, x_left + bar_px / size], [ybar, ybar], transform=fig.transFigure,
                          color="0.2", lw=2.0))
    fig.text(x_left + bar_px / size + 6 / size, ybar, f"{length:g} {unit}", va="center", ha="left",
             fontsize=fs_foot - 1, color="0.2")

    # colour bars and legend along the bottom
    from matplotlib.ticker import NullFormatter

    zig = "zigzag deviation ‖(u₀+u₂)/2 − u₁‖² (log scale)"
    if thinned:
        zig += f"; every {max(thinned)}th structure line drawn"
    bars = [(norm, cmap, zig)]
    if pl_norm is not None:
        what = ("face planarity: diagonal gap / mean diagonal (log scale)" if "relative" in kinds
                else f"face planarity: diagonal gap in {unit} (log scale)")
        bars.append((pl_norm, pl_cmap, what))
    if cb_values is not None:
        bars.append((cb_norm, cb_cmap, cb_label))
    for j, (nm, cm, label) in enumerate(bars):
        row = 0 if side else j  # rows counted from the top of the footer
        y = legend_h + (bar_rows - 1 - row) * bar_block + bar_block - 14
        left, width = (0.1, 0.8) if len(bars) == 1 or not side else (0.05 + j * 0.48, 0.42)
        cax = fig.add_axes((left, y / height, width, 14 / height))
        cb = fig.colorbar(plt.cm.ScalarMappable(norm=nm, cmap=cm), cax=cax, orientation="horizontal")
        cb.ax.xaxis.set_minor_formatter(NullFormatter())
        cb.ax.tick_params(labelsize=fs_foot - 1)
        cb.set_label(label, fontsize=fs_foot)
    if labels:
        handles = []
        if "freed vertex (moved)" in labels:
            handles.append(Line2D([], [], ls="", marker="o", ms=6, mfc="black", mec="black", label=labels[0]))
        if "fixed vertex" in labels:
            handles.append(Line2D([], [], ls="", marker="s", ms=8, mfc="none", mec="black",
                                  label="fixed vertex"))
        if any(r is not None for r in refs):
            handles.append(Line2D([], [], color=_REF_BOUNDARY_RGBA, ls=(0, (3, 2)), lw=1.5, label=labels[-1]))
        fig.legend(handles=handles, loc="lower center", ncol=len(handles) if one_row else 1, frameon=False,
                   fontsize=fs_foot, bbox_to_anchor=(0.5, 0.0), borderaxespad=0.3)
    try:
        report_progress(0.8, f"writing {Path(path).name}")
        out = write_atomic(path, lambda tmp: _save(fig, tmp, palette))
        report_progress(1.0, f"wrote {out.name}")
        return out
    finally:
        plt.close(fig)


def _save(fig: Any, tmp: str, palette: int | None) -> None:
    if palette is None:
        fig.savefig(tmp, format="png", dpi=_DPI)
        return
    import io

    from PIL import Image

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=_DPI)
    buf.seek(0)
    with Image.open(buf) as im:
        q = im.convert("RGB").quantize(colors=palette, method=Image.Quantize.FASTOCTREE,
                                       dither=Image.Dither.NONE)
    q.save(tmp, format="PNG", optimize=True)


def _planarity_values(mesh: QuadMesh, relative: bool = True) -> np.ndarray:
    from .flatness import diagonal_distance

    return diagonal_distance(mesh, relative=relative)


#: Structure lines closer than this many pixels are thinned out (see :func:`_line_step`).
MIN_LINE_GAP_PX = 5.0


def _line_step(edge_px: float) -> int:
    """Draw every k-th structure line when edges are shorter than :data:`MIN_LINE_GAP_PX` pixels.

    Examples
    --------
    >>> _line_step(12.0), _line_step(4.0), _line_step(1.2)
    (1, 2, 5)
    """
    return max(1, int(np.ceil(MIN_LINE_GAP_PX / max(edge_px, 1e-9))))


def _every_kth_line(mesh: QuadMesh, step: int) -> np.ndarray:
    """Edges of every ``step``-th structure line of each family (rows/columns of a grid), ``(E,) bool``.

    On a grid (``grid_shape``) the kept lines are rows and columns ``0, step, 2·step, …``;
    on other meshes every ``step``-th line in the tracing order.
    """
    topo = mesh.topology
    e = topo.edges
    if mesh.grid_shape is not None:
        cols = mesh.grid_shape[1]
        r, c = np.divmod(e, cols)
        along_row = r[:, 0] == r[:, 1]
        return np.where(along_row, r[:, 0] % step == 0, c[:, 0] % step == 0)
    lines = topo.structure_lines
    keep = np.zeros(len(e), dtype=bool)
    ln = lines.lengths
    off = lines.offsets[: len(ln)]
    chosen = np.flatnonzero(np.arange(len(ln)) % step == 0)
    for li in chosen:  # a few hundred lines at most: the picture has room for no more
        v = lines.indices[off[li]: off[li] + ln[li]]
        a, b = v[:-1], v[1:]
        if lines.closed[li]:
            a, b = np.append(a, v[-1]), np.append(b, v[0])
        from ._view import edge_ids

        keep[edge_ids(mesh, a, b)] = True
    return keep


def _nice_length(x: float) -> float:
    """The largest 1, 2 or 5 × 10^k not above ``x``.

    Examples
    --------
    >>> _nice_length(1234.0), _nice_length(0.07)
    (1000.0, 0.05)
    """
    if x <= 0:
        return 1.0
    k = np.floor(np.log10(x))
    for f in (5.0, 2.0, 1.0):
        if f * 10**k <= x:
            return float(f * 10**k)
    return float(10**k)


def _planarity_norm(values: list[np.ndarray | None], given: tuple[float, float] | None) -> Any:
    from matplotlib.colors import LogNorm

    if given is not None:
        if isinstance(given, (str, bytes)) or len(given) != 2:
            raise InputError(f"planarity_range: expected (low, high), got {given!r}")
        a = _validate.positive_number(given[0], "planarity_range[0]")
        b = _validate.positive_number(given[1], "planarity_range[1]")
        if a >= b:
            raise InputError(f"planarity_range: low must be less than high, got {given!r}")
        return LogNorm(a, b, clip=True)
    v = np.concatenate([x for x in values if x is not None])
    hi = float(v.max()) if v.size else 1.0
    pos = v[v > 0]
    if hi <= 0 or pos.size == 0:
        return LogNorm(1e-4, 1e-1, clip=True)  # all planar: any range shows them at its low end
    lo = min(max(float(np.percentile(pos, 2)), hi * 1e-3), hi / 10)  # at least a decade: labelled ticks
    return LogNorm(lo, hi, clip=True)


def _planarity_cmap() -> Any:
    """White (planar) through sand to dark brown: apart from the blues and greens of faired lines."""
    from matplotlib.colors import LinearSegmentedColormap

    return LinearSegmentedColormap.from_list("planarity", ["#ffffff", "#f2dcc0", "#c9925a", "#6b4a2e"])


def _color_values(color_by: Any, meshes: list[QuadMesh]) -> tuple[list[np.ndarray] | None, str]:
    """Per-panel face values for ``color_by`` and the colour bar's label (None: not requested)."""
    if color_by is None:
        return None, ""
    k = len(meshes)
    per = list(color_by) if isinstance(color_by, (list, tuple)) else [color_by] * k
    if len(per) != k:
        raise InputError(f"color_by: {len(per)} values for {k} meshes")
    out: list[np.ndarray] = []
    names = set()
    for i, (m, c) in enumerate(zip(meshes, per)):
        where = "color_by" if len(per) == 1 or not isinstance(color_by, (list, tuple)) else f"color_by[{i}]"
        if isinstance(c, str):
            from .discrete_curvature import CURVATURE_KEYS, curvature

            key = _validate.choice(c, CURVATURE_KEYS, where)
            names.add(key)
            vals = curvature(m)[key]
        else:
            vals = np.asarray(c, dtype=np.float64)
            names.add("value")
            if vals.shape not in ((m.n_vertices,), (m.n_faces,)):
                raise InputError(f"{where}: expected a curvature name, {m.n_vertices} vertex values or "
                                 f"{m.n_faces} panel values, got shape {vals.shape}")
        if vals.shape == (m.n_vertices,) and m.n_vertices != m.n_faces:
            fv = vals[m.faces]
            cnt = np.isfinite(fv).sum(axis=1)
            vals = np.divide(np.where(np.isfinite(fv), fv, 0.0).sum(axis=1), cnt,
                             out=np.full(m.n_faces, np.nan), where=cnt > 0)  # over the corners that have one
        out.append(vals)
    label = (names.pop() if len(names) == 1 else "value")
    label = {"mean": "mean curvature H", "gaussian": "Gaussian curvature G(4)", "k1": "principal curvature k1",
             "k2": "principal curvature k2", "line_max": "structure-line curvature (Def. 2.33)"}.get(label, label)
    return out, f"{label} (panel mean of its vertices)"


def _color_norm(values: list[np.ndarray]) -> tuple[Any, Any]:
    """A shared colour scale: diverging around 0 for signed data, sequential otherwise."""
    import matplotlib.pyplot as plt
    from matplotlib.colors import Normalize, TwoSlopeNorm

    v = np.concatenate([x[np.isfinite(x)] for x in values]) if values else np.zeros(0)
    if v.size == 0:
        return Normalize(0.0, 1.0), plt.get_cmap("viridis")
    lo, hi = float(np.percentile(v, 1)), float(np.percentile(v, 99))
    if lo < 0 < hi:
        m = max(-lo, hi)
        return TwoSlopeNorm(0.0, -m, m), plt.get_cmap("coolwarm")
    if lo == hi:
        lo, hi = lo - 1.0 if lo == 0 else lo - abs(lo) * 0.5, hi + 1.0 if hi == 0 else hi + abs(hi) * 0.5
    return Normalize(lo, hi, clip=True), plt.get_cmap("viridis")
