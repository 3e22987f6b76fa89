"""pixgraph.BufferChannels: the SSN++ 3D-aware buffer channels (PixHt-Lab Sec. 3.2)."""
from __future__ import annotations

from pixgraph_nodes import types as T
from pixgraph.node import Node, node, port

from ._checks import finite_outputs
from ._shadow_ports import ShadowInputs, check_inputs, thickness_param
from .ops.buffers import buffer_channels
from .ops.lights import disk_extremes, light_point


@node("pixgraph.BufferChannels", version=1)
class BufferChannels(Node):
    """Cutout pixel height, background pixel-height gradient, the hard shadow from the
    light's centre, the sparse hard shadows from the disk's 4 extreme points and the
    relative occluder distance, as named float32 channels. Export them as one
    multichannel EXR with pixgraph.SaveBuffers.

    All inputs share the camera's size; pixel heights must be finite and >= 0
    (the cutout's inside its mask), else the node stops with an input error. An
    empty mask gives no shadow channels (all zero)."""

    class Inputs(ShadowInputs):
        light: T.Light = port(doc="the (disk) light")

    class Params:
        thickness: float = thickness_param()

    class Outputs:
        buffers: T.Buffers = port(doc="named float32 (H, W) channels")

    impl_version = "1"

    def compute(self, ctx, inputs, params):
        check_inputs(inputs)
        cam, light = inputs.camera, inputs.light
        buffers = buffer_channels(ctx.device, inputs.mask, inputs.fg_height, inputs.bg_height,
                                  light_point(light, cam), disk_extremes(light, cam), params.thickness,
                                  progress=ctx.progress, check_cancelled=ctx.check_cancelled)
        finite_outputs(**buffers)
        return {"buffers": buffers}
