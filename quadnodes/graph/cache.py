"""Results of nodes by cache key: in memory, and optionally in a folder on disk.

A :class:`Cache` maps a node's key (see :mod:`quadnodes.graph.run`) to a
:class:`CacheEntry`: the node's outputs and, for nodes that write files, the
digests of what they wrote.

The disk format is not pickle. Each entry is one ``.npz`` file (loaded with
``allow_pickle=False``): the arrays, plus a JSON description of the value tree
that refers to them. It covers None, bool, int, float, str, lists, tuples,
dicts, sets, paths, NumPy arrays and scalars, enums, and dataclasses (rebuilt by
calling their constructor, so a :class:`~quadnodes.mesh.QuadMesh` comes back
validated with read-only arrays). An output of any other type is kept in memory
only. Reading an entry can therefore not run arbitrary code: the classes an
entry names (dataclasses, enums, paths) must be on an allow-list — classes of
the quadnodes package and the :mod:`pathlib` path classes — checked on the name
*before* any module is imported; an entry naming anything else is unreadable (a
miss). Values of other classes are kept in memory only.

build123d shapes (the faces of the surface nodes) are stored as OCCT BREP text
(``BRepTools.Write``), read back with ``BRepTools.Read`` — a parser, no code —
so an unchanged surface is never rebuilt, also across processes. Outputs of an
entry read from disk are decoded when first used, so a run whose nodes all come
from the cache does not even import build123d to decode a face nobody reads.

Writes are atomic (temporary file in the same folder, then ``os.replace``), so
concurrent runs sharing a folder never see half an entry. A corrupt or
unreadable entry is a miss (with a :class:`CacheWarning`), never an error.
"""

from __future__ import annotations

import dataclasses
import enum
import hashlib
import importlib
import io
import json
import os
import pathlib
import re
import sys
import warnings
from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..errors import ExportError
from ..io._atomic import write_atomic

__all__ = ["CacheEntry", "Cache", "CacheWarning", "encode", "decode"]

_DISK_FORMAT = "quadnodes-cache"
_DISK_VERSION = 1


class CacheWarning(UserWarning):
    """The disk cache could not read or write an entry (the run goes on without it)."""


@dataclass(frozen=True)
class CacheEntry:
    """A node's outputs by port name, and digests of the files it wrote (by setting)."""

    outputs: Mapping[str, Any]
    files: Mapping[str, list[str]] = field(default_factory=dict)


