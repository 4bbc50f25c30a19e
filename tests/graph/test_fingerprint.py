"""Fingerprints of values and code."""

from __future__ import annotations

import dataclasses
import enum
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from hypothesis import given
from hypothesis import strategies as st

from quadnodes.fairing import fair
from quadnodes.graph import code_fingerprint, file_digest, fingerprint
from quadnodes.mesh import QuadMesh, grid
from strategies import meshes


@given(meshes(), st.data())
def test_quadmesh_fingerprint_stable_across_copies_and_sensitive_to_every_coordinate(mesh, data):
    copy = QuadMesh(mesh.vertices.copy(), mesh.faces.copy(), mesh.grid_shape)
    assert fingerprint(copy) == fingerprint(mesh) is not None
    i = data.draw(st.integers(0, mesh.n_vertices - 1))
    c = data.draw(st.integers(0, 2))
    delta = data.draw(st.floats(1e-9, 1.0) | st.floats(-1.0, -1e-9))
    v = mesh.vertices.copy()
    v[i, c] += delta
    if v[i, c] == mesh.vertices[i, c]:
        v[i, c] = np.nextafter(v[i, c], np.inf)
    moved = QuadMesh(v, mesh.faces, mesh.grid_shape)
    assert fingerprint(moved) != fingerprint(mesh)


def test_mesh_parts_all_count():
    m = grid(3, 4)
    assert fingerprint(m) != fingerprint(QuadMesh(m.vertices, m.faces))  # grid_shape
    flipped = QuadMesh(m.vertices, m.faces[:, [1, 2, 3, 0]], m.grid_shape)  # same quads, other start
    assert fingerprint(flipped) != fingerprint(m)


def test_arrays_by_dtype_shape_and_bytes():
    a = np.arange(6, dtype=np.float64)
    assert fingerprint(a) == fingerprint(a.copy())
    assert fingerprint(a) != fingerprint(a.astype(np.float32))
    assert fingerprint(a) != fingerprint(a.reshape(2, 3))
    assert fingerprint(a.reshape(2, 3).T) == fingerprint(np.ascontiguousarray(a.reshape(2, 3).T))
    assert fingerprint(np.array([None])) is None


def test_primitives_and_containers():
    assert fingerprint(1) != fingerprint(1.0) != fingerprint(True)
    assert fingerprint(0.1 + 0.2) != fingerprint(0.3)
    assert fingerprint([1, 2]) != fingerprint((1, 2))
    assert fingerprint({"a": 1, "b": [2]}) == fingerprint({"b": [2], "a": 1})
    assert fingerprint({1, 2}) == fingerprint({2, 1})
    assert fingerprint(Path("a/b")) != fingerprint("a/b")
    assert fingerprint("x") != fingerprint(b"x")
    assert fingerprint(None) != fingerprint(0)
    assert fingerprint(np.float64(1.0)) != fingerprint(np.float32(1.0))


def test_unfingerprintable_gives_none_never_a_guess():
    assert fingerprint(object()) is None
    assert fingerprint([1, {"x": object()}]) is None
    assert fingerprint(lambda: 0) is None
    loop: list = []
    loop.append(loop)
    assert fingerprint(loop) is None


class Color(enum.Enum):
    RED = 1


@dataclasses.dataclass(frozen=True)
class Pair:
    a: object
    b: object


def test_dataclasses_enums_reports_sparse_and_opt_in():
    _, rep = fair(grid(4, 4, height=np.eye(4)), iterations=2, threshold=0.01)
    _, rep2 = fair(grid(4, 4, height=np.eye(4)), iterations=2, threshold=0.01)
    assert fingerprint(rep) == fingerprint(rep2) is not None
    assert fingerprint(Pair(1, 2)) != fingerprint(Pair(2, 1))
    assert fingerprint(Pair(1, object())) is None
    assert fingerprint(Color.RED) is not None
    m = sp.random(5, 5, density=0.4, random_state=0, format="csr")
    assert fingerprint(m) == fingerprint(m.tocsc()) is not None

    class Shape:
        def __quadnodes_fingerprint__(self) -> str:
            return "brep-digest"

    assert fingerprint(Shape()) == fingerprint(Shape()) is not None


def test_code_fingerprint_depends_on_source():
    def f(x):
        return x + 1

    def g(x):
        return x + 2

    assert code_fingerprint(f) != code_fingerprint(g)
    assert code_fingerprint(f) == code_fingerprint(f)
    assert code_fingerprint(len) is None


def test_file_digest_of_files_and_folders(tmp_path):
    assert file_digest(tmp_path / "none") is None
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "a.txt").write_text("1")
    before = file_digest(tmp_path / "d")
    (tmp_path / "d" / "a.txt").write_text("2")
    assert file_digest(tmp_path / "d") != before
