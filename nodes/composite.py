"""pixgraph.Composite: shadow on the background in linear light, then the cutout over it."""
from __future__ import annotations

from pixgraph_nodes import types as T
from pixgraph.node import Node, node, param, port

from ._checks import finite, same_size
from .ops.composite import composite_layers, composite_layers_cl, device_for


@node("pixgraph.Composite", version=1)
class Composite(Node):
    """Darken the background by the shadow (``bg * (1 - opacity * darkness * (1 - tint))``,
    linear light), then put the premultiplied cutout over it with its alpha.

    The result is linear light with the background's channels; SaveImage encodes it
    (sRGB for PNG, linear for EXR). A full-size image is composited on the OpenCL
    device when that is a GPU (``ops.composite.device_for``; the same numbers).
    """

    class Inputs:
        background: T.Image = port(doc="linear-light background (RGB or premultiplied RGBA)")
        cutout: T.Image = port(doc="linear-light premultiplied cutout colour")
        alpha: T.Mask = port(doc="cutout coverage")
        shadow: T.Mask = port(optional=True, doc="shadow darkness, 1 = full shadow")

    class Params:
        opacity: float = param(0.85, min=0.0, max=1.0, doc="shadow strength")
        tint: list[float] = param([0.08, 0.09, 0.12], length=3, min=0.0, max=1.0,
                                  doc="fraction of each colour channel left in full shadow (sky fill)")

    class Outputs:
        image: T.Image = port(doc="composite, linear light")

    impl_version = "1"
    disk_cache = False      # large and cheaper to recompute than to read back from disk

    def compute(self, ctx, inputs, params):
        same_size(background=inputs.background, cutout=inputs.cutout, alpha=inputs.alpha, shadow=inputs.shadow)
        finite(background=inputs.background, cutout=inputs.cutout, alpha=inputs.alpha, shadow=inputs.shadow)
        args = (inputs.background, inputs.shadow, params.opacity, params.tint, [(inputs.cutout, inputs.alpha)])
        device = device_for(inputs.background.shape, lambda: ctx.device)
        return {"image": composite_layers(*args) if device is None else composite_layers_cl(device, *args)}
