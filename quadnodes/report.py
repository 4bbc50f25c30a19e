"""The thesis comparison: Laplacian, Taubin and the new method on the thesis's four examples.

:func:`thesis_comparison` rebuilds each example of the thesis's chapter 5 (the
stand-in surfaces of :func:`quadnodes.surfaces.example`), adds the seeded zigzag
noise of ``examples/make_thesis_graphs.py``, runs the three methods with the
thesis's parameters on the same noisy input, and writes one figure per example
and a metrics table (Markdown and CSV). It also runs the variants a fair
comparison needs: Laplacian and Taubin with the boundary held fixed, the new
method at the documented default weight (``quadnodes.fairing.DEFAULT_WEIGHT``)
and the new method with the boundary held fixed.

The thesis's weights (0.001, 0.005, 0.001, 0.0005) are used as **normalized**
weights (``weight_scale="normalized"``: ω / h² with h the mean edge length),
i.e. as if the thesis's meshes had unit edge length; the thesis does not give
its meshes' unit, and read as raw weights on these millimetre models they would
hold every vertex in place.

Every length in the tables is in mean edge lengths ``h`` of the clean mesh
(given per example in millimetres), so the examples can be compared. The
command ``quadnodes compare`` runs it.
"""

from __future__ import annotations

import csv
import io
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from types import MappingProxyType
from typing import Any, Literal

import numpy as np

from . import _validate
from .errors import ExportError, InputError
from .fairing import DEFAULT_WEIGHT
from .fairing import fair as _fair
from .io._atomic import write_text_atomic
from .mesh import QuadMesh
from .metrics import compare, distance_to_mesh
from .noise import perturb, vertex_normals
from .progress import part, report_progress
from .smoothing import laplacian, taubin
from .zigzag import detect

__all__ = ["ThesisExample", "THESIS_EXAMPLES", "COLUMNS", "METHODS", "SPREAD_COLUMNS", "KEY_COLUMNS",
           "ExampleResult", "ComparisonResult", "measure", "run_example", "format_markdown", "format_csv",
           "thesis_comparison",
           "CHAPTER3_METHODS", "CLOSED_METHODS", "CHAPTER3_COLUMNS", "run_chapter3", "run_closed_example",
           "format_chapter3_markdown", "chapter3_figure"]

#: Refinement of the clean surface sample used for the distance to the clean *surface*.
_SURFACE_REFINE = 4


@dataclass(frozen=True)
class ThesisExample:
    """One example of the thesis's chapter 5 and the settings used to reproduce it.

    Attributes
    ----------
    name : str
        ``"E1"`` … ``"E4"``.
    surface : str
        The :mod:`quadnodes.surfaces` family (default settings).
    rows, cols : int
        Sampling grid (vertices).
    laplace, taubin : int
        The thesis's iteration counts.
    fair : Mapping
        Keyword arguments of :func:`quadnodes.fair` (iterations, threshold
        schedule, thesis weight as a normalized weight).
    noise : (float, float)
        Tangential and normal zigzag amplitude of :func:`quadnodes.perturb`, in
        local edge lengths (seed 7, corners fixed).
    elev, azim : float
        Camera of the figure, degrees.
    """

    name: str
    surface: str
    rows: int
    cols: int
    laplace: int
    taubin: int
    fair: Mapping[str, Any]
    noise: tuple[float, float]
    elev: float = 35.0
    azim: float = -60.0


def _ex(name: str, surface: str, rows: int, cols: int, laplace: int, taubin_: int, fair: dict,
        noise: tuple[float, float], **camera: float) -> ThesisExample:
    return ThesisExample(name, surface, rows, cols, laplace, taubin_, MappingProxyType(fair), noise, **camera)


#: How the "new method" rows run fair: the thesis's method, edge lengths frozen one by one (eq. 32) and only the
#: found vertices moved, since the page checks the thesis's claims about it; fair's defaults ``line_spacing="fair"``
#: and ``gaps="fair"`` are measured against it in ``docs/fairing.md`` (``benchmarks/studies/bench_real_meshes.py
#: --spacing`` and ``--gaps``), and so is the default ``line_curvature="auto"`` (``--curvature``) against the
#: thesis's single solve pinned here.
THESIS_FAIR: Mapping[str, Any] = MappingProxyType({"line_spacing": "hold", "gaps": "hold", "line_curvature": "fair"})

#: The thesis's examples with its parameters (chapter 5) and the noise of examples/make_thesis_graphs.py.
THESIS_EXAMPLES: Mapping[str, ThesisExample] = MappingProxyType({
    "E1": _ex("E1", "saddle", 10, 10, 3, 40, dict(iterations=3, threshold=0.1, weight=0.001), (0.25, 0.1)),
    "E2": _ex("E2", "s_shape", 13, 13, 1, 20, dict(iterations=3, threshold=0.1, weight=0.005), (0.25, 0.1),
              elev=35.0, azim=-70.0),
    "E3": _ex("E3", "wavy", 22, 41, 4, 50,
              dict(iterations=10, threshold=1.0, threshold_decay=0.5, weight=0.001), (0.25, 0.1),
              elev=25.0, azim=-30.0),
    "E4": _ex("E4", "dome", 22, 41, 4, 30, dict(iterations=5, threshold=1.0, weight=0.0005), (0.6, 0.2),
              elev=30.0, azim=-60.0),
})

#: Columns of the metrics table: (key, Markdown header, format). Lengths in edge lengths h.
COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("zigzag_mean", "zigzag mean", ".2e"),
    ("zigzag_max", "zigzag max", ".3g"),
    ("vertices_above_0.1", "vertices > 0.1", "d"),
    ("vertices_above_0.01", "vertices > 0.01", "d"),
    ("displacement_mean_h", "moved mean (h)", ".3f"),
    ("displacement_max_h", "moved max (h)", ".3f"),
    ("boundary_displacement_max_h", "boundary moved max (h)", ".3f"),
    ("surface_distance_mean_h", "to clean surface mean (h)", ".3f"),
    ("surface_distance_max_h", "to clean surface max (h)", ".3f"),
    ("vertex_distance_mean_h", "to clean vertex mean (h)", ".3f"),
    ("vertex_distance_max_h", "to clean vertex max (h)", ".3f"),
    ("boundary_outward_max_h", "boundary out of clean max (h)", ".3f"),
    ("boundary_inward_max_h", "boundary inside clean max (h)", ".3f"),
    ("bbox_change_pct", "bounding box vs clean (%)", "+.2f"),
    ("relief_change_pct", "relief vs clean (%)", "+.1f"),
    ("normal_offset_mean_h", "normal offset mean (h)", "+.3f"),
    ("planarity_mean", "planarity mean", ".2e"),
    ("planarity_max", "planarity max", ".3g"),
)

