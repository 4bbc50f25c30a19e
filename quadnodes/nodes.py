"""The built-in node types: thin wrappers over the library functions.

Importing this module registers them in :data:`quadnodes.graph.REGISTRY`. Every
node's docstring is what ``quadnodes nodes`` shows; the work itself lives in the
library modules, which are just as usable from a script without a graph.
Lengths are in the model's unit (millimetres for the built-in surfaces).
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from . import _validate
from . import io as _io
from . import metrics as _metrics
from . import smoothing as _smoothing
from .smoothing import SmoothingReport
from . import surfaces as _surfaces
from .errors import InputError
from .fairing import DEFAULT_WEIGHT, FairingReport
from .fairing import fair as _fair
from .graph import node
from .graph.node import Range
from .io._atomic import write_text_atomic
from .mesh import QuadMesh
from .mesh import grid as _grid
from .noise import NoiseReport
from .noise import perturb as _perturb
from .flatness import DEFAULT_PLANAR_TOLERANCE
from .flatness import planarity as _planarity_of
from .planarization import DEFAULT_TOLERANCE, PlanarizeReport
from .planarization import planarize as _planarize
from .flatness import summary as _summary
from .zigzag import ZigzagReport
from .zigzag import detect as _detect
from .topology import corner_vertices as _corner_vertices


class _FaceType(type):
    """The metaclass of :class:`Face`: answers ``isinstance``/``issubclass`` for build123d shapes without
    importing build123d (a build123d object exists only once build123d has been imported)."""

    def __instancecheck__(cls, obj: Any) -> bool:
        shape = _build123d_shape()
        return shape is not None and isinstance(obj, shape)

    def __subclasscheck__(cls, sub: Any) -> bool:
        if isinstance(sub, type) and cls in sub.__mro__:
            return True
        shape = _build123d_shape()
        return shape is not None and isinstance(sub, type) and issubclass(sub, shape)


def _build123d_shape() -> type | None:
    mod = sys.modules.get("build123d")
    return getattr(mod, "Shape", None)


class Face(metaclass=_FaceType):
    """The type of a face port: a build123d ``Face`` (or a build123d shape holding one face).

    A stand-in, so that ``import quadnodes.nodes`` does not import build123d and the graph checker can still
    tell a face from a :class:`~quadnodes.mesh.QuadMesh` (a face wired into a mesh input is refused before
    anything runs). Any build123d shape is an instance; annotate your own nodes' face ports with it.

    Examples
    --------
    >>> from quadnodes.mesh import QuadMesh, grid
    >>> from quadnodes.surfaces import saddle
    >>> isinstance(saddle(), Face), isinstance(grid(2, 2), Face), issubclass(QuadMesh, Face)
    (True, False, False)
    """

    stands_in = True  # quadnodes.graph._types.maybe_compatible: feeds an input annotated build123d.Face too


FixMode = Literal["none", "corners", "boundary"]

# --- sources ---------------------------------------------------------------------


@node("saddle", outputs=("face",),
      ranges={"width": Range(min=0, min_open=True), "depth": Range(min=0, min_open=True), "rise": Range(min=0)})
def saddle(*, width: float = 5000.0, depth: float = 5000.0, rise: float = 1000.0) -> Face:
    """A hyperbolic paraboloid z = rise·(ξ² − η²) over width × depth (build123d face).

    Parameters
    ----------
    width, depth : float
        Extent in x and y (model units, mm).
    rise : float
        Height of the saddle's highs above its corners (0 gives a plane).
    """
    return _surfaces.saddle(width, depth, rise)


@node("s_shape", outputs=("face",),
      ranges={"width": Range(min=0, min_open=True), "depth": Range(min=0, min_open=True), "rise": Range(min=0),
              "taper": Range(min=0, max=1), "bend": Range(min=0)})
def s_shape(*, width: float = 6000.0, depth: float = 6000.0, rise: float = 1200.0,
            taper: float = 0.5, bend: float = 600.0) -> Face:
    """An S-shaped free-form surface (bicubic B-spline face).

    Parameters
    ----------
    width, depth : float
        Extent in x and y (model units, mm).
    rise : float
        Amplitude of the S at the near edge.
    taper : float
        Relative loss of amplitude towards the far edge, 0 to 1.
    bend : float
        Sideways bow in plan of the middle section.
    """
    return _surfaces.s_shape(width, depth, rise, taper=taper, bend=bend)


@node("wavy", outputs=("face",),
      ranges={"width": Range(min=0, min_open=True), "depth": Range(min=0, min_open=True),
              "amplitude": Range(min=0), "waves_u": Range(min=0, min_open=True),
              "waves_v": Range(min=0, min_open=True)})
def wavy(*, width: float = 4000.0, depth: float = 8000.0, amplitude: float = 500.0,
         waves_u: float = 0.5, waves_v: float = 1.5) -> Face:
    """A wavy sheet: a product of two cosines (bicubic B-spline face).

    Parameters
    ----------
    width, depth : float
        Extent in x and y (model units, mm).
    amplitude : float
        Height of the crests.
    waves_u, waves_v : float
        Number of full waves along x and along y.
    """
    return _surfaces.wavy(width, depth, amplitude, waves_u=waves_u, waves_v=waves_v)


@node("dome", outputs=("face",),
      ranges={"span": Range(min=0, min_open=True), "depth": Range(min=0, min_open=True),
              "rise": Range(min=0, min_open=True)})
def dome(*, span: float = 6000.0, depth: float = 6000.0, rise: float = 1200.0) -> Face:
    """A spherical dome patch (exact OCCT sphere) over span × depth.

    Parameters
    ----------
    span, depth : float
        Extent in x and y (model units, mm).
    rise : float
        Height of the dome (at most span/2, a half sphere).
    """
    return _surfaces.dome(span, depth, rise)


@node("cylinder_segment", outputs=("face",),
      ranges={"radius": Range(min=0, min_open=True), "length": Range(min=0, min_open=True),
              "angle": Range(min=0, max=360, min_open=True, max_open=True)})
def cylinder_segment(*, radius: float = 5000.0, length: float = 8000.0, angle: float = 90.0) -> Face:
    """A barrel vault: a cylinder segment of the given opening angle (degrees).

    Parameters
    ----------
    radius : float
        Radius of the vault.
    length : float
        Length along the axis.
    angle : float
        Opening angle in degrees.
    """
    return _surfaces.cylinder_segment(radius, length, angle)


@node("torus_patch", outputs=("face",),
      ranges={"major": Range(min=0, min_open=True), "minor": Range(min=0, min_open=True)})
def torus_patch(*, major: float = 6000.0, minor: float = 2000.0,
                u_range: list[float] | None = None, v_range: list[float] | None = None) -> Face:
    """A patch of a torus; angle ranges in degrees (defaults -45..45 and 0..90).

    Parameters
    ----------
    major, minor : float
        Radii of the torus (minor < major).
    u_range, v_range : list of float
        Start and end angle in degrees (defaults -45..45 and 0..90).
    """
    kw: dict[str, Any] = {}
    if u_range is not None:
        kw["u_range"] = tuple(u_range)
    if v_range is not None:
        kw["v_range"] = tuple(v_range)
    return _surfaces.torus_patch(major, minor, **kw)


@node("read_step_surface", outputs=("face",), reads=("path",),
      ranges={"face": Range(min=0)})
def read_step_surface(*, path: str, face: int | str | None = None, allow_trimmed: bool = False) -> Face:
    """One face of a STEP file, e.g. a surface drawn in Rhino, by index or name; a file with several faces
    needs face= (read_surface reads IGES and .3dm too, by the same rule).

    Parameters
    ----------
    path : str
        The STEP file, relative to the graph file's folder.
    face : int or str
        Which face: its index (0: the first) or its STEP label; needed when the file has several.
    allow_trimmed : bool
        Accept a trimmed face (its untrimmed underlying surface is sampled).
    """
    return _surfaces.from_step(path, face=face, allow_trimmed=allow_trimmed)


@node("sample", outputs=("mesh",),
      ranges={"nu": Range(min=2), "nv": Range(min=2)})
def sample(face: Face, *, nu: int = 10, nv: int = 10,
           method: Literal["auto", "bspline", "analytic", "occt"] = "auto") -> QuadMesh:
    """Sample a face on a uniform (u, v) grid of nu × nv vertices into a quad mesh.

    Parameters
    ----------
    nu, nv : int
        Vertices along u and v.
    method : str
        How points are evaluated: B-spline, analytic formula, OCCT, or auto (the fastest exact one).
    """
    return _surfaces.sample(face, nu, nv, method=method)


@node("thesis_example", outputs=("mesh",))
def thesis_example(*, name: Literal["E1", "E2", "E3", "E4"] = "E1") -> QuadMesh:
    """The clean surface of one of the thesis's examples, sampled (E1 10×10 … E4 22×41).

    Parameters
    ----------
    name : str
        Which example: E1 saddle, E2 S-shape, E3 wavy sheet, E4 dome.
    """
    return _surfaces.example(name)


@node("grid", outputs=("mesh",),
      ranges={"rows": Range(min=2), "cols": Range(min=2), "spacing": Range(min=0, min_open=True)})
def grid(*, rows: int = 10, cols: int = 10, spacing: float = 1.0) -> QuadMesh:
    """A flat rows × cols grid in the xy plane.

    Parameters
    ----------
    rows, cols : int
        Vertices along y and x.
    spacing : float
        Distance between neighbouring vertices.
    """
    return _grid(rows, cols, spacing=spacing)


@node("read_mesh", outputs=("mesh",), reads=("path",))
def read_mesh(*, path: str, non_quads: Literal["error", "drop", "split"] = "error",
              renumber_grid: bool = True) -> QuadMesh:
    """Read a quad mesh from OBJ, OFF, PLY, Rhino .3dm (quads kept) or quadnodes JSON, by extension.

    Parameters
    ----------
    path : str
        The mesh file, relative to the graph file's folder.
    non_quads : str
        What to do with faces that are not quads: refuse the file, drop them, or split them.
    renumber_grid : bool
        Renumber a grid whose faces and vertices come in any order row by row (topology.as_grid).
    """
    if Path(path).suffix.lower() == ".json":  # quadnodes JSON holds quads only
        return _io.load(path, renumber_grid=renumber_grid)
    return _io.load(path, renumber_grid=renumber_grid, non_quads=non_quads)


# --- processing --------------------------------------------------------------------


@node("perturb", outputs=("mesh", "report"),
      ranges={"tangential": Range(min=0), "normal": Range(min=0), "jitter": Range(min=0),
              "seed": Range(min=0)})
def perturb(mesh: QuadMesh, region: np.ndarray | None = None, fixed: np.ndarray | None = None, *,
            tangential: float = 0.0, normal: float = 0.0, jitter: float = 0.0, seed: int = 0,
            fix: FixMode = "corners") -> tuple[QuadMesh, NoiseReport]:
    """Seeded zigzag noise; amplitudes in local edge lengths (tangential, normal, jitter);
    only the vertices of an optional ``region`` mask move (e.g. from select_fixed with a box);
    ``fix``/``fixed`` vertices stay (corners by default, as fairing holds them).

    Parameters
    ----------
    tangential : float
        Zigzag amplitude along the surface, in local edge lengths.
    normal : float
        Amplitude across the surface, in local edge lengths.
    jitter : float
        Random extra displacement, in local edge lengths.
    seed : int
        Seed of the random numbers (same seed, same noise).
    fix : str
        Vertices that do not move: none, the corners, or the whole boundary (plus a connected ``fixed`` mask).
    """
    return _perturb(mesh, tangential=tangential, normal=normal, jitter=jitter, seed=seed, fix=fix, fixed=fixed,
                    region=region)


@node("detect", outputs=("report", "free"),
      ranges={"threshold": Range(min=0)})
@_validate.renamed(fix_boundary="fix = \"boundary\"")
def detect(mesh: QuadMesh, fixed: np.ndarray | None = None, *, threshold: float | None = None,
           fix: FixMode = "corners",
           detection: Literal["alternating", "thesis"] = "alternating") -> tuple[ZigzagReport, np.ndarray]:
    """Find zigzag vertices (deviation strictly above threshold); outputs the report and the free mask.

    Parameters
    ----------
    threshold : float
        Zigzag cut-off: a vertex whose deviation is strictly above it is freed (empty: 0.03 alternating, 0.1 thesis).
    fix : str
        Vertices never freed: none, the corners, or the whole boundary (plus a connected ``fixed`` mask).
    detection : str
        alternating (default: lines that turn left-right-left; steady bends are left alone) or thesis (eq. 30).
    """
    rep = _detect(mesh, threshold, fix=fix, fixed=fixed, detection=detection)
    return rep, rep.free


@node("select_fixed", outputs=("fixed",),
      ranges={"indices": Range(min=0)})
def select_fixed(mesh: QuadMesh, report: ZigzagReport | None = None, *, corners: bool = False,
                 boundary: bool = False, indices: list[int] | None = None,
                 box: list[float] | None = None,
                 zigzag: Literal["none", "fixed", "free"] = "none", invert: bool = False) -> np.ndarray:
    """A mask of vertices to hold: union of corners, boundary, indices, an axis box
    [xmin, ymin, zmin, xmax, ymax, zmax] and, with a report, its fixed or free vertices;
    ``invert`` flips the result.

    Parameters
    ----------
    corners : bool
        Include the corner vertices.
    boundary : bool
        Include every boundary vertex.
    indices : list of int
        Include these vertex indices.
    box : list of float
        Include the vertices inside the axis box [xmin, ymin, zmin, xmax, ymax, zmax].
    zigzag : str
        With a zigzag report: include its fixed or its free vertices.
    invert : bool
        Select the complement.
    """
    n = mesh.n_vertices
    mask = np.zeros(n, dtype=bool)
    if corners:
        mask |= _corner_vertices(mesh)
    if boundary:
        mask |= mesh.topology.boundary_vertices
    if indices:
        idx = np.asarray(indices, dtype=np.int64)
        bad = (idx < 0) | (idx >= n)
        if bad.any():
            raise InputError(f"indices: vertex {int(idx[bad][0])} is outside 0..{n - 1}")
        mask[idx] = True
    if box is not None:
        if len(box) != 6:
            raise InputError(f"box: expected 6 numbers [xmin, ymin, zmin, xmax, ymax, zmax], got {len(box)}")
        lo, hi = np.asarray(box[:3]), np.asarray(box[3:])
        for axis, a, b in zip("xyz", box[:3], box[3:]):
            if a > b:  # an empty box would select nothing, silently
                raise InputError(f"box: {axis} goes from {a:g} down to {b:g} ([xmin, ymin, zmin, xmax, ymax, "
                                 "zmax]: the smaller values first)")
        mask |= ((mesh.vertices >= lo) & (mesh.vertices <= hi)).all(axis=1)
    if zigzag != "none":
        if report is None:
            raise InputError("zigzag: needs a zigzag report connected to the 'report' input")
        mask |= report.fixed if zigzag == "fixed" else report.free
    return ~mask if invert else mask


@node("fair", outputs=("mesh", "report"),
      ranges={"iterations": Range(min=1), "threshold": Range(min=0),
              "threshold_decay": Range(min=0, min_open=True), "weight": Range(min=0, min_open=True),
              "weight_decay": Range(min=0, min_open=True)})
@_validate.renamed(deviation="threshold", deviation_decay="threshold_decay", fix_boundary="fix = \"boundary\"")
def fair(mesh: QuadMesh, fixed: np.ndarray | None = None, reference: QuadMesh | Face | None = None, *,
         iterations: int = 1,
         threshold: float | list[float] | None = None, threshold_decay: float = 1.0,
         weight: float | list[float] = DEFAULT_WEIGHT, weight_decay: float = 1.0,
         weight_scale: Literal["normalized", "raw"] = "normalized",
         anchor: Literal["current", "input"] = "current",
         fix: FixMode = "corners",
         solver: Literal["auto", "direct", "cg"] = "auto",
         extraordinary: Literal["fair", "lines", "hold"] = "fair",
         detection: Literal["alternating", "thesis"] = "alternating",
         line_spacing: Literal["fair", "hold"] = "fair",
         gaps: Literal["auto", "fair", "hold"] = "auto",
         line_curvature: Literal["fair", "hold", "auto"] = "auto") -> tuple[QuadMesh, FairingReport]:
    """The thesis's structure-line fairing (eq. 32–34); threshold and weight may be per-iteration lists;
    with a ``reference`` surface (face or mesh) the vertices are pulled to it and slide along it.

    Parameters
    ----------
    iterations : int
        Rounds of detect-then-solve (each re-detects the zigzag vertices).
    threshold : float or list of float
        Zigzag cut-off per round (eq. 30): vertices deviating more are freed (empty: 0.03 alternating, 0.1 thesis).
    threshold_decay : float
        Factor applied to the cut-off after each round (1: constant).
    weight : float or list of float
        Penalty weight ω pulling freed vertices to their anchor (eq. 34); larger moves them less.
    weight_decay : float
        Factor applied to the weight after each round (1: constant).
    weight_scale : str
        normalized: ω relative to the mesh's edge length (the default, unit-free); raw: the thesis's ω as is.
    anchor : str
        Pull towards the current positions of each round or the input positions.
    fix : str
        Vertices held in place: none, the corners (the default), or the whole boundary (plus a ``fixed`` mask).
    solver : str
        Linear solver: direct factorization, conjugate gradients, or auto by size.
    extraordinary : str
        fair (default: vertices where lines end or lines are too short for a window get a 1-ring fairness
        term of their own), lines (lines continued through extraordinary vertices) or hold (the thesis).
    detection : str
        alternating (default: steady bends are no zigzag) or thesis (eq. 30 exactly).
    line_spacing : str
        fair (default: uneven spacing along a line is faired too) or hold (the thesis: every edge keeps its length).
    gaps : str
        fair (a vertex between two found vertices of a line is faired too) or hold (only what is found moves; the
        thesis); auto (default): fair with the alternating detection, hold with the thesis's.
    line_curvature : str
        auto (default: where the design's lines change curvature markedly — rounded edges and corners — a second
        solve holds their faired line terms, so the design drifts less; elsewhere one solve, as fair), fair (the
        thesis: every curvature change along the lines is faired, the design's too) or hold (bias correction
        everywhere: a second solve gives back the smooth part of what the first removed; two solves per round).
    """
    return _fair(mesh, iterations=iterations, threshold=threshold, threshold_decay=threshold_decay,
                 weight=weight, weight_decay=weight_decay, weight_scale=weight_scale, anchor=anchor,
                 fix=fix, fixed=fixed, solver=solver, reference=reference, extraordinary=extraordinary,
                 detection=detection, line_spacing=line_spacing, gaps=gaps, line_curvature=line_curvature)


@node("planarize", outputs=("mesh", "report"),
      ranges={"planar_tolerance": Range(min=0, min_open=True), "max_iterations": Range(min=1),
              "planarity_weight": Range(min=0, min_open=True), "fairness_weight": Range(min=0),
              "closeness_weight": Range(min=0), "input_weight": Range(min=0), "reference_samples": Range(min=1),
              "newton_steps": Range(min=1)})
@_validate.renamed(tolerance="planar_tolerance")
def planarize(mesh: QuadMesh, reference: QuadMesh | Face | None = None, fixed: np.ndarray | None = None, *,
              planar_tolerance: float | str = DEFAULT_TOLERANCE, max_iterations: int = 2000,
              planarity_weight: float = 1.0, fairness_weight: float = 0.1, closeness_weight: float = 0.1,
              input_weight: float | None = None, fix: FixMode = "corners",
              reference_samples: int = 4, method: Literal["auto", "local-global", "gauss-newton", "newton"] = "auto",
              newton_steps: int = 30, shape: Literal["keep", "free"] = "keep") -> tuple[QuadMesh, PlanarizeReport]:
    """Make every quad planar (within planar_tolerance: relative, or a length such as "2 mm") while keeping
    structure lines fair and the vertices close to a reference surface (a face or a mesh; they may slide
    along it) or to their input positions; corners, boundary or a mask held fixed. method: local/global
    projection, Newton steps with planarity as a hard constraint, or auto (local/global, Newton where it
    stalls).

    Parameters
    ----------
    planar_tolerance : float or str
        Target planarity: a number is diagonal distance / mean diagonal, text such as "2 mm" a length.
    max_iterations : int
        Most local/global iterations.
    planarity_weight : float
        Weight of planarity in the energy.
    fairness_weight : float
        Weight of straight, evenly spaced structure lines.
    closeness_weight : float
        Weight of staying on the reference surface.
    input_weight : float
        Weight of staying at the input positions (default: the closeness weight without a reference, else 0).
    fix : str
        Vertices held in place: none, the corners, or the whole boundary (plus a connected ``fixed`` mask).
    reference_samples : int
        Reference surface sampled this many times finer than the mesh for closest points.
    method : str
        local-global projection, newton steps with planarity as a hard constraint, gauss-newton (a planarity
        penalty with a growing weight, steps that fold nothing), or auto (gauss-newton, then newton, where
        local-global stalls).
    newton_steps : int
        Most Newton steps.
    shape : str
        keep (default: no quad folds into a dart or bow-tie, no edge shrinks below 0.3 of its length) or free.
    """
    return _planarize(mesh, reference=reference, planar_tolerance=planar_tolerance, max_iterations=max_iterations,
                      planarity_weight=planarity_weight, fairness_weight=fairness_weight,
                      closeness_weight=closeness_weight, input_weight=input_weight, fix=fix, fixed=fixed,
                      reference_samples=reference_samples, method=method, newton_steps=newton_steps, shape=shape)


@node("laplacian", outputs=("mesh", "report"),
      ranges={"iterations": Range(min=1), "lam": Range(min=0, max=1, min_open=True)})
@_validate.renamed(weights="weighting")
def laplacian(mesh: QuadMesh, fixed: np.ndarray | None = None, *, iterations: int = 1, lam: float = 0.5,
              weighting: Literal["uniform", "inverse_length"] = "uniform",
              fix: FixMode = "none") -> tuple[QuadMesh, SmoothingReport]:
    """Laplacian smoothing x' = x + λ L x on the quad edge 1-ring (the thesis's baseline; fixes none by default).

    Parameters
    ----------
    iterations : int
        Smoothing steps.
    lam : float
        Step size λ.
    weighting : str
        Neighbour weights: uniform or inverse edge length.
    fix : str
        Vertices held in place: none, the corners, or the whole boundary (plus a connected ``fixed`` mask).
    """
    return _smoothing.laplacian(mesh, iterations=iterations, lam=lam, weighting=weighting, fix=fix, fixed=fixed)


@node("taubin", outputs=("mesh", "report"),
      ranges={"iterations": Range(min=1), "lam": Range(min=0, min_open=True),
              "k_pb": Range(min=0, max=1, min_open=True, max_open=True)})
@_validate.renamed(weights="weighting")
def taubin(mesh: QuadMesh, fixed: np.ndarray | None = None, *, iterations: int = 1,
           lam: float | None = None, k_pb: float = 0.1,
           weighting: Literal["uniform", "inverse_length"] = "uniform",
           fix: FixMode = "none") -> tuple[QuadMesh, SmoothingReport]:
    """Taubin λ|μ smoothing (μ = 1/(k_PB − 1/λ)) on the quad edge 1-ring (fixes none by default, as the thesis).

    Parameters
    ----------
    iterations : int
        λ|μ step pairs.
    lam : float
        Shrinking step λ (default from k_pb).
    k_pb : float
        Pass-band frequency k_PB; μ = 1/(k_PB − 1/λ).
    weighting : str
        Neighbour weights: uniform or inverse edge length.
    fix : str
        Vertices held in place: none, the corners, or the whole boundary (plus a connected ``fixed`` mask).
    """
    return _smoothing.taubin(mesh, iterations=iterations, lam=lam, k_pb=k_pb, weighting=weighting, fix=fix,
                             fixed=fixed)


# --- analysis ------------------------------------------------------------------------


@node("planarity", outputs=("diagonal", "angle_defect", "summary"))
def planarity(mesh: QuadMesh) -> tuple[np.ndarray, np.ndarray, dict]:
    """Per-panel planarity: diagonal distance / mean diagonal, angle-sum defect, and their summary."""
    p = _planarity_of(mesh)
    return p["diagonal"], p["angle_defect"], {k: _summary(v) for k, v in p.items()}


@node("compare", outputs=("metrics",),
      ranges={"thresholds": Range(min=0, min_open=True)})
def compare(original: QuadMesh, result: QuadMesh, reference: QuadMesh | Face | None = None, *,
            thresholds: list[float] | None = None) -> dict:
    """Zigzag, displacement, boundary, bounding-box, planarity (and distance to a reference) numbers.

    Parameters
    ----------
    thresholds : list of float
        Zigzag cut-offs to count vertices above (default 0.1 and 0.01).
    """
    return _metrics.compare(original, result, reference=reference,
                            thresholds=tuple(thresholds) if thresholds else (0.1, 0.01))


# --- outputs -------------------------------------------------------------------------


@node("export_step", outputs=("path", "report"), writes=("path",))
@_validate.renamed(planar_tol="planar_tolerance", mesh_unit="the mesh's own unit (mesh.with_unit)")
def export_step(mesh: QuadMesh, *, path: str, mode: Literal["compound", "shell", "assembly"] = "shell",
                planar_tolerance: float | str = DEFAULT_PLANAR_TOLERANCE,
                colors: bool = False) -> tuple[Path, _io.StepReport]:
    """Panels to STEP in the mesh's unit: plane faces for panels within planar_tolerance, else exact bilinear
    patches; shell: one sewn shell with faces named P_<row>_<col>; assembly: one labelled part per panel.

    Parameters
    ----------
    path : str
        Output file, relative to the output folder.
    mode : str
        shell (one sewn shell of named faces, the default), assembly (one labelled part per panel), or compound.
    planar_tolerance : float or str
        Panels this planar become plane faces (corners moved onto the plane, at most half of it; the report
        gives the largest move), others exact bilinear patches: a relative number, or a length such as "2 mm".
    colors : bool
        Colour panels by planarity.
    """
    return _io.write_step(mesh, path, mode=mode, planar_tolerance=planar_tolerance, colors=colors)


@node("export_obj", outputs=("path",), writes=("path",))
def export_obj(mesh: QuadMesh, *, path: str) -> Path:
    """The mesh as OBJ with quads kept.

    Parameters
    ----------
    path : str
        Output file, relative to the output folder.
    """
    return _io.save_obj(mesh, path)


@node("export_csv", outputs=("path",), writes=("path",))
@_validate.renamed(planar_tol="planar_tolerance")
def export_csv(mesh: QuadMesh, *, path: str, planar_tolerance: float | str = DEFAULT_PLANAR_TOLERANCE,
               precision: Literal["rounded", "full"] = "rounded") -> Path:
    """The panel schedule: id, row/col, corners, area, edge lengths, both planarity measures, kind (planar flag),
    corner move; column names carry the mesh's unit.

    Parameters
    ----------
    path : str
        Output file, relative to the output folder.
    planar_tolerance : float or str
        Panels this planar are of kind planar: a relative number, or a length such as "2 mm".
    precision : str
        rounded (lengths to 0.001 mm, as a schedule is read) or full (exact floats).
    """
    return _io.save_schedule(mesh, path, planar_tolerance=planar_tolerance, precision=precision)


@node("export_json", outputs=("path",), writes=("path",))
def export_json(mesh: QuadMesh, *, path: str) -> Path:
    """The mesh as quadnodes JSON (exact round trip).

    Parameters
    ----------
    path : str
        Output file, relative to the output folder.
    """
    return _io.save_json(mesh, path)


def _plain(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if hasattr(value, "to_dict"):
        return _plain(value.to_dict())
    return value


@node("export_report", outputs=("path",), writes=("path",))
def export_report(data: Any, data2: Any = None, data3: Any = None, data4: Any = None, *, path: str,
                  names: list[str] | None = None) -> Path:
    """Up to four reports (metrics, fairing logs, planarity summaries) as one pretty JSON file,
    under the given names (default: the input port names).

    Parameters
    ----------
    path : str
        Output file, relative to the output folder.
    names : list of str
        Key of each connected report in the file (default: the port names).
    """
    items = [d for d in (data, data2, data3, data4) if d is not None]
    labels = names if names is not None else ["data", "data2", "data3", "data4"][: len(items)]
    if len(labels) != len(items):
        raise InputError(f"names: {len(labels)} names for {len(items)} connected reports")
    body = _plain(dict(zip(labels, items))) if len(items) > 1 or names is not None else _plain(data)
    return write_text_atomic(path, json.dumps(body, indent=2, sort_keys=True) + "\n")


@node("render_png", outputs=("path",), writes=("path",),
      ranges={"elev": Range(min=-90, max=90), "ncols": Range(min=1), "vmin": Range(min=0, min_open=True),
              "vmax": Range(min=0, min_open=True), "size_px": Range(min=200)}, templates=("titles", "notes"))
def render_png(mesh: QuadMesh, mesh2: QuadMesh | None = None, mesh3: QuadMesh | None = None,
               mesh4: QuadMesh | None = None, reference: QuadMesh | None = None,
               zigzag: ZigzagReport | None = None, *, path: str, titles: list[str] | None = None,
               notes: list[str] | None = None, planarity: bool | Literal["relative", "length"] = False, elev: float = 35.0,
               azim: float = -60.0, ncols: int | None = None, vmin: float = 1e-4, vmax: float = 1.0,
               size_px: int = 1200,
               color_by: Literal["mean", "gaussian", "gaussian_1", "gaussian_2", "gaussian_3", "k1", "k2",
                                 "line_max"] | None = None) -> Path:
    """Up to four meshes side by side: shaded, structure lines coloured by zigzag deviation (one log
    scale); optional faint clean ``reference``, freed/fixed markers from a ``zigzag`` report (on every
    panel), faces coloured by planarity or by a discrete curvature.

    Parameters
    ----------
    path : str
        Output file, relative to the output folder.
    titles : list of str
        One title per mesh; {node.setting} is replaced by that setting, e.g. "{fair.iterations} iterations".
    notes : list of str
        Lines under the figure; {node.setting} is replaced as in titles.
    planarity : bool or str
        Colour faces by planarity: true or relative (diagonal gap / diagonal), or length (gap in the unit).
    color_by : str
        Colour faces by a discrete curvature (mean, gaussian, gaussian_1..3, k1, k2, line_max), one shared scale.
    elev, azim : float
        Camera elevation and azimuth in degrees.
    ncols : int
        Panels per row (default: up to 2, 3 for three meshes).
    vmin, vmax : float
        Ends of the deviation colour scale (log).
    size_px : int
        Figure width in pixels.
    """
    from . import viz

    meshes = [m for m in (mesh, mesh2, mesh3, mesh4) if m is not None]
    if titles is not None and len(titles) != len(meshes):
        raise InputError(f"titles: {len(titles)} titles for {len(meshes)} connected meshes")
    return viz.render_png(meshes, path, titles=titles, notes=notes, free=zigzag, reference=reference,
                          planarity=planarity, elev=elev, azim=azim, ncols=ncols, vmin=vmin, vmax=vmax,
                          size_px=size_px, color_by=color_by)


@node("render_html", outputs=("path",), writes=("path",),
      ranges={"elev": Range(min=-90, max=90), "vmin": Range(min=0, min_open=True),
              "vmax": Range(min=0, min_open=True)}, templates=("titles",))
def render_html(mesh: QuadMesh, mesh2: QuadMesh | None = None, mesh3: QuadMesh | None = None,
                mesh4: QuadMesh | None = None, reference: QuadMesh | None = None, *, path: str,
                titles: list[str] | None = None, elev: float = 35.0, azim: float = -60.0,
                vmin: float = 1e-4, vmax: float = 1.0) -> Path:
    """Up to four meshes in one self-contained interactive HTML page (works offline), buttons switching
    between them; structure lines coloured by zigzag deviation; hover shows vertex and panel ids,
    deviation and planarity; an optional clean reference is shown as grey edges.

    Parameters
    ----------
    path : str
        Output file, relative to the output folder.
    titles : list of str
        One button label per mesh; {node.setting} is replaced by that setting.
    elev, azim : float
        Camera elevation and azimuth in degrees.
    vmin, vmax : float
        Ends of the deviation colour scale (log).
    """
    from . import html

    meshes = [m for m in (mesh, mesh2, mesh3, mesh4) if m is not None]
    if titles is not None and len(titles) != len(meshes):
        raise InputError(f"titles: {len(titles)} titles for {len(meshes)} connected meshes")
    return html.render_html(meshes, path, titles=titles, reference=reference, elev=elev, azim=azim,
                            vmin=vmin, vmax=vmax)


# --- Rhino, DXF and surface files (issue 13) ---------------------------------------------

from .io.dxf import DxfReport  # noqa: E402  (kept beside the nodes that use it)


@node("read_surface", outputs=("face",), reads=("path",), ranges={"face": Range(min=0)})
def read_surface(*, path: str, face: int | str | None = None, allow_trimmed: bool = False) -> Face:
    """The designer's surface from STEP, IGES or Rhino .3dm (NURBS converted exactly, in mm), by index or name;
    a file with several faces needs face=, a trimmed face is refused unless allow_trimmed.

    Parameters
    ----------
    path : str
        The surface file (.step, .stp, .iges, .igs or .3dm), relative to the graph's folder.
    face : int or str
        Which face: its index, or its name (Rhino object name or STEP label); needed when the file has several.
    allow_trimmed : bool
        Accept a trimmed face (its untrimmed underlying surface is sampled).
    """
    return _surfaces.from_file(path, face=face, allow_trimmed=allow_trimmed)


@node("export_3dm", outputs=("path",), writes=("path",))
def export_3dm(mesh: QuadMesh, *, path: str, planar_tolerance: float | str = DEFAULT_PLANAR_TOLERANCE,
               lines: bool = True, user_text: bool = True) -> Path:
    """Rhino .3dm in the mesh's unit: the quad mesh, every panel a named degree-1 surface with user text on
    layer panels::planar or panels::bilinear (planar_tolerance: relative, or a length such as "2 mm"), and
    the structure lines as polylines.

    Parameters
    ----------
    path : str
        Output file, relative to the output folder.
    planar_tolerance : float or str
        Panels this planar go on layer panels::planar: a relative number, or a length such as "2 mm".
    lines : bool
        Also write the structure lines as polylines.
    user_text : bool
        Attach user text (id, row/col, planarity, area, edges) to every panel.
    """
    return _io.save_3dm(mesh, path, planar_tolerance=planar_tolerance, lines=lines, user_text=user_text)


@node("export_dxf", outputs=("path", "report"), writes=("path",),
      ranges={"per_row": Range(min=1), "gap": Range(min=0), "text_height": Range(min=0, min_open=True)})
def export_dxf(mesh: QuadMesh, *, path: str, planar_tolerance: float | str = DEFAULT_PLANAR_TOLERANCE,
               per_row: int | None = None, gap: float | None = None,
               text_height: float | None = None) -> tuple[Path, DxfReport]:
    """DXF unrolls for fabrication: every panel flat (unfolded along a diagonal), in rows without overlaps, on
    layer PANELS (green planar, orange bilinear) with its label on LABELS; the report gives each panel's
    distortion (largest edge or diagonal length change, in the mesh's unit).

    Parameters
    ----------
    path : str
        Output file, relative to the output folder.
    planar_tolerance : float or str
        Panels this planar are drawn green: a relative number, or a length such as "2 mm".
    per_row : int
        Panels per row of the layout (default: about the square root of the panel count).
    gap : float
        Space between unrolled panels, in the mesh's unit (default: a tenth of the mean edge).
    text_height : float
        Height of the labels, in the mesh's unit (default: from the panel size).
    """
    return _io.dxf_report(mesh, path, planar_tolerance=planar_tolerance, per_row=per_row, gap=gap,
                          text_height=text_height)


# --- advice in the run summary ----------------------------------------------------------


@dataclass(frozen=True)
class Advice:
    """Short notes for the run summary (``quadnodes run`` prints every output's ``notes()``)."""

    lines: tuple[str, ...] = ()

    def notes(self) -> list[str]:
        """The notes, one line each (none when the condition did not hold)."""
        return list(self.lines)


@node("advise", outputs=("advice",), templates=("message",))
def advise(metrics: dict, baseline: dict | None = None, *, key: str, above: float | None = None,
           below: float | None = None, message: str = "") -> Advice:
    """Say why a result looks bad, in the run summary, when a number of a metrics table crosses a limit.

    The limit is ``above``/``below``, or else the same number of a connected
    ``baseline`` table (e.g. Laplacian's metrics: note when the new method is
    worse). The note names the number, its value and the limit, then
    ``message``; when the limit is not crossed there is no note, so a summary
    never claims what the run did not show.

    Parameters
    ----------
    key : str
        The number to watch, a key of the connected metrics (e.g. boundary_displacement_max).
    above, below : float
        Note when the number is above or below this limit (default: above the baseline's number).
    message : str
        The explanation and the setting that fixes it; {node.setting} is replaced by that setting.
    """
    def number(table: dict, what: str) -> float:
        if key not in table:
            raise InputError(f"key: no {key!r} in the {what} (keys: {', '.join(sorted(map(str, table)))})")
        return float(table[key])

    value = number(metrics, "metrics")
    limit = ""
    if above is None and below is None:
        if baseline is None:
            raise InputError("above, below: give a limit, or connect a baseline to compare with")
        ref = number(baseline, "baseline")
        if value > ref:
            limit = f"above the baseline's {ref:.4g}"
    elif above is not None and value > above:
        limit = f"above {above:g}"
    elif below is not None and value < below:
        limit = f"below {below:g}"
    if not limit:
        return Advice()
    return Advice((f"{key} = {value:.4g} ({limit})" + (f": {message}" if message else ""),))


# --- the thesis's chapter 2-3 methods (issue 17) ------------------------------------


@node("fair_web", outputs=("mesh", "report"),
      ranges={"tension": Range(min=0), "closeness": Range(min=0), "max_iterations": Range(min=1, max=100_000),
              "tolerance": Range(min=0, min_open=True)})
def fair_web(mesh: QuadMesh, fixed: np.ndarray | None = None, *,
             energy: Literal["E1", "E2", "tension"] = "E2", tension: float = 1.0, closeness: float = 0.0,
             cylinder_radius: float | str | None = None, cylinder_height: float | str | None = None,
             fix: FixMode = "boundary", solver: Literal["newton", "admm", "projected_gradient"] = "newton",
             max_iterations: int = 5000, tolerance: float = 1e-5) -> tuple[QuadMesh, Any]:
    """Fair web (thesis 3.1.1): minimize E1, E2 or E2 + τE1 of the structure-line network, optionally inside
    tolerance cylinders (radius across, half-height along the normal; mesh unit or text such as '20 mm').

    Parameters
    ----------
    energy : str
        E1 (edge vectors), E2 (second differences along the lines) or tension (E2 + tension · E1).
    tension : float
        The weight τ of E1 in the tension energy.
    closeness : float
        Weight of a pull to the input positions (0, as in the thesis's eq. 11).
    cylinder_radius : float or str
        Tolerance cylinder radius across the surface, in the mesh's unit or text such as "20 mm" (none: unbounded).
    cylinder_height : float or str
        Half-height of the tolerance cylinder along the input's normal, as cylinder_radius.
    fix : str
        Vertices held in place: none, corners or boundary (the thesis holds the boundary).
    solver : str
        newton (semismooth Newton, the default), admm or projected_gradient, for the cylinder constraints.
    max_iterations : int
        Cap on constrained solver iterations (Newton steps for newton).
    tolerance : float
        Stop when the KKT residual is below this many mean edge lengths.
    """
    from .webs import fair_web as _fair_web

    return _fair_web(mesh, energy=energy, tension=tension, closeness=closeness, cylinder_radius=cylinder_radius,
                     cylinder_height=cylinder_height, fix=fix, fixed=fixed, solver=solver,
                     max_iterations=max_iterations, tolerance=tolerance)


@node("spring", outputs=("mesh", "report"),
      ranges={"max_iterations": Range(min=1, max=100_000), "tolerance": Range(min=0, min_open=True),
              "step": Range(min=0, max=1, min_open=True)})
def spring(mesh: QuadMesh, fixed: np.ndarray | None = None, *, fix: FixMode = "boundary",
           max_iterations: int = 500, tolerance: float = 1e-4, step: float = 0.5,
           tangential: bool = True) -> tuple[QuadMesh, Any]:
    """Spring model of Yamada et al. (thesis 3.3): equal spring lengths along neighbouring normals, a
    tangential regularizing move; stops when the largest move is below tolerance (in edge lengths).

    Parameters
    ----------
    fix : str
        Vertices held in place: none, corners or boundary (the thesis holds the boundary).
    max_iterations : int
        Cap on iterations.
    tolerance : float
        Stop when the largest move is below this many mean edge lengths.
    step : float
        Damping of each move (0 < step <= 1).
    tangential : bool
        Add the tangential regularizing component.
    """
    from .spring_model import spring as _spring

    return _spring(mesh, fix=fix, fixed=fixed, max_iterations=max_iterations, tolerance=tolerance, step=step,
                   tangential=tangential)


@node("schneider_kobbelt", outputs=("mesh", "report"),
      ranges={"ring": Range(min=0), "max_iterations": Range(min=1, max=100_000),
              "tolerance": Range(min=0, min_open=True), "step": Range(min=0, max=1, min_open=True)})
def schneider_kobbelt(mesh: QuadMesh, fixed: np.ndarray | None = None, *, fix: FixMode = "boundary",
                      ring: int = 1, max_iterations: int = 200, tolerance: float = 1e-4,
                      step: float = 0.5) -> tuple[QuadMesh, Any]:
    """Schneider–Kobbelt (thesis 3.4): Δ_B H = 0 with the cotangent Laplace–Beltrami operator and
    Moreton–Séquin mean curvature; the fixed vertices and a ring around them hold the G1 boundary.

    Parameters
    ----------
    fix : str
        Vertices held in place: none, corners or boundary (the thesis holds the boundary).
    ring : int
        Rings of neighbours of the held vertices also held (the G1 boundary condition).
    max_iterations : int
        Cap on iterations.
    tolerance : float
        Stop when the largest move is below this many mean edge lengths.
    step : float
        Damping of each move (0 < step <= 1).
    """
    from .pde_fairing import schneider_kobbelt as _sk

    return _sk(mesh, fix=fix, fixed=fixed, ring=ring, max_iterations=max_iterations, tolerance=tolerance,
               step=step)


@node("curvature", outputs=("curvature", "mean", "gaussian"))
def curvature(mesh: QuadMesh) -> tuple[dict, np.ndarray, np.ndarray]:
    """Discrete curvatures (thesis 2.2.3): all fields as a dict (mean, gaussian, gaussian_1..3, k1, k2,
    principal directions, structure-line curvature), and the mean and Gaussian curvature per vertex."""
    from .discrete_curvature import curvature as _curvature

    c = _curvature(mesh)
    return c, c["mean"], c["gaussian"]


@node("fourier", outputs=("mesh", "report"), ranges={"keep": Range(min=0)})
def fourier(mesh: QuadMesh, fixed: np.ndarray | None = None, *, keep: int = 3,
            fix: FixMode = "none") -> tuple[QuadMesh, Any]:
    """Fourier descriptors (thesis 3.2.1): low-pass every closed structure line, keeping harmonics
    0..keep; open lines are left alone (the report says how many).

    Parameters
    ----------
    keep : int
        The highest harmonic kept (1 keeps a circle).
    fix : str
        Vertices held in place: none, corners or boundary.
    """
    from .fourier_descriptors import fourier as _fourier

    return _fourier(mesh, keep=keep, fix=fix, fixed=fixed)


__all__ = ["Face"]  # import for the side effect of registering the nodes; Face types your own nodes' face ports

# The file suffixes of the writers fixed to one format, checked with the other output-path rules
# (quadnodes.graph.paths): `path = "panels.stl"` on export_step would write STEP text under an STL name.
for _writer, _suffixes in ((export_step, (".step", ".stp")), (export_obj, (".obj",)), (export_csv, (".csv",)),
                           (export_json, (".json",)), (export_report, (".json",)), (render_png, (".png",)),
                           (render_html, (".html", ".htm")), (export_3dm, (".3dm",)), (export_dxf, (".dxf",))):
    _writer.file_suffixes = {"path": _suffixes}  # type: ignore[attr-defined]
del _writer, _suffixes
