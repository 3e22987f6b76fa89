"""pixgraph.HardShadow: hard shadow of the cutout from the light's centre (SSG's march)."""
from __future__ import annotations

from pixgraph_nodes import types as T
from pixgraph.node import Node, node, port

from ._checks import finite_outputs
from ._shadow_ports import ShadowInputs, ShadowOutputs, check_inputs, thickness_param
from .ops.lights import light_point
from .ops.shadow import hard_shadow


@node("pixgraph.HardShadow", version=1)
class HardShadow(Node):
    """Hard shadow cast by the cutout on the background and on itself, traced in
    pixel-height space toward the light's centre (an area light acts as a point here).

    All inputs share the camera's size; pixel heights must be finite and >= 0
    (the cutout's inside its mask), else the node stops with an input error. An
    empty mask casts no shadow (all lit)."""

    class Inputs(ShadowInputs):
        """The shared five (``_shadow_ports.ShadowInputs``)."""

    class Params:
        thickness: float = thickness_param()

    class Outputs(ShadowOutputs):
        lit: T.Mask = port(doc="1 = lit, 0 = shadow")

    impl_version = "1"
    #: shells may switch this node among the registered types declaring the same handles kind
    handles = {"kind": "shadow"}

    def compute(self, ctx, inputs, params):
        check_inputs(inputs)
        lp = light_point(inputs.light, inputs.camera)
        lit = hard_shadow(ctx.device, inputs.mask, inputs.fg_height, inputs.bg_height, lp, params.thickness,
                          progress=ctx.progress, check_cancelled=ctx.check_cancelled)
        finite_outputs(lit=lit)
        return {"lit": lit, "darkness": (1.0 - lit).astype(lit.dtype)}
