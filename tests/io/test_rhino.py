"""Rhino .3dm out and in, checked with rhino3dm's own reader (not quadnodes' loader)."""

import os

import numpy as np
import pytest
import rhino3dm
from hypothesis import given, settings
from hypothesis import strategies as st

from quadnodes.errors import ExportError, InputError
from quadnodes.flatness import diagonal_distance, planar_panels
from quadnodes.io import load, rhino, save
from quadnodes.io.panels import bilinear_area, edge_lengths, panel_labels
from quadnodes.io.rhino import load_3dm, save_3dm
from quadnodes.mesh import QuadMesh, cylinder, grid
from quadnodes.topology import structure_lines


def wavy(rows=5, cols=6, lift=None):
    """A grid in mm whose first row of panels is flat and the rest twisted."""
    rng = np.random.default_rng(3)
    h = rng.normal(scale=20.0, size=(rows, cols))
    h[:2] = 0.0
    if lift is not None:
        h = lift
    return grid(rows, cols, spacing=(500.0, 400.0), height=h)


def objects(path):
    model = rhino3dm.File3dm.Read(str(path))
    layers = {layer.Index: layer.FullPath for layer in model.Layers}
    by = {}
    for o in model.Objects:
        by.setdefault(type(o.Geometry).__name__, []).append((o, layers[o.Attributes.LayerIndex]))
    return model, by


def test_counts_corners_layers_and_user_text(tmp_path):
    m = wavy()
    tol = "2 mm"
    p = save(m, tmp_path / "w.3dm", planar_tolerance=tol)
    model, by = objects(p)
    assert str(model.Settings.ModelUnitSystem) == "UnitSystem.Millimeters"
    # the mesh, quads kept, vertices exact
    (mesh_obj, mesh_layer), = by["Mesh"]
    assert mesh_layer == "mesh"
    rm = mesh_obj.Geometry
    v = np.array([(q.X, q.Y, q.Z) for q in rm.Vertices.ToPoint3dArray()])
    assert np.array_equal(v, m.vertices)
    faces = np.array([tuple(rm.Faces[k]) for k in range(len(rm.Faces))])
    assert np.array_equal(faces, m.faces) and rm.Faces.QuadCount == m.n_faces
    # one named degree-1 surface per panel through its corners
    surfaces = by["NurbsSurface"]
    assert len(surfaces) == m.n_faces
    labels = panel_labels(m)
    planar = planar_panels(m, tol)
    assert 0 < planar.sum() < m.n_faces
    corners = m.vertices[m.faces]
    area, edges = bilinear_area(m), edge_lengths(m)
    for k, (o, layer) in enumerate(surfaces):
        s = o.Geometry
        assert (s.Degree(0), s.Degree(1), s.Points.CountU, s.Points.CountV) == (1, 1, 2, 2)
        assert not s.IsRational
        got = [s.Points.GetControlPoint(i, j) for i, j in ((0, 0), (1, 0), (1, 1), (0, 1))]
        got = np.array([(q.X, q.Y, q.Z) for q in got])
        np.testing.assert_allclose(got, corners[k], rtol=0, atol=1e-9 * 3000)
        mid = s.PointAt(*(0.5 * (s.Domain(0).T0 + s.Domain(0).T1), 0.5 * (s.Domain(1).T0 + s.Domain(1).T1)))
        np.testing.assert_allclose([mid.X, mid.Y, mid.Z], corners[k].mean(axis=0), atol=1e-9 * 3000)
        assert o.Attributes.Name == labels[k]
        assert layer == ("panels::planar" if planar[k] else "panels::bilinear")
        text = dict(o.Attributes.GetUserStrings())
        assert text["id"] == labels[k]
        assert (int(text["row"]), int(text["col"])) == divmod(k, 5)
        assert float(text["planarity"]) == diagonal_distance(m)[k]
        assert float(text["planarity_mm"]) == diagonal_distance(m, relative=False)[k]
        assert float(text["area_mm2"]) == area[k]
        assert [float(x) for x in text["edges_mm"].split()] == edges[k].tolist()
        assert text["planar"] == ("yes" if planar[k] else "no")
    # structure lines as polylines through the mesh vertices
    lines = structure_lines(m)
    curves = by["PolylineCurve"]
    assert len(curves) == len(lines)
    assert {layer for _, layer in curves} == {"structure lines"}
    for (o, _), idx in zip(curves, lines):
        c = o.Geometry
        pts = np.array([(c.Point(i).X, c.Point(i).Y, c.Point(i).Z) for i in range(c.PointCount)])
        assert np.array_equal(pts, m.vertices[idx])


