"""pixgraph.GaussianBlur: separable Gaussian blur on the OpenCL device."""
from __future__ import annotations

from pixgraph_nodes import types as T
from pixgraph.node import Node, node, param, port

from .ops.blur import gaussian_blur


@node("pixgraph.GaussianBlur", version=1)
class GaussianBlur(Node):
    """Gaussian blur of an image (every channel, premultiplied alpha included), edges clamped."""

    class Inputs:
        image: T.Image = port(doc="image or mask to blur")

    class Params:
        sigma: float = param(2.0, min=0.0, max=100.0, unit="px", doc="standard deviation; 0 leaves the image as is")

    class Outputs:
        image: T.Image = port(doc="blurred image, same shape as the input")

    impl_version = "1"

    def compute(self, ctx, inputs, params):
        return {"image": gaussian_blur(ctx.device, inputs.image, params.sigma)}
