"""Annotations of node parameters: which settings types are allowed, coercion, names.

Settings are JSON/TOML values. Their annotation decides how a value read from a
file (or given in Python) is checked and converted: ``int`` accepts ``3`` and
``3.0``, ``float`` accepts ints, ``pathlib.Path`` accepts strings, ``tuple``
accepts lists, and so on. Input ports may carry any annotation; they are only
checked where a check is certain (see :func:`maybe_instance`, :func:`maybe_compatible`).
"""

from __future__ import annotations

import inspect
import numbers
import pathlib
import types
import typing
from collections import abc
from typing import Any, Literal, Union, get_args, get_origin

import numpy as np
import numpy.typing as npt

__all__ = [
    "Mismatch",
    "unsupported_setting_reason",
    "coerce",
    "to_plain",
    "type_name",
    "maybe_instance",
    "maybe_compatible",
]

_EMPTY = inspect.Parameter.empty
_NONE = type(None)
_SEQ_ORIGINS = (list, abc.Sequence, abc.MutableSequence)
_MAP_ORIGINS = (dict, abc.Mapping, abc.MutableMapping)


class Mismatch(Exception):
    """A value does not fit an annotation; ``where`` is the path inside it (``[2]``, ``.a``)."""

    def __init__(self, message: str, where: str = "") -> None:
        super().__init__(message)
        self.message = message
        self.where = where

    def at(self, step: str) -> Mismatch:
        return Mismatch(self.message, step + self.where)


def _is_any(ann: Any) -> bool:
    return ann is Any or ann is _EMPTY or ann is object


def _is_union(ann: Any) -> bool:
    return get_origin(ann) in (Union, types.UnionType)


def _show(value: Any) -> str:
    r = repr(value)
    if len(r) > 60:
        r = r[:57] + "..."
    return f"{type(value).__name__} {r}"


def unsupported_setting_reason(ann: Any) -> str | None:
    """Why ``ann`` cannot annotate a setting, or None when it can.

    Examples
    --------
    >>> unsupported_setting_reason(float | list[float]) is None
    True
    >>> unsupported_setting_reason(np.ndarray)
    'ndarray is not a JSON/TOML value'
    """
    if _is_any(ann) or ann is _NONE:
        return None
    if ann in (bool, int, float, str, list, tuple, dict):
        return None
    if isinstance(ann, type) and issubclass(ann, pathlib.PurePath):
        return None
    origin = get_origin(ann)
    args = get_args(ann)
    if origin is Literal:
        bad = [a for a in args if not isinstance(a, (str, int, float, bool))]
        return f"Literal value {bad[0]!r} is not a JSON/TOML value" if bad else None
    if _is_union(ann) or origin in _SEQ_ORIGINS or origin is tuple:
        for a in args:
            if a is Ellipsis:
                continue
            reason = unsupported_setting_reason(a)
            if reason:
                return reason
        return None
    if origin in _MAP_ORIGINS:
        if args and args[0] is not str:
            return f"{type_name(ann)}: mapping keys must be str"
        return unsupported_setting_reason(args[1]) if args else None
    return f"{type_name(ann)} is not a JSON/TOML value"


