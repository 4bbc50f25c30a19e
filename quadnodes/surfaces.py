"""Source surfaces (build123d faces) and their sampling into quad grids.

Three ways to get a surface, all returning a build123d ``Face``:

- built-in parametric families: :func:`saddle`, :func:`s_shape`, :func:`wavy`,
  :func:`dome`, :func:`cylinder_segment`, :func:`torus_patch`. Sizes are in
  millimetres (the defaults are a few metres across); nothing depends on the
  unit, so read them as unit-free if you prefer. In every family ``u`` runs
  along x and ``v`` along y (for :func:`torus_patch`: ``u`` around the z axis,
  ``v`` around the tube), and the face normal points up (+z) at the patch's
  centre.
- :func:`from_points`: a B-spline face *interpolating* a ``(rows, cols, 3)``
  grid of points (``points[i, j]`` lies at ``(u_i, v_j)``: the first index runs
  along ``u``), and :func:`grid_parameters` for those ``(u_i, v_j)``.
- :func:`from_file`: one face of a STEP, IGES or Rhino .3dm file (NURBS converted
  exactly), by index or name, refusing trimmed and ambiguous input with a message;
  :func:`from_step`: the same for a STEP file whatever its suffix (``face`` means the
  same in both: default the only face, an error listing them when there are several).

:func:`sample` turns any untrimmed face into a :class:`~quadnodes.mesh.QuadMesh`
on an ``nu × nv`` grid of ``(u, v)`` parameters, uniform or user-given. It
evaluates B-spline surfaces (rational or not, periodic or not) with SciPy from
the surface's poles and knots, the elementary surfaces (plane, cylinder, cone,
sphere, torus) in closed form, and anything else through OCCT one point at a
time.

:data:`EXAMPLES` and :func:`example` rebuild stand-ins for the four examples of
the thesis (E1 saddle 10×10, E2 S-shape 13×13, E3 and E4 smooth free-form
22×41).

build123d (and OCP under it) is imported inside the functions, so importing
this module stays cheap.
"""

from __future__ import annotations

import math
import os
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from . import _occt, _validate
from .errors import InputError
from .mesh import QuadMesh, grid_faces

if TYPE_CHECKING:
    from build123d import Face

__all__ = [
    "saddle",
    "s_shape",
    "wavy",
    "dome",
    "cylinder_segment",
    "torus_patch",
    "from_points",
    "grid_parameters",
    "from_step",
    "from_file",
    "sample",
    "EXAMPLES",
    "example",
]

Method = Literal["auto", "bspline", "analytic", "occt"]
Parametrization = Literal["uniform", "chord", "centripetal"]

#: Stand-ins for the thesis's examples: name -> (family, nu, nv), default family settings.
EXAMPLES: dict[str, tuple[str, int, int]] = {
    "E1": ("saddle", 10, 10),
    "E2": ("s_shape", 13, 13),
    "E3": ("wavy", 22, 41),
    "E4": ("dome", 22, 41),
}

# Relative area difference above which a face counts as trimmed (see ``sample``).
_TRIM_RTOL = 1e-6


# ----------------------------------------------------------------------------
# OCP helpers (lazy)
# ----------------------------------------------------------------------------


def _bspline_face(
    poles: np.ndarray, knots_u: np.ndarray, knots_v: np.ndarray, deg_u: int, deg_v: int
) -> Face:
    """A non-rational B-spline face from ``(nu, nv, 3)`` poles and flat (repeated) knot vectors."""
    from OCP.Geom import Geom_BSplineSurface
    from OCP.gp import gp_Pnt

    Pnt2, _, _, _ = _occt.arrays()

    nu, nv = poles.shape[:2]
    arr = Pnt2(1, nu, 1, nv)
    for i, row in enumerate(poles.tolist()):
        for j, p in enumerate(row):
            arr.SetValue(i + 1, j + 1, gp_Pnt(*p))
    ku, mu = _occt.knots_mults(knots_u)
    kv, mv = _occt.knots_mults(knots_v)
    return _occt.face_from_geom(Geom_BSplineSurface(arr, ku, kv, mu, mv, deg_u, deg_v))


def _as_face(face: Any) -> Face:
    """Accept a build123d Face, or any build123d shape holding exactly one face."""
    from build123d import Face, Shape

    if isinstance(face, Face):
        return face
    if isinstance(face, Shape):
        faces = face.faces()
        if len(faces) == 1:
            return faces[0]
        raise InputError(
            f"face: expected a build123d Face, got a {type(face).__name__} with {len(faces)} faces; "
            "pick one, e.g. shape.faces()[0]"
        )
    raise InputError(f"face: expected a build123d Face, got {type(face).__name__}")


def _geom_surface(face: Face) -> Any:
    """The face's surface in world coordinates (location applied), rectangular trims unwrapped."""
    from OCP.BRep import BRep_Tool
    from OCP.Geom import Geom_RectangularTrimmedSurface

    surf = BRep_Tool.Surface_s(face.wrapped)  # one-argument form: a located copy when needed
    while isinstance(surf, Geom_RectangularTrimmedSurface):
        surf = surf.BasisSurface()
    return surf


def _area(topo_face: Any) -> float:
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    props = GProp_GProps()
    BRepGProp.SurfaceProperties_s(topo_face, props)
    return float(props.Mass())


# ----------------------------------------------------------------------------
# Parametric families
# ----------------------------------------------------------------------------


def _grid_st(n_s: int, n_t: int) -> tuple[np.ndarray, np.ndarray]:
    s, t = np.meshgrid(np.linspace(0.0, 1.0, n_s), np.linspace(0.0, 1.0, n_t), indexing="ij")
    return s, t


def _samples_per(waves: float, per_wave: int = 16, minimum: int = 9) -> int:
    return max(minimum, int(math.ceil(per_wave * waves)) + 1)


