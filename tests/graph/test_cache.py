"""The disk cache reads entries without running code named in them."""

from __future__ import annotations

import io
import json
import sys

import numpy as np
import pytest

from quadnodes.graph.cache import Cache, CacheEntry, CacheWarning, _allowed, decode, encode
from quadnodes.mesh import grid


def _craft(cache: Cache, key: str, outputs_tree: dict) -> None:
    meta = {"format": "quadnodes-cache", "version": 1, "key": key, "outputs": outputs_tree, "files": {}}
    buf = io.BytesIO()
    np.savez(buf, __meta__=np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8))
    path = cache._path(key)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(buf.getvalue())


@pytest.mark.parametrize("tag", ["$dataclass", "$enum", "$path"])
def test_an_entry_naming_a_foreign_module_never_imports_it(tmp_path, monkeypatch, tag):
    marker = tmp_path / "imported.marker"
    (tmp_path / "qn_evil_mod.py").write_text(
        f"open({str(marker)!r}, 'w').write('ran')\n"
        "import dataclasses\n@dataclasses.dataclass\nclass Payload:\n    x: int = 0\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    sys.modules.pop("qn_evil_mod", None)
    key = "e" * 64
    cache = Cache(tmp_path / "cache")
    body = {"$dataclass": "qn_evil_mod:Payload", "fields": []} if tag == "$dataclass" else (
        {"$enum": "qn_evil_mod:Payload", "value": 1} if tag == "$enum" else {"$path": "/x", "cls": "qn_evil_mod:Payload"})
    _craft(cache, key, {"$dict": [["out", body]]})
    with pytest.warns(CacheWarning, match="qn_evil_mod:Payload"):
        assert Cache(tmp_path / "cache").get(key) is None       # a miss, with a warning naming the class
    assert not marker.exists() and "qn_evil_mod" not in sys.modules


@pytest.mark.parametrize("name", ["os:system", "subprocess:Popen", "quadnodes_x:Y", "builtins:eval",
                                  "quadnodes.mesh:QuadMesh.__init__.__globals__", "pathlib:Path.home", ""])
def test_names_outside_the_allow_list_are_refused_without_import(name):
    assert not _allowed(name)
    with pytest.raises(ValueError):
        decode({"$dataclass": name, "fields": []}, [])


def test_quadnodes_classes_and_paths_still_round_trip(tmp_path):
    import pathlib

    arrays: list[np.ndarray] = []
    tree = encode({"m": grid(2, 3), "p": pathlib.PurePosixPath("a/b")}, arrays)
    back = decode(json.loads(json.dumps(tree)), arrays)
    assert back["m"].grid_shape == (2, 3) and back["p"] == pathlib.PurePosixPath("a/b")


def test_values_of_classes_outside_the_allow_list_stay_in_memory(tmp_path):
    import dataclasses

    @dataclasses.dataclass
    class Local:
        x: int = 1

    c = Cache(tmp_path / "c")
    assert c.put("a" * 64, CacheEntry({"v": Local()})) is False   # not written to disk: could not be read back
    assert c.get("a" * 64).outputs["v"] == Local()
    assert not list((tmp_path / "c").rglob("*.npz"))
