"""DXF unrolls for fabrication (ezdxf): every panel laid out flat, in rows, labelled.

Every panel is unfolded into the plane along one diagonal, as its two triangles
(the diagonal whose unfolding changes the other diagonal's length least, so a
planar panel, convex or not, comes out as itself): its four edges keep their 3-D
lengths exactly (to rounding). A planar panel is then congruent to the 3-D one;
a bilinear (twisted) panel cannot be, and its **distortion** is the length
change of the other diagonal, the largest change of any edge or diagonal
(:func:`panel_distortion`, in the mesh's unit).

The flat panels are turned so that edge 01 runs along +x, and placed in
shelves (rows of bounding boxes, a gap apart), one shelf per grid row when the
mesh has a grid: no two panels' boxes overlap. Each panel is a closed
LWPOLYLINE on layer ``PANELS`` (green when planar within the planar tolerance,
orange when bilinear) and its label (``P_<row>_<col>``) a TEXT in its middle on
layer ``LABELS``. The drawing is in the mesh's unit (``$INSUNITS``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import _validate
from ..errors import ExportError
from ..flatness import planar_panels, resolve_planar_tolerance
from ..mesh import QuadMesh
from ._atomic import write_text_atomic
from ..flatness import DEFAULT_PLANAR_TOLERANCE as DEFAULT_PLANAR_TOL
from .panels import check_panels, panel_labels, panel_rows_cols

__all__ = [
    "INSUNITS", "Unfolding", "DxfReport", "unfold", "panel_distortion", "layout", "dxf_document", "save_dxf", "dxf_report",
]

INSUNITS: dict[str, int] = {"in": 1, "ft": 2, "mm": 4, "cm": 5, "m": 6}
"""quadnodes unit -> DXF ``$INSUNITS`` code."""

_PLANAR_COLOR, _BILINEAR_COLOR = 3, 30  # AutoCAD colour index: green, orange


@dataclass(frozen=True)
class Unfolding:
    """Flat panels.

    Attributes
    ----------
    outlines : (m, 4, 2) float64
        Corner ``k`` of panel ``i`` in its own flat frame: corner 0 at the origin,
        edge 01 along +x, counter-clockwise as seen from the panel's front.
    diagonal : (m,) int8
        The diagonal unfolded along: 0 for corners 0–2, 1 for corners 1–3.
    distortion : (m,) float64
        Largest change of an edge or diagonal length from 3-D to flat, in the mesh's unit
        (0 up to rounding for a planar panel).
    """

    outlines: np.ndarray
    diagonal: np.ndarray
    distortion: np.ndarray


@dataclass(frozen=True)
class DxfReport:
    """What :func:`save_dxf` wrote."""

    path: str
    unit: str
    n_panels: int
    n_planar: int
    planar_tolerance: float | str
    max_distortion: float
    sheet: tuple[float, float]
    distortion: np.ndarray = field(repr=False)

    def to_dict(self) -> dict[str, Any]:
        """Plain values (the per-panel distortion as a list)."""
        return {
            "path": self.path,
            "unit": self.unit,
            "n_panels": self.n_panels,
            "n_planar": self.n_planar,
            "planar_tolerance": self.planar_tolerance,
            "max_distortion": self.max_distortion,
            "sheet": list(self.sheet),
            "distortion": self.distortion.tolist(),
        }


def _unfold_along(p: np.ndarray, a: int) -> tuple[np.ndarray, np.ndarray]:
    """Unfold along diagonal ``a``–``a+2``: flat corners ``(m, 4, 2)`` and the other diagonal's length change."""
    i0, i1, i2, i3 = a, (a + 1) % 4, (a + 2) % 4, (a + 3) % 4
    o = p[:, i0]
    d = p[:, i2] - o
    length = np.linalg.norm(d, axis=1)
    u = d / length[:, None]

    def place(q: np.ndarray, sign: float) -> np.ndarray:
        w = q - o
        x = np.einsum("ij,ij->i", w, u)
        y = np.linalg.norm(np.cross(u, w), axis=1)
        return np.stack([x, sign * y], axis=1)

    flat = np.empty((len(p), 4, 2))
    flat[:, i0] = 0.0
    flat[:, i2, 0] = length
    flat[:, i2, 1] = 0.0
    flat[:, i1] = place(p[:, i1], -1.0)  # corners turn counter-clockwise: i1 right of the diagonal, i3 left
    flat[:, i3] = place(p[:, i3], 1.0)
    other3d = np.linalg.norm(p[:, i3] - p[:, i1], axis=1)
    other2d = np.linalg.norm(flat[:, i3] - flat[:, i1], axis=1)
    return flat, np.abs(other2d - other3d)


