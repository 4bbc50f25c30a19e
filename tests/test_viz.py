"""PNG views: non-blank images of the right size, every option, errors that name the parameter."""

import numpy as np
import pytest
from matplotlib.image import imread
from PIL import Image

import quadnodes as qn
import quadnodes.nodes  # noqa: F401  (registers the built-in nodes)
from quadnodes import viz
from quadnodes.errors import ExportError, InputError
from quadnodes.graph import Cache, Graph
from quadnodes.mesh import grid
from quadnodes.topology import windows
from quadnodes.zigzag import window_deviation


def _wavy(rows=8, cols=11):
    i, j = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    return grid(rows, cols, height=0.6 * np.sin(j / 2.0) * np.cos(i / 3.0))


@pytest.fixture(scope="module")
def meshes():
    clean = _wavy()
    noisy, _ = qn.perturb(clean, tangential=0.25, normal=0.1, seed=3, fix="corners")
    faired, _ = qn.fair(noisy, iterations=2)
    return clean, noisy, faired


def _pixels(path):
    img = imread(path)
    assert img.ndim == 3
    return img[..., :3]


def _check_image(path, width):
    px = _pixels(path)
    assert px.shape[1] == width
    assert px.shape[0] > 0.2 * width
    # not blank: many distinct values, dark lines on a white background
    assert px.std() > 0.05
    assert (px.min(axis=2) < 0.3).mean() > 0.002
    assert (px.min(axis=2) > 0.98).mean() > 0.2
    assert len(np.unique(px.reshape(-1, 3).round(2), axis=0)) > 30
    return px


def test_plain_render_has_the_right_size_and_is_not_blank(tmp_path, meshes):
    _, noisy, _ = meshes
    p = viz.render_png(noisy, tmp_path / "one.png", size_px=400)
    assert p == tmp_path / "one.png"
    _check_image(p, 400)


def test_all_options(tmp_path, meshes):
    clean, noisy, faired = meshes
    rep = qn.detect(noisy, 0.1)
    plain = viz.render_png([noisy, faired], tmp_path / "plain.png", size_px=600)
    full = viz.render_png(
        [noisy, faired], tmp_path / "full.png", titles=["noisy", "faired"], notes=["a", "b\nc"],
        free=[rep, np.flatnonzero(rep.free)], fixed=[None, noisy.topology.corner_vertices],
        reference=clean, planarity=[False, True], elev=20, azim=-30, size_px=600,
    )
    a, b = _check_image(plain, 600), _check_image(full, 600)
    assert a.shape != b.shape or not np.array_equal(a, b)
    assert b.shape[0] > a.shape[0]  # titles, notes and legend take room


def test_options_change_the_picture(tmp_path, meshes):
    clean, noisy, _ = meshes
    base = _pixels(viz.render_png(noisy, tmp_path / "a.png", size_px=400, ncols=1))
    for name, kw in [("free", dict(free=qn.detect(noisy, 0.1).free)),
                     ("planarity", dict(planarity=True)),
                     ("camera", dict(elev=60.0, azim=10.0))]:
        px = _pixels(viz.render_png(noisy, tmp_path / f"{name}.png", size_px=400, ncols=1, **kw))
        if px.shape == base.shape:
            assert np.abs(px - base).max() > 0.2, name
    # a reference in every panel: its dashed boundary adds dark pixels outside a shrunk mesh
    shrunk, _ = qn.laplacian(noisy, iterations=5)
    without = _pixels(viz.render_png(shrunk, tmp_path / "s0.png", size_px=400))
    with_ref = _pixels(viz.render_png(shrunk, tmp_path / "s1.png", size_px=400, reference=[clean]))
    assert without.shape[1] == with_ref.shape[1] == 400