def saddle(width: float = 5000.0, depth: float = 5000.0, rise: float = 1000.0) -> Face:
    """A hyperbolic paraboloid over a ``width × depth`` rectangle.

    ``z = rise · (ξ² − η²)`` with ``ξ = 2x/width``, ``η = 2y/depth`` in ``[-1, 1]``:
    the corners lie at ``z = 0``, the middles of the edges along x at ``-rise``
    and those along y at ``+rise``. Represented exactly as a biquadratic Bézier
    (B-spline) surface; ``u`` runs along x, ``v`` along y, both over ``[0, 1]``.

    Parameters
    ----------
    width, depth : float
        Extent along x and y (> 0), centred on the origin.
    rise : float
        Height of the saddle's highs above its corners (>= 0; 0 gives a plane).

    Returns
    -------
    build123d.Face

    Raises
    ------
    InputError
        On a non-positive size or a negative or non-finite rise.

    Examples
    --------
    >>> f = saddle(width=2.0, depth=2.0, rise=1.0)
    >>> [round(c, 9) for c in f.position_at(0.5, 0.0)]
    [0.0, -1.0, -1.0]
    """
    w = _validate.positive_number(width, "width")
    d = _validate.positive_number(depth, "depth")
    h = _validate.nonnegative_number(rise, "rise")
    x = np.array([-w / 2, 0.0, w / 2])
    y = np.array([-d / 2, 0.0, d / 2])
    b = np.array([1.0, -1.0, 1.0])  # Bernstein coefficients of (2s - 1)^2
    poles = np.stack(
        np.broadcast_arrays(x[:, None], y[None, :], h * (b[:, None] - b[None, :])), axis=-1
    )
    knots = np.array([0.0, 0.0, 0.0, 1.0, 1.0, 1.0])
    return _bspline_face(poles, knots, knots, 2, 2)


def s_shape(
    width: float = 6000.0,
    depth: float = 6000.0,
    rise: float = 1200.0,
    *,
    taper: float = 0.5,
    bend: float = 600.0,
) -> Face:
    """A free-form sheet whose sections along x are S-shaped.

    With ``s, t`` in ``[0, 1]`` (``u = s`` along x, ``v = t`` along y)::

        x = width·(s − ½) + bend·sin(π t)
        y = depth·(t − ½)
        z = rise·sin(2π s)·(1 − taper·t)

    so every section ``t = const`` is one full sine wave (an S lying on its side)
    whose amplitude shrinks along y, and the sheet bows in plan by ``bend``. The
    face is the bicubic B-spline interpolating these formulas on a uniform
    ``17 × 9`` grid (it deviates from them by well under 0.1 % of ``rise``).

    Parameters
    ----------
    width, depth : float
        Extent along x and y (> 0).
    rise : float
        Amplitude of the S at ``t = 0`` (>= 0).
    taper : float
        Relative loss of amplitude from ``t = 0`` to ``t = 1``, in ``[0, 1]``.
    bend : float
        Sideways bow in plan of the middle section (>= 0).

    Returns
    -------
    build123d.Face

    Raises
    ------
    InputError
        On a non-positive size, a negative ``rise`` or ``bend``, or ``taper``
        outside ``[0, 1]``.

    Examples
    --------
    >>> f = s_shape()
    >>> [round(c, 6) for c in f.position_at(0.25, 0.0)]
    [-1500.0, -3000.0, 1200.0]
    """
    w = _validate.positive_number(width, "width")
    d = _validate.positive_number(depth, "depth")
    h = _validate.nonnegative_number(rise, "rise")
    tp = _validate.nonnegative_number(taper, "taper")
    if tp > 1.0:
        raise InputError(f"taper: must be in [0, 1], got {taper!r}")
    b = _validate.nonnegative_number(bend, "bend")
    s, t = _grid_st(17, 9)
    pts = np.stack(
        [
            w * (s - 0.5) + b * np.sin(np.pi * t),
            d * (t - 0.5),
            h * np.sin(2 * np.pi * s) * (1.0 - tp * t),
        ],
        axis=-1,
    )
    return from_points(pts, parametrization="uniform")


def wavy(
    width: float = 4000.0,
    depth: float = 8000.0,
    amplitude: float = 500.0,
    *,
    waves_u: float = 0.5,
    waves_v: float = 1.5,
) -> Face:
    """A wavy sheet: a product of two cosine waves over a ``width × depth`` rectangle.

    With ``s, t`` in ``[0, 1]`` (``u = s`` along x, ``v = t`` along y)::

        z = amplitude · cos(2π·waves_u·(s − ½)) · cos(2π·waves_v·(t − ½))

    The defaults give one arch across x and three half waves along y. The face is
    the bicubic B-spline interpolating the formula on a uniform grid with 16
    points per wave (at least 9 per direction); it deviates from the formula by
    about 1e-4 of the amplitude.

    Parameters
    ----------
    width, depth : float
        Extent along x and y (> 0), centred on the origin.
    amplitude : float
        Height of the crests (>= 0).
    waves_u, waves_v : float
        Number of full waves along x and along y (> 0).

    Returns
    -------
    build123d.Face

    Raises
    ------
    InputError
        On a non-positive size or wave count, or a negative amplitude.

    Examples
    --------
    >>> f = wavy()
    >>> [round(c, 6) for c in f.position_at(0.5, 0.5)]
    [0.0, 0.0, 500.0]
    """
    w = _validate.positive_number(width, "width")
    d = _validate.positive_number(depth, "depth")
    a = _validate.nonnegative_number(amplitude, "amplitude")
    ku = _validate.positive_number(waves_u, "waves_u")
    kv = _validate.positive_number(waves_v, "waves_v")
    s, t = _grid_st(_samples_per(ku), _samples_per(kv))
    z = a * np.cos(2 * np.pi * ku * (s - 0.5)) * np.cos(2 * np.pi * kv * (t - 0.5))
    pts = np.stack([w * (s - 0.5), d * (t - 0.5), z], axis=-1)
    return from_points(pts, parametrization="uniform")