# The Markdown file splits the columns into two tables (zigzag and movement / shape).
_TABLE_A = COLUMNS[:7]
_TABLE_B = COLUMNS[7:]


@dataclass
class ExampleResult:
    """Meshes and numbers of one example.

    Attributes
    ----------
    example : ThesisExample
    clean : QuadMesh
        The clean sampled surface (the reference).
    meshes : dict of str to QuadMesh
        ``"original"`` (the noisy input) and one entry per method (see :data:`METHODS`).
    labels : dict of str to str
        A readable label per method.
    rows : list of dict
        One metrics row per mesh, keys ``example``, ``seed``, ``method``, ``label``,
        ``edge_length_mm`` and those of :data:`COLUMNS`.
    free, fixed : dict of str to (n,) bool
        Vertices freed (moved) and held fixed by each method, for the figure.
    seconds : float
        Time to run the methods and measure them (excluding the figures).
    """

    example: ThesisExample
    clean: QuadMesh
    meshes: dict[str, QuadMesh] = field(default_factory=dict)
    labels: dict[str, str] = field(default_factory=dict)
    rows: list[dict[str, Any]] = field(default_factory=list)
    free: dict[str, np.ndarray] = field(default_factory=dict)
    fixed: dict[str, np.ndarray] = field(default_factory=dict)
    seconds: float = 0.0


def _boundary_frame(clean: QuadMesh) -> tuple[np.ndarray, np.ndarray]:
    """Non-corner boundary vertices of ``clean`` and their outward unit directions in the surface."""
    topo = clean.topology
    v = clean.vertices
    idx = np.flatnonzero(topo.boundary_vertices & ~topo.corner_vertices)
    be = topo.edges[topo.boundary_edges]
    # a regular boundary vertex has exactly two boundary edges: tangent from one neighbour to the other
    ends = np.concatenate([be[:, 0], be[:, 1]])
    others = np.concatenate([be[:, 1], be[:, 0]])
    order = np.argsort(ends, kind="stable")
    ends, others = ends[order], others[order]
    start = np.searchsorted(ends, idx)
    tangent = v[others[start + 1]] - v[others[start]]
    normal = vertex_normals(clean)[idx]
    out = np.cross(tangent, normal)
    out /= np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-300)
    indptr, nbr, _ = topo.ring
    centre = np.array([v[nbr[indptr[i]:indptr[i + 1]]].mean(axis=0) for i in idx]).reshape(-1, 3)
    flip = np.einsum("ij,ij->i", out, v[idx] - centre) < 0
    out[flip] *= -1.0
    return idx, out


def _bbox_diagonal(v: np.ndarray) -> float:
    return float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))


def _relief(v: np.ndarray) -> float:
    """RMS distance of the points from their best-fit plane."""
    c = v - v.mean(axis=0)
    return float(np.linalg.svd(c, compute_uv=False)[-1] / np.sqrt(len(v)))


def measure(
    original: QuadMesh,
    result: QuadMesh,
    clean: QuadMesh,
    surface: QuadMesh,
    *,
    boundary_frame: tuple[np.ndarray, np.ndarray] | None = None,
) -> dict[str, float]:
    """The numbers of one row of the comparison table.

    Parameters
    ----------
    original : QuadMesh
        The noisy input the method ran on.
    result : QuadMesh
        The method's output (same faces).
    clean : QuadMesh
        The clean mesh (same faces): vertex-to-vertex distances, the boundary
        frame, normals and relief are taken from it; ``h`` is its mean edge length.
    surface : QuadMesh
        A fine sample of the clean surface, for the distance to the surface.
    boundary_frame : (indices, outward directions), optional
        Precomputed :func:`_boundary_frame` of ``clean``.

    Returns
    -------
    dict
        The keys of :data:`COLUMNS`; lengths divided by ``h``.

    Raises
    ------
    InputError
        If the meshes do not share their faces.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> m = grid(5, 5)
    >>> row = measure(m, m, m, m)
    >>> row["zigzag_max"], row["vertex_distance_max_h"], row["bbox_change_pct"]
    (0.0, 0.0, 0.0)
    """
    for name, m in (("result", result), ("clean", clean)):
        if not np.array_equal(m.faces, original.faces):
            raise InputError(f"{name}: must have the same faces as original")
    h = clean.mean_edge_length
    c = compare(original, result, reference=clean)
    row: dict[str, float] = {
        "zigzag_mean": c["zigzag_mean"],
        "zigzag_max": c["zigzag_max"],
        "vertices_above_0.1": c["vertices_above_0.1"],
        "vertices_above_0.01": c["vertices_above_0.01"],
        "displacement_mean_h": c["displacement_mean"] / h,
        "displacement_max_h": c["displacement_max"] / h,
        "boundary_displacement_max_h": c["boundary_displacement_max"] / h,
    }
    d0 = _bbox_diagonal(clean.vertices)
    row["bbox_change_pct"] = 100.0 * (_bbox_diagonal(result.vertices) - d0) / d0
    ds = distance_to_mesh(result.vertices, surface)
    row["surface_distance_mean_h"] = float(ds.mean()) / h
    row["surface_distance_max_h"] = float(ds.max()) / h
    row["vertex_distance_mean_h"] = c["reference_vertex_mean"] / h
    row["vertex_distance_max_h"] = c["reference_vertex_max"] / h
    idx, out = boundary_frame if boundary_frame is not None else _boundary_frame(clean)
    off = np.einsum("ij,ij->i", result.vertices[idx] - clean.vertices[idx], out) / h
    row["boundary_outward_max_h"] = float(max(off.max(), 0.0)) if off.size else 0.0
    row["boundary_inward_max_h"] = float(max(-off.min(), 0.0)) if off.size else 0.0
    r0 = _relief(clean.vertices)
    row["relief_change_pct"] = 100.0 * (_relief(result.vertices) / r0 - 1.0) if r0 > 0 else 0.0
    nrm = vertex_normals(clean)
    row["normal_offset_mean_h"] = float(np.einsum("ij,ij->i", result.vertices - clean.vertices, nrm).mean()) / h
    row["planarity_mean"] = c["planarity_mean"]
    row["planarity_max"] = c["planarity_max"]
    return row


