"""pixgraph.SaveImage: write an image file (a sink)."""
from __future__ import annotations

from pathlib import Path

from pixgraph_nodes import types as T
import numpy as np

from pixgraph.node import InputError, Node, node, param, port

from .ops.imageio import write_data, write_image


@node("pixgraph.SaveImage", version=1)
class SaveImage(Node):
    """Write an image; the extension picks the format.

    PNG, TIFF and JPEG are sRGB-encoded with straight alpha (JPEG drops alpha);
    EXR is linear and premultiplied, half or float; ``.npy`` is the array itself.
    A data map (``kind: data``, or ``auto`` and a 2-D array: a matte, a shadow
    darkness, a pixel height) is written as numbers: never sRGB-encoded or clipped
    (.npy / float EXR / float TIFF exact; PNG 16-bit holding ``value / white``).
    A sink: it runs whenever its ``path`` output is requested and is never served
    from cache.
    """

    class Inputs:
        image: T.Any = port(doc="linear, premultiplied image, or a data map (Mask, PixelHeight)")

    class Params:
        path: Path = param(None, writes=True, doc="file to write, relative to the graph file's folder")
        bit_depth: int = param(0, min=0, max=32,
                               doc="0: format default (8 for PNG/TIFF/JPEG, 32 for EXR; data: 16 for PNG); "
                                   "16: 16-bit / half EXR")
        kind: str = param("auto", choices=["auto", "color", "data"],
                          doc="color: sRGB-encoded for PNG/TIFF/JPEG; data: the numbers; auto: 2-D arrays are data")
        white: float = param(1.0, min=1e-9, doc="data in integer files (PNG): the value stored as full white")
        compression: int = param(-1, min=-1, max=9,
                                 doc="PNG only: -1 fast (ISA-L deflate, as small as zlib level 6 on photos); "
                                     "0-9 zlib's level (9: ~15 % smaller, ~100x slower)")

    class Outputs:
        path: T.Any = port(doc="absolute path of the file written")

    impl_version = "3"
    side_effects = True

    def compute(self, ctx, inputs, params):
        if not isinstance(inputs.image, np.ndarray):
            raise InputError(f"SaveImage writes arrays, got {type(inputs.image).__name__}")
        data = params.kind == "data" or (params.kind == "auto" and inputs.image.ndim == 2)
        level = None if params.compression < 0 else params.compression
        if level is not None and Path(params.path).suffix.lower() != ".png":
            raise InputError(f"param 'compression' applies to PNG files only, not {Path(params.path).name}")
        if data:
            return {"path": write_data(params.path, inputs.image, params.bit_depth or None, params.white, level)}
        return {"path": write_image(params.path, inputs.image, bit_depth=params.bit_depth or None,
                                    compression=level)}
