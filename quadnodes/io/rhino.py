"""Rhino .3dm files (rhino3dm): panels as named surfaces with user text, and quad meshes in and out.

:func:`save_3dm` writes, in the mesh's unit (the file's model unit system):

- layer ``mesh``: the quad mesh as one Rhino mesh, quads kept, double-precision vertices;
- layers ``panels::planar`` and ``panels::bilinear``: every panel as a surface named by its
  label (``P_<row>_<col>`` on a grid, else ``P_<face>``): the degree-1 NURBS surface through its four
  corners (the bilinear patch; a planar panel's surface is flat within the planar tolerance,
  because its corners are), with user text (Rhino's Attribute User Text) ``id`` (the label),
  ``row``, ``col`` (only on a grid), ``planarity`` (relative diagonal distance),
  ``planarity_<unit>`` (the same as a length), ``area_<unit>2``, ``edges_<unit>`` (the four edge
  lengths 01 12 23 30, space-separated) and ``planar`` (``yes``/``no``); numbers as shortest
  round-trip text;
- layer ``structure lines``: every structure line as a polyline (closed ones repeat their first point).

Which panels are planar is decided by :func:`quadnodes.flatness.planar_panels` (the same test as the
STEP exporter and the schedule). :func:`load_3dm` reads a Rhino mesh back into a :class:`QuadMesh`.

rhino3dm writes the document, the layers and the mesh; the panels' and lines' object records are, by
default (``engine="fast"``), written by :mod:`quadnodes.io._3dm_records` from records rhino3dm writes
for sentinel objects in the same call — the same file as adding every object through rhino3dm
(:func:`model_3dm`, ``engine="rhino3dm"``), about four times faster.
"""

from __future__ import annotations

import os
import warnings
from collections import deque
from pathlib import Path
from collections.abc import Iterator
from typing import Any, Literal

import numpy as np

from .. import __version__, _occt, _validate
from ..errors import ExportError, InputError
from ..flatness import diagonal_distance, planar_panels, resolve_planar_tolerance
from ..mesh import QuadMesh
from ..units import UNITS
from ._3dm_records import (LayoutError, PanelRecords, PolylineRecords, panel_records, polyline_records, random_ids,
                           write_records)
from ._atomic import write_atomic, write_bytes_atomic
from ._polygons import quads_from_blocks
from ..flatness import DEFAULT_PLANAR_TOLERANCE as DEFAULT_PLANAR_TOL
from .panels import bilinear_area, check_panels, edge_lengths, panel_labels, panel_rows_cols

__all__ = ["RHINO_UNITS", "LAYERS", "model_3dm", "save_3dm", "load_3dm", "nurbs_face", "rhino_faces"]

RHINO_UNITS: dict[str, str] = {"mm": "Millimeters", "cm": "Centimeters", "m": "Meters", "in": "Inches", "ft": "Feet"}
"""quadnodes unit -> name of Rhino's ``UnitSystem`` member."""

LAYERS: dict[str, str] = {
    "mesh": "mesh",
    "planar": "panels::planar",
    "bilinear": "panels::bilinear",
    "lines": "structure lines",
}
"""What goes on which layer (full layer paths)."""

_COLORS = {"mesh": (160, 160, 160, 255), "panels": (40, 40, 40, 255), "planar": (40, 150, 90, 255),
           "bilinear": (210, 120, 30, 255), "lines": (30, 80, 200, 255)}


def _unit_system(unit: str, what: str) -> Any:
    import rhino3dm

    name = RHINO_UNITS.get(unit)
    if name is None:
        raise ExportError(f"{what}: the mesh's unit {unit!r} has no Rhino unit system (known: {', '.join(RHINO_UNITS)})")
    return getattr(rhino3dm.UnitSystem, name)


