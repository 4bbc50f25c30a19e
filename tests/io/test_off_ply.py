"""OFF and PLY quad meshes in, quads kept, with the OBJ reader's rules for other faces."""

import struct

import numpy as np
import pytest
from hypothesis import given

from quadnodes.errors import InputError
from quadnodes.io import load
from quadnodes.io.off import parse_off
from quadnodes.mesh import grid
from strategies import irregular

POINTS = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (2, 0, 0.5), (2, 1, 0.25), (3, 0, 0), (3, 1, 0)]


def off_text(faces, points=POINTS, newline="\n"):
    lines = ["OFF", "# a comment", f"{len(points)} {len(faces)} 0"]
    lines += [" ".join(map(repr, map(float, p))) for p in points]
    lines += [" ".join(map(str, [len(f), *f])) for f in faces]
    return newline.join(lines) + newline


def test_off_quads_kept(tmp_path):
    p = tmp_path / "a.off"
    p.write_text(off_text([(0, 1, 2, 3), (1, 4, 5, 2), (4, 6, 7, 5)]))
    m = load(p, renumber_grid=False)
    assert m.faces.tolist() == [[0, 1, 2, 3], [1, 4, 5, 2], [4, 6, 7, 5]]
    assert np.array_equal(m.vertices, np.array(POINTS, dtype=float)) and m.unit == "mm"
    assert load(p, renumber_grid=False, unit="m").unit == "m"


def test_off_variants_bom_crlf_tabs_colours_and_counts_on_the_keyword_line(tmp_path):
    text = off_text([(0, 1, 2, 3), (1, 4, 5, 2)], newline="\r\n").replace(" ", "\t")
    text = text.replace("OFF\r\n# a comment\r\n8\t2\t0", "\ufeffCOFF 8 2 0")
    text = text.replace("4\t1\t4\t5\t2", "4\t1\t4\t5\t2\t255 0 0")  # a face colour
    p = tmp_path / "c.off"
    p.write_text(text, encoding="utf-8")
    assert load(p, renumber_grid=False).faces.tolist() == [[0, 1, 2, 3], [1, 4, 5, 2]]


def test_off_non_quads_follow_the_obj_rule():
    text = off_text([(0, 1, 2, 3), (1, 4, 5), (1, 4, 6, 7, 5, 2)])
    with pytest.raises(InputError, match=r"x.off: face 1 \(line 13\) has 3 corners; only quads are supported"):
        parse_off(text, name="x.off")
    assert parse_off(text, non_quads="drop").faces.tolist() == [[0, 1, 2, 3]]
    with pytest.raises(InputError, match="odd polygon"):
        parse_off(text, non_quads="split")
    hexagon = off_text([(0, 1, 2, 3), (1, 4, 6, 7, 5, 2)])
    assert parse_off(hexagon, non_quads="split").faces.tolist() == [[0, 1, 2, 3], [1, 4, 6, 7], [1, 7, 5, 2]]


@pytest.mark.parametrize(
    "text, message",
    [
        ("OFF\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 9\n", r"line 7: vertex index 9 is out of range"),
        ("OFF\n4 1 0\n0 0 0\n1 0 0\n1 1\n0 1 0\n4 0 1 2 3\n", r"line 5: a vertex needs 3 coordinates"),
        ("OFF\n4 1 0\n0 0 0\n1 0 0\n1 x 0\n0 1 0\n4 0 1 2 3\n", r"line 5: bad vertex coordinates"),
        ("OFF\n4 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n", r"promise 4 vertices and 2 faces"),
        ("OFF\nfour 1 0\n", r"line 2: expected the counts"),
        ("OFF\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2\n", r"line 7: face says 4 corners but lists 3"),
        ("4OFF\n", r"unsupported OFF variant"),
        ("", "empty OFF file"),
    ],
)
def test_off_errors_name_the_line(text, message):
    with pytest.raises(InputError, match=message):
        parse_off(text, name="e.off")


