import os

import numpy as np
import pytest
import trimesh
from hypothesis import given

from quadnodes.errors import ExportError, InputError
from quadnodes.io import _atomic
from quadnodes.io.obj import load_obj, obj_text, parse_obj, save_obj
from quadnodes.mesh import QuadMesh, grid
from strategies import grids, irregular

SQUARE = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"


def assert_same(a: QuadMesh, b: QuadMesh) -> None:
    assert np.array_equal(a.vertices, b.vertices)  # bit for bit
    assert np.array_equal(a.faces, b.faces)
    assert a.grid_shape == b.grid_shape


@given(grids(amplitude=1e3))
def test_round_trip_of_random_height_grids_is_exact(m):
    m = m.with_vertices(m.vertices * np.pi)  # coordinates with full mantissas
    assert_same(parse_obj(obj_text(m)), m)


@given(irregular())
def test_round_trip_of_irregular_meshes_is_exact(m):
    back = parse_obj(obj_text(m))
    assert_same(back, m)
    assert back.grid_shape is None


def test_file_round_trip(tmp_path):
    m = grid(5, 7, height=np.random.default_rng(0).normal(size=(5, 7)))
    p = save_obj(m, tmp_path / "m.obj")
    assert p == tmp_path / "m.obj"
    assert_same(load_obj(p), m)
    assert os.listdir(tmp_path) == ["m.obj"]


def test_quads_are_written_as_quads():
    text = obj_text(grid(3, 4), header=False)
    f_lines = [l for l in text.splitlines() if l.startswith("f ")]
    assert len(f_lines) == 6 and all(len(l.split()) == 5 for l in f_lines)
    assert f_lines[0] == "f 1 2 6 5"


def test_trimesh_reads_our_file_independently(tmp_path):
    m = grid(4, 5, height=np.random.default_rng(2).normal(size=(4, 5)))
    p = save_obj(m, tmp_path / "m.obj")
    tm = trimesh.load(p, process=False, maintain_order=True)
    np.testing.assert_array_equal(tm.vertices, m.vertices)
    assert len(tm.faces) == 2 * m.n_faces  # trimesh splits every quad into two triangles


def test_grid_comment_is_ignored_when_it_does_not_match():
    text = "# quadnodes grid_shape 2 2\n" + SQUARE + "f 1 2 3 4\n"  # not grid order
    assert parse_obj(text).grid_shape is None
    grid_order = SQUARE.replace("v 1 1 0\nv 0 1 0", "v 0 1 0\nv 1 1 0") + "f 1 2 4 3\n"
    assert parse_obj("# quadnodes grid_shape 2 2\n" + grid_order).grid_shape == (2, 2)
    assert parse_obj("# quadnodes grid_shape 3 3\n" + grid_order).grid_shape is None
    assert parse_obj("# quadnodes grid_shape two 2\n" + grid_order).grid_shape is None
    assert parse_obj(grid_order).grid_shape is None


def test_index_forms_negative_indices_comments_and_other_statements():
    text = (
        "# a comment\n"
        "mtllib panels.mtl\n"
        "o panel\n"
        "v 0 0 0 1.0\n"          # optional weight
        "v 1 0 0 0.5 0.5 0.5\n"  # vertex colour
        "\n"
        "vt 0 0\nvn 0 0 1\n"
        "v 1 1 0  # trailing comment\n"
        "v 0 1 0\n"
        "g group\ns off\nusemtl glass\n"
        "f 1/1/1 2/1/1 -2//1 -1/1\n"
        "l 1 2\n"
    )
    m = parse_obj(text)
    assert m.faces.tolist() == [[0, 1, 2, 3]]
    np.testing.assert_array_equal(m.vertices, [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])


def test_crlf_and_line_continuation():
    text = SQUARE.replace("\n", "\r\n") + "f 1 2 \\\r\n 3 4\r\n"
    assert parse_obj(text).faces.tolist() == [[0, 1, 2, 3]]


def test_relative_indices_count_from_the_vertices_read_so_far():
    text = SQUARE + "f -4 -3 -2 -1\nv 2 0 0\nv 2 1 0\nf 2 -2 -1 3\n"
    assert parse_obj(text).faces.tolist() == [[0, 1, 2, 3], [1, 4, 5, 2]]


