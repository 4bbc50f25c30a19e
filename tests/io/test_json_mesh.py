import json
import os

import numpy as np
import pytest
from hypothesis import given

from quadnodes.errors import InputError
from quadnodes.io.json_mesh import JSON_FORMAT, JSON_VERSION, load_json, mesh_from_json, mesh_to_json, save_json
from quadnodes.mesh import grid, torus
from strategies import grids, irregular


def assert_same(a, b):
    assert np.array_equal(a.vertices, b.vertices)  # bit for bit
    assert np.array_equal(a.faces, b.faces)
    assert a.grid_shape == b.grid_shape


@given(grids(amplitude=1e3))
def test_round_trip_of_random_height_grids_is_exact(m):
    m = m.with_vertices(m.vertices * np.e + 1e-9)  # full mantissas
    assert_same(mesh_from_json(mesh_to_json(m)), m)


@given(irregular())
def test_round_trip_of_irregular_meshes_is_exact(m):
    assert_same(mesh_from_json(mesh_to_json(m)), m)


def test_extreme_floats_round_trip():
    m = grid(2, 2, spacing=1e-300, height=[[5e-324, -0.0], [1e300, -1.7976931348623157e308]])
    assert_same(mesh_from_json(mesh_to_json(m)), m)


def test_document_is_plain_json_with_version_and_grid_shape(tmp_path):
    m = torus(4, 5)
    p = save_json(m, tmp_path / "t.json")
    assert p == tmp_path / "t.json" and os.listdir(tmp_path) == ["t.json"]
    doc = json.loads(p.read_text())
    assert list(doc) == ["format", "version", "grid_shape", "unit", "vertices", "faces"]
    assert doc["format"] == JSON_FORMAT and doc["version"] == JSON_VERSION
    assert doc["grid_shape"] is None
    assert_same(load_json(p), m)
    assert json.loads(mesh_to_json(grid(2, 3)))["grid_shape"] == [2, 3]


def doc_text(**changes):
    doc = json.loads(mesh_to_json(grid(2, 2)))
    doc.update(changes)
    return json.dumps(doc)


@pytest.mark.parametrize(
    "text, message",
    [
        ('{"format": "quadnodes.QuadMesh",\n  "version": 1,\n  oops}', r"m\.json, line 3 column 3: invalid JSON"),
        ("[1, 2]", r"not a quadnodes mesh .*got 'list'"),
        (doc_text(format="other"), r"not a quadnodes mesh .*got 'other'"),
        (doc_text(version=JSON_VERSION + 1), r"newer than this reader"),
        (doc_text(version="1"), r'"version" must be a positive integer'),
        (doc_text(vertices=None), r'"vertices" must be a list'),
        (doc_text(grid_shape=[2]), r'"grid_shape" must be null or \[rows, cols\]'),
        (doc_text(grid_shape=[3, 3]), r"grid_shape: \(3, 3\) holds 9 vertices"),
        (doc_text(faces=[[0, 1, 3, 7]]), r"face 0 refers to vertex 7"),
        (doc_text(faces=[[0, 1, 3]]), r"expected shape \(m, 4\)"),
    ],
)
def test_malformed_documents_are_input_errors(text, message):
    with pytest.raises(InputError, match=message) as info:
        mesh_from_json(text, name="m.json")
    assert str(info.value).startswith("m.json")


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="cannot read"):
        load_json(tmp_path / "nope.json")
