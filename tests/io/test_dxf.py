"""DXF unrolls, read back with ezdxf (not quadnodes' code)."""

import os

import ezdxf
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from quadnodes.errors import ExportError, InputError
from quadnodes.flatness import planar_panels
from quadnodes.io import dxf, save
from quadnodes.io.dxf import dxf_report, layout, panel_distortion, save_dxf, unfold
from quadnodes.io.panels import panel_labels
from quadnodes.mesh import QuadMesh, grid


def twisted(rows=5, cols=6):
    rng = np.random.default_rng(5)
    h = rng.normal(scale=30.0, size=(rows, cols))
    h[:2] = 0.0  # first row of panels flat
    return grid(rows, cols, spacing=(500.0, 400.0), height=h)


def read(path):
    doc = ezdxf.readfile(path)
    msp = doc.modelspace()
    polys = [np.array(e.get_points("xy")) for e in msp.query("LWPOLYLINE")]
    layers = [e.dxf.layer for e in msp.query("LWPOLYLINE")]
    closed = [e.closed for e in msp.query("LWPOLYLINE")]
    texts = [(e.dxf.text, e.dxf.layer, np.array(e.dxf.align_point)[:2]) for e in msp.query("TEXT")]
    return doc, polys, layers, closed, texts


def lengths3d(m):
    p = m.vertices[m.faces]
    edges = np.linalg.norm(np.roll(p, -1, axis=1) - p, axis=2)
    diags = np.stack([np.linalg.norm(p[:, 2] - p[:, 0], axis=1), np.linalg.norm(p[:, 3] - p[:, 1], axis=1)], 1)
    return edges, diags


def lengths2d(polys):
    q = np.array(polys)
    edges = np.linalg.norm(np.roll(q, -1, axis=1) - q, axis=2)
    diags = np.stack([np.linalg.norm(q[:, 2] - q[:, 0], axis=1), np.linalg.norm(q[:, 3] - q[:, 1], axis=1)], 1)
    return edges, diags


def assert_no_overlaps(polys):
    q = np.array(polys)
    lo, hi = q.min(axis=1), q.max(axis=1)
    apart = (hi[:, None, 0] < lo[None, :, 0]) | (hi[None, :, 0] < lo[:, None, 0]) | \
            (hi[:, None, 1] < lo[None, :, 1]) | (hi[None, :, 1] < lo[:, None, 1])
    np.fill_diagonal(apart, True)
    assert apart.all()


def test_unroll_edges_layers_labels_and_units(tmp_path):
    m = twisted()
    tol = "1 mm"
    p, report = dxf_report(m, tmp_path / "t.dxf", planar_tolerance=tol)
    doc, polys, layers, closed, texts = read(p)
    assert doc.header["$INSUNITS"] == 4 and doc.header["$MEASUREMENT"] == 1
    assert len(polys) == len(texts) == m.n_faces
    assert set(layers) == {"PANELS"} and all(closed) and {t[1] for t in texts} == {"LABELS"}
    assert [t[0] for t in texts] == panel_labels(m)
    for poly, (_, _, at) in zip(polys, texts):  # every label inside its own panel's box
        assert (poly.min(axis=0) <= at).all() and (at <= poly.max(axis=0)).all()
    assert_no_overlaps(polys)
    e3, d3 = lengths3d(m)
    e2, d2 = lengths2d(polys)
    np.testing.assert_allclose(e2, e3, rtol=1e-9)  # every edge keeps its length (two-triangle unfolding)
    planar = planar_panels(m, tol)
    assert 0 < planar.sum() < m.n_faces
    np.testing.assert_allclose(d2[planar], d3[planar], rtol=1e-9)  # a planar panel is itself
    distortion = np.abs(d2 - d3).max(axis=1)
    np.testing.assert_allclose(report.distortion, distortion, rtol=1e-6, atol=1e-9)
    assert (report.distortion[~planar] > 1e-3).all() and report.max_distortion == report.distortion.max()
    assert report.n_planar == int(planar.sum())
    colors = [e.dxf.color for e in doc.modelspace().query("LWPOLYLINE")]
    assert colors == [3 if f else 30 for f in planar]
    assert len(doc.audit().errors) == 0


def test_fast_writer_matches_ezdxf_entities(tmp_path):
    m = twisted(4, 4)
    a = read(save_dxf(m, tmp_path / "fast.dxf"))
    b = read(save_dxf(m, tmp_path / "slow.dxf", engine="ezdxf"))
    for pa, pb in zip(a[1], b[1]):
        assert np.array_equal(pa, pb)
    assert a[2:4] == b[2:4]
    assert [(t, l) for t, l, _ in a[4]] == [(t, l) for t, l, _ in b[4]]
    assert all(np.array_equal(x[2], y[2]) for x, y in zip(a[4], b[4]))


@pytest.mark.parametrize("unit, code", [("mm", 4), ("cm", 5), ("m", 6), ("in", 1), ("ft", 2)])
def test_units(tmp_path, unit, code):
    g = grid(3, 3)
    doc = ezdxf.readfile(save(QuadMesh(g.vertices, g.faces, unit=unit), tmp_path / "u.dxf"))
    assert doc.header["$INSUNITS"] == code


def _crosses(a, b, c, d):
    """Whether segments ab and cd intersect (opposite edges of a quad)."""

    def side(p, q, r):
        return np.sign((q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]))

    return side(a, b, c) * side(a, b, d) <= 0 and side(c, d, a) * side(c, d, b) <= 0


