import json

import numpy as np
import pytest

import quadnodes.nodes  # noqa: F401
from quadnodes.errors import GraphError, NodeError
from quadnodes.graph import REGISTRY, Cache, Graph, describe
from quadnodes.io import load_obj

EXPECTED = {
    "saddle", "s_shape", "wavy", "dome", "cylinder_segment", "torus_patch", "read_step_surface", "sample",
    "thesis_example", "grid", "read_mesh", "perturb", "detect", "select_fixed", "fair", "laplacian", "taubin",
    "planarity", "compare", "export_step", "export_obj", "export_csv", "export_json", "export_report",
    "render_png", "render_html", "planarize", "read_surface", "export_3dm", "export_dxf",
}


def test_every_built_in_node_is_registered_and_documented():
    ops = {nt.op.split("@")[0] for nt in REGISTRY.latest()}
    assert EXPECTED <= ops
    for op in EXPECTED:
        d = describe(op)
        assert d["summary"], op


def test_pipeline_from_surface_to_files(tmp_path):
    g = Graph(base_dir=tmp_path)
    face = g.add("saddle", id="surface", width=3000.0, depth=2000.0)
    mesh = g.add("sample", face.face, id="mesh", nu=8, nv=9)
    noisy = g.add("perturb", mesh.mesh, id="noisy", tangential=0.2, seed=2, fix="corners")
    zz = g.add("detect", noisy.mesh, id="zz", threshold=0.05)
    fixed = g.add("select_fixed", noisy.mesh, zz.report, id="fixed", boundary=True)
    new = g.add("fair", noisy.mesh, fixed.fixed, id="fair", iterations=2)
    lap = g.add("laplacian", noisy.mesh, fixed.fixed, id="lap", iterations=2)
    tau = g.add("taubin", noisy.mesh, id="tau", iterations=2, fix="corners")
    cmp_ = g.add("compare", noisy.mesh, new.mesh, mesh.mesh, id="cmp")
    pl = g.add("planarity", new.mesh, id="pl")
    g.add("export_obj", new.mesh, id="obj", path="a.obj")
    g.add("export_json", new.mesh, id="json", path="a.json")
    g.add("export_csv", new.mesh, id="csv", path="a.csv")
    g.add("export_report", cmp_.metrics, pl.summary, id="rep", path="r.json", names=["metrics", "planarity"])
    g.add("render_png", noisy.mesh, new.mesh, lap.mesh, tau.mesh, id="png", path="a.png", size_px=400)
    res = g.run(cache=Cache())
    out = res["fair.mesh"]
    b = out.topology.boundary_vertices
    assert np.array_equal(out.vertices[b], res["noisy.mesh"].vertices[b])
    assert res["cmp.metrics"]["boundary_displacement_max"] == 0.0
    assert np.array_equal(load_obj(tmp_path / "a.obj").faces, out.faces)
    rep = json.loads((tmp_path / "r.json").read_text())
    assert set(rep) == {"metrics", "planarity"}
    # boundary lines are held (zigzag stays there); overall the zigzag drops
    assert rep["metrics"]["zigzag_mean"] < 0.5 * res["zz.report"].window_deviation.mean()
    assert (tmp_path / "a.png").stat().st_size > 10_000
    assert len((tmp_path / "a.csv").read_text().splitlines()) == 1 + out.n_faces
    # read the mesh back through the graph
    g2 = Graph(base_dir=tmp_path)
    g2.add("read_mesh", id="m", path="a.json")
    assert np.array_equal(g2.run()["m.mesh"].vertices, out.vertices)


def test_select_fixed_modes():
    g = Graph()
    m = g.add("grid", id="m", rows=4, cols=5)
    g.add("select_fixed", m.mesh, id="c", corners=True)
    g.add("select_fixed", m.mesh, id="i", indices=[1, 2], box=[-0.5, -0.5, -1, 0.5, 3.5, 1], invert=True)
    r = g.run()
    assert np.flatnonzero(r["c.fixed"]).tolist() == [0, 4, 15, 19]
    held = ~r["i.fixed"]
    assert np.flatnonzero(held).tolist() == [0, 1, 2, 5, 10, 15]


