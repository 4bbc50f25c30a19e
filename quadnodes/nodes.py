"""The built-in node types: thin wrappers over the library functions.

Importing this module registers them in :data:`quadnodes.graph.REGISTRY`. Every
node's docstring is what ``quadnodes nodes`` shows; the work itself lives in the
library modules, which are just as usable from a script without a graph.
Lengths are in the model's unit (millimetres for the built-in surfaces).
"""

from __future__ import annotations

import json
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
from .io._atomic import write_text_atomic
from .mesh import QuadMesh
from .mesh import grid as _grid
from .noise import NoiseReport
from .noise import perturb as _perturb
from .flatness import planarity as _planarity_of
from .planarization import DEFAULT_TOLERANCE, PlanarizeReport
from .planarization import planarize as _planarize
from .flatness import summary as _summary
from .zigzag import ZigzagReport
from .zigzag import detect as _detect
from .topology import corner_vertices as _corner_vertices

Face = Any  # a build123d Face; build123d is imported lazily by quadnodes.surfaces
FixMode = Literal["none", "corners", "boundary"]

# --- sources ---------------------------------------------------------------------


@node("saddle", outputs=("face",))
def saddle(*, width: float = 5000.0, depth: float = 5000.0, rise: float = 1000.0) -> Face:
    """A hyperbolic paraboloid z = rise·(ξ² − η²) over width × depth (build123d face)."""
    return _surfaces.saddle(width, depth, rise)


@node("s_shape", outputs=("face",))
def s_shape(*, width: float = 6000.0, depth: float = 6000.0, rise: float = 1200.0,
            taper: float = 0.5, bend: float = 600.0) -> Face:
    """An S-shaped free-form surface (bicubic B-spline face)."""
    return _surfaces.s_shape(width, depth, rise, taper=taper, bend=bend)


@node("wavy", outputs=("face",))
def wavy(*, width: float = 4000.0, depth: float = 8000.0, amplitude: float = 500.0,
         waves_u: float = 0.5, waves_v: float = 1.5) -> Face:
    """A wavy sheet: a product of two cosines (bicubic B-spline face)."""
    return _surfaces.wavy(width, depth, amplitude, waves_u=waves_u, waves_v=waves_v)


@node("dome", outputs=("face",))
def dome(*, span: float = 6000.0, depth: float = 6000.0, rise: float = 1200.0) -> Face:
    """A spherical dome patch (exact OCCT sphere) over span × depth."""
    return _surfaces.dome(span, depth, rise)


@node("cylinder_segment", outputs=("face",))
def cylinder_segment(*, radius: float = 5000.0, length: float = 8000.0, angle: float = 90.0) -> Face:
    """A barrel vault: a cylinder segment of the given opening angle (degrees)."""
    return _surfaces.cylinder_segment(radius, length, angle)


@node("torus_patch", outputs=("face",))
def torus_patch(*, major: float = 6000.0, minor: float = 2000.0,
                u_range: list[float] | None = None, v_range: list[float] | None = None) -> Face:
    """A patch of a torus; angle ranges in degrees (defaults -45..45 and 0..90)."""
    kw: dict[str, Any] = {}
    if u_range is not None:
        kw["u_range"] = tuple(u_range)
    if v_range is not None:
        kw["v_range"] = tuple(v_range)
    return _surfaces.torus_patch(major, minor, **kw)


@node("read_step_surface", outputs=("face",), reads=("path",))
def read_step_surface(*, path: str, face: int = 0) -> Face:
    """Read one face (by index) of a STEP file, e.g. a surface drawn in Rhino."""
    return _surfaces.from_step(path, face=face)


@node("sample", outputs=("mesh",))
def sample(face: Face, *, nu: int = 10, nv: int = 10,
           method: Literal["auto", "bspline", "analytic", "occt"] = "auto") -> QuadMesh:
    """Sample a face on a uniform (u, v) grid of nu × nv vertices into a quad mesh."""
    return _surfaces.sample(face, nu, nv, method=method)


@node("thesis_example", outputs=("mesh",))
def thesis_example(*, name: Literal["E1", "E2", "E3", "E4"] = "E1") -> QuadMesh:
    """The clean surface of one of the thesis's examples, sampled (E1 10×10 … E4 22×41)."""
    return _surfaces.example(name)


