"""The interactive HTML view: page content without a browser, then the page in headless Chromium."""

from __future__ import annotations

import base64
import json
import re
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

import quadnodes.nodes  # noqa: F401  (grid, perturb, fair, render_html nodes)
from quadnodes._view import edge_deviation, face_deviation
from quadnodes.errors import ExportError, InputError, NodeError
from quadnodes.fairing import fair
from quadnodes.graph import Graph
from quadnodes.html import build_html, figure, render_html
from quadnodes.mesh import grid
from quadnodes.noise import perturb
from quadnodes.flatness import diagonal_distance
from quadnodes.zigzag import detect

# --- helpers ------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def meshes():
    clean = grid(6, 8, height=0.1 * np.sin(np.arange(48.0)).reshape(6, 8))
    noisy, _ = perturb(clean, tangential=0.2, normal=0.1, seed=3, fix="corners")
    faired, _ = fair(noisy, iterations=2)
    return clean, noisy, faired


@pytest.fixture(scope="module")
def page(meshes, tmp_path_factory):
    clean, noisy, faired = meshes
    path = tmp_path_factory.mktemp("html") / "view.html"
    render_html([noisy, faired], path, titles=["noisy", "faired"], reference=clean)
    return path


class _Tags(HTMLParser):
    """Every start tag with its attributes."""

    def __init__(self) -> None:
        super().__init__()
        self.tags: list[tuple[str, dict[str, str | None]]] = []

    def handle_starttag(self, tag, attrs):
        self.tags.append((tag, dict(attrs)))


def _plot_args(text: str) -> tuple[list[dict], dict]:
    """The data and layout passed to ``Plotly.newPlot`` in the page."""
    m = re.search(r'Plotly\.newPlot\(\s*"[^"]+",\s*', text)
    assert m, "no Plotly.newPlot call in the page"
    dec = json.JSONDecoder()
    data, end = dec.raw_decode(text, m.end())
    layout, _ = dec.raw_decode(text, text.index("{", end))
    return data, layout


def _by_name(data: list[dict]) -> dict[str, dict]:
    return {t["name"]: t for t in data}


# --- the page without a browser ------------------------------------------------------------------------


def test_page_is_self_contained(page):
    text = page.read_text(encoding="utf-8")
    parser = _Tags()
    parser.feed(text)
    scripts = [a for t, a in parser.tags if t == "script"]
    assert scripts, "no script in the page"
    assert all("src" not in a for a in scripts), "a script is loaded from elsewhere"
    assert not [a for t, a in parser.tags if t == "link"], "the page links a stylesheet or another resource"
    assert '<script src="http' not in text
    assert "plotly.js v" in text  # the library itself is in the page
    assert text.startswith("<!DOCTYPE html>") and "<title>noisy / faired — quadnodes</title>" in text
    # plotly.js is about 4.8 MB; the meshes add little
    size = page.stat().st_size
    assert 3_000_000 < size < 7_000_000, size


def test_page_holds_the_traces_of_every_mesh_and_the_toggle(page):
    data, layout = _plot_args(page.read_text(encoding="utf-8"))
    names = [t["name"] for t in data]
    assert names == [
        "noisy: panels", "noisy: structure lines", "noisy: vertices",
        "faired: panels", "faired: structure lines", "faired: vertices",
        "reference", "reference boundary",
    ]
    assert [t.get("visible", True) for t in data] == [True] * 3 + [False] * 3 + [True] * 2
    (menu,) = layout["updatemenus"]
    assert [b["label"] for b in menu["buttons"]] == ["noisy", "faired"]
    show_faired = menu["buttons"][1]["args"]
    assert show_faired[0]["visible"] == [False] * 3 + [True] * 3 + [True] * 2
    assert "faired" in show_faired[1]["title.text"] and "zigzag max" in show_faired[1]["title.text"]
    assert "noisy" in layout["title"]["text"]
    # one scene whose ranges cover both meshes, so switching keeps the scale
    assert layout["scene"]["xaxis"]["range"][0] < 0 < 7 < layout["scene"]["xaxis"]["range"][1]