def test_positive_forward_references_are_allowed():
    text = "f 1 2 3 4\n" + SQUARE
    assert parse_obj(text).faces.tolist() == [[0, 1, 2, 3]]


def test_triangle_is_rejected_naming_file_and_line(tmp_path):
    p = tmp_path / "tri.obj"
    p.write_text(SQUARE + "f 1 2 3 4\n# a comment\nf 1 2 3\n")
    with pytest.raises(InputError, match=r"tri\.obj, line 7: face with 3 corners"):
        load_obj(p)


def test_non_quads_drop():
    m = parse_obj(SQUARE + "f 1 2 3\nf 1 2 3 4\nf 1 2 3 4 4 4\n", non_quads="drop")
    assert m.faces.tolist() == [[0, 1, 2, 3]]


def test_non_quads_split_even_polygons_into_a_quad_fan():
    hexagon = "".join(f"v {float(np.cos(t))!r} {float(np.sin(t))!r} 0\n" for t in np.arange(6) * np.pi / 3)
    m = parse_obj(hexagon + "f 1 2 3 4 5 6\n", non_quads="split")
    assert m.faces.tolist() == [[0, 1, 2, 3], [0, 3, 4, 5]]
    octagon = "".join(f"v {float(np.cos(t))!r} {float(np.sin(t))!r} 0\n" for t in np.arange(8) * np.pi / 4)
    assert parse_obj(octagon + "f 1 2 3 4 5 6 7 8\n", non_quads="split").n_faces == 3
    with pytest.raises(InputError, match=r"line 6: face with 5 corners; an odd polygon"):
        parse_obj(SQUARE + "v 2 0 0\nf 1 5 2 3 4\n", non_quads="split")
    with pytest.raises(InputError, match="line 5: face with 3 corners"):
        parse_obj(SQUARE + "f 1 2 3\n", non_quads="split")


@pytest.mark.parametrize(
    "text, message",
    [
        (SQUARE + "f 1 2 3 0\n", r"line 5: vertex index 0"),
        (SQUARE + "f 1 2 3 9\n", r"line 5: vertex index 9 is out of range \(the file has 4 vertices\)"),
        (SQUARE + "f 1 2 3 -5\n", r"line 5: relative index -5"),
        (SQUARE + "f 1 2 3 x/1\n", r"line 5: bad vertex index 'x/1'"),
        (SQUARE + "f 1 2\n", r"line 5: a face needs at least 3 corners, got 2"),
        ("v 0 0\n" + SQUARE, r"line 1: a vertex needs 3 coordinates, got 2"),
        ("v 0 0 0\nv 1 zero 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n", r"line 2: bad vertex coordinates '1 zero 0'"),
        (SQUARE, r"no quad faces found \(4 vertices\)"),
        ("v 0 0 0\nv nan 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n", r"vertex 1 .*vertex 1 is on line 2"),
        (SQUARE + "v 2 0 0\nv 2 1 0\nf 1 2 3 4\nf 2 3 6 5\n",
         r"faces 0 and 1 .*face 0 is on line 7; face 1 is on line 8"),
    ],
)
def test_malformed_files_name_the_line(text, message):
    with pytest.raises(InputError, match=message) as info:
        parse_obj(text, name="bad.obj")
    assert str(info.value).startswith("bad.obj")


def test_option_and_file_errors(tmp_path):
    with pytest.raises(InputError, match="non_quads"):
        parse_obj(SQUARE + "f 1 2 3 4\n", non_quads="ignore")
    with pytest.raises(InputError, match="cannot read"):
        load_obj(tmp_path / "missing.obj")


def test_failed_write_keeps_old_file(tmp_path, monkeypatch):
    p = tmp_path / "m.obj"
    p.write_text("old")

    real_open = open

    class Truncating:
        """A file object that dies after the first chunk, like a full disk."""

        def __init__(self, *a, **k):
            self.f = real_open(*a, **k)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.f.close()

        def write(self, text):
            self.f.write(text[:10])
            raise OSError(28, "No space left on device")

    monkeypatch.setattr(_atomic, "open", Truncating, raising=False)
    with pytest.raises(ExportError, match="No space left"):
        save_obj(grid(3, 3), p)
    assert p.read_text() == "old"
    assert os.listdir(tmp_path) == ["m.obj"]


