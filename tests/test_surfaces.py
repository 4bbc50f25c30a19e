"""Tests of quadnodes.surfaces: families, from_points, STEP, sampling paths, trims, orientation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from quadnodes import _occt, surfaces
from quadnodes.errors import InputError

build123d = pytest.importorskip("build123d")

FAMILIES = ["saddle", "s_shape", "wavy", "dome", "cylinder_segment", "torus_patch"]


@pytest.fixture(scope="module")
def family_faces() -> dict:
    return {name: getattr(surfaces, name)() for name in FAMILIES}


def position_grid(face, u, v) -> np.ndarray:
    """Reference: build123d's Face.position_at at every (u_i, v_j), shape (nu*nv, 3)."""
    return np.array([[tuple(face.position_at(a, b)) for b in v] for a in u]).reshape(-1, 3)


def random_params(rng: np.random.Generator, n: int) -> np.ndarray:
    """n strictly increasing parameters in [0, 1] (endpoints included half the time)."""
    x = np.sort(rng.random(n))
    if rng.random() < 0.5:
        x[0], x[-1] = 0.0, 1.0
    return x


def rational_face():
    """A rational B-spline face: an OCCT sphere patch converted to NURBS."""
    from OCP.Geom import Geom_RectangularTrimmedSurface, Geom_SphericalSurface
    from OCP.GeomConvert import GeomConvert
    from OCP.gp import gp_Ax3

    patch = Geom_RectangularTrimmedSurface(Geom_SphericalSurface(gp_Ax3(), 1000.0), 0.2, 1.5, -0.5, 0.7)
    bs = GeomConvert.SurfaceToBSplineSurface_s(patch)
    assert bs.IsURational()
    return _occt.face_from_geom(bs)


def periodic_face():
    """A u-periodic B-spline face: a full cylinder converted to B-spline form."""
    from OCP.Geom import Geom_CylindricalSurface, Geom_RectangularTrimmedSurface
    from OCP.GeomConvert import GeomConvert
    from OCP.gp import gp_Ax3

    cyl = Geom_RectangularTrimmedSurface(Geom_CylindricalSurface(gp_Ax3(), 500.0), 0.0, 2 * math.pi, 0.0, 800.0)
    bs = GeomConvert.SurfaceToBSplineSurface_s(cyl)
    assert bs.IsUPeriodic()
    return _occt.face_from_geom(bs)


def bezier_face():
    """A Geom_BezierSurface face (biquadratic), evaluated through its B-spline form."""
    from OCP.Geom import Geom_BezierSurface
    from OCP.gp import gp_Pnt

    Pnt2 = _occt.arrays()[0]
    arr = Pnt2(1, 3, 1, 4)
    for i in range(3):
        for j in range(4):
            arr.SetValue(i + 1, j + 1, gp_Pnt(10.0 * i, 7.0 * j, 3.0 * ((i - 1) ** 2 - (j - 1.5) ** 2)))
    return _occt.face_from_geom(Geom_BezierSurface(arr))


def quad_normals(mesh) -> np.ndarray:
    p = mesh.vertices[mesh.faces]
    return np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 1])


# ---------------------------------------------------------------------------
# families
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("name", FAMILIES)
def test_family_builds_valid_face_and_samples(family_faces, name):
    face = family_faces[name]
    assert face.is_valid
    mesh = surfaces.sample(face, 7, 5)
    assert mesh.grid_shape == (7, 5)
    assert mesh.n_vertices == 35 and mesh.n_faces == 24
    # the family's documented convention: the face normal points up at the centre
    assert face.normal_at(0.5, 0.5).Z > 0.5


