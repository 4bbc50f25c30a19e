"""An interactive 3-D view of quad meshes as one self-contained HTML file (plotly, works offline).

:func:`render_html` writes a page that shows one mesh at a time: its panels
shaded, its structure lines coloured edge by edge by zigzag deviation (thesis
eq. 30, on a logarithmic colour scale shared by all meshes, the same colouring
as the PNG views: see :func:`quadnodes._view.edge_deviation`) and its vertices
as small dots. Buttons switch between the meshes — e.g. the noisy input and the
faired result — in the same camera and the same axes, so the difference shows
as a jump. Hovering a vertex shows its id, zigzag deviation and the worst
planarity of the panels around it; hovering an edge its deviation; hovering a
panel its id, zigzag deviation and planarity. An optional clean reference
surface stays in view as thin grey edges with its boundary dashed.

plotly.js (about 4.8 MB) is written into the page, so it needs no network and
no server: open it from disk, mail it, put it next to the STEP file.
plotly is imported only when a page is built.

Examples
--------
>>> import tempfile, pathlib
>>> from quadnodes.mesh import grid
>>> from quadnodes.noise import perturb
>>> from quadnodes.fairing import fair
>>> noisy, _ = perturb(grid(6, 8), tangential=0.2, seed=1)
>>> faired, _ = fair(noisy, iterations=2)
>>> p = render_html([noisy, faired], pathlib.Path(tempfile.mkdtemp()) / "view.html",
...                 titles=["noisy", "faired"])
>>> p.stat().st_size > 4_000_000, "<script src=" in p.read_text()
(True, False)
"""

from __future__ import annotations

import html as _html
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from . import _validate
from ._view import camera, edge_deviation, face_deviation, face_normals, light
from .errors import InputError
from .io._atomic import write_text_atomic
from .mesh import QuadMesh
from .flatness import angle_defect, diagonal_distance
from .zigzag import _mesh_window_deviation, vertex_deviation

if TYPE_CHECKING:
    import plotly.graph_objects as go

__all__ = ["figure", "build_html", "render_html"]

_FACE_RGB = np.array([214.0, 220.0, 230.0])  # light blue-grey: the dark ends of turbo stay readable on it
_VERTEX_COLOR = "#30343b"
_REF_COLOR = "#8f96a0"
_REF_BOUNDARY_COLOR = "#1f1f1f"
_COLORSCALE = "Turbo"
_BAKED = {"ambient": 1.0, "diffuse": 0.0, "specular": 0.0, "roughness": 1.0, "fresnel": 0.0}  # colours as given
_SHADE_MIN = 0.55  # the shade of a panel seen edge-on to the light (1: facing it)
_FLAT = 0.15  # the shortest box side, as a fraction of the longest (flat meshes get some depth)
_LIFT = 0.03  # structure lines float this many mean edge lengths off the surface (see _mesh_traces)
_VIEW = (2.3, 1.6)  # width and height of the initial picture of the box, in plotly's scene units
#: Meshes with more panels than this are drawn in compact detail by default (see :func:`figure`).
COMPACT_FACES = 2500


# ----------------------------------------------------------------------------
# option checking
# ----------------------------------------------------------------------------


def _titles(titles: Any, k: int) -> list[str]:
    if titles is None:
        return ["mesh"] if k == 1 else [f"mesh {i + 1}" for i in range(k)]
    if isinstance(titles, str) or not isinstance(titles, Sequence):
        raise InputError(f"titles: expected a list of strings, one per mesh, got {titles!r}")
    if len(titles) != k:
        raise InputError(f"titles: {len(titles)} titles for {k} meshes")
    for i, t in enumerate(titles):
        if not isinstance(t, str):
            raise InputError(f"titles[{i}]: expected a string, got {type(t).__name__}")
    return list(titles)


# ----------------------------------------------------------------------------
# per-mesh data
# ----------------------------------------------------------------------------


def _segments(points: np.ndarray) -> np.ndarray:
    """``(k, 2, 3)`` segments as one polyline broken by NaN rows, ``(3k, 3)``."""
    out = np.full((len(points), 3, 3), np.nan)
    out[:, :2] = points
    return out.reshape(-1, 3)