def test_closed_lines_close_and_units_are_stated(tmp_path):
    c = cylinder(4, 8, radius=2.0, height=3.0)
    c = QuadMesh(c.vertices, c.faces, unit="m")
    p = save_3dm(c, tmp_path / "c.3dm")
    model, by = objects(p)
    assert str(model.Settings.ModelUnitSystem) == "UnitSystem.Meters"
    closed = [o.Geometry for o, _ in by["PolylineCurve"] if o.Geometry.IsClosed]
    assert len(closed) == int(structure_lines(c).closed.sum()) == 4
    text = dict(by["NurbsSurface"][0][0].Attributes.GetUserStrings())
    assert {"planarity_m", "area_m2", "edges_m"} <= set(text)
    back = load(p, renumber_grid=False)
    assert back.unit == "m" and np.array_equal(back.vertices, c.vertices)


@pytest.mark.parametrize("unit, name", [("mm", "Millimeters"), ("cm", "Centimeters"), ("m", "Meters"),
                                        ("in", "Inches"), ("ft", "Feet")])
def test_every_unit_round_trips(tmp_path, unit, name):
    m = grid(3, 4, spacing=2.5)
    m = QuadMesh(m.vertices, m.faces, grid_shape=m.grid_shape, unit=unit)
    p = save_3dm(m, tmp_path / "u.3dm")
    assert str(rhino3dm.File3dm.Read(str(p)).Settings.ModelUnitSystem) == f"UnitSystem.{name}"
    back = load_3dm(p)
    assert back.unit == unit and back.grid_shape == (3, 4)
    assert np.array_equal(back.faces, m.faces) and np.array_equal(back.vertices, m.vertices)


@settings(max_examples=15, deadline=None)
@given(st.integers(2, 6), st.integers(2, 6), st.floats(0.0, 50.0), st.integers(0, 2**31 - 1))
def test_surfaces_pass_through_the_corners_and_layers_agree_with_flatness(tmp_path_factory, r, c, amp, seed):
    h = np.random.default_rng(seed).normal(scale=amp, size=(r, c))
    m = grid(r, c, spacing=300.0, height=h)
    p = save_3dm(m, tmp_path_factory.mktemp("h") / "h.3dm", planar_tolerance=1e-3, lines=False)
    _, by = objects(p)
    planar = planar_panels(m, 1e-3)
    corners = m.vertices[m.faces]
    for k, (o, layer) in enumerate(by["NurbsSurface"]):
        s = o.Geometry
        for (i, j), q in zip(((0, 0), (1, 0), (1, 1), (0, 1)), corners[k]):
            cp = s.Points.GetControlPoint(i, j)
            assert np.allclose([cp.X, cp.Y, cp.Z], q, rtol=0, atol=1e-9 * 2000)
        assert layer.endswith("planar" if planar[k] else "bilinear")


def _rhino_mesh_file(path, faces, unit=rhino3dm.UnitSystem.Centimeters):
    model = rhino3dm.File3dm()
    model.Settings.ModelUnitSystem = unit
    rm = rhino3dm.Mesh()
    for p in [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (2, 0, 0), (2, 1, 0)]:
        rm.Vertices.Add(*p)
    for f in faces:
        rm.Faces.AddFace(*f)
    model.Objects.AddMesh(rm)
    model.Write(str(path), 0)
    return path


def test_load_a_mesh_rhino_wrote(tmp_path):
    p = _rhino_mesh_file(tmp_path / "r.3dm", [(0, 1, 2, 3), (1, 4, 5, 2)])
    m = load(p, renumber_grid=False)
    assert m.unit == "cm" and m.faces.tolist() == [[0, 1, 2, 3], [1, 4, 5, 2]]


def test_triangles_follow_the_non_quads_rule(tmp_path):
    p = _rhino_mesh_file(tmp_path / "t.3dm", [(0, 1, 2, 3), (1, 4, 5)])
    with pytest.raises(InputError, match=r"face 1 has 3 corners; only quads are supported \(non_quads='drop'"):
        load(p, renumber_grid=False)
    with pytest.raises(InputError, match="odd polygon cannot be split"):
        load(p, renumber_grid=False, non_quads="split")
    assert load(p, renumber_grid=False, non_quads="drop").faces.tolist() == [[0, 1, 2, 3]]