def test_family_shapes_match_their_formulas():
    # saddle: z = rise (xi^2 - eta^2), exact
    f = surfaces.saddle(width=4.0, depth=2.0, rise=3.0)
    u = np.linspace(0, 1, 6)
    m = surfaces.sample(f, u=u, v=u)
    x, y, z = m.vertices.T
    np.testing.assert_allclose(z, 3.0 * ((x / 2) ** 2 - y**2), atol=1e-12)
    # dome: every sample on a sphere through the crown (0, 0, rise)
    span, rise = 6000.0, 1200.0
    radius = (span**2 / 4 + rise**2) / (2 * rise)
    m = surfaces.sample(surfaces.dome(span=span, rise=rise), 9, 9)
    centre = np.array([0.0, 0.0, rise - radius])
    np.testing.assert_allclose(np.linalg.norm(m.vertices - centre, axis=1), radius, rtol=1e-12)
    corners = m.vertices.reshape(9, 9, 3)[[0, -1], 4]  # middles of the edges v = 1/2
    np.testing.assert_allclose(corners[:, 2], 0.0, atol=1e-9)
    np.testing.assert_allclose(np.abs(corners[:, 0]), span / 2, rtol=1e-12)
    # cylinder segment: springing lines at z = 0, crown at r(1 - cos(a/2))
    m = surfaces.sample(surfaces.cylinder_segment(radius=2.0, length=3.0, angle=120.0), 5, 3)
    g = m.vertices.reshape(5, 3, 3)
    np.testing.assert_allclose(g[[0, -1], :, 2], 0.0, atol=1e-12)
    np.testing.assert_allclose(g[2, :, 2], 2.0 * (1 - math.cos(math.radians(60))), rtol=1e-12)
    # wavy: interpolates its formula at the nodes, close to it in between
    f = surfaces.wavy(width=4000, depth=8000, amplitude=500, waves_u=0.5, waves_v=1.5)
    s = np.linspace(0, 1, 37)
    m = surfaces.sample(f, u=s, v=s)
    x, y, z = m.vertices.T
    expect = 500 * np.cos(2 * np.pi * 0.5 * x / 4000) * np.cos(2 * np.pi * 1.5 * y / 8000)
    assert np.abs(z - expect).max() < 1e-3 * 500


@pytest.mark.parametrize(
    "call",
    [
        lambda: surfaces.saddle(width=0.0),
        lambda: surfaces.saddle(rise=-1.0),
        lambda: surfaces.s_shape(taper=1.5),
        lambda: surfaces.wavy(waves_u=0),
        lambda: surfaces.dome(span=1000.0, rise=600.0),
        lambda: surfaces.dome(span=1000.0, depth=5000.0, rise=100.0),
        lambda: surfaces.cylinder_segment(angle=360.0),
        lambda: surfaces.torus_patch(major=1.0, minor=2.0),
        lambda: surfaces.torus_patch(u_range=(10.0, 0.0)),
        lambda: surfaces.torus_patch(v_range=(0.0, float("nan"))),
    ],
)
def test_family_rejects_bad_settings(call):
    with pytest.raises(InputError):
        call()


@pytest.mark.parametrize("name", sorted(surfaces.EXAMPLES))
def test_examples_have_thesis_grid_sizes(name):
    _, nu, nv = surfaces.EXAMPLES[name]
    assert surfaces.example(name).grid_shape == (nu, nv)


# ---------------------------------------------------------------------------
# sampling paths agree with build123d's position_at
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("name", FAMILIES)
def test_auto_path_equals_position_at(family_faces, name):
    face = family_faces[name]
    rng = np.random.default_rng(FAMILIES.index(name))
    u, v = random_params(rng, 8), random_params(rng, 6)
    ref = position_grid(face, u, v)
    scale = np.abs(ref).max()
    for method in ("auto", "occt"):
        got = surfaces.sample(face, u=u, v=v, method=method).vertices
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-9 * scale)


@pytest.mark.parametrize(
    "make", [rational_face, periodic_face, bezier_face, lambda: surfaces.wavy()],
    ids=["rational", "periodic", "bezier", "plain"],
)
def test_bspline_fast_path_equals_position_at(make):
    face = make()
    rng = np.random.default_rng(7)
    u, v = random_params(rng, 9), random_params(rng, 7)
    ref = position_grid(face, u, v)
    got = surfaces.sample(face, u=u, v=v, method="bspline").vertices
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-9 * np.abs(ref).max())


