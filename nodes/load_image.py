"""pixgraph.LoadImage: read an image file into linear, premultiplied float32."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from pixgraph_nodes import types as T
from pixgraph.node import InputError, Node, node, param, port
from pixgraph_nodes.types import Shape

from ._checks import file_shape, no_alpha

from .ops.imageio import host_pixels, read_image, to_internal
from .ops.resample import at_scale


@node("pixgraph.LoadImage", version=1)
class LoadImage(Node):
    """Read PNG, JPEG, TIFF or EXR; decode to linear light and premultiply alpha.

    A host may bind a numpy array instead of the file (as for pixgraph.InputImage;
    ``auto`` then means linear, premultiplied).
    """

    class Params:
        path: Path = param(None, doc="image file, relative to the graph file's folder")
        colorspace: str = param("auto", choices=["auto", "srgb", "linear"],
                                doc="encoding of the file's colour; auto: EXR/HDR linear, others sRGB")
        alpha: str = param("auto", choices=["auto", "straight", "premultiplied"],
                           doc="what the file holds; auto: EXR/HDR premultiplied, others straight")

    class Outputs:
        image: T.Image = port(doc="(H, W, C) linear light, premultiplied")
        alpha: T.Mask = port(doc="coverage; ones when the file has no alpha")

    impl_version = "1"
    disk_cache = False      # the file is its own cache: decoding it is cheaper than a float32 copy
    uses_scale = True       # a scaled run (Session.run(scale=...)) reads it at that size

    def bind(self, value, params):
        colorspace = "linear" if params.colorspace == "auto" else params.colorspace
        alpha = "premultiplied" if params.alpha == "auto" else params.alpha
        image, a = to_internal(host_pixels(value, (1, 2, 3, 4), "an image"), colorspace, alpha)
        return {"image": image, "alpha": a}

    def unusable_outputs(self, node_id, params):
        """``alpha`` of a file without an alpha channel is all ones: as a cutout's
        coverage it would cover the whole frame, so any node that uses it is refused
        (the engine's plan and check), with PlaceCutout's message."""
        shape = file_shape(params.path, node_id)
        return {} if shape.channels in (2, 4) else {"alpha": no_alpha(shape)}

    def infer(self, ctx, inputs, params):
        shape = file_shape(params.path, ctx.node_id)
        return {"image": shape, "alpha": Shape(shape.height, shape.width, 1, shape.source)}

    def compute(self, ctx, inputs, params):
        try:
            image, alpha = read_image(params.path, params.colorspace, params.alpha)
        except OSError as e:
            raise InputError(str(e).splitlines()[0]) from None
        if ctx.scale != 1.0:
            image, alpha = at_scale(image, ctx.scale), np.clip(at_scale(alpha, ctx.scale), 0.0, 1.0)
        return {"image": image, "alpha": alpha}
