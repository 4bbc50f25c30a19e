"""Stable sha256 fingerprints of values, files and node code.

A fingerprint is the same in every process and on every machine for equal data,
and different for different data. Values that cannot be fingerprinted exactly
(arbitrary objects, object arrays, recursive containers) give ``None`` — never a
guess — and the runner then refuses to cache anything that depends on them.

What is covered:

- ``None``, bool, int, float (bit-exact, via ``float.hex``), complex, str, bytes;
- NumPy arrays and scalars: dtype, shape and the raw bytes (C order);
- lists, tuples (named tuples by class), dicts and sets (order-free);
- ``pathlib`` paths (the path text, not the file: see :func:`file_digest`), enums;
- dataclass instances, by qualified class name and fields — this covers
  :class:`~quadnodes.mesh.QuadMesh` (``vertices``, ``faces``, ``grid_shape``) and
  reports such as ``FairingReport``;
- ``scipy.sparse`` matrices (canonical CSR);
- any object with a ``__quadnodes_fingerprint__()`` method returning a string.
"""

from __future__ import annotations

import dataclasses
import enum
import functools
import hashlib
import inspect
import json
import marshal
import os
import pathlib
import sys
from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = [
    "fingerprint",
    "canonical_json",
    "file_digest",
    "code_fingerprint",
    "package_digest",
]

_PACKAGE_DIR = pathlib.Path(__file__).resolve().parent.parent


def canonical_json(obj: Any) -> str:
    """JSON with sorted keys and no whitespace: the hashing form of plain data.

    Examples
    --------
    >>> canonical_json({"b": [1, 2.5], "a": "x"})
    '{"a":"x","b":[1,2.5]}'
    """
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=True)


def fingerprint(value: Any) -> str | None:
    """sha256 hex digest of ``value``, or None when it cannot be fingerprinted exactly.

    Parameters
    ----------
    value : any
        See the module docstring for the supported types.

    Returns
    -------
    str or None
        64 hex digits; None for unsupported objects (anywhere inside ``value``).

    Examples
    --------
    >>> from quadnodes.mesh import grid
    >>> m = grid(3, 3)
    >>> fingerprint(m) == fingerprint(grid(3, 3))
    True
    >>> fingerprint(m) == fingerprint(grid(3, 3, spacing=2.0))
    False
    >>> fingerprint(1) == fingerprint(1.0), fingerprint(object())
    (False, None)
    """
    h = hashlib.sha256(b"quadnodes-fingerprint-v1\0")
    return h.hexdigest() if _feed(h, value, set()) else None


def _tag(h: Any, tag: bytes, payload: bytes = b"") -> None:
    h.update(tag + len(payload).to_bytes(8, "little") + payload)


def _qualname(obj: Any) -> bytes:
    cls = type(obj)
    return f"{cls.__module__}.{cls.__qualname__}".encode()


def _sub(value: Any, seen: set[int]) -> bytes | None:
    h = hashlib.sha256()
    return h.digest() if _feed(h, value, seen) else None


def _feed(h: Any, v: Any, seen: set[int]) -> bool:
    if v is None:
        _tag(h, b"N")
        return True
    if isinstance(v, (np.ndarray, np.generic)):
        a = np.asarray(v)
        if a.dtype.hasobject:
            return False
        _tag(h, b"A" if isinstance(v, np.ndarray) else b"g", repr((a.dtype.descr, a.dtype.str, a.shape)).encode())
        h.update(np.ascontiguousarray(a).tobytes())
        return True
    if isinstance(v, bool):
        _tag(h, b"B", b"1" if v else b"0")
        return True
    if isinstance(v, enum.Enum):
        _tag(h, b"E", _qualname(v))
        return _feed(h, v.value, seen)
    if type(v) is int:
        _tag(h, b"I", str(v).encode())
        return True
    if type(v) is float:
        _tag(h, b"F", v.hex().encode())
        return True
    if type(v) is complex:
        _tag(h, b"C", f"{v.real.hex()},{v.imag.hex()}".encode())
        return True
    if type(v) is str:
        _tag(h, b"S", v.encode("utf-8", "surrogatepass"))
        return True
    if isinstance(v, (bytes, bytearray, memoryview)):
        _tag(h, b"Y", bytes(v))
        return True
    if isinstance(v, pathlib.PurePath):
        _tag(h, b"P", _qualname(v) + b"\0" + str(v).encode("utf-8", "surrogatepass"))
        return True
    method = getattr(type(v), "__quadnodes_fingerprint__", None)
    if method is not None:
        fp = method(v)
        if not isinstance(fp, str):
            return False
        _tag(h, b"X", _qualname(v) + b"\0" + fp.encode())
        return True
    if isinstance(v, (list, tuple, dict, set, frozenset)) or dataclasses.is_dataclass(v):
        if id(v) in seen:
            return False  # a recursive structure has no finite fingerprint
        seen.add(id(v))
        try:
            return _feed_container(h, v, seen)
        finally:
            seen.discard(id(v))
    if "scipy.sparse" in sys.modules:
        import scipy.sparse as sp

        if sp.issparse(v):
            m = sp.csr_matrix(v, copy=True)
            m.sum_duplicates()
            m.sort_indices()
            _tag(h, b"Z", repr(m.shape).encode())
            return all(_feed(h, a, seen) for a in (m.data, m.indices.astype(np.int64), m.indptr.astype(np.int64)))
    return False