def _array(value) -> np.ndarray:
    """An array as plotly writes it into the page: a list, or ``{"dtype", "bdata", "shape"}`` (base64)."""
    if isinstance(value, dict) and "bdata" in value:
        a = np.frombuffer(base64.b64decode(value["bdata"]), dtype=np.dtype(value["dtype"]))
        shape = value.get("shape")
        return a.reshape([int(k) for k in str(shape).split(",")]) if shape else a
    return np.asarray(value)


def test_hover_texts_show_ids_deviation_and_planarity(page, meshes):
    _, noisy, _ = meshes
    data, _ = _plot_args(page.read_text(encoding="utf-8"))
    t = _by_name(data)
    n, m = noisy.n_vertices, noisy.n_faces
    rep = detect(noisy, 0.0)

    # vertices: one dot on each side of the surface, both with the vertex's numbers and exact position
    v = t["noisy: vertices"]
    assert v["hovertemplate"].startswith("<b>vertex %{customdata[0]}</b> (row %{customdata[1]}, col %{customdata[2]})")
    assert "zigzag deviation %{customdata[3]:.3~g}%{text}" in v["hovertemplate"]
    assert "max planarity of its panels %{customdata[4]:.3~g}" in v["hovertemplate"]
    cd = _array(v["customdata"])
    assert cd.shape == (2 * n, 8) and np.array_equal(cd[:n], cd[n:])
    ids = np.arange(n)
    np.testing.assert_array_equal(cd[:n, :3], np.column_stack([ids, ids // 8, ids % 8]))
    np.testing.assert_array_equal(cd[:n, 3], rep.vertex_deviation)
    plan = diagonal_distance(noisy)
    worst = np.array([plan[(noisy.faces == i).any(axis=1)].max() for i in range(n)])
    np.testing.assert_array_equal(cd[:n, 4], worst)
    np.testing.assert_array_equal(cd[:n, 5:], noisy.vertices)
    ends = np.flatnonzero(~noisy.topology.window_middle)
    assert [v["text"][i] for i in ends] == [" (its lines end here)"] * len(ends)
    assert {v["text"][i] for i in np.flatnonzero(noisy.topology.window_middle)} == {""}

    # panels: every corner of a panel carries the panel's numbers
    f = t["noisy: panels"]
    assert f["hovertemplate"].startswith("<b>panel %{customdata[0]}</b> (vertices %{customdata[1]}")
    assert "<br>planarity %{customdata[6]:.3~g}" in f["hovertemplate"]
    cd = _array(f["customdata"])
    assert cd.shape == (4 * m, 9)
    cd = cd[::4]
    np.testing.assert_array_equal(cd[:, 0], np.arange(m))
    np.testing.assert_array_equal(cd[:, 1:5], noisy.faces)
    np.testing.assert_allclose(cd[:, 5], face_deviation(noisy), rtol=1e-6)
    np.testing.assert_allclose(cd[:, 6], plan, rtol=1e-6)
    np.testing.assert_allclose(cd[:, 8], diagonal_distance(noisy, relative=False), rtol=1e-6)  # gap in mm
    assert "gap %{customdata[8]:.3~g} mm" in f["hovertemplate"]

    # edges: every point of an edge's piece carries the edge's ends and deviation
    e = t["noisy: structure lines"]
    assert e["hovertemplate"].startswith("edge %{customdata[0]}–%{customdata[1]}<br>zigzag deviation")
    cd = _array(e["customdata"])[::3]
    edges = noisy.topology.edges
    edev = edge_deviation(noisy)
    inner = int((~noisy.topology.boundary_edges).sum())
    assert len(cd) == 2 * inner + (len(edges) - inner)
    got = {(int(a), int(b)): d for a, b, d in cd}
    assert set(got) == set(map(tuple, edges.tolist()))
    for (a, b), d in zip(edges.tolist(), edev):
        assert got[a, b] == pytest.approx(d, rel=1e-6)


def test_figure_shapes_and_options(meshes):
    clean, noisy, _ = meshes
    fig = figure(noisy, show_vertices=False, vmin=1e-3, vmax=0.5)
    assert [t.name for t in fig.data] == ["mesh: panels", "mesh: structure lines"]
    assert not fig.layout.updatemenus  # one mesh: nothing to switch
    lines = fig.data[1]
    assert lines.line.cmin == pytest.approx(-3) and lines.line.cmax == pytest.approx(np.log10(0.5))
    # panels are split into two triangles each, shaded alike, within the shading range
    panels = fig.data[0]
    shade = np.asarray(panels.intensity)
    assert len(panels.i) == 2 * noisy.n_faces and panels.intensitymode == "cell"
    np.testing.assert_array_equal(shade[: noisy.n_faces], shade[noisy.n_faces :])
    assert panels.cmin <= shade.min() and shade.max() <= panels.cmax == 1.0
    # interior lines float off the surface to both sides, boundary lines do not double
    inner = int((~noisy.topology.boundary_edges).sum())
    outer = int(noisy.topology.boundary_edges.sum())
    assert len(lines.x) == 3 * (2 * inner + outer)
    pts = np.column_stack([lines.x, lines.y, lines.z])[np.isfinite(lines.x)]
    gap = np.linalg.norm(pts[:, None] - noisy.vertices[None], axis=2).min(axis=1)
    assert gap.max() < 0.1 * noisy.mean_edge_length  # close to the vertices they stand for
    # line width: 6 by default, thinner for dense meshes, or as given
    assert lines.line.width == 6.0
    assert figure(grid(60, 60)).data[1].line.width < 6.0
    assert figure(noisy, line_width=2.5).data[1].line.width == 2.5


@pytest.mark.parametrize("name", ["extraordinary", "l_shape", "cylinder", "tiny"])
def test_any_quad_mesh(name):
    from meshes import extraordinary_mesh, l_shape_with_hole

    from quadnodes.mesh import cylinder

    m = {"extraordinary": extraordinary_mesh, "l_shape": l_shape_with_hole,
         "cylinder": lambda: cylinder(4, 9), "tiny": lambda: grid(2, 2)}[name]()
    fig = figure(m, titles=[name])
    assert [t.name for t in fig.data][0] == f"{name}: panels"
    lines, dots = fig.data[1], fig.data[2]
    x = np.asarray(lines.x, dtype=float)
    assert np.isfinite(x).sum() == 2 * np.isnan(x).sum()  # two points and a gap per piece
    assert np.isfinite(np.asarray(lines.customdata, dtype=float)).all()
    assert len(dots.customdata) == 2 * m.n_vertices


def test_build_html_page_title(meshes):
    _, noisy, _ = meshes
    text = build_html(noisy, page_title="E1 <draft>")
    assert "<title>E1 &lt;draft&gt;</title>" in text


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"meshes": "mesh.obj"}, r"^meshes: expected a QuadMesh"),
        ({"meshes": []}, r"^meshes: got an empty sequence"),
        ({"meshes": "second-bad"}, r"^meshes\[1\]: expected a QuadMesh, got int"),
        ({"titles": ["only one"]}, r"^titles: 1 titles for 2 meshes"),
        ({"titles": "ab"}, r"^titles: expected a list of strings"),
        ({"titles": ["a", 2]}, r"^titles\[1\]: expected a string"),
        ({"reference": np.zeros((3, 3))}, r"^reference: expected a QuadMesh"),
        ({"vmin": 1.0, "vmax": 0.5}, r"^vmin: must be less than vmax"),
        ({"vmin": -1.0}, r"^vmin: must be > 0"),
        ({"elev": float("nan")}, r"^elev: must be finite"),
        ({"line_width": 0}, r"^line_width: must be > 0"),
        ({"show_vertices": "yes"}, r"^show_vertices: expected True or False"),
        ({"page_title": 3}, r"^page_title: expected a string"),
    ],
)
def test_errors_name_the_parameter(meshes, tmp_path, kwargs, match):
    _, noisy, faired = meshes
    kw = dict(kwargs)
    ms = kw.pop("meshes", [noisy, faired])
    if ms == "second-bad":
        ms = [noisy, 7]
    with pytest.raises(InputError, match=match):
        render_html(ms, tmp_path / "x.html", **kw)
    assert not list(tmp_path.iterdir())