quads = st.tuples(
    st.floats(0.2, 5.0), st.floats(0.2, 5.0), st.floats(-0.9, 0.9), st.floats(-0.9, 0.9),
    st.floats(-3.0, 3.0), st.floats(-3, 3), st.floats(1e-3, 1e4), st.integers(0, 2**31 - 1),
)


@settings(max_examples=60, deadline=None)
@given(quads)
def test_a_planar_quad_unfolds_to_itself_convex_or_not(q):
    """Any simple planar quad (also non-convex), anywhere in space, at any scale."""
    w, h, sx, sy, tilt, spin, scale, seed = q
    flat = np.array([[0, 0], [w, 0], [w * (1 + sx), h], [w * sy, h * 0.7]], dtype=float)
    area = 0.5 * np.sum(flat[:, 0] * np.roll(flat[:, 1], -1) - np.roll(flat[:, 0], -1) * flat[:, 1])
    e = np.linalg.norm(np.roll(flat, -1, axis=0) - flat, axis=1)
    if area < 1e-3 * e.max() ** 2 or _crosses(flat[0], flat[1], flat[2], flat[3]) or _crosses(
        flat[1], flat[2], flat[3], flat[0]
    ):
        return  # a bow-tie or nearly degenerate: not a panel
    rot = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))[0]
    v = scale * np.c_[flat, np.zeros(4)] @ rot.T + np.random.default_rng(seed).normal(size=3) * scale
    m = QuadMesh(v, np.array([[0, 1, 2, 3]]))
    u = unfold(m)
    e3, d3 = lengths3d(m)
    e2, d2 = lengths2d(u.outlines)
    np.testing.assert_allclose(e2, e3, rtol=1e-9)
    np.testing.assert_allclose(d2, d3, rtol=1e-9)
    o = u.outlines[0]
    signed = 0.5 * np.sum(o[:, 0] * np.roll(o[:, 1], -1) - np.roll(o[:, 0], -1) * o[:, 1])
    assert np.isclose(signed, area * scale**2, rtol=1e-9)  # counter-clockwise, not mirrored
    assert u.distortion[0] <= 1e-9 * d3.max()


@settings(max_examples=30, deadline=None)
@given(st.integers(1, 40), st.floats(0.0, 10.0), st.integers(0, 2**31 - 1))
def test_layout_never_overlaps(per_row, gap, seed):
    rng = np.random.default_rng(seed)
    outlines = rng.uniform(-5, 5, size=(int(rng.integers(1, 60)), 4, 2)) * rng.uniform(0.01, 100)
    assert_no_overlaps(layout(outlines, per_row=per_row, gap=gap + 1e-9))


def test_distortion_of_a_twisted_panel():
    m = grid(2, 2, spacing=1000.0, height=[[0, 0], [0, 100]])
    d = panel_distortion(m)[0]
    e3, d3 = lengths3d(m)
    e2, d2 = lengths2d(unfold(m).outlines)
    np.testing.assert_allclose(e2, e3, rtol=1e-12)  # the edges keep their lengths
    # one diagonal is kept, the other changes by the distortion
    assert np.abs(d2 - d3).min() < 1e-9 and d == pytest.approx(np.abs(d2 - d3).max(), rel=1e-9) and d > 1.0


def test_bad_input_leaves_nothing(tmp_path, monkeypatch):
    v = grid(2, 3, spacing=100.0).vertices.copy()
    v[[3, 4, 5], 1] = 0.0
    v[[3, 4, 5], 0] += 1.0
    bad = grid(2, 3).with_vertices(v)  # a processed mesh can collapse a panel; QuadMesh() refuses one
    with pytest.raises(ExportError, match=r"panel 0 \(P_0_0\) is degenerate"):
        save_dxf(bad, tmp_path / "d.dxf")
    (tmp_path / "file").write_text("x")
    with pytest.raises(ExportError, match="file"):
        save_dxf(twisted(), tmp_path / "file" / "x.dxf")
    monkeypatch.delitem(dxf.INSUNITS, "cm")
    g = grid(3, 3)
    with pytest.raises(ExportError, match=r"unit 'cm' has no DXF \$INSUNITS"):
        save_dxf(QuadMesh(g.vertices, g.faces, unit="cm"), tmp_path / "cm.dxf")
    for kw, name in [({"planar_tolerance": -1.0}, "planar_tolerance"), ({"per_row": 0}, "per_row"),
                     ({"gap": -1.0}, "gap"), ({"text_height": 0.0}, "text_height"), ({"engine": "EZDXF"}, "engine")]:
        with pytest.raises(InputError, match=name):
            save_dxf(g, tmp_path / "k.dxf", **kw)
    assert sorted(os.listdir(tmp_path)) == ["file"]


def test_a_closed_mesh_without_grid_unrolls_without_overlaps(tmp_path):
    from quadnodes.mesh import torus

    t = torus(6, 10, major=2000.0, minor=600.0)
    m = QuadMesh(t.vertices, t.faces)
    p = save_dxf(m, tmp_path / "t.dxf")
    _, polys, _, _, texts = read(p)
    assert len(polys) == 60 and [x[0] for x in texts] == [f"P_{k}" for k in range(60)]
    assert_no_overlaps(polys)
    e3, _ = lengths3d(m)
    e2, _ = lengths2d(polys)
    np.testing.assert_allclose(e2, e3, rtol=1e-9)