def test_fast_paths_follow_moved_and_mirrored_faces():
    loc = build123d.Location((100.0, -50.0, 20.0), (1.0, 1.0, 0.0), 35.0)
    for face in (surfaces.s_shape().moved(loc), surfaces.torus_patch().moved(loc),
                 surfaces.saddle().mirror(build123d.Plane.XZ)):
        u = v = np.linspace(0, 1, 5)
        ref = position_grid(face, u, v)
        np.testing.assert_allclose(surfaces.sample(face, 5, 5).vertices, ref, atol=1e-9 * np.abs(ref).max())


def test_analytic_path_covers_plane_and_cone():
    cone = next(f for f in build123d.Solid.make_cone(100, 40, 200).faces() if f.geom_type.name == "CONE")
    for face in (build123d.Face.make_rect(100, 50), cone):
        u, v = np.linspace(0, 1, 4), np.linspace(0, 1, 3)
        got = surfaces.sample(face, u=u, v=v, method="analytic").vertices
        np.testing.assert_allclose(got, position_grid(face, u, v), atol=1e-9)


def test_method_that_does_not_apply_is_an_error(family_faces):
    with pytest.raises(InputError, match="bspline"):
        surfaces.sample(family_faces["dome"], 3, 3, method="bspline")
    with pytest.raises(InputError, match="analytic"):
        surfaces.sample(family_faces["saddle"], 3, 3, method="analytic")
    with pytest.raises(InputError, match="method"):
        surfaces.sample(family_faces["saddle"], 3, 3, method="fast")


# ---------------------------------------------------------------------------
# build123d's make_surface_from_array_of_points and our from_points
# ---------------------------------------------------------------------------


def test_make_surface_from_array_of_points_first_index_is_u():
    # 4 x 6 points: x grows with the first index, y with the second
    pts = [[(100.0 * i, 100.0 * j, 10.0 * math.sin(i) * math.cos(j)) for j in range(6)] for i in range(4)]
    face = build123d.Face.make_surface_from_array_of_points(pts)
    np.testing.assert_allclose(tuple(face.position_at(1, 0)), pts[3][0], atol=1e-2)
    np.testing.assert_allclose(tuple(face.position_at(0, 1)), pts[0][5], atol=1e-2)
    # and so sampling it gives grid_shape (rows, cols) with points[i, j] at vertex i*cols + j
    m = surfaces.sample(face, 4, 6)
    np.testing.assert_allclose(m.vertices.reshape(4, 6, 3)[[0, -1, 0, -1], [0, 0, -1, -1]],
                               np.array(pts)[[0, -1, 0, -1], [0, 0, -1, -1]], atol=1e-2)


@pytest.mark.parametrize("parametrization", ["uniform", "chord", "centripetal"])
@pytest.mark.parametrize("shape", [(2, 2), (3, 5), (6, 4), (13, 9)])
def test_from_points_interpolates_the_grid(parametrization, shape):
    rng = np.random.default_rng(shape[0] * 100 + shape[1])
    r, c = shape
    x = np.cumsum(rng.uniform(0.5, 2.0, r))  # uneven spacing
    y = np.cumsum(rng.uniform(0.5, 2.0, c))
    X, Y = np.meshgrid(x, y, indexing="ij")
    pts = np.stack([X, Y + 0.1 * X, np.sin(X) * np.cos(0.7 * Y)], axis=-1)
    face = surfaces.from_points(pts, parametrization=parametrization)
    u, v = surfaces.grid_parameters(pts, parametrization=parametrization)
    m = surfaces.sample(face, u=u, v=v)
    np.testing.assert_allclose(m.vertices, pts.reshape(-1, 3), atol=1e-9)
    # and OCCT agrees at the same parameters
    np.testing.assert_allclose(position_grid(face, u, v), pts.reshape(-1, 3), atol=1e-9)


