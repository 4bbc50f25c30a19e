"""Toy node types for the graph engine tests (independent of the built-in nodes)."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

import numpy as np
import pytest

from quadnodes.graph import Registry, node, report_progress
from quadnodes.mesh import QuadMesh, grid

REG = Registry()


@node("num", outputs=("value",), registry=REG)
def num(*, value: float = 0.0) -> float:
    """A constant number."""
    return value


@node("add", registry=REG)
def add(a: float, b: float = 0.0) -> float:
    """Sum of two numbers."""
    return a + b


@node("scale", registry=REG)
def scale(x: float, *, factor: float = 2.0) -> float:
    """Multiply by a factor."""
    for i in range(4):
        report_progress((i + 1) / 4, f"step {i + 1}")
    return x * factor


@node("fail", registry=REG)
def fail(x: float, *, message: str = "boom") -> float:
    raise ValueError(message)


@node("read_num", registry=REG, reads=("path",))
def read_num(*, path: Path) -> float:
    """A number read from a text file."""
    return float(path.read_text())


@node("write_num", registry=REG, writes=("path",))
def write_num(x: float, *, path: Path) -> float:
    """Write a number to a text file, pass it on."""
    path.write_text(repr(x))
    return x


@node("grid", outputs=("mesh",), registry=REG)
def mesh_grid(*, rows: int = 3, cols: int = 3, spacing: float = 1.0) -> QuadMesh:
    return grid(rows, cols, spacing=spacing)


@node("lift", outputs=("mesh",), registry=REG)
def lift(mesh: QuadMesh, *, dz: float = 1.0) -> QuadMesh:
    return mesh.with_vertices(mesh.vertices + np.array([0.0, 0.0, dz]))


@node("stats", outputs=("zmax", "n"), registry=REG)
def stats(mesh: QuadMesh) -> tuple[float, int]:
    return float(mesh.vertices[:, 2].max()), mesh.n_vertices


@node("stats_dict", outputs=("zmax", "n"), registry=REG)
def stats_dict(mesh: QuadMesh) -> dict:
    return {"n": mesh.n_vertices, "zmax": float(mesh.vertices[:, 2].max())}


@node("bad_return", outputs=("a", "b"), registry=REG)
def bad_return(x: float) -> Any:
    return x


@node("anything", registry=REG)
def anything(x: Any) -> float:
    return 1.0


@node("opaque", registry=REG)
def opaque(*, n: int = 1) -> object:
    return object()


@node("zoo", registry=REG)
def zoo(
    *,
    req: int,
    i: int = 1,
    f: float = 0.5,
    b: bool = False,
    s: str = "a",
    mode: Literal["uniform", "cotan"] = "uniform",
    fl: list[float] = [0.1],  # noqa: B006 - coerced to a fresh list per node
    ff: float | list[float] = 0.1,
    t: tuple[float, float] = (0.0, 0.0),
    opt: int | None = None,
    p: Path | None = None,
) -> float:
    """Every kind of setting."""
    return float(req)


@pytest.fixture
def reg() -> Registry:
    return REG
