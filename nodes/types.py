"""The built-in pack's port types: images, masks, pixel heights, cameras, lights,
per-pixel geometry and buffer channels.

Nodes import them as ``from pixgraph_nodes import types as T``; the engine's
generic types (``Any``, ``Scalar``) and ``Shape`` are re-exported here so one
module serves every declaration. A value type of another pack subclasses
``pixgraph.types.PortType`` the same way (see docs/writing-nodes.md).
"""
from __future__ import annotations

from pixgraph.types import Any, PortType, Scalar, Shape, check_array

__all__ = ["Any", "PortType", "Scalar", "Shape", "Image", "Mask", "PixelHeight", "Camera", "Light",
           "Geometry", "Buffers"]


class Image(PortType):
    """float32 array (H, W, C), C in 1..4, linear light, alpha premultiplied when C == 4."""

    describe = "float32 (H, W, C) linear-light image, premultiplied alpha when C = 4"
    sized = True
    finite = True

    @classmethod
    def validate(cls, value):
        check_array(value, (2, 3), "Image")

    @classmethod
    def write(cls, path, value):
        """Colour: sRGB-encoded 8/16-bit files, or linear EXR."""
        from .ops.imageio import write_image

        cls.validate(value)
        return write_image(path, value)


def _write_data(cls, path, value):
    """A data map (a matte, a darkness, a pixel height) written as its numbers, never
    colour-encoded: the ``write`` of Mask and PixelHeight."""
    from .ops.imageio import write_data

    cls.validate(value)
    return write_data(path, value)


class Mask(Image):
    """float32 array (H, W) in [0, 1]: coverage, 1 = inside. A Mask may feed an
    Image input (it is an image with one channel), not the reverse."""

    describe = "float32 (H, W) coverage in [0, 1]"

    @classmethod
    def validate(cls, value):
        check_array(value, (2,), "Mask")

    write = classmethod(_write_data)


class PixelHeight(PortType):
    """float32 array (H, W): distance in pixels from each point to its foot on the ground."""

    describe = "float32 (H, W) pixel height, pixels"
    sized = True
    finite = True

    @classmethod
    def validate(cls, value):
        check_array(value, (2,), "PixelHeight")

    write = classmethod(_write_data)


class Camera(PortType):
    """A pixel-height camera (``pixgraph_nodes.ops.camera.Camera``)."""

    describe = "pinhole camera with horizon (lens shift), field of view and height"


class Light(PortType):
    """A light in 3D and in pixel-height space (``pixgraph_nodes.ops.lights.Light``)."""

    describe = "point, directional or disk area light"


class Geometry(PortType):
    """Per-pixel 3D reconstruction: positions, depth, normals and validity."""

    describe = "reconstructed 3D positions, depth, normals and validity mask"
    sized = True


class Buffers(PortType):
    """Named float32 (H, W) channels, e.g. the SSN++ buffer channels."""

    describe = "dict of named float32 (H, W) channels"
    sized = True
    finite = True

    @classmethod
    def validate(cls, value):
        if not isinstance(value, dict):
            raise TypeError(f"Buffers must be a dict of arrays, got {type(value).__name__}")
        for k, v in value.items():
            check_array(v, (2,), f"Buffers channel {k!r}")