def test_from_points_rejects_bad_input():
    with pytest.raises(InputError, match="rows, cols"):
        surfaces.from_points(np.zeros((1, 3, 3)))
    p = np.zeros((3, 3, 3))
    p[..., 0], p[..., 1] = np.meshgrid(np.arange(3.0), np.arange(3.0), indexing="ij")
    with pytest.raises(InputError, match="degree"):
        surfaces.from_points(p, degree=6)
    with pytest.raises(InputError, match="parametrization"):
        surfaces.from_points(p, parametrization="foley")
    q = p.copy()
    q[1] = q[0]  # rows 0 and 1 coincide
    with pytest.raises(InputError, match="coincide"):
        surfaces.from_points(q)
    q = p.copy()
    q[2, 2, 2] = np.nan
    with pytest.raises(InputError, match=r"\[2, 2\]"):
        surfaces.from_points(q)


# ---------------------------------------------------------------------------
# STEP
# ---------------------------------------------------------------------------


def test_step_round_trip(tmp_path):
    face = surfaces.wavy()
    path = tmp_path / "wavy.step"
    assert build123d.export_step(face, path)
    back = surfaces.from_step(path)
    u, v = np.linspace(0, 1, 9), np.linspace(0, 1, 7)
    a = surfaces.sample(face, u=u, v=v)
    b = surfaces.sample(back, u=u, v=v)
    np.testing.assert_allclose(b.vertices, a.vertices, atol=1e-6)
    np.testing.assert_array_equal(a.faces, b.faces)


def test_step_face_index(tmp_path):
    box = build123d.Box(10, 20, 30)
    path = tmp_path / "box.step"
    build123d.export_step(box, path)
    faces = [surfaces.from_step(path, face=k) for k in range(6)]
    assert sorted(round(f.area) for f in faces) == sorted(round(f.area) for f in box.faces())
    with pytest.raises(InputError, match=r"box\.step.*6 faces"):
        surfaces.from_step(path, face=6)
    with pytest.raises(InputError, match="6 faces"):
        surfaces.from_step(path, face=-1)
    with pytest.raises(InputError, match="does not exist"):
        surfaces.from_step(tmp_path / "missing.step")
    # no face= on a file with several: refused, listing them (face 0 was taken without a word), as from_file
    for reader in (surfaces.from_step, surfaces.from_file):
        with pytest.raises(InputError, match=r"^face: '[^']*box\.step' holds 6 faces \(0: \(unnamed\) \(a plane "
                                             r"face\), 1: .*\); pass face= an index or a name$"):
            reader(path)
    with pytest.raises(InputError, match="face: expected an index or a name, got 1.5"):
        surfaces.from_step(path, face=1.5)


def test_from_step_picks_a_face_by_its_label_whatever_the_suffix(tmp_path):
    from quadnodes.io import save_step
    from quadnodes.mesh import grid

    mesh = grid(3, 3, spacing=100.0, height=[[0, 0, 0], [0, 0, 0], [0, 0, 50]])
    p = save_step(mesh, tmp_path / "a.step", mode="assembly")
    q = p.rename(tmp_path / "a.txt")  # from_step reads STEP whatever the name; from_file goes by the suffix
    face = surfaces.from_step(q, face="P_1_1")
    assert tuple(face.center()) == pytest.approx((150.0, 150.0, 12.5))
    assert surfaces.from_step(q, face=3).area == pytest.approx(face.area)
    with pytest.raises(InputError, match=r"has no face named 'P_2_2' \(found 0: P_0_0 \(a plane face\)"):
        surfaces.from_step(q, face="P_2_2")


