"""Port types: what flows along an edge, and which output may feed which input.

A port type is a class; ``B`` may feed an input of type ``A`` when ``B`` is ``A``
or a subclass of it (a Mask is an Image with one channel, so a Mask output may
feed an Image input, but not the reverse). ``Any`` accepts everything.

The engine never looks inside values; these classes only describe them, check
them (``validate``) and give a byte size for the memory cache.
"""
from __future__ import annotations

import dataclasses
import sys
from typing import Any as _Any

import numpy as np


class PortType:
    """Base of every port type. ``describe`` is the one-line doc in node references."""

    describe = "any value"

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

    #: A port type whose values can be saved defines ``write(path, value) -> path``
    #: (``Session.write_output`` calls it: an image is written as colour, a matte or
    #: a pixel height as data). Types without it cannot be written to a file.
    write = None


class Any(PortType):
    describe = "any value"


def _check_array(value, ndim: tuple[int, ...], name: str) -> None:
    if not isinstance(value, np.ndarray):
        raise TypeError(f"{name} must be a numpy array, got {type(value).__name__}")
    if value.ndim not in ndim:
        raise TypeError(f"{name} must have {' or '.join(map(str, ndim))} dimensions, got shape {value.shape}")
    if value.dtype != np.float32:
        raise TypeError(f"{name} must be float32, got {value.dtype}")


class Image(PortType):
    """float32 array (H, W, C), C in 1..4, linear light, alpha premultiplied when C == 4."""

    describe = "float32 (H, W, C) linear-light image, premultiplied alpha when C = 4"

    @classmethod
    def validate(cls, value):
        _check_array(value, (2, 3), "Image")

    @classmethod
    def write(cls, path, value):
        """Colour: sRGB-encoded 8/16-bit files, or linear EXR."""
        from pixgraph_nodes.ops.imageio import write_image  # moves with the domain types to the node package

        cls.validate(value)
        return write_image(path, value)


class Mask(Image):
    """float32 array (H, W) in [0, 1]: coverage, 1 = inside."""

    describe = "float32 (H, W) coverage in [0, 1]"

    @classmethod
    def validate(cls, value):
        _check_array(value, (2,), "Mask")

    @classmethod
    def write(cls, path, value):
        """Data: the numbers themselves, never colour-encoded."""
        from pixgraph_nodes.ops.imageio import write_data

        cls.validate(value)
        return write_data(path, value)


class PixelHeight(PortType):
    """float32 array (H, W): distance in pixels from each point to its foot on the ground."""

    describe = "float32 (H, W) pixel height, pixels"

    @classmethod
    def validate(cls, value):
        _check_array(value, (2,), "PixelHeight")

    @classmethod
    def write(cls, path, value):
        """Data: heights in pixels, never colour-encoded."""
        from pixgraph_nodes.ops.imageio import write_data

        cls.validate(value)
        return write_data(path, value)


class Scalar(PortType):
    describe = "a float"

    @classmethod
    def validate(cls, value):
        if not isinstance(value, (int, float, np.floating, np.integer)):
            raise TypeError(f"Scalar must be a number, got {type(value).__name__}")


class Camera(PortType):
    """A pixel-height camera (``pixgraph_nodes.ops.camera.Camera``)."""

    describe = "pinhole camera with horizon (lens shift), field of view and height"


class Light(PortType):
    """A light in 3D and in pixel-height space (``pixgraph_nodes.ops.lights.Light``)."""

    describe = "point, directional or disk area light"


class Geometry(PortType):
    """Per-pixel 3D reconstruction: positions, depth, normals and validity."""

    describe = "reconstructed 3D positions, depth, normals and validity mask"


class Buffers(PortType):
    """Named float32 (H, W) channels, e.g. the SSN++ buffer channels."""

    describe = "dict of named float32 (H, W) channels"

    @classmethod
    def validate(cls, value):
        if not isinstance(value, dict):
            raise TypeError(f"Buffers must be a dict of arrays, got {type(value).__name__}")
        for k, v in value.items():
            _check_array(v, (2,), f"Buffers channel {k!r}")


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


#: port types whose values are (H, W[, C]) arrays or carry one image size
SIZED = (Image, Mask, PixelHeight, Buffers, Geometry)


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


#: every built-in port type by name, for the file format and schema
ALL: dict[str, type[PortType]] = {
    t.type_name(): t
    for t in (Any, Image, Mask, PixelHeight, Scalar, Camera, Light, Geometry, Buffers)
}