def model_3dm(
    mesh: QuadMesh,
    *,
    planar_tolerance: float | str = DEFAULT_PLANAR_TOL,
    panels: bool = True,
    lines: bool = True,
    user_text: bool = True,
) -> Any:
    """The Rhino model of ``mesh``: a ``rhino3dm.File3dm`` (see the module docstring for its content).

    Every object is added through rhino3dm (``save_3dm(engine="rhino3dm")`` writes this model;
    the default engine writes the same file faster).

    Parameters
    ----------
    mesh : QuadMesh
    planar_tolerance : float or str
        Relative diagonal distance (a number) or a length such as ``"2 mm"`` up to which a panel
        goes on the ``panels::planar`` layer (:func:`quadnodes.flatness.planar_panels`).
    panels, lines : bool
        Write the panel surfaces / the structure lines (the mesh is always written).
    user_text : bool
        Give every panel surface its user text.

    Returns
    -------
    rhino3dm.File3dm

    Raises
    ------
    InputError
        On a bad ``planar_tolerance``.
    ExportError
        On a degenerate (zero-area) panel, naming it, or a unit Rhino cannot state.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> model = model_3dm(grid(3, 3, spacing=100.0))
    >>> len(model.Objects), str(model.Settings.ModelUnitSystem)
    (11, 'UnitSystem.Millimeters')
    """
    model, layer_index, p = _model_without_panels(mesh, planar_tolerance, lines=False, user_text=user_text)
    if panels:
        names, columns = p.texts(0, p.n)
        _add_panel_objects(model, layer_index, p.keys, p.fixed, p.corners, names, columns, None, p.flags.tolist())
    if lines:
        _add_lines(model, mesh, layer_index["lines"])
    return model


def _model_without_panels(mesh: QuadMesh, planar_tolerance: float | str, *, lines: bool,
                          user_text: bool) -> tuple[Any, dict[str, int], _Panels]:
    """The checked model with layers, the mesh (and the lines), and what the panels need."""
    import rhino3dm

    _validate.quad_mesh(mesh)
    resolve_planar_tolerance(planar_tolerance, mesh.unit)
    unit_system = _unit_system(mesh.unit, "3dm")
    check_panels(mesh, planar_tolerance, "3dm")
    planar = planar_panels(mesh, planar_tolerance)

    model = _new_model()
    model.Settings.ModelUnitSystem = unit_system
    model.ApplicationName = "quadnodes"
    model.ApplicationDetails = f"quadnodes {__version__}"
    layer_index = _add_layers(model)

    rmesh = rhino3dm.Mesh()
    verts = rmesh.Vertices
    verts.UseDoublePrecisionVertices = True
    deque(map(verts.AddPoint3d, *mesh.vertices.T.tolist()), maxlen=0)
    deque(map(rmesh.Faces.AddFace, *mesh.faces.T.tolist()), maxlen=0)
    attrs = rhino3dm.ObjectAttributes()
    attrs.Name = "quad mesh"
    attrs.LayerIndex = layer_index["mesh"]
    if mesh.grid_shape is not None:
        attrs.SetUserString("grid_shape", "%d %d" % mesh.grid_shape)
    model.Objects.AddMesh(rmesh, attrs)
    if lines:
        _add_lines(model, mesh, layer_index["lines"])
    return model, layer_index, _Panels(mesh, planar, user_text)


def _new_model() -> Any:
    import rhino3dm

    return rhino3dm.File3dm()


def _add_layers(model: Any) -> dict[str, int]:
    import rhino3dm

    def add(name: str, color: tuple[int, int, int, int], parent: Any = None) -> int:
        layer = rhino3dm.Layer()
        layer.Name = name
        layer.Color = color
        if parent is not None:
            layer.ParentLayerId = parent
        return model.Layers.Add(layer)

    out = {"mesh": add("mesh", _COLORS["mesh"])}
    panels = add("panels", _COLORS["panels"])
    pid = model.Layers.FindIndex(panels).Id
    out["planar"] = add("planar", _COLORS["planar"], pid)
    out["bilinear"] = add("bilinear", _COLORS["bilinear"], pid)
    out["lines"] = add("structure lines", _COLORS["lines"])
    return out