# --- the class of "a file that looks fine but is read wrong" (issue 12, item 3) -------------

QUAD2 = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 1 0\nf 1 2 3 4\nf 2 5 6 3\n"
EXPECTED_V = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0], [2, 1, 0]]


@pytest.mark.parametrize(
    "encoding, prefix",
    [("utf-8", b"\xef\xbb\xbf"), ("utf-16-le", b"\xff\xfe"), ("utf-16-be", b"\xfe\xff")],
)
def test_byte_order_mark_keeps_the_first_vertex(tmp_path, encoding, prefix):
    p = tmp_path / "bom.obj"
    p.write_bytes(prefix + QUAD2.encode(encoding))
    m = load_obj(p)
    assert m.vertices.tolist() == EXPECTED_V
    assert m.faces.tolist() == [[0, 1, 2, 3], [1, 4, 5, 2]]
    assert parse_obj("\ufeff" + QUAD2).vertices.tolist() == EXPECTED_V


@pytest.mark.parametrize("newline", ["\r\n", "\r", "\n"])
def test_line_ends_and_tabs(tmp_path, newline):
    p = tmp_path / "crlf.obj"
    p.write_bytes(QUAD2.replace(" ", "\t").replace("\n", newline).encode())
    m = load_obj(p)
    assert m.vertices.tolist() == EXPECTED_V and m.faces.tolist() == [[0, 1, 2, 3], [1, 4, 5, 2]]
    bad = QUAD2.replace("f 2 5 6 3", "f 2 5 6 9").replace("\n", newline)
    with pytest.raises(InputError, match="line 8: vertex index 9 is out of range"):
        parse_obj(bad)


def test_form_feed_does_not_shift_line_numbers():
    text = "v 0 0 0\x0c\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 7\n"
    with pytest.raises(InputError, match="line 5: vertex index 7"):
        parse_obj(text)


def test_vertex_weight_and_colour_are_not_coordinates():
    text = "v 0 0 0 1.0\nv 1 0 0 1.0\nv 1 1 0 0.2 0.3 0.4\nv 0 1 0 0.2 0.3 0.4\nf 1 2 3 4\n"
    assert parse_obj(text).vertices.tolist() == [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]


def test_texture_and_normal_indices_and_relative_indices():
    text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf 1/1/1 2/1/1 -2/1/1 -1//1\n"
    assert parse_obj(text).faces.tolist() == [[0, 1, 2, 3]]
    with pytest.raises(InputError, match=r"line 7: bad vertex index '/1/1'"):
        parse_obj(text.replace("f 1/1/1", "f /1/1"))
    with pytest.raises(InputError, match="line 7: relative index -5 points before the first vertex"):
        parse_obj(text.replace("-1//1", "-5//1"))


def test_unit_is_written_and_read_back(tmp_path):
    m = grid(3, 3, spacing=0.25).with_unit("m")
    text = obj_text(m)
    assert "# quadnodes unit m\n" in text
    assert parse_obj(text).unit == "m"
    assert parse_obj(obj_text(grid(2, 2))).unit == "mm"
    assert parse_obj(SQUARE + "f 1 2 3 4\n", unit="ft").unit == "ft"
    with pytest.raises(InputError, match="unit: 'mm' given, but <string>, line 2 says the file is in 'm'"):
        parse_obj(text, unit="mm")
    with pytest.raises(InputError, match="line 2: unit: expected one of"):
        parse_obj(text.replace("unit m", "unit parsec"))
    assert load_obj(save_obj(m, tmp_path / "m.obj")).unit == "m"


def test_meshio_reads_the_obj_quads_kept(tmp_path):
    import meshio

    m = grid(4, 5, height=np.random.default_rng(2).normal(size=(4, 5))).with_unit("cm")
    data = meshio.read(save_obj(m, tmp_path / "m.obj"))
    assert [c.type for c in data.cells] == ["quad"]
    assert np.array_equal(data.cells[0].data, m.faces)
    assert np.allclose(data.points, m.vertices, rtol=1e-15, atol=0)
