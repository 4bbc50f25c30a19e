"""Numbers for comparing a processed mesh with its input (and a reference surface)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from . import _validate
from . import flatness as _planarity
from .errors import InputError
from .mesh import QuadMesh
from .zigzag import _mesh_window_deviation, vertex_deviation

__all__ = ["zigzag_stats", "distance_to_mesh", "compare"]


def zigzag_stats(mesh: QuadMesh, thresholds: Sequence[float] = (0.1, 0.01)) -> dict[str, float]:
    """Mean and max window deviation (eq. 30) and how many vertices exceed each threshold.

    A vertex counts when its per-vertex deviation (max over the windows in which
    it is a middle point) is strictly greater than the threshold.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> zigzag_stats(grid(4, 5))
    {'zigzag_mean': 0.0, 'zigzag_max': 0.0, 'vertices_above_0.1': 0, 'vertices_above_0.01': 0}
    """
    _validate.quad_mesh(mesh)
    if isinstance(thresholds, (str, bytes)) or not isinstance(thresholds, Sequence):
        raise InputError(f"thresholds: expected a list of numbers, got {thresholds!r}")
    thresholds = [_validate.nonnegative_number(t, f"thresholds[{i}]") for i, t in enumerate(thresholds)]
    w = mesh.topology.windows
    wd = _mesh_window_deviation(mesh)
    vd = vertex_deviation(wd, w, mesh.n_vertices)
    out: dict[str, float] = {
        "zigzag_mean": float(wd.mean()) if wd.size else 0.0,
        "zigzag_max": float(wd.max()) if wd.size else 0.0,
    }
    for t in thresholds:
        out[f"vertices_above_{t:g}"] = int((vd > t).sum())
    return out


def distance_to_mesh(points: np.ndarray, reference: QuadMesh) -> np.ndarray:
    """Distance from each point to the surface of ``reference``.

    The reference quads are split into two triangles each (along the diagonal
    ``p0p2``), so for non-planar reference quads this is the distance to that
    piecewise-flat surface; sample the reference finely when that matters.

    Parameters
    ----------
    points : (k, 3) float64
    reference : QuadMesh

    Returns
    -------
    (k,) float64
    """
    import trimesh  # heavy; only needed here

    f = reference.faces
    tris = np.concatenate([f[:, [0, 1, 2]], f[:, [0, 2, 3]]])
    tm = trimesh.Trimesh(reference.vertices, tris, process=False)
    _, dist, _ = trimesh.proximity.closest_point(tm, np.asarray(points, dtype=np.float64))
    return np.asarray(dist, dtype=np.float64)


def _bbox_diagonal(v: np.ndarray) -> float:
    return float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))


def compare(
    original: QuadMesh,
    result: QuadMesh,
    *,
    reference: Any = None,
    thresholds: Sequence[float] = (0.1, 0.01),
) -> dict[str, float]:
    """Everything the comparisons report, for ``result`` against ``original``.

    Parameters
    ----------
    original : QuadMesh
        The input of the processing step.
    result : QuadMesh
        Same faces as ``original``.
    reference : QuadMesh, build123d Face or Reference, optional
        The clean design surface (a face is sampled finely, see
        :func:`quadnodes.reference.as_reference`); adds ``reference_mean``/``reference_max`` (distance
        of the result's vertices to its surface, see :func:`distance_to_mesh`). When it
        has the same faces as ``result`` (e.g. the clean grid before noise was
        added), also ``reference_vertex_mean``/``reference_vertex_max``: the distance
        of each vertex to its counterpart, which also sees sliding within the surface.
    thresholds : sequence of float
        Zigzag thresholds for the vertex counts.

    Returns
    -------
    dict
        ``zigzag_mean``, ``zigzag_max``, ``vertices_above_<t>``, ``displacement_mean``,
        ``displacement_max``, ``boundary_displacement_max``, ``bbox_diagonal_change_pct``,
        ``planarity_mean``, ``planarity_max`` (relative diagonal distance),
        ``angle_defect_mean``, ``angle_defect_max`` (radians, absolute), and with a
        reference ``reference_mean``, ``reference_max``; all lengths in ``original``'s unit
        (a result or reference mesh in another unit is converted).

    Raises
    ------
    InputError
        If an argument is not a mesh (or a reference), or the two meshes do not
        share their faces.

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> m = grid(4, 4)
    >>> compare(m, m)["displacement_max"]
    0.0
    """
    _validate.quad_mesh(original, "original")
    _validate.quad_mesh(result, "result")
    if original.faces.shape != result.faces.shape or not np.array_equal(original.faces, result.faces):
        raise InputError("result: must have the same faces as original to compare vertex by vertex")
    result = result.with_unit(original.unit)  # every number in the original's unit
    if isinstance(reference, QuadMesh):
        reference = reference.with_unit(original.unit)
    out = zigzag_stats(result, thresholds)
    d = np.linalg.norm(result.vertices - original.vertices, axis=1)
    b = original.topology.boundary_vertices
    out["displacement_mean"] = float(d.mean())
    out["displacement_max"] = float(d.max())
    out["boundary_displacement_max"] = float(d[b].max()) if b.any() else 0.0
    d0 = _bbox_diagonal(original.vertices)
    out["bbox_diagonal_change_pct"] = 100.0 * (_bbox_diagonal(result.vertices) - d0) / d0
    pl = _planarity.planarity(result)
    for key, name in (("diagonal", "planarity"), ("angle_defect", "angle_defect")):
        s = _planarity.summary(pl[key])
        out[f"{name}_mean"] = s["mean"]
        out[f"{name}_max"] = s["max"]
    if reference is not None:
        if isinstance(reference, QuadMesh):
            r = distance_to_mesh(result.vertices, reference)
        else:
            from .reference import as_reference

            r = as_reference(reference, result).closest(result.vertices)[1]
        out["reference_mean"] = float(r.mean())
        out["reference_max"] = float(r.max())
        if isinstance(reference, QuadMesh) and np.array_equal(reference.faces, result.faces):
            dv = np.linalg.norm(result.vertices - reference.vertices, axis=1)
            out["reference_vertex_mean"] = float(dv.mean())
            out["reference_vertex_max"] = float(dv.max())
    return out
