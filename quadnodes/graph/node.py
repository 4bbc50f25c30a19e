"""Node types: plain typed functions registered under a versioned name.

A node type wraps a function. Its positional parameters are the **input ports**
(any annotated type: meshes, reports, arrays); its keyword-only parameters are
the **settings** (JSON/TOML values with defaults, validated and coerced to their
annotation; a keyword-only parameter without a default is a required setting).
The function returns one value (one output) or, for several named outputs, a
tuple in the declared order or a dict keyed by output name.

The decorator returns the function unchanged, so it stays an ordinary function
usable from any script; the node type is attached as ``func.node_type``.

Examples
--------
>>> reg = Registry()
>>> @node("scale", outputs=("value",), registry=reg)
... def scale(x: float, *, factor: float = 2.0) -> float:
...     '''Multiply by a factor.'''
...     return x * factor
>>> scale(3.0)
6.0
>>> nt = reg.get("scale")
>>> nt.op, [p.name for p in nt.inputs], [s.name for s in nt.settings]
('scale@1', ['x'], ['factor'])
>>> nt.resolve_settings({"factor": 3}, node_id="s1")
{'factor': 3.0}
"""

from __future__ import annotations

import inspect
import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, TypeVar, get_args, get_origin

from ..errors import GraphError
from . import _types
from ._util import did_you_mean, graph_error, label
from .fingerprint import code_fingerprint

__all__ = [
    "NO_DEFAULT",
    "Range",
    "Port",
    "Setting",
    "NodeType",
    "Registry",
    "REGISTRY",
    "node",
    "describe",
    "first_sentence",
    "setting_docs",
]

F = TypeVar("F", bound=Callable[..., Any])

#: Marks a port or setting without a default (a required one).
NO_DEFAULT: Any = inspect.Parameter.empty

_NAME_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_OP_RE = re.compile(r"(?P<name>[A-Za-z_][A-Za-z0-9_]*)(?:@(?P<version>[0-9]+))?\Z")
_RESERVED = {"id"}  # Graph.add(op, *inputs, id=..., **settings)


@dataclass(frozen=True)
class Range:
    """The allowed values of a numeric setting (each number of a list setting), declared with ``@node(ranges=...)``.

    ``min``/``max`` are bounds (None: unbounded); ``min_open``/``max_open`` make
    them strict. NaN and ±inf are never in range. The same object feeds the load-time check,
    ``quadnodes nodes`` and editors' sliders (:func:`describe`).

    Examples
    --------
    >>> r = Range(min=0, max=1, min_open=True)
    >>> str(r), r.problem(0.5), r.problem(0)
    ('> 0 and <= 1', None, '0 is out of range (must be > 0 and <= 1)')
    >>> str(Range(min=1)), Range(min=1).problem([3, -1])
    ('>= 1', '[1]: -1 is out of range (must be >= 1)')
    """

    min: float | None = None
    max: float | None = None
    min_open: bool = False
    max_open: bool = False

    def __str__(self) -> str:
        parts = []
        if self.min is not None:
            parts.append(f"{'>' if self.min_open else '>='} {self.min:g}")
        if self.max is not None:
            parts.append(f"{'<' if self.max_open else '<='} {self.max:g}")
        return " and ".join(parts) or "any number"

    def _out(self, v: float) -> bool:
        if v != v or v in (math.inf, -math.inf):  # NaN, or infinite: no bound admits them
            return True
        if self.min is not None and (v <= self.min if self.min_open else v < self.min):
            return True
        return self.max is not None and (v >= self.max if self.max_open else v > self.max)

    def problem(self, value: Any, where: str = "") -> str | None:
        """A message when ``value`` (a number, or numbers nested in lists) is out of range, else None."""
        if isinstance(value, bool) or value is None:
            return None
        if isinstance(value, (int, float)):
            return f"{where + ': ' if where else ''}{value!r} is out of range (must be {self})" if self._out(
                value) else None
        if isinstance(value, (list, tuple)):
            for i, v in enumerate(value):
                msg = self.problem(v, f"{where}[{i}]")
                if msg:
                    return msg
        return None

    def to_dict(self) -> dict[str, Any]:
        """``{"min", "max", "min_open", "max_open", "text"}`` (JSON-ready, for editors' sliders)."""
        return {"min": self.min, "max": self.max, "min_open": self.min_open, "max_open": self.max_open,
                "text": str(self)}