def test_build_html_rejects_unknown_options(meshes):
    with pytest.raises(InputError, match=r"^colour: unknown option"):
        build_html(meshes[1], colour="red")


def test_unwritable_path_leaves_nothing(meshes, tmp_path):
    with pytest.raises(ExportError, match="missing"):
        render_html(meshes[1], tmp_path / "missing" / "x.html")
    assert not list(tmp_path.iterdir())


def test_node_in_a_graph(tmp_path):
    g = Graph(base_dir=tmp_path)
    m = g.add("grid", id="m", rows=5, cols=6)
    noisy = g.add("perturb", m.mesh, id="noisy", tangential=0.2, seed=1)
    new = g.add("fair", noisy.mesh, id="fair", iterations=2)
    g.add("render_html", noisy.mesh, new.mesh, reference=m.mesh, id="view", path="view.html",
          titles=["noisy", "faired"])
    out = g.run()["view.path"]
    assert Path(out) == tmp_path / "view.html"
    data, layout = _plot_args((tmp_path / "view.html").read_text(encoding="utf-8"))
    assert [b["label"] for b in layout["updatemenus"][0]["buttons"]] == ["noisy", "faired"]
    assert data[-1]["name"] == "reference boundary"

    g2 = Graph(base_dir=tmp_path)
    m2 = g2.add("grid", id="m", rows=3, cols=3)
    g2.add("render_html", m2.mesh, m2.mesh, id="pic", path="y.html", titles=["one"])
    with pytest.raises(NodeError, match="node 'pic'.*titles: 1 titles for 2"):
        g2.run()


