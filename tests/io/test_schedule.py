import csv
import io
import os

import numpy as np
import pytest
from hypothesis import given

from quadnodes.errors import InputError
from quadnodes.io.panels import planar_mask
from quadnodes.io.schedule import SCHEDULE_COLUMNS, panel_schedule, save_schedule, schedule_csv
from quadnodes.io.step import step_shape
from quadnodes.mesh import QuadMesh, grid
from quadnodes.flatness import angle_defect, diagonal_distance
from strategies import grids


def rows(text):
    return list(csv.DictReader(io.StringIO(text)))


def test_columns_and_values_of_a_grid(tmp_path):
    m = grid(3, 4, spacing=(2.0, 3.0), height=np.arange(12.0).reshape(3, 4) ** 1.5 / 10)
    p = save_schedule(m, tmp_path / "s.csv")
    assert p == tmp_path / "s.csv" and os.listdir(tmp_path) == ["s.csv"]
    table = rows(p.read_text())
    assert tuple(table[0]) == SCHEDULE_COLUMNS
    assert len(table) == m.n_faces
    corners = m.vertices[m.faces]
    for k, r in enumerate(table):
        i, j = divmod(int(m.faces[k, 0]), 4)
        assert (r["panel"], int(r["face"]), int(r["row"]), int(r["col"])) == (f"P_{i}_{j}", k, i, j)
        got = np.array([[float(r[f"{a}{c}"]) for a in "xyz"] for c in range(4)])
        assert np.array_equal(got, corners[k])  # exact floats
        edges = [float(r[e]) for e in ("edge01", "edge12", "edge23", "edge30")]
        np.testing.assert_allclose(edges, np.linalg.norm(np.roll(corners[k], -1, 0) - corners[k], axis=1))
    assert [float(r["diagonal_distance"]) for r in table] == diagonal_distance(m).tolist()
    assert [float(r["diagonal_gap"]) for r in table] == diagonal_distance(m, relative=False).tolist()
    assert [float(r["angle_defect"]) for r in table] == angle_defect(m).tolist()


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
    assert panel_schedule(m)["area"][0] == pytest.approx(shoelace, rel=1e-13)


def test_bilinear_area_matches_occt():
    m = QuadMesh([[0, 0, 0], [1, 0, 0.2], [1.3, 1.1, 1.0], [0, 1, 0.1]], [[0, 1, 2, 3]])
    occt = step_shape(m).faces()[0].area
    assert panel_schedule(m)["area"][0] == pytest.approx(occt, rel=1e-9)


@given(grids())
def test_kind_matches_the_step_planarity_test(m):
    kinds = panel_schedule(m, planar_tol=1e-3)["kind"]
    assert kinds == np.where(planar_mask(m, planar_tol=1e-3), "planar", "bilinear").tolist()


def test_kind_matches_the_faces_in_the_step_shape():
    z = np.zeros((3, 3))
    z[2, 2] = 0.5
    m = grid(3, 3, height=z)
    kinds = panel_schedule(m)["kind"]
    assert kinds == ["planar", "planar", "planar", "bilinear"]
    faces = step_shape(m, mode="assembly").children
    assert [f.geom_type.name for f in faces] == ["PLANE", "PLANE", "PLANE", "BEZIER"]


def test_bad_tolerance():
    with pytest.raises(InputError, match="planar_tol"):
        schedule_csv(grid(2, 2), planar_tol=float("nan"))