#: Method keys in table order: the thesis's three, then the variants.
METHODS: tuple[str, ...] = ("original", "laplacian", "taubin", "new", "laplacian_fixed_boundary",
                            "taubin_fixed_boundary", "new_default_weight", "new_fixed_boundary")

#: Columns of the seed-spread table (the key numbers of each claim).
SPREAD_COLUMNS: tuple[str, ...] = ("zigzag_max", "boundary_displacement_max_h", "boundary_outward_max_h",
                                   "boundary_inward_max_h", "surface_distance_mean_h", "vertex_distance_mean_h",
                                   "relief_change_pct", "bbox_change_pct", "normal_offset_mean_h")

#: Columns of the interior-noise table.
KEY_COLUMNS: tuple[str, ...] = ("zigzag_max", "vertices_above_0.1", "boundary_displacement_max_h",
                                "surface_distance_mean_h", "vertex_distance_mean_h", "relief_change_pct",
                                "bbox_change_pct", "normal_offset_mean_h")


def _plural(n: int, word: str) -> str:
    return f"{n} {word}{'' if n == 1 else 's'}"


@lru_cache(maxsize=None)
def _geometry(name: str) -> tuple[QuadMesh, QuadMesh]:
    """The clean sampled example and a finer sample of the same face (cached; meshes are immutable)."""
    from . import surfaces

    ex = THESIS_EXAMPLES[name]
    face = getattr(surfaces, ex.surface)()
    clean = surfaces.sample(face, ex.rows, ex.cols)
    r = _SURFACE_REFINE
    return clean, surfaces.sample(face, r * (ex.rows - 1) + 1, r * (ex.cols - 1) + 1)


def _check_names(examples: Sequence[str]) -> list[str]:
    if isinstance(examples, str) or not isinstance(examples, Sequence) or len(examples) == 0:
        raise InputError(f"examples: expected a non-empty list of example names, got {examples!r}")
    names = [str(e).upper() for e in examples]
    unknown = [e for e in names if e not in THESIS_EXAMPLES]
    if unknown:
        raise InputError(f"examples: unknown example {unknown[0]!r}, expected some of {sorted(THESIS_EXAMPLES)}")
    if len(set(names)) != len(names):
        raise InputError(f"examples: listed twice: {sorted({e for e in names if names.count(e) > 1})}")
    return names


def _check_seed(seed: Any, name: str = "seed") -> int:
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool):
        raise InputError(f"{name}: expected an integer, got {seed!r}")
    return int(seed)


def _noisy_example(name: str, seed: int, fix: str) -> tuple[ThesisExample, QuadMesh, QuadMesh, QuadMesh, int, str]:
    """An example's settings, clean and finely sampled meshes, and its seeded noisy mesh (arguments checked)."""
    name = _check_names([name])[0]
    seed = _check_seed(seed)
    fix = _validate.choice(fix, ("corners", "boundary"), "fix")
    ex = THESIS_EXAMPLES[name]
    clean, fine = _geometry(name)
    noisy, _ = perturb(clean, tangential=ex.noise[0], normal=ex.noise[1], seed=seed, fix=fix)
    return ex, clean, fine, noisy, seed, fix


@_validate.renamed(noise_fix="fix")
def run_example(name: str, *, seed: int = 7, fix: Literal["corners", "boundary"] = "corners") -> ExampleResult:
    """Run Laplacian, Taubin, the new method and the variants on one noisy example.

    Methods (keys of :data:`METHODS`): the noisy ``original``; ``laplacian`` and
    ``taubin`` with the thesis's iteration counts and nothing fixed (as in the
    thesis); ``new`` with the thesis's schedule and weight; the same three with
    the boundary fixed (``*_fixed_boundary``); and ``new_default_weight``, the
    thesis's schedule at the default weight.

    Parameters
    ----------
    name : str
        A key of :data:`THESIS_EXAMPLES`.
    seed : int
        Seed of the noise (7 as in the example graphs).
    fix : {"corners", "boundary"}
        Vertices the noise leaves alone (``perturb(fix=...)[0]``): the corners (as in the example graphs,
        so the boundary lines zigzag too) or the whole boundary (noise inside only).

    Returns
    -------
    ExampleResult

    Raises
    ------
    InputError
        On an unknown example name, a bad seed or ``fix``.

    Examples
    --------
    >>> r = run_example("E1")
    >>> [row["method"] for row in r.rows][:4]
    ['original', 'laplacian', 'taubin', 'new']
    """
    t0 = time.perf_counter()
    ex, clean, fine, noisy, seed, fix = _noisy_example(name, seed, fix)
    topo = noisy.topology
    boundary = topo.boundary_vertices
    none = np.zeros(noisy.n_vertices, dtype=bool)
    corners = ~topo.window_middle  # what the new method never moves
    fp = dict(ex.fair)
    it, w = fp["iterations"], fp["weight"]
    res = ExampleResult(ex, clean)

    def put(key: str, label: str, mesh: QuadMesh, fixed: np.ndarray, free: np.ndarray | None = None) -> None:
        res.meshes[key] = mesh
        res.labels[key] = label
        res.fixed[key] = fixed
        moved = np.linalg.norm(mesh.vertices - noisy.vertices, axis=1) > 0
        res.free[key] = moved if free is None else free

    first = _validate.schedule(fp["threshold"], it, "threshold", decay=fp.get("threshold_decay", 1.0))[0]
    zz = detect(noisy, float(first))
    lap, tau = _plural(ex.laplace, "step"), _plural(ex.taubin, "iteration")
    new = f"New method, {_plural(it, 'iteration')}"
    put("original", "Original (noisy input)", noisy, zz.fixed, zz.free)
    put("laplacian", f"Laplacian, {lap}", laplacian(noisy, iterations=ex.laplace)[0], none)
    put("taubin", f"Taubin, {tau}", taubin(noisy, iterations=ex.taubin)[0], none)
    put("new", f"{new}, ω = {w:g}", _fair(noisy, **fp, **THESIS_FAIR)[0], corners)
    put("laplacian_fixed_boundary", f"Laplacian, {lap}, boundary fixed",
        laplacian(noisy, iterations=ex.laplace, fix="boundary")[0], boundary)
    put("taubin_fixed_boundary", f"Taubin, {tau}, boundary fixed",
        taubin(noisy, iterations=ex.taubin, fix="boundary")[0], boundary)
    put("new_default_weight", f"{new}, ω = {DEFAULT_WEIGHT:g} (default)",
        _fair(noisy, **{**fp, "weight": DEFAULT_WEIGHT}, **THESIS_FAIR)[0], corners)
    put("new_fixed_boundary", f"{new}, ω = {w:g}, boundary fixed",
        _fair(noisy, **fp, fix="boundary", **THESIS_FAIR)[0], corners | boundary)
    frame = _boundary_frame(clean)
    h = clean.mean_edge_length
    for key in METHODS:
        row: dict[str, Any] = {"example": ex.name, "seed": seed, "fix": fix, "method": key,
                               "label": res.labels[key], "edge_length_mm": h}
        row.update(measure(noisy, res.meshes[key], clean, fine, boundary_frame=frame))
        res.rows.append(row)
    res.seconds = time.perf_counter() - t0
    return res


