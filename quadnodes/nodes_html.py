"""The ``render_html`` node: the interactive HTML view of :mod:`quadnodes.html` in a graph.

Importing this module registers the node in :data:`quadnodes.graph.REGISTRY`
(like :mod:`quadnodes.nodes`, which is expected to import it). It is a separate
module so that :mod:`quadnodes.html` stays a plain library module that knows
nothing about graphs.
"""

from __future__ import annotations

from pathlib import Path

from .errors import InputError
from .graph import node
from .mesh import QuadMesh


@node("render_html", outputs=("path",), writes=("path",))
def render_html(mesh: QuadMesh, mesh2: QuadMesh | None = None, mesh3: QuadMesh | None = None,
                mesh4: QuadMesh | None = None, reference: QuadMesh | None = None, *, path: str,
                titles: list[str] | None = None) -> Path:
    """Up to four meshes in one self-contained interactive HTML page (works offline), buttons switching
    between them; structure lines coloured by zigzag deviation; hover shows vertex and panel ids,
    deviation and planarity; an optional clean reference is shown as grey edges."""
    from . import html

    meshes = [m for m in (mesh, mesh2, mesh3, mesh4) if m is not None]
    if titles is not None and len(titles) != len(meshes):
        raise InputError(f"titles: {len(titles)} titles for {len(meshes)} connected meshes")
    return html.render_html(meshes, path, titles=titles, reference=reference)


__all__: list[str] = []  # import for the side effect of registering the node
