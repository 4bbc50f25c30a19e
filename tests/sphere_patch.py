"""A sampled sphere patch (quadnodes.surfaces.dome) and its sphere, shared by the fairing tests."""

from __future__ import annotations

import numpy as np

from quadnodes import surfaces

RADIUS = (6000.0**2 / 4 + 1200.0**2) / 2400.0
CENTRE = np.array([0.0, 0.0, 1200.0 - RADIUS])


def patch(n: int = 17):
    return surfaces.sample(surfaces.dome(), n, n)


def distance(vertices: np.ndarray) -> np.ndarray:
    return np.abs(np.linalg.norm(vertices - CENTRE, axis=1) - RADIUS)


def normals(vertices: np.ndarray) -> np.ndarray:
    return (vertices - CENTRE) / RADIUS
