"""STEP export: every quad becomes a panel face, planar or an exact bilinear patch.

Planar or bilinear
------------------
A panel whose relative diagonal distance (:func:`quadnodes.flatness.diagonal_distance`)
is at most ``planar_tol`` (default ``1e-6``) is written as a **plane** face
bounded by its four straight edges; every other panel as the **bilinear patch**
through its four corners, a degree-(1, 1) ``Geom_BezierSurface`` with poles
``[[p0, p3], [p1, p2]]`` (``u`` runs from ``p0`` to ``p1``, ``v`` from ``p0`` to
``p3``; the same surface as build123d's
``Face.make_bezier_surface([[p0, p3], [p1, p2]])``), so ``S_u × S_v`` points
along the quad's counter-clockwise normal and the patch's four boundary curves
are exactly the quad's straight edges. Faces are built with OCP directly
(``BRepBuilderAPI_MakePolygon`` / ``BRepBuilderAPI_MakeFace`` /
``Geom_BezierSurface``), about 0.1 ms per panel.

The plane is the mid-plane of the two diagonal lines: through the centroid,
normal to ``(p2 - p0) × (p3 - p1)``; every corner lies at half the diagonal
distance from it. OCCT's own route (``BRepBuilderAPI_MakeFace(wire,
OnlyPlane=True)``, i.e. ``Face(Wire.make_polygon(..., close=True))`` in
build123d) accepts a polygon only when its *absolute* diagonal distance is
below about ``1e-6`` model units (measured with OCCT 8.0.1: between 6e-7 and
1e-6, whatever the panel size), so a 1 m panel in millimetres that is planar to a
relative ``1e-6`` (0.001 mm) would be refused. The exporter therefore builds the
face on the fitted plane itself, keeps the corners exactly where the mesh puts
them, and widens the edge and vertex tolerances to the corners' distance from the
plane (``BRepLib.SameParameter``) so that the face is valid
(``BRepCheck_Analyzer``). The panel schedule (:mod:`quadnodes.io.schedule`)
uses the same test, so its ``kind`` column matches the STEP file.

Modes
-----
``"compound"``
    One compound of independent faces (fastest, neighbours share no edges).
``"shell"``
    Faces sewn along shared edges with ``BRepBuilderAPI_Sewing``: one shell per
    connected piece of the mesh (a compound of shells when there are several).
``"assembly"``
    An assembly whose children are the panels, each named ``P_<row>_<col>`` (row
    and column of the face's grid cell, when the mesh has a ``grid_shape``) or
    ``P_<face index>``, optionally coloured by planarity. Only this form keeps
    the panel labels through STEP (they are written as product names).

Units
-----
``mesh_unit`` declares the unit of the mesh coordinates (default ``"mm"``, like
build123d's ``Unit.MM``). The coordinates are written **unchanged** and the file
declares that unit (``SI_UNIT(.MILLI.,.METRE.)``, ``SI_UNIT($,.METRE.)``, …), so
no value is rescaled and rounded; a unit-aware reader converts. For example a
mesh in metres, read back with ``build123d.import_step`` (which works in
millimetres), comes back 1000 times larger, as it should. OCCT writes real
numbers with 12 significant digits, so coordinates round-trip to a relative
``1e-12``, not bit for bit (use OBJ or JSON for exact coordinates).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from .. import _validate
from ..progress import report_progress
from ..errors import ExportError, InputError
from ..mesh import QuadMesh
from ..flatness import diagonal_distance
from ._atomic import write_atomic
from .panels import DEFAULT_PLANAR_TOL, panel_labels

if TYPE_CHECKING:
    from build123d import Shape

__all__ = ["STEP_MODES", "STEP_UNITS", "step_shape", "save_step"]

STEP_MODES: tuple[str, ...] = ("compound", "shell", "assembly")
"""The values of ``mode``."""

# mesh_unit -> (build123d Unit member name, OCCT "write.step.unit" value)
_UNITS: dict[str, tuple[str, str]] = {
    "um": ("MC", "UM"),
    "mm": ("MM", "MM"),
    "cm": ("CM", "CM"),
    "m": ("M", "M"),
    "in": ("IN", "INCH"),
    "ft": ("FT", "FT"),
}
STEP_UNITS: tuple[str, ...] = tuple(_UNITS)
"""The values of ``mesh_unit``."""

_PLANAR_RGB = (0.62, 0.80, 0.95)  # light blue
_BILINEAR_LOW_RGB = (1.00, 0.85, 0.20)  # yellow: just above the tolerance
_BILINEAR_HIGH_RGB = (0.85, 0.10, 0.10)  # red: the mesh's least planar panel

_OCC_CONFUSION = 1e-7  # OCCT Precision::Confusion(), the default edge tolerance


def _panel_error(k: int, label: str, kind: str, why: str) -> ExportError:
    return ExportError(f"panel {k} ({label}): cannot build the {kind} face: {why}")


def _build_faces(
    mesh: QuadMesh, planar: np.ndarray, labels: list[str], *, check: bool
) -> list[Any]:
    """One ``TopoDS_Face`` per quad, built with OCP directly (no build123d wrappers)."""
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace, BRepBuilderAPI_MakePolygon
    from OCP.BRepCheck import BRepCheck_Analyzer
    from OCP.BRepLib import BRepLib
    from OCP.collections import HArray2_gp_Pnt
    from OCP.Geom import Geom_BezierSurface
    from OCP.gp import gp_Dir, gp_Pln, gp_Pnt

    p = mesh.vertices[mesh.faces]  # (m, 4, 3)
    normal = np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 1])
    nlen = np.linalg.norm(normal, axis=1)
    centroid = p.mean(axis=1)
    half_gap = 0.5 * diagonal_distance(mesh, relative=False)
    corners = p.tolist()
    normal_l = normal.tolist()
    centroid_l = centroid.tolist()
    faces: list[Any] = []
    every = max(1, mesh.n_faces // 20)
    for k in range(mesh.n_faces):
        if k % every == 0:
            report_progress(0.8 * k / mesh.n_faces, f"building panel {k}/{mesh.n_faces}")
        c = corners[k]
        is_planar = bool(planar[k])
        kind = "planar" if is_planar else "bilinear"
        try:
            p0, p1, p2, p3 = (gp_Pnt(*q) for q in c)
            if is_planar:
                if not nlen[k] > 0.0:
                    raise _panel_error(k, labels[k], kind, "its diagonals are parallel (degenerate quad)")
                plane = gp_Pln(gp_Pnt(*centroid_l[k]), gp_Dir(*normal_l[k]))
                poly = BRepBuilderAPI_MakePolygon(p0, p1, p2, p3, True)
                if not poly.IsDone():
                    raise _panel_error(k, labels[k], kind, f"polygon error {poly.Error()}")
                maker = BRepBuilderAPI_MakeFace(plane, poly.Wire(), True)
                if not maker.IsDone():
                    raise _panel_error(k, labels[k], kind, f"face error {maker.Error()}")
                face = maker.Face()
                if half_gap[k] > _OCC_CONFUSION:
                    # corners off the fitted plane by up to half_gap: widen tolerances
                    BRepLib.SameParameter_s(face, _OCC_CONFUSION, True)
            else:
                poles = HArray2_gp_Pnt(1, 2, 1, 2)
                poles.SetValue(1, 1, p0)
                poles.SetValue(2, 1, p1)
                poles.SetValue(2, 2, p2)
                poles.SetValue(1, 2, p3)
                maker = BRepBuilderAPI_MakeFace(Geom_BezierSurface(poles), _OCC_CONFUSION)
                if not maker.IsDone():
                    raise _panel_error(k, labels[k], kind, f"face error {maker.Error()}")
                face = maker.Face()
            if check and not BRepCheck_Analyzer(face).IsValid():
                raise _panel_error(
                    k, labels[k], kind,
                    "OCCT reports the face invalid (self-intersecting or degenerate quad?)",
                )
        except ExportError:
            raise
        except Exception as exc:  # OCCT's Standard_Failure family arrives as Python exceptions
            raise _panel_error(k, labels[k], kind, f"{type(exc).__name__}: {exc}") from exc
        faces.append(face)
    return faces


def _colors(mesh: QuadMesh, planar: np.ndarray, planar_tol: float) -> list[tuple[float, float, float]]:
    """Planar panels light blue; bilinear ones from yellow to red by log diagonal distance."""
    dev = diagonal_distance(mesh)
    out = np.tile(np.array(_PLANAR_RGB), (mesh.n_faces, 1))
    bil = ~planar
    if bil.any():
        d = dev[bil]
        lo = np.log10(max(planar_tol, float(d.min())))
        hi = np.log10(float(d.max()))
        t = np.clip((np.log10(d) - lo) / (hi - lo), 0.0, 1.0) if hi > lo else np.ones(d.size)
        out[bil] = (1 - t)[:, None] * _BILINEAR_LOW_RGB + t[:, None] * np.array(_BILINEAR_HIGH_RGB)
    return [tuple(row) for row in out.tolist()]


def step_shape(
    mesh: QuadMesh,
    *,
    mode: Literal["compound", "shell", "assembly"] = "compound",
    planar_tol: float = DEFAULT_PLANAR_TOL,
    colors: bool = False,
    name: str = "panels",
    check: bool = True,
) -> Shape:
    """Build the panels of ``mesh`` as a build123d shape, ready for STEP.

    See the module documentation for the planar/bilinear rule, the modes and
    the units.

    Parameters
    ----------
    mesh : QuadMesh
        ``m`` quads; one face per quad, in face order.
    mode : {"compound", "shell", "assembly"}
        Compound of faces, sewn shell(s), or an assembly of labelled panels.
    planar_tol : float
        Largest relative diagonal distance of a panel written as a plane
        (default ``1e-6``); see :func:`quadnodes.io.panels.planar_mask`.
    colors : bool
        Colour the panels by planarity (assembly mode only): planar light blue,
        bilinear from yellow (just above ``planar_tol``) to red (the least
        planar panel), on a log scale of the diagonal distance.
    name : str
        Label of the top-level shape (the STEP product / header name).
    check : bool
        Run ``BRepCheck_Analyzer`` on every face (about 0.2 ms per panel) and
        fail on an invalid one, e.g. a self-intersecting planar quad.

    Returns
    -------
    build123d.Compound or build123d.Shell
        ``compound``: a Compound of ``m`` faces. ``shell``: a Shell, or a
        Compound of Shells for a mesh in several pieces. ``assembly``: a Compound
        labelled ``name`` whose ``children`` are ``m`` labelled Faces.

    Raises
    ------
    InputError
        On an unknown ``mode``, a negative ``planar_tol``, or ``colors`` outside
        assembly mode.
    ExportError
        When OCCT cannot build a panel (the message names its face index and
        label) or sewing loses faces.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> m = grid(2, 3, height=[[0, 0, 0], [0, 0, 1]])
    >>> asm = step_shape(m, mode="assembly")
    >>> [(f.label, f.geom_type.name) for f in asm.children]
    [('P_0_0', 'PLANE'), ('P_0_1', 'BEZIER')]
    """
    _validate.quad_mesh(mesh)
    mode = _validate.choice(mode, STEP_MODES, "mode")  # type: ignore[assignment]
    tol = _validate.nonnegative_number(planar_tol, "planar_tol")
    if colors and mode != "assembly":
        raise InputError(f"colors: panel colours are written in mode='assembly' only, got mode={mode!r}")
    from build123d import Color, Compound, Face, Shell

    dev = diagonal_distance(mesh)
    planar = dev <= tol
    labels = panel_labels(mesh)
    topo_faces = _build_faces(mesh, planar, labels, check=check)

    if mode == "assembly":
        rgb = _colors(mesh, planar, tol) if colors else None
        children = [
            Face(f, label=labels[k], color=Color(*rgb[k]) if rgb is not None else None)
            for k, f in enumerate(topo_faces)
        ]
        return Compound(children=children, label=name)

    from OCP.BRep import BRep_Builder
    from OCP.TopoDS import TopoDS_Compound

    if mode == "compound":
        comp = TopoDS_Compound()
        builder = BRep_Builder()
        builder.MakeCompound(comp)
        for f in topo_faces:
            builder.Add(comp, f)
        return Compound(comp, label=name)

    # shell
    from OCP.BRepBuilderAPI import BRepBuilderAPI_Sewing
    from OCP.TopAbs import TopAbs_FACE, TopAbs_SHELL
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    # The corners of neighbouring panels are bit-identical, so a tolerance far
    # below the panel size only has to absorb the widened tolerances of
    # nearly-planar faces.
    sew_tol = max(_OCC_CONFUSION, 1e-6 * mesh.mean_edge_length)
    sewing = BRepBuilderAPI_Sewing(sew_tol)
    for f in topo_faces:
        sewing.Add(f)
    sewing.Perform()
    sewn = sewing.SewedShape()
    n_sewn = 0
    explorer = TopExp_Explorer(sewn, TopAbs_FACE)
    while explorer.More():
        n_sewn += 1
        explorer.Next()
    if n_sewn != mesh.n_faces or sewing.NbMultipleEdges() != 0:
        raise ExportError(
            f"sewing {mesh.n_faces} panels gave {n_sewn} faces and "
            f"{sewing.NbMultipleEdges()} edges shared by more than two faces"
        )
    if sewn.ShapeType() == TopAbs_SHELL:
        return Shell(TopoDS.Shell(sewn), label=name)
    if sewn.ShapeType() == TopAbs_FACE:  # a one-panel mesh
        return Shell(Face(TopoDS.Face(sewn)), label=name)
    return Compound(TopoDS.Compound(sewn), label=name)


def _write_step(shape: Shape, path: str, mesh_unit: str) -> None:
    """Write ``shape`` to ``path`` declaring ``mesh_unit``, coordinates unscaled."""
    from build123d import Unit, export_step
    from OCP.Interface import Interface_Static
    from OCP.STEPControl import STEPControl_Controller

    unit_name, step_unit = _UNITS[mesh_unit]
    STEPControl_Controller.Init_s()  # registers the "write.step.*" parameters
    # build123d scales from the document unit to OCCT's (process-global) write
    # unit; making both the mesh unit writes the numbers as they are.
    previous = Interface_Static.CVal_s("write.step.unit")
    Interface_Static.SetCVal_s("write.step.unit", step_unit)
    try:
        export_step(shape, path, unit=Unit[unit_name])
    finally:
        Interface_Static.SetCVal_s("write.step.unit", previous or "MM")


def save_step(
    mesh: QuadMesh,
    path: str | os.PathLike[str],
    *,
    mode: Literal["compound", "shell", "assembly"] = "compound",
    planar_tol: float = DEFAULT_PLANAR_TOL,
    mesh_unit: str = "mm",
    colors: bool = False,
    name: str = "panels",
    check: bool = True,
) -> Path:
    """Write the panels of ``mesh`` to a STEP file, atomically.

    Builds the shape with :func:`step_shape` (same ``mode``, ``planar_tol``,
    ``colors``, ``name``, ``check``), then writes it to a temporary file in the
    target folder and renames it over ``path``.

    Parameters
    ----------
    mesh : QuadMesh
    path : str or path-like
        Target file, usually ``*.step`` or ``*.stp``.
    mesh_unit : {"um", "mm", "cm", "m", "in", "ft"}
        Unit of the mesh coordinates (default ``"mm"``). The file declares this
        unit and holds the coordinates unscaled.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        On an unknown ``mode`` or ``mesh_unit`` (before anything is built).
    ExportError
        When a panel cannot be built (naming its face index and label), OCCT
        fails to write, or the path is not writable; no partial or temporary
        file is left, and an existing file at ``path`` is unchanged.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from quadnodes.mesh import grid
    >>> out = save_step(grid(3, 3), pathlib.Path(tempfile.mkdtemp()) / "p.step", mode="shell")
    >>> out.read_text().startswith("ISO-10303-21;")
    True
    """
    unit = _validate.choice(mesh_unit, STEP_UNITS, "mesh_unit")
    shape = step_shape(mesh, mode=mode, planar_tol=planar_tol, colors=colors, name=name, check=check)
    report_progress(0.8, f"writing {mesh.n_faces} panels to STEP")
    out = write_atomic(path, lambda tmp: _write_step(shape, tmp, unit))
    report_progress(1.0, f"wrote {out.name}")
    return out