class Cache:
    """Node results by key, in memory and (optionally) in a folder.

    Parameters
    ----------
    directory : path, optional
        Folder of the disk cache (created if missing). None: memory only.
    max_memory_entries : int, optional
        Keep at most this many entries in memory, dropping the least recently
        used (None: no limit). The disk cache is never trimmed automatically;
        see :meth:`clear`.

    Raises
    ------
    InputError
        If ``directory`` cannot be created or is not a folder.

    Examples
    --------
    >>> import tempfile
    >>> from quadnodes.mesh import grid
    >>> d = tempfile.mkdtemp()
    >>> Cache(d).put("k" * 64, CacheEntry({"mesh": grid(2, 3), "n": 6}))
    True
    >>> fresh = Cache(d)                       # e.g. another process
    >>> entry = fresh.get("k" * 64)
    >>> entry.outputs["mesh"].grid_shape, entry.outputs["n"], entry.outputs["mesh"].vertices.flags.writeable
    ((2, 3), 6, False)
    """

    def __init__(
        self,
        directory: str | os.PathLike[str] | None = None,
        *,
        max_memory_entries: int | None = None,
    ) -> None:
        self._memory: OrderedDict[str, CacheEntry] = OrderedDict()
        if max_memory_entries is not None and (isinstance(max_memory_entries, bool) or max_memory_entries < 0):
            raise InputError(f"max_memory_entries: expected a non-negative int or None, got {max_memory_entries!r}")
        self.max_memory_entries = max_memory_entries
        self.directory: Path | None = None
        if directory is not None:
            d = Path(directory).expanduser()
            try:
                d.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise InputError(f"directory: cannot create cache folder {str(d)!r}: {exc}") from exc
            if not d.is_dir():
                raise InputError(f"directory: {str(d)!r} is not a folder")
            self.directory = d

    def __repr__(self) -> str:
        where = f"directory={str(self.directory)!r}, " if self.directory else ""
        return f"Cache({where}{len(self._memory)} in memory)"

    def _path(self, key: str) -> Path:
        assert self.directory is not None
        return self.directory / key[:2] / f"{key}.npz"

    def __contains__(self, key: str) -> bool:
        return key in self._memory or (self.directory is not None and self._path(key).is_file())

    def on_disk(self, key: str) -> bool:
        """Whether the disk cache holds an entry for ``key`` (other processes can read it)."""
        return self.directory is not None and self._path(key).is_file()

    def get(self, key: str) -> CacheEntry | None:
        """The entry for ``key`` from memory, else from disk (then kept in memory), else None."""
        entry = self._memory.get(key)
        if entry is not None:
            self._memory.move_to_end(key)
            return entry
        if self.directory is None:
            return None
        path = self._path(key)
        if not path.is_file():
            return None
        try:
            entry = _read_entry(path, key)
        except Exception as exc:  # a corrupt, truncated or outdated entry is a miss
            warnings.warn(f"cache entry {str(path)!r} is unreadable, recomputing: {exc}", CacheWarning,
                          stacklevel=2)
            return None
        self._remember(key, entry)
        return entry

    def put(self, key: str, entry: CacheEntry) -> bool:
        """Store ``entry``; return True when it also reached the disk cache.

        An entry whose outputs cannot be encoded (see the module docstring) is kept
        in memory only; so is one whose file cannot be written (a
        :class:`CacheWarning` says why).
        """
        self._remember(key, entry)
        if self.directory is None:
            return False
        try:
            payload = _encode_entry(key, entry)
        except _Unsupported:
            return False
        path = self._path(key)
        try:
            path.parent.mkdir(exist_ok=True)
            write_atomic(path, lambda tmp: Path(tmp).write_bytes(payload))
        except (OSError, ExportError) as exc:
            warnings.warn(f"cannot write cache entry {str(path)!r}: {exc}", CacheWarning, stacklevel=2)
            return False
        return True

    def _remember(self, key: str, entry: CacheEntry) -> None:
        self._memory[key] = entry
        self._memory.move_to_end(key)
        if self.max_memory_entries is not None:
            while len(self._memory) > self.max_memory_entries:
                self._memory.popitem(last=False)

    def clear(self, *, disk: bool = False) -> None:
        """Forget the memory entries, and with ``disk=True`` delete the disk entries too."""
        self._memory.clear()
        if disk and self.directory is not None:
            for p in self.directory.glob("??/*.npz"):
                p.unlink(missing_ok=True)


# ------------------------------------------------------------------ the codec
class _Unsupported(Exception):
    pass


def _encode_entry(key: str, entry: CacheEntry) -> bytes:
    arrays: list[np.ndarray] = []
    meta = {
        "format": _DISK_FORMAT,
        "version": _DISK_VERSION,
        "key": key,
        "outputs": encode(dict(entry.outputs), arrays),
        "files": {k: list(v) for k, v in entry.files.items()},
    }
    buf = io.BytesIO()
    blobs = {f"a{i}": a for i, a in enumerate(arrays)}
    np.savez(buf, __meta__=np.frombuffer(json.dumps(meta, allow_nan=True).encode(), dtype=np.uint8), **blobs)
    return buf.getvalue()


def _read_entry(path: Path, key: str) -> CacheEntry:
    with np.load(path, allow_pickle=False) as z:
        meta = json.loads(z["__meta__"].tobytes().decode())
        if meta.get("format") != _DISK_FORMAT or meta.get("version") != _DISK_VERSION or meta.get("key") != key:
            raise ValueError("not an entry of this cache version")
        arrays = [z[f"a{i}"] for i in range(len(z.files) - 1)]
    tree = meta["outputs"]
    if not (isinstance(tree, dict) and isinstance(tree.get("$dict"), list)):
        raise ValueError("malformed entry: outputs are not a table")
    outputs = _LazyOutputs(tree["$dict"], arrays)
    return CacheEntry(outputs, {k: list(v) for k, v in meta["files"].items()})


