"""STEP never fails on a valid mesh; labelled and connected shells; one planar tolerance (issue 13)."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from quadnodes.errors import ExportError, InputError
from quadnodes.flatness import DEFAULT_PLANAR_TOLERANCE, diagonal_distance, planar_panels
from quadnodes.io import step as step_mod
from quadnodes.io.panels import panel_labels
from quadnodes.io.step import STEP_MODES, save_step, step_panels, write_step
from quadnodes.mesh import QuadMesh, grid
from meshes import extraordinary_mesh


def _read_back(path):
    """Independent read with OCCT's XCAF STEP reader: (shape, {face index: name}, edge -> face counts)."""
    from OCP.collections import IndexedDataMap_TopoDS_Shape_List_TopoDS_Shape_TopTools_ShapeMapHasher as EMap
    from OCP.collections import Sequence_TDF_Label
    from OCP.Interface import Interface_Static
    from OCP.STEPCAFControl import STEPCAFControl_Controller, STEPCAFControl_Reader
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDataStd import TDataStd_Name
    from OCP.TDocStd import TDocStd_Document
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE
    from OCP.TopExp import TopExp
    from OCP.XCAFApp import XCAFApp_Application
    from OCP.XCAFDoc import XCAFDoc_DocumentTool

    STEPCAFControl_Controller.Init_s()
    Interface_Static.SetIVal_s("read.stepcaf.subshapes.name", 1)
    doc = TDocStd_Document(TCollection_ExtendedString("XmlOcaf"))
    XCAFApp_Application.GetApplication_s().NewDocument(TCollection_ExtendedString("MDTV-XCAF"), doc)
    reader = STEPCAFControl_Reader()
    reader.SetNameMode(True)
    reader.ReadFile(str(path))
    reader.Transfer(doc)
    tool = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    free = Sequence_TDF_Label()
    tool.GetFreeShapes(free)
    assert free.Length() == 1
    top = free.Value(1)
    shape = tool.GetShape_s(top)
    subs = Sequence_TDF_Label()
    tool.GetSubShapes_s(top, subs)
    names = []
    for i in range(1, subs.Length() + 1):
        attr = TDataStd_Name()
        if subs.Value(i).FindAttribute(TDataStd_Name.GetID_s(), attr):
            names.append(attr.Get().ToExtString())
    emap = EMap()
    TopExp.MapShapesAndAncestors_s(shape, TopAbs_EDGE, TopAbs_FACE, emap)
    counts = [emap.FindFromIndex(i).Size() for i in range(1, emap.Extent() + 1)]
    return shape, names, counts


_GMSH = r"""
import json, sys
import gmsh
gmsh.initialize(interruptible=False)
gmsh.option.setNumber("General.Terminal", 0)
out = []
for path in sys.argv[1:]:
    gmsh.clear()
    gmsh.open(path)
    out.append([len(gmsh.model.getEntities(2)), len(gmsh.model.getEntities(1))])
gmsh.finalize()
print(json.dumps(out))
"""


def gmsh_counts(*paths):
    pytest.importorskip("gmsh")
    env = dict(os.environ)
    res = subprocess.run([sys.executable, "-c", _GMSH, *map(str, paths)], capture_output=True, text=True,
                         timeout=300, check=True, env=env)
    return json.loads(res.stdout.strip().splitlines()[-1])


def lifted_panel(size, lift):
    v = np.array([[0, 0, 0], [size, 0, 0], [size, size, lift], [0, size, 0]], float)
    return QuadMesh(v, [[0, 1, 2, 3]])


@pytest.mark.parametrize("lift", [0.0, 3e-7, 6e-7, 1e-6, 3e-6, 1e-5, 3e-5, 1e-4, 1e-3])
def test_the_reported_almost_flat_panel_is_a_valid_plane(lift):
    # issue 13: a 1 m panel (mm) with one corner lifted 1e-6 … 1e-5 mm used to abort the export
    m = lifted_panel(1000.0, lift)
    shape, report = step_panels(m, planar_tolerance=1e-6)
    assert shape.is_valid and shape.faces()[0].geom_type.name == "PLANE"
    assert report.fallback == () and report.n_planar == 1
    gap = float(diagonal_distance(m, relative=False)[0])
    assert report.max_corner_move == pytest.approx(gap / 2, abs=1e-15)
    assert report.max_corner_move <= 0.5 * 1e-6 * 1000 * np.sqrt(2)


