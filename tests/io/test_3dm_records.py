"""The fast .3dm engine: panel records written at once must be the records rhino3dm itself writes.

Checked two ways: byte for byte against rhino3dm's own records of the same panels (same object ids), and
object by object through rhino3dm's reader against files written with ``engine="rhino3dm"``.
"""

import struct
import uuid
import warnings

import numpy as np
import pytest
import rhino3dm
from hypothesis import given, settings
from hypothesis import strategies as st

from quadnodes.io import _3dm_records as rec
from quadnodes.io import rhino
from quadnodes.io.rhino import save_3dm
from quadnodes.mesh import QuadMesh, cylinder, grid
from quadnodes.topology import structure_lines

KEYS = ("id", "row", "col", "planarity", "planarity_mm", "area_mm2", "edges_mm", "planar")
FIXED = {False: {"planar": "no"}, True: {"planar": "yes"}}


def _records_of(file: bytes) -> list[bytes]:
    (table,) = [c for c in rec._chunks(file, 32, len(file)) if c[0] == rec._OBJECT_TABLE]
    return [file[c0:c1] for tc, c0, _, c1 in rec._chunks(file, table[2], table[3]) if tc == rec._OBJECT_RECORD]


def _without_copy_counts(records: bytes) -> bytes:
    """The records with every user-data header's copy count (and so its CRC) zeroed.

    openNURBS counts how often a piece of user data was copied (``ON_UserData::m_userdata_copycount``)
    and writes the count: rhino3dm's count grows with every panel added from the same attributes, the
    fast engine writes its template's. The value has no meaning in the file (any count above zero).
    """
    out = bytearray(records)
    tc = struct.pack("<I", 0x0002FFF9)  # TCODE_OPENNURBS_CLASS_USERDATA_HEADER
    at = out.find(tc)
    while at >= 0:
        n = struct.unpack_from("<Q", out, at + 4)[0]
        data = at + 12
        out[data + 32:data + 36] = b"\0" * 4  # after the class id and the user-data id
        out[data + n - 4:data + n] = b"\0" * 4
        at = out.find(tc, data + n)
    return bytes(out)


def _rhino3dm_records(version, keys, fixed, corners, names, columns, ids, flags):
    model = rhino._new_model()
    layers = rhino._add_layers(model)
    rhino._add_panel_objects(model, layers, keys, fixed, corners, names, columns,
                             [bytes(i) for i in ids], flags)
    return _records_of(rhino._file_bytes(model, version, "test")), layers


def _templates(version, keys, fixed, layers):
    def new_model():
        m = rhino._new_model()
        rhino._add_layers(m)
        return m

    def build(m, c, n, cols, ids, f):
        rhino._add_panel_objects(m, layers, keys, fixed, c, n, cols, ids, f)

    return rec.panel_records(build, new_model, lambda m: rhino._file_bytes(m, version, "test"), keys, fixed)


label = st.from_regex(r"P_[0-9]{1,4}(_[0-9]{1,4})?", fullmatch=True)  # what panel_labels makes
text = st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters="\0"), min_size=1, max_size=12)


@settings(max_examples=25, deadline=None)
@given(st.integers(1, 6), st.sampled_from([5, 6, 7, 8]), st.booleans(), st.integers(0, 2**31 - 1), st.data())
def test_records_are_byte_for_byte_rhino3dms(n, version, user_text, seed, data):
    rng = np.random.default_rng(seed)
    corners = rng.normal(scale=10.0 ** rng.uniform(-3, 5), size=(n, 4, 3))
    flags = rng.random(n) < 0.5
    names = data.draw(st.lists(label, min_size=n, max_size=n))
    keys = KEYS if user_text else ()
    fixed = FIXED if user_text else {False: {}, True: {}}
    columns = [data.draw(st.lists(text, min_size=n, max_size=n)) for _ in keys[:-1]]
    ids = rec.random_ids(n)
    want, layers = _rhino3dm_records(version, keys, fixed, corners, names, columns, ids, flags.tolist())
    got = _templates(version, keys, fixed, layers).records(flags, corners, names, columns, ids)
    assert _without_copy_counts(got) == _without_copy_counts(b"".join(want))


def _objects(path):
    model = rhino3dm.File3dm.Read(str(path))
    assert model is not None
    return model, list(model.Objects)