def dome(span: float = 6000.0, depth: float = 6000.0, rise: float = 1200.0) -> Face:
    """A spherical patch: a dome over a roughly ``span × depth`` plan.

    The sphere's axis is the y axis; ``u`` is the longitude (the arc across x)
    and ``v`` the latitude (towards ±y), so the patch has no pole. The sphere
    radius is ``R = (span²/4 + rise²) / (2·rise)``: the central arc ``v = 0`` is a
    great circle whose chord is ``span`` (at ``z = 0``) and whose crown is at
    ``z = rise``; the latitudes reach ``±asin(depth / 2R)``, so the central arc
    ``u = ½`` has chord ``depth``. The surface is an exact OCCT sphere, sampled
    in closed form by :func:`sample`.

    Parameters
    ----------
    span : float
        Chord of the central arc across x (> 0).
    depth : float
        Chord of the central arc along y (> 0, less than ``2R``).
    rise : float
        Height of the crown above the chord (> 0, at most ``span / 2``).

    Returns
    -------
    build123d.Face

    Raises
    ------
    InputError
        On non-positive values, ``rise > span / 2`` (more than a half sphere
        across x), or ``depth >= 2R`` (the patch would reach the poles).

    Examples
    --------
    >>> f = dome(span=2.0, depth=1.0, rise=1.0)
    >>> [round(c, 9) for c in f.position_at(0.5, 0.5)]
    [0.0, 0.0, 1.0]
    """
    from OCP.Geom import Geom_SphericalSurface
    from OCP.gp import gp_Ax3, gp_Dir, gp_Pnt

    c = _validate.positive_number(span, "span")
    d = _validate.positive_number(depth, "depth")
    h = _validate.positive_number(rise, "rise")
    if h > c / 2:
        raise InputError(f"rise: at most span/2 = {c / 2:g} (a half sphere), got {rise!r}")
    radius = (c * c / 4 + h * h) / (2 * h)
    if d >= 2 * radius:
        raise InputError(
            f"depth: must be less than the sphere's diameter {2 * radius:g} "
            f"(span {c:g}, rise {h:g}), got {depth!r}"
        )
    half_u = math.acos((radius - h) / radius)  # the chord at z = 0; rise <= span/2 keeps it <= 90°
    half_v = math.asin(d / (2 * radius))
    # axis +y, x-direction +z: longitude u = 0 points up, increasing u turns towards +x
    ax = gp_Ax3(gp_Pnt(0.0, 0.0, h - radius), gp_Dir(0.0, 1.0, 0.0), gp_Dir(0.0, 0.0, 1.0))
    # right-handed, so its y-direction is +y × +z = +x: the latitude v tilts towards +y,
    # and Su × Sv (the face normal) points outwards, up at the crown
    return _occt.face_from_geom(Geom_SphericalSurface(ax, radius), (-half_u, half_u, -half_v, half_v))


def cylinder_segment(radius: float = 5000.0, length: float = 8000.0, angle: float = 90.0) -> Face:
    """A barrel vault: part of a circular cylinder whose axis is parallel to y.

    ``u`` runs around the axis (across x) over ``angle`` degrees centred on the
    crown, ``v`` along the axis (y) over ``[-length/2, length/2]``. The springing
    lines (the edges along y) lie at ``z = 0``, the crown at
    ``z = radius·(1 − cos(angle/2))``. An exact OCCT cylinder, sampled in closed
    form by :func:`sample`.

    Parameters
    ----------
    radius : float
        Cylinder radius (> 0).
    length : float
        Extent along the axis (> 0).
    angle : float
        Opening angle in degrees, in ``(0, 360)``.

    Returns
    -------
    build123d.Face

    Raises
    ------
    InputError
        On a non-positive size or an angle outside ``(0, 360)``.

    Examples
    --------
    >>> f = cylinder_segment(radius=1.0, length=2.0, angle=180.0)
    >>> [round(c, 9) for c in f.position_at(0.5, 0.5)]
    [0.0, 0.0, 1.0]
    """
    from OCP.Geom import Geom_CylindricalSurface
    from OCP.gp import gp_Ax3, gp_Dir, gp_Pnt

    r = _validate.positive_number(radius, "radius")
    ln = _validate.positive_number(length, "length")
    a = _validate.positive_number(angle, "angle")
    if a >= 360.0:
        raise InputError(f"angle: must be in (0, 360) degrees, got {angle!r}")
    half = math.radians(a) / 2
    ax = gp_Ax3(gp_Pnt(0.0, 0.0, -r * math.cos(half)), gp_Dir(0.0, 1.0, 0.0), gp_Dir(0.0, 0.0, 1.0))
    return _occt.face_from_geom(Geom_CylindricalSurface(ax, r), (-half, half, -ln / 2, ln / 2))


def torus_patch(
    major: float = 6000.0,
    minor: float = 2000.0,
    *,
    u_range: tuple[float, float] = (-45.0, 45.0),
    v_range: tuple[float, float] = (0.0, 90.0),
) -> Face:
    """A patch of a torus around the z axis.

    ``u`` is the angle around the z axis (0 at +x), ``v`` the angle around the
    tube (0 on the outer equator, 90 on top, 180 on the inner equator), both in
    degrees. ``v`` between -90 and 90 gives a dome-like (synclastic) patch, ``v``
    between 90 and 270 a saddle-like one. An exact OCCT torus, sampled in closed
    form by :func:`sample`.

    Parameters
    ----------
    major : float
        Distance from the z axis to the tube's centre circle (> 0).
    minor : float
        Tube radius (> 0, less than ``major``).
    u_range, v_range : (float, float)
        Start and end angles in degrees (start < end, spanning at most 360).

    Returns
    -------
    build123d.Face

    Raises
    ------
    InputError
        On non-positive radii, ``minor >= major``, or a bad angle range.

    Examples
    --------
    >>> f = torus_patch(major=3.0, minor=1.0, u_range=(0.0, 90.0), v_range=(0.0, 90.0))
    >>> [round(c, 9) for c in f.position_at(0.0, 1.0)]
    [3.0, 0.0, 1.0]
    """
    from OCP.Geom import Geom_ToroidalSurface
    from OCP.gp import gp_Ax3

    big = _validate.positive_number(major, "major")
    small = _validate.positive_number(minor, "minor")
    if small >= big:
        raise InputError(f"minor: must be less than major = {big:g}, got {minor!r}")
    bounds = []
    for name, rng in (("u_range", u_range), ("v_range", v_range)):
        if np.ndim(rng) != 1 or len(rng) != 2:
            raise InputError(f"{name}: expected (start, end) in degrees, got {rng!r}")
        a0 = _validate.finite_number(rng[0], f"{name}[0]")
        a1 = _validate.finite_number(rng[1], f"{name}[1]")
        if not a0 < a1 <= a0 + 360.0:
            raise InputError(f"{name}: expected start < end <= start + 360 degrees, got {rng!r}")
        bounds += [math.radians(a0), math.radians(a1)]
    return _occt.face_from_geom(Geom_ToroidalSurface(gp_Ax3(), big, small), tuple(bounds))  # type: ignore[arg-type]