# --- the page in headless Chromium -------------------------------------------------------------------

_BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")

# Written into a copy of the page before plotly's script: records script errors and failed loads.
_CATCH = """<script>
window.__errors = [];
function __note() { document.documentElement.setAttribute('data-errors', JSON.stringify(window.__errors)); }
window.addEventListener('error', function (e) {
  window.__errors.push(e.message ? 'error: ' + e.message : 'failed to load: ' + (e.target && (e.target.src || e.target.href)));
  __note();
}, true);
window.addEventListener('unhandledrejection', function (e) { window.__errors.push('rejection: ' + e.reason); __note(); });
__note();
</script>"""

# Written at the end of the copy: switches meshes with the buttons and hovers the scene, then writes
# what happened into <body data-probe="...">. The hover goes through plotly's own picking: a mouse move
# on the WebGL canvas, then one render of the scene (plotly redraws on the next animation frame, which
# headless Chromium's virtual clock does not always give after a synthetic event).
_PROBE = """<script>
window.addEventListener('load', function () {
  var out = {steps: []};
  function save() { document.body.setAttribute('data-probe', JSON.stringify(out)); }
  function visible(gd) { return gd.data.map(function (t) { return t.visible !== false; }); }
  function click(gd, k) {
    var b = gd.querySelectorAll('.updatemenu-button')[k];
    b.dispatchEvent(new MouseEvent('click', {bubbles: true}));
  }
  setTimeout(function () {
    var gd = document.querySelector('.js-plotly-plot');
    out.plotted = !!gd && !!gd._fullLayout;
    out.webgl_missing = document.body.innerText.indexOf('WebGL is not supported') >= 0;
    if (!out.plotted) { save(); return; }
    out.buttons = gd.querySelectorAll('.updatemenu-button').length;
    out.visible0 = visible(gd);
    click(gd, 1);
    setTimeout(function () {
      out.visible1 = visible(gd);
      out.title1 = gd.layout.title.text;
      click(gd, 0);
      setTimeout(function () {
        out.visible2 = visible(gd);
        out.hovers = [];
        gd.on('plotly_hover', function () {
          var label = document.querySelector('g.hovertext');
          out.hovers.push(label ? label.textContent : '(no label)');
        });
        var scene = gd._fullLayout.scene && gd._fullLayout.scene._scene;
        out.scene = !!scene;
        if (!scene) { save(); return; }
        var canvas = scene.glplot.canvas, r = canvas.getBoundingClientRect(), pts = [];
        for (var i = 2; i < 15; i++) for (var j = 2; j < 11; j++)
          pts.push([r.left + r.width * i / 16, r.top + r.height * j / 12]);
        var k = 0;
        (function step() {
          if (k >= pts.length || out.hovers.length >= 3) {
            out.resources = performance.getEntriesByType('resource').map(function (e) { return e.name; });
            out.done = true; save(); return;
          }
          var p = pts[k]; k += 5;
          canvas.dispatchEvent(new MouseEvent('mousemove', {clientX: p[0], clientY: p[1], bubbles: true}));
          setTimeout(function () { scene.render(); setTimeout(step, 50); }, 100);
        })();
      }, 500);
    }, 500);
  }, 1500);
});
</script>"""