def _non_finite(value: Any, where: str = "") -> str | None:
    """A message when ``value`` (a float, or floats nested in lists) is NaN or infinite, else None.

    Examples
    --------
    >>> _non_finite([1.0, float("inf")]), _non_finite("2 mm"), _non_finite(0.5)
    ('[1]: inf is not a finite number', None, None)
    """
    if isinstance(value, float):
        return None if math.isfinite(value) else f"{where + ': ' if where else ''}{value!r} is not a finite number"
    if isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            msg = _non_finite(v, f"{where}[{i}]")
            if msg:
                return msg
    return None


@dataclass(frozen=True)
class Port:
    """An input or output port: its name, annotation and (inputs only) default."""

    name: str
    annotation: Any = NO_DEFAULT
    default: Any = NO_DEFAULT

    @property
    def required(self) -> bool:
        """An input port without a default must be connected."""
        return self.default is NO_DEFAULT

    @property
    def type_name(self) -> str:
        return _types.type_name(self.annotation)


@dataclass(frozen=True)
class Setting:
    """A keyword-only parameter: a JSON/TOML value, coerced to ``annotation``.

    ``file`` is ``"read"`` for paths the node reads (their bytes enter the cache
    key), ``"write"`` for paths it writes (checked before reusing a cached result).
    ``range`` bounds a numeric setting; ``template`` marks a text setting whose
    ``{node.setting}`` fields the runner fills in (see :func:`node`).
    """

    name: str
    annotation: Any = NO_DEFAULT
    default: Any = NO_DEFAULT
    file: str | None = None
    range: Range | None = None
    template: bool = False

    @property
    def required(self) -> bool:
        return self.default is NO_DEFAULT

    @property
    def type_name(self) -> str:
        return _types.type_name(self.annotation)