def _feed_container(h: Any, v: Any, seen: set[int]) -> bool:
    if dataclasses.is_dataclass(v) and not isinstance(v, type):
        _tag(h, b"D", _qualname(v))
        for f in dataclasses.fields(v):
            _tag(h, b"f", f.name.encode())
            if not _feed(h, getattr(v, f.name), seen):
                return False
        return True
    if isinstance(v, (list, tuple)):
        kind = b"L" if type(v) is list else b"T" if type(v) is tuple else b"t" + _qualname(v)
        _tag(h, kind, str(len(v)).encode())
        return all(_feed(h, x, seen) for x in v)
    if isinstance(v, dict):
        pairs = []
        for k, x in v.items():
            dk, dx = _sub(k, seen), _sub(x, seen)
            if dk is None or dx is None:
                return False
            pairs.append(dk + dx)
        _tag(h, b"M", str(len(pairs)).encode())
        for p in sorted(pairs):
            h.update(p)
        return True
    items = []
    for x in v:  # set / frozenset
        d = _sub(x, seen)
        if d is None:
            return False
        items.append(d)
    _tag(h, b"s", str(len(items)).encode())
    for d in sorted(items):
        h.update(d)
    return True


def file_digest(path: str | os.PathLike[str]) -> str | None:
    """sha256 of a file's bytes; of a folder, of its sorted relative names and file digests.

    Returns None when nothing exists at ``path``.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "a.txt"
    >>> file_digest(p) is None
    True
    >>> _ = p.write_text("abc")
    >>> file_digest(p)[:12]
    'ba7816bf8f01'
    """
    p = pathlib.Path(path)
    if p.is_dir():
        h = hashlib.sha256(b"quadnodes-folder-v1\0")
        for child in sorted(q for q in p.rglob("*") if q.is_file()):
            rel = child.relative_to(p).as_posix().encode("utf-8", "surrogateescape")
            h.update(len(rel).to_bytes(8, "little") + rel)
            h.update(bytes.fromhex(file_digest(child) or ""))
        return h.hexdigest()
    if not p.is_file():
        return None
    h = hashlib.sha256()
    with open(p, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


@functools.lru_cache(maxsize=1)
def package_digest() -> str:
    """sha256 of the quadnodes package's source files and the versions it runs on.

    Every ``*.py`` file under the package folder (sorted by relative path) plus the
    Python, NumPy and SciPy versions: a change to the library, or to the numerics
    under it, invalidates every cached result. Computed once per process.
    """
    from importlib import metadata

    h = hashlib.sha256(b"quadnodes-package-v1\0")
    versions = [f"python {sys.version_info[0]}.{sys.version_info[1]}"]
    for dist in ("numpy", "scipy"):
        try:
            versions.append(f"{dist} {metadata.version(dist)}")
        except metadata.PackageNotFoundError:
            versions.append(f"{dist} -")
    h.update("\n".join(versions).encode() + b"\0")
    for path in sorted(_PACKAGE_DIR.rglob("*.py")):
        if "__pycache__" in path.parts:
            continue
        rel = path.relative_to(_PACKAGE_DIR).as_posix().encode()
        h.update(len(rel).to_bytes(8, "little") + rel)
        h.update(bytes.fromhex(file_digest(path) or ""))
    return h.hexdigest()


def code_fingerprint(func: Callable[..., Any]) -> str | None:
    """sha256 of a node function's code and of the library it runs on.

    Hashes the function's source (or, when there is none, e.g. code typed at a
    prompt, its compiled code object), the whole source file of its module when
    that lies outside the quadnodes package (so helpers the function calls are
    covered too), and :func:`package_digest`.

    Returns None for callables without code (builtins, most callable objects);
    such nodes are never cached.

    Examples
    --------
    >>> def f(x: float) -> float:
    ...     return x + 1
    >>> len(code_fingerprint(f)), code_fingerprint(len)
    (64, None)
    """
    func = inspect.unwrap(func)
    code = getattr(func, "__code__", None)
    if code is None:
        return None
    h = hashlib.sha256(b"quadnodes-code-v1\0")
    h.update(package_digest().encode())
    try:
        _tag(h, b"src", inspect.getsource(func).encode("utf-8", "surrogatepass"))
    except (OSError, TypeError):
        _tag(h, b"code", marshal.dumps(code))
    module = sys.modules.get(getattr(func, "__module__", "") or "")
    filename = getattr(module, "__file__", None)
    if filename:
        path = pathlib.Path(filename).resolve()
        if _PACKAGE_DIR not in path.parents and path.is_file():
            _tag(h, b"module", path.read_bytes())
    return h.hexdigest()
