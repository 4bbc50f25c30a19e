import os
import re

import numpy as np
import pytest

from build123d import Face, GeomType, import_step

from quadnodes.errors import ExportError, InputError
from quadnodes.io import step as step_mod
from quadnodes.flatness import planar_panels as planar_mask
from quadnodes.io.panels import panel_labels
from quadnodes.io.step import STEP_MODES, save_step, step_shape
from quadnodes.mesh import QuadMesh, cylinder, grid
from meshes import extraordinary_mesh

MODES = list(STEP_MODES)


def mixed_grid() -> QuadMesh:
    """4×5 grid: the first row of panels flat, the rest curved (a saddle)."""
    y, x = np.meshgrid(np.arange(4.0), np.arange(5.0), indexing="ij")
    z = np.where(y >= 1, 0.15 * (x - 2) * (y - 1), 0.0)
    return grid(4, 5, spacing=10.0, height=z)


def quad_normal(p):
    return np.cross(p[2] - p[0], p[3] - p[1])


def only_file(folder, name):
    assert sorted(os.listdir(folder)) == [name], os.listdir(folder)


def test_mixed_grid_is_mixed():
    kinds = planar_mask(mixed_grid())
    assert kinds.sum() == 4 and (~kinds).sum() == 8


@pytest.mark.parametrize("mode", MODES)
def test_each_mode_reads_back_with_import_step(tmp_path, mode):
    m = mixed_grid()
    path = save_step(m, tmp_path / f"{mode}.step", mode=mode)
    assert path == tmp_path / f"{mode}.step"
    only_file(tmp_path, f"{mode}.step")
    back = import_step(path)
    assert len(back.faces()) == m.n_faces
    kinds = [f.geom_type for f in back.faces()]
    assert kinds.count(GeomType.PLANE) == 4
    assert kinds.count(GeomType.BSPLINE) == 8  # STEP stores the Bezier patches as B-splines
    if mode == "assembly":
        assert back.label == "panels"
        assert [c.label for c in back.children] == panel_labels(m)
        assert all(len(c.faces()) == 1 for c in back.children)


def test_gmsh_reads_every_mode_with_the_same_face_count(tmp_path, gmsh_face_counts):
    m = mixed_grid()
    paths = [save_step(m, tmp_path / f"{mode}.step", mode=mode) for mode in MODES]
    irregular = extraordinary_mesh(levels=1)
    paths.append(save_step(irregular, tmp_path / "irregular.step", mode="shell"))
    assert gmsh_face_counts(*paths) == [m.n_faces] * 3 + [irregular.n_faces]


def test_assembly_labels_without_grid_are_face_indices(tmp_path):
    m = extraordinary_mesh(levels=1)
    back = import_step(save_step(m, tmp_path / "a.step", mode="assembly"))
    assert [c.label for c in back.children] == [f"P_{k}" for k in range(m.n_faces)]


def test_grid_labels_use_row_and_col_of_first_vertex():
    m = grid(3, 4)
    labels = panel_labels(m)
    assert labels[0] == "P_0_0" and labels[2] == "P_0_2" and labels[3] == "P_1_0"
    asm = step_shape(m, mode="assembly")
    assert [c.label for c in asm.children] == labels


def test_flat_grid_gives_planes_after_read_back(tmp_path):
    m = grid(4, 4, spacing=(1000.0, 700.0))
    for mode in MODES:
        back = import_step(save_step(m, tmp_path / f"{mode}.step", mode=mode))
        assert {f.geom_type for f in back.faces()} == {GeomType.PLANE}


def test_twisted_quad_gives_a_bilinear_patch(tmp_path):
    p = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 1], [0, 1, 0.0]])
    m = QuadMesh(p, [[0, 1, 2, 3]])
    built = step_shape(m).faces()[0]
    assert built.geom_type == GeomType.BEZIER
    # the same surface and orientation as build123d's own constructor with poles [[p0, p3], [p1, p2]]
    ref = Face.make_bezier_surface([[p[0], p[3]], [p[1], p[2]]])
    for uv in [(0.2, 0.7), (0.5, 0.5), (0.9, 0.1)]:
        assert (built.position_at(*uv) - ref.position_at(*uv)).length < 1e-12
        assert (built.normal_at(*uv) - ref.normal_at(*uv)).length < 1e-12
    assert np.dot(tuple(built.normal_at(0.5, 0.5)), quad_normal(p)) > 0
    back = import_step(save_step(m, tmp_path / "t.step")).faces()[0]
    assert back.geom_type == GeomType.BSPLINE
    for face in (built, back):
        corners = sorted(tuple(np.round(tuple(v), 12)) for v in face.vertices())
        assert corners == sorted(map(tuple, p))
        # the patch passes through its centre (the mean of the corners for a bilinear patch)
        assert face.distance_to(tuple(p.mean(axis=0))) < 1e-9
        # a point on an edge lies on the straight segment: the boundary is the quad's edges
        assert face.distance_to((0.5, 0.0, 0.0)) < 1e-9