def test_layouts_and_palette(tmp_path, meshes):
    _, noisy, faired = meshes
    three = viz.render_png([noisy, faired, noisy], tmp_path / "three.png", size_px=900)
    _check_image(three, 900)
    p = viz.render_png([noisy, faired, noisy, faired], tmp_path / "pal.png", size_px=800, palette=64,
                       ncols=4)
    with Image.open(p) as im:
        assert im.mode == "P" and im.size[0] == 800
    _check_image(p, 800)


def test_flat_mesh_and_planarity_of_planar_faces(tmp_path):
    # all-planar faces and no zigzag: still a valid picture, values clipped to the scales' low ends
    p = viz.render_png(grid(4, 5), tmp_path / "flat.png", planarity=True, size_px=300)
    px = _pixels(p)
    assert px.shape[1] == 300 and px.std() > 0.02


def test_edge_deviation_matches_the_windows(meshes):
    _, noisy, _ = meshes
    d = viz.edge_deviation(noisy)
    e = noisy.topology.edges
    w = windows(noisy.topology.structure_lines)
    wd = window_deviation(noisy.vertices, w)
    assert d.shape == (len(e),)
    lookup = {tuple(x): k for k, x in enumerate(e.tolist())}
    for (a, b, c, dd), v in zip(w.tolist(), wd):
        assert d[lookup[tuple(sorted((b, c)))]] >= v - 1e-15
    assert d.max() == pytest.approx(wd.max())
    assert np.all(viz.edge_deviation(grid(3, 4)) == 0.0)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(titles=["just one"]), "titles: 1 titles for 2 meshes"),
        (dict(notes="not a list"), "notes:"),
        (dict(free=np.ones(5, dtype=bool)), r"free: boolean mask must have shape \(88,\)"),
        (dict(free=[None]), "free: 1 values for 2 meshes"),
        (dict(fixed=[None, np.array([1000])]), r"fixed\[1\]: vertex index 1000"),
        (dict(reference="clean"), "reference:"),
        (dict(reference=[None, 3]), r"reference\[1\]: expected a QuadMesh"),
        (dict(planarity=[True]), "planarity: 1 values for 2 meshes"),
        (dict(planarity=[True, "yes"]), r"planarity\[1\]"),
        (dict(vmin=1.0, vmax=0.1), "vmin: must be less than vmax"),
        (dict(vmin=-1.0), "vmin: must be > 0"),
        (dict(elev=float("nan")), "elev: must be finite"),
        (dict(size_px=50), "size_px: must be >= 200"),
        (dict(ncols=0), "ncols: must be >= 1"),
        (dict(palette=1000), "palette: at most 256"),
        (dict(planarity=True, planarity_range=(0.1, 0.01)), "planarity_range"),
    ],
)
def test_errors_name_the_parameter(tmp_path, meshes, kwargs, match):
    _, noisy, faired = meshes
    with pytest.raises(InputError, match=match):
        viz.render_png([noisy, faired], tmp_path / "x.png", **kwargs)
    assert not (tmp_path / "x.png").exists()


def test_bad_meshes_and_paths(tmp_path, meshes):
    _, noisy, _ = meshes
    with pytest.raises(InputError, match="meshes: got an empty sequence"):
        viz.render_png([], tmp_path / "x.png")
    with pytest.raises(InputError, match=r"meshes\[1\]: expected a QuadMesh"):
        viz.render_png([noisy, "mesh"], tmp_path / "x.png")
    with pytest.raises(InputError, match="ZigzagReport is for"):
        viz.render_png(grid(3, 3), tmp_path / "x.png", free=qn.detect(noisy, 0.1))
    with pytest.raises(ExportError, match="missing"):
        viz.render_png(noisy, tmp_path / "missing" / "x.png", size_px=300)


