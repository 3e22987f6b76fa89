"""pixgraph.SoftShadow: classical soft shadow, the average of hard shadows over the area light."""
from __future__ import annotations

import numpy as np

from pixgraph_nodes import types as T
from pixgraph.node import Node, node, param, port

from ._checks import finite_outputs
from ._shadow_ports import SOFT_PREVIEW, ShadowInputs, ShadowOutputs, check_inputs, thickness_param
from .ops.lights import disk_samples, light_point
from .ops.upsample import AUTO_MAX_SIDE, lit_and_darkness, proxy_soft_shadow_parts


@node("pixgraph.SoftShadow", version=1)
class SoftShadow(Node):
    """Soft shadow in pixel-height space: the fraction of ``samples`` stratified points of
    the disk light (sunflower pattern) that each pixel sees. The pixel-height-space
    reference; its cost grows linearly with ``samples``. A point light needs one.

    All inputs share the camera's size; pixel heights must be finite and >= 0
    (the cutout's inside its mask), else the node stops with an input error. An
    empty mask casts no shadow (all lit). Long runs work in bands of image rows:
    they report progress and stop at the next band when the run is cancelled.
    Images larger than ``proxy`` are traced at a proxy resolution (docs/auto.md)."""

    class Inputs(ShadowInputs):
        light: T.Light = port(doc="the light; its radius / angular radius is the softness")

    class Params:
        samples: int = param(64, min=1, max=65536, doc="light samples (noise falls like 1/samples)")
        seed: int = param(0, min=0, max=2**31 - 1, doc="rotation of the sample pattern")
        thickness: float = thickness_param()
        proxy: int = param(AUTO_MAX_SIDE, min=0, max=1 << 20, unit="px, longer side",
                           doc="images whose longer side exceeds this are traced on a copy of this longer side "
                               "and enlarged edge-aware against the full-resolution mask (0: never)")

    class Outputs(ShadowOutputs):
        lit: T.Mask = port(doc="fraction of the light seen, 1 = fully lit")

    impl_version = "1"
    #: a cheaper node type with the same ports that stands in for this one in previews
    preview = SOFT_PREVIEW
    #: shells may switch this node among the registered types declaring the same handles kind
    handles = {"kind": "shadow"}

    def compute(self, ctx, inputs, params):
        check_inputs(inputs)
        light, cam = inputs.light, inputs.camera
        if light.is_area:
            samples = disk_samples(light, cam, params.samples, params.seed)
        else:  # every sample would be the same point: one hard shadow is the exact answer
            samples = light_point(light, cam)[None]
        side = max(inputs.mask.shape) if params.proxy == 0 else params.proxy
        parts = proxy_soft_shadow_parts(ctx.device, inputs.mask, inputs.fg_height, inputs.bg_height, samples,
                                        params.thickness, side, progress=ctx.progress,
                                        check_cancelled=ctx.check_cancelled)
        lit, darkness = lit_and_darkness(*parts, np.shape(inputs.mask))
        finite_outputs(lit=lit)
        return {"lit": lit, "darkness": darkness}