def random_quad(rng, size, nonplanar):
    """A convex quad of about ``size`` with relative diagonal distance about ``nonplanar``."""
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float) + rng.uniform(-0.2, 0.2, (4, 2))
    p = np.c_[uv, np.zeros(4)] * size
    p[:, 2] = np.array([1, -1, 1, -1]) * nonplanar * size * np.sqrt(2) / 2
    rot, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return p @ rot.T + rng.uniform(-10, 10, 3) * size


@settings(max_examples=40, deadline=None)
@given(st.floats(0, 5), st.floats(-12, -2), st.integers(0, 2**31 - 1),
       st.sampled_from([DEFAULT_PLANAR_TOLERANCE, 1e-6, 0.0, "2 mm", "0.001 mm"]))
def test_every_random_quad_is_written_as_one_valid_face(log_size, log_np, seed, tol):
    # sizes 1 mm … 100 m (in mm), non-planarity 1e-12 … 1e-2 relative, log-spaced
    rng = np.random.default_rng(seed)
    m = QuadMesh(random_quad(rng, 10.0**log_size, 10.0**log_np), [[0, 1, 2, 3]])
    shape, report = step_panels(m, planar_tolerance=tol)
    assert shape.is_valid and len(shape.faces()) == 1
    assert report.n_planar == int(planar_panels(m, tol)[0]) and report.fallback == ()
    gap = float(diagonal_distance(m, relative=False)[0])
    assert report.max_corner_move <= 0.5 * gap * (1 + 1e-9)


def test_random_quads_read_back_with_gmsh_one_face_per_panel(tmp_path):
    rng = np.random.default_rng(13)
    sizes = 10.0 ** np.linspace(0, 5, 11)  # 1 mm … 100 m
    nonplanar = np.r_[0.0, 10.0 ** np.arange(-12, -1.5, 0.5)]  # 0, 1e-12 … 1e-2
    quads = [random_quad(rng, s, d) for s in sizes for d in nonplanar]
    m = QuadMesh(np.vstack(quads), np.arange(4 * len(quads)).reshape(-1, 4))
    paths = []
    for tol in (DEFAULT_PLANAR_TOLERANCE, 1e-6, "2 mm"):
        path, report = write_step(m, tmp_path / f"q{len(paths)}.step", planar_tolerance=tol)
        assert report.n_panels == m.n_faces and report.fallback == ()
        assert report.n_planar == int(planar_panels(m, tol).sum())
        paths.append(path)
    assert [c[0] for c in gmsh_counts(*paths)] == [m.n_faces] * 3


@pytest.mark.parametrize("mode", ["shell", "assembly", "compound"])
def test_shell_is_labelled_and_connected(tmp_path, mode):
    m = grid(5, 7, spacing=300.0, height=np.random.default_rng(1).normal(0, 5, (5, 7)))
    path, report = write_step(m, tmp_path / "s.step", mode=mode)
    shape, names, counts = _read_back(path)
    n_edges = len(m.topology.edges)
    n_boundary = 2 * (4 + 6)
    if mode == "shell":
        assert names == panel_labels(m)
        assert counts.count(2) == n_edges - n_boundary and counts.count(1) == n_boundary
        assert (report.n_shared_edges, report.n_free_edges) == (n_edges - n_boundary, n_boundary)
    else:
        assert counts.count(2) == 0 and len(counts) == 4 * m.n_faces
    surfaces, curves = gmsh_counts(path)[0]
    assert surfaces == m.n_faces
    assert curves == (n_edges if mode == "shell" else 4 * m.n_faces)


def test_shell_of_planar_panels_stays_connected_after_their_corners_move(tmp_path):
    # every panel planar within "2 mm", none exactly: neighbours' projected corners differ
    i, j = np.indices((6, 6))
    m = grid(6, 6, spacing=1000.0, height=0.4 * (-1.0) ** (i + j))
    path, report = write_step(m, tmp_path / "p.step", mode="shell", planar_tolerance="2 mm")
    assert report.n_planar == m.n_faces and 0 < report.max_corner_move <= 1.0
    _, names, counts = _read_back(path)
    assert len(names) == m.n_faces
    assert counts.count(2) == len(m.topology.edges) - 20 and counts.count(1) == 20


