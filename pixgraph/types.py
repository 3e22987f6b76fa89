"""Port types: what flows along an edge, and which output may feed which input.

A port type is a class; ``B`` may feed an input of type ``A`` when ``B`` is ``A``
or a subclass of it. ``Any`` accepts everything. The engine knows only the
generic types below; a node pack declares its own value types (the built-in
pack's images, masks, cameras and lights are in ``pixgraph_nodes.types``) by
subclassing ``PortType``, and the registry collects them from the ports of the
registered nodes (``Registry.port_types()``).

The engine never looks inside values; these classes only describe them, check
them (``validate``), say whether they carry an image size (``sized``), how to
write them to a file (``write``), and give a byte size for the memory cache.
"""
from __future__ import annotations

import dataclasses
import sys
from typing import Any as _Any, Callable, ClassVar

import numpy as np


class PortType:
    """Base of every port type. Subclasses override the hooks they need:

    ``describe``
        one line for node references (``pixgraph nodes``, docs/nodes.md).
    ``validate(value)``
        raise ``TypeError`` when ``value`` is not a valid value of the type; the
        engine calls it on every computed, bound or disk-cached output. Default:
        accepts anything.
    ``sized``
        True when a value is an (H, W[, C]) array or carries one image size: the
        default check before running (``Engine.check``) gives such outputs the
        size of the node's inputs. Default False.
    ``finite``
        True when every number of a value must be finite: a disk cache entry
        holding NaN or infinity is discarded, not served. Default False.
    ``write(path, value) -> path``
        write a value to a file (``Session.write_output`` calls it; the type
        decides colour vs data encoding). Default ``None``: the type cannot be
        written to a file.
    """

    describe: ClassVar[str] = "any value"
    sized: ClassVar[bool] = False
    finite: ClassVar[bool] = False
    write: ClassVar[Callable[[str, _Any], str] | None] = None

    @classmethod
    def type_name(cls) -> str:
        return cls.__name__

    @classmethod
    def accepts(cls, other: type["PortType"]) -> bool:
        """True when an output of type ``other`` may feed an input of this type."""
        return cls is Any or issubclass(other, cls)

    @classmethod
    def validate(cls, value: _Any) -> None:
        """Raise ``TypeError`` when ``value`` is not a valid value of this type."""


class Any(PortType):
    describe = "any value"


class Scalar(PortType):
    describe = "a float"

    @classmethod
    def validate(cls, value):
        if not isinstance(value, (int, float, np.floating, np.integer)):
            raise TypeError(f"Scalar must be a number, got {type(value).__name__}")


def check_array(value: _Any, ndim: tuple[int, ...], name: str) -> None:
    """Raise ``TypeError`` unless ``value`` is a float32 numpy array with one of
    the dimension counts ``ndim`` (a helper for array port types' ``validate``)."""
    if not isinstance(value, np.ndarray):
        raise TypeError(f"{name} must be a numpy array, got {type(value).__name__}")
    if value.ndim not in ndim:
        raise TypeError(f"{name} must have {' or '.join(map(str, ndim))} dimensions, got shape {value.shape}")
    if value.dtype != np.float32:
        raise TypeError(f"{name} must be float32, got {value.dtype}")


@dataclasses.dataclass(frozen=True)
class Shape:
    """What a check before running knows of an array value: its size, its channels
    when known, and where it comes from (``"'cutout.png' (node 'cutout')"``), so a
    mismatch can name the user's files. Nodes' ``infer`` hooks make these from file
    headers; the engine's ``check`` passes them along the graph."""

    height: int
    width: int
    channels: int | None = None
    source: str = ""

    @property
    def size(self) -> str:
        """``"WxH"``, as image sizes are written."""
        return f"{self.width}x{self.height}"

    def described(self) -> str:
        return f"{self.size} from {self.source}" if self.source else self.size


def nbytes(value: _Any) -> int:
    """Approximate size of a value in bytes, for the memory-bounded cache."""
    if isinstance(value, np.ndarray):
        return int(value.nbytes)
    if isinstance(value, dict):
        return sum(nbytes(v) for v in value.values()) + 64
    if isinstance(value, (list, tuple)):
        return sum(nbytes(v) for v in value) + 64
    nb = getattr(value, "nbytes", None)
    if isinstance(nb, int):
        return nb
    return sys.getsizeof(value)


#: the engine's own port types by name; a registry adds those of its nodes' ports
BUILTIN: dict[str, type[PortType]] = {t.type_name(): t for t in (Any, Scalar)}
