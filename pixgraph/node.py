"""The node contract: a node is one class that declares its ports and params and
subclasses ``Node``, whose hooks it overrides.

    from pixgraph.node import Node, node, param, port
    from pixgraph_nodes import types as T

    @node("pixgraph.GaussianBlur", version=1)
    class GaussianBlur(Node):
        '''Gaussian blur of an image on the OpenCL device.'''
        class Inputs:
            image: T.Image = port(doc="image to blur")
        class Params:
            sigma: float = param(2.0, min=0.0, max=100.0, unit="px", doc="standard deviation")
        class Outputs:
            image: T.Image = port(doc="blurred image")

        def compute(self, ctx, inputs, params):
            return {"image": blur(ctx.device, inputs.image, params.sigma)}

``Node`` declares every hook the engine calls, each with one signature and a
documented default (read its docstrings); ``@node`` reads which hooks a class
overrides into ``spec.hooks``, and refuses an override whose signature differs
from the base's (a ``staticmethod`` hook, a missing argument). A class that does
not subclass ``Node`` gets it as a base from ``@node``.

``compute`` receives ``inputs`` and ``params`` as read-only attribute namespaces
(``inputs.image``, ``params.sigma``; an absent optional input is ``None``) and
returns a dict with one value per output name. ``ctx`` gives the OpenCL device,
progress and cancellation (see ``pixgraph.engine.NodeContext``).

Param value types: ``float``, ``int``, ``bool``, ``str`` (optionally with
``choices``), ``list[float]`` (fixed ``length`` optional) and ``Path`` (a file;
its *content* is part of the cache key, so editing the file reruns the node).
A ``Path`` param with default ``None`` is required; ``param(None, writes=True)``
declares a file the node writes (its path, not its content, is hashed).

Working resolution (``Session.run(..., scale=s)``): params declared with
``unit="px"`` reach ``compute`` multiplied by ``s``; a node that makes images of
its own size from files (a loader), or whose result depends on ``s`` otherwise,
sets ``uses_scale = True`` and reads ``ctx.scale`` (see ``Node``).
"""
from __future__ import annotations

import dataclasses
import functools
import math
import pathlib
import sys
import typing
from types import MappingProxyType
import inspect
from typing import Any, Callable, ClassVar, Collection

from . import types as T
from .errors import InputError  # noqa: F401 (nodes import it from here)

_MISSING = object()

PARAM_KINDS = ("float", "int", "bool", "str", "floats", "path")


class ParamError(ValueError):
    """A param value that does not fit its declaration. ``param`` names it."""

    def __init__(self, param: str, message: str):
        super().__init__(f"param {param!r}: {message}")
        self.param = param
        self.message = message


def _huge_int(value: Any) -> int:
    """The bits of the first integer beyond a float's range in ``value`` (nested lists,
    tuples and dicts), else 0: ``float()`` of one raises OverflowError, ``repr()`` of one
    over 4300 digits ValueError (a ``--set``, a manifest cell or a JSON edit of
    ``0xfff...`` stopped a run with exit 1, and was a 500 from the server)."""
    stack = [value]
    while stack:
        v = stack.pop()
        if isinstance(v, int) and not isinstance(v, bool) and abs(v) > sys.float_info.max:
            return v.bit_length()
        if isinstance(v, (list, tuple)):
            stack.extend(v)
        elif isinstance(v, dict):
            stack.extend(v.values())
    return 0


