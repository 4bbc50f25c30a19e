import csv
import io
import os

import numpy as np
import pytest
from hypothesis import given

from quadnodes.errors import InputError
from quadnodes.flatness import planar_panels
from quadnodes.io.schedule import SCHEDULE_COLUMNS, panel_schedule, save_schedule, schedule_csv
from quadnodes.io.step import step_panels, step_shape
from quadnodes.mesh import QuadMesh, grid
from quadnodes.flatness import angle_defect, diagonal_distance
from strategies import grids


def rows(text):
    return list(csv.DictReader(io.StringIO(text)))


def test_columns_and_values_of_a_grid(tmp_path):
    m = grid(3, 4, spacing=(2.0, 3.0), height=np.arange(12.0).reshape(3, 4) ** 1.5 / 10)
    p = save_schedule(m, tmp_path / "s.csv", precision="full")
    assert p == tmp_path / "s.csv" and os.listdir(tmp_path) == ["s.csv"]
    table = rows(p.read_text())
    assert tuple(table[0]) == SCHEDULE_COLUMNS
    assert len(table) == m.n_faces
    corners = m.vertices[m.faces]
    for k, r in enumerate(table):
        i, j = divmod(int(m.faces[k, 0]), 4)
        assert (r["panel"], int(r["face"]), int(r["row"]), int(r["col"])) == (f"P_{i}_{j}", k, i, j)
        got = np.array([[float(r[f"{a}{c}_mm"]) for a in "xyz"] for c in range(4)])
        assert np.array_equal(got, corners[k])  # exact floats
        edges = [float(r[f"edge_{e}_mm"]) for e in ("01", "12", "23", "30")]
        np.testing.assert_allclose(edges, np.linalg.norm(np.roll(corners[k], -1, 0) - corners[k], axis=1))
    assert [float(r["planarity_rel"]) for r in table] == diagonal_distance(m).tolist()
    assert [float(r["planarity_mm"]) for r in table] == diagonal_distance(m, relative=False).tolist()
    assert [float(r["angle_defect_rad"]) for r in table] == angle_defect(m).tolist()


def test_rounded_numbers_resolve_a_micrometre_in_every_unit():
    m = grid(3, 3, spacing=1234.56789, height=[[0, 0, 0], [0, 0.3, 0], [0, 0, 0.1]])
    full = rows(schedule_csv(m, precision="full"))
    rounded = rows(schedule_csv(m))
    assert rounded[0]["x1_mm"] == "1234.568"
    assert rounded[0]["planarity_rel"] == f"{float(full[0]['planarity_rel']):.4g}"  # four significant digits
    for a, b in zip(full, rounded):
        for key in a:
            if key.endswith("_mm"):
                assert abs(float(a[key]) - float(b[key])) <= 0.0005 + 1e-12
            if key.endswith("_rel"):
                assert float(b[key]) == pytest.approx(float(a[key]), rel=1e-3)
    metres = rows(schedule_csv(m.with_unit("m")))
    assert "x1_m" in metres[0] and "area_m2" in metres[0] and "x1_mm" not in metres[0]
    assert metres[0]["x1_m"] == "1.234568"
    assert [r["kind"] for r in metres] == [r["kind"] for r in rounded]
    with pytest.raises(InputError, match="precision"):
        schedule_csv(m, precision="exact")


def test_corner_move_is_the_step_files():
    m = grid(3, 3, spacing=1000.0, height=[[0, 0, 0], [0, 0.8, 0], [0, 0, 0]])
    sched = panel_schedule(m, planar_tolerance="2 mm")
    _, report = step_panels(m, planar_tolerance="2 mm")
    assert sched["kind"] == ["planar"] * 4
    assert max(sched["corner_move_mm"]) == pytest.approx(report.max_corner_move, rel=1e-12)
    assert max(sched["corner_move_mm"]) <= 1.0  # at most half the tolerance
    assert panel_schedule(m, planar_tolerance=0.0)["corner_move_mm"] == [0.0] * 4