def ply_header(fmt, n_faces, index="int", coord="double"):
    return (
        f"ply\nformat {fmt} 1.0\ncomment made by hand\nelement vertex {len(POINTS)}\nproperty {coord} x\n"
        f"property {coord} y\nproperty {coord} z\nelement face {n_faces}\n"
        f"property list uchar {index} vertex_indices\nend_header\n"
    )


FACES = [(0, 1, 2, 3), (1, 4, 5, 2), (4, 6, 7, 5)]


def test_ascii_ply(tmp_path):
    body = "".join(" ".join(map(repr, map(float, q))) + "\n" for q in POINTS)
    body += "".join(" ".join(map(str, [len(f), *f])) + "\n" for f in FACES)
    p = tmp_path / "a.ply"
    p.write_text(ply_header("ascii", 3) + body)
    m = load(p, renumber_grid=False)
    assert m.faces.tolist() == [list(f) for f in FACES]
    assert np.array_equal(m.vertices, np.array(POINTS, dtype=float))


@pytest.mark.parametrize("endian, fmt", [("<", "binary_little_endian"), (">", "binary_big_endian")])
def test_binary_ply(tmp_path, endian, fmt):
    pts = np.array(POINTS, dtype=float) * np.pi  # full mantissas
    data = b"".join(struct.pack(endian + "3d", *q) for q in pts.tolist())
    data += b"".join(struct.pack(endian + "B4i", 4, *f) for f in FACES)
    p = tmp_path / "b.ply"
    p.write_bytes(ply_header(fmt, 3).encode() + data)
    m = load(p, renumber_grid=False, unit="cm")
    assert m.faces.tolist() == [list(f) for f in FACES] and m.unit == "cm"
    assert np.array_equal(m.vertices, pts)  # bit for bit


def test_ply_non_quads(tmp_path):
    faces = [(0, 1, 2, 3), (1, 4, 5), (4, 6, 7, 5)]
    body = "".join(" ".join(map(repr, map(float, q))) + "\n" for q in POINTS)
    body += "".join(" ".join(map(str, [len(f), *f])) + "\n" for f in faces)
    p = tmp_path / "t.ply"
    p.write_text(ply_header("ascii", 3) + body)
    with pytest.raises(InputError, match=r"t.ply: face 1 has 3 corners; only quads are supported"):
        load(p, renumber_grid=False)
    assert load(p, renumber_grid=False, non_quads="drop").faces.tolist() == [[0, 1, 2, 3], [4, 6, 7, 5]]


def test_ply_that_is_not_ply(tmp_path):
    p = tmp_path / "bad.ply"
    p.write_text("ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nend_header\n1\n")
    with pytest.raises(InputError, match="bad.ply: not a PLY file meshio can read"):
        load(p, renumber_grid=False)
    with pytest.raises(InputError, match="cannot read"):
        load(tmp_path / "missing.ply")


def test_grid_through_off(tmp_path):
    g = grid(4, 5, height=np.random.default_rng(1).normal(size=(4, 5)))
    lines = ["OFF", f"{g.n_vertices} {g.n_faces} 0"] + ["%r %r %r" % tuple(v) for v in g.vertices.tolist()]
    lines += ["4 %d %d %d %d" % tuple(f) for f in g.faces.tolist()]
    (tmp_path / "g.off").write_text("\n".join(lines))
    m = load(tmp_path / "g.off", renumber_grid=False)
    assert np.array_equal(m.vertices, g.vertices) and np.array_equal(m.faces, g.faces)


@given(irregular())
def test_off_reads_any_quad_mesh_exactly(m):
    lines = ["OFF", f"{m.n_vertices} {m.n_faces} 0"] + ["%r %r %r" % tuple(v) for v in m.vertices.tolist()]
    lines += ["4 %d %d %d %d" % tuple(f) for f in m.faces.tolist()]
    back = parse_off("\n".join(lines))
    assert np.array_equal(back.vertices, m.vertices) and np.array_equal(back.faces, m.faces)