def unfold(mesh: QuadMesh) -> Unfolding:
    """Every panel flat, along the diagonal that distorts it least.

    Returns
    -------
    Unfolding

    Raises
    ------
    InputError
        If ``mesh`` is not a QuadMesh.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> u = unfold(grid(2, 2, spacing=(2.0, 3.0)))
    >>> u.outlines[0].round(12).tolist(), float(u.distortion[0])
    ([[0.0, 0.0], [2.0, 0.0], [2.0, 3.0], [0.0, 3.0]], 0.0)
    """
    _validate.quad_mesh(mesh)
    p = mesh.vertices[mesh.faces]
    flat0, dist0 = _unfold_along(p, 0)
    flat1, dist1 = _unfold_along(p, 1)
    use1 = dist1 < dist0
    flat = np.where(use1[:, None, None], flat1, flat0)
    dist = np.where(use1, dist1, dist0)
    # corner 0 at the origin, edge 01 along +x
    flat = flat - flat[:, :1]
    e = flat[:, 1]
    ang = np.arctan2(e[:, 1], e[:, 0])
    c, s = np.cos(ang)[:, None], np.sin(ang)[:, None]
    x, y = flat[..., 0], flat[..., 1]
    flat = np.stack([c * x + s * y, -s * x + c * y], axis=2)
    flat[:, 1, 1] = 0.0  # exactly on the x axis
    return Unfolding(flat, use1.astype(np.int8), dist)


def panel_distortion(mesh: QuadMesh) -> np.ndarray:
    """Largest edge- or diagonal-length change of every panel's DXF unroll, in the mesh's unit.

    Returns
    -------
    (m,) float64
        0 (to rounding) for a planar panel.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> m = grid(2, 2, spacing=1000.0, height=[[0, 0], [0, 10]])
    >>> round(float(panel_distortion(m)[0]), 4)
    0.0354
    """
    return unfold(mesh).distortion


def layout(outlines: np.ndarray, *, per_row: int | None = None, gap: float | None = None) -> np.ndarray:
    """Place flat panels in shelves without overlaps.

    Parameters
    ----------
    outlines : (m, 4, 2) float64
        Flat panels, each in its own frame.
    per_row : int, optional
        Panels per shelf (default: about the square root of ``m``).
    gap : float, optional
        Space between boxes (default: a tenth of the median box size).

    Returns
    -------
    (m, 4, 2) float64
        The panels moved onto the sheet; their bounding boxes are disjoint.

    Examples
    --------
    >>> sq = np.array([[[0, 0], [1, 0], [1, 1], [0, 1]]] * 4, dtype=float)
    >>> layout(sq, per_row=2, gap=0.5)[:, 0].tolist()
    [[0.0, 0.0], [1.5, 0.0], [0.0, 1.5], [1.5, 1.5]]
    """
    m = len(outlines)
    lo = outlines.min(axis=1)
    size = outlines.max(axis=1) - lo
    if per_row is None:
        per_row = max(1, int(np.ceil(np.sqrt(m))))
    if gap is None:
        gap = 0.1 * float(np.median(size.max(axis=1))) if m else 0.0
    shelf = np.arange(m) // per_row
    n_shelves = int(shelf[-1]) + 1 if m else 0
    w = size[:, 0] + gap
    x = np.cumsum(w) - w
    first = np.searchsorted(shelf, np.arange(n_shelves))
    x = x - (np.cumsum(w) - w)[first][shelf]
    h = np.zeros(n_shelves)
    np.maximum.at(h, shelf, size[:, 1])
    y0 = np.concatenate([[0.0], np.cumsum(h + gap)[:-1]])
    offset = np.stack([x, y0[shelf]], axis=1) - lo
    return outlines + offset[:, None, :]