def _cell(value: Any, fmt: str) -> str:
    if fmt == "d":
        return str(int(value))
    text = format(float(value), fmt)
    return "0" if fmt.endswith("g") and float(value) == 0 else text


def _params(ex: ThesisExample) -> str:
    fp = dict(ex.fair)
    sched = f"threshold {fp['threshold']:g}"
    if fp.get("threshold_decay", 1.0) != 1.0:
        sched += f" × {fp['threshold_decay']:g} per iteration"
    return (f"Laplacian {_plural(ex.laplace, 'step')}; Taubin {_plural(ex.taubin, 'iteration')}; new method "
            f"{_plural(fp['iterations'], 'iteration')}, {sched}, weight {fp['weight']:g} (normalized)")


HEADER = """\
Written by `quadnodes compare`. Lengths are in mean edge lengths h of the clean mesh. Zigzag: the
deviation of eq. 30 per window (max over windows; vertices counted by their largest window). Moved and
boundary moved: from the noisy input. To clean surface: distance of each vertex to the clean surface
(sampled 4× finer); to clean vertex: distance to the vertex's own clean position (sees sliding too).
Boundary out of / inside clean: largest offset of a non-corner boundary vertex beyond / inside the clean
boundary, measured in the surface across the boundary. Bounding box: change of its diagonal against the
clean mesh. Relief: RMS distance of the vertices from their best-fit plane, against the clean mesh's
(negative = flatter). Normal offset: mean signed offset from the clean vertex along the clean normal
(+ = up/out). Planarity: distance between the diagonals over the mean diagonal, per quad.
"""


def format_markdown(
    results: Sequence[ExampleResult],
    *,
    figures: Mapping[str, str] | None = None,
    spread: Mapping[str, Sequence[ExampleResult]] | None = None,
    interior: Mapping[str, ExampleResult] | None = None,
) -> str:
    """The metrics as Markdown: per example its parameters, figure link and tables.

    Parameters
    ----------
    results : sequence of ExampleResult
        One per example (the figure's seed).
    figures : mapping of str to str, optional
        Example name -> relative path of its figure (linked above its tables).
    spread : mapping of str to sequence of ExampleResult, optional
        Example name -> runs with other seeds: adds a table of min–max ranges of
        the :data:`SPREAD_COLUMNS`.
    interior : mapping of str to ExampleResult, optional
        Example name -> the run with noise on interior vertices only: adds a
        table of the :data:`KEY_COLUMNS`.

    Returns
    -------
    str
    """
    lines = ["# Thesis comparison: Laplacian, Taubin and the new method", "", HEADER]
    heads = {k: hdr for k, hdr, _ in COLUMNS}
    fmts = {k: f for k, _, f in COLUMNS}
    for res in results:
        ex = res.example
        lines += [
            f"## {ex.name}: {ex.surface} {ex.rows}×{ex.cols}, h = {res.rows[0]['edge_length_mm']:.1f} mm",
            "",
            f"Noise: tangential {ex.noise[0]:g} h, normal {ex.noise[1]:g} h, seed {res.rows[0]['seed']}, "
            f"corners fixed. {_params(ex)}.",
            "",
        ]
        if figures and ex.name in figures:
            lines += [f"![{ex.name}]({figures[ex.name]})", ""]
        for cols in (_TABLE_A, _TABLE_B):
            lines.append("| method | " + " | ".join(c[1] for c in cols) + " |")
            lines.append("|---|" + "---:|" * len(cols))
            for row in res.rows:
                lines.append(f"| {row['label']} | " + " | ".join(_cell(row[k], f) for k, _, f in cols) + " |")
            lines.append("")
        runs = list(spread.get(ex.name, ())) if spread else []
        if runs:
            seeds = ", ".join(str(r.rows[0]["seed"]) for r in runs)
            lines += [f"Range (min – max) over seeds {seeds}:", ""]
            lines.append("| method | " + " | ".join(heads[k] for k in SPREAD_COLUMNS) + " |")
            lines.append("|---|" + "---:|" * len(SPREAD_COLUMNS))
            for j, key in enumerate(METHODS):
                cells = []
                for k in SPREAD_COLUMNS:
                    vals = [r.rows[j][k] for r in runs]
                    cells.append(f"{_cell(min(vals), fmts[k])} – {_cell(max(vals), fmts[k])}")
                lines.append(f"| {runs[0].rows[j]['label']} | " + " | ".join(cells) + " |")
            lines.append("")
        inner = interior.get(ex.name) if interior else None
        if inner is not None:
            lines += [f"The same with the noise on interior vertices only (the boundary left clean), seed "
                      f"{inner.rows[0]['seed']}:", ""]
            lines.append("| method | " + " | ".join(heads[k] for k in KEY_COLUMNS) + " |")
            lines.append("|---|" + "---:|" * len(KEY_COLUMNS))
            for row in inner.rows:
                lines.append(f"| {row['label']} | " + " | ".join(_cell(row[k], fmts[k]) for k in KEY_COLUMNS) + " |")
            lines.append("")
    return "\n".join(lines)