@node("grid", outputs=("mesh",))
def grid(*, rows: int = 10, cols: int = 10, spacing: float = 1.0) -> QuadMesh:
    """A flat rows × cols grid in the xy plane."""
    return _grid(rows, cols, spacing=spacing)


@node("read_mesh", outputs=("mesh",), reads=("path",))
def read_mesh(*, path: str, non_quads: Literal["error", "drop", "split"] = "error",
              renumber_grid: bool = True) -> QuadMesh:
    """Read a quad mesh from OBJ (quads kept) or quadnodes JSON, by extension; a grid whose faces
    come in any order is renumbered row by row (``renumber_grid``, see topology.as_grid)."""
    if Path(path).suffix.lower() == ".obj":
        return _io.load(path, file_type="obj", renumber_grid=renumber_grid, non_quads=non_quads)
    return _io.load(path, renumber_grid=renumber_grid)


# --- processing --------------------------------------------------------------------


@node("perturb", outputs=("mesh", "report"))
def perturb(mesh: QuadMesh, region: np.ndarray | None = None, fixed: np.ndarray | None = None, *,
            tangential: float = 0.0, normal: float = 0.0, jitter: float = 0.0, seed: int = 0,
            fix: FixMode = "corners") -> tuple[QuadMesh, NoiseReport]:
    """Seeded zigzag noise; amplitudes in local edge lengths (tangential, normal, jitter);
    only the vertices of an optional ``region`` mask move (e.g. from select_fixed with a box);
    ``fix``/``fixed`` vertices stay (corners by default, as fairing holds them)."""
    return _perturb(mesh, tangential=tangential, normal=normal, jitter=jitter, seed=seed, fix=fix, fixed=fixed,
                    region=region)


@node("detect", outputs=("report", "free"))
@_validate.renamed(fix_boundary="fix = \"boundary\"")
def detect(mesh: QuadMesh, fixed: np.ndarray | None = None, *, threshold: float = 0.1,
           fix: FixMode = "corners",
           detection: Literal["alternating", "thesis"] = "alternating") -> tuple[ZigzagReport, np.ndarray]:
    """Find zigzag vertices (deviation strictly above threshold); outputs the report and the free mask;
    ``detection`` "thesis" is eq. 30, "alternating" leaves steady bends alone."""
    rep = _detect(mesh, threshold, fix=fix, fixed=fixed, detection=detection)
    return rep, rep.free


@node("select_fixed", outputs=("fixed",))
def select_fixed(mesh: QuadMesh, report: ZigzagReport | None = None, *, corners: bool = False,
                 boundary: bool = False, indices: list[int] | None = None,
                 box: list[float] | None = None,
                 zigzag: Literal["none", "fixed", "free"] = "none", invert: bool = False) -> np.ndarray:
    """A mask of vertices to hold: union of corners, boundary, indices, an axis box
    [xmin, ymin, zmin, xmax, ymax, zmax] and, with a report, its fixed or free vertices;
    ``invert`` flips the result."""
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
        mask |= ((mesh.vertices >= lo) & (mesh.vertices <= hi)).all(axis=1)
    if zigzag != "none":
        if report is None:
            raise InputError("zigzag: needs a zigzag report connected to the 'report' input")
        mask |= report.fixed if zigzag == "fixed" else report.free
    return ~mask if invert else mask


@node("fair", outputs=("mesh", "report"))
@_validate.renamed(deviation="threshold", deviation_decay="threshold_decay", fix_boundary="fix = \"boundary\"")
def fair(mesh: QuadMesh, fixed: np.ndarray | None = None, reference: QuadMesh | Face | None = None, *,
         iterations: int = 1,
         threshold: float | list[float] = 0.1, threshold_decay: float = 1.0,
         weight: float | list[float] = DEFAULT_WEIGHT, weight_decay: float = 1.0,
         weight_scale: Literal["normalized", "raw"] = "normalized",
         anchor: Literal["current", "input"] = "current",
         fix: FixMode = "corners",
         solver: Literal["auto", "direct", "cg"] = "auto",
         extraordinary: Literal["fair", "hold"] = "fair",
         detection: Literal["alternating", "thesis"] = "alternating") -> tuple[QuadMesh, FairingReport]:
    """The thesis's structure-line fairing (eq. 32–34); threshold and weight may be per-iteration lists;
    with a ``reference`` surface (face or mesh) the vertices are pulled to it and slide along it;
    ``extraordinary="hold"`` and ``detection="thesis"`` give the thesis's method exactly."""
    return _fair(mesh, iterations=iterations, threshold=threshold, threshold_decay=threshold_decay,
                 weight=weight, weight_decay=weight_decay, weight_scale=weight_scale, anchor=anchor,
                 fix=fix, fixed=fixed, solver=solver, reference=reference, extraordinary=extraordinary,
                 detection=detection)