def _browser() -> str:
    for name in _BROWSERS:
        exe = shutil.which(name)
        if exe:
            return exe
    pytest.skip(f"no Chromium found (looked for {', '.join(_BROWSERS)}); apt-get install chromium")


def _run_browser(exe: str, tmp: Path, page: Path, *mode: str) -> subprocess.CompletedProcess:
    profile = tmp / f"profile-{len(list(tmp.glob('profile-*')))}"
    cmd = [
        exe, "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader", "--disable-quic",
        "--no-first-run", "--disable-background-networking", "--disable-component-update", "--disable-sync",
        "--disable-extensions", "--hide-scrollbars", f"--user-data-dir={profile}",
        # no name resolves: anything the page tried to fetch from the network would fail and be noted
        "--host-resolver-rules=MAP * ~NOTFOUND",
        "--enable-logging=stderr", "--v=0",
        "--window-size=1200,900", "--virtual-time-budget=15000", *mode, page.as_uri(),
    ]
    try:
        return subprocess.run(cmd, capture_output=True, text=True, timeout=180)
    except subprocess.TimeoutExpired:
        pytest.fail(f"Chromium did not finish within 180 s: {' '.join(cmd)}")


def _console_errors(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if ":CONSOLE" in line and "Uncaught" in line]


def test_page_in_headless_chromium(page, tmp_path):
    exe = _browser()
    text = page.read_text(encoding="utf-8")
    probed = tmp_path / "probed.html"
    probed.write_text(text.replace("<head>", "<head>\n" + _CATCH, 1).replace("</body>", _PROBE + "\n</body>", 1),
                      encoding="utf-8")

    res = _run_browser(exe, tmp_path, probed, "--dump-dom")
    assert res.returncode == 0, res.stderr[-3000:]
    dom = res.stdout
    errors = re.search(r'<html[^>]*data-errors="([^"]*)"', dom)
    assert errors, "the error catcher did not run: " + dom[:500]
    assert json.loads(_unescape(errors.group(1))) == []
    assert not _console_errors(res.stderr), _console_errors(res.stderr)
    probe_attr = re.search(r'<body[^>]*data-probe="([^"]*)"', dom)
    assert probe_attr, "the probe did not finish within the virtual time budget"
    probe = json.loads(_unescape(probe_attr.group(1)))
    assert probe["plotted"] and not probe["webgl_missing"], probe
    assert probe.get("done"), probe
    # the page fetched nothing (the library is inline)
    assert probe["resources"] == [], probe["resources"]
    # the buttons switch between the meshes; the reference stays
    assert probe["buttons"] == 2
    assert probe["visible0"] == [True] * 3 + [False] * 3 + [True] * 2
    assert probe["visible1"] == [False] * 3 + [True] * 3 + [True] * 2
    assert "faired" in probe["title1"]
    assert probe["visible2"] == probe["visible0"]
    # hovering the scene shows our texts
    assert probe["scene"] and probe["hovers"], "no hover label over the mesh"
    assert all(re.match(r"(vertex|panel) \d+ |edge \d+–\d+zigzag", h) for h in probe["hovers"]), probe["hovers"]
    assert any("zigzag deviation" in h for h in probe["hovers"])

    # a screenshot of the page as it is: not blank, and the structure-line colours are there
    shot = tmp_path / "view.png"
    res = _run_browser(exe, tmp_path, page, f"--screenshot={shot}")
    assert res.returncode == 0 and shot.exists(), res.stderr[-3000:]
    assert not _console_errors(res.stderr), _console_errors(res.stderr)
    import matplotlib.image as mpimg

    img = mpimg.imread(shot)[..., :3]
    assert img.shape[0] >= 600 and img.shape[1] >= 1000, img.shape
    assert float(img.std()) > 0.05, "the screenshot is (nearly) blank"
    non_white = (img < 0.94).any(axis=2).mean()
    assert non_white > 0.05, f"only {non_white:.1%} of the screenshot is drawn"
    saturated = (img.max(axis=2) - img.min(axis=2) > 0.35).mean()
    assert saturated > 0.002, f"hardly any coloured pixels ({saturated:.2%}): no structure lines drawn?"