def coerce(value: Any, ann: Any) -> Any:
    """Check ``value`` against ``ann`` and convert it to the annotated type.

    Raises
    ------
    Mismatch
        With a message such as ``expected int, got str 'three'``.

    Examples
    --------
    >>> coerce(3, float), coerce([1, 2], tuple[float, float]), coerce(4.0, int)
    (3.0, (1.0, 2.0), 4)
    >>> coerce("raw", Literal["normalized", "raw"])
    'raw'
    >>> coerce(0.5, float | list[float]), coerce([1], float | list[float])
    (0.5, [1.0])
    >>> coerce("a.step", pathlib.Path | None)
    PosixPath('a.step')
    >>> coerce([1, "x"], list[float])
    Traceback (most recent call last):
    ...
    quadnodes.graph._types.Mismatch: expected float, got str 'x'
    """
    if _is_any(ann):
        return value
    if ann is _NONE:
        if value is None:
            return None
        raise Mismatch(f"expected None, got {_show(value)}")
    origin = get_origin(ann)
    args = get_args(ann)
    if origin is Literal:
        for lit in args:
            if type(value) is type(lit) and value == lit:
                return lit
        if isinstance(value, str):
            import difflib

            close = difflib.get_close_matches(value, [a for a in args if isinstance(a, str)], n=1)
            hint = f"; did you mean {close[0]!r}?" if close else ""
        else:
            hint = ""
        raise Mismatch(f"expected one of {', '.join(map(repr, args))}, got {_show(value)}{hint}")
    if _is_union(ann):
        if value is None and _NONE in args:
            return None
        # A member the value already is wins (3 stays an int in ``float | int``).
        for a in args:
            if isinstance(a, type) and a is not _NONE and _exactly(value, a):
                return coerce(value, a)
        for a in args:
            try:
                return coerce(value, a)
            except Mismatch:
                continue
        raise Mismatch(f"expected {type_name(ann)}, got {_show(value)}")
    if ann is bool:
        if isinstance(value, (bool, np.bool_)):
            return bool(value)
        raise Mismatch(f"expected bool (true or false), got {_show(value)}")
    if ann is int:
        if isinstance(value, (bool, np.bool_)):
            raise Mismatch(f"expected int, got {_show(value)}")
        if isinstance(value, numbers.Integral):
            return int(value)
        if isinstance(value, numbers.Real) and float(value).is_integer():
            return int(value)
        raise Mismatch(f"expected int, got {_show(value)}")
    if ann is float:
        if isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_)):
            return float(value)
        raise Mismatch(f"expected float, got {_show(value)}")
    if ann is str:
        if isinstance(value, str):
            return value
        raise Mismatch(f"expected str, got {_show(value)}")
    if isinstance(ann, type) and issubclass(ann, pathlib.PurePath):
        if isinstance(value, (str, pathlib.PurePath)) and str(value) != "":
            return pathlib.Path(value) if ann is pathlib.PurePath else ann(value)
        raise Mismatch(f"expected a path (string), got {_show(value)}")
    if ann in (list, tuple) or origin in _SEQ_ORIGINS or origin is tuple:
        if isinstance(value, np.ndarray) and value.ndim == 1:
            value = value.tolist()
        if not isinstance(value, (list, tuple)):
            raise Mismatch(f"expected {type_name(ann)}, got {_show(value)}")
        if ann is tuple or origin is tuple:
            if args and not (len(args) == 2 and args[1] is Ellipsis):
                if args == ((),):
                    args = ()
                if len(value) != len(args):
                    raise Mismatch(f"expected {type_name(ann)} ({len(args)} items), got {len(value)} items")
                return tuple(_item(v, a, i) for i, (v, a) in enumerate(zip(value, args)))
            item = args[0] if args else Any
            return tuple(_item(v, item, i) for i, v in enumerate(value))
        item = args[0] if args else Any
        return [_item(v, item, i) for i, v in enumerate(value)]
    if ann is dict or origin in _MAP_ORIGINS:
        if not isinstance(value, abc.Mapping):
            raise Mismatch(f"expected {type_name(ann)}, got {_show(value)}")
        vt = args[1] if len(args) == 2 else Any
        out = {}
        for k, v in value.items():
            if not isinstance(k, str):
                raise Mismatch(f"expected str keys, got {_show(k)}")
            try:
                out[k] = coerce(v, vt)
            except Mismatch as exc:
                raise exc.at(f"[{k!r}]") from None
        return out
    raise Mismatch(f"cannot check a value against {type_name(ann)}")


def _item(value: Any, ann: Any, i: int) -> Any:
    try:
        return coerce(value, ann)
    except Mismatch as exc:
        raise exc.at(f"[{i}]") from None


def _exactly(value: Any, cls: type) -> bool:
    if cls in (int, float) and isinstance(value, (bool, np.bool_)):
        return False
    if cls is float:
        return isinstance(value, float)
    if cls is int:
        return isinstance(value, numbers.Integral)
    try:
        return isinstance(value, cls)
    except TypeError:
        return False


