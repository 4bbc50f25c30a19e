"""The package's own exceptions.

Every error that quadnodes raises on purpose derives from :class:`QuadnodesError`,
so a caller can catch them all in one place. Input errors are also ``ValueError``
so that code written against plain NumPy conventions keeps working.
"""

from __future__ import annotations

__all__ = ["QuadnodesError", "InputError", "GraphError", "NodeError", "ExportError"]


class QuadnodesError(Exception):
    """Base class of every error raised by quadnodes."""


class InputError(QuadnodesError, ValueError):
    """An argument is malformed: wrong shape, dtype, range, or a broken mesh.

    The message names the parameter and, for meshes, the offending face or vertex.
    """


class GraphError(QuadnodesError):
    """A node graph is malformed: unknown op, port or setting, a cycle, a duplicate id."""


class NodeError(QuadnodesError):
    """A node failed while running; the message names the node id."""


class ExportError(QuadnodesError):
    """Writing an output file failed; no partial file is left behind."""