def _unescape(attr: str) -> str:
    import html

    return html.unescape(attr)


def test_large_meshes_are_sent_compactly(tmp_path):
    # 100 x 100: was 47 MB (about 1 kB per vertex); compact detail keeps the data under 5 MB for two meshes
    from quadnodes.fairing import fair

    noisy, _ = perturb(grid(100, 100, spacing=100.0), tangential=0.2, normal=0.1, seed=1)
    faired, _ = fair(noisy, iterations=1)
    page = render_html([noisy, faired], tmp_path / "big.html", titles=["noisy", "faired"])
    text = page.read_text(encoding="utf-8")
    data, layout = _plot_args(text)
    plotly_js = len(text) - len(json.dumps(data))
    assert len(json.dumps(data)) < 5_000_000 and len(data) == 4, (len(json.dumps(data)), plotly_js)
    t = _by_name(data)
    lines = t["noisy: structure lines"]
    assert lines["hovertemplate"].startswith("<b>vertex %{customdata[0]}</b>")
    cd = _array(lines["customdata"])
    ok = ~np.isnan(_array(lines["x"]))
    ids = cd[ok, 0].astype(int)
    assert set(ids) == set(range(noisy.n_vertices))  # every vertex is on a drawn line
    np.testing.assert_allclose(cd[ok, 1], detect(noisy, 0.0).vertex_deviation[ids], rtol=1e-6)
    assert layout["scene"]["xaxis"]["title"]["text"] == "x (mm)"
    full = figure(grid(5, 5), detail="full")
    assert len(full.data) == 3 and figure(grid(5, 5), detail="compact").data[1].mode == "lines"


def test_a_vertex_in_no_face_does_not_move_the_camera(meshes):
    # an OBJ's unreferenced vertex, never drawn, set the scene's ranges: the mesh shrank into a corner
    from quadnodes.mesh import QuadMesh

    _, noisy, _ = meshes
    far = noisy.vertices.max(axis=0) + 20 * (noisy.vertices.max(axis=0) - noisy.vertices.min(axis=0))
    stray = QuadMesh(np.vstack([noisy.vertices, far]), noisy.faces)
    a, b = figure(noisy).layout.scene, figure(stray).layout.scene
    for axis in ("xaxis", "yaxis", "zaxis"):
        assert a[axis].range == b[axis].range
    assert a.aspectratio == b.aspectratio


def test_meshes_in_other_units_are_shown_in_the_first_one_s_unit(meshes):
    # a mesh or reference in metres beside one in millimetres was drawn a thousand times too small
    clean, noisy, _ = meshes
    a = figure([noisy, noisy], reference=clean).layout.scene
    b = figure([noisy, noisy.with_unit("m")], reference=clean.with_unit("cm")).layout.scene
    for axis in ("xaxis", "yaxis", "zaxis"):
        np.testing.assert_allclose(a[axis].range, b[axis].range, rtol=1e-9)
    fig = figure([noisy, noisy.with_unit("m")], reference=clean.with_unit("cm"))
    panels = [t for t in fig.data if t.name.endswith(": panels")]
    assert len(panels) == 2
    for c in "xyz":
        np.testing.assert_allclose(panels[1][c], panels[0][c], rtol=1e-9, atol=1e-9)
    ref = next(t for t in fig.data if t.name == "reference")
    want = next(t for t in figure(noisy, reference=clean).data if t.name == "reference")
    np.testing.assert_allclose(np.asarray(ref.x, float), np.asarray(want.x, float), rtol=1e-9)