@dataclass(frozen=True, eq=False)
class NodeType:
    """A registered node function with its ports and settings (made by :func:`node`)."""

    name: str
    version: int
    func: Callable[..., Any]
    inputs: tuple[Port, ...]
    settings: tuple[Setting, ...]
    outputs: tuple[Port, ...]
    doc: str = ""
    code_fingerprint: str | None = None
    _input_index: dict[str, Port] = field(default_factory=dict, repr=False)
    _setting_index: dict[str, Setting] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        self._input_index.update({p.name: p for p in self.inputs})
        self._setting_index.update({s.name: s for s in self.settings})

    @property
    def op(self) -> str:
        """``"name@version"``."""
        return f"{self.name}@{self.version}"

    @property
    def output_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.outputs)

    @property
    def reads(self) -> tuple[str, ...]:
        """Settings naming files the node reads."""
        return tuple(s.name for s in self.settings if s.file == "read")

    @property
    def writes(self) -> tuple[str, ...]:
        """Settings naming files the node writes."""
        return tuple(s.name for s in self.settings if s.file == "write")

    def input(self, name: str) -> Port | None:
        return self._input_index.get(name)

    def output(self, name: str) -> Port | None:
        for p in self.outputs:
            if p.name == name:
                return p
        return None

    def setting(self, name: str) -> Setting | None:
        return self._setting_index.get(name)

    def coerce_setting(self, name: str, value: Any, *, node_id: str) -> Any:
        """Check one setting and convert it to its annotated type.

        Raises
        ------
        GraphError
            Naming the node and the setting: unknown name (with the closest valid
            one) or a value of the wrong type.
        """
        s = self._setting_index.get(name)
        if s is None:
            where = label(node_id, self.op)
            if name in self._input_index:
                raise graph_error(
                    f"{where}: {name!r} is an input port, not a setting; connect it to another node's output",
                    node_id=node_id,
                )
            renamed = getattr(self.func, "renamed_settings", {})
            if name in renamed:
                raise graph_error(f"{where}: setting {name!r} was renamed: use {renamed[name]}", node_id=node_id)
            hint = did_you_mean(name, self._setting_index, kind="settings")
            raise graph_error(f"{where}: unknown setting {name!r}{hint}", node_id=node_id)
        try:
            coerced = _types.coerce(value, s.annotation)
        except _types.Mismatch as exc:
            raise graph_error(
                f"{label(node_id, self.op)}: setting {name!r}{exc.where}: {exc.message}", node_id=node_id
            ) from None
        # out of its range, or inf/nan (settings without a range too: no setting means anything by inf or nan)
        problem = (s.range.problem(coerced) if s.range is not None else None) or _non_finite(coerced)
        if problem:
            sep = "" if problem.startswith("[") else ": "
            err = graph_error(f"{label(node_id, self.op)}: setting {name!r}{sep}{problem}", node_id=node_id)
            err.out_of_range = True  # type: ignore[attr-defined]  (a sweep keeps such a variant as an error row)
            raise err
        return coerced

    def resolve_settings(self, params: Mapping[str, Any], *, node_id: str) -> dict[str, Any]:
        """All settings of a node: ``params`` coerced, defaults filled in.

        Raises
        ------
        GraphError
            On an unknown or wrong-typed setting, or a missing required one.

        Examples
        --------
        >>> reg = Registry()
        >>> @node("f", registry=reg)
        ... def f(x: float, *, n: int, mode: str = "a") -> float:
        ...     return x
        >>> reg.get("f").resolve_settings({"n": 2.0}, node_id="f1")
        {'n': 2, 'mode': 'a'}
        >>> reg.get("f").resolve_settings({}, node_id="f1")
        Traceback (most recent call last):
        ...
        quadnodes.errors.GraphError: node 'f1' (f@1): missing required setting 'n' (int)
        """
        given = {k: self.coerce_setting(k, v, node_id=node_id) for k, v in params.items()}
        out: dict[str, Any] = {}
        for s in self.settings:
            if s.name in given:
                out[s.name] = given[s.name]
            elif s.required:
                raise graph_error(
                    f"{label(node_id, self.op)}: missing required setting {s.name!r} ({s.type_name})",
                    node_id=node_id,
                )
            else:
                out[s.name] = s.default
        return out

    def call(self, inputs: Mapping[str, Any], settings: Mapping[str, Any]) -> dict[str, Any]:
        """Run the function and return its outputs by name.

        Unconnected optional inputs get their defaults. Exceptions of the function
        propagate unchanged (the runner wraps them in ``NodeError``).

        Raises
        ------
        TypeError
            If a multi-output node returns neither a tuple of the right length nor
            a dict with exactly the output names.
        """
        args = [inputs[p.name] if p.name in inputs else p.default for p in self.inputs]
        result = self.func(*args, **settings)
        names = self.output_names
        if len(names) == 1:
            return {names[0]: result}
        if isinstance(result, Mapping):
            keys = set(result)
            if keys != set(names):
                missing = [n for n in names if n not in keys]
                extra = sorted(str(k) for k in keys - set(names))
                raise TypeError(
                    f"returned a dict with keys {sorted(map(str, keys))}; expected {list(names)}"
                    + (f" (missing {missing})" if missing else "")
                    + (f" (unexpected {extra})" if extra else "")
                )
            return {n: result[n] for n in names}
        if isinstance(result, (tuple, list)) and len(result) == len(names):
            return dict(zip(names, result))
        raise TypeError(
            f"returned {type(result).__name__}; expected a tuple of {len(names)} values "
            f"({', '.join(names)}) or a dict with those keys"
        )

    def __repr__(self) -> str:
        return f"NodeType({self.op!r})"


