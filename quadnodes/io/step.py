"""STEP export: every quad becomes a panel face, planar or an exact bilinear patch.

Planar or bilinear
------------------
Which panels are planar is decided in one place for every exporter and the
schedule, :func:`quadnodes.flatness.planar_panels`: a panel is planar when its
diagonal distance is within ``planar_tolerance`` (a number: relative to the
mean diagonal, default ``1e-3``; text such as ``"2 mm"``: a length, converted to
the mesh's unit) and it is a simple polygon in its plane. A planar panel is
written as a **plane** face: the mid-plane of its two diagonal lines (through
the centroid, normal ``(p2 - p0) × (p3 - p1)``), bounded by its four corners
**projected onto that plane**. Every corner of such a panel lies exactly half
the diagonal distance from the plane, so each corner moves by that much (at most
half the tolerance) and the face is exactly planar, with OCCT's default
tolerances. :class:`StepReport` gives the largest move of the export
(``max_corner_move``), the schedule gives every panel's (``corner_move_<unit>``).

Every other panel is the **bilinear patch** through its four exact corners, a
degree-(1, 1) ``Geom_BezierSurface`` with poles ``[[p0, p3], [p1, p2]]`` (``u``
from ``p0`` to ``p1``, ``v`` from ``p0`` to ``p3``), so ``S_u × S_v`` points
along the quad's counter-clockwise normal and its boundary curves are the quad's
straight edges. A planar panel that OCCT still refuses as a plane face (never
seen; the classification already excludes folded quads) falls back to its
bilinear patch, and the report lists it in ``fallback``: one panel never aborts
an export. Only a degenerate panel (an edge of zero length, or zero area) is an
:class:`~quadnodes.errors.ExportError`, naming the panel, before anything is
written.

Why projected corners: the corners of an almost-planar quad are off its plane by
half the diagonal distance. The previous exporter kept them there and widened
the edge and vertex tolerances with ``BRepLib::SameParameter``; for deviations
between about ``1.5e-7`` and ``1e-5`` model units OCCT widened only the edges
whose pcurves it recomputed (two of the four for a one-corner lift), left the
vertex they share at ``1e-7`` although it lies ``2.5e-7 … 2.5e-6`` off the
plane, and ``BRepCheck_Analyzer`` rejected the face (a 1 m panel with one corner
lifted 1e-6 … 1e-5 mm). A face on its plane with its corners on it has nothing
to tolerate.

Modes
-----
``"compound"``
    One compound of independent faces (fastest; neighbours share no edges).
``"shell"`` (the export node's default)
    The panels connected along their shared edges: one shell per connected piece
    of the mesh, built on the mesh's own vertices and edges (one OCCT vertex per
    mesh vertex, one edge per mesh edge, used by both its panels; no sewing),
    every face **named** with its panel
    label ``P_<row>_<col>`` (or ``P_<face index>``) through XCAF sub-shape names
    (the STEP ``ADVANCED_FACE`` names, read by OCCT with
    ``read.stepcaf.subshapes.name``); optionally coloured. Labelled and
    connected: what a CAD user expects of a panelled surface.
``"assembly"``
    An assembly whose children are the panels (one product per panel, named
    with its label), optionally coloured; neighbours share no edges.

In a shell the panels share their corners, so a planar panel's corners are not
moved: its shared vertices are the mesh's vertices, its plane face is bounded by
their projections onto its plane (the pcurves), and each shared edge and vertex
carries the distance between the two as its tolerance — the panel's corner move,
at most half the tolerance, exactly as much as the compound moves its corners.
The whole shape is built in one read of OCCT's BRep text
(:mod:`quadnodes.io._brep`): about 1 s of CPU for 10,000 panels, where building
them face by face and sewing them took 13 s.

Pcurves
-------
Every edge is a straight line on planes and bilinear patches, which a reader
projects onto each face exactly, so by default the file leaves out the edges'
curves on each face (``write.surfacecurve.mode = 0``): 13 MB instead of 32 MB and
about 40 % less writing time for 10,000 panels; ``pcurves=True`` writes them (OCCT's
default). The tests read both back (OCCT, gmsh): the same faces, edges and names.

Units
-----
The file declares the mesh's own unit (:attr:`quadnodes.mesh.QuadMesh.unit`;
``SI_UNIT(.MILLI.,.METRE.)``, ``SI_UNIT($,.METRE.)``, inch, foot, …) and holds
the coordinates **unchanged**, so no value is rescaled and rounded; a unit-aware
reader converts. OCCT writes real numbers with 12 significant digits, so
coordinates round-trip to a relative ``1e-12``, not bit for bit (use OBJ or
JSON for exact coordinates).
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from .. import _validate
from ..errors import ExportError, InputError
from ..flatness import DEFAULT_PLANAR_TOLERANCE, diagonal_distance, planar_panels
from ..mesh import QuadMesh
from ..progress import report_progress
from ._atomic import write_atomic
from .panels import check_panels, corner_moves, panel_labels

if TYPE_CHECKING:
    from build123d import Shape

__all__ = ["STEP_MODES", "STEP_UNITS", "StepReport", "step_panels", "step_shape", "write_step", "save_step"]

STEP_MODES: tuple[str, ...] = ("compound", "shell", "assembly")
"""The values of ``mode``."""

# mesh unit -> (metres per unit, OCCT "write.step.unit" value)
_UNITS: dict[str, tuple[float, str]] = {
    "mm": (1e-3, "MM"),
    "cm": (1e-2, "CM"),
    "m": (1.0, "M"),
    "in": (0.0254, "INCH"),
    "ft": (0.3048, "FT"),
}
STEP_UNITS: tuple[str, ...] = tuple(_UNITS)
"""The mesh units a STEP file can declare (every unit of :data:`quadnodes.units.UNITS`)."""

_RENAMED = {
    "planar_tol": "planar_tolerance",
    "mesh_unit": "the mesh's own unit (QuadMesh.unit; use mesh.with_unit(...))",
}

_PLANAR_RGB = (0.62, 0.80, 0.95)  # light blue
_BILINEAR_LOW_RGB = (1.00, 0.85, 0.20)  # yellow: just above the tolerance
_BILINEAR_HIGH_RGB = (0.85, 0.10, 0.10)  # red: the mesh's least planar panel



def _refuse_renamed(removed: dict[str, Any], where: str) -> None:
    """Raise InputError for an old keyword (saying its new name) or an unknown one."""
    for key in removed:
        if key in _RENAMED:
            raise InputError(f"{where}: {key!r} was renamed; use {_RENAMED[key]}")
        raise InputError(f"{where}: unexpected keyword argument {key!r}")


@dataclass(frozen=True)
class StepReport:
    """What a STEP export did.

    Attributes
    ----------
    mode : str
    unit : str
        The unit the file declares (the mesh's).
    planar_tolerance : float or str
        As given (relative number, or a length such as ``"2 mm"``).
    n_panels, n_planar, n_bilinear : int
        Faces written, plane faces, bilinear patches (``n_planar + n_bilinear ==
        n_panels``).
    fallback : tuple of int
        Planar panels OCCT refused as plane faces, written as bilinear patches.
    max_corner_move : float
        The largest distance any corner was moved (flattening planar panels), in
        ``unit``; at most half the tolerance.
    n_shared_edges : int
        Edges shared by two faces in the built shape (0 unless ``mode="shell"``).
    n_free_edges : int
        Edges of one face only (in shell mode: the mesh's boundary edges).
    """

    mode: str
    unit: str
    planar_tolerance: float | str
    n_panels: int
    n_planar: int
    n_bilinear: int
    fallback: tuple[int, ...]
    max_corner_move: float
    n_shared_edges: int
    n_free_edges: int

    def to_dict(self) -> dict[str, Any]:
        """Plain data (JSON-ready).

        Examples
        --------
        >>> from quadnodes.mesh import grid
        >>> step_panels(grid(2, 3))[1].to_dict()["n_planar"]
        2
        """
        d = asdict(self)
        d["fallback"] = list(self.fallback)
        return d


def _panel_error(k: int, label: str, kind: str, why: str) -> ExportError:
    return ExportError(f"panel {k} ({label}): cannot build the {kind} face: {why}")


def _topology(mesh: QuadMesh, planar: np.ndarray, mode: str) -> tuple[Any, list[Any]]:
    """The OCCT shape of the panels and its faces in mesh order (see :mod:`quadnodes.io._brep`).

    ``shell``: the mesh's own vertices and edges, shared by the panels, one shell per connected
    piece; the plane of a planar panel passes within half its diagonal distance of its corners
    and the shared edges and vertices carry that distance as their tolerance. Otherwise every
    panel has its own four vertices and edges, a planar panel's corners projected onto its plane.
    """
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    from ._brep import panel_topology

    p = mesh.vertices[mesh.faces]  # (m, 4, 3)
    m = mesh.n_faces
    normal = np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 1])
    nlen = np.linalg.norm(normal, axis=1)
    unit_n = normal / np.where(nlen > 0, nlen, 1.0)[:, None]
    centroid = p.mean(axis=1)
    xdir = p[:, 1] - p[:, 0]
    xdir -= np.einsum("fj,fj->f", xdir, unit_n)[:, None] * unit_n
    xlen = np.linalg.norm(xdir, axis=1)
    xdir /= np.where(xlen > 0, xlen, 1.0)[:, None]
    if mode == "shell":
        topo = mesh.topology
        twin = topo.he_twin
        inner = np.flatnonzero(twin >= 0)
        adjacent = csr_matrix((np.ones(inner.size), (inner // 4, twin[inner] // 4)), shape=(m, m))
        _, piece = connected_components(adjacent, directed=False)
        return panel_topology(mesh.vertices, mesh.faces, planar, centroid, unit_n, xdir, topo.edges,
                              topo.he_edge.reshape(m, 4), piece)
    # planar panels: corners onto the mid-plane of the diagonals (each moves half the diagonal distance)
    height = np.einsum("fkj,fj->fk", p - centroid[:, None, :], unit_n)
    corners = np.where(planar[:, None, None], p - height[:, :, None] * unit_n[:, None, :], p)
    quads = np.arange(4 * m).reshape(m, 4)
    nxt = np.roll(quads, -1, axis=1)
    edges = np.stack([np.minimum(quads, nxt), np.maximum(quads, nxt)], axis=2).reshape(-1, 2)
    return panel_topology(corners.reshape(-1, 3), quads, planar, centroid, unit_n, xdir, edges, quads, None)


def _build_faces(
    mesh: QuadMesh, planar: np.ndarray, labels: list[str], mode: str, *, check: bool
) -> tuple[Any, list[Any], list[int]]:
    """The shape, one ``TopoDS_Face`` per quad, and the planar panels that fell back to bilinear."""
    try:
        shape, faces = _topology(mesh, planar, mode)
    except Exception as exc:  # OCCT's Standard_Failure family arrives as Python exceptions
        raise ExportError(f"cannot build the {mesh.n_faces} panels: {type(exc).__name__}: {exc}") from exc
    fallback: list[int] = []
    if check:
        from OCP.BRepCheck import BRepCheck_Analyzer

        bad = [k for k, f in enumerate(faces) if not BRepCheck_Analyzer(f).IsValid()]
        fallback = [k for k in bad if planar[k]]
        if len(fallback) < len(bad):
            k = next(k for k in bad if not planar[k])
            raise _panel_error(k, labels[k], "bilinear", "OCCT reports the face invalid")
        if fallback:  # the refused plane faces as bilinear patches, the rest unchanged
            planar = planar.copy()
            planar[fallback] = False
            shape, faces = _topology(mesh, planar, mode)
            for k in fallback:
                if not BRepCheck_Analyzer(faces[k]).IsValid():
                    raise _panel_error(k, labels[k], "bilinear", "OCCT reports the face invalid")
    return shape, faces, fallback


def _colors(mesh: QuadMesh, planar: np.ndarray) -> list[tuple[float, float, float]]:
    """Planar panels light blue; bilinear ones from yellow to red by log diagonal distance."""
    dev = np.maximum(diagonal_distance(mesh), 1e-300)
    out = np.tile(np.array(_PLANAR_RGB), (mesh.n_faces, 1))
    bil = ~planar
    if bil.any():
        d = dev[bil]
        most_planar = dev[planar].max() if planar.any() else d.min()
        lo = np.log10(max(float(most_planar), float(d.min())))
        hi = np.log10(float(d.max()))
        t = np.clip((np.log10(d) - lo) / (hi - lo), 0.0, 1.0) if hi > lo else np.ones(d.size)
        out[bil] = (1 - t)[:, None] * _BILINEAR_LOW_RGB + t[:, None] * np.array(_BILINEAR_HIGH_RGB)
    return [tuple(row) for row in out.tolist()]


@dataclass
class _Built:
    """What the writer needs: the top OCP shape, the faces in mesh order, labels, colours."""

    shape: Any  # build123d shape
    faces: list[Any]  # TopoDS_Face per panel, as they appear in ``shape``
    labels: list[str]
    rgb: list[tuple[float, float, float]] | None
    mode: str
    name: str
    pcurves: bool = False  # also write every edge's curve on each of its faces


def step_panels(
    mesh: QuadMesh,
    *,
    mode: Literal["compound", "shell", "assembly"] = "compound",
    planar_tolerance: float | str = DEFAULT_PLANAR_TOLERANCE,
    colors: bool = False,
    name: str = "panels",
    check: bool = False,
    **renamed: Any,
) -> tuple[Shape, StepReport]:
    """Build the panels of ``mesh`` as a build123d shape, and report what was built.

    See the module documentation for the planar/bilinear rule, the modes and
    the units.

    Parameters
    ----------
    mesh : QuadMesh
        ``m`` quads; one face per quad, in face order.
    mode : {"compound", "shell", "assembly"}
        Compound of faces, sewn shell(s) with named faces, or an assembly of
        labelled panels.
    planar_tolerance : float or str
        A number: the largest relative diagonal distance of a panel written as a
        plane (default ``1e-3``); text such as ``"2 mm"``: the largest diagonal
        distance as a length. See :func:`quadnodes.flatness.planar_panels`.
    colors : bool
        Colour the panels by planarity (shell and assembly modes): planar light
        blue, bilinear from yellow (the least twisted) to red (the most), on a
        log scale of the diagonal distance.
    name : str
        Label of the top-level shape (the STEP product / header name).
    check : bool
        Also run ``BRepCheck_Analyzer`` on every face (about 0.3 ms per panel on
        a quiet machine, a few times the whole build) and fall back to the bilinear
        patch for a plane face it rejects. Off by default: a plane face on
        projected corners of a simple polygon and the bilinear patch of a
        non-degenerate quad are valid by construction (the tests check every
        face with ``BRepCheck``).

    Returns
    -------
    shape : build123d.Compound or build123d.Shell
        ``compound``: a Compound of ``m`` faces. ``shell``: a Shell, or a
        Compound of Shells for a mesh in several pieces. ``assembly``: a Compound
        labelled ``name`` whose ``children`` are ``m`` labelled Faces.
    report : StepReport

    Raises
    ------
    InputError
        On an unknown ``mode``, a bad ``planar_tolerance``, ``colors`` in
        compound mode, or an old keyword (``planar_tol``, ``mesh_unit``; the
        message gives the new name).
    ExportError
        On a degenerate panel (zero-length edge or zero area; the message names
        it), or when OCCT cannot build the panels.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> asm, report = step_panels(grid(2, 3, height=[[0, 0, 0], [0, 0, 1]]), mode="assembly")
    >>> [(f.label, f.geom_type.name) for f in asm.children]
    [('P_0_0', 'PLANE'), ('P_0_1', 'BEZIER')]
    >>> report.n_planar, report.n_bilinear, report.max_corner_move
    (1, 1, 0.0)
    """
    built, report = _build(mesh, mode=mode, planar_tolerance=planar_tolerance, colors=colors, name=name,
                           check=check, renamed=renamed, where="step_panels")
    return built.shape, report


def _build(
    mesh: QuadMesh, *, mode: str, planar_tolerance: float | str, colors: bool, name: str, check: bool,
    renamed: dict[str, Any], where: str,
) -> tuple[_Built, StepReport]:
    _refuse_renamed(renamed, where)
    _validate.quad_mesh(mesh)
    mode = _validate.choice(mode, STEP_MODES, "mode")
    if mesh.unit not in _UNITS:
        raise ExportError(f"unit: STEP cannot declare the mesh's unit {mesh.unit!r}; STEP units: {', '.join(_UNITS)}")
    planar = planar_panels(mesh, planar_tolerance)  # checks planar_tolerance
    if colors and mode == "compound":
        raise InputError("colors: panel colours are written in mode='shell' or 'assembly', got mode='compound'")
    if not isinstance(name, str) or not name:
        raise InputError(f"name: expected a non-empty string, got {name!r}")
    from build123d import Color, Compound, Face, Shell
    from OCP.TopAbs import TopAbs_SHELL
    from OCP.TopoDS import TopoDS

    labels = panel_labels(mesh)
    check_panels(mesh, planar_tolerance, "step")
    report_progress(0.1, f"building panels ({mesh.n_faces}, {mode})")
    top, topo_faces, fallback = _build_faces(mesh, planar, labels, mode, check=check)
    is_plane = planar.copy()
    is_plane[fallback] = False
    moves = corner_moves(mesh, is_plane)
    max_move = float(moves.max()) if moves.size else 0.0
    rgb = _colors(mesh, is_plane) if colors else None

    report_progress(0.7, f"assembling {mesh.n_faces} panels ({mode})")
    shape: Any
    if mode == "assembly":
        children = [
            Face(f, label=labels[k], color=Color(*rgb[k]) if rgb is not None else None)
            for k, f in enumerate(topo_faces)
        ]
        shape = Compound(children=children, label=name)
    elif mode == "compound":
        shape = Compound(TopoDS.Compound(top), label=name)
    elif top.ShapeType() == TopAbs_SHELL:
        shape = Shell(TopoDS.Shell(top), label=name)
    else:  # a mesh in several pieces: a compound of shells
        shape = Compound(TopoDS.Compound(top), label=name)
    if mode == "shell":  # the mesh's edges, each one edge of the shell
        per_edge = mesh.topology.edge_face_count
        shared, free = int((per_edge == 2).sum()), int((per_edge == 1).sum())
    else:  # every panel its own four edges
        shared, free = 0, 4 * mesh.n_faces
    report = StepReport(
        mode=mode, unit=mesh.unit, planar_tolerance=planar_tolerance, n_panels=mesh.n_faces,
        n_planar=int(is_plane.sum()), n_bilinear=int(mesh.n_faces - is_plane.sum()), fallback=tuple(fallback),
        max_corner_move=max_move, n_shared_edges=shared, n_free_edges=free,
    )
    return _Built(shape, topo_faces, labels, rgb, mode, name), report


def step_shape(
    mesh: QuadMesh,
    *,
    mode: Literal["compound", "shell", "assembly"] = "compound",
    planar_tolerance: float | str = DEFAULT_PLANAR_TOLERANCE,
    colors: bool = False,
    name: str = "panels",
    check: bool = False,
    **renamed: Any,
) -> Shape:
    """The shape of :func:`step_panels` without its report.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> len(step_shape(grid(3, 3), mode="shell").faces())
    4
    """
    built, _ = _build(mesh, mode=mode, planar_tolerance=planar_tolerance, colors=colors, name=name,
                      check=check, renamed=renamed, where="step_shape")
    return built.shape


def _write_named_shell(built: _Built, path: str, metres: float) -> None:
    """Write a shell with every face named (XCAF sub-shape labels) and optionally coloured."""
    from OCP.IFSelect import IFSelect_ReturnStatus
    from OCP.Interface import Interface_Static
    from OCP.Quantity import Quantity_Color, Quantity_TypeOfColor
    from OCP.STEPCAFControl import STEPCAFControl_Controller, STEPCAFControl_Writer
    from OCP.STEPControl import STEPControl_StepModelType
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDataStd import TDataStd_Name
    from OCP.TDocStd import TDocStd_Document
    from OCP.XCAFApp import XCAFApp_Application
    from OCP.XCAFDoc import XCAFDoc_ColorType, XCAFDoc_DocumentTool

    doc = TDocStd_Document(TCollection_ExtendedString("XmlOcaf"))
    app = XCAFApp_Application.GetApplication_s()
    app.NewDocument(TCollection_ExtendedString("MDTV-XCAF"), doc)
    app.InitDocument(doc)
    XCAFDoc_DocumentTool.SetLengthUnit_s(doc, metres)
    shapes = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    colours = XCAFDoc_DocumentTool.ColorTool_s(doc.Main())
    top = shapes.AddShape(built.shape.wrapped, False, False)
    TDataStd_Name.Set_s(top, TCollection_ExtendedString(built.name))
    for k, face in enumerate(built.faces):
        sub = shapes.AddSubShape(top, face)
        if sub.IsNull():
            raise ExportError(f"panel {k} ({built.labels[k]}): its face is not part of the shell")
        TDataStd_Name.Set_s(sub, TCollection_ExtendedString(built.labels[k]))
        if built.rgb is not None:
            colours.SetColor(sub, Quantity_Color(*built.rgb[k], Quantity_TypeOfColor.Quantity_TOC_sRGB),
                             XCAFDoc_ColorType.XCAFDoc_ColorSurf)
    STEPCAFControl_Controller.Init_s()
    previous = {key: Interface_Static.IVal_s(key) for key in ("write.stepcaf.subshapes.name", "write.surfacecurve.mode")}
    Interface_Static.SetIVal_s("write.stepcaf.subshapes.name", 1)
    Interface_Static.SetIVal_s("write.surfacecurve.mode", int(built.pcurves))
    try:
        writer = STEPCAFControl_Writer()
        writer.SetNameMode(True)
        writer.SetColorMode(True)
        if not writer.Transfer(doc, STEPControl_StepModelType.STEPControl_AsIs):
            raise ExportError("OCCT could not transfer the shell to STEP")
        if writer.Write(path) != IFSelect_ReturnStatus.IFSelect_RetDone:
            raise ExportError("OCCT failed to write the STEP file")
    finally:
        for key, value in previous.items():
            Interface_Static.SetIVal_s(key, value)


def _write_step(built: _Built, path: str, unit: str) -> None:
    """Write ``built`` to ``path`` declaring ``unit``, coordinates unscaled."""
    from build123d import Unit, export_step
    from OCP.Interface import Interface_Static
    from OCP.Message import Message, Message_Gravity
    from OCP.STEPControl import STEPControl_Controller

    metres, step_unit = _UNITS[unit]
    STEPControl_Controller.Init_s()  # registers the "write.step.*" parameters
    for printer in Message.DefaultMessenger_s().Printers():  # no transfer statistics on the console
        printer.SetTraceLevel(Message_Gravity.Message_Fail)
    # build123d scales from the document unit to OCCT's (process-global) write
    # unit; making both the mesh unit writes the numbers as they are.
    previous = Interface_Static.CVal_s("write.step.unit")
    Interface_Static.SetCVal_s("write.step.unit", step_unit)
    try:
        if built.mode == "shell":
            _write_named_shell(built, path, metres)
        else:
            b123d_unit = {"mm": "MM", "cm": "CM", "m": "M", "in": "IN", "ft": "FT"}[unit]
            export_step(built.shape, path, unit=Unit[b123d_unit], write_pcurves=built.pcurves)
    finally:
        Interface_Static.SetCVal_s("write.step.unit", previous or "MM")


def write_step(
    mesh: QuadMesh,
    path: str | os.PathLike[str],
    *,
    mode: Literal["compound", "shell", "assembly"] = "compound",
    planar_tolerance: float | str = DEFAULT_PLANAR_TOLERANCE,
    colors: bool = False,
    name: str = "panels",
    check: bool = False,
    pcurves: bool = False,
    **renamed: Any,
) -> tuple[Path, StepReport]:
    """:func:`save_step`, also returning the :class:`StepReport`.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from quadnodes.mesh import grid
    >>> m = grid(2, 2, spacing=1000.0, height=[[0, 0], [0, 0.4]])  # 0.4 mm out of plane
    >>> path, report = write_step(m, pathlib.Path(tempfile.mkdtemp()) / "p.step", planar_tolerance="1 mm")
    >>> report.n_planar, round(report.max_corner_move, 6)
    (1, 0.1)
    """
    pcurves = _validate.flag(pcurves, "pcurves")
    built, report = _build(mesh, mode=mode, planar_tolerance=planar_tolerance, colors=colors, name=name,
                           check=check, renamed=renamed, where="save_step")
    built.pcurves = pcurves
    report_progress(0.8, f"writing {mesh.n_faces} panels to STEP")
    out = write_atomic(path, lambda tmp: _write_step(built, tmp, mesh.unit))
    report_progress(1.0, f"wrote {out.name}")
    return out, report


def save_step(
    mesh: QuadMesh,
    path: str | os.PathLike[str],
    *,
    mode: Literal["compound", "shell", "assembly"] = "compound",
    planar_tolerance: float | str = DEFAULT_PLANAR_TOLERANCE,
    colors: bool = False,
    name: str = "panels",
    check: bool = False,
    pcurves: bool = False,
    **renamed: Any,
) -> Path:
    """Write the panels of ``mesh`` to a STEP file, atomically.

    Builds the shape as :func:`step_panels` (same ``mode``,
    ``planar_tolerance``, ``colors``, ``name``, ``check``), then writes it to a
    temporary file in the target folder and renames it over ``path``. The file
    declares the mesh's unit (``mesh.unit``) and holds the coordinates unscaled.
    :func:`write_step` does the same and also returns the :class:`StepReport`.

    Parameters
    ----------
    mesh : QuadMesh
    path : str or path-like
        Target file, usually ``*.step`` or ``*.stp``.
    pcurves : bool
        Also write every edge's curve on each of its faces (OCCT's default; off
        here: the edges are straight lines that every reader projects exactly,
        and the file is 2.5 times smaller and written faster).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        On an unknown ``mode``, a bad ``planar_tolerance``, ``pcurves`` not a
        bool, or an old keyword (``planar_tol``, ``mesh_unit``), before anything
        is built.
    ExportError
        On a degenerate panel (naming its face index and label), a unit STEP
        cannot declare, an OCCT failure while writing, or an unwritable path;
        no partial or temporary file is left, and an existing file at ``path``
        is unchanged.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from quadnodes.mesh import grid
    >>> out = save_step(grid(3, 3), pathlib.Path(tempfile.mkdtemp()) / "p.step", mode="shell")
    >>> out.read_text().startswith("ISO-10303-21;")
    True
    """
    return write_step(mesh, path, mode=mode, planar_tolerance=planar_tolerance, colors=colors, name=name,
                      check=check, pcurves=pcurves, **renamed)[0]
