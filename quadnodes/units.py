"""Units of length: the names quadnodes accepts and lengths written with a unit.

Ground floor (standard library only). Every mesh carries a ``unit``
(:attr:`quadnodes.mesh.QuadMesh.unit`, ``"mm"`` by default); every file format
that can state a unit states it, and a length given as text (``"2 mm"``) is
converted to the mesh's unit where it is used.

Examples
--------
>>> to_unit(2.0, "mm", "m")
0.002
>>> parse_length("2 mm", "m")
0.002
>>> parse_length(1.5, "mm")  # a plain number is already in the target unit
1.5
"""

from __future__ import annotations

import re
from typing import Any

from .errors import InputError

__all__ = ["UNITS", "DEFAULT_UNIT", "check_unit", "to_unit", "parse_length", "is_length_text"]

#: Millimetres per unit, for every unit name quadnodes accepts.
UNITS: dict[str, float] = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4, "ft": 304.8}

#: The unit of meshes that do not say otherwise (the built-in surfaces are in millimetres).
DEFAULT_UNIT = "mm"

_LENGTH_RE = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([A-Za-z]+)\s*$")


def check_unit(unit: Any, name: str = "unit") -> str:
    """Return ``unit`` if it is one of :data:`UNITS`, else raise :class:`InputError`.

    Examples
    --------
    >>> check_unit("m")
    'm'
    """
    if isinstance(unit, str) and unit in UNITS:
        return unit
    raise InputError(f"{name}: expected one of {', '.join(map(repr, UNITS))}, got {unit!r}")


def to_unit(value: float, unit: str, target: str) -> float:
    """Convert a length ``value`` from ``unit`` to ``target``.

    Raises
    ------
    InputError
        On an unknown unit name.
    """
    return float(value) * UNITS[check_unit(unit)] / UNITS[check_unit(target, "target unit")]


def is_length_text(value: Any) -> bool:
    """True when ``value`` is text of the form ``"<number> <unit>"``.

    Examples
    --------
    >>> is_length_text("2 mm"), is_length_text("2"), is_length_text(2.0)
    (True, False, False)
    """
    return isinstance(value, str) and _LENGTH_RE.match(value) is not None


def parse_length(value: Any, target: str, name: str = "length") -> float:
    """A length in ``target`` units from a number (already in ``target``) or text such as ``"2 mm"``.

    Raises
    ------
    InputError
        On text that is not ``"<number> <unit>"``, an unknown unit, or a non-finite number.
    """
    check_unit(target, "target unit")
    if isinstance(value, str):
        m = _LENGTH_RE.match(value)
        if m is None:
            raise InputError(f"{name}: expected a number or a length such as '2 mm', got {value!r}")
        length = to_unit(float(m.group(1)), check_unit(m.group(2), f"{name} (unit of {value!r})"), target)
        if length != length or length in (float("inf"), float("-inf")):  # '1e400 mm': too large for a float
            raise InputError(f"{name}: {value!r} is not a finite length in {target}")
        return length
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{name}: expected a number or a length such as '2 mm', got {value!r}")
    v = float(value)
    if v != v or v in (float("inf"), float("-inf")):
        raise InputError(f"{name}: must be finite, got {value!r}")
    return v