def format_csv(results: Sequence[ExampleResult]) -> str:
    """All rows of all runs as CSV (full precision), one header line.

    Columns: ``example, seed, fix, method, label, edge_length_mm`` and the keys of :data:`COLUMNS`.
    """
    buf = io.StringIO()
    keys = ["example", "seed", "fix", "method", "label", "edge_length_mm", *(c[0] for c in COLUMNS)]
    wr = csv.DictWriter(buf, fieldnames=keys, lineterminator="\n")
    wr.writeheader()
    for res in results:
        for row in res.rows:
            wr.writerow({k: (repr(float(row[k])) if isinstance(row[k], float) else row[k]) for k in keys})
    return buf.getvalue()


@dataclass
class ComparisonResult:
    """What :func:`thesis_comparison` wrote and measured.

    ``results`` holds the runs with the figures' seed, ``spread`` the runs with
    the other seeds per example, ``interior`` the runs with noise on interior
    vertices only.
    """

    results: list[ExampleResult]
    spread: dict[str, list[ExampleResult]]
    interior: dict[str, ExampleResult]
    figures: dict[str, Path]
    variant_figures: dict[str, Path]
    markdown: Path
    csv: Path
    seeds_csv: Path | None
    seconds: float
    chapter3: dict[str, ExampleResult] = field(default_factory=dict)
    chapter3_figures: dict[str, Path] = field(default_factory=dict)
    chapter3_markdown: Path | None = None
    chapter3_csv: Path | None = None


def _note(row: Mapping[str, Any]) -> str:
    relief = int(round(row["relief_change_pct"]))
    return (f"zigzag max {row['zigzag_max']:.2g} · boundary moved {row['boundary_displacement_max_h']:.2f} h\n"
            f"to clean surface {row['surface_distance_mean_h']:.3f} h mean · relief vs clean "
            f"{relief:+d} %".replace("+0 %", "±0 %"))


def _figure(res: ExampleResult, keys: Sequence[str], path: Path, size_px: int, palette: int | None) -> Path:
    from . import viz

    rows = {r["method"]: r for r in res.rows}
    ex = res.example
    return viz.render_png(
        [res.meshes[k] for k in keys], path,
        titles=[res.labels[k] for k in keys], notes=[_note(rows[k]) for k in keys],
        free=[res.free[k] for k in keys], fixed=[res.fixed[k] for k in keys],
        reference=res.clean, elev=ex.elev, azim=ex.azim, size_px=size_px, palette=palette,
    )


def thesis_comparison(
    out_dir: str | os.PathLike[str],
    *,
    examples: Sequence[str] = ("E1", "E2", "E3", "E4"),
    seed: int = 7,
    spread_seeds: Sequence[int] = (1, 2, 3, 4, 5),
    interior_noise: bool = True,
    size_px: int = 1200,
    palette: int | None = 256,
    variants_figure: bool = True,
    log: Callable[[str], None] | None = None,
    chapter3: bool = True,
) -> ComparisonResult:
    """Run the thesis comparison and write its figures and tables into ``out_dir``.

    For every example: ``<name>.png`` (panels Original / Laplacian / Taubin /
    New method with the thesis's parameters) and, with ``variants_figure``,
    ``<name>_variants.png`` (Laplacian and Taubin with the boundary fixed, the
    new method at the default weight and with the boundary fixed). For all of
    them: ``comparison.md`` (tables and figure links) and ``comparison.csv``
    (every column at full precision), both for the noise ``seed``; with
    ``spread_seeds``, the same runs with those seeds add a min–max table per
    example to the Markdown and ``comparison_seeds.csv``; with
    ``interior_noise``, a run whose noise leaves the boundary clean adds one
    more table per example (its rows are in ``comparison.csv`` too, with
    ``fix = boundary``).

    Parameters
    ----------
    out_dir : path-like
        Created if missing.
    examples : sequence of str
        Keys of :data:`THESIS_EXAMPLES`, in the order to report.
    seed : int
        Seed of the noise for the figures and main tables (7, as the example graphs).
    spread_seeds : sequence of int
        More seeds, to show how much the numbers depend on the noise (empty: none).
    interior_noise : bool
        Also run every example with noise on interior vertices only.
    size_px : int
        Width of the figures in pixels.
    palette : int or None
        Colours of the indexed PNGs (smaller files); None for full colour.
    variants_figure : bool
        Also draw the variants figure per example.
    log : callable, optional
        Called with one line of progress per example.
    chapter3 : bool
        Also run the thesis's chapter-3 methods (:func:`run_chapter3`, with and
        without boundary noise, and :func:`run_closed_example`): figures
        ``<name>_chapter3.png`` and ``C1_chapter3.png``, tables ``chapter3.md``
        and ``chapter3.csv``.

    Returns
    -------
    ComparisonResult

    Raises
    ------
    InputError
        On an unknown example name, an empty or duplicated list, or bad settings.
    ExportError
        If the folder cannot be created or a file cannot be written.

    Examples
    --------
    >>> import tempfile
    >>> r = thesis_comparison(tempfile.mkdtemp(), examples=["E1"], spread_seeds=(), interior_noise=False,
    ...                       size_px=600, variants_figure=False, chapter3=False)
    >>> sorted(p.name for p in (r.figures["E1"], r.markdown, r.csv))
    ['E1.png', 'comparison.csv', 'comparison.md']
    """
    names = _check_names(examples)
    seed = _check_seed(seed)
    if isinstance(spread_seeds, (str, bytes)) or not isinstance(spread_seeds, Sequence):
        raise InputError(f"spread_seeds: expected a list of integers, got {spread_seeds!r}")
    extra = [_check_seed(s, f"spread_seeds[{i}]") for i, s in enumerate(spread_seeds)]
    size_px = _validate.positive_int(size_px, "size_px", minimum=200)
    say = log or (lambda _msg: None)
    t0 = time.perf_counter()
    out = Path(os.fspath(out_dir))
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ExportError(f"out_dir: cannot create {str(out)!r}: {exc}") from exc
    results: list[ExampleResult] = []
    spread: dict[str, list[ExampleResult]] = {}
    interior: dict[str, ExampleResult] = {}
    figures: dict[str, Path] = {}
    variants: dict[str, Path] = {}
    steps = 2 + bool(variants_figure) + len(extra) + bool(interior_noise)  # per example, for progress
    span = 0.75 if chapter3 else 1.0  # the chapter-3 methods take the last quarter of the progress
    for i, name in enumerate(names):
        t = time.perf_counter()

        def step(k: int, what: str, i: int = i, name: str = name) -> Any:
            """Report the start of step ``k`` of this example; inside it, the messages of the library calls.

            A figure's own progress maps onto the step; a run of several methods
            (each reporting 0..1 of its own) keeps the step's start, so the
            fraction never goes back.
            """
            lo, hi = (span * (i + k / steps) / len(names), span * (i + (k + 1) / steps) / len(names))
            label = f"{name} ({i + 1}/{len(names)}): {what}"
            report_progress(lo, label)
            return part(lo, hi if "figure" in what else lo, f"{label}: ")

        with step(0, f"seed {seed}"):
            res = run_example(name, seed=seed)
        results.append(res)
        with step(1, "figure"):
            figures[name] = _figure(res, METHODS[:4], out / f"{name}.png", size_px, palette)
        if variants_figure:
            with step(2, "variants figure"):
                variants[name] = _figure(res, METHODS[4:], out / f"{name}_variants.png", size_px, palette)
        spread[name] = []
        for j, s in enumerate(extra):
            with step(2 + bool(variants_figure) + j, f"seed {s} ({j + 1} of {len(extra)} for the spread)"):
                spread[name].append(run_example(name, seed=s))
        if interior_noise:
            with step(steps - 1, "interior noise"):
                interior[name] = run_example(name, seed=seed, fix="boundary")
        say(f"{name}: {_plural(1 + len(extra), 'seed')}{', interior noise' if interior_noise else ''}, "
            f"{time.perf_counter() - t:.2f} s")
    md = write_text_atomic(out / "comparison.md", format_markdown(
        results, figures={k: v.name for k, v in figures.items()}, spread=spread, interior=interior))
    cs = write_text_atomic(out / "comparison.csv", format_csv([*results, *interior.values()]))
    seeds_csv = None
    if extra:
        seeds_csv = write_text_atomic(out / "comparison_seeds.csv",
                                      format_csv([r for runs in spread.values() for r in runs]))
    result = ComparisonResult(results, spread, interior, figures, variants, md, cs, seeds_csv,
                              time.perf_counter() - t0)
    if chapter3:
        _chapter3(result, out, names, seed, size_px, palette, say, start=span)
        result.seconds = time.perf_counter() - t0
    return result


