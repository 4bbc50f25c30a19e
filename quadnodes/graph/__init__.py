"""The node-graph engine: node types, graphs, graph files, caching and the runner.

A node type is a plain typed function registered with :func:`node`; a
:class:`Graph` wires nodes together (in Python, or from a TOML/JSON file with
:func:`load`); :func:`run` executes it, reusing results from a :class:`Cache`
whose keys chain through the graph, so after a change only the affected nodes
run again.

Examples
--------
>>> from quadnodes.graph import Cache, Graph, Registry, node
>>> from quadnodes.mesh import QuadMesh, grid
>>> reg = Registry()
>>> @node("lift", outputs=("mesh",), registry=reg)
... def lift(mesh: QuadMesh, *, dz: float = 1.0) -> QuadMesh:
...     return mesh.with_vertices(mesh.vertices + [0.0, 0.0, dz])
>>> g = Graph(registry=reg)
>>> up = g.add("lift", grid(2, 2), dz=0.5)
>>> cache = Cache()
>>> g.run(cache=cache)[up].vertices[:, 2].tolist()
[0.5, 0.5, 0.5, 0.5]
>>> g.run(cache=cache).cached
['lift1']
"""

from __future__ import annotations

from .cache import Cache, CacheEntry, CacheWarning
from .files import FORMAT, VERSION, dumps, load, loads, parse_value, save
from .fingerprint import code_fingerprint, file_digest, fingerprint
from .graph import Constant, Graph, NodeHandle, NodeSpec, PortRef
from .node import REGISTRY, NodeType, Registry, describe, node
from ..progress import report_progress
from .run import ProgressEvent, RunRecord, RunResult, keys, run
from .sweep import SweepResult, SweepRow, parse_vary, run_sweep, variants

__all__ = [
    "node",
    "describe",
    "NodeType",
    "Registry",
    "REGISTRY",
    "Graph",
    "NodeHandle",
    "NodeSpec",
    "PortRef",
    "Constant",
    "load",
    "loads",
    "save",
    "dumps",
    "parse_value",
    "FORMAT",
    "VERSION",
    "fingerprint",
    "file_digest",
    "code_fingerprint",
    "Cache",
    "CacheEntry",
    "CacheWarning",
    "run",
    "keys",
    "RunResult",
    "RunRecord",
    "ProgressEvent",
    "report_progress",
    "run_sweep",
    "variants",
    "parse_vary",
    "SweepResult",
    "SweepRow",
]
