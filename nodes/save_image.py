"""pixgraph.SaveImage: write an image file (a sink)."""
from __future__ import annotations

from pathlib import Path

from pixgraph import types as T
from pixgraph.node import node, param, port

from .ops.imageio import write_image


@node("pixgraph.SaveImage", version=1)
class SaveImage:
    """Write an image; the extension picks the format.

    PNG, TIFF and JPEG are sRGB-encoded with straight alpha (JPEG drops alpha);
    EXR is linear and premultiplied, half or float. A sink: it runs whenever its
    ``path`` output is requested and is never served from cache.
    """

    class Inputs:
        image: T.Image = port(doc="linear, premultiplied image")

    class Params:
        path: Path = param(None, writes=True, doc="file to write, relative to the graph file's folder")
        bit_depth: int = param(0, min=0, max=32,
                               doc="0: format default (8 for PNG/TIFF/JPEG, 32 for EXR); 16: 16-bit / half EXR")

    class Outputs:
        path: T.Any = port(doc="absolute path of the file written")

    impl_version = "1"
    side_effects = True

    def compute(self, ctx, inputs, params):
        return {"path": write_image(params.path, inputs.image, bit_depth=params.bit_depth or None)}