def test_irregular_mesh_shell_names_faces_by_index(tmp_path):
    m = extraordinary_mesh(levels=1)
    _, names, counts = _read_back(save_step(m, tmp_path / "x.step", mode="shell"))
    assert names == [f"P_{k}" for k in range(m.n_faces)]
    assert counts.count(2) > 0


def test_nan_never_reaches_the_exporter():
    v = grid(2, 2).vertices.copy()
    v[3, 2] = np.nan
    with pytest.raises(InputError, match="vertex 3"):
        QuadMesh(v, [[0, 1, 3, 2]])


@pytest.mark.parametrize("mode", STEP_MODES)
def test_a_unit_step_cannot_declare_is_an_export_error(tmp_path, mode, monkeypatch):
    monkeypatch.delitem(step_mod._UNITS, "ft")
    target = tmp_path / "f.step"
    with pytest.raises(ExportError, match="unit.*'ft'"):
        save_step(grid(2, 2).with_unit("ft"), target, mode=mode)
    assert os.listdir(tmp_path) == []


def test_degenerate_panel_names_the_panel_and_writes_nothing(tmp_path):
    g = grid(3, 3, spacing=10.0)
    v = g.vertices.copy()
    v[[0, 1, 3, 4], 1] = 0.0  # processing put panel P_0_0's corners on one line (QuadMesh() refuses that)
    v[[3, 4], 0] += [-5.0, 15.0]
    m = g.with_vertices(v)
    with pytest.raises(ExportError, match=r"panel 0 \(P_0_0\) is degenerate: zero area"):
        save_step(m, tmp_path / "d.step", mode="shell")
    assert os.listdir(tmp_path) == []


def test_default_tolerance_is_the_planarize_target():
    from quadnodes.planarization import DEFAULT_TOLERANCE

    assert DEFAULT_PLANAR_TOLERANCE == DEFAULT_TOLERANCE


def test_report_to_dict_is_plain_data(tmp_path):
    _, report = write_step(grid(3, 3), tmp_path / "r.step", mode="shell")
    d = report.to_dict()
    assert json.loads(json.dumps(d)) == d
    assert d["mode"] == "shell" and d["unit"] == "mm" and d["n_panels"] == 4


def test_shell_faces_carry_their_planarity_colours(tmp_path):
    m = grid(3, 4, spacing=100.0, height=[[0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 20, 0]])
    planar = planar_panels(m)
    assert 0 < planar.sum() < m.n_faces
    text = save_step(m, tmp_path / "c.step", mode="shell", colors=True).read_text()
    assert text.count("STYLED_ITEM(") == m.n_faces  # one style per named face
    rgb = {tuple(round(float(c), 2) for c in t.split(",")) for t in
           __import__("re").findall(r"COLOUR_RGB\('[^']*',([^)]*)\)", text)}
    assert tuple(round(c, 2) for c in step_mod._PLANAR_RGB) in rgb and len(rgb) >= 2


def test_pcurves_are_optional_and_the_shell_reads_back_the_same(tmp_path):
    # the edges are straight lines on planes and bilinear patches: a reader projects them exactly, so
    # the file leaves out the edges' curves on each face unless asked (pcurves=True, OCCT's default)
    m = grid(4, 5, spacing=300.0, height=np.random.default_rng(3).normal(0, 2, (4, 5)))
    lean = save_step(m, tmp_path / "lean.step", mode="shell", planar_tolerance="2 mm")
    full = save_step(m, tmp_path / "full.step", mode="shell", planar_tolerance="2 mm", pcurves=True)
    assert "PCURVE" not in lean.read_text() and "PCURVE" in full.read_text()
    for path in (lean, full):
        shape, names, counts = _read_back(path)
        assert names == panel_labels(m)
        assert counts.count(2) == len(m.topology.edges) - 14 and counts.count(1) == 14
        from OCP.BRepCheck import BRepCheck_Analyzer

        assert BRepCheck_Analyzer(shape).IsValid()
    assert gmsh_counts(lean, full) == [[m.n_faces, len(m.topology.edges)]] * 2
    with pytest.raises(InputError, match="pcurves: expected true or false, got 'yes'"):
        save_step(m, tmp_path / "never.step", pcurves="yes")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["full.step", "lean.step"]