def _chapter3(result: ComparisonResult, out: Path, names: Sequence[str], seed: int, size_px: int,
              palette: int | None, say: Callable[[str], None], start: float = 0.0) -> None:
    """Run the chapter-3 methods and write their figures and tables into ``out`` (part of :func:`thesis_comparison`).

    Progress goes from ``start`` to 1: one share per example and one for the closed example.
    """
    keys = ("original", "new", "fair_web_cylinders", "spring", "schneider_kobbelt", "fair_web")
    inner: dict[str, ExampleResult] = {}
    share = (1.0 - start) / (len(names) + 1)
    for i, name in enumerate(names):
        t = time.perf_counter()
        lo = start + i * share
        label = f"{name}: chapter-3 methods"
        report_progress(lo, label)
        with part(lo, lo, f"{label}: "):  # the methods' own 0..1 keeps the step's start
            res = run_chapter3(name, seed=seed)
            result.chapter3[name] = res
            inner[name] = run_chapter3(name, seed=seed, fix="boundary")
        with part(lo + 0.5 * share, lo + share, f"{name}: chapter-3 figure: "):
            result.chapter3_figures[name] = chapter3_figure(res, keys, out / f"{name}_chapter3.png",
                                                            size_px=size_px, palette=palette)
        say(f"{name}: chapter-3 methods, {time.perf_counter() - t:.2f} s")
    t = time.perf_counter()
    lo = start + len(names) * share
    report_progress(lo, "C1 (closed lines): every method")
    with part(lo, lo, "C1: "):
        closed = run_closed_example(seed=seed)
    result.chapter3["C1"] = closed
    with part(lo + 0.5 * share, 1.0, "C1: figure: "):
        result.chapter3_figures["C1"] = chapter3_figure(
            closed, ("original", "fourier", "new", "fair_web", "spring", "schneider_kobbelt"), out / "C1_chapter3.png",
            size_px=size_px, palette=palette)
    say(f"C1 (closed lines): every method, {time.perf_counter() - t:.2f} s")
    figs = {k: v.name for k, v in result.chapter3_figures.items()}
    result.chapter3_markdown = write_text_atomic(out / "chapter3.md", format_chapter3_markdown(
        [result.chapter3[n] for n in names], interior=inner, closed=closed, figures=figs))
    buf = io.StringIO()
    keys_csv = ["example", "seed", "fix", "method", "label", "edge_length_mm", "seconds", "iterations",
                *(c[0] for c in COLUMNS)]
    wr = csv.DictWriter(buf, fieldnames=keys_csv, lineterminator="\n")
    wr.writeheader()
    for res in [*result.chapter3.values(), *inner.values()]:
        for row in res.rows:
            wr.writerow({k: (repr(float(row[k])) if isinstance(row[k], float) else row[k]) for k in keys_csv})
    result.chapter3_csv = write_text_atomic(out / "chapter3.csv", buf.getvalue())


# --- the thesis's chapter-3 methods on the same examples (issue 17) ----------------------------------------

#: Method keys of :func:`run_chapter3`, in table order.
CHAPTER3_METHODS: tuple[str, ...] = ("original", "new", "fair_web", "fair_web_cylinders", "spring",
                                     "schneider_kobbelt", "laplacian_fixed_boundary", "taubin_fixed_boundary")
#: Method keys of :func:`run_closed_example` (a noisy cylinder: closed structure lines).
CLOSED_METHODS: tuple[str, ...] = ("original", "fourier", "new", "fair_web", "spring", "schneider_kobbelt",
                                   "laplacian", "taubin")