def test_files_without_a_mesh_or_with_several(tmp_path):
    model = rhino3dm.File3dm()
    model.Objects.AddPoint(rhino3dm.Point3d(0, 0, 0))
    model.Write(str(tmp_path / "pt.3dm"), 0)
    with pytest.raises(InputError, match="no mesh in the file .*Point"):
        load(tmp_path / "pt.3dm")
    p = save_3dm(grid(3, 3), tmp_path / "a.3dm")
    model = rhino3dm.File3dm.Read(str(p))
    model.Objects.AddMesh(model.Objects[0].Geometry)
    model.Write(str(tmp_path / "two.3dm"), 0)
    with pytest.raises(InputError, match="holds 2 meshes .*pass name="):
        load(tmp_path / "two.3dm")
    assert load(tmp_path / "two.3dm", name="quad mesh").n_faces == 4
    with pytest.raises(InputError, match="cannot read .*no such file"):
        load(tmp_path / "missing.3dm")
    (tmp_path / "folder.3dm").mkdir()
    with pytest.raises(InputError, match="cannot read .*a folder, not a file"):
        load(tmp_path / "folder.3dm")


def test_a_damaged_file_is_refused_not_read_in_part(tmp_path):
    """rhino3dm's reader checks every chunk's CRC: one changed byte or a cut makes the file unreadable."""
    p = save_3dm(wavy(), tmp_path / "w.3dm")
    data = p.read_bytes()
    label = "P_2_3".encode("utf-16-le")
    at = data.index(label)  # in a panel's user text (the fast engine's records)
    (tmp_path / "flip.3dm").write_bytes(data[:at + 2] + b"X" + data[at + 3:])
    (tmp_path / "cut.3dm").write_bytes(data[: len(data) * 9 // 10])
    for name in ("flip.3dm", "cut.3dm"):
        assert rhino3dm.File3dm.Read(str(tmp_path / name)) is None
        with pytest.raises(InputError, match="not a .3dm file rhino3dm can read .*damaged"):
            load(tmp_path / name)


def test_bad_input_leaves_nothing(tmp_path, monkeypatch):
    m = wavy()
    # a degenerate (zero-area) panel: three corners on one line and the fourth on it too
    v = grid(2, 3, spacing=100.0).vertices.copy()
    v[[3, 4, 5], 1] = 0.0
    v[[3, 4, 5], 0] += 1.0
    v[3:, 2] = 0.0
    flat = grid(2, 3).with_vertices(v)  # a processed mesh can collapse a panel; QuadMesh() refuses one
    with pytest.raises(ExportError, match=r"panel 0 \(P_0_0\) is degenerate"):
        save_3dm(flat, tmp_path / "d.3dm")
    # an unwritable place: the folder is a file
    (tmp_path / "file").write_text("x")
    with pytest.raises(ExportError, match="file"):
        save_3dm(m, tmp_path / "file" / "w.3dm")
    # a unit the format cannot state
    monkeypatch.delitem(rhino.RHINO_UNITS, "ft")
    with pytest.raises(ExportError, match="unit 'ft' has no Rhino unit system"):
        save_3dm(QuadMesh(m.vertices, m.faces, unit="ft"), tmp_path / "ft.3dm")
    with pytest.raises(InputError, match="planar_tolerance"):
        save_3dm(m, tmp_path / "t.3dm", planar_tolerance="2 parsecs")
    with pytest.raises(InputError, match="version"):
        save_3dm(m, tmp_path / "v.3dm", version=3)
    with pytest.raises(InputError, match="engine: expected one of 'fast', 'rhino3dm'"):
        save_3dm(m, tmp_path / "e.3dm", engine="Fast")
    with pytest.raises(ExportError, match=r"panel 0 \(P_0_0\) is degenerate"):  # both engines check first
        save_3dm(flat, tmp_path / "d.3dm", engine="rhino3dm")
    assert sorted(os.listdir(tmp_path)) == ["file"]


def test_a_file_that_is_not_3dm(tmp_path):
    p = tmp_path / "x.3dm"
    p.write_bytes(b"not a rhino file\x00" * 10)
    with pytest.raises(InputError, match="not a .3dm file rhino3dm can read"):
        load(p, renumber_grid=False)


def test_a_mesh_without_grid_is_labelled_by_face(tmp_path):
    c = cylinder(3, 6, radius=1000.0, height=2000.0)
    m = QuadMesh(c.vertices, c.faces)  # no grid_shape
    _, by = objects(save_3dm(m, tmp_path / "c.3dm"))
    names = [o.Attributes.Name for o, _ in by["NurbsSurface"]]
    assert names == [f"P_{k}" for k in range(m.n_faces)]
    text = dict(by["NurbsSurface"][0][0].Attributes.GetUserStrings())
    assert "row" not in text and "col" not in text and text["id"] == "P_0" and text["planar"] == "yes"
    assert load_3dm(tmp_path / "c.3dm").grid_shape is None
