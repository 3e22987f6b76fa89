"""pixgraph.InputPixelHeight: a pixel-height map a host application hands in as a numpy array."""
from __future__ import annotations

from pixgraph_nodes import types as T
from pixgraph.node import InputError, Node, node, port

from .input_image import unbound
from .ops.imageio import host_pixels


@node("pixgraph.InputPixelHeight", version=1)
class InputPixelHeight(Node):
    """A host's pixel height: bind an (H, W) float array in pixels (of that array's
    own size; 0 on the ground). Values are passed on as they are: the nodes that
    use a height refuse NaN or infinite values where they matter (inside the
    cutout), naming the pixel. Unbound, the node is an error."""

    class Outputs:
        height: T.PixelHeight = port(doc="pixel height [px]")

    impl_version = "1"

    def bind(self, value, params):
        if getattr(value, "dtype", None) is not None and value.dtype.kind == "u":
            raise ValueError("a pixel-height map must be float pixels, got unsigned integers")
        a = host_pixels(value, (1,), "a pixel-height map")
        return {"height": a[:, :, 0].copy()}

    def compute(self, ctx, inputs, params):
        raise InputError(unbound(ctx.node_id))