@pytest.mark.parametrize("mode", MODES)
def test_face_normals_follow_the_quads_ccw_normal(tmp_path, mode):
    m = mixed_grid()
    p = m.vertices[m.faces]
    built = step_shape(m, mode=mode)
    back = import_step(save_step(m, tmp_path / "n.step", mode=mode))
    for shape in (built, back):
        faces = shape.faces()
        assert len(faces) == m.n_faces
        for face in faces:
            c = np.array(tuple(face.center()))
            k = int(np.argmin(np.linalg.norm(p.mean(axis=1) - c, axis=1)))
            n = np.array(tuple(face.normal_at(face.center())))
            assert np.dot(n, quad_normal(p[k])) > 0.99 * np.linalg.norm(quad_normal(p[k]))


def test_nearly_planar_panels_beyond_occt_tolerance_are_valid_planes(tmp_path):
    # 1 m panels in mm, out of plane by a relative 3e-7 (about 0.6 µm): OCCT's own
    # MakeFace(wire, OnlyPlane) refuses such a polygon (its limit is ~1e-6 absolute).
    i, j = np.indices((3, 3))
    m = grid(3, 3, spacing=1000.0, height=2e-4 * (-1.0) ** (i + j))
    rel = step_mod.diagonal_distance(m)
    absolute = step_mod.diagonal_distance(m, relative=False)
    assert (rel < 1e-6).all() and (absolute > 1e-5).all()
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace, BRepBuilderAPI_MakePolygon
    from OCP.gp import gp_Pnt

    corners = [gp_Pnt(*q) for q in m.vertices[m.faces[0]].tolist()]
    wire = BRepBuilderAPI_MakePolygon(*corners, True).Wire()
    assert not BRepBuilderAPI_MakeFace(wire, True).IsDone()  # OCCT alone says "not planar"
    shape = step_shape(m, check=True)
    assert shape.is_valid
    assert {f.geom_type for f in shape.faces()} == {GeomType.PLANE}
    back = import_step(save_step(m, tmp_path / "p.step", mode="shell"))
    assert {f.geom_type for f in back.faces()} == {GeomType.PLANE}
    assert len(back.faces()) == 4
    # corners move onto each panel's plane by half its diagonal distance, no more
    _, report = step_mod.step_panels(m, mode="shell")
    assert report.max_corner_move == pytest.approx(0.5 * absolute.max(), rel=1e-9)
    got = np.array([tuple(v) for v in back.vertices()])
    nearest = np.linalg.norm(got[:, None, :] - m.vertices[None], axis=2).min(axis=1)
    assert nearest.max() <= 2 * report.max_corner_move
    # with a zero tolerance the same panels are bilinear, through the exact corners
    assert {f.geom_type for f in step_shape(m, planar_tolerance=0.0).faces()} == {GeomType.BEZIER}


def test_shell_mode_sews_one_shell(tmp_path):
    for m in (mixed_grid(), extraordinary_mesh(levels=1), cylinder(3, 8)):
        shell = step_shape(m, mode="shell")
        assert type(shell).__name__ == "Shell"
        assert len(shell.faces()) == m.n_faces
        # sewing shares edges: as many edges as the mesh has
        assert len(shell.edges()) == len(m.topology.edges)


def test_two_pieces_give_a_compound_of_shells():
    a = grid(2, 3)
    v = np.vstack([a.vertices, a.vertices + [0, 0, 5.0]])
    m = QuadMesh(v, np.vstack([a.faces, a.faces + a.n_vertices]))
    shape = step_shape(m, mode="shell")
    assert len(shape.shells()) == 2 and len(shape.faces()) == 4


@pytest.mark.parametrize("mode", MODES)
def test_mesh_unit_is_declared_and_coordinates_are_unscaled(tmp_path, mode):
    m = grid(2, 2, spacing=1.25, height=[[0, 0], [0, 0.5]])
    mm = save_step(m, tmp_path / "mm.step", mode=mode)
    in_metres = QuadMesh(m.vertices, m.faces, grid_shape=m.grid_shape, unit="m")  # same numbers, in m
    metres = save_step(in_metres, tmp_path / "m.step", mode=mode)
    assert "SI_UNIT(.MILLI.,.METRE.)" in mm.read_text()
    text = metres.read_text()
    assert "SI_UNIT($,.METRE.)" in text and ".MILLI." not in text
    assert re.search(r"CARTESIAN_POINT\('',\(1\.25,1\.25,0\.5\)\)", text)
    # a unit-aware reader (build123d works in mm) converts
    box_mm = import_step(mm).bounding_box()
    box_m = import_step(metres).bounding_box()
    assert box_mm.max.X == pytest.approx(1.25)
    assert box_m.max.X == pytest.approx(1250.0)
    # the process-wide OCCT setting is restored
    from OCP.Interface import Interface_Static

    assert Interface_Static.CVal_s("write.step.unit") == "MM"


def test_assembly_colours_by_planarity(tmp_path):
    m = mixed_grid()
    planar = planar_mask(m)
    back = import_step(save_step(m, tmp_path / "c.step", mode="assembly", colors=True))
    rgb = np.array([tuple(c.color)[:3] for c in back.children])
    np.testing.assert_allclose(rgb[planar], np.tile(step_mod._PLANAR_RGB, (planar.sum(), 1)), atol=1e-3)
    assert (rgb[~planar][:, 2] < 0.3).all()  # yellow to red
    with pytest.raises(InputError, match="colors"):
        step_shape(m, mode="compound", colors=True)