class _Panels:
    """What the panel objects need: corners, layer flags, user-text keys, and their texts on demand.

    ``keys`` are the user-text keys in order, ``fixed[flag]`` the values that are the same for every
    panel of a layer (``planar``); :meth:`texts` formats the labels and one column of texts per other
    key (numbers as shortest round-trip text) for a range of panels, each column in one pass.
    """

    def __init__(self, mesh: QuadMesh, planar: np.ndarray, user_text: bool) -> None:
        u = mesh.unit
        self.n = mesh.n_faces
        self.corners = mesh.vertices[mesh.faces]
        self.flags = np.asarray(planar, dtype=bool)
        self.labels = panel_labels(mesh)
        self.keys: tuple[str, ...] = ()
        self.fixed: dict[bool, dict[str, str]] = {False: {}, True: {}}
        self.numbers: list[tuple[str, np.ndarray]] = []
        if not user_text:
            return
        rc = panel_rows_cols(mesh)
        keys = ("id", "row", "col", "planarity", f"planarity_{u}", f"area_{u}2", f"edges_{u}", "planar")
        if rc is None:  # Rhino drops a key whose text is empty: no row and col without a grid
            keys = keys[:1] + keys[3:]
        else:
            self.numbers += [("%d", rc[0][:, None]), ("%d", rc[1][:, None])]
        self.keys = keys
        self.fixed = {False: {"planar": "no"}, True: {"planar": "yes"}}
        self.numbers += [("%r", diagonal_distance(mesh)[:, None]),
                         ("%r", diagonal_distance(mesh, relative=False)[:, None]),
                         ("%r", bilinear_area(mesh)[:, None]),
                         ("%r %r %r %r", edge_lengths(mesh))]

    def texts(self, start: int, stop: int) -> tuple[list[str], list[list[str]]]:
        """The labels and the text columns (every key not in ``fixed``, in key order) of panels
        ``start`` to ``stop``."""
        names = self.labels[start:stop]
        if not self.keys:
            return names, []
        m = len(names)

        def column(fmt: str, values: np.ndarray) -> list[str]:
            if m == 0:
                return []
            return ((fmt + "\0") * m % tuple(values[start:stop].ravel().tolist())).split("\0")[:-1]

        return names, [names] + [column(fmt, values) for fmt, values in self.numbers]


def _add_panel_objects(model: Any, layer_index: dict[str, int], keys: tuple[str, ...],
                       fixed: dict[bool, dict[str, str]], corners: np.ndarray, names: list[str],
                       columns: list[list[str]], ids: list[bytes] | None, flags: list[bool]) -> None:
    """Add every panel as a named degree-1 NURBS surface with its user text, through rhino3dm.

    ``corners`` (m, 4, 3); ``columns`` one text per panel for every key not in ``fixed``; ``ids``
    the object ids (``UUID.bytes_le``) or None; ``flags`` planar or not (the layer).
    """
    import uuid

    import rhino3dm

    m = len(flags)
    # the control points (0,0) (1,0) (1,1) (0,1) of panel k are its corners 0..3: points[4k : 4k + 4]
    flat = np.asarray(corners, dtype=np.float64).reshape(-1, 3)
    points = list(map(rhino3dm.Point4d, *flat.T.tolist(), [1.0] * len(flat)))
    template = rhino3dm.NurbsSurface.Create(3, False, 2, 2, 2, 2)
    for knots in (template.KnotsU, template.KnotsV):
        knots[0] = 0.0
        knots[1] = 1.0
    varying = [key for key in keys if key not in fixed[False] or key not in fixed[True]]
    # one attributes object per layer, copied by AddSurface: its fixed texts and layer set once, the
    # other keys (all set first, so every panel lists its keys in the same order) set for every panel
    by_flag = []
    for flag in (False, True):
        attrs = rhino3dm.ObjectAttributes()
        attrs.LayerIndex = layer_index["planar" if flag else "bilinear"]
        for key in keys:
            attrs.SetUserString(key, fixed[flag].get(key, "-"))
        by_flag.append(attrs)
    set_text = [a.SetUserString for a in by_flag]
    rows = list(zip(*columns)) if columns else [()] * m
    add = model.Objects.AddSurface
    put = template.Points.__setitem__
    c00, c10, c11, c01 = (0, 0), (1, 0), (1, 1), (0, 1)
    for k, flag in enumerate(flags):
        j = 4 * k
        put(c00, points[j])
        put(c10, points[j + 1])
        put(c11, points[j + 2])
        put(c01, points[j + 3])
        attrs = by_flag[flag]
        attrs.Name = names[k]
        if ids is not None:
            attrs.Id = uuid.UUID(bytes_le=ids[k])
        deque(map(set_text[flag], varying, rows[k]), maxlen=0)
        add(template, attrs)


