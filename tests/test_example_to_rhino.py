"""examples/to_rhino.toml end to end: STEP, .3dm, DXF and the schedule agree on the planar panels,
each output read back by an independent reader (gmsh, rhino3dm, ezdxf, the csv module)."""

import csv
import json
import subprocess
import sys
from collections import Counter
from pathlib import Path

import ezdxf
import numpy as np
import pytest
import rhino3dm

import quadnodes.nodes  # noqa: F401
from quadnodes.cli import main

EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "to_rhino.toml"

_GMSH = r"""
import json, sys
import gmsh
gmsh.initialize(interruptible=False)
gmsh.option.setNumber("General.Terminal", 0)
gmsh.open(sys.argv[1])
print(json.dumps({"types": [gmsh.model.getType(2, t) for _, t in gmsh.model.getEntities(2)],
                  "curves": len(gmsh.model.getEntities(1))}))
gmsh.finalize()
"""


def step_faces(path):
    pytest.importorskip("gmsh")
    out = subprocess.run([sys.executable, "-c", _GMSH, str(path)], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def outputs(folder):
    """Per output: which panels (by label) are planar."""
    rows = list(csv.DictReader((folder / "panels.csv").open()))
    schedule = {r["panel"]: r["kind"] == "planar" for r in rows}
    model = rhino3dm.File3dm.Read(str(folder / "panels.3dm"))
    layers = {layer.Index: layer.FullPath for layer in model.Layers}
    rhino = {
        o.Attributes.Name: layers[o.Attributes.LayerIndex] == "panels::planar"
        for o in model.Objects
        if isinstance(o.Geometry, rhino3dm.NurbsSurface)
    }
    flags = {o.Attributes.Name: o.Attributes.GetUserString("planar") == "yes" for o in model.Objects
             if isinstance(o.Geometry, rhino3dm.NurbsSurface)}
    msp = ezdxf.readfile(folder / "unrolls.dxf").modelspace()
    colors = [e.dxf.color for e in msp.query("LWPOLYLINE[layer=='PANELS']")]
    labels = [e.dxf.text for e in msp.query("TEXT[layer=='LABELS']")]
    dxf = {label: color == 3 for label, color in zip(labels, colors, strict=True)}
    return schedule, rhino, flags, dxf, model


def check_agreement(folder, n_panels):
    schedule, rhino, flags, dxf, model = outputs(folder)
    assert len(schedule) == len(rhino) == len(dxf) == n_panels
    assert schedule == rhino == flags == dxf
    step = step_faces(folder / "panels.step")
    kinds = Counter(step["types"])
    assert len(step["types"]) == n_panels
    assert kinds["Plane"] == sum(schedule.values())
    # one sewn shell: a 13 x 13 grid of panels has 2 * 13 * 14 edges, each shared by its two panels
    assert step["curves"] == 2 * 13 * 14
    assert str(model.Settings.ModelUnitSystem) == "UnitSystem.Millimeters"
    return sum(schedule.values())


def test_to_rhino_end_to_end(tmp_path):
    out, cache = tmp_path / "out", tmp_path / "cache"
    assert main(["run", str(EXAMPLE), "--out", str(out), "--cache", str(cache)]) == 0
    n_planar = check_agreement(out, 169)
    assert n_planar == 169  # planarized to the graph's 2 mm, every output calls every panel planar at 2 mm
    report = json.loads((out / "report.json").read_text())
    assert report["unrolls"]["n_planar"] == 169 and report["unrolls"]["max_distortion"] < 1.0
    assert len(report["unrolls"]["distortion"]) == 169

    # a tighter tolerance splits the panels; the four outputs still agree panel by panel
    tight = [a for node in ("step", "csv", "rhino", "dxf") for a in ("--set", f'{node}.planar_tolerance="0.2 mm"')]
    tighter = tmp_path / "tight"
    assert main(["run", str(EXAMPLE), "--out", str(tighter), "--cache", str(cache), *tight]) == 0
    n_planar = check_agreement(tighter, 169)
    assert 0 < n_planar < 169
    report = json.loads((tighter / "report.json").read_text())
    distortion = np.array(report["unrolls"]["distortion"])
    assert report["unrolls"]["n_planar"] == n_planar and (distortion >= 0).all()
