"""pixgraph.ReflectionComposite: background, shadow, reflection, refraction and cutout in linear light."""
from __future__ import annotations

import numpy as np

from pixgraph_nodes import types as T
from pixgraph.node import Node, node, param, port

from ._checks import finite, same_size
from .ops.composite import apply_shadow, over


@node("pixgraph.ReflectionComposite", version=1)
class ReflectionComposite(Node):
    """Background, shadow, reflection, cutout and refraction layered in linear light.

    Layers the effects in the order light reaches the eye:
    the background darkened by the shadow (``bg (1 - opacity darkness (1 - tint))``),
    the reflection layer over it (premultiplied *over*: the floor's own reflection of
    what the cutout now hides is replaced), then the cutout, and the refraction layer
    on top where the cutout is transparent.
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

    def compute(self, ctx, inputs, params):
        same_size(background=inputs.background, cutout=inputs.cutout, alpha=inputs.alpha,
                  reflection=inputs.reflection, shadow=inputs.shadow, refraction=inputs.refraction)
        finite(background=inputs.background, cutout=inputs.cutout, alpha=inputs.alpha,
               reflection=inputs.reflection, shadow=inputs.shadow, refraction=inputs.refraction)
        bg = np.asarray(inputs.background, np.float32)
        if bg.ndim == 2:
            bg = bg[..., None]
        if inputs.shadow is not None:
            bg = apply_shadow(bg, inputs.shadow, params.opacity, params.tint)
        if inputs.reflection is not None:
            bg = over(inputs.reflection, inputs.reflection[..., 3], bg)
        out = over(inputs.cutout, inputs.alpha, bg)
        if inputs.refraction is not None:
            out = over(inputs.refraction, inputs.refraction[..., 3], out)
        return {"image": out}