def _line_points(mesh: QuadMesh) -> tuple[list[np.ndarray], list[str]]:
    """The points ``(n, 3)`` of every structure line (a closed one repeats its first point) and its name."""
    from ..topology import structure_lines

    lines = structure_lines(mesh)
    v = mesh.vertices
    points = [v[np.append(idx, idx[0]) if closed else idx] for idx, closed in zip(lines, lines.closed.tolist())]
    return points, [f"L_{i}" for i in range(len(points))]


def _add_lines(model: Any, mesh: QuadMesh, layer: int) -> None:
    _add_polylines(model, layer, *_line_points(mesh), None)


def _add_polylines(model: Any, layer: int, points: list[np.ndarray], names: list[str],
                   ids: list[bytes] | None) -> None:
    import uuid

    import rhino3dm

    P3 = rhino3dm.Point3d
    for k, (pts, name) in enumerate(zip(points, names)):
        attrs = rhino3dm.ObjectAttributes()
        attrs.Name = name
        attrs.LayerIndex = layer
        if ids is not None:
            attrs.Id = uuid.UUID(bytes_le=ids[k])
        model.Objects.AddPolyline(list(map(P3, *np.asarray(pts).T.tolist())), attrs)


def save_3dm(
    mesh: QuadMesh,
    path: str | os.PathLike[str],
    *,
    planar_tolerance: float | str = DEFAULT_PLANAR_TOL,
    panels: bool = True,
    lines: bool = True,
    user_text: bool = True,
    version: int = 8,
    engine: str = "fast",
) -> Path:
    """Write ``mesh`` to a Rhino .3dm file atomically (see :func:`model_3dm`).

    Parameters
    ----------
    version : int
        The .3dm version to write (Rhino 8 by default; 5, 6, 7 for older Rhinos).
    engine : {"fast", "rhino3dm"}
        ``"rhino3dm"`` adds every object through rhino3dm (:func:`model_3dm`) and lets it write
        the file. ``"fast"`` (the default) lets rhino3dm write the file without the panels and
        writes the panels' object records all at once from templates that rhino3dm writes for
        one panel of each layer in the same call (:mod:`quadnodes.io._3dm_records`): the same
        content, about four times faster for many panels. Should the installed rhino3dm lay the
        records out in a way the fast engine does not recognise, it warns and writes through
        rhino3dm.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        On a bad setting.
    ExportError
        As :func:`model_3dm`, or when the file cannot be written; nothing is left behind.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from quadnodes.mesh import grid
    >>> p = save_3dm(grid(3, 3, spacing=100.0), pathlib.Path(tempfile.mkdtemp()) / "g.3dm")
    >>> load_3dm(p).n_faces
    4
    """
    version = _validate.choice(str(version), ("5", "6", "7", "8"), "version")
    engine = _validate.choice(engine, ("fast", "rhino3dm"), "engine")
    v = int(version)
    if engine == "fast" and panels:
        model, layer_index, p = _model_without_panels(mesh, planar_tolerance, lines=False, user_text=user_text)
        try:
            templates = _templates(layer_index, p, v, path)
            line_template = _line_template(layer_index, v, path) if lines else None
        except LayoutError as exc:
            warnings.warn(f"3dm: the fast engine does not recognise rhino3dm's object records ({exc}); "
                          "writing through rhino3dm", RuntimeWarning, stacklevel=2)
            engine = "rhino3dm"
        else:
            data = _file_bytes(model, v, path)
            del model
            ids = random_ids(p.n)

            def batches() -> Iterator[bytes]:
                for a in range(0, p.n, _BATCH):
                    b = min(a + _BATCH, p.n)
                    names, columns = p.texts(a, b)
                    yield templates.records(p.flags[a:b], p.corners[a:b], names, columns, ids[a:b])
                if line_template is not None:
                    points, names = _line_points(mesh)
                    yield line_template.records(points, names, random_ids(len(points)))

            def write(tmp: str) -> None:
                with open(tmp, "wb") as f:
                    write_records(f, data, batches(), after=1)

            return write_atomic(path, write)
    model = model_3dm(mesh, planar_tolerance=planar_tolerance, panels=panels, lines=lines, user_text=user_text)
    return write_bytes_atomic(path, _file_bytes(model, v, path))