#: Columns of the chapter-3 tables (plus seconds and iterations of each method).
CHAPTER3_COLUMNS: tuple[str, ...] = ("zigzag_max", "vertices_above_0.1", "boundary_displacement_max_h",
                                     "surface_distance_mean_h", "vertex_distance_mean_h", "relief_change_pct",
                                     "bbox_change_pct", "normal_offset_mean_h")
#: Tolerance cylinders of ``fair_web_cylinders``: radius and half-height as multiples of the noise's
#: tangential and normal amplitude (in local edge lengths, times the clean mesh's mean edge length).
CYLINDER_FACTOR = 2.0
#: The closed example: a cylinder (rows along the axis, vertices around), millimetres.
CLOSED_EXAMPLE = MappingProxyType(dict(rows=9, cols=32, radius=3000.0, height=4000.0, noise=(0.25, 0.1),
                                       keep=3, laplace=3, taubin=40, fair_iterations=3))


def _mesh_of(result: Any) -> QuadMesh:
    """The mesh of a method's result: ``(mesh, report)`` or (older smoothing) a mesh alone."""
    return result[0] if isinstance(result, tuple) else result


def _timed(fn: Callable[[], Any]) -> tuple[QuadMesh, Any, float]:
    t = time.perf_counter()
    out = fn()
    sec = time.perf_counter() - t
    rep = out[1] if isinstance(out, tuple) else None
    return _mesh_of(out), rep, sec


def _iterations(rep: Any) -> int:
    if rep is None:
        return 0
    it = getattr(rep, "iterations", 0)
    # fair_web's Newton solver counts its ADMM warm start apart
    return (len(it) if isinstance(it, list) else int(it)) + int(getattr(rep, "warm_start_iterations", 0))


@_validate.renamed(noise_fix="fix")
def run_chapter3(name: str, *, seed: int = 7, fix: Literal["corners", "boundary"] = "corners") -> ExampleResult:
    """Run the chapter-3 methods beside the thesis's method on one noisy example (same noise as :func:`run_example`).

    Methods (keys of :data:`CHAPTER3_METHODS`): ``new`` (the thesis's method with
    its parameters); ``fair_web`` (E2 of the structure-line network, eq. 11,
    boundary fixed); ``fair_web_cylinders`` (E2, corners fixed, every vertex
    inside a tolerance cylinder around its noisy position, radius and half-height
    :data:`CYLINDER_FACTOR` times the noise amplitudes); ``spring`` (Yamada et al.,
    boundary fixed); ``schneider_kobbelt`` (boundary and one ring fixed);
    Laplacian and Taubin with the boundary fixed. Rows carry ``seconds`` and
    ``iterations`` too.

    Raises
    ------
    InputError
        On an unknown example name, a bad seed or ``fix``.

    Examples
    --------
    >>> r = run_chapter3("E1")
    >>> [row["method"] for row in r.rows][:4]
    ['original', 'new', 'fair_web', 'fair_web_cylinders']
    """
    from .pde_fairing import schneider_kobbelt
    from .spring_model import spring
    from .webs import fair_web

    ex, clean, fine, noisy, seed, fix = _noisy_example(name, seed, fix)
    h = clean.mean_edge_length
    fp = dict(ex.fair)
    r, hc = CYLINDER_FACTOR * ex.noise[0] * h, CYLINDER_FACTOR * ex.noise[1] * h
    runs: dict[str, tuple[str, Callable[[], Any]]] = {
        "new": (f"New method, {_plural(fp['iterations'], 'iteration')}, ω = {fp['weight']:g}",
                lambda: _fair(noisy, **fp, **THESIS_FAIR)),
        "fair_web": ("Fair web E2, boundary fixed", lambda: fair_web(noisy, energy="E2", fix="boundary")),
        "fair_web_cylinders": (f"Fair web E2 in cylinders r = {r / h:.2g} h, ±{hc / h:.2g} h",
                               lambda: fair_web(noisy, energy="E2", fix="corners", cylinder_radius=r,
                                                cylinder_height=hc)),
        "spring": ("Spring model, boundary fixed", lambda: spring(noisy)),
        "schneider_kobbelt": ("Schneider–Kobbelt, boundary + ring fixed", lambda: schneider_kobbelt(noisy)),
        "laplacian_fixed_boundary": (f"Laplacian, {_plural(ex.laplace, 'step')}, boundary fixed",
                                     lambda: laplacian(noisy, iterations=ex.laplace, fix="boundary")),
        "taubin_fixed_boundary": (f"Taubin, {_plural(ex.taubin, 'iteration')}, boundary fixed",
                                  lambda: taubin(noisy, iterations=ex.taubin, fix="boundary")),
    }
    return _run_methods(ex, clean, fine, noisy, runs, seed, fix)


def _run_methods(ex: ThesisExample, clean: QuadMesh, fine: QuadMesh, noisy: QuadMesh,
                 runs: Mapping[str, tuple[str, Callable[[], Any]]], seed: int, fix: str) -> ExampleResult:
    t0 = time.perf_counter()
    res = ExampleResult(ex, clean)
    topo = noisy.topology
    res.meshes["original"], res.labels["original"] = noisy, "Original (noisy input)"
    res.free["original"] = np.zeros(noisy.n_vertices, dtype=bool)
    res.fixed["original"] = np.zeros(noisy.n_vertices, dtype=bool)
    extra: dict[str, tuple[float, int]] = {"original": (0.0, 0)}
    for key, (label, fn) in runs.items():
        mesh, rep, sec = _timed(fn)
        res.meshes[key], res.labels[key] = mesh, label
        moved = np.linalg.norm(mesh.vertices - noisy.vertices, axis=1) > 0
        res.free[key] = moved
        res.fixed[key] = ~moved & (topo.boundary_vertices if "boundary" in label or key in (
            "fair_web", "spring", "schneider_kobbelt") else topo.corner_vertices)
        extra[key] = (sec, _iterations(rep))
    frame = _boundary_frame(clean)
    h = clean.mean_edge_length
    for key in res.meshes:
        row: dict[str, Any] = {"example": ex.name, "seed": seed, "fix": fix, "method": key,
                               "label": res.labels[key], "edge_length_mm": h,
                               "seconds": extra[key][0], "iterations": extra[key][1]}
        row.update(measure(noisy, res.meshes[key], clean, fine, boundary_frame=frame))
        res.rows.append(row)
    res.seconds = time.perf_counter() - t0
    return res