def test_extra_columns_are_the_extension_point():
    m = grid(2, 3, spacing=1000.0)
    text = schedule_csv(m, extra={"distortion_mm": [0.00012, 0.5]})
    table = rows(text)
    assert list(table[0])[-1] == "distortion_mm"
    assert [r["distortion_mm"] for r in table] == ["0.000", "0.500"]
    with pytest.raises(InputError, match="one value per panel"):
        schedule_csv(m, extra={"distortion_mm": [1.0]})
    with pytest.raises(InputError, match="standard column"):
        schedule_csv(m, extra={"kind": [1.0, 2.0]})


def test_degenerate_panel_is_listed_as_degenerate_without_nan():
    v = np.array([[0., 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0], [0, 1, 0], [1, 1, 0]])
    m = QuadMesh(v, [[0, 1, 5, 4], [1, 2, 3, 5]])  # face 1: 1-2-3 collinear, but 5 off the line
    # all four corners on one line (QuadMesh() refuses that; processing can make it)
    m2 = QuadMesh(np.array([[0., 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]), [[0, 1, 2, 3]]).with_vertices(
        np.array([[0., 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]]))
    for mesh in (m, m2):
        text = schedule_csv(mesh)
        assert "nan" not in text.lower() and "inf" not in text.lower()
    assert rows(schedule_csv(m2))[0]["kind"] == "degenerate"
    assert rows(schedule_csv(m2))[0]["planarity_rel"] == ""


def test_no_grid_leaves_row_and_col_empty():
    m = grid(2, 3)
    table = rows(schedule_csv(QuadMesh(m.vertices, m.faces)))
    assert [(r["panel"], r["row"], r["col"]) for r in table] == [("P_0", "", ""), ("P_1", "", "")]


def test_planar_area_is_the_polygon_area():
    # a planar convex quad in a tilted plane: area by the shoelace formula in-plane
    uv = np.array([[0, 0], [4, 0.5], [3.5, 3], [0.5, 2.0]])
    e1, e2 = np.array([1.0, 0, 1]) / np.sqrt(2), np.array([0.0, 1, 0])
    m = QuadMesh(uv[:, :1] * e1 + uv[:, 1:] * e2 + [1, 2, 3], [[0, 1, 2, 3]])
    x, y = uv.T
    shoelace = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
    assert panel_schedule(m)["area_mm2"][0] == pytest.approx(shoelace, rel=1e-13)


def test_bilinear_area_matches_occt():
    m = QuadMesh([[0, 0, 0], [1, 0, 0.2], [1.3, 1.1, 1.0], [0, 1, 0.1]], [[0, 1, 2, 3]])
    occt = step_shape(m).faces()[0].area
    assert panel_schedule(m)["area_mm2"][0] == pytest.approx(occt, rel=1e-9)


@given(grids())
def test_kind_matches_the_step_planarity_test(m):
    for tol in (1e-3, "0.5 mm"):
        kinds = panel_schedule(m, planar_tolerance=tol)["kind"]
        assert kinds == np.where(planar_panels(m, tol), "planar", "bilinear").tolist()


def test_kind_matches_the_faces_in_the_step_shape():
    z = np.zeros((3, 3))
    z[2, 2] = 0.5
    m = grid(3, 3, height=z)
    kinds = panel_schedule(m)["kind"]
    assert kinds == ["planar", "planar", "planar", "bilinear"]
    faces = step_shape(m, mode="assembly").children
    assert [f.geom_type.name for f in faces] == ["PLANE", "PLANE", "PLANE", "BEZIER"]


def test_bad_tolerance():
    with pytest.raises(InputError, match="planar_tolerance"):
        schedule_csv(grid(2, 2), planar_tolerance=float("nan"))
    with pytest.raises(InputError, match="'planar_tol' was renamed; use 'planar_tolerance'"):
        save_schedule(grid(2, 2), "never.csv", planar_tol=1e-3)
    assert not os.path.exists("never.csv")
