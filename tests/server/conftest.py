"""Toy node types and a small graph file for the server tests (fast: no build123d, no exporters)."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
import pytest

from quadnodes.graph.node import Range
from quadnodes.graph import Registry, node
from quadnodes.io._atomic import write_text_atomic
from quadnodes.mesh import QuadMesh, grid

REG = Registry()
CALLS: list[str] = []


@node("plane", outputs=("mesh",), registry=REG)
def plane(*, rows: int = 4, cols: int = 5, spacing: float = 1.0) -> QuadMesh:
    """A flat grid."""
    CALLS.append("plane")
    return grid(rows, cols, spacing=spacing)


@node("lift", outputs=("mesh",), registry=REG)
def lift(mesh: QuadMesh, *, dz: float = 1.0, mode: Literal["add", "scale"] = "add", keep: bool = False) -> QuadMesh:
    """Move every vertex up by dz (or scale z)."""
    CALLS.append("lift")
    v = np.array(mesh.vertices)
    v[:, 2] = v[:, 2] + dz if mode == "add" else v[:, 2] * dz
    return mesh.with_vertices(v)


@node("count", outputs=("n",), registry=REG)
def count(mesh: QuadMesh) -> int:
    """Number of vertices."""
    CALLS.append("count")
    return int(mesh.n_vertices)


@node("boom", outputs=("mesh",), registry=REG)
def boom(mesh: QuadMesh, *, fail: bool = True) -> QuadMesh:
    """Fails on purpose when fail is true."""
    CALLS.append("boom")
    if fail:
        raise ValueError("boom went off on purpose")
    return mesh


@node("save_text", outputs=("path",), writes=("path",), registry=REG)
def save_text(n: int, *, path: str) -> Path:
    """Write a number to a text file."""
    CALLS.append("save_text")
    return write_text_atomic(path, f"{n}\n")


@node("read_text", outputs=("n",), reads=("path",), registry=REG)
def read_text(*, path: str) -> int:
    """Read a number from a text file."""
    CALLS.append("read_text")
    return int(Path(path).read_text().strip())


# a declared range for a setting: the page shows a slider for it
object.__setattr__(REG.get("lift").setting("dz"), "range", Range(min=-10.0, max=10.0))

GRAPH = """\
# a toy graph for the server tests
format = "quadnodes-graph"
version = 1

[nodes.base]
op = "plane@1"
params = { rows = 4, cols = 5 }   # a small grid

[nodes.up]
op = "lift@1"
inputs = { mesh = "base.mesh" }
params = { dz = 2.0 }

[nodes.n]
op = "count@1"
inputs = { mesh = "up.mesh" }

[nodes.other]
op = "count@1"
inputs = { mesh = "base.mesh" }

[nodes.save]
op = "save_text@1"
inputs = { n = "n.n" }
params = { path = "n.txt" }
"""


@pytest.fixture
def graph_file(tmp_path: Path) -> Path:
    p = tmp_path / "design" / "toy.toml"
    p.parent.mkdir()
    p.write_text(GRAPH)
    return p


@pytest.fixture
def reg() -> Registry:
    return REG


@pytest.fixture
def calls() -> list[str]:
    CALLS.clear()
    return CALLS