def test_render_node_with_reference_and_zigzag(tmp_path):
    g = Graph(base_dir=tmp_path)
    m = g.add("grid", id="m", rows=6, cols=7)
    noisy = g.add("perturb", m.mesh, id="noisy", tangential=0.2, seed=1, fix="corners")
    zz = g.add("detect", noisy.mesh, id="zz", threshold=0.05)
    new = g.add("fair", noisy.mesh, id="fair", iterations=2)
    g.add("render_png", noisy.mesh, new.mesh, reference=m.mesh, zigzag=zz.report, id="png", path="v.png",
          titles=["noisy", "faired"], notes=["in", "out"], planarity=True, ncols=2, size_px=500)
    g.run(cache=Cache())
    _check_image(tmp_path / "v.png", 500)


def test_dense_meshes_show_every_kth_line_and_a_scale_bar(tmp_path):
    # 300 x 300 at 1200 px: 4 px per edge drew a moiré of edges; now every k-th structure line
    from quadnodes.viz import _every_kth_line, _line_step

    m = grid(300, 300, spacing=20.0)
    step = _line_step(4.0)
    keep = _every_kth_line(m, step)
    e = m.topology.edges
    r, c = np.divmod(e, 300)
    assert step == 2 and keep.sum() == ((r[:, 0] == r[:, 1]) & (r[:, 0] % 2 == 0)).sum() * 2
    p = viz.render_png(m, tmp_path / "dense.png", planarity="length")
    assert p.stat().st_size > 10_000
    with pytest.raises(InputError, match="planarity"):
        viz.render_png([m, m], tmp_path / "x.png", planarity=["relative", "length"])
    with pytest.raises(InputError, match="planarity"):
        viz.render_png(m, tmp_path / "x.png", planarity="mm")


def test_color_by_curvature_and_arrays(tmp_path):
    from quadnodes import surfaces

    m = surfaces.sample(surfaces.saddle(), 9, 9)
    render_png = viz.render_png
    a = render_png([m, m], tmp_path / "a.png", color_by="mean", size_px=400)
    b = render_png([m, m], tmp_path / "b.png", color_by=["gaussian", np.arange(m.n_faces, dtype=float)],
                   size_px=400)
    c = render_png(m, tmp_path / "c.png", size_px=400)
    assert a.read_bytes() != c.read_bytes() and b.read_bytes() != a.read_bytes()
    render_png(m, tmp_path / "d.png", color_by=np.linspace(0, 1, m.n_vertices), size_px=400)
    with pytest.raises(InputError, match="color_by: expected one of"):
        render_png(m, tmp_path / "e.png", color_by="Mean")
    with pytest.raises(InputError, match=r"color_by: expected a curvature name, 81 vertex values or 64 panel"):
        render_png(m, tmp_path / "e.png", color_by=np.ones(5))
    assert not (tmp_path / "e.png").exists()


def test_a_vertex_in_no_face_does_not_move_the_camera(tmp_path, meshes):
    # an OBJ's unreferenced vertex, never drawn, set the view's limits: the mesh shrank into a corner
    _, noisy, _ = meshes
    far = noisy.vertices.max(axis=0) + 20 * (noisy.vertices.max(axis=0) - noisy.vertices.min(axis=0))
    stray = qn.QuadMesh(np.vstack([noisy.vertices, far]), noisy.faces)
    a = viz.render_png(noisy, tmp_path / "a.png", size_px=300)
    b = viz.render_png(stray, tmp_path / "b.png", size_px=300)
    np.testing.assert_array_equal(imread(a), imread(b))


def test_meshes_in_other_units_are_drawn_in_the_first_one_s_unit(tmp_path, meshes):
    # a mesh or reference in metres beside one in millimetres was drawn a thousand times too small
    clean, noisy, _ = meshes
    a = viz.render_png([noisy, noisy], tmp_path / "a.png", size_px=300, reference=clean)
    b = viz.render_png([noisy, noisy.with_unit("m")], tmp_path / "b.png", size_px=300,
                       reference=clean.with_unit("cm"))
    np.testing.assert_allclose(imread(a), imread(b), atol=1 / 255)