_BATCH = 20_000
"""Panels whose records are made at once (bounds the memory of a large file to about 0.2 GB)."""


def _line_template(layer_index: dict[str, int], version: int, path: str | os.PathLike[str]) -> PolylineRecords:
    """The structure-line record template, made by rhino3dm in the same way as :func:`model_3dm` adds lines."""

    def new_model() -> Any:
        m = _new_model()
        if _add_layers(m) != layer_index:
            raise LayoutError("the template's layers differ from the model's")
        return m

    def build(m: Any, points: list[np.ndarray], names: list[str], ids: list[bytes]) -> None:
        _add_polylines(m, layer_index["lines"], points, names, ids)

    return polyline_records(build, new_model, lambda m: _file_bytes(m, version, path))


def _templates(layer_index: dict[str, int], p: _Panels, version: int, path: str | os.PathLike[str]) -> PanelRecords:
    """The panel record templates, made by rhino3dm in the same way as :func:`model_3dm` adds panels."""
    keys, fixed = p.keys, p.fixed

    def new_model() -> Any:
        m = _new_model()
        if _add_layers(m) != layer_index:
            raise LayoutError("the template's layers differ from the model's")
        return m

    def build(m: Any, c: np.ndarray, n: list[str], cols: list[list[str]], ids: list[bytes], f: list[bool]) -> None:
        _add_panel_objects(m, layer_index, keys, fixed, c, n, cols, ids, f)

    return panel_records(build, new_model, lambda m: _file_bytes(m, version, path), keys, fixed)


def _file_bytes(model: Any, version: int, path: str | os.PathLike[str]) -> bytes:
    """The .3dm file of ``model`` as bytes, written by openNURBS into memory (``File3dm.Encode``).

    ``File3dm.Write`` makes the same file but flushes the C stream after every object and seeks back
    to every chunk's length field, which made it 0.6 s slower for 10,000 panels (measured; docs/cad.md).
    Unlike ``Write``, the in-memory file does not record the (temporary) file name it was written to.
    """
    import base64

    import rhino3dm

    options = rhino3dm.File3dmWriteOptions()
    options.Version = version
    text = model.Encode(options)
    data = base64.b64decode(text) if text else b""
    if not data:
        raise ExportError(f"3dm: rhino3dm could not write {str(path)!r} (File3dm.Encode gave no data)")
    return data


def _grid_shape(text: str | None, faces: np.ndarray, n: int) -> tuple[int, int] | None:
    """The ``grid_shape`` user text of a mesh written by :func:`save_3dm`, when it still fits its faces."""
    try:
        r, c = (int(t) for t in (text or "").split())
    except ValueError:
        return None
    if r >= 2 and c >= 2 and r * c == n and _validate.grid_wrap(faces, r, c) is not None:
        return r, c
    return None


