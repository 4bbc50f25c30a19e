"""build123d faces in the disk cache (BREP text), and outputs decoded only when used."""

from __future__ import annotations

import json
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from quadnodes.graph import Cache, CacheEntry
from quadnodes.graph.cache import _LazyOutputs

pytest.importorskip("build123d")

ROOT = Path(__file__).resolve().parents[2]


def test_a_face_survives_the_disk_cache_exactly(tmp_path):
    from quadnodes import surfaces

    face = surfaces.wavy(4000.0, 8000.0, 500.0, waves_u=0.5, waves_v=1.5)
    assert Cache(tmp_path).put("f" * 64, CacheEntry({"face": face, "n": 3}))
    back = Cache(tmp_path).get("f" * 64).outputs["face"]
    assert type(back).__name__ == "Face" and back is not face
    a, b = surfaces.sample(face, 12, 9), surfaces.sample(back, 12, 9)
    assert np.array_equal(a.vertices, b.vertices)
    assert abs(back.area - face.area) < 1e-9 * face.area
    # the entry holds BREP text and names no class to import for it
    entry = np.load(tmp_path / "ff" / f"{'f' * 64}.npz", allow_pickle=False)
    meta = json.loads(entry["__meta__"].tobytes().decode())
    assert "$brep" in json.dumps(meta) and "build123d" not in json.dumps(meta)
    assert b"CASCADE Topology" in entry["a0"].tobytes()[:80]


def test_a_corrupt_brep_is_a_cache_miss(tmp_path):
    from quadnodes import surfaces
    from quadnodes.graph import CacheWarning

    Cache(tmp_path).put("e" * 64, CacheEntry({"face": surfaces.saddle(10.0, 10.0, 1.0)}))
    path = tmp_path / "ee" / f"{'e' * 64}.npz"
    z = dict(np.load(path, allow_pickle=False))
    z["a0"] = z["a0"][:-40]  # a truncated shape
    np.savez(path, **z)
    with pytest.warns(CacheWarning, match="BREP text does not match its checksum"):
        assert Cache(tmp_path).get("e" * 64) is None


def test_outputs_read_from_disk_are_decoded_on_first_use(tmp_path):
    from quadnodes.mesh import grid

    Cache(tmp_path).put("m" * 64, CacheEntry({"mesh": grid(3, 4), "n": 12}))
    out = Cache(tmp_path).get("m" * 64).outputs
    assert isinstance(out, _LazyOutputs) and set(out._values) == {"mesh", "n"}  # no shape: decoded at once
    assert out["mesh"].grid_shape == (3, 4) and dict(out)["n"] == 12 and len(out) == 2


def test_a_shape_is_decoded_on_first_use(tmp_path):
    from quadnodes import surfaces

    Cache(tmp_path).put("s" * 64, CacheEntry({"face": surfaces.saddle(10.0, 10.0, 1.0), "n": 1}))
    out = Cache(tmp_path).get("s" * 64).outputs
    assert list(out._values) == ["n"]
    assert type(out["face"]).__name__ == "Face" and set(out._values) == {"face", "n"}


def test_an_unchanged_surface_is_not_rebuilt_across_processes(tmp_path):
    """Two `quadnodes run` processes: the second reuses the face and does not even import build123d."""
    g = tmp_path / "g.toml"
    g.write_text('format = "quadnodes-graph"\nversion = 1\n[nodes.surface]\nop = "saddle@1"\n'
                 '[nodes.mesh]\nop = "sample@1"\ninputs = { face = "surface.face" }\nparams = { nu = 5, nv = 6 }\n'
                 '[nodes.obj]\nop = "export_obj@1"\ninputs = { mesh = "mesh.mesh" }\nparams = { path = "m.obj" }\n')
    env = {"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"}
    code = ("import sys; from quadnodes.cli import main; rc = main(sys.argv[1:]); "
            "print('build123d imported' if 'build123d' in sys.modules else 'build123d not imported'); sys.exit(rc)")
    args = [sys.executable, "-c", code, "run", str(g), "--out", str(tmp_path / "out")]
    first = subprocess.run(args, capture_output=True, text=True, env=env, cwd=tmp_path, timeout=600)
    assert first.returncode == 0, first.stderr
    assert "3 ran, 0 from cache" in first.stdout
    # without the note of the last run (see runlog), the runner reads every entry: the face stays undecoded
    for note in (tmp_path / "out" / ".cache" / "runs").glob("*.json"):
        note.unlink()
    second = subprocess.run(args, capture_output=True, text=True, env=env, cwd=tmp_path, timeout=600)
    assert "0 ran, 3 from cache" in second.stdout, second.stdout
    assert "build123d not imported" in second.stdout
    # a downstream change reuses the cached face: the surface node does not run
    third = subprocess.run([*args, "--set", "mesh.nu=7"], capture_output=True, text=True, env=env, cwd=tmp_path,
                           timeout=600)
    assert "2 ran, 1 from cache" in third.stdout, third.stdout