def test_node_errors_name_the_node(tmp_path):
    g = Graph(base_dir=tmp_path)
    m = g.add("grid", id="m", rows=3, cols=3)
    g.add("render_png", m.mesh, m.mesh, id="pic", path="x.png", titles=["one"])
    with pytest.raises(NodeError, match="node 'pic'.*titles: 1 titles for 2"):
        g.run()
    g2 = Graph(base_dir=tmp_path)
    g2.add("read_mesh", id="reader", path="missing.obj")
    with pytest.raises(NodeError, match="reader.*path.*missing.obj"):
        g2.run()


def test_rhino_and_dxf_nodes(tmp_path):
    """read_surface@1 (file hashed for the cache), export_3dm@1 and export_dxf@1 in one graph."""
    import ezdxf
    import rhino3dm

    s = rhino3dm.NurbsSurface.Create(3, True, 3, 3, 3, 3)
    for kl in (s.KnotsU, s.KnotsV):
        for i, k in enumerate([0.0, 0.0, 1.0, 1.0]):
            kl[i] = k
    for i in range(3):
        for j in range(3):
            w = 1.0 + 0.3 * (i == 1)
            s.Points[(i, j)] = rhino3dm.Point4d(2.0 * i * w, 1.5 * j * w, (0.8 if (i, j) == (1, 1) else 0.0) * w, w)
    model = rhino3dm.File3dm()
    model.Settings.ModelUnitSystem = rhino3dm.UnitSystem.Meters
    attrs = rhino3dm.ObjectAttributes()
    attrs.Name = "roof"
    model.Objects.AddSurface(s, attrs)
    model.Write(str(tmp_path / "design.3dm"), 0)

    def graph():
        g = Graph(base_dir=tmp_path)
        face = g.add("read_surface", id="surface", path="design.3dm", face="roof")
        mesh = g.add("sample", face.face, id="mesh", nu=6, nv=5)
        g.add("export_3dm", mesh.mesh, id="rhino", path="out.3dm", planar_tolerance="2 mm")
        g.add("export_dxf", mesh.mesh, id="dxf", path="out.dxf", planar_tolerance="2 mm")
        return g

    cache = Cache()
    res = graph().run(cache=cache)
    mesh = res["mesh.mesh"]
    assert mesh.n_faces == 20
    assert np.abs(mesh.vertices).max() == pytest.approx(4000.0)  # metres in the file, millimetres here
    back = rhino3dm.File3dm.Read(str(tmp_path / "out.3dm"))
    assert sum(isinstance(o.Geometry, rhino3dm.NurbsSurface) for o in back.Objects) == 20
    report = res["dxf.report"]
    assert report.n_panels == 20 and len(report.distortion) == 20 and report.to_dict()["unit"] == "mm"
    assert len(ezdxf.readfile(tmp_path / "out.dxf").modelspace().query("LWPOLYLINE")) == 20
    # unchanged file: from the cache; an edited file is read again
    assert graph().run(cache=cache).ran == []
    s.Points[(1, 1)] = rhino3dm.Point4d(2.6, 1.95, 0.0, 1.3)  # flatten the middle
    model = rhino3dm.File3dm()
    model.Settings.ModelUnitSystem = rhino3dm.UnitSystem.Meters
    model.Objects.AddSurface(s, attrs)
    model.Write(str(tmp_path / "design.3dm"), 0)
    again = graph().run(cache=cache)
    assert {"surface", "mesh", "rhino", "dxf"} <= set(again.ran)
    assert np.abs(again["mesh.mesh"].vertices[:, 2]).max() < 1e-6
    g = Graph(base_dir=tmp_path)
    g.add("read_surface", id="reader", path="design.3dm", face="floor")
    with pytest.raises(NodeError, match="reader.*no face named 'floor'"):
        g.run()