def load_3dm(
    path: str | os.PathLike[str],
    *,
    non_quads: Literal["error", "drop", "split"] = "error",
    name: str | None = None,
) -> QuadMesh:
    """Read a quad mesh from a Rhino .3dm file, in the file's unit.

    Parameters
    ----------
    path : str or path-like
    non_quads : {"error", "drop", "split"}
        What to do with a triangle, as in :func:`quadnodes.io.obj.parse_obj` (Rhino mesh faces
        are triangles or quads; ``"split"`` cannot split a triangle and refuses it).
    name : str, optional
        The object name of the mesh to read when the file holds several meshes.

    Returns
    -------
    QuadMesh
        With ``unit`` from the file's model unit system (millimetres when the file states none).

    Raises
    ------
    InputError
        If the file cannot be read, holds no mesh or several (without ``name``), a unit quadnodes
        does not know, or a face that is not a quad (see ``non_quads``).
    """
    import rhino3dm

    p = Path(os.fspath(path))
    if not p.is_file():
        raise InputError(f"cannot read {str(p)!r}: {'a folder, not a file' if p.is_dir() else 'no such file'}")
    model = rhino3dm.File3dm.Read(str(p))
    if model is None:
        raise InputError(f"{p}: not a .3dm file rhino3dm can read (or a damaged one: a CRC error, cut short)")
    meshes = [(o.Attributes.Name, o.Geometry, o.Attributes.GetUserString("grid_shape"))
              for o in model.Objects if isinstance(o.Geometry, rhino3dm.Mesh)]
    if name is not None:
        meshes = [m for m in meshes if m[0] == name]
        if not meshes:
            raise InputError(f"name: {p} holds no mesh named {name!r}")
    if not meshes:
        kinds = sorted({type(o.Geometry).__name__ for o in model.Objects})
        raise InputError(f"{p}: no mesh in the file (it holds {', '.join(kinds) or 'no objects'})")
    if len(meshes) > 1:
        raise InputError(
            f"name: {p} holds {len(meshes)} meshes ({', '.join(repr(m[0]) for m in meshes[:5])}); pass name= to pick one"
        )
    unit = _file_unit(model, p)
    _, rmesh, grid_text = meshes[0]
    pts = rmesh.Vertices.ToPoint3dArray()
    vertices = np.array([(q.X, q.Y, q.Z) for q in pts], dtype=np.float64).reshape(-1, 3)
    faces = np.array([tuple(rmesh.Faces[k]) for k in range(len(rmesh.Faces))], dtype=np.int64).reshape(-1, 4)
    tri = faces[:, 2] == faces[:, 3]
    blocks = [(faces[~tri], np.flatnonzero(~tri)), (faces[tri, :3], np.flatnonzero(tri))]
    quads = quads_from_blocks(blocks, non_quads=non_quads, name=str(p))
    if len(quads) == 0:
        raise InputError(f"{p}: no quad faces found ({len(vertices)} vertices)")
    grid_shape = _grid_shape(grid_text, quads, len(vertices))
    try:
        return QuadMesh(vertices, quads, unit=unit, grid_shape=grid_shape)
    except InputError as exc:
        raise InputError(f"{p}: {exc}") from None


# --- Rhino surfaces in --------------------------------------------------------------------


def _occt_flat_knots(rhino_knots: list[float]) -> np.ndarray:
    """OCCT's flat knot vector from Rhino's: Rhino leaves out the superfluous first and last knot.

    A Rhino surface of order ``k`` with ``n`` control points has ``n + k - 2`` knots; OCCT (and every
    textbook) wants ``n + k``. The two extra knots do not change the surface on its domain, so they
    are taken equal to their neighbours.
    """
    t = np.asarray(rhino_knots, dtype=np.float64)
    return np.concatenate([t[:1], t, t[-1:]])


