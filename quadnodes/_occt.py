"""The few OCCT building blocks that the surface readers share (package-private; imported whole).

``surfaces`` (the design surfaces, STEP/IGES faces) and ``io.rhino`` (Rhino NURBS surfaces)
both build OCCT B-spline surfaces and faces from NumPy arrays; this module holds the pieces
once. OCP and build123d are imported inside the functions, so importing this module is free.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .errors import InputError

__all__ = ["arrays", "knots_mults", "face_from_geom"]


def arrays() -> tuple[Any, Any, Any, Any]:
    """OCCT array classes: (Array2 of gp_Pnt, Array1 of double, Array1 of int, Array2 of double)."""
    try:  # OCP >= 7.9 exposes NCollection arrays here
        from OCP.collections import Array1_double, Array1_int, Array2_double, Array2_gp_Pnt

        return Array2_gp_Pnt, Array1_double, Array1_int, Array2_double
    except ImportError:  # older OCP
        from OCP.TColgp import TColgp_Array2OfPnt
        from OCP.TColStd import TColStd_Array1OfInteger, TColStd_Array1OfReal, TColStd_Array2OfReal

        return TColgp_Array2OfPnt, TColStd_Array1OfReal, TColStd_Array1OfInteger, TColStd_Array2OfReal


def knots_mults(t: np.ndarray) -> tuple[Any, Any]:
    """A flat knot vector (repeated knots) as OCCT's distinct knots and their multiplicities.

    Examples
    --------
    >>> k, m = knots_mults(np.array([0.0, 0.0, 0.5, 1.0, 1.0]))
    >>> [k.Value(i) for i in range(1, 4)], [m.Value(i) for i in range(1, 4)]
    ([0.0, 0.5, 1.0], [2, 1, 2])
    """
    _, Real1, Int1, _ = arrays()
    k, m = np.unique(np.asarray(t, dtype=np.float64), return_counts=True)
    ka, ma = Real1(1, len(k)), Int1(1, len(m))
    for i, (x, n) in enumerate(zip(k.tolist(), m.tolist(), strict=True)):
        ka.SetValue(i + 1, x)
        ma.SetValue(i + 1, n)
    return ka, ma


def face_from_geom(surface: Any, bounds: tuple[float, float, float, float] | None = None) -> Any:
    """A build123d Face on a Geom_Surface, over its natural bounds or ``(u0, u1, v0, v1)``.

    Raises
    ------
    InputError
        If OCCT cannot make a face on the surface.
    """
    from build123d import Face
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace
    from OCP.Precision import Precision

    tol = Precision.Confusion_s()
    if bounds is None:
        maker = BRepBuilderAPI_MakeFace(surface, tol)
    else:
        maker = BRepBuilderAPI_MakeFace(surface, *bounds, tol)
    if not maker.IsDone():  # pragma: no cover - OCCT refuses only broken geometry
        raise InputError(f"OCCT could not make a face on the surface (error {maker.Error()})")
    return Face(maker.Face())