def _xyz(points: np.ndarray) -> dict[str, np.ndarray]:
    """Coordinates to draw, as float32: what WebGL draws with anyway, at half the size in the page.

    The hover texts show the exact float64 positions (from ``customdata``).
    """
    p = np.asarray(points, dtype=np.float32)
    return {"x": p[:, 0], "y": p[:, 1], "z": p[:, 2]}


def _g(x: float) -> str:
    return f"{x:.3g}"


class _MeshData:
    """Everything shown for one mesh: deviations, planarity and the hover data."""

    def __init__(self, mesh: QuadMesh) -> None:
        self.mesh = mesh
        topo = mesh.topology
        w = topo.windows
        wd = _mesh_window_deviation(mesh)
        self.window_dev = wd
        self.vertex_dev = vertex_deviation(wd, w, mesh.n_vertices)
        self.edge_dev = edge_deviation(mesh, deviation=wd)
        self.face_dev = face_deviation(mesh, edge_dev=self.edge_dev)
        self.planarity = diagonal_distance(mesh)
        self.planarity_length = diagonal_distance(mesh, relative=False)
        self.angle_defect = np.degrees(angle_defect(mesh))
        vp = np.zeros(mesh.n_vertices)
        np.maximum.at(vp, mesh.faces.reshape(-1), np.repeat(self.planarity, 4))
        self.vertex_planarity = vp

    # Hover texts are plotly templates filled from numbers per point (``customdata``), which the page
    # stores as binary arrays: a few bytes per point instead of a formatted string each.

    def vertex_hover(self) -> tuple[np.ndarray, list[str], str]:
        """``customdata (n, 8)`` (id, row, col, deviation, planarity, x, y, z), ``text`` and template.

        The position is the vertex's own, not that of the dot drawn off the surface.
        """
        m = self.mesh
        n = m.n_vertices
        ids = np.arange(n)
        cols = m.grid_shape[1] if m.grid_shape else 1
        cd = np.column_stack([ids, ids // cols, ids % cols, self.vertex_dev, self.vertex_planarity, m.vertices])
        text = np.where(m.topology.window_middle, "", " (its lines end here)").tolist()
        where = " (row %{customdata[1]}, col %{customdata[2]})" if m.grid_shape else ""
        template = (
            f"<b>vertex %{{customdata[0]}}</b>{where}<br>zigzag deviation %{{customdata[3]:.3~g}}%{{text}}"
            "<br>max planarity of its panels %{customdata[4]:.3~g}"
            "<br>(%{customdata[5]:.6~g}, %{customdata[6]:.6~g}, %{customdata[7]:.6~g})<extra></extra>"
        )
        return cd, text, template

    def edge_hover(self) -> tuple[np.ndarray, str]:
        """``customdata (E, 3) float32`` (end vertices, deviation) and the template."""
        e = self.mesh.topology.edges
        cd = np.column_stack([e, self.edge_dev]).astype(np.float32)
        return cd, "edge %{customdata[0]}–%{customdata[1]}<br>zigzag deviation %{customdata[2]:.3~g}<extra></extra>"

    def face_hover(self) -> tuple[np.ndarray, str]:
        """``customdata (m, 9) float32`` (id, corners, deviation, planarity, angle defect, gap) and the template."""
        m = self.mesh
        cd = np.column_stack([np.arange(m.n_faces), m.faces, self.face_dev, self.planarity, self.angle_defect,
                              self.planarity_length])
        template = (
            "<b>panel %{customdata[0]}</b> (vertices %{customdata[1]}, %{customdata[2]}, %{customdata[3]}, "
            "%{customdata[4]})<br>zigzag deviation %{customdata[5]:.3~g}"
            "<br>planarity %{customdata[6]:.3~g} (diagonal gap / diagonal), gap %{customdata[8]:.3~g} "
            + _html.escape(m.unit) + "<br>angle defect %{customdata[7]:.2f}°<extra></extra>"
        )
        return cd.astype(np.float32), template

    def summary(self) -> str:
        wd = self.window_dev
        zmax = _g(float(wd.max())) if wd.size else "–"
        zmean = _g(float(wd.mean())) if wd.size else "–"
        return (
            f"{self.mesh.n_vertices} vertices, {self.mesh.n_faces} panels  ·  zigzag max {zmax}, mean {zmean}"
            f"  ·  planarity max {_g(float(self.planarity.max()))} "
            f"({_g(float(self.planarity_length.max()))} {_html.escape(self.mesh.unit)} diagonal gap)"
        )


# ----------------------------------------------------------------------------
# traces
# ----------------------------------------------------------------------------


def _log_scale(values: np.ndarray, vmin: float, vmax: float) -> np.ndarray:
    return np.log10(np.clip(values, vmin, vmax))


def _colorbar(vmin: float, vmax: float) -> dict[str, Any]:
    lo, hi = int(np.ceil(np.log10(vmin) - 1e-9)), int(np.floor(np.log10(vmax) + 1e-9))
    ticks = list(range(lo, hi + 1))
    return {
        "title": {"text": "zigzag deviation<br>‖(u₀+u₂)/2 − u₁‖²", "side": "right"},
        "tickvals": ticks,
        "ticktext": [f"{10.0 ** t:g}" for t in ticks],
        "len": 0.6,
        "thickness": 14,
        "x": 1.0,
        "xanchor": "right",
    }


def _shade(mesh: QuadMesh, light: np.ndarray) -> np.ndarray:
    """Two-sided Lambert intensity of every panel in ``[_SHADE_MIN, 1]``, baked into the colours.

    plotly lights one side of a surface only; baking keeps both sides of a
    cylinder or a dome equally readable (the shading turns with the mesh).
    """
    cos = np.abs(face_normals(mesh) @ light)
    return _SHADE_MIN + (1.0 - _SHADE_MIN) * cos


def _rgb(c: np.ndarray) -> str:
    r, g, b = np.clip(np.round(c), 0, 255).astype(int).tolist()
    return f"rgb({r},{g},{b})"


def _lifted(mesh: QuadMesh, eye: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vertices moved off the panels to the front and to the back side, ``2 × (n, 3)``.

    Interior vertices move ``_LIFT`` mean edge lengths along the area-weighted
    vertex normal, one copy each way. Boundary vertices get one position (both
    copies the same, so boundary lines are not doubled): as far outwards in the
    plane of their panels, where no panel covers them, and as far along the
    normal towards ``eye``, the direction to the initial camera.
    """
    t = mesh.topology
    p = mesh.vertices[mesh.faces]
    fn = np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 1])  # twice the vector area of every panel
    vn = np.zeros_like(mesh.vertices)
    for k in range(4):
        np.add.at(vn, mesh.faces[:, k], fn)
    vn = _unit(vn)
    # outwards at the boundary: perpendicular to the boundary edge, in its panel's plane, away from the panel
    h = np.flatnonzero(t.he_twin < 0)
    a, b, f = t.he_start[h], t.he_end[h], h // 4
    out = np.cross(mesh.vertices[b] - mesh.vertices[a], fn[f])
    side = np.einsum("ij,ij->i", out, 0.5 * (mesh.vertices[a] + mesh.vertices[b]) - p[f].mean(axis=1))
    out = _unit(out * np.sign(side)[:, None])
    bd = np.zeros_like(mesh.vertices)
    np.add.at(bd, a, out)
    np.add.at(bd, b, out)
    d = _LIFT * mesh.mean_edge_length
    up, down = mesh.vertices + d * vn, mesh.vertices - d * vn
    on = t.boundary_vertices
    towards = np.where((vn[on] @ eye)[:, None] >= 0, vn[on], -vn[on])
    up[on] = mesh.vertices[on] + d * (_unit(bd[on]) + towards)
    down[on] = up[on]
    return up, down


def _unit(v: np.ndarray) -> np.ndarray:
    length = np.linalg.norm(v, axis=1, keepdims=True)
    return np.divide(v, length, out=np.zeros_like(v), where=length > 0)


def _mesh_traces(data: _MeshData, title: str, vmin: float, vmax: float, show_vertices: bool,
                 line_width: float, light: np.ndarray, eye: np.ndarray) -> list[Any]:
    import plotly.graph_objects as go

    m = data.mesh
    quads = m.vertices[m.faces].reshape(-1, 3)  # four own corners per panel: one hover text per panel
    base = 4 * np.arange(m.n_faces, dtype=np.int32)
    tri_i = np.concatenate([base, base])
    tri_j = np.concatenate([base + 1, base + 2])
    tri_k = np.concatenate([base + 2, base + 3])
    fcd, ftemplate = data.face_hover()
    shade = _shade(m, light).astype(np.float32)
    faces = go.Mesh3d(
        **_xyz(quads), i=tri_i, j=tri_j, k=tri_k, name=f"{title}: panels",
        # the shade of every triangle — (0, 1, 2) of every panel, then (0, 2, 3) — on a scale from the
        # darkest to the lightest face colour: a number per triangle instead of a colour string
        intensity=np.concatenate([shade, shade]), intensitymode="cell", cmin=_SHADE_MIN, cmax=1.0,
        colorscale=[[0.0, _rgb(_SHADE_MIN * _FACE_RGB)], [1.0, _rgb(_FACE_RGB)]], showscale=False,
        flatshading=True, lighting=_BAKED,
        customdata=np.repeat(fcd, 4, axis=0), hovertemplate=ftemplate,
    )
    # A wide line lying in the surface is drawn as a flat strip facing the viewer, and the tilted panels
    # beside it cover half of it. So interior edges and vertices are drawn twice, lifted a little off the
    # surface to either side (from either side one copy is in front, the other hidden), and boundary
    # edges once, moved a little outwards (see _lifted).
    up, down = _lifted(m, eye)
    e = m.topology.edges
    inner = ~m.topology.boundary_edges
    pieces = np.concatenate([up[e[inner]], down[e[inner]], up[e[~inner]]])
    order = np.concatenate([np.flatnonzero(inner), np.flatnonzero(inner), np.flatnonzero(~inner)])
    c = np.repeat(_log_scale(data.edge_dev, vmin, vmax)[order], 3).astype(np.float32)
    ecd, etemplate = data.edge_hover()
    # every edge is its own two-point piece, so plotly's pick (the nearest point of the piece under the
    # mouse) always lands on one of the edge's own points and shows that edge's text
    lines = go.Scatter3d(
        **_xyz(_segments(pieces)), mode="lines", name=f"{title}: structure lines", connectgaps=False,
        line={"color": c, "width": line_width, "colorscale": _COLORSCALE, "cmin": np.log10(vmin),
              "cmax": np.log10(vmax), "showscale": True, "colorbar": _colorbar(vmin, vmax)},
        customdata=np.repeat(ecd[order], 3, axis=0), hovertemplate=etemplate,
    )
    traces = [faces, lines]
    if show_vertices:
        vcd, vtext, vtemplate = data.vertex_hover()
        traces.append(go.Scatter3d(
            **_xyz(np.concatenate([up, down])), mode="markers", name=f"{title}: vertices",
            marker={"size": 0.5 * line_width, "color": _VERTEX_COLOR},
            customdata=np.concatenate([vcd, vcd]), text=vtext + vtext, hovertemplate=vtemplate,
        ))
    return traces


def _compact_traces(data: _MeshData, title: str, vmin: float, vmax: float, line_width: float,
                    light: np.ndarray, eye: np.ndarray) -> list[Any]:
    """The traces of a large mesh in a few bytes per vertex (see :data:`COMPACT_FACES`).

    Panels share their vertices (no per-panel hover); the structure lines are
    polylines through their own vertices, lifted once towards the initial camera
    and coloured by the vertices' zigzag deviation, and carry the vertex hover
    (id, deviation, planarity); no separate vertex dots. About 60 bytes per vertex
    instead of about 1 kB.
    """
    import plotly.graph_objects as go

    m = data.mesh
    f = m.faces.astype(np.uint16 if m.n_vertices < 2**16 else np.int32)  # typed arrays: 2 bytes an index
    shade = _shade(m, light).astype(np.float32)
    faces = go.Mesh3d(
        **_xyz(m.vertices), i=np.concatenate([f[:, 0], f[:, 0]]), j=np.concatenate([f[:, 1], f[:, 2]]),
        k=np.concatenate([f[:, 2], f[:, 3]]), name=f"{title}: panels",
        intensity=np.concatenate([shade, shade]), intensitymode="cell", cmin=_SHADE_MIN, cmax=1.0,
        colorscale=[[0.0, _rgb(_SHADE_MIN * _FACE_RGB)], [1.0, _rgb(_FACE_RGB)]], showscale=False,
        flatshading=True, lighting=_BAKED, hoverinfo="skip",
    )
    up, down = _lifted(m, eye)
    # one copy of every vertex: the one on the side of the initial camera
    front = np.where(((up - m.vertices) @ eye >= 0)[:, None], up, down)
    lines = m.topology.structure_lines
    idx, ln = lines.indices, lines.lengths
    off = lines.offsets[: len(ln)]
    closed = lines.closed
    # each line's vertices (closed lines repeat their first), then a gap
    extra = closed.astype(np.int64) + 1
    total = int(ln.sum() + extra.sum())
    order = np.full(total, -1, dtype=np.int64)
    start = np.concatenate([[0], np.cumsum(ln + extra)[:-1]])
    pos = np.repeat(start, ln) + (np.arange(idx.size) - np.repeat(off, ln))
    order[pos] = idx
    first = idx[off[closed]] if closed.any() else np.zeros(0, dtype=np.int64)
    order[(start + ln)[closed]] = first
    gap = order < 0
    pts = front[np.where(gap, 0, order)].astype(np.float64)
    pts[gap] = np.nan
    vid = np.where(gap, 0, order)
    c = _log_scale(data.vertex_dev[vid], vmin, vmax).astype(np.float32)
    cd = np.column_stack([vid, data.vertex_dev[vid], data.vertex_planarity[vid]]).astype(np.float32)
    where = ""
    poly = go.Scatter3d(
        **_xyz(pts), mode="lines", name=f"{title}: structure lines", connectgaps=False,
        line={"color": c, "width": line_width, "colorscale": _COLORSCALE, "cmin": np.log10(vmin),
              "cmax": np.log10(vmax), "showscale": True, "colorbar": _colorbar(vmin, vmax)},
        customdata=cd,
        hovertemplate=(f"<b>vertex %{{customdata[0]}}</b>{where}<br>zigzag deviation %{{customdata[1]:.3~g}}"
                       "<br>max planarity of its panels %{customdata[2]:.3~g}<extra></extra>"),
    )
    return [faces, poly]


def _reference_traces(ref: QuadMesh) -> list[Any]:
    """The reference as thin grey edges and its boundary dashed.

    A faint reference *surface* would lie almost in the shown mesh and flicker
    through it (z-fighting), so only its edges are drawn.
    """
    import plotly.graph_objects as go

    t = ref.topology
    wire = go.Scatter3d(
        **_xyz(_segments(ref.vertices[t.edges])), mode="lines", name="reference", connectgaps=False,
        line={"color": _REF_COLOR, "width": 2}, opacity=0.55, hoverinfo="skip",
    )
    border = go.Scatter3d(
        **_xyz(_segments(ref.vertices[t.edges[t.boundary_edges]])), mode="lines", name="reference boundary",
        connectgaps=False, line={"color": _REF_BOUNDARY_COLOR, "width": 3, "dash": "dash"}, hoverinfo="skip",
    )
    return [wire, border]


def _scene(points: np.ndarray, elev: float, azim: float, unit: str = "mm") -> dict[str, Any]:
    lo, hi = points.min(axis=0), points.max(axis=0)
    size = hi - lo
    longest = float(size.max()) or 1.0
    box = np.maximum(size, _FLAT * longest)
    mid = 0.5 * (lo + hi)
    pad = 0.04 * longest
    ranges = [[float(c - 0.5 * b - pad), float(c + 0.5 * b + pad)] for c, b in zip(mid, box)]
    ratio = (box + 2 * pad) / float((box + 2 * pad).max())
    cam = camera(elev, azim)
    # an orthographic plotly camera zooms with the aspect ratio, not the eye distance: scale the box so
    # that its picture fills about the same part of the page whatever its shape
    corners = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)]) * ratio
    extent = np.ptp(corners @ cam[:2].T, axis=0)
    ratio = ratio * min(_VIEW[0] / extent[0], _VIEW[1] / extent[1])
    eye = dict(zip("xyz", (2.0 * cam[2]).tolist()))
    axis = {"showbackground": False, "gridcolor": "#e4e6ea", "zerolinecolor": "#d0d3d8",
            "showspikes": False, "tickfont": {"size": 10, "color": "#8a8f98"},
            "title": {"font": {"size": 12, "color": "#8a8f98"}}}
    return {
        "xaxis": {**axis, "range": ranges[0], "title": {**axis["title"], "text": f"x ({unit})"}},
        "yaxis": {**axis, "range": ranges[1], "title": {**axis["title"], "text": f"y ({unit})"}},
        "zaxis": {**axis, "range": ranges[2], "title": {**axis["title"], "text": f"z ({unit})"}},
        "aspectmode": "manual",
        "aspectratio": {"x": float(ratio[0]), "y": float(ratio[1]), "z": float(ratio[2])},
        "camera": {"eye": eye, "up": {"x": 0, "y": 0, "z": 1},
                   "projection": {"type": "orthographic"}},
        "dragmode": "orbit",
    }


def _title(title: str, summary: str) -> str:
    return f"<b>{_html.escape(title)}</b><br><span style='font-size:12px;color:#5b616b'>{summary}</span>"


# ----------------------------------------------------------------------------
# public functions
# ----------------------------------------------------------------------------


def figure(
    meshes: QuadMesh | Sequence[QuadMesh],
    *,
    titles: Sequence[str] | None = None,
    reference: QuadMesh | None = None,
    vmin: float = 1e-4,
    vmax: float = 1.0,
    elev: float = 35.0,
    azim: float = -60.0,
    show_vertices: bool = True,
    line_width: float | None = None,
    detail: str = "auto",
) -> go.Figure:
    """The interactive view as a plotly figure (for notebooks: ``figure(m).show()``).

    One group of traces per mesh — panels (``Mesh3d``), structure lines and,
    unless ``show_vertices`` is false, vertices — of which only
    the first is visible; the buttons at the top left (one per mesh, shown for two
    meshes or more) switch between them and the title follows. The reference, if
    given, is drawn in every state. Axis ranges are the union of all meshes and
    the reference, so switching keeps the scale and the camera.

    Parameters
    ----------
    meshes : QuadMesh or sequence of QuadMesh
        The meshes to switch between, e.g. ``[noisy, faired]``.
    titles : sequence of str, optional
        One name per mesh, used on the buttons and in the title (default
        ``"mesh 1"``, ``"mesh 2"``, …).
    reference : QuadMesh, optional
        A clean surface shown in every state: its edges thin and grey, its
        boundary as a dark dashed line (so a shrunk or moved boundary shows).
    vmin, vmax : float
        Range of the logarithmic deviation colour scale (``0 < vmin < vmax``);
        values outside are clipped to its ends.
    elev, azim : float
        Initial camera elevation above the xy plane and azimuth about z, in
        degrees (as in :func:`quadnodes.viz.render_png`). The camera is
        orthographic.
    show_vertices : bool
        Draw the vertices as dots (they carry the vertex hover texts).
    line_width : float, optional
        Width of the structure lines in pixels (> 0); vertex dots are half as
        wide. Default: 6, less for meshes of more than about 1700 panels (down
        to 1.5 at 28 000).
    detail : {"auto", "full", "compact"}
        ``"full"``: every panel, edge and vertex carries its own hover text
        (about 1 kB per vertex in the page); ``"compact"``: panels share their
        vertices, structure lines are polylines carrying the vertex hover, no
        vertex dots (about 60 bytes per vertex); ``"auto"`` (default): compact
        when a mesh has more than :data:`COMPACT_FACES` panels.

    Returns
    -------
    plotly.graph_objects.Figure
        ``fig.data`` holds ``3`` traces per mesh — panels, structure lines,
        vertices (``2`` without vertices or in compact detail) — in the order of
        ``meshes``, then ``2`` for the reference (its edges and its dashed boundary).

    Raises
    ------
    InputError
        On a non-mesh input, titles that are not one string per mesh, a bad
        reference or a bad number; the message names the parameter.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> fig = figure([grid(3, 4), grid(3, 4)], titles=["a", "b"])
    >>> len(fig.data), [t.visible for t in fig.data]
    (6, [True, True, True, False, False, False])
    >>> [b.label for b in fig.layout.updatemenus[0].buttons]
    ['a', 'b']
    """
    import plotly.graph_objects as go

    ms = _validate.quad_meshes(meshes)
    k = len(ms)
    names = _titles(titles, k)
    if reference is not None:
        _validate.quad_mesh(reference, "reference")
    # one scene: every mesh in the first one's unit
    ms = [m.with_unit(ms[0].unit) for m in ms]
    if reference is not None:
        reference = reference.with_unit(ms[0].unit)
    vmin_ = _validate.positive_number(vmin, "vmin")
    vmax_ = _validate.positive_number(vmax, "vmax")
    if vmin_ >= vmax_:
        raise InputError(f"vmin: must be less than vmax = {vmax_:g}, got {vmin!r}")
    elev_ = _validate.finite_number(elev, "elev")
    azim_ = _validate.finite_number(azim, "azim")
    if line_width is None:
        # thinner lines for denser meshes, so that a 100 × 100 grid is not one block of colour
        width = float(np.clip(250.0 / np.sqrt(max(m.n_faces for m in ms)), 1.5, 6.0))
    else:
        width = _validate.positive_number(line_width, "line_width")
    if not isinstance(show_vertices, (bool, np.bool_)):
        raise InputError(f"show_vertices: expected True or False, got {show_vertices!r}")
    detail = _validate.choice(detail, ("auto", "full", "compact"), "detail")
    compact = detail == "compact" or (detail == "auto" and max(m.n_faces for m in ms) > COMPACT_FACES)

    data = [_MeshData(m) for m in ms]
    cam = camera(elev_, azim_)
    light_dir = light(cam)
    if compact:
        groups = [_compact_traces(d, t, vmin_, vmax_, width, light_dir, cam[2]) for d, t in zip(data, names)]
    else:
        groups = [_mesh_traces(d, t, vmin_, vmax_, bool(show_vertices), width, light_dir, cam[2])
                  for d, t in zip(data, names)]
    ref_traces = _reference_traces(reference) if reference is not None else []
    fig = go.Figure()
    owner: list[int] = []
    for i, g in enumerate(groups):
        for tr in g:
            tr.visible = i == 0
            fig.add_trace(tr)
            owner.append(i)
    for tr in ref_traces:
        fig.add_trace(tr)
        owner.append(-1)

    pts = [m.vertices[m.topology.vertex_face_count > 0] for m in ms]  # (a vertex in no face is not drawn)
    pts += [reference.vertices[reference.topology.vertex_face_count > 0]] if reference is not None else []
    titles_html = [_title(t, d.summary()) for t, d in zip(names, data)]
    menus = []
    if k > 1:
        buttons = [
            {"label": _html.escape(t), "method": "update",
             "args": [{"visible": [o in (-1, i) for o in owner]}, {"title.text": titles_html[i]}]}
            for i, t in enumerate(names)
        ]
        menus.append({
            "type": "buttons", "direction": "right", "buttons": buttons, "active": 0, "showactive": True,
            "x": 0.0, "xanchor": "left", "y": 1.0, "yanchor": "top", "pad": {"l": 12, "t": 10},
            "bgcolor": "#f3f4f6", "bordercolor": "#b8bdc6", "font": {"size": 13},
        })
    hint = ("drag: rotate · scroll: zoom · " + ("hover a structure line" if compact else "hover a vertex, edge or panel")
            + (" · buttons: switch meshes" if k > 1 else "")
            + (" · grey edges, dashed boundary: reference" if reference is not None else ""))
    fig.update_layout(
        title={"text": titles_html[0], "x": 0.5, "xanchor": "center", "y": 0.97, "yanchor": "top",
               "font": {"size": 18}},
        scene=_scene(np.vstack(pts), elev_, azim_, ms[0].unit),
        updatemenus=menus,
        showlegend=False,
        margin={"l": 0, "r": 0, "t": 70, "b": 0},
        paper_bgcolor="white",
        hoverlabel={"bgcolor": "white", "bordercolor": "#8a8f98", "font": {"size": 12, "color": "#1f2328"},
                    "align": "left"},
        annotations=[{"text": hint, "showarrow": False, "xref": "paper", "yref": "paper", "x": 0.005, "y": 0.005,
                      "xanchor": "left", "yanchor": "bottom", "font": {"size": 11, "color": "#8a8f98"}}],
        uirevision="quadnodes",
    )
    return fig


def build_html(
    meshes: QuadMesh | Sequence[QuadMesh],
    *,
    titles: Sequence[str] | None = None,
    reference: QuadMesh | None = None,
    page_title: str | None = None,
    **options: Any,
) -> str:
    """The complete, self-contained HTML page of :func:`figure` as a string.

    plotly.js is inlined (no ``<script src=...>``), so the page works offline.

    Parameters
    ----------
    meshes, titles, reference
        As in :func:`figure`.
    page_title : str, optional
        The browser tab's title (default: the titles joined by " / ").
    **options
        Further keyword options of :func:`figure` (``vmin``, ``vmax``, ``elev``,
        ``azim``, ``show_vertices``, ``line_width``, ``detail``).

    Returns
    -------
    str

    Raises
    ------
    InputError
        As :func:`figure`, or on an unknown option or a non-string ``page_title``.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> page = build_html(grid(3, 3), titles=["flat"])
    >>> page.startswith("<!DOCTYPE html>"), "plotly.js v" in page, len(page) > 1_000_000
    (True, True, True)
    """
    import plotly.io as pio

    allowed = {"vmin", "vmax", "elev", "azim", "show_vertices", "line_width", "detail"}
    unknown = sorted(set(options) - allowed)
    if unknown:
        raise InputError(f"{unknown[0]}: unknown option; expected one of {', '.join(sorted(allowed))}")
    if page_title is not None and not isinstance(page_title, str):
        raise InputError(f"page_title: expected a string, got {type(page_title).__name__}")
    fig = figure(meshes, titles=titles, reference=reference, **options)
    if page_title is None:
        k = 1 if isinstance(meshes, QuadMesh) else len(meshes)
        page_title = " / ".join(_titles(titles, k)) + " — quadnodes"
    body = pio.to_html(
        fig, full_html=False, include_plotlyjs=True, include_mathjax=False, validate=True,
        default_width="100%", default_height="100vh",
        config={"displaylogo": False, "responsive": True, "scrollZoom": True,
                "toImageButtonOptions": {"format": "png", "filename": "quadnodes", "scale": 2}},
    )
    return (
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
        "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
        f"<title>{_html.escape(page_title)}</title>\n"
        "<style>html, body { margin: 0; padding: 0; height: 100%; overflow: hidden; background: #fff; "
        "font-family: system-ui, sans-serif; }</style>\n"
        f"</head>\n<body>\n{body}\n</body>\n</html>\n"
    )


def render_html(
    meshes: QuadMesh | Sequence[QuadMesh],
    path: str | os.PathLike[str],
    *,
    titles: Sequence[str] | None = None,
    reference: QuadMesh | None = None,
    page_title: str | None = None,
    vmin: float = 1e-4,
    vmax: float = 1.0,
    elev: float = 35.0,
    azim: float = -60.0,
    show_vertices: bool = True,
    line_width: float | None = None,
    detail: str = "auto",
) -> Path:
    """Write the interactive view of :func:`figure` to a self-contained HTML file, atomically.

    Parameters
    ----------
    meshes : QuadMesh or sequence of QuadMesh
        The meshes to switch between with the buttons, e.g. ``[noisy, faired]``.
    path : path-like
        Output file (``.html``; its folder must exist).
    titles, reference, vmin, vmax, elev, azim, show_vertices, line_width, detail
        As in :func:`figure`.
    page_title : str, optional
        As in :func:`build_html`.

    Returns
    -------
    Path
        About 4.8 MB of plotly.js plus about 1 kB per vertex of every mesh in
        full detail, about 60 bytes in compact detail (the default above
        :data:`COMPACT_FACES` panels: a 100 × 100 grid adds about 0.7 MB).

    Raises
    ------
    InputError
        As :func:`figure`; the message names the parameter.
    ExportError
        If the file cannot be written (nothing is left behind).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from quadnodes.mesh import grid
    >>> p = render_html(grid(4, 5), pathlib.Path(tempfile.mkdtemp()) / "grid.html")
    >>> p.suffix, p.stat().st_size > 4_000_000
    ('.html', True)
    """
    text = build_html(meshes, titles=titles, reference=reference, page_title=page_title, vmin=vmin, vmax=vmax,
                      elev=elev, azim=azim, show_vertices=show_vertices, line_width=line_width, detail=detail)
    return write_text_atomic(path, text)