def run_closed_example(*, seed: int = 7) -> ExampleResult:
    """Every method on a noisy open cylinder, whose rings are closed structure lines (for Fourier descriptors).

    The cylinder of :data:`CLOSED_EXAMPLE` (millimetres) gets the zigzag noise of
    the examples on its interior vertices (the two end rings stay clean); the
    methods: Fourier descriptors (keep harmonics 0…3), the thesis's method (3
    iterations, default settings), fair web (E2, end rings fixed), spring model,
    Schneider–Kobbelt, Laplacian (3 steps) and Taubin (40 iterations) with the end
    rings fixed.

    Examples
    --------
    >>> r = run_closed_example()
    >>> r.rows[1]["method"], r.rows[1]["zigzag_max"] < r.rows[0]["zigzag_max"]
    ('fourier', True)
    """
    from .fourier_descriptors import fourier
    from .mesh import cylinder
    from .pde_fairing import schneider_kobbelt
    from .spring_model import spring
    from .webs import fair_web

    seed = _check_seed(seed)
    c = CLOSED_EXAMPLE
    clean = cylinder(c["rows"], c["cols"], radius=c["radius"], height=c["height"])
    fine = cylinder(_SURFACE_REFINE * (c["rows"] - 1) + 1, _SURFACE_REFINE * c["cols"], radius=c["radius"],
                    height=c["height"])
    ex = ThesisExample("C1", "cylinder", c["rows"], c["cols"], c["laplace"], c["taubin"],
                       MappingProxyType(dict(iterations=c["fair_iterations"])), c["noise"], elev=25.0, azim=-60.0)
    noisy, _ = perturb(clean, tangential=c["noise"][0], normal=c["noise"][1], seed=seed, fix="boundary")
    runs: dict[str, tuple[str, Callable[[], Any]]] = {
        "fourier": (f"Fourier descriptors, harmonics 0–{c['keep']}", lambda: fourier(noisy, keep=c["keep"])),
        "new": (f"New method, {_plural(c['fair_iterations'], 'iteration')} (threshold 0.1, ω = 0.3)",
                lambda: _fair(noisy, iterations=c["fair_iterations"], threshold=0.1, **THESIS_FAIR)),
        "fair_web": ("Fair web E2, boundary fixed", lambda: fair_web(noisy, energy="E2", fix="boundary")),
        "spring": ("Spring model, boundary fixed", lambda: spring(noisy)),
        "schneider_kobbelt": ("Schneider–Kobbelt, boundary + ring fixed", lambda: schneider_kobbelt(noisy)),
        "laplacian": (f"Laplacian, {_plural(c['laplace'], 'step')}, boundary fixed",
                      lambda: laplacian(noisy, iterations=c["laplace"], fix="boundary")),
        "taubin": (f"Taubin, {_plural(c['taubin'], 'iteration')}, boundary fixed",
                   lambda: taubin(noisy, iterations=c["taubin"], fix="boundary")),
    }
    return _run_methods(ex, clean, fine, noisy, runs, seed, "boundary")


def format_chapter3_markdown(results: Sequence[ExampleResult], *, interior: Mapping[str, ExampleResult] | None = None,
                             closed: ExampleResult | None = None, figures: Mapping[str, str] | None = None) -> str:
    """The chapter-3 tables as Markdown: per example the :data:`CHAPTER3_COLUMNS`, seconds and iterations."""
    heads = {k: hdr for k, hdr, _ in COLUMNS}
    fmts = {k: f for k, _, f in COLUMNS}
    cols = list(CHAPTER3_COLUMNS)

    def table(res: ExampleResult) -> list[str]:
        out = ["| method | " + " | ".join(heads[k] for k in cols) + " | seconds | iterations |",
               "|---|" + "---:|" * (len(cols) + 2)]
        for row in res.rows:
            out.append(f"| {row['label']} | " + " | ".join(_cell(row[k], fmts[k]) for k in cols)
                       + f" | {row['seconds']:.3f} | {row['iterations']} |")
        return out + [""]

    lines = ["# The thesis's chapter-3 methods on its examples", "",
             "Written by `quadnodes compare`. Same noise, measures and units (mean edge lengths h of the clean "
             "mesh) as `comparison.md`; seconds: wall time of the method alone.", ""]
    for res in results:
        ex = res.example
        lines += [f"## {ex.name}: {ex.surface} {ex.rows}×{ex.cols}", ""]
        if figures and ex.name in figures:
            lines += [f"![{ex.name}]({figures[ex.name]})", ""]
        lines += [f"Noise tangential {ex.noise[0]:g} h, normal {ex.noise[1]:g} h, seed {res.rows[0]['seed']}, "
                  "corners fixed:", ""] + table(res)
        inner = interior.get(ex.name) if interior else None
        if inner is not None:
            lines += ["The same with the noise on interior vertices only (clean boundary):", ""] + table(inner)
    if closed is not None:
        lines += [f"## Closed lines: a cylinder {closed.example.rows}×{closed.example.cols} (rings closed)", ""]
        if figures and "C1" in figures:
            lines += [f"![C1]({figures['C1']})", ""]
        lines += [f"Noise tangential {closed.example.noise[0]:g} h, normal {closed.example.noise[1]:g} h, seed "
                  f"{closed.rows[0]['seed']}, end rings clean:", ""] + table(closed)
    return "\n".join(lines)


def chapter3_figure(res: ExampleResult, keys: Sequence[str], path: Path, *, size_px: int = 1200,
                    palette: int | None = 256) -> Path:
    """Panels of the given methods in a grid of three columns, with the example's camera and clean reference."""
    from . import viz

    rows = {r["method"]: r for r in res.rows}
    ex = res.example
    return viz.render_png(
        [res.meshes[k] for k in keys], path,
        titles=[res.labels[k] for k in keys], notes=[_note(rows[k]) for k in keys],
        free=[res.free[k] for k in keys], fixed=[res.fixed[k] for k in keys],
        reference=res.clean, elev=ex.elev, azim=ex.azim, size_px=size_px, palette=palette, ncols=3,
    )