# ----------------------------------------------------------------------------
# From points and from STEP
# ----------------------------------------------------------------------------


def _direction_parameters(p: np.ndarray, parametrization: str, name: str) -> np.ndarray:
    """Averaged parameters along axis 0 of ``(n, m, 3)`` points (Piegl & Tiller, eq. 9.5)."""
    n = p.shape[0]
    if parametrization == "uniform":
        return np.linspace(0.0, 1.0, n)
    d = np.linalg.norm(np.diff(p, axis=0), axis=2)  # (n-1, m)
    if parametrization == "centripetal":
        d = np.sqrt(d)
    total = d.sum(axis=0)
    ok = total > 0
    if not ok.any():
        raise InputError(f"points: all {name} coincide, no {parametrization} parameters exist")
    t = np.vstack([np.zeros((1, int(ok.sum()))), np.cumsum(d[:, ok], axis=0) / total[ok]]).mean(axis=1)
    t[0], t[-1] = 0.0, 1.0
    same = np.flatnonzero(np.diff(t) <= 0)
    if same.size:
        k = int(same[0])
        raise InputError(
            f"points: {name} {k} and {k + 1} coincide everywhere; interpolation needs distinct {name}"
        )
    return t


def grid_parameters(
    points: ArrayLike, *, parametrization: Parametrization = "chord"
) -> tuple[np.ndarray, np.ndarray]:
    """The ``(u_i, v_j)`` in ``[0, 1]`` at which :func:`from_points` interpolates ``points[i, j]``.

    Parameters
    ----------
    points : (rows, cols, 3) float
        Grid of points; ``points[i, j]`` goes to ``(u_i, v_j)``.
    parametrization : {"chord", "centripetal", "uniform"}
        ``"uniform"``: evenly spaced. ``"chord"``: cumulative distances along each
        column (for ``u``) or row (for ``v``), normalized and averaged over the
        columns (rows). ``"centripetal"``: the same with square roots of the
        distances (smoother for very uneven spacing).

    Returns
    -------
    u : (rows,) float64
    v : (cols,) float64
        Increasing, from 0 to 1. Pass them to :func:`sample` as ``u=``, ``v=`` to
        get the points back.

    Raises
    ------
    InputError
        On a bad shape, a non-finite point, an unknown parametrization, or two
        rows (columns) that coincide everywhere.

    Examples
    --------
    >>> p = np.zeros((3, 2, 3)); p[:, :, 0] = [[0, 0], [1, 1], [4, 4]]; p[:, 1, 1] = 1
    >>> [a.tolist() for a in grid_parameters(p)]
    [[0.0, 0.25, 1.0], [0.0, 1.0]]
    """
    p = _validate.point_grid(points)
    if parametrization not in ("uniform", "chord", "centripetal"):
        raise InputError(
            f"parametrization: expected 'uniform', 'chord' or 'centripetal', got {parametrization!r}"
        )
    u = _direction_parameters(p, parametrization, "rows")
    v = _direction_parameters(np.swapaxes(p, 0, 1), parametrization, "columns")
    return u, v


def from_points(
    points: ArrayLike, *, parametrization: Parametrization = "chord", degree: int = 3
) -> Face:
    """A B-spline face that interpolates a grid of points.

    ``points[i, j]`` lies on the face at ``(u_i, v_j)`` from
    :func:`grid_parameters` (the first index runs along ``u``). The surface is the
    tensor-product interpolant (not-a-knot end conditions for odd degree, as
    :func:`scipy.interpolate.make_interp_spline`) with clamped knots and parameter
    range ``[0, 1]²``, built directly as an OCCT ``Geom_BSplineSurface``. Unlike
    build123d's ``Face.make_surface_from_array_of_points`` (an approximation
    within a tolerance, whose first index also maps to ``u`` despite its
    docstring), it passes through the points exactly.

    Parameters
    ----------
    points : (rows, cols, 3) float
        At least 2 × 2 points.
    parametrization : {"chord", "centripetal", "uniform"}
        How the interpolation parameters are chosen, see :func:`grid_parameters`.
    degree : int
        Spline degree in both directions, 1..5; lowered to ``rows - 1`` or
        ``cols - 1`` where there are too few points.

    Returns
    -------
    build123d.Face

    Raises
    ------
    InputError
        As :func:`grid_parameters`, or on a degree outside 1..5.

    Examples
    --------
    >>> u, v = np.meshgrid(np.linspace(0, 1, 4), np.linspace(0, 2, 5), indexing="ij")
    >>> pts = np.stack([u, v, u * v], axis=-1)
    >>> f = from_points(pts, parametrization="uniform")
    >>> np.allclose(sample(f, 4, 5).vertices, pts.reshape(-1, 3))
    True
    """
    from scipy.interpolate import make_interp_spline

    deg = _validate.positive_int(degree, "degree")
    if deg > 5:
        raise InputError(f"degree: must be in 1..5, got {degree!r}")
    p = _validate.point_grid(points)
    pu, pv = grid_parameters(p, parametrization=parametrization)
    ku = min(deg, p.shape[0] - 1)
    kv = min(deg, p.shape[1] - 1)
    su = make_interp_spline(pu, p, k=ku)  # along u, every column at once
    q = np.asarray(su.c)  # (n_u, cols, 3)
    sv = make_interp_spline(pv, np.swapaxes(q, 0, 1), k=kv)  # along v
    poles = np.swapaxes(np.asarray(sv.c), 0, 1)  # (n_u, n_v, 3)
    return _bspline_face(poles, np.asarray(su.t), np.asarray(sv.t), ku, kv)


