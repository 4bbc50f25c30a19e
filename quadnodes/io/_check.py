"""Option checks specific to :mod:`quadnodes.io`.

Kept beside the exporters only because this module's author could not edit
``quadnodes/_validate.py`` at the time; these two helpers belong there.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from ..errors import InputError
from ..mesh import QuadMesh


def quad_mesh(mesh: Any, name: str = "mesh") -> QuadMesh:
    """Return ``mesh`` if it is a :class:`QuadMesh`, else raise :class:`InputError`."""
    if not isinstance(mesh, QuadMesh):
        raise InputError(f"{name}: expected a QuadMesh, got {type(mesh).__name__}")
    return mesh


def choice(value: Any, options: Iterable[str], name: str) -> str:
    """Return ``value`` lower-cased if it is one of ``options``, else raise :class:`InputError`."""
    opts = tuple(options)
    if isinstance(value, str) and value.lower() in opts:
        return value.lower()
    raise InputError(f"{name}: expected one of {', '.join(map(repr, opts))}, got {value!r}")