@pytest.mark.parametrize("reader", [surfaces.from_step, surfaces.from_file])
def test_a_damaged_step_file_is_called_unreadable_not_empty(tmp_path, reader):
    # build123d's import_step ignores the parser's status: a STEP file cut short, an empty file or another
    # format renamed .step gave "holds no faces" (no surface), which sends the designer looking for a
    # missing surface rather than a broken export
    good = tmp_path / "wavy.step"
    build123d.export_step(surfaces.wavy(), good)
    text = good.read_text()
    cases = {"cut.step": text[: len(text) // 2], "empty.step": "", "renamed.step": "v 0 0 0\nf 1 2 3 4\n"}
    for name, content in cases.items():
        (tmp_path / name).write_text(content)
        with pytest.raises(InputError, match=rf"^path: cannot read STEP file '.*{name}': not a STEP file, "
                                             r"or a damaged one \(cut short\?\)$"):
            reader(tmp_path / name)
    edge = tmp_path / "edge.step"  # a readable file that holds no face is still told so
    build123d.export_step(build123d.Edge.make_line((0, 0, 0), (1, 0, 0)), edge)
    with pytest.raises(InputError, match="holds no (faces|surface)"):
        reader(edge)


# ---------------------------------------------------------------------------
# trims, degeneracies, orientation, spacing
# ---------------------------------------------------------------------------


def test_trimmed_faces_are_rejected():
    disc = build123d.Face(build123d.Wire.make_circle(50))
    holed = build123d.Face.make_rect(100, 100) - build123d.Face(build123d.Wire.make_circle(10))
    corner = (surfaces.wavy() - build123d.Box(10, 10, 5000).moved(build123d.Location((-2000, -4000, 0)))).faces()[0]
    for face in (disc, holed, corner):
        with pytest.raises(InputError, match="trimmed"):
            surfaces.sample(face, 5, 5)
    # explicitly allowed: the underlying rectangle is sampled
    m = surfaces.sample(disc, 3, 3, allow_trimmed=True)
    np.testing.assert_allclose(m.vertices[0], [-50, -50, 0], atol=1e-9)


def test_rectangular_sub_patch_is_not_trimmed():
    from OCP.BRepTools import BRepTools

    whole = surfaces.wavy()
    surf = surfaces._geom_surface(whole)
    part = _occt.face_from_geom(surf, (0.2, 0.7, 0.1, 0.4))
    assert BRepTools.UVBounds_s(part.wrapped) == pytest.approx((0.2, 0.7, 0.1, 0.4))
    m = surfaces.sample(part, 4, 4)
    np.testing.assert_allclose(m.vertices[0], tuple(whole.position_at(0.2, 0.1)), atol=1e-9)


def test_degenerate_pole_is_an_error():
    sphere = build123d.Solid.make_sphere(10).faces()[0]
    with pytest.raises(InputError, match="coincide"):
        surfaces.sample(sphere, 5, 5)


@pytest.mark.parametrize("reverse", [False, True])
@pytest.mark.parametrize("make", [lambda: surfaces.saddle(), lambda: surfaces.dome(), rational_face,
                                  lambda: surfaces.torus_patch(v_range=(100.0, 200.0)),
                                  lambda: surfaces.s_shape().mirror(build123d.Plane.YZ)])
def test_faces_are_counter_clockwise_about_the_face_normal(make, reverse):
    face = make()
    if reverse:
        face = -face
    nu, nv = 6, 5
    m = surfaces.sample(face, nu, nv)
    normals = quad_normals(m)
    # quad (i, j) spans parameters [u_i, u_i+1] x [v_j, v_j+1]
    s = np.linspace(0, 1, nu)
    t = np.linspace(0, 1, nv)
    i, j = np.divmod(m.faces.min(axis=1), nv)
    ref = np.array([tuple(face.normal_at((s[a] + s[a + 1]) / 2, (t[b] + t[b + 1]) / 2)) for a, b in zip(i, j)])
    cos = np.einsum("ij,ij->i", normals, ref) / np.linalg.norm(normals, axis=1)
    assert (cos > 0.9).all()


def test_non_uniform_spacing():
    face = surfaces.saddle(width=2.0, depth=2.0, rise=0.0)  # flat: x = 2u - 1, y = 2v - 1
    u = np.array([0.0, 0.05, 0.2, 0.6, 1.0])
    v = np.array([0.0, 0.5, 0.9, 1.0])
    m = surfaces.sample(face, u=u, v=v)
    g = m.vertices.reshape(5, 4, 3)
    np.testing.assert_allclose(g[:, 0, 0], 2 * u - 1, atol=1e-12)
    np.testing.assert_allclose(g[0, :, 1], 2 * v - 1, atol=1e-12)
    # the count may be given too, and must agree
    assert surfaces.sample(face, 5, 4, u=u, v=v).grid_shape == (5, 4)
    with pytest.raises(InputError, match="does not match"):
        surfaces.sample(face, 6, 4, u=u, v=v)
    # on a non-linear parametrization too: the dome's longitude is proportional to u
    m = surfaces.sample(surfaces.dome(span=2.0, depth=1.0, rise=1.0), u=u, v=v)
    g = m.vertices.reshape(5, 4, 3)
    ang = np.arctan2(g[:, 0, 0], g[:, 0, 2])
    np.testing.assert_allclose((ang - ang[0]) / (ang[-1] - ang[0]), u, atol=1e-12)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(nu=1, nv=3), "nu"),
        (dict(nu=3), "nv"),
        (dict(nu=3.0, nv=3), "nu"),
        (dict(u=[0.0, 0.5, 0.5, 1.0], nv=3), "strictly increasing"),
        (dict(u=[0.0, 1.5], nv=3), r"\[0, 1\]"),
        (dict(u=[[0.0, 1.0]], nv=3), "1-D"),
        (dict(u=[0.0, np.inf], nv=3), "finite"),
    ],
)
def test_sample_rejects_bad_parameters(family_faces, kwargs, match):
    with pytest.raises(InputError, match=match):
        surfaces.sample(family_faces["saddle"], **kwargs)