def from_step(
    path: str | os.PathLike[str],
    *,
    face: int | str | None = None,
    allow_trimmed: bool = False,
) -> Face:
    """One face of a STEP file (whatever its file name ends with), by the rule of :func:`from_file`.

    The file is read with build123d's ``import_step`` (which gives a compound,
    shell, solid, ...); its faces are numbered in OCCT's exploration order, the
    same order as ``shape.faces()``. :func:`from_file` reads STEP too (by the
    ``.step``/``.stp`` suffix), and IGES and Rhino .3dm; ``face`` means the same in both.

    Parameters
    ----------
    path : str or os.PathLike
        The STEP file.
    face : int or str, optional
        Which face: an index ``0 <= face < number of faces``, or a STEP label. Default: the
        only face, and an error listing the faces when the file holds several.
    allow_trimmed : bool
        Accept a trimmed face (a hole, a cut edge); its whole underlying surface is returned.
        Default: refuse it, saying what was found.

    Returns
    -------
    build123d.Face

    Raises
    ------
    InputError
        If the file does not exist or is unreadable; holds no face; holds several and ``face``
        is not given; ``face`` is out of range or names none of them; or the face is trimmed
        (without ``allow_trimmed``). Messages name the file and list the faces found.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from build123d import export_step
    >>> tmp = pathlib.Path(tempfile.mkdtemp()) / "saddle.step"
    >>> _ = export_step(saddle(), tmp)
    >>> from_step(tmp).geom_type.name
    'BSPLINE'
    """
    _check_face_choice(face)
    fs = os.fspath(path)
    if not os.path.isfile(fs):
        raise InputError(f"path: STEP file {fs!r} does not exist")
    faces, trimmed, found = _faces_occt(fs, ".step")
    if not faces:
        raise InputError(f"path: STEP file {fs!r} holds no faces")
    return _pick_face(fs, faces, trimmed, found, face, allow_trimmed)


def _check_face_choice(face: Any) -> None:
    """Raise unless ``face`` is None, an integer index or a name (the one rule of ``face=``)."""
    if face is not None and (isinstance(face, (bool, np.bool_)) or not isinstance(face, (int, np.integer, str))):
        raise InputError(f"face: expected an index or a name, got {face!r}")


def _check_step_parses(fs: str) -> None:
    """Raise when OCCT's STEP parser fails on ``fs`` (build123d's ``import_step`` ignores its status and
    gives an empty shape). Called only when the import found no face, so a sound file is parsed once.

    Raises
    ------
    InputError
        Naming the file as unreadable: not STEP, or damaged (cut short).
    """
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.STEPControl import STEPControl_Reader

    if STEPControl_Reader().ReadFile(fs) != IFSelect_RetDone:
        raise InputError(f"path: cannot read STEP file {fs!r}: not a STEP file, or a damaged one (cut short?)")


def from_file(
    path: str | os.PathLike[str],
    *,
    face: int | str | None = None,
    allow_trimmed: bool = False,
) -> Face:
    """The designer's surface from a STEP, IGES or Rhino .3dm file, as a build123d face.

    A .3dm surface (a NURBS surface, or any Rhino surface or polysurface face in its NURBS form)
    is converted exactly: control points, weights and knots carried over
    (:func:`quadnodes.io.rhino.nurbs_face`), scaled from the file's unit to millimetres. STEP and
    IGES are read by OCCT, which gives millimetres too.

    Parameters
    ----------
    path : str or os.PathLike
        ``.step``/``.stp``, ``.iges``/``.igs`` or ``.3dm``.
    face : int or str, optional
        Which face: an index (in file order: OCCT's exploration order for STEP/IGES; object
        order, every polysurface face in turn, for .3dm) or a name (a .3dm object name, with
        ``[k]`` for face ``k`` of a polysurface; a STEP label). Default: the only face, and an
        error naming what was found when there are several.
    allow_trimmed : bool
        Accept a trimmed face (a hole, a cut edge); its whole underlying surface is returned.
        Default: refuse it, saying what was found.

    Returns
    -------
    build123d.Face

    Raises
    ------
    InputError
        If the file is missing, of an unknown type or unreadable; holds no face; holds several
        and ``face`` is not given; ``face`` names none of them; or the face is trimmed (without
        ``allow_trimmed``). Messages name the file and list the faces found.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from build123d import export_step
    >>> tmp = pathlib.Path(tempfile.mkdtemp()) / "saddle.step"
    >>> _ = export_step(saddle(), tmp)
    >>> from_file(tmp).geom_type.name
    'BSPLINE'
    """
    _check_face_choice(face)
    fs = os.fspath(path)
    if not os.path.isfile(fs):
        raise InputError(f"path: file {fs!r} does not exist")
    ext = os.path.splitext(fs)[1].lower()
    if ext == ".3dm":
        faces, trimmed, found = _faces_3dm(fs)
    elif ext in (".step", ".stp", ".iges", ".igs"):
        faces, trimmed, found = _faces_occt(fs, ext)
    else:
        raise InputError(f"path: {fs!r} is not a surface file quadnodes reads (.step, .stp, .iges, .igs, .3dm)")
    if not faces:
        raise InputError(f"path: {fs!r} holds no surface")
    return _pick_face(fs, faces, trimmed, found, face, allow_trimmed)


def _pick_face(fs: str, faces: list[Any], trimmed: list[bool] | None, found: list[tuple[str, str]],
               face: int | str | None, allow_trimmed: bool) -> Face:
    """The face ``face`` picks from a file's ``faces`` (the only one when None), trim-checked.

    Raises
    ------
    InputError
        Several faces and no ``face``; an index out of range; a name found nowhere or twice; a trimmed face
        (without ``allow_trimmed``). Messages name the file ``fs`` and list the faces found.
    """
    names = [n for n, _ in found]
    listing = ", ".join(f"{i}: {n or '(unnamed)'} ({what})" for i, (n, what) in enumerate(found[:8]))
    listing += ", ..." if len(found) > 8 else ""
    if face is None:
        if len(faces) > 1:
            raise InputError(
                f"face: {fs!r} holds {len(faces)} faces ({listing}); pass face= an index or a name"
            )
        k = 0
    elif isinstance(face, str):
        if face not in names:
            raise InputError(f"face: {fs!r} has no face named {face!r} (found {listing})")
        if names.count(face) > 1:
            raise InputError(f"face: {fs!r} has {names.count(face)} faces named {face!r}; pick one by index ({listing})")
        k = names.index(face)
    else:
        if not 0 <= face < len(faces):
            raise InputError(
                f"face: index {face} is out of range, {fs!r} has {len(faces)} face"
                f"{'s' if len(faces) != 1 else ''} (valid indices 0..{len(faces) - 1})"
            )
        k = int(face)
    result = faces[k]() if callable(faces[k]) else faces[k]
    if trimmed is not None and not allow_trimmed:
        if trimmed[k]:
            raise InputError(
                f"face: face {k} ({found[k][0] or 'unnamed'}, {found[k][1]}) of {fs!r} is trimmed (not its whole "
                "underlying surface); split it into four-sided untrimmed surfaces in Rhino (e.g. Untrim or "
                "ShrinkTrimmedSrf when the trim follows the surface's edges), or pass allow_trimmed=True to use "
                "the whole underlying surface"
            )
    elif trimmed is None and not allow_trimmed:
        from OCP.BRepTools import BRepTools

        bounds = tuple(float(b) for b in BRepTools.UVBounds_s(result.wrapped))
        _check_untrimmed(result, _geom_surface(result), bounds)  # type: ignore[arg-type]
    return result