def _same_file_content(a, b):
    """Two .3dm files hold the same objects, in order, with the same geometry and attributes (but ids)."""
    ma, oa = _objects(a)
    mb, ob = _objects(b)
    assert str(ma.Settings.ModelUnitSystem) == str(mb.Settings.ModelUnitSystem)
    assert [layer.FullPath for layer in ma.Layers] == [layer.FullPath for layer in mb.Layers]
    assert len(oa) == len(ob)
    for x, y in zip(oa, ob):
        assert x.Geometry.Encode()["data"] == y.Geometry.Encode()["data"]
        assert x.Attributes.Name == y.Attributes.Name and x.Attributes.LayerIndex == y.Attributes.LayerIndex
        assert list(x.Attributes.GetUserStrings()) == list(y.Attributes.GetUserStrings())
    ids = [str(o.Attributes.Id) for o in oa]
    assert len(set(ids)) == len(ids) and str(uuid.UUID(int=0)) not in ids
    return oa


@settings(max_examples=10, deadline=None)
@given(st.integers(2, 7), st.integers(2, 7), st.floats(0.0, 30.0), st.booleans(), st.booleans(),
       st.sampled_from([5, 6, 7, 8]), st.sampled_from(["mm", "m", "in"]), st.integers(0, 2**31 - 1))
def test_fast_and_rhino3dm_engines_write_the_same_content(tmp_path_factory, r, c, amp, on_grid, user_text,
                                                          version, unit, seed):
    h = np.random.default_rng(seed).normal(scale=amp, size=(r, c))
    g = grid(r, c, spacing=250.0, height=h)
    m = QuadMesh(g.vertices, g.faces, unit=unit, grid_shape=g.grid_shape if on_grid else None)
    folder = tmp_path_factory.mktemp("e")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the fast engine must not fall back
        a = save_3dm(m, folder / "fast.3dm", planar_tolerance=1e-3, user_text=user_text, version=version)
    b = save_3dm(m, folder / "slow.3dm", planar_tolerance=1e-3, user_text=user_text, version=version,
                 engine="rhino3dm")
    objects = _same_file_content(a, b)
    assert rhino3dm.File3dm.ReadArchiveVersion(str(a)) == 10 * version
    assert len(objects) == 1 + m.n_faces + len(structure_lines(m))
    assert [type(o.Geometry).__name__ for o in objects[1:1 + m.n_faces]] == ["NurbsSurface"] * m.n_faces


def test_a_closed_mesh_and_the_structure_lines(tmp_path):
    cyl = cylinder(3, 7, radius=900.0, height=1500.0)
    a = save_3dm(cyl, tmp_path / "a.3dm")
    b = save_3dm(cyl, tmp_path / "b.3dm", engine="rhino3dm")
    objects = _same_file_content(a, b)
    kinds = [type(o.Geometry).__name__ for o in objects]
    assert kinds[0] == "Mesh" and kinds.count("NurbsSurface") == cyl.n_faces
    assert kinds[1:1 + cyl.n_faces] == ["NurbsSurface"] * cyl.n_faces  # the panels right after the mesh


def test_a_layout_it_does_not_recognise_falls_back_with_a_warning(tmp_path, monkeypatch):
    def refuse(*args, **kwargs):
        raise rec.LayoutError("test: an unknown record layout")

    monkeypatch.setattr(rhino, "panel_records", refuse)
    m = grid(3, 4, spacing=100.0)
    with pytest.warns(RuntimeWarning, match="unknown record layout.*writing through rhino3dm"):
        p = save_3dm(m, tmp_path / "w.3dm")
    _, objects = _objects(p)
    assert sum(type(o.Geometry).__name__ == "NurbsSurface" for o in objects) == m.n_faces


def test_splice_refuses_what_is_not_a_3dm_file():
    with pytest.raises(rec.LayoutError):
        rec.splice_records(b"3D Geometry File Format       80" + b"\x01" * 40, b"", after=1)
    model = rhino._new_model()
    data = rhino._file_bytes(model, 8, "test")
    with pytest.raises(rec.LayoutError, match="fewer than 1 records"):
        rec.splice_records(data, b"", after=1)


def test_random_ids_are_version_4_uuids():
    ids = rec.random_ids(1000)
    u = [uuid.UUID(bytes_le=bytes(row)) for row in ids]
    assert len(set(u)) == 1000 and {x.version for x in u} == {4} and {x.variant for x in u} == {uuid.RFC_4122}