def dxf_document(
    mesh: QuadMesh,
    *,
    planar_tolerance: float | str = DEFAULT_PLANAR_TOL,
    per_row: int | None = None,
    gap: float | None = None,
    text_height: float | None = None,
    engine: str = "fast",
) -> tuple[Any, DxfReport]:
    """The ezdxf document of the unrolled panels, and what it holds.

    Parameters
    ----------
    mesh : QuadMesh
    planar_tolerance : float or str
        Relative, or a length such as ``"2 mm"`` (:func:`quadnodes.flatness.planar_panels`): planar
        panels are drawn green, bilinear ones orange.
    per_row : int, optional
        Panels per row of the sheet (default: the grid's panels per row, else about ``sqrt(m)``).
    gap : float, optional
        Space between panels, in the mesh's unit (default a tenth of the median panel size).
    text_height : float, optional
        Label height (default a fifth of the smallest panel's box, at most a tenth of the median).
    engine : {"fast", "ezdxf"}
        ``"fast"`` (default): ezdxf makes the document (header, layers, tables) and the panels'
        entities are formatted in one pass, 20× faster than ``"ezdxf"``, which adds every entity
        through ezdxf's objects (the reference the tests compare with).

    Returns
    -------
    drawing
        Its ``text()`` is the DXF file; ``doc`` the ezdxf document.
    report : DxfReport
        ``path`` empty (not written yet).

    Raises
    ------
    InputError
        On a bad setting.
    ExportError
        On a degenerate panel (naming it) or a unit DXF cannot state.
    """
    import ezdxf
    from ezdxf.enums import TextEntityAlignment

    _validate.quad_mesh(mesh)
    engine = _validate.choice(engine, ("fast", "ezdxf"), "engine")
    resolve_planar_tolerance(planar_tolerance, mesh.unit)
    if mesh.unit not in INSUNITS:
        raise ExportError(f"dxf: the mesh's unit {mesh.unit!r} has no DXF $INSUNITS code (known: {', '.join(INSUNITS)})")
    if per_row is not None:
        per_row = _validate.positive_int(per_row, "per_row")
    if gap is not None:
        gap = _validate.nonnegative_number(gap, "gap")
    check_panels(mesh, planar_tolerance, "dxf")
    planar = planar_panels(mesh, planar_tolerance)
    unf = unfold(mesh)
    if per_row is None and mesh.grid_shape is not None and panel_rows_cols(mesh) is not None:
        per_row = mesh.grid_shape[1] - 1 + mesh.grid_wrap[1]  # a ring of a cylinder has one cell more
    sheet = layout(unf.outlines, per_row=per_row, gap=gap)
    box = sheet.max(axis=1) - sheet.min(axis=1)
    if text_height is None:
        text_height = min(0.2 * float(box.min()), 0.1 * float(np.median(box.max(axis=1))))
    else:
        text_height = _validate.positive_number(text_height, "text_height")

    doc = ezdxf.new("R2010", setup=False)
    doc.header["$INSUNITS"] = INSUNITS[mesh.unit]
    doc.header["$MEASUREMENT"] = 0 if mesh.unit in ("in", "ft") else 1
    doc.layers.add("PANELS", color=7)
    doc.layers.add("LABELS", color=1)
    msp = doc.modelspace()
    labels = panel_labels(mesh)
    centers = sheet.mean(axis=1)
    colors = np.where(planar, _PLANAR_COLOR, _BILINEAR_COLOR)
    if engine == "ezdxf":
        middle = TextEntityAlignment.MIDDLE_CENTER
        for k, pts in enumerate(sheet.tolist()):
            msp.add_lwpolyline(pts, format="xy", close=True, dxfattribs={"layer": "PANELS", "color": int(colors[k])})
            msp.add_text(labels[k], height=text_height, dxfattribs={"layer": "LABELS"}).set_placement(
                tuple(centers[k]), align=middle
            )
        entities = ""
    else:
        first = int(doc.entitydb.handles.next(), 16)
        doc.entitydb.handles.reset(f"{first + 2 * mesh.n_faces:X}")  # $HANDSEED past the handles used below
        entities = _entities_text(sheet, centers, colors, labels, text_height, first, msp.layout_key)
    lo, hi = sheet.reshape(-1, 2).min(axis=0), sheet.reshape(-1, 2).max(axis=0)
    report = DxfReport(
        path="",
        unit=mesh.unit,
        n_panels=mesh.n_faces,
        n_planar=int(planar.sum()),
        planar_tolerance=planar_tolerance,
        max_distortion=float(unf.distortion.max()),
        sheet=(float(hi[0] - lo[0]), float(hi[1] - lo[1])),
        distortion=unf.distortion,
    )
    return _Drawing(doc, entities), report


