"""pixgraph.ReflectionComposite: background, shadow, reflection, refraction and cutout in linear light."""
from __future__ import annotations

from pixgraph_nodes import types as T
from pixgraph.node import Node, node, param, port

from ._checks import finite, same_size
from .ops.composite import composite_layers, composite_layers_cl, device_for


@node("pixgraph.ReflectionComposite", version=1)
class ReflectionComposite(Node):
    """Background, shadow, reflection, cutout and refraction layered in linear light.

    Layers the effects in the order light reaches the eye:
    the background darkened by the shadow (``bg (1 - opacity darkness (1 - tint))``),
    the reflection layer over it (premultiplied *over*: the floor's own reflection of
    what the cutout now hides is replaced), then the cutout, and the refraction layer
    on top where the cutout is transparent. A full-size image is composited on the
    OpenCL device when that is a GPU (``ops.composite.device_for``; the same numbers).
    """

    class Inputs:
        background: T.Image = port(doc="background, linear light")
        cutout: T.Image = port(doc="cutout colour, premultiplied linear RGBA (or RGB with alpha)")
        alpha: T.Mask = port(doc="cutout coverage")
        reflection: T.Image = port(optional=True, doc="reflection layer (pixgraph.Reflection)")
        shadow: T.Mask = port(optional=True, doc="shadow darkness, 1 = full shadow")
        refraction: T.Image = port(optional=True, doc="refraction layer (pixgraph.Refraction)")

    class Params:
        opacity: float = param(0.85, min=0.0, max=1.0, doc="shadow strength")
        tint: list[float] = param([0.08, 0.09, 0.12], length=3, min=0.0, max=1.0,
                                  doc="fraction of each channel left in full shadow")

    class Outputs:
        image: T.Image = port(doc="composite, linear light")

    impl_version = "1"
    disk_cache = False      # large and cheaper to recompute than to read back from disk

    def compute(self, ctx, inputs, params):
        same_size(background=inputs.background, cutout=inputs.cutout, alpha=inputs.alpha,
                  reflection=inputs.reflection, shadow=inputs.shadow, refraction=inputs.refraction)
        finite(background=inputs.background, cutout=inputs.cutout, alpha=inputs.alpha,
               reflection=inputs.reflection, shadow=inputs.shadow, refraction=inputs.refraction)
        layers = [(inputs.cutout, inputs.alpha)]
        if inputs.reflection is not None:
            layers.insert(0, (inputs.reflection, inputs.reflection[..., 3]))
        if inputs.refraction is not None:
            layers.append((inputs.refraction, inputs.refraction[..., 3]))
        args = (inputs.background, inputs.shadow, params.opacity, params.tint, layers)
        device = device_for(inputs.background.shape, lambda: ctx.device)
        return {"image": composite_layers(*args) if device is None else composite_layers_cl(device, *args)}