class Registry:
    """Node types by name and version.

    ``get("fair")`` gives the latest version, ``get("fair@1")`` exactly that one.

    Examples
    --------
    >>> reg = Registry()
    >>> @node("inc", version=1, registry=reg)
    ... def inc1(x: float) -> float:
    ...     return x + 1
    >>> @node("inc", version=2, registry=reg)
    ... def inc2(x: float, *, step: float = 1.0) -> float:
    ...     return x + step
    >>> reg.get("inc").op, reg.get("inc@1").op, reg.ops()
    ('inc@2', 'inc@1', ['inc@1', 'inc@2'])
    >>> reg.get("inx")
    Traceback (most recent call last):
    ...
    quadnodes.errors.GraphError: unknown op 'inx'; did you mean 'inc'? (ops: inc)
    """

    def __init__(self) -> None:
        self._types: dict[str, dict[int, NodeType]] = {}

    def register(self, node_type: NodeType) -> NodeType:
        """Add a node type.

        Registering the same ``name@version`` again is allowed only for the same
        function re-imported (same module and qualified name, e.g. a module
        reload); it then replaces the old one.

        Raises
        ------
        GraphError
            If another function already holds ``name@version``.
        """
        versions = self._types.setdefault(node_type.name, {})
        old = versions.get(node_type.version)
        if old is not None:
            same = (
                getattr(old.func, "__module__", None) == getattr(node_type.func, "__module__", None)
                and getattr(old.func, "__qualname__", None) == getattr(node_type.func, "__qualname__", None)
            )
            if not same:
                raise GraphError(
                    f"op {node_type.op!r} is already registered by "
                    f"{old.func.__module__}.{old.func.__qualname__}; pick another name or version"
                )
        versions[node_type.version] = node_type
        return node_type

    def get(self, op: str | Callable[..., Any], *, node_id: str | None = None) -> NodeType:
        """The node type for ``"name"`` (latest version), ``"name@version"`` or a decorated function.

        Raises
        ------
        GraphError
            For an unknown name or version (with the closest known name), or a
            malformed op string. Names ``node_id`` when given.
        """
        prefix = f"{label(node_id)}: " if node_id is not None else ""
        if callable(op) and not isinstance(op, str):
            nt = getattr(op, "node_type", None)
            if not isinstance(nt, NodeType):
                raise graph_error(f"{prefix}{op!r} is not a node function (decorate it with @node)", node_id=node_id)
            if self._types.get(nt.name, {}).get(nt.version) is not nt:
                raise graph_error(f"{prefix}op {nt.op!r} is not registered in this graph's registry", node_id=node_id)
            return nt
        if not isinstance(op, str):
            raise graph_error(f"{prefix}op: expected a string such as 'fair' or 'fair@1', got {op!r}", node_id=node_id)
        m = _OP_RE.match(op.strip())
        if m is None:
            raise graph_error(f"{prefix}op {op!r}: expected 'name' or 'name@version'", node_id=node_id)
        name = m.group("name")
        versions = self._types.get(name)
        if not versions:
            hint = did_you_mean(name, self._types, kind="ops")
            raise graph_error(f"{prefix}unknown op {op!r}{hint}", node_id=node_id)
        if m.group("version") is None:
            return versions[max(versions)]
        v = int(m.group("version"))
        if v not in versions:
            known = ", ".join(str(k) for k in sorted(versions))
            raise graph_error(f"{prefix}unknown version {v} of op {name!r} (registered: {known})", node_id=node_id)
        return versions[v]

    def ops(self) -> list[str]:
        """Every registered ``name@version``, sorted."""
        return [f"{n}@{v}" for n in sorted(self._types) for v in sorted(self._types[n])]

    def latest(self) -> list[NodeType]:
        """The latest version of every name, sorted by name."""
        return [vs[max(vs)] for n, vs in sorted(self._types.items()) if vs]

    def unregister(self, op: str) -> None:
        """Remove ``name@version`` (or every version of ``name``)."""
        m = _OP_RE.match(op)
        if m is None or m.group("name") not in self._types:
            return
        if m.group("version") is None:
            del self._types[m.group("name")]
        else:
            self._types[m.group("name")].pop(int(m.group("version")), None)

    def __contains__(self, op: object) -> bool:
        try:
            self.get(op)  # type: ignore[arg-type]
        except GraphError:
            return False
        return True

    def __len__(self) -> int:
        return sum(len(v) for v in self._types.values())

    def __repr__(self) -> str:
        return f"Registry({self.ops()})"


#: The registry :func:`node` and :class:`~quadnodes.graph.Graph` use by default.
REGISTRY = Registry()


def _output_annotations(ret: Any, n: int) -> list[Any]:
    if n == 1:
        return [ret]
    if get_origin(ret) is tuple:
        args = get_args(ret)
        if len(args) == n and Ellipsis not in args:
            return list(args)
    return [NO_DEFAULT] * n