@node("planarize", outputs=("mesh", "report"))
@_validate.renamed(tolerance="planar_tolerance")
def planarize(mesh: QuadMesh, reference: QuadMesh | Face | None = None, fixed: np.ndarray | None = None, *,
              planar_tolerance: float | str = DEFAULT_TOLERANCE, max_iterations: int = 2000,
              planarity_weight: float = 1.0, fairness_weight: float = 0.1, closeness_weight: float = 0.1,
              input_weight: float | None = None, fix: FixMode = "corners",
              reference_samples: int = 4, method: Literal["auto", "local-global", "newton"] = "auto",
              newton_steps: int = 30) -> tuple[QuadMesh, PlanarizeReport]:
    """Make every quad planar (within planar_tolerance: relative, or a length such as "2 mm") while keeping
    structure lines fair and the vertices close to a reference surface (a face or a mesh; they may slide
    along it) or to their input positions; corners, boundary or a mask held fixed. method: local/global
    projection, Newton steps with planarity as a hard constraint, or auto (local/global, Newton where it
    stalls)."""
    return _planarize(mesh, reference=reference, planar_tolerance=planar_tolerance, max_iterations=max_iterations,
                      planarity_weight=planarity_weight, fairness_weight=fairness_weight,
                      closeness_weight=closeness_weight, input_weight=input_weight, fix=fix, fixed=fixed,
                      reference_samples=reference_samples, method=method, newton_steps=newton_steps)


@node("laplacian", outputs=("mesh", "report"))
@_validate.renamed(weights="weighting")
def laplacian(mesh: QuadMesh, fixed: np.ndarray | None = None, *, iterations: int = 1, lam: float = 0.5,
              weighting: Literal["uniform", "inverse_length"] = "uniform",
              fix: FixMode = "none") -> tuple[QuadMesh, SmoothingReport]:
    """Laplacian smoothing x' = x + λ L x on the quad edge 1-ring (the thesis's baseline; fixes none by default)."""
    return _smoothing.laplacian(mesh, iterations=iterations, lam=lam, weighting=weighting, fix=fix, fixed=fixed)


@node("taubin", outputs=("mesh", "report"))
@_validate.renamed(weights="weighting")
def taubin(mesh: QuadMesh, fixed: np.ndarray | None = None, *, iterations: int = 1,
           lam: float | None = None, k_pb: float = 0.1,
           weighting: Literal["uniform", "inverse_length"] = "uniform",
           fix: FixMode = "none") -> tuple[QuadMesh, SmoothingReport]:
    """Taubin λ|μ smoothing (μ = 1/(k_PB − 1/λ)) on the quad edge 1-ring (fixes none by default, as the thesis)."""
    return _smoothing.taubin(mesh, iterations=iterations, lam=lam, k_pb=k_pb, weighting=weighting, fix=fix,
                             fixed=fixed)


# --- analysis ------------------------------------------------------------------------


@node("planarity", outputs=("diagonal", "angle_defect", "summary"))
def planarity(mesh: QuadMesh) -> tuple[np.ndarray, np.ndarray, dict]:
    """Per-panel planarity: diagonal distance / mean diagonal, angle-sum defect, and their summary."""
    p = _planarity_of(mesh)
    return p["diagonal"], p["angle_defect"], {k: _summary(v) for k, v in p.items()}


@node("compare", outputs=("metrics",))
def compare(original: QuadMesh, result: QuadMesh, reference: QuadMesh | None = None, *,
            thresholds: list[float] | None = None) -> dict:
    """Zigzag, displacement, boundary, bounding-box, planarity (and distance to a reference) numbers."""
    return _metrics.compare(original, result, reference=reference,
                            thresholds=tuple(thresholds) if thresholds else (0.1, 0.01))


# --- outputs -------------------------------------------------------------------------