def _faces_3dm(fs: str) -> tuple[list[Any], list[bool], list[tuple[str, str]]]:
    from .io.rhino import nurbs_face, rhino_faces
    from .units import to_unit

    entries, unit = rhino_faces(fs)
    scale = to_unit(1.0, unit, "mm")
    makers = [(lambda s=s: nurbs_face(s, scale=scale)) for _, s, _, _ in entries]
    return makers, [t for _, _, t, _ in entries], [(n, what) for n, _, _, what in entries]


def _faces_occt(fs: str, ext: str) -> tuple[list[Any], None, list[tuple[str, str]]]:
    from build123d import Face, Shape

    if ext in (".step", ".stp"):
        from build123d import import_step

        try:
            shape = import_step(fs)
        except (OSError, ValueError, RuntimeError) as exc:
            raise InputError(f"path: cannot read STEP file {fs!r} ({exc})") from None
        if not shape.faces():
            _check_step_parses(fs)
    else:
        from OCP.IFSelect import IFSelect_RetDone
        from OCP.IGESControl import IGESControl_Reader

        reader = IGESControl_Reader()
        if reader.ReadFile(fs) != IFSelect_RetDone:
            raise InputError(f"path: cannot read IGES file {fs!r}")
        reader.TransferRoots()
        shape = Shape.cast(reader.OneShape())
    faces = shape.faces()
    labels: dict[int, str] = {}

    def walk(s: Any) -> None:
        for child in getattr(s, "children", ()) or ():
            sub = child.faces()
            if getattr(child, "label", "") and len(sub) == 1:
                labels[hash(sub[0])] = child.label
            walk(child)

    walk(shape)
    found = [(labels.get(hash(f), getattr(f, "label", "") or ""), f"a {f.geom_type.name.lower()} face") for f in faces]
    return [Face(f.wrapped) if not isinstance(f, Face) else f for f in faces], None, found


# ----------------------------------------------------------------------------
# Sampling
# ----------------------------------------------------------------------------


def _axis(n: int | None, given: ArrayLike | None, name: str, count: str) -> np.ndarray:
    if given is None:
        if n is None:
            raise InputError(f"{count}: give a vertex count or a parameter array {name}=")
        return np.linspace(0.0, 1.0, _validate.positive_int(n, count, minimum=2))
    a = _validate.unit_parameters(given, name)
    if n is not None and _validate.positive_int(n, count, minimum=2) != a.size:
        raise InputError(f"{count}: {n} does not match the {a.size} parameters given in {name}=")
    return a


def _is_bspline(surf: Any) -> bool:
    from OCP.Geom import Geom_BezierSurface, Geom_BSplineSurface

    return isinstance(surf, (Geom_BSplineSurface, Geom_BezierSurface))


def _is_analytic(surf: Any) -> bool:
    from OCP.Geom import (
        Geom_ConicalSurface,
        Geom_CylindricalSurface,
        Geom_Plane,
        Geom_SphericalSurface,
        Geom_ToroidalSurface,
    )

    return isinstance(
        surf, (Geom_Plane, Geom_CylindricalSurface, Geom_ConicalSurface, Geom_SphericalSurface, Geom_ToroidalSurface)
    )


def _bspline_data(surf: Any) -> tuple[np.ndarray, np.ndarray | None, np.ndarray, np.ndarray, int, int]:
    """Poles (nu, nv, 3), weights (nu, nv) or None, flat knots u and v, degrees; non-periodic."""
    from OCP.Geom import Geom_BezierSurface
    from OCP.GeomConvert import GeomConvert

    if isinstance(surf, Geom_BezierSurface):
        surf = GeomConvert.SurfaceToBSplineSurface_s(surf)  # same parametrization on [0, 1]
    if surf.IsUPeriodic() or surf.IsVPeriodic():
        surf = surf.Copy()  # the same geometry and parametrization, without wrap-around
        if surf.IsUPeriodic():
            surf.SetUNotPeriodic()
        if surf.IsVPeriodic():
            surf.SetVNotPeriodic()
    Pnt2, Real1, _, Real2 = _occt.arrays()
    nu, nv = surf.NbUPoles(), surf.NbVPoles()
    arr = Pnt2(1, nu, 1, nv)
    surf.Poles(arr)  # the filling overloads copy; the returning ones hand out internals
    poles = np.array(
        [[arr.Value(i, j).Coord() for j in range(1, nv + 1)] for i in range(1, nu + 1)], dtype=np.float64
    )
    weights = None
    if surf.IsURational() or surf.IsVRational():
        w = Real2(1, nu, 1, nv)
        surf.Weights(w)
        weights = np.array([[w.Value(i, j) for j in range(1, nv + 1)] for i in range(1, nu + 1)])

    def flat(length: int, fill: Any) -> np.ndarray:
        k = Real1(1, length)
        fill(k)
        return np.array([k.Value(i) for i in range(1, length + 1)])

    du, dv = surf.UDegree(), surf.VDegree()
    tu = flat(nu + du + 1, surf.UKnotSequence)
    tv = flat(nv + dv + 1, surf.VKnotSequence)
    return poles, weights, tu, tv, du, dv