@dataclasses.dataclass(frozen=True)
class ParamSpec:
    """Declaration of one param: kind, default, range or choices, unit and doc."""

    name: str
    kind: str
    default: Any
    min: float | None = None
    max: float | None = None
    choices: tuple[str, ...] | None = None
    length: int | None = None
    unit: str = ""
    doc: str = ""
    #: False for params that cannot change the result (e.g. a progress interval)
    cache: bool = True
    #: for kind "path": True when the node *writes* this file (it need not exist,
    #: and its path, not its content, is part of the cache key)
    writes: bool = False

    @property
    def required(self) -> bool:
        """A param with no default (``param(None)`` on a path) must be set in the graph."""
        return self.default is None

    def coerce(self, value: Any) -> Any:
        """Check ``value`` against this declaration and return it in canonical form.

        Raises ``ParamError`` naming the param on a wrong type, a value out of
        range, or a choice that is not offered.
        """
        k = self.kind
        if value is None and self.required:
            raise ParamError(self.name, "is required and was not set")
        bits = _huge_int(value)
        if bits:
            raise ParamError(self.name, f"an integer of {bits} bits is beyond a float's range (about 1.8e308)")
        if k == "bool":
            if not isinstance(value, bool):
                raise ParamError(self.name, f"expected true or false, got {value!r}")
            return value
        if k == "int":
            if isinstance(value, bool) or not isinstance(value, int):
                if isinstance(value, float) and value.is_integer():
                    value = int(value)
                else:
                    raise ParamError(self.name, f"expected an integer, got {value!r}")
            self._check_range(value)
            return int(value)
        if k == "float":
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ParamError(self.name, f"expected a number, got {value!r}")
            value = float(value)
            if not math.isfinite(value):
                raise ParamError(self.name, f"expected a finite number, got {value!r}")
            self._check_range(value)
            return value
        if k == "str":
            if not isinstance(value, str):
                raise ParamError(self.name, f"expected a string, got {value!r}")
            if self.choices is not None and value not in self.choices:
                raise ParamError(self.name, f"{value!r} is not one of {', '.join(self.choices)}")
            return value
        if k == "floats":
            if not isinstance(value, (list, tuple)):
                raise ParamError(self.name, f"expected a list of numbers, got {value!r}")
            if self.length is not None and len(value) != self.length:
                raise ParamError(self.name, f"expected {self.length} numbers, got {len(value)}")
            out = []
            for v in value:
                if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                    raise ParamError(self.name, f"expected finite numbers, got {v!r}")
                self._check_range(float(v))
                out.append(float(v))
            return tuple(out)
        if k == "path":
            if not isinstance(value, (str, pathlib.PurePath)) or str(value) == "":
                raise ParamError(self.name, f"expected a file path, got {value!r}")
            return str(value)
        raise AssertionError(k)

    def _check_range(self, value: float) -> None:
        if self.min is not None and value < self.min:
            raise ParamError(self.name, f"{value} is below the minimum {self.min}")
        if self.max is not None and value > self.max:
            raise ParamError(self.name, f"{value} is above the maximum {self.max}")

    def json_schema(self) -> dict:
        """JSON Schema fragment for this param's value."""
        k = self.kind
        s: dict[str, Any]
        if k == "bool":
            s = {"type": "boolean"}
        elif k == "int":
            s = {"type": "integer"}
        elif k == "float":
            s = {"type": "number"}
        elif k == "str":
            s = {"type": "string"}
            if self.choices is not None:
                s["enum"] = list(self.choices)
        elif k == "floats":
            s = {"type": "array", "items": {"type": "number"}}
            if self.length is not None:
                s["minItems"] = s["maxItems"] = self.length
        else:
            s = {"type": "string", "minLength": 1}
        if k in ("int", "float"):
            if self.min is not None:
                s["minimum"] = self.min
            if self.max is not None:
                s["maximum"] = self.max
        if k == "floats":
            if self.min is not None:
                s["items"]["minimum"] = self.min
            if self.max is not None:
                s["items"]["maximum"] = self.max
        desc = self.doc + (f" [{self.unit}]" if self.unit else "")
        if desc:
            s["description"] = desc
        if not self.required:
            s["default"] = list(self.default) if isinstance(self.default, tuple) else self.default
        return s


@dataclasses.dataclass(frozen=True)
class PortSpec:
    """Declaration of one input or output port."""

    name: str
    type: type[T.PortType]
    optional: bool = False
    doc: str = ""


@dataclasses.dataclass(frozen=True)
class _ParamDecl:
    default: Any
    min: float | None
    max: float | None
    choices: tuple[str, ...] | None
    length: int | None
    unit: str
    doc: str
    cache: bool
    writes: bool


@dataclasses.dataclass(frozen=True)
class _PortDecl:
    optional: bool
    doc: str


def param(default: Any = _MISSING, *, min: float | None = None, max: float | None = None,
          choices: typing.Sequence[str] | None = None, length: int | None = None,
          unit: str = "", doc: str = "", cache: bool = True, writes: bool = False) -> Any:
    """Declare a param inside a node's ``Params`` class; the annotation gives its kind.

    A ``Path`` param may have default ``None``: it is then required in every graph.
    ``writes=True`` marks a path the node writes (an output file).
    """
    if default is _MISSING:
        raise TypeError("param() needs a default")
    return _ParamDecl(default, min, max, tuple(choices) if choices is not None else None,
                      length, unit, doc, cache, writes)


def port(*, optional: bool = False, doc: str = "") -> Any:
    """Declare an input or output inside a node's ``Inputs``/``Outputs`` class."""
    return _PortDecl(optional, doc)


