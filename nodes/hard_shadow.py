"""pixgraph.HardShadow: hard shadow of the cutout from the light's centre (SSG's march)."""
from __future__ import annotations

from pixgraph_nodes import types as T
from pixgraph.node import Node, node, param, port

from ._checks import finite, finite_outputs, inside, pixel_heights, same_size
from .ops.lights import light_point
from .ops.shadow import hard_shadow


@node("pixgraph.HardShadow", version=1)
class HardShadow(Node):
    """Hard shadow cast by the cutout on the background and on itself, traced in
    pixel-height space toward the light's centre (an area light acts as a point here).

    All inputs share the camera's size; pixel heights must be finite and >= 0
    (the cutout's inside its mask), else the node stops with an input error. An
    empty mask casts no shadow (all lit)."""

    class Inputs:
        mask: T.Mask = port(doc="cutout coverage (occluder where > 0.5)")
        fg_height: T.PixelHeight = port(doc="cutout pixel height [px]")
        bg_height: T.PixelHeight = port(doc="background pixel height [px]")
        light: T.Light = port(doc="the light")
        camera: T.Camera = port(doc="camera that converts the light to pixel-height space")

    class Params:
        thickness: float = param(1.0, min=0.0, max=1000.0, unit="px",
                                 doc="how far a ray may pass behind the cutout surface and still be blocked")

    class Outputs:
        lit: T.Mask = port(doc="1 = lit, 0 = shadow")
        darkness: T.Mask = port(doc="1 - lit: 1 = full shadow (what Composite takes)")

    impl_version = "1"

    def compute(self, ctx, inputs, params):
        same_size(inputs.camera, mask=inputs.mask, fg_height=inputs.fg_height, bg_height=inputs.bg_height)
        finite(mask=inputs.mask)
        pixel_heights(inside(inputs.mask), fg_height=inputs.fg_height)
        pixel_heights(bg_height=inputs.bg_height)
        lp = light_point(inputs.light, inputs.camera)
        lit = hard_shadow(ctx.device, inputs.mask, inputs.fg_height, inputs.bg_height, lp, params.thickness,
                          progress=ctx.progress, check_cancelled=ctx.check_cancelled)
        finite_outputs(lit=lit)
        return {"lit": lit, "darkness": (1.0 - lit).astype(lit.dtype)}
