"""pixgraph.Constant: an image of one colour."""
from __future__ import annotations

import numpy as np

from pixgraph_nodes import types as T
from pixgraph.node import Node, node, param, port


@node("pixgraph.Constant", version=1)
class Constant(Node):
    """An RGBA image filled with one linear-light colour (premultiplied on output)."""

    class Params:
        color: list[float] = param([0.18, 0.18, 0.18, 1.0], length=4, min=0.0,
                                   doc="R, G, B in linear light and straight alpha in [0, 1]")
        width: int = param(512, min=1, max=65536, unit="px", doc="image width")
        height: int = param(512, min=1, max=65536, unit="px", doc="image height")

    class Outputs:
        image: T.Image = port(doc="(height, width, 4) premultiplied RGBA")

    impl_version = "1"

    def compute(self, ctx, inputs, params):
        r, g, b, a = params.color
        a = min(a, 1.0)
        pixel = np.array([r * a, g * a, b * a, a], np.float32)
        return {"image": np.broadcast_to(pixel, (params.height, params.width, 4)).copy()}