def node(
    name: str,
    *,
    version: int = 1,
    outputs: Sequence[str] | Mapping[str, Any] = ("out",),
    reads: Sequence[str] = (),
    writes: Sequence[str] = (),
    ranges: Mapping[str, Range] | None = None,
    templates: Sequence[str] = (),
    registry: Registry | None = None,
) -> Callable[[F], F]:
    """Register a function as a node type ``name@version``.

    Parameters
    ----------
    name : str
        A Python identifier; graph files refer to ``name`` (latest) or ``name@version``.
    version : int
        Bump it when the node's meaning changes, so old graph files can pin the old one.
    outputs : sequence of str, or mapping name -> annotation
        Output port names, in the order of the returned tuple. Their types come
        from the return annotation (``tuple[QuadMesh, FairingReport]``) unless
        given as a mapping.
    reads : sequence of str
        Settings that name input files (str, Path, a list of them, or None):
        their bytes enter the cache key.
    writes : sequence of str
        Settings that name output files: a cached result is reused only while
        those files still hold what the node wrote. Their paths must stay inside
        the run's output folder (:mod:`quadnodes.graph.paths`).
    ranges : mapping setting name -> Range, optional
        Allowed values of numeric settings (every number of a list setting),
        checked whenever a setting is given (graph file load, ``--set``,
        :meth:`Graph.add`), so a bad value is refused before any node runs.
    templates : sequence of str
        Text settings (str or list of str) in which ``{node.setting}`` is replaced
        by the resolved value of another node's setting when the graph runs, e.g.
        ``titles = ["faired, {fair.iterations} iterations"]`` (``{{`` for a brace).
    registry : Registry, optional
        Defaults to :data:`REGISTRY`.

    Returns
    -------
    callable
        A decorator returning the function unchanged, with ``func.node_type`` set.

    Raises
    ------
    GraphError
        On a malformed name, ``*args``/``**kwargs`` parameters, a parameter named
        ``id``, a setting annotation that is not a JSON/TOML value type, a default
        that does not fit its annotation, unresolvable annotations, or ``reads`` /
        ``writes`` naming something that is not a setting.

    Examples
    --------
    >>> reg = Registry()
    >>> @node("split", outputs=("lo", "hi"), registry=reg)
    ... def split(x: float, *, at: float = 0.5) -> tuple[float, float]:
    ...     return min(x, at), max(x, at)
    >>> reg.get("split").call({"x": 0.2}, {"at": 0.5})
    {'lo': 0.2, 'hi': 0.5}
    >>> @node("bad", registry=reg)
    ... def bad(x: float, *, n: int = "three") -> float:
    ...     return x
    Traceback (most recent call last):
    ...
    quadnodes.errors.GraphError: op 'bad@1': setting 'n': default 'three' does not fit int: expected int, got str 'three'
    """
    reg = REGISTRY if registry is None else registry

    def decorate(func: F) -> F:
        nt = _make_node_type(func, name, version, outputs, reads, writes, ranges or {}, templates)
        reg.register(nt)
        func.node_type = nt  # type: ignore[attr-defined]
        return func

    return decorate