def test_thesis_chapter3_nodes_run_in_a_graph():
    from quadnodes.mesh import cylinder

    g = Graph()
    m = g.add("grid", id="m", rows=7, cols=8)
    noisy = g.add("perturb", m.mesh, id="noisy", normal=0.2, seed=1, fix="boundary")
    pick = g.add("select_fixed", noisy.mesh, id="pick", indices=[9])
    web = g.add("fair_web", noisy.mesh, pick.fixed, id="web", cylinder_height=0.05, cylinder_radius="0.1 mm")
    g.add("spring", noisy.mesh, pick.fixed, id="spring", max_iterations=20)
    g.add("schneider_kobbelt", noisy.mesh, id="sk", max_iterations=5, fix="boundary")
    g.add("curvature", web.mesh, id="curv")
    r = g.run()
    base = r["noisy.mesh"].vertices
    for key in ("web", "spring", "sk"):
        out, rep = r[f"{key}.mesh"], r[f"{key}.report"]
        b = out.topology.boundary_vertices
        assert np.array_equal(out.vertices[b], base[b]), key
        assert isinstance(rep.to_dict(), dict)
    assert np.array_equal(r["web.mesh"].vertices[9], base[9]) and np.array_equal(r["spring.mesh"].vertices[9], base[9])
    assert r["web.report"].max_outside < 1e-9
    assert r["curv.mean"].shape == (56,) and set(r["curv.curvature"]) >= {"mean", "gaussian", "k1", "k2"}
    for op in ("fair_web", "spring", "schneider_kobbelt", "curvature", "fourier"):
        assert describe(op)["summary"]
    c = cylinder(3, 12)
    v = c.vertices + 0.01 * np.cos(5 * np.arange(36))[:, None]
    out, rep = REGISTRY.get("fourier@1").func(c.with_vertices(v), keep=2)
    assert rep.closed_lines == 3 and rep.open_lines_untouched == 12


def test_render_png_node_colours_by_curvature(tmp_path):
    g = Graph()
    m = g.add("grid", id="m", rows=6, cols=7)
    noisy = g.add("perturb", m.mesh, id="noisy", normal=0.2, seed=3)
    g.add("render_png", noisy.mesh, id="png", path="k.png", color_by="gaussian", size_px=400)
    g.run(out=tmp_path)
    assert (tmp_path / "k.png").stat().st_size > 5_000
    bad = Graph()
    bm = bad.add("grid", id="m", rows=3, cols=3)
    with pytest.raises(GraphError, match="color_by"):
        bad.add("render_png", bm.mesh, id="png", path="x.png", color_by="Gauss")


def test_perturb_node_refuses_a_negative_seed_at_load_time():
    from quadnodes.graph import Graph

    g = Graph()
    m = g.add("grid", id="g", rows=4, cols=4)
    with pytest.raises(GraphError, match=r"node 'noisy' \(perturb@1\): setting 'seed': -1 is out of range \(must be >= 0\)"):
        g.add("perturb", m.mesh, id="noisy", tangential=0.2, seed=-1)


def test_select_fixed_refuses_a_box_whose_min_exceeds_its_max():
    # [xmax, ymax, zmax, xmin, ymin, zmin] selected nothing, silently: the vertices meant to stay moved
    g = Graph()
    m = g.add("grid", id="g", rows=4, cols=4)
    g.add("select_fixed", m.mesh, id="s", box=[3, 3, 1, 0, 0, -1])
    with pytest.raises(NodeError, match=r"node 's' \(select_fixed@1\): box: x goes from 3 down to 0 "
                                        r"\(\[xmin, ymin, zmin, xmax, ymax, zmax\]: the smaller values first\)"):
        g.run()
    g2 = Graph()
    m2 = g2.add("grid", id="g", rows=4, cols=4)
    s2 = g2.add("select_fixed", m2.mesh, id="s", box=[0, 0, 0, 1, 3, 0])  # a flat box (zmin = zmax) is fine
    assert int(g2.run()[s2.fixed].sum()) == 8