def _design(x: np.ndarray, t: np.ndarray, k: int) -> Any:
    from scipy.interpolate import BSpline

    lo, hi = t[k], t[len(t) - k - 1]
    return BSpline.design_matrix(np.clip(x, lo, hi), t, k)


def _eval_bspline(surf: Any, uu: np.ndarray, vv: np.ndarray) -> np.ndarray:
    """Tensor-product evaluation on the grid ``uu × vv`` (raw parameters): ``(nu, nv, 3)``."""
    poles, weights, tu, tv, du, dv = _bspline_data(surf)
    bu = _design(uu, tu, du)  # (Nu, n_u) sparse
    bv = _design(vv, tv, dv)  # (Nv, n_v) sparse
    n_u, n_v = poles.shape[:2]
    coef = poles if weights is None else np.concatenate([poles * weights[..., None], weights[..., None]], axis=2)
    dim = coef.shape[2]
    a = bu @ coef.reshape(n_u, n_v * dim)  # (Nu, n_v*dim)
    a = a.reshape(len(uu), n_v, dim).transpose(1, 0, 2).reshape(n_v, len(uu) * dim)
    b = (bv @ a).reshape(len(vv), len(uu), dim).transpose(1, 0, 2)  # (Nu, Nv, dim)
    if weights is None:
        return np.ascontiguousarray(b)
    return b[..., :3] / b[..., 3:]


def _eval_analytic(surf: Any, uu: np.ndarray, vv: np.ndarray) -> np.ndarray:
    """Closed-form evaluation of OCCT's elementary surfaces (formulas of ElSLib)."""
    from OCP.Geom import Geom_ConicalSurface, Geom_CylindricalSurface, Geom_Plane, Geom_SphericalSurface

    ax = surf.Position()
    o = np.array(ax.Location().Coord())
    x = np.array(ax.XDirection().Coord())
    y = np.array(ax.YDirection().Coord())
    z = np.array(ax.Direction().Coord())
    U = uu[:, None, None]
    V = vv[None, :, None]
    if isinstance(surf, Geom_Plane):
        return o + U * x + V * y
    radial = np.cos(U) * x + np.sin(U) * y
    if isinstance(surf, Geom_CylindricalSurface):
        return o + surf.Radius() * radial + V * z
    if isinstance(surf, Geom_ConicalSurface):
        ang = surf.SemiAngle()
        return o + (surf.RefRadius() + V * math.sin(ang)) * radial + V * math.cos(ang) * z
    if isinstance(surf, Geom_SphericalSurface):
        r = surf.Radius()
        return o + r * np.cos(V) * radial + r * np.sin(V) * z
    big, small = surf.MajorRadius(), surf.MinorRadius()
    return o + (big + small * np.cos(V)) * radial + small * np.sin(V) * z


def _eval_occt(face: Face, uu: np.ndarray, vv: np.ndarray) -> np.ndarray:
    """One OCCT evaluation per point (BRepAdaptor_Surface.Value, location applied)."""
    from OCP.BRepAdaptor import BRepAdaptor_Surface

    ad = BRepAdaptor_Surface(face.wrapped)
    value = ad.Value
    vl = vv.tolist()
    return np.array([[value(a, b).Coord() for b in vl] for a in uu.tolist()], dtype=np.float64).reshape(
        len(uu), len(vv), 3
    )


def _perimeter_out(face: Face, bounds: tuple[float, float, float, float], per_side: int = 16) -> tuple[float, float] | None:
    """First normalized (u, v) just inside the parameter rectangle's perimeter that lies outside the face."""
    from OCP.gp import gp_Pnt2d
    from OCP.IntTools import IntTools_FClass2d
    from OCP.TopAbs import TopAbs_OUT

    u0, u1, v0, v1 = bounds
    inset = 1e-6
    t = np.linspace(inset, 1.0 - inset, per_side).tolist()
    probes = [(a, inset) for a in t] + [(a, 1 - inset) for a in t]
    probes += [(inset, b) for b in t] + [(1 - inset, b) for b in t]
    classifier = IntTools_FClass2d(face.wrapped, 1e-9)
    for a, b in probes:
        if classifier.Perform(gp_Pnt2d(u0 + a * (u1 - u0), v0 + b * (v1 - v0)), True) == TopAbs_OUT:
            return a, b
    return None


def _check_untrimmed(face: Face, surf: Any, bounds: tuple[float, float, float, float]) -> None:
    u0, u1, v0, v1 = bounds
    where = f"u in [{u0:g}, {u1:g}], v in [{v0:g}, {v1:g}]"
    advice = (
        "so grid samples would fall off the face. Split it into four-sided untrimmed faces, refit "
        "it (e.g. sample points on it and use from_points), or pass allow_trimmed=True to sample "
        "the whole underlying rectangle anyway"
    )
    out = _perimeter_out(face, bounds)
    if out is not None:
        raise InputError(
            "face: the face is trimmed (not the whole (u, v) rectangle of its surface): the "
            f"normalized parameter point ({out[0]:.6g}, {out[1]:.6g}) of its bounds {where} lies "
            f"outside it, {advice}"
        )
    face_area = _area(face.wrapped)
    patch_area = _area(_occt.face_from_geom(surf, bounds).wrapped)
    if abs(face_area - patch_area) > _TRIM_RTOL * max(patch_area, 1e-300):
        raise InputError(
            "face: the face is trimmed (not the whole (u, v) rectangle of its surface): its area "
            f"{face_area:.6g} differs from the area {patch_area:.6g} of the untrimmed patch over "
            f"its parameter bounds {where} (a hole or a notch?), {advice}"
        )