def _param_kind(annotation: Any, owner: str, name: str) -> str:
    if annotation in (float, "float"):
        return "float"
    if annotation in (int, "int"):
        return "int"
    if annotation in (bool, "bool"):
        return "bool"
    if annotation in (str, "str"):
        return "str"
    if annotation in (pathlib.Path, "Path", "pathlib.Path"):
        return "path"
    if typing.get_origin(annotation) in (list, tuple) or annotation in ("list[float]", "tuple[float, ...]"):
        return "floats"
    raise TypeError(f"{owner}: param {name!r} has unsupported type {annotation!r}")


def _annotations(cls: type | None) -> dict[str, Any]:
    """Annotations of an ``Inputs``/``Params``/``Outputs`` class and its bases (a
    node pack may share a block of ports: ``class Inputs(ShadowInputs)``), bases
    first, each resolved in its own module (so ``mask: T.Mask`` works with or
    without ``from __future__ import annotations``)."""
    if cls is None:
        return {}
    import sys
    out: dict[str, Any] = {}
    for klass in reversed(cls.__mro__):
        own = klass.__dict__.get("__annotations__")
        if not own:
            continue
        module = sys.modules.get(klass.__module__)
        globalns = dict(vars(module)) if module else {}
        globalns.setdefault("T", T)
        globalns.setdefault("Path", pathlib.Path)
        for name, ann in own.items():
            if isinstance(ann, str):
                try:
                    ann = eval(ann, globalns, dict(vars(klass)))  # noqa: S307 - the node's own source text
                except Exception:  # noqa: BLE001 - reported as a bad annotation by the caller
                    pass
            out[name] = ann
    return out


@dataclasses.dataclass(frozen=True)
class NodeSpec:
    """Everything the engine knows about a node type, read from its declaration."""

    type_id: str
    version: int
    impl_version: str
    doc: str
    inputs: tuple[PortSpec, ...]
    outputs: tuple[PortSpec, ...]
    params: tuple[ParamSpec, ...]
    cls: type
    #: where the class came from, for error messages ("module:Class")
    source: str
    #: True for sinks that write files: they run whenever requested, never from cache
    side_effects: bool = False
    #: the hooks of ``Node`` this class overrides (``"infer"``, ``"bind"``, ...)
    hooks: frozenset = frozenset()
    #: False: results stay in the memory cache only (``Node.disk_cache``)
    disk_cache: bool = True

    @functools.cached_property
    def has_paths(self) -> bool:
        """Whether a param names a file (read or written)."""
        return any(p.kind == "path" for p in self.params)

    @functools.cached_property
    def _params_by_name(self) -> dict:
        return {p.name: p for p in self.params}

    @property
    def summary(self) -> str:
        """The first paragraph of the doc, on one line."""
        first = self.doc.strip().split("\n\n")[0]
        return " ".join(first.split())

    def input(self, name: str) -> PortSpec | None:
        return next((p for p in self.inputs if p.name == name), None)

    def output(self, name: str) -> PortSpec | None:
        return next((p for p in self.outputs if p.name == name), None)

    def param(self, name: str) -> ParamSpec | None:
        return self._params_by_name.get(name)

    def coerce_params(self, values: typing.Mapping[str, Any]) -> dict[str, Any]:
        """Defaults filled in, every value checked and canonical. Raises ParamError."""
        out = {}
        for name in values:
            if self.param(name) is None:
                known = ", ".join(p.name for p in self.params) or "none"
                raise ParamError(name, f"unknown param (known: {known})")
        for p in self.params:
            out[p.name] = p.coerce(values[p.name] if p.name in values else p.default)
        return out


#: the hooks a node may override; each is declared once, on ``Node``
HOOKS = ("compute", "infer", "bind", "describe", "affects")