def test_sample_accepts_a_single_face_shape_only(family_faces):
    shell = build123d.Shell([family_faces["saddle"]])
    assert surfaces.sample(shell, 3, 3).n_vertices == 9
    with pytest.raises(InputError, match="6 faces"):
        surfaces.sample(build123d.Box(1, 1, 1), 3, 3)
    with pytest.raises(InputError, match="Face"):
        surfaces.sample(np.zeros((3, 3)), 3, 3)


@settings(max_examples=25, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(name=st.sampled_from(FAMILIES), nu=st.integers(2, 30), nv=st.integers(2, 30))
def test_sampled_corners_are_the_face_corners(family_faces, name, nu, nv):
    face = family_faces[name]
    m = surfaces.sample(face, nu, nv)
    g = m.vertices.reshape(nu, nv, 3)
    for (a, b), p in zip([(0, 0), (1, 0), (0, 1), (1, 1)], [g[0, 0], g[-1, 0], g[0, -1], g[-1, -1]]):
        np.testing.assert_allclose(p, tuple(face.position_at(a, b)), atol=1e-9 * np.abs(g).max())


# --- from_file: STEP, IGES and Rhino .3dm (issue 13) --------------------------------------------


def _rhino_surface(rational, knots_u, knots_v, order_u, order_v, seed=0):
    import rhino3dm

    rng = np.random.default_rng(seed)
    cu, cv = len(knots_u) - order_u + 2, len(knots_v) - order_v + 2  # Rhino: n + order - 2 knots
    s = rhino3dm.NurbsSurface.Create(3, rational, order_u, order_v, cu, cv)
    for i, k in enumerate(knots_u):
        s.KnotsU[i] = k
    for i, k in enumerate(knots_v):
        s.KnotsV[i] = k
    for i in range(cu):
        for j in range(cv):
            w = rng.uniform(0.4, 2.5) if rational else 1.0
            x, y, z = 1000.0 * i + 90 * rng.normal(), 800.0 * j, 300.0 * rng.normal()
            s.Points[(i, j)] = rhino3dm.Point4d(x * w, y * w, z * w, w)  # homogeneous
    assert s.IsValid
    return s


def _write_3dm(path, *surfaces, names=(), unit=None):
    import rhino3dm

    model = rhino3dm.File3dm()
    model.Settings.ModelUnitSystem = unit or rhino3dm.UnitSystem.Millimeters
    for k, s in enumerate(surfaces):
        attrs = rhino3dm.ObjectAttributes()
        attrs.Name = names[k] if k < len(names) else ""
        if isinstance(s, rhino3dm.Brep):
            model.Objects.AddBrep(s, attrs)
        else:
            model.Objects.AddSurface(s, attrs)
    assert model.Write(str(path), 0)
    return path


def _max_gap(surface, face, scale=1.0):
    """Largest distance between rhino3dm's PointAt and OCCT's value at the same (u, v), and the size."""
    from OCP.BRep import BRep_Tool

    g = BRep_Tool.Surface_s(face.wrapped)
    d0, d1 = surface.Domain(0), surface.Domain(1)
    gap, size = 0.0, 0.0
    for a in np.linspace(d0.T0, d0.T1, 9):
        for b in np.linspace(d1.T0, d1.T1, 9):
            p, q = surface.PointAt(a, b), g.Value(a, b)
            r = np.array([p.X, p.Y, p.Z]) * scale
            gap = max(gap, float(np.abs(r - [q.X(), q.Y(), q.Z()]).max()))
            size = max(size, float(np.abs(r).max()))
    return gap, size


@pytest.mark.parametrize("rational", [False, True])
@pytest.mark.parametrize(
    "knots_u, knots_v, order_u, order_v",
    [
        ([0, 0, 0, 0.3, 0.35, 1, 1, 1], [0, 0, 0.25, 0.6, 1, 1], 4, 3),  # clamped, non-uniform
        ([0, 1, 2, 3.5, 4, 5, 6], [0, 0, 1, 2, 3, 3], 4, 3),  # unclamped in u
        ([2, 2, 5, 5], [0, 0, 0.5, 0.5, 1, 1], 3, 3),  # a shifted domain, a double inner knot
    ],
)
def test_rhino_nurbs_converts_exactly(tmp_path, rational, knots_u, knots_v, order_u, order_v):
    s = _rhino_surface(rational, knots_u, knots_v, order_u, order_v)
    face = surfaces.from_file(_write_3dm(tmp_path / "s.3dm", s))
    gap, size = _max_gap(s, face)
    assert gap <= 1e-9 * size


def test_rhino_units_become_millimetres(tmp_path):
    import rhino3dm

    s = _rhino_surface(True, [0, 0, 1, 1], [0, 0, 1, 1], 3, 3)
    face = surfaces.from_file(_write_3dm(tmp_path / "m.3dm", s, unit=rhino3dm.UnitSystem.Meters))
    gap, size = _max_gap(s, face, scale=1000.0)
    assert gap <= 1e-9 * size


def test_rhino_faces_by_name_index_and_the_errors(tmp_path):
    import rhino3dm

    a = _rhino_surface(False, [0, 0, 1, 1], [0, 0, 1, 1], 3, 3, seed=1)
    b = _rhino_surface(True, [0, 0, 0, 1, 1, 1], [0, 0, 1, 1], 4, 3, seed=2)
    p = _write_3dm(tmp_path / "two.3dm", a, b, names=["roof", "wall"])
    with pytest.raises(InputError, match=r"holds 2 faces \(0: roof \(a NurbsSurface\), 1: wall"):
        surfaces.from_file(p)
    assert _max_gap(b, surfaces.from_file(p, face="wall"))[0] < 1e-6
    assert _max_gap(a, surfaces.from_file(p, face=0))[0] < 1e-6
    with pytest.raises(InputError, match="no face named 'floor'"):
        surfaces.from_file(p, face="floor")
    with pytest.raises(InputError, match=r"index 2 is out of range.*valid indices 0..1"):
        surfaces.from_file(p, face=2)
    box = rhino3dm.Brep.CreateFromBoundingBox(rhino3dm.BoundingBox(0, 0, 0, 1000, 2000, 3000))
    p = _write_3dm(tmp_path / "box.3dm", box, names=["box"])
    with pytest.raises(InputError, match=r"holds 6 faces \(0: box\[0\] \(face 0 of a 6-face polysurface\)"):
        surfaces.from_file(p)
    assert surfaces.from_file(p, face="box[2]").area == pytest.approx(surfaces.from_file(p, face=2).area)
    assert surfaces.from_file(p, face=2).area in (pytest.approx(2e6), pytest.approx(3e6), pytest.approx(6e6))
    trimmed = rhino3dm.Brep.CreateTrimmedPlane(
        rhino3dm.Plane.WorldXY(), rhino3dm.Circle(rhino3dm.Point3d(0, 0, 0), 500.0).ToNurbsCurve()
    )
    p = _write_3dm(tmp_path / "disc.3dm", trimmed, names=["disc"])
    with pytest.raises(InputError, match=r"face 0 \(disc, face 0 of a 1-face polysurface\) .* is trimmed"):
        surfaces.from_file(p)
    assert surfaces.from_file(p, allow_trimmed=True).area > 0
    _write_3dm(tmp_path / "empty.3dm")
    with pytest.raises(InputError, match="holds no surface"):
        surfaces.from_file(tmp_path / "empty.3dm")


def test_from_file_step_iges_and_bad_paths(tmp_path):
    from build123d import Box, export_step
    from OCP.IGESControl import IGESControl_Writer

    face = surfaces.saddle()
    step = tmp_path / "s.step"
    export_step(face, step)
    a, b = surfaces.sample(surfaces.from_file(step), 5, 5), surfaces.sample(surfaces.from_step(step), 5, 5)
    assert np.array_equal(a.vertices, b.vertices)
    writer = IGESControl_Writer("MM", 0)
    writer.AddShape(face.wrapped)
    writer.ComputeModel()
    assert writer.Write(str(tmp_path / "s.igs"))
    c = surfaces.sample(surfaces.from_file(tmp_path / "s.igs"), 5, 5)
    np.testing.assert_allclose(c.vertices, a.vertices, atol=1e-6 * 5000)
    export_step(Box(10, 20, 30), tmp_path / "box.step")
    with pytest.raises(InputError, match="holds 6 faces .*pass face="):
        surfaces.from_file(tmp_path / "box.step")
    assert surfaces.from_file(tmp_path / "box.step", face=1).area > 0
    with pytest.raises(InputError, match="does not exist"):
        surfaces.from_file(tmp_path / "missing.3dm")
    (tmp_path / "x.obj").write_text("v 0 0 0\n")
    with pytest.raises(InputError, match="not a surface file"):
        surfaces.from_file(tmp_path / "x.obj")
    with pytest.raises(InputError, match="face: expected an index or a name"):
        surfaces.from_file(step, face=1.5)


def test_from_file_picks_a_step_face_by_its_label(tmp_path):
    from quadnodes.io import save_step
    from quadnodes.mesh import grid

    mesh = grid(3, 3, spacing=100.0, height=[[0, 0, 0], [0, 0, 0], [0, 0, 50]])
    p = save_step(mesh, tmp_path / "a.step", mode="assembly")
    with pytest.raises(InputError, match=r"holds 4 faces \(0: P_0_0 \(a plane face\).*3: P_1_1 \(a bspline face\)"):
        surfaces.from_file(p)
    face = surfaces.from_file(p, face="P_1_1")
    assert tuple(face.center()) == pytest.approx((150.0, 150.0, 12.5))