class _Drawing:
    """An ezdxf document plus pre-formatted entities for its ENTITIES section."""

    def __init__(self, doc: Any, entities: str) -> None:
        self.doc = doc
        self.entities = entities

    def text(self) -> str:
        import io

        stream = io.StringIO()
        self.doc.write(stream)
        text = stream.getvalue()
        if not self.entities:
            return text
        mark = "  2\nENTITIES\n"
        at = text.index(mark) + len(mark)
        return text[:at] + self.entities + text[at:]


def _entities_text(sheet: np.ndarray, centers: np.ndarray, colors: np.ndarray, labels: list[str],
                   text_height: float, first: int, owner: str) -> str:
    """LWPOLYLINE + TEXT records of every panel, formatted in one pass (ezdxf's entity objects
    take about 0.4 ms each; this is the same DXF, checked against them in the tests)."""
    m = len(sheet)
    handles = [f"{h:X}" for h in range(first, first + 2 * m)]
    poly = (
        "  0\nLWPOLYLINE\n  5\n%s\n330\n" + owner + "\n100\nAcDbEntity\n  8\nPANELS\n 62\n%d\n"
        "100\nAcDbPolyline\n 90\n4\n 70\n1\n" + " 10\n%r\n 20\n%r\n" * 4
    )
    text = (
        "  0\nTEXT\n  5\n%s\n330\n" + owner + "\n100\nAcDbEntity\n  8\nLABELS\n100\nAcDbText\n"
        " 10\n%r\n 20\n%r\n 30\n0.0\n 40\n" + repr(float(text_height)) + "\n  1\n%s\n 72\n1\n"
        " 11\n%r\n 21\n%r\n 31\n0.0\n100\nAcDbText\n 73\n2\n"
    )
    pts = sheet.reshape(m, 8).tolist()
    c = centers.tolist()
    col = colors.tolist()
    out = []
    for k in range(m):
        out.append(poly % (handles[2 * k], col[k], *pts[k]))
        out.append(text % (handles[2 * k + 1], c[k][0], c[k][1], labels[k], c[k][0], c[k][1]))
    return "".join(out)


def save_dxf(
    mesh: QuadMesh,
    path: str | os.PathLike[str],
    *,
    planar_tolerance: float | str = DEFAULT_PLANAR_TOL,
    per_row: int | None = None,
    gap: float | None = None,
    text_height: float | None = None,
    engine: str = "fast",
) -> Path:
    """Write the unrolled panels to a DXF file atomically (see :func:`dxf_document`).

    Returns
    -------
    Path
        ``path`` (:func:`dxf_report` gives the distortion as well).

    Raises
    ------
    InputError, ExportError
        As :func:`dxf_document`, or when the file cannot be written; nothing is left behind.

    Examples
    --------
    >>> import tempfile, pathlib, ezdxf
    >>> from quadnodes.mesh import grid
    >>> p = save_dxf(grid(3, 3, spacing=100.0), pathlib.Path(tempfile.mkdtemp()) / "g.dxf")
    >>> len(ezdxf.readfile(p).modelspace().query("LWPOLYLINE[layer=='PANELS']"))
    4
    """
    return dxf_report(mesh, path, planar_tolerance=planar_tolerance, per_row=per_row, gap=gap,
                      text_height=text_height, engine=engine)[0]


def dxf_report(
    mesh: QuadMesh,
    path: str | os.PathLike[str],
    *,
    planar_tolerance: float | str = DEFAULT_PLANAR_TOL,
    per_row: int | None = None,
    gap: float | None = None,
    text_height: float | None = None,
    engine: str = "fast",
) -> tuple[Path, DxfReport]:
    """:func:`save_dxf`, also returning the :class:`DxfReport` (per-panel distortion included).

    Raises
    ------
    InputError, ExportError
        As :func:`save_dxf`.
    """
    doc, report = dxf_document(mesh, planar_tolerance=planar_tolerance, per_row=per_row, gap=gap,
                               text_height=text_height, engine=engine)
    out = write_text_atomic(path, doc.text())
    return out, DxfReport(**{**report.__dict__, "path": str(out)})