def test_option_errors():
    m = grid(2, 2)
    with pytest.raises(InputError, match="mode"):
        step_shape(m, mode="solid")
    with pytest.raises(InputError, match="mesh_unit.*renamed.*QuadMesh.unit"):
        save_step(m, "never-written.step", mesh_unit="m")
    with pytest.raises(InputError, match="'planar_tol' was renamed; use planar_tolerance"):
        step_shape(m, planar_tol=1e-3)
    with pytest.raises(InputError, match="planar_tolerance"):
        step_shape(m, planar_tolerance=-1.0)
    with pytest.raises(InputError, match="planar_tolerance"):
        save_step(m, "never-written.step", planar_tolerance="2 furlongs")
    with pytest.raises(InputError, match="unexpected keyword argument 'colour'"):
        save_step(m, "never-written.step", colour=True)
    with pytest.raises(InputError, match="QuadMesh"):
        step_shape(m.vertices)
    assert not os.path.exists("never-written.step")


@pytest.mark.parametrize("mode", MODES)
def test_failed_occt_build_names_the_panel_and_leaves_nothing(tmp_path, mode):
    good = grid(2, 3, spacing=2.0)
    # face 1 is degenerate: four collinear corners (its diagonals are parallel); the mesh refuses it
    v = np.vstack([good.vertices, [[10, 0, 0], [11, 0, 0], [12, 0, 0], [13, 0, 0]]])
    with pytest.raises(InputError, match=r"face 1 \[6, 7, 8, 9\] has no area"):
        QuadMesh(v, np.vstack([good.faces[:1], [[6, 7, 8, 9]], good.faces[1:]]))
    # a flat panel whose edges cross (a bow-tie) is neither a plane face nor a sound patch: refused, named
    v = np.vstack([good.vertices, [[10, 0, 0], [12, 0, 0], [10.5, 1, 0], [11.5, 1.2, 0]]])
    m = QuadMesh(v, np.vstack([good.faces[:1], [[6, 7, 8, 9]], good.faces[1:]]))
    target = tmp_path / "out.step"
    target.write_text("old content")
    with pytest.raises(ExportError, match=r"panel 1 \(P_1\) is folded: its edges cross"):
        save_step(m, target, mode=mode)
    assert target.read_text() == "old content"
    only_file(tmp_path, "out.step")


def test_self_intersecting_flat_quad_is_refused_not_written_folded(tmp_path):
    # a flat bow-tie cannot be a plane face, and its bilinear patch folds over itself: no output takes it
    m = QuadMesh([[0, 0, 0], [2, 0, 0], [0.5, 1, 0], [1.5, 1.2, 0]], [[0, 1, 2, 3]])
    assert not planar_mask(m)[0]
    with pytest.raises(ExportError, match=r"panel 0 \(P_0\) is folded"):
        save_step(m, tmp_path / "bowtie.step")
    assert os.listdir(tmp_path) == []
    # the same outline lifted well out of plane is a sound twisted patch
    lifted = m.with_vertices(m.vertices + [[0, 0, 0], [0, 0, 0], [0, 0, 2.0], [0, 0, 0]])
    shape, report = step_mod.step_panels(lifted)
    assert shape.faces()[0].geom_type == GeomType.BEZIER
    assert (report.n_planar, report.n_bilinear, report.fallback) == (0, 1, ())


def test_failure_while_writing_keeps_the_old_file(tmp_path, monkeypatch):
    target = tmp_path / "out.step"
    target.write_text("old content")

    def half_write(shape, path, unit):
        with open(path, "w") as f:
            f.write("ISO-10303-21;\nHEADER;\n")  # a truncated file
        raise RuntimeError("Failed to write STEP file")

    monkeypatch.setattr(step_mod, "_write_step", half_write)
    with pytest.raises(ExportError, match="out.step"):
        save_step(grid(3, 3), target)
    assert target.read_text() == "old content"
    only_file(tmp_path, "out.step")


def test_unwritable_paths_raise_export_error(tmp_path):
    m = grid(2, 2)
    with pytest.raises(ExportError, match="missing"):
        save_step(m, tmp_path / "missing" / "p.step")
    (tmp_path / "adir").mkdir()
    with pytest.raises(ExportError):
        save_step(m, tmp_path / "adir")  # a directory is in the way
    assert os.listdir(tmp_path / "adir") == []
    only_file(tmp_path, "adir")


def test_read_only_directory_raises_export_error(read_only_folder):
    # (root ignores permission bits: the fixture injects the refusal where the OS gives it, creating a file)
    ro = read_only_folder
    with pytest.raises(ExportError, match="Permission denied"):
        save_step(grid(2, 2), ro / "p.step")
    assert os.listdir(ro) == []


def test_build123d_is_imported_lazily():
    import subprocess
    import sys

    code = "import sys, quadnodes.io; print('build123d' in sys.modules or 'OCP' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