def sample(
    face: Face,
    nu: int | None = None,
    nv: int | None = None,
    *,
    u: ArrayLike | None = None,
    v: ArrayLike | None = None,
    method: Method = "auto",
    allow_trimmed: bool = False,
) -> QuadMesh:
    """Sample a face on an ``nu × nv`` grid of surface parameters into a quad mesh.

    Parameters are normalized: ``0`` and ``1`` are the face's own parameter
    bounds (``BRepTools.UVBounds``), as in build123d's ``Face.position_at``, so
    vertex ``(i, j)`` equals ``face.position_at(u[i], v[j])``.

    Parameters
    ----------
    face : build123d.Face
        The surface (a shape holding exactly one face is accepted too). It must be
        untrimmed: its boundary is the full rectangle of its parameter bounds.
        Two checks enforce it: 64 parameter points just inside the rectangle's
        perimeter must classify as inside the face (catches cut corners and
        edges), and the face's area must equal that of its surface over the
        rectangle to a relative 1e-6 (catches holes and notches).
    nu, nv : int, optional
        Vertex counts along ``u`` and ``v`` (>= 2), evenly spaced. May be left out
        when ``u`` or ``v`` is given; must match its length otherwise.
    u, v : (nu,) and (nv,) float, optional
        Strictly increasing normalized parameters in ``[0, 1]`` for non-uniform
        spacing (e.g. from :func:`grid_parameters`).
    method : {"auto", "bspline", "analytic", "occt"}
        ``"bspline"``: SciPy B-spline basis matrices times the surface's poles
        (homogeneous coordinates when rational), for B-spline and Bézier surfaces.
        ``"analytic"``: closed form for planes, cylinders, cones, spheres and tori.
        ``"occt"``: one ``BRepAdaptor_Surface`` evaluation per point (any surface,
        ~100× slower). ``"auto"`` takes the first that applies. All agree to
        rounding error.
    allow_trimmed : bool
        Skip the trim check and sample the whole underlying parameter rectangle
        even when the face covers only part of it (samples may lie off the face).

    Returns
    -------
    QuadMesh
        ``nu * nv`` vertices with ``grid_shape == (nu, nv)``: vertex ``i*nv + j``
        is the point at ``(u[i], v[j])``. Faces are counter-clockwise seen from
        the side the face's normal (``face.normal_at``) points to, whichever the
        face's orientation. On a surface closed in ``u`` or ``v`` sampled over its
        full period, the seam vertices are duplicated (the mesh stays open there).

    Raises
    ------
    InputError
        On bad counts or parameters; if the face is trimmed (see ``face``); if
        ``method`` does not apply to the face's surface; or if
        neighbouring samples coincide (a pole or apex inside the grid).

    Examples
    --------
    >>> m = sample(saddle(), 10, 10)
    >>> m.grid_shape, m.n_faces
    ((10, 10), 81)
    >>> m = sample(dome(), u=[0.0, 0.1, 0.5, 0.9, 1.0], v=np.linspace(0, 1, 4))
    >>> m.grid_shape
    (5, 4)
    """
    from OCP.BRepTools import BRepTools
    from OCP.TopAbs import TopAbs_REVERSED

    f = _as_face(face)
    if method not in ("auto", "bspline", "analytic", "occt"):
        raise InputError(f"method: expected 'auto', 'bspline', 'analytic' or 'occt', got {method!r}")
    su = _axis(nu, u, "u", "nu")
    sv = _axis(nv, v, "v", "nv")
    bounds = tuple(float(b) for b in BRepTools.UVBounds_s(f.wrapped))
    u0, u1, v0, v1 = bounds
    surf = _geom_surface(f)
    if not allow_trimmed:
        _check_untrimmed(f, surf, bounds)  # type: ignore[arg-type]
    uu = np.where(su == 1.0, u1, u0 + su * (u1 - u0))
    vv = np.where(sv == 1.0, v1, v0 + sv * (v1 - v0))

    kind = type(surf).__name__
    if method == "auto":
        method = "bspline" if _is_bspline(surf) else "analytic" if _is_analytic(surf) else "occt"
    if method == "bspline":
        if not _is_bspline(surf):
            raise InputError(f"method: 'bspline' does not apply to a {kind}; use 'auto' or 'occt'")
        pts = _eval_bspline(surf, uu, vv)
    elif method == "analytic":
        if not _is_analytic(surf):
            raise InputError(f"method: 'analytic' does not apply to a {kind}; use 'auto' or 'occt'")
        pts = _eval_analytic(surf, uu, vv)
    else:
        pts = _eval_occt(f, uu, vv)

    if not np.isfinite(pts).all():
        raise InputError(f"face: evaluating the {kind} gave non-finite points")
    # coincident neighbours (to rounding, relative to the patch size) mean a degenerate edge
    tiny = 1e-12 * float(np.linalg.norm(pts.reshape(-1, 3).max(axis=0) - pts.reshape(-1, 3).min(axis=0)))
    for axis, label in ((0, "u"), (1, "v")):
        step = np.linalg.norm(np.diff(pts, axis=axis), axis=2)
        if (step <= tiny).any():
            i, j = (int(k) for k in np.argwhere(step <= tiny)[0])
            raise InputError(
                f"face: samples ({i}, {j}) and ({i + (axis == 0)}, {j + (axis == 1)}) coincide along {label} "
                "(the surface degenerates there, e.g. a pole or an apex); a quad grid cannot include it"
            )
    # grid_faces' cycles run along j (v) then i (u): normal along Sv × Su = -(Su × Sv).
    # The face normal is Su × Sv, reversed when the face is REVERSED.
    faces = grid_faces(len(uu), len(vv))
    if f.wrapped.Orientation() != TopAbs_REVERSED:
        faces = faces[:, ::-1]
    return QuadMesh(pts.reshape(-1, 3), np.ascontiguousarray(faces), grid_shape=(len(uu), len(vv)))


def example(name: str, *, method: Method = "auto") -> QuadMesh:
    """Sample one of the stand-in thesis examples from :data:`EXAMPLES`.

    ``"E1"``: :func:`saddle` on 10 × 10 vertices; ``"E2"``: :func:`s_shape`
    13 × 13; ``"E3"``: :func:`wavy` 22 × 41; ``"E4"``: :func:`dome` 22 × 41, each
    with its default settings. The surfaces are shaped like the thesis's
    examples, not copies of its data.

    Parameters
    ----------
    name : str
        A key of :data:`EXAMPLES`.
    method : str
        Passed to :func:`sample`.

    Returns
    -------
    QuadMesh

    Raises
    ------
    InputError
        On an unknown name.

    Examples
    --------
    >>> example("E3").grid_shape
    (22, 41)
    """
    if name not in EXAMPLES:
        raise InputError(f"name: unknown example {name!r}, expected one of {sorted(EXAMPLES)}")
    family, nu, nv = EXAMPLES[name]
    return sample(globals()[family](), nu, nv, method=method)
