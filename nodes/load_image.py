"""pixgraph.LoadImage: read an image file into linear, premultiplied float32."""
from __future__ import annotations

from pathlib import Path

from pixgraph import types as T
from pixgraph.node import node, param, port

from .ops.imageio import read_image


@node("pixgraph.LoadImage", version=1)
class LoadImage:
    """Read PNG, JPEG, TIFF or EXR; decode to linear light and premultiply alpha."""

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

    def compute(self, ctx, inputs, params):
        image, alpha = read_image(params.path, params.colorspace, params.alpha)
        return {"image": image, "alpha": alpha}