# --------------------------------------------------------------- face= means one thing in every reader (followups)
# read_step_surface took face 0 of a STEP file holding several faces without a word, where read_surface (and
# surfaces.from_file) refuse and list the faces.


def _two_face_step(path):
    """A STEP file holding a flat floor (2000 x 1000 at the origin) and a saddle roof (beside it, higher up)."""
    import build123d

    from quadnodes import surfaces

    floor = build123d.Face.make_rect(2000.0, 1000.0)
    floor.label = "floor"
    roof = surfaces.saddle(3000.0, 3000.0, 500.0).moved(build123d.Location((5000.0, 0.0, 800.0)))
    roof.label = "roof"
    assert build123d.export_step(build123d.Compound(children=[floor, roof]), path)
    return floor, roof


@pytest.mark.parametrize("op", ["read_step_surface", "read_surface"])
def test_a_file_with_several_faces_needs_face_and_gives_the_one_picked(tmp_path, op):
    from quadnodes import surfaces

    floor, roof = _two_face_step(tmp_path / "two.step")
    g = Graph(base_dir=tmp_path)
    g.add(op, id="reader", path="two.step")
    with pytest.raises(NodeError, match=rf"^node 'reader' \({op}@1\): face: '[^']*two\.step' holds 2 faces "
                                        r"\(0: floor \(a plane face\), 1: roof \(a bspline face\)\); "
                                        r"pass face= an index or a name"):
        g.run()
    for pick, want in ((1, roof), ("roof", roof), (0, floor), ("floor", floor)):
        g = Graph(base_dir=tmp_path)
        face = g.add(op, id="reader", path="two.step", face=pick)
        mesh = g.add("sample", face.face, id="mesh", nu=5, nv=4)
        res = g.run()
        got = res[face]
        assert got.area == pytest.approx(want.area, rel=1e-6), pick
        assert tuple(got.center()) == pytest.approx(tuple(want.center()), abs=1e-6), pick
        np.testing.assert_allclose(res[mesh].vertices, surfaces.sample(want, 5, 4).vertices, atol=1e-6)
    g = Graph(base_dir=tmp_path)
    g.add(op, id="reader", path="two.step", face=2)
    with pytest.raises(NodeError, match=r"face: index 2 is out of range, '[^']*two\.step' has 2 faces"):
        g.run()
    with pytest.raises(GraphError, match=rf"node 'r' \({op}@1\): setting 'face': -1 is out of range \(must be >= 0\)"):
        Graph(base_dir=tmp_path).add(op, id="r", path="two.step", face=-1)
    with pytest.raises(GraphError, match=rf"node 'r' \({op}@1\): setting 'face': expected int \| str \| None"):
        Graph(base_dir=tmp_path).add(op, id="r", path="two.step", face=1.5)


def test_read_step_surface_of_a_file_with_one_face_is_unchanged(tmp_path):
    import build123d

    from quadnodes import surfaces

    face = surfaces.wavy(2000.0, 3000.0, 200.0)
    assert build123d.export_step(face, tmp_path / "wavy.step")
    (tmp_path / "g.toml").write_text(
        'format = "quadnodes-graph"\nversion = 1\n\n'
        '[nodes.surface]\nop = "read_step_surface@1"\nparams = { path = "wavy.step" }\n\n'
        '[nodes.mesh]\nop = "sample@1"\ninputs = { face = "surface.face" }\nparams = { nu = 6, nv = 7 }\n\n'
        '[nodes.first]\nop = "read_step_surface@1"\nparams = { path = "wavy.step", face = 0 }\n'
    )
    from quadnodes.graph import load

    res = load(tmp_path / "g.toml").run()
    np.testing.assert_allclose(res["mesh.mesh"].vertices, surfaces.sample(face, 6, 7).vertices, atol=1e-6)
    assert res["first.face"].area == pytest.approx(face.area, rel=1e-9)