class Node:
    """Base of every node: every hook the engine calls, with its one signature and
    its default. A node overrides ``compute`` and whatever else it needs.

    Class attributes (declarations, read once by ``@node``):

    ``impl_version = "1"``
        the version of the numbers the node produces; it is part of every cache
        key of the node. The engine also hashes the node's code into its key
        (``pixgraph.codehash``), so an edit reruns the node even when this is not
        bumped; bump it for changes the code hash cannot see (weights files read
        by path, a dependency's new version).
    ``side_effects = False``
        True for a sink that writes files: it runs whenever one of its outputs is
        requested and is never served from a cache.
    ``disk_cache = True``
        False keeps the node's results in the memory cache only (outputs that are
        large and cheaper to remake than to read back).
    ``uses_scale = False``
        True for a node whose result depends on the run's working resolution
        beyond its inputs and its ``unit="px"`` params: a node that makes images
        of its own size from files (a loader), or one that reads a px param in
        another unit for some settings. It reads the resolution as ``ctx.scale``
        (and the scale is part of its cache key).
    ``preview = None``
        a cheaper stand-in for interactive previews (e.g. the type id of a node
        with the same ports, as the soft shadows name a cheaper shadow); None: the
        node itself previews. The engine never reads it; shells may.
    ``preview_params = None``
        how this node's params map onto its ``preview`` stand-in's: a mapping of
        param values the stand-in gets on top of the params it shares with this
        node (a shell that swaps in the stand-in keeps those of this node's params
        the stand-in declares, then sets these), e.g. to tell the stand-in the unit
        a shared param is in here, which the stand-in converts from its inputs;
        None: the shared params alone. The engine never reads it; shells may.
    ``handles = None``
        what an interactive shell may draw and drag for this node: a mapping with
        a ``kind`` (``"light"``, ``"background"``...) and the names of the params
        and inputs it moves (``pixgraph_serve.scene`` reads it; the Light node's
        says its shadow tip and the object's top). The engine never reads it.
    """

    spec: ClassVar["NodeSpec"]
    impl_version: ClassVar[str] = "1"
    side_effects: ClassVar[bool] = False
    disk_cache: ClassVar[bool] = True
    uses_scale: ClassVar[bool] = False
    preview: ClassVar[Any] = None
    preview_params: ClassVar[Any] = None
    handles: ClassVar[Any] = None

    def compute(self, ctx, inputs: "Namespace", params: "Namespace") -> dict[str, Any]:
        """The node's work: a dict with one value per declared output, each valid
        for its port type. ``ctx`` is a ``pixgraph.engine.NodeContext`` (device,
        progress, cancellation, log). Raise ``InputError`` when the inputs or params
        do not fit together (bad input, exit 2); anything else is a node failure.
        Required: the base raises."""
        raise NotImplementedError(f"{type(self).__name__} has no compute")

    def infer(self, ctx, inputs: "Namespace", params: "Namespace") -> dict[str, Any] | None:
        """The check before running (``pixgraph validate``, ``Session.check``): from
        what is known of the inputs (a ``types.Shape`` where a size is known, else
        None) and the params, what is known of the outputs, ``{output: Shape}``,
        reading file headers at most. Raise ``InputError`` for inputs that cannot
        work. Default: every input of known size has the same size, and each
        ``sized`` output gets it."""
        shapes = {port: v for port, v in inputs.items() if isinstance(v, T.Shape)}
        sizes = {(v.height, v.width) for v in shapes.values()}
        if len(sizes) > 1:
            listing = ", ".join(f"{port} {v.described()}" for port, v in shapes.items())
            raise InputError(f"inputs differ in size: {listing}")
        if not sizes:
            return {}
        (h, w), = sizes
        source = next(iter(shapes.values())).source
        return {p.name: T.Shape(h, w, None, source) for p in self.spec.outputs if p.type.sized}

    def bind(self, value: Any, params: "Namespace") -> dict[str, Any]:
        """The outputs when a host binds an array to this node
        (``Session.run(bind={node: array})``). A host input overrides it to read the
        array the way its params say (colour space, alpha); its params are then part
        of the key. Default: the array is the first output, keyed by its content
        alone."""
        return {self.spec.outputs[0].name: value}

    def describe(self, params: "Namespace") -> str | None:
        """One line for ``pixgraph explain``: what the node will do with these params
        (e.g. which method an automatic choice picks). Default None: nothing to add."""
        return None

    def affects(self, params: "Namespace") -> Collection[str] | None:
        """The key hook (Gaffer's *affects*): the names of the params and inputs
        that affect the outputs with these param values, e.g. only the shadow-tip
        handles when a light is placed by its shadow tip. Params and inputs left out
        are left out of the node's cache key, so changing them reruns neither the
        node nor anything downstream. Name the params that choose the mode too.
        Default None: every cache-relevant param and every input."""
        return None


