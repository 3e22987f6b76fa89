"""pixgraph.InputImage: an image a host application hands in as a numpy array."""
from __future__ import annotations

from pixgraph_nodes import types as T
from pixgraph.node import InputError, Node, node, param, port

from .ops.imageio import host_pixels, to_internal


@node("pixgraph.InputImage", version=1)
class InputImage(Node):
    """A host's image: bind a numpy array to this node (``Session.run(bind={id: array})``).

    The array is (H, W, 3) RGB (a background photo) or (H, W, 4) RGBA (a cutout;
    alpha last), also (H, W) / (H, W, 2) grey; float (any float dtype) or unsigned
    integers (normalised by 255 / 65535). ``colorspace`` and ``alpha`` say how the
    host holds it; the defaults are pixgraph's own convention (linear light,
    premultiplied), e.g. Blender's compositor buffers. Unbound, the node is an error.
    """

    class Params:
        colorspace: str = param("linear", choices=["linear", "srgb"],
                                doc="encoding of the host array's colour")
        alpha: str = param("premultiplied", choices=["premultiplied", "straight"],
                           doc="how the host array's colour relates to its alpha")

    class Outputs:
        image: T.Image = port(doc="(H, W, C) linear light, premultiplied")
        alpha: T.Mask = port(doc="coverage; ones when the array has no alpha channel")

    impl_version = "1"

    def bind(self, value, params):
        image, alpha = to_internal(host_pixels(value, (1, 2, 3, 4), "an image"), params.colorspace, params.alpha)
        return {"image": image, "alpha": alpha}

    def compute(self, ctx, inputs, params):
        raise InputError(unbound(ctx.node_id))


def unbound(node_id: str) -> str:
    return (f"host input {node_id!r} has no array: bind one with Session.run(..., bind={{{node_id!r}: array}}) "
            f"(from the command line use pixgraph.LoadImage / LoadMask / LoadPixelHeight instead)")