@node("export_step", outputs=("path",), writes=("path",))
def export_step(mesh: QuadMesh, *, path: str, mode: Literal["compound", "shell", "assembly"] = "assembly",
                planar_tol: float = _io.DEFAULT_PLANAR_TOL, mesh_unit: str = "mm",
                colors: bool = False) -> Path:
    """Panels to STEP: planar faces within planar_tol, else exact bilinear patches; assembly keeps labels."""
    return _io.save_step(mesh, path, mode=mode, planar_tol=planar_tol, mesh_unit=mesh_unit, colors=colors)


@node("export_obj", outputs=("path",), writes=("path",))
def export_obj(mesh: QuadMesh, *, path: str) -> Path:
    """The mesh as OBJ with quads kept."""
    return _io.save_obj(mesh, path)


@node("export_csv", outputs=("path",), writes=("path",))
def export_csv(mesh: QuadMesh, *, path: str, planar_tol: float = _io.DEFAULT_PLANAR_TOL) -> Path:
    """The panel schedule: id, row/col, corners, area, edge lengths, planarity, planar flag."""
    return _io.save_schedule(mesh, path, planar_tol=planar_tol)


@node("export_json", outputs=("path",), writes=("path",))
def export_json(mesh: QuadMesh, *, path: str) -> Path:
    """The mesh as quadnodes JSON (exact round trip)."""
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
    under the given names (default: the input port names)."""
    items = [d for d in (data, data2, data3, data4) if d is not None]
    labels = names if names is not None else ["data", "data2", "data3", "data4"][: len(items)]
    if len(labels) != len(items):
        raise InputError(f"names: {len(labels)} names for {len(items)} connected reports")
    body = _plain(dict(zip(labels, items))) if len(items) > 1 or names is not None else _plain(data)
    return write_text_atomic(path, json.dumps(body, indent=2, sort_keys=True) + "\n")


@node("render_png", outputs=("path",), writes=("path",))
def render_png(mesh: QuadMesh, mesh2: QuadMesh | None = None, mesh3: QuadMesh | None = None,
               mesh4: QuadMesh | None = None, reference: QuadMesh | None = None,
               zigzag: ZigzagReport | None = None, *, path: str, titles: list[str] | None = None,
               notes: list[str] | None = None, planarity: bool = False, elev: float = 35.0,
               azim: float = -60.0, ncols: int | None = None, vmin: float = 1e-4, vmax: float = 1.0,
               size_px: int = 1200) -> Path:
    """Up to four meshes side by side: shaded, structure lines coloured by zigzag deviation (one log
    scale); optional faint clean ``reference``, freed/fixed markers from a ``zigzag`` report (on every
    panel), faces coloured by planarity."""
    from . import viz

    meshes = [m for m in (mesh, mesh2, mesh3, mesh4) if m is not None]
    if titles is not None and len(titles) != len(meshes):
        raise InputError(f"titles: {len(titles)} titles for {len(meshes)} connected meshes")
    return viz.render_png(meshes, path, titles=titles, notes=notes, free=zigzag, reference=reference,
                          planarity=planarity, elev=elev, azim=azim, ncols=ncols, vmin=vmin, vmax=vmax,
                          size_px=size_px)


@node("render_html", outputs=("path",), writes=("path",))
def render_html(mesh: QuadMesh, mesh2: QuadMesh | None = None, mesh3: QuadMesh | None = None,
                mesh4: QuadMesh | None = None, reference: QuadMesh | None = None, *, path: str,
                titles: list[str] | None = None, elev: float = 35.0, azim: float = -60.0,
                vmin: float = 1e-4, vmax: float = 1.0) -> Path:
    """Up to four meshes in one self-contained interactive HTML page (works offline), buttons switching
    between them; structure lines coloured by zigzag deviation; hover shows vertex and panel ids,
    deviation and planarity; an optional clean reference is shown as grey edges."""
    from . import html

    meshes = [m for m in (mesh, mesh2, mesh3, mesh4) if m is not None]
    if titles is not None and len(titles) != len(meshes):
        raise InputError(f"titles: {len(titles)} titles for {len(meshes)} connected meshes")
    return html.render_html(meshes, path, titles=titles, reference=reference, elev=elev, azim=azim,
                            vmin=vmin, vmax=vmax)


__all__: list[str] = []  # import for the side effect of registering the nodes