def _hook_overrides(cls: type, owner: str) -> frozenset:
    """The hooks ``cls`` overrides, each checked against the base's signature."""
    found = set()
    for name in HOOKS:
        mine, base = inspect.getattr_static(cls, name), Node.__dict__[name]
        if mine is base:
            continue
        want = list(inspect.signature(base).parameters)
        if not inspect.isfunction(mine):
            raise TypeError(f"{owner}: hook {name!r} must be a plain method {name}({', '.join(want)}) "
                            "(not a staticmethod, classmethod or attribute)")
        got = [q for q in inspect.signature(mine).parameters.values()
               if q.kind in (q.POSITIONAL_ONLY, q.POSITIONAL_OR_KEYWORD)]
        if len(got) != len(want):
            raise TypeError(f"{owner}: hook {name!r} must take ({', '.join(want)}), "
                            f"got ({', '.join(q.name for q in got)})")
        found.add(name)
    return frozenset(found)


def _read_spec(cls: type, type_id: str, version: int) -> NodeSpec:
    owner = f"{cls.__module__}:{cls.__qualname__}"
    inputs, outputs, params = [], [], []
    for name, ann in _annotations(getattr(cls, "Inputs", None)).items():
        decl = getattr(cls.Inputs, name, _PortDecl(False, ""))
        if not (isinstance(ann, type) and issubclass(ann, T.PortType)):
            raise TypeError(f"{owner}: input {name!r} must be annotated with a port type")
        inputs.append(PortSpec(name, ann, decl.optional, decl.doc))
    for name, ann in _annotations(getattr(cls, "Outputs", None)).items():
        decl = getattr(cls.Outputs, name, _PortDecl(False, ""))
        if not (isinstance(ann, type) and issubclass(ann, T.PortType)):
            raise TypeError(f"{owner}: output {name!r} must be annotated with a port type")
        outputs.append(PortSpec(name, ann, False, decl.doc))
    for name, ann in _annotations(getattr(cls, "Params", None)).items():
        decl = getattr(cls.Params, name, None)
        if not isinstance(decl, _ParamDecl):
            raise TypeError(f"{owner}: param {name!r} must be declared with param(...)")
        spec = ParamSpec(name, _param_kind(ann, owner, name), decl.default, decl.min, decl.max,
                         decl.choices, decl.length, decl.unit, decl.doc, decl.cache, decl.writes)
        if spec.required and spec.kind != "path":
            raise TypeError(f"{owner}: param {name!r}: only a Path param may be required (default None)")
        if not spec.required:
            spec.coerce(spec.default)  # a bad default is the node author's bug: fail at import
        params.append(spec)
    if not outputs:
        raise TypeError(f"{owner}: a node needs at least one output")
    hooks = _hook_overrides(cls, owner)
    if "compute" not in hooks:
        raise TypeError(f"{owner}: a node needs a compute(self, ctx, inputs, params) method")
    return NodeSpec(type_id, version, str(cls.impl_version), cls.__doc__ or "",
                    tuple(inputs), tuple(outputs), tuple(params), cls, owner,
                    bool(cls.side_effects), hooks, bool(cls.disk_cache))


def node(type_id: str, *, version: int = 1) -> Callable[[type], type]:
    """Class decorator that reads the declaration into ``cls.spec`` (a ``NodeSpec``).

    ``type_id`` is namespaced: ``"<namespace>.<Name>"`` (built-ins use ``pixgraph``).
    ``version`` is the interface version: bump it when ports or params change meaning.
    """
    if "." not in type_id or type_id.startswith(".") or type_id.endswith("."):
        raise ValueError(f"node type id {type_id!r} must be namespaced, like 'mypack.MyNode'")

    def wrap(cls: type) -> type:
        if not issubclass(cls, Node):  # an older plain class: give it the base and its defaults
            cls = type(cls.__name__, (cls, Node), {"__module__": cls.__module__, "__qualname__": cls.__qualname__,
                                                   "__doc__": cls.__doc__})
        cls.spec = _read_spec(cls, type_id, version)
        return cls

    return wrap


def is_node_class(obj: Any) -> bool:
    return isinstance(obj, type) and isinstance(getattr(obj, "spec", None), NodeSpec)


class Namespace(typing.Mapping[str, Any]):
    """Read-only attribute and mapping access to a node's inputs or params."""

    __slots__ = ("_d",)

    def __init__(self, values: typing.Mapping[str, Any]):
        object.__setattr__(self, "_d", MappingProxyType(dict(values)))

    def __getattr__(self, name: str) -> Any:
        try:
            return self._d[name]
        except KeyError:
            raise AttributeError(name) from None

    def __setattr__(self, name, value):
        raise AttributeError("read-only")

    def __getitem__(self, k):
        return self._d[k]

    def __iter__(self):
        return iter(self._d)

    def __len__(self):
        return len(self._d)

    def __repr__(self):
        return f"Namespace({dict(self._d)!r})"
