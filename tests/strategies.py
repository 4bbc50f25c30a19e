"""Hypothesis strategies for quad meshes."""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st

from quadnodes.mesh import QuadMesh, grid
from quadnodes.noise import perturb
from meshes import extraordinary_mesh, l_shape_with_hole


@st.composite
def grids(draw, min_size: int = 4, max_size: int = 10, amplitude: float = 0.6) -> QuadMesh:
    """Random height-field grids with unit spacing."""
    r = draw(st.integers(min_size, max_size))
    c = draw(st.integers(min_size, max_size))
    seed = draw(st.integers(0, 2**31 - 1))
    z = np.random.default_rng(seed).uniform(-amplitude, amplitude, (r, c))
    return grid(r, c, height=z)


@st.composite
def irregular(draw) -> QuadMesh:
    """Meshes with extraordinary vertices, holes and reflex corners, randomly perturbed."""
    base = draw(st.sampled_from(["extraordinary", "lhole"]))
    m = extraordinary_mesh() if base == "extraordinary" else l_shape_with_hole()
    seed = draw(st.integers(0, 2**31 - 1))
    return perturb(m, tangential=0.2, normal=0.1, jitter=0.05, seed=seed)[0]


def meshes():
    """Grids or irregular meshes."""
    return st.one_of(grids(), irregular())