def _make_node_type(
    func: Callable[..., Any],
    name: str,
    version: int,
    outputs: Sequence[str] | Mapping[str, Any],
    reads: Sequence[str],
    writes: Sequence[str],
    ranges: Mapping[str, Range] = MappingProxyType({}),
    templates: Sequence[str] = (),
) -> NodeType:
    if not isinstance(name, str) or not _NAME_RE.match(name):
        raise GraphError(f"node name {name!r}: expected a Python identifier")
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise GraphError(f"op {name!r}: version must be a positive int, got {version!r}")
    op = f"{name}@{version}"
    if isinstance(reads, str) or isinstance(writes, str):
        raise GraphError(f"op {op!r}: reads/writes must be sequences of setting names, not a string")
    try:
        hints = _types.resolve_hints(func)
    except Exception as exc:  # NameError for an unresolvable string annotation, etc.
        raise GraphError(f"op {op!r}: cannot resolve the annotations of {func.__qualname__}: {exc}") from exc
    sig = inspect.signature(func)
    inputs: list[Port] = []
    settings: list[Setting] = []
    for p in sig.parameters.values():
        ann = hints.get(p.name, NO_DEFAULT)
        if p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD):
            raise GraphError(f"op {op!r}: *args/**kwargs parameter {p.name!r} is not allowed; name every port")
        if p.name in _RESERVED:
            raise GraphError(f"op {op!r}: parameter name {p.name!r} is reserved (Graph.add takes id=)")
        if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD):
            inputs.append(Port(p.name, ann, p.default))
            continue
        reason = _types.unsupported_setting_reason(ann)
        if reason:
            raise GraphError(
                f"op {op!r}: setting {p.name!r}: {reason}; make it an input port (a positional parameter)"
            )
        default = p.default
        if default is not NO_DEFAULT:
            try:
                default = _types.coerce(default, ann)
            except _types.Mismatch as exc:
                raise GraphError(
                    f"op {op!r}: setting {p.name!r}: default {p.default!r} does not fit "
                    f"{_types.type_name(ann)}: {exc.message}"
                ) from None
        file = "read" if p.name in reads else "write" if p.name in writes else None
        rng = ranges.get(p.name)
        if rng is not None and not isinstance(rng, Range):
            raise GraphError(f"op {op!r}: ranges[{p.name!r}] must be a Range, got {rng!r}")
        if rng is not None and default is not NO_DEFAULT and rng.problem(default):
            raise GraphError(f"op {op!r}: setting {p.name!r}: default {rng.problem(default)}")
        settings.append(Setting(p.name, ann, default, file, rng, p.name in templates))
    setting_names = {s.name for s in settings}
    if isinstance(templates, str):
        raise GraphError(f"op {op!r}: templates must be a sequence of setting names, not a string")
    for kind, names in (("reads", reads), ("writes", writes), ("ranges", list(ranges)), ("templates", templates)):
        for n in names:
            if n not in setting_names:
                hint = did_you_mean(n, setting_names, kind="settings")
                raise GraphError(f"op {op!r}: {kind} names {n!r}, which is not a setting{hint}")
    overlap = set(reads) & set(writes)
    if overlap:
        raise GraphError(f"op {op!r}: {sorted(overlap)} cannot be both read and written")
    if isinstance(outputs, str):
        outputs = (outputs,)
    if isinstance(outputs, Mapping):
        out_ports = tuple(Port(str(k), v) for k, v in outputs.items())
    else:
        names = list(outputs)
        anns = _output_annotations(hints.get("return", NO_DEFAULT), len(names))
        out_ports = tuple(Port(n, a) for n, a in zip(names, anns))
    if not out_ports:
        raise GraphError(f"op {op!r}: at least one output is needed")
    seen: set[str] = set()
    for p in out_ports:
        if not _NAME_RE.match(p.name) or p.name in seen:
            raise GraphError(f"op {op!r}: output name {p.name!r} is not a unique Python identifier")
        seen.add(p.name)
    return NodeType(
        name=name,
        version=version,
        func=func,
        inputs=tuple(inputs),
        settings=tuple(settings),
        outputs=out_ports,
        doc=inspect.getdoc(func) or "",
        code_fingerprint=code_fingerprint(func),
    )


