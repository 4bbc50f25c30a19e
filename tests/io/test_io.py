"""The format table and the save/load dispatch of quadnodes.io."""

import os

import numpy as np
import pytest

from build123d import import_step

from quadnodes.errors import ExportError, InputError
from quadnodes.io import EXPORTERS, LOADERS, load, save
from quadnodes.mesh import grid


@pytest.fixture
def mesh():
    return grid(3, 4, height=np.random.default_rng(0).normal(size=(3, 4)))


@pytest.mark.parametrize("ext", sorted(set(LOADERS) & set(EXPORTERS)))
def test_round_trip_by_extension(tmp_path, mesh, ext):
    p = save(mesh, tmp_path / f"m.{ext}")
    assert p == tmp_path / f"m.{ext}"
    back = load(p)
    assert np.array_equal(back.vertices, mesh.vertices)
    assert np.array_equal(back.faces, mesh.faces)
    assert back.grid_shape == mesh.grid_shape


def test_every_exporter_writes_only_its_file(tmp_path, mesh):
    for ext in EXPORTERS:
        save(mesh, tmp_path / f"m.{ext.upper()}")
    assert sorted(os.listdir(tmp_path)) == sorted(f"m.{e.upper()}" for e in EXPORTERS)
    assert len(import_step(tmp_path / "m.STP").faces()) == mesh.n_faces
    assert (tmp_path / "m.CSV").read_text().count("\n") == mesh.n_faces + 1


def test_options_reach_the_writer_and_reader(tmp_path, mesh):
    p = save(mesh, tmp_path / "panels.dat", file_type="step", mode="assembly")
    assert [c.label for c in import_step(p).children][:2] == ["P_0_0", "P_0_1"]
    (tmp_path / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 4 3\nf 1 2 3\n")
    assert load(tmp_path / "tri.obj", non_quads="drop").n_faces == 1


def test_dispatch_errors(tmp_path, mesh):
    with pytest.raises(InputError, match="cannot write 'ply'"):
        save(mesh, tmp_path / "m.ply")
    with pytest.raises(InputError, match="no extension"):
        save(mesh, tmp_path / "m")
    with pytest.raises(InputError, match="cannot read 'step'"):
        load(tmp_path / "m.step")
    with pytest.raises(InputError, match="obj writer: .*unexpected keyword argument 'mode'"):
        save(mesh, tmp_path / "m.obj", mode="shell")
    with pytest.raises(InputError, match="json reader: .*unexpected keyword argument"):
        load(tmp_path / "m.json", non_quads="drop")
    with pytest.raises(ExportError):
        save(mesh, tmp_path / "missing" / "m.obj")
    assert os.listdir(tmp_path) == []