def nurbs_face(surface: Any, *, scale: float = 1.0) -> Any:
    """A build123d face exactly equal to a Rhino surface (any ``rhino3dm.Surface``, as NURBS).

    Control points, weights and knots are carried over as they are (Rhino's homogeneous control
    points divided by their weights, Rhino's knot vector completed with its two superfluous end
    knots and turned into OCCT's knots with multiplicities), so the face evaluates the same points
    as ``surface.PointAt`` at the same parameters.

    Parameters
    ----------
    surface : rhino3dm.Surface
    scale : float
        Factor applied to the coordinates (a unit conversion).

    Returns
    -------
    build123d.Face
        Over the surface's whole parameter domain.

    Raises
    ------
    InputError
        If the surface has no NURBS form or OCCT refuses its data (the message says why).

    Examples
    --------
    >>> import rhino3dm
    >>> s = rhino3dm.NurbsSurface.Create(3, False, 2, 2, 2, 2)
    >>> for kl in (s.KnotsU, s.KnotsV):
    ...     kl[0], kl[1] = 0.0, 1.0
    >>> for (i, j), p in zip([(0, 0), (1, 0), (0, 1), (1, 1)], [(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 1)]):
    ...     s.Points[(i, j)] = rhino3dm.Point4d(*p, 1.0)
    >>> f = nurbs_face(s)
    >>> [round(c, 6) for c in f.position_at(0.5, 0.5)]
    [0.5, 0.5, 0.25]
    """
    import rhino3dm
    from OCP.Geom import Geom_BSplineSurface
    from OCP.gp import gp_Pnt
    from OCP.Standard import Standard_Failure


    ns = surface if isinstance(surface, rhino3dm.NurbsSurface) else surface.ToNurbsSurface()
    if ns is None:
        raise InputError(f"face: the Rhino {type(surface).__name__} has no NURBS form")
    deg_u, deg_v = int(ns.Degree(0)), int(ns.Degree(1))
    cu, cv = int(ns.Points.CountU), int(ns.Points.CountV)
    rational = bool(ns.IsRational)
    h = np.array([[tuple(_xyzw(ns.Points.GetControlPoint(i, j))) for j in range(cv)] for i in range(cu)])
    weights = h[..., 3]
    if rational and not (weights > 0).all():
        raise InputError(f"face: the Rhino surface has a weight <= 0 ({weights.min():g}); OCCT needs positive weights")
    poles = h[..., :3] / (weights[..., None] if rational else 1.0) * scale
    Pnt2, Real1, Int1, Real2 = _occt.arrays()
    knots_mults = _occt.knots_mults

    arr = Pnt2(1, cu, 1, cv)
    for i, row in enumerate(poles.tolist()):
        for j, p in enumerate(row):
            arr.SetValue(i + 1, j + 1, gp_Pnt(*p))
    ku, mu = knots_mults(_occt_flat_knots(ns.KnotsU.ToList()))
    kv, mv = knots_mults(_occt_flat_knots(ns.KnotsV.ToList()))
    try:
        if rational:
            w = Real2(1, cu, 1, cv)
            for i, row in enumerate(weights.tolist()):
                for j, x in enumerate(row):
                    w.SetValue(i + 1, j + 1, x)
            geom = Geom_BSplineSurface(arr, w, ku, kv, mu, mv, deg_u, deg_v)
        else:
            geom = Geom_BSplineSurface(arr, ku, kv, mu, mv, deg_u, deg_v)
    except Standard_Failure as exc:
        raise InputError(f"face: OCCT refuses the Rhino surface's NURBS data ({exc})") from None
    return _occt.face_from_geom(geom)


def _xyzw(p: Any) -> tuple[float, float, float, float]:
    return (p.X, p.Y, p.Z, p.W)


def rhino_faces(path: str | os.PathLike[str]) -> tuple[list[tuple[str, Any, bool, str]], str]:
    """The surfaces of a .3dm file: ``[(name, rhino surface, trimmed, what)]`` and the file's unit.

    Every surface object is one entry; every face of a polysurface (Brep) one entry, named
    ``"<object name>[<face index>]"`` when the Brep has several faces. ``trimmed`` is true for a
    Brep face that is not its whole underlying surface (Rhino's ``IsSurface``).

    Raises
    ------
    InputError
        If the file cannot be read or its unit is not one quadnodes knows.
    """
    import rhino3dm

    p = Path(os.fspath(path))
    model = rhino3dm.File3dm.Read(str(p))
    if model is None:
        raise InputError(f"path: {str(p)!r} is not a .3dm file rhino3dm can read")
    unit = _file_unit(model, p)
    out: list[tuple[str, Any, bool, str]] = []
    for o in model.Objects:
        g = o.Geometry
        name = o.Attributes.Name or ""
        if isinstance(g, rhino3dm.Extrusion):
            g = g.ToBrep(False) if hasattr(g, "ToBrep") else None
            if g is None:
                continue
        if isinstance(g, rhino3dm.Brep):
            n = len(g.Faces)
            for k in range(n):
                f = g.Faces[k]
                single = f.DuplicateFace(False)
                trimmed = not bool(single.IsSurface)
                label = name if n == 1 else f"{name}[{k}]"
                out.append((label, f.UnderlyingSurface(), trimmed, f"face {k} of a {n}-face polysurface"))
        elif isinstance(g, rhino3dm.Surface):
            out.append((name, g, False, f"a {type(g).__name__}"))
    return out, unit


def _file_unit(model: Any, p: Path) -> str:
    unit_system = str(model.Settings.ModelUnitSystem).split(".")[-1]
    if unit_system in ("None", "Unset"):
        return "mm"
    by_name = {v: k for k, v in RHINO_UNITS.items()}
    if unit_system not in by_name:
        raise InputError(f"{p}: the model unit {unit_system} is not one quadnodes works in ({', '.join(UNITS)})")
    return by_name[unit_system]