def describe(op: str | NodeType, *, registry: Registry | None = None) -> dict[str, Any]:
    """What ``quadnodes nodes`` prints about a node type, as JSON-ready data.

    Parameters
    ----------
    op : str or NodeType
        ``"name"`` (latest version) or ``"name@version"``.
    registry : Registry, optional
        Defaults to :data:`REGISTRY`.

    Returns
    -------
    dict
        ``op``, ``name``, ``version``, ``versions`` (all registered), ``summary``
        (the docstring's first whole sentence), ``doc``, ``inputs`` / ``settings``
        / ``outputs`` as lists of dicts with ``name`` and ``type``; inputs add
        ``required``, settings add ``required``, ``default`` (JSON form, absent
        when required), ``file`` (``"read"``, ``"write"`` or None), ``range``
        (:meth:`Range.to_dict` or None) and ``doc`` (one line of meaning from the
        docstring's ``Parameters`` section, ``""`` when undocumented).

    Raises
    ------
    GraphError
        For an unknown op.

    Examples
    --------
    >>> from typing import Literal
    >>> reg = Registry()
    >>> @node("smooth", outputs=("mesh",), registry=reg)
    ... def smooth(mesh: object, *, rounds: int = 1,
    ...            mode: Literal["uniform", "cotan"] = "uniform") -> object:
    ...     '''Smooth a mesh.'''
    ...     return mesh
    >>> d = describe("smooth", registry=reg)
    >>> d["op"], d["summary"], d["inputs"]
    ('smooth@1', 'Smooth a mesh.', [{'name': 'mesh', 'type': 'any', 'required': True}])
    >>> d["settings"][1]
    {'name': 'mode', 'type': "'uniform' | 'cotan'", 'required': False, 'file': None, 'default': 'uniform', 'range': None, 'doc': ''}
    """
    reg = REGISTRY if registry is None else registry
    nt = op if isinstance(op, NodeType) else reg.get(op)
    meanings = setting_docs(nt.doc)
    settings = []
    for s in nt.settings:
        d: dict[str, Any] = {"name": s.name, "type": s.type_name, "required": s.required, "file": s.file}
        if not s.required:
            d["default"] = _types.to_plain(s.default)
        d["range"] = s.range.to_dict() if s.range is not None else None
        d["doc"] = meanings.get(s.name, "")
        settings.append(d)
    versions = sorted(int(o.split("@")[1]) for o in reg.ops() if o.split("@")[0] == nt.name) or [nt.version]
    return {
        "op": nt.op,
        "name": nt.name,
        "version": nt.version,
        "versions": versions,
        "summary": first_sentence(nt.doc),
        "doc": nt.doc,
        "inputs": [{"name": p.name, "type": p.type_name, "required": p.required} for p in nt.inputs],
        "settings": settings,
        "outputs": [{"name": p.name, "type": p.type_name} for p in nt.outputs],
    }


_SENTENCE_END = re.compile(r"(?<=[.!?])\s+(?=[A-Z(\"'`])")
_SECTION = re.compile(r"^(\w[\w ]*)\n-{3,}$", re.M)


def first_sentence(doc: str) -> str:
    """The first whole sentence of a docstring's first paragraph (lines joined), never cut mid-sentence.

    Examples
    --------
    >>> first_sentence("Smooth a mesh\\nin place. Then more.\\n\\nDetails.")
    'Smooth a mesh in place.'
    >>> first_sentence("Fair lines (eq. 32) e.g. on a grid")
    'Fair lines (eq. 32) e.g. on a grid'
    """
    para = " ".join(line.strip() for line in doc.strip().split("\n\n", 1)[0].splitlines()).strip()
    return _SENTENCE_END.split(para, maxsplit=1)[0] if para else ""


def setting_docs(doc: str) -> dict[str, str]:
    """One line of meaning per parameter of a NumPy ``Parameters`` section: its first sentence.

    Several names may share an entry (``lam, mu : float``).

    Examples
    --------
    >>> setting_docs("Do it.\\n\\nParameters\\n----------\\niterations : int\\n"
    ...              "    Rounds of fairing. Each one re-detects.\\nlam, mu : float\\n    Step sizes.\\n")
    {'iterations': 'Rounds of fairing.', 'lam': 'Step sizes.', 'mu': 'Step sizes.'}
    """
    text = inspect.cleandoc(doc or "")
    m = re.search(r"^Parameters\n-{3,}\n", text, re.M)
    if m is None:
        return {}
    body = text[m.end():]
    nxt = _SECTION.search(body)
    if nxt is not None:
        body = body[: nxt.start()]
    out: dict[str, str] = {}
    names: list[str] = []
    desc: list[str] = []

    def flush() -> None:
        sentence = first_sentence(" ".join(desc))
        for n in names:
            out[n] = sentence

    for line in body.splitlines():
        if line and not line[0].isspace():
            flush()
            names = [n.strip() for n in line.split(":", 1)[0].split(",") if n.strip()]
            desc = []
        elif line.strip():
            desc.append(line.strip())
    flush()
    return out