def to_plain(value: Any) -> Any:
    """The JSON/TOML form of a coerced setting: paths become strings, tuples lists.

    Examples
    --------
    >>> to_plain({"p": pathlib.Path("a/b.obj"), "t": (1.0, 2)})
    {'p': 'a/b.obj', 't': [1.0, 2]}
    """
    if isinstance(value, pathlib.PurePath):
        return value.as_posix()
    if isinstance(value, (list, tuple)):
        return [to_plain(v) for v in value]
    if isinstance(value, abc.Mapping):
        return {str(k): to_plain(v) for k, v in value.items()}
    if isinstance(value, np.generic):
        return value.item()
    return value


def type_name(ann: Any) -> str:
    """A short readable name of an annotation.

    Examples
    --------
    >>> type_name(float | list[float]), type_name(Literal["a", "b"]), type_name(pathlib.Path | None)
    ('float | list[float]', "'a' | 'b'", 'Path | None')
    >>> type_name(tuple[int, ...]), type_name(inspect.Parameter.empty)
    ('tuple[int, ...]', 'any')
    >>> type_name(npt.ArrayLike | None)
    'ArrayLike | None'
    
    """
    if _is_any(ann):
        return "any"
    if ann is _NONE or ann is None:
        return "None"
    if ann is Ellipsis:
        return "..."
    origin = get_origin(ann)
    args = get_args(ann)
    if origin is Literal:
        return " | ".join(repr(a) for a in args)
    if _is_union(ann):
        names = []
        array_like = set(get_args(npt.ArrayLike))
        if array_like <= set(args):  # numpy.typing.ArrayLike, spelled out by typing
            names.append("ArrayLike")
            args = tuple(a for a in args if a not in array_like)
        return " | ".join(names + [type_name(a) for a in args])
    if origin is not None:
        base = getattr(origin, "__name__", None) or str(origin).replace("typing.", "")
        if not args:
            return base
        return f"{base}[{', '.join(type_name(a) for a in args)}]"
    if isinstance(ann, type):
        return ann.__name__
    if isinstance(ann, str):
        return ann
    return str(ann).replace("typing.", "")


def _classes(ann: Any) -> list[Any] | None:
    """Concrete classes an annotation stands for, or None when unsure (Any, TypeVar, ...)."""
    if _is_any(ann):
        return None
    if ann is _NONE:
        return [_NONE]
    origin = get_origin(ann)
    if origin is Literal:
        return [type(a) for a in get_args(ann)]
    if _is_union(ann):
        out: list[Any] = []
        for a in get_args(ann):
            c = _classes(a)
            if c is None:
                return None
            out += c
        return out
    if origin is not None:
        return [origin] if isinstance(origin, type) else None
    if isinstance(ann, type) and not getattr(ann, "_is_protocol", False):
        return [ann]
    return None


_NUMERIC = {float: numbers.Real, int: numbers.Integral, complex: numbers.Complex}


def maybe_instance(value: Any, ann: Any) -> bool:
    """False only when ``value`` certainly does not fit ``ann``.

    Examples
    --------
    >>> maybe_instance(3, float), maybe_instance("x", float), maybe_instance("x", typing.Any)
    (True, False, True)
    """
    classes = _classes(ann)
    if classes is None:
        return True
    for c in classes:
        c = _NUMERIC.get(c, c)
        try:
            if isinstance(value, c):
                return True
        except TypeError:
            return True
    return False


def maybe_compatible(out_ann: Any, in_ann: Any) -> bool:
    """False only when an output annotated ``out_ann`` certainly cannot feed ``in_ann``.

    Lenient on unions: one member that fits is enough.

    Examples
    --------
    >>> maybe_compatible(int, float), maybe_compatible(str, float), maybe_compatible(bool | None, int)
    (True, False, True)
    """
    outs = _classes(out_ann)
    ins = _classes(in_ann)
    if outs is None or ins is None:
        return True
    for o in outs:
        for i in ins:
            i = _NUMERIC.get(i, i)
            try:
                if issubclass(o, i):
                    return True
                # a stand-in class (``stands_in = True``, e.g. quadnodes.nodes.Face for build123d's lazily
                # imported shapes) also feeds an input annotated with a class it stands for
                if getattr(o, "stands_in", False) is True and issubclass(i, o):
                    return True
            except TypeError:
                return True
    return False


def resolve_hints(func: Any) -> dict[str, Any]:
    """``typing.get_type_hints`` (string annotations resolved); raises NameError etc. as is."""
    return typing.get_type_hints(func)