class _LazyOutputs(Mapping):
    """Outputs by port of an entry read from disk.

    Ports holding a build123d shape are decoded when first read (that needs
    build123d); the others at once, so a corrupt entry is a miss when it is read.
    The BREP text is checked against its sha256 when the entry is read.
    """

    def __init__(self, items: list[Any], arrays: list[np.ndarray]) -> None:
        if not all(isinstance(kv, list) and len(kv) == 2 and isinstance(kv[0], str) for kv in items):
            raise ValueError("malformed entry: output names are not strings")
        self._trees = {k: v for k, v in items}
        self._arrays = arrays
        self._values: dict[str, Any] = {}
        for port, tree in self._trees.items():
            breps = _breps(tree)
            for node in breps:
                data = arrays[node["$brep"]]
                if hashlib.sha256(np.asarray(data, dtype=np.uint8).tobytes()).hexdigest() != node.get("sha256"):
                    raise ValueError("malformed entry: BREP text does not match its checksum")
            if not breps:
                self._values[port] = decode(tree, arrays)

    def __getitem__(self, port: str) -> Any:
        if port not in self._values:
            self._values[port] = decode(self._trees[port], self._arrays)
        return self._values[port]

    def __iter__(self) -> Any:
        return iter(self._trees)

    def __len__(self) -> int:
        return len(self._trees)

    def decoded_ports(self) -> list[str]:
        """Ports whose values are decoded already (reading them imports nothing, e.g. not build123d)."""
        return list(self._values)

    def __repr__(self) -> str:
        return f"_LazyOutputs({list(self._trees)})"


def _breps(tree: Any) -> list[dict[str, Any]]:
    """The ``$brep`` nodes of an encoded tree."""
    if isinstance(tree, list):
        return [b for v in tree for b in _breps(v)]
    if isinstance(tree, dict):
        if "$brep" in tree:
            return [tree]
        return [b for v in tree.values() for b in _breps(v)]
    return []


def _brep_bytes(value: Any) -> bytes | None:
    """OCCT BREP text of a build123d shape, or None for any other value (build123d is not imported)."""
    bd = sys.modules.get("build123d")
    if bd is None or not isinstance(value, bd.Shape) or value.wrapped is None:
        return None
    from OCP.BRepTools import BRepTools

    buf = io.BytesIO()
    BRepTools.Write_s(value.wrapped, buf)
    return buf.getvalue()


def _brep_shape(data: np.ndarray) -> Any:
    """The build123d shape (Face, Shell, …, by its OCCT type) of BREP text."""
    import build123d as bd
    from OCP.BRep import BRep_Builder
    from OCP.BRepTools import BRepTools
    from OCP.TopoDS import TopoDS_Shape

    shape = TopoDS_Shape()
    BRepTools.Read_s(shape, io.BytesIO(np.asarray(data, dtype=np.uint8).tobytes()), BRep_Builder())
    if shape.IsNull():
        raise ValueError("malformed entry: empty BREP shape")
    return bd.Compound.cast(shape)


def _cls_name(cls: type) -> str:
    name = f"{cls.__module__}:{cls.__qualname__}"
    if not _allowed(name):
        raise _Unsupported(f"{name} is not on the cache's allow-list")  # kept in memory only
    return name


def encode(value: Any, arrays: list[np.ndarray]) -> Any:
    """The JSON tree of ``value``; arrays are appended to ``arrays`` and referred to by index.

    Raises
    ------
    _Unsupported
        For any value outside the supported types.

    Examples
    --------
    >>> arrays = []
    >>> encode({"n": 3, "p": (1.5, None)}, arrays), arrays
    ({'$dict': [['n', 3], ['p', {'$tuple': [1.5, None]}]]}, [])
    """
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, enum.Enum):
        return {"$enum": _cls_name(type(value)), "value": encode(value.value, arrays)}
    if type(value) is int or type(value) is float:
        return value
    if isinstance(value, (np.ndarray, np.generic)):
        a = np.asarray(value)
        if a.dtype.hasobject:
            raise _Unsupported("object array")
        arrays.append(np.array(a, copy=True))
        return {"$array" if isinstance(value, np.ndarray) else "$scalar": len(arrays) - 1}
    if type(value) is list:
        return [encode(v, arrays) for v in value]
    if type(value) is tuple:
        return {"$tuple": [encode(v, arrays) for v in value]}
    if type(value) is dict:
        return {"$dict": [[encode(k, arrays), encode(v, arrays)] for k, v in value.items()]}
    if type(value) in (set, frozenset):
        return {"$set" if type(value) is set else "$frozenset": [encode(v, arrays) for v in value]}
    if isinstance(value, pathlib.PurePath):
        return {"$path": str(value), "cls": _cls_name(type(value))}
    brep = _brep_bytes(value)
    if brep is not None:
        arrays.append(np.frombuffer(brep, dtype=np.uint8).copy())
        return {"$brep": len(arrays) - 1, "sha256": hashlib.sha256(brep).hexdigest()}
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = dataclasses.fields(value)
        if any(not f.init for f in fields):
            raise _Unsupported(f"{type(value).__qualname__} has fields outside __init__")
        return {
            "$dataclass": _cls_name(type(value)),
            "fields": [[f.name, encode(getattr(value, f.name), arrays)] for f in fields],
        }
    raise _Unsupported(type(value).__qualname__)


_PATH_CLASSES = frozenset(f"pathlib:{c}" for c in
                          ("Path", "PosixPath", "WindowsPath", "PurePath", "PurePosixPath", "PureWindowsPath"))
_QUADNODES_CLASS = re.compile(r"quadnodes(\.[A-Za-z_][A-Za-z0-9_]*)*:[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*\Z")


def _allowed(name: str) -> bool:
    """Whether a cache entry may name this ``module:qualname`` (decided on the text alone, nothing imported).

    Examples
    --------
    >>> _allowed("quadnodes.mesh:QuadMesh"), _allowed("pathlib:PosixPath")
    (True, True)
    >>> _allowed("os:system"), _allowed("quadnodes_evil:X"), _allowed("quadnodes.mesh:QuadMesh.__init__.__globals__")
    (False, False, False)
    """
    if name in _PATH_CLASSES:
        return True
    return bool(_QUADNODES_CLASS.match(name)) and "__" not in name


def _find_class(name: str) -> Any:
    """The class an entry names, if it is on the allow-list (checked before any import).

    Raises
    ------
    ValueError
        For a name outside the allow-list (nothing is imported), or one that does
        not exist.
    """
    if not isinstance(name, str) or not _allowed(name):
        raise ValueError(f"class {name!r} is not one a cache entry may name (quadnodes classes and pathlib paths)")
    module, _, qual = name.partition(":")
    try:
        obj: Any = sys.modules.get(module) or importlib.import_module(module)
        for part in qual.split("."):
            obj = getattr(obj, part)
    except (ImportError, AttributeError) as exc:
        raise ValueError(f"class {name!r} does not exist: {exc}") from None
    return obj


def decode(tree: Any, arrays: list[np.ndarray]) -> Any:
    """Inverse of :func:`encode`.

    Raises
    ------
    ValueError
        On a malformed tree or a class that is not a dataclass, enum or path class.
    """
    if tree is None or isinstance(tree, (bool, int, float, str)):
        return tree
    if isinstance(tree, list):
        return [decode(v, arrays) for v in tree]
    if not isinstance(tree, dict) or len(tree) == 0:
        raise ValueError(f"malformed entry: {tree!r}")
    if "$array" in tree:
        a = arrays[tree["$array"]]
        a.setflags(write=False)  # cached values are shared between runs
        return a
    if "$brep" in tree:
        return _brep_shape(arrays[tree["$brep"]])
    if "$scalar" in tree:
        return arrays[tree["$scalar"]][()]
    if "$tuple" in tree:
        return tuple(decode(v, arrays) for v in tree["$tuple"])
    if "$dict" in tree:
        return {decode(k, arrays): decode(v, arrays) for k, v in tree["$dict"]}
    if "$set" in tree:
        return {decode(v, arrays) for v in tree["$set"]}
    if "$frozenset" in tree:
        return frozenset(decode(v, arrays) for v in tree["$frozenset"])
    if "$path" in tree:
        cls = _find_class(tree["cls"])
        if not (isinstance(cls, type) and issubclass(cls, pathlib.PurePath)):
            raise ValueError(f"{tree['cls']} is not a path class")
        return cls(tree["$path"])
    if "$enum" in tree:
        cls = _find_class(tree["$enum"])
        if not (isinstance(cls, type) and issubclass(cls, enum.Enum)):
            raise ValueError(f"{tree['$enum']} is not an enum")
        return cls(decode(tree["value"], arrays))
    if "$dataclass" in tree:
        cls = _find_class(tree["$dataclass"])
        if not (isinstance(cls, type) and dataclasses.is_dataclass(cls)):
            raise ValueError(f"{tree['$dataclass']} is not a dataclass")
        return cls(**{k: decode(v, arrays) for k, v in tree["fields"]})
    raise ValueError(f"malformed entry: unknown tag in {sorted(tree)}")
