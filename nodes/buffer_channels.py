"""pixgraph.BufferChannels: the SSN++ 3D-aware buffer channels (PixHt-Lab Sec. 3.2)."""
from __future__ import annotations

from pixgraph_nodes import types as T
from pixgraph.node import Node, node, param, port

from ._checks import finite, finite_outputs, inside, pixel_heights, same_size
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

    class Inputs:
        mask: T.Mask = port(doc="cutout coverage")
        fg_height: T.PixelHeight = port(doc="cutout pixel height [px]")
        bg_height: T.PixelHeight = port(doc="background pixel height [px]")
        light: T.Light = port(doc="the (disk) light")
        camera: T.Camera = port(doc="camera that converts the light to pixel-height space")

    class Params:
        thickness: float = param(1.0, min=0.0, max=1000.0, unit="px",
                                 doc="how far a ray may pass behind the cutout surface and still be blocked")

    class Outputs:
        buffers: T.Buffers = port(doc="named float32 (H, W) channels")

    impl_version = "1"

    def compute(self, ctx, inputs, params):
        same_size(inputs.camera, mask=inputs.mask, fg_height=inputs.fg_height, bg_height=inputs.bg_height)
        finite(mask=inputs.mask)
        pixel_heights(inside(inputs.mask), fg_height=inputs.fg_height)
        pixel_heights(bg_height=inputs.bg_height)
        cam, light = inputs.camera, inputs.light
        buffers = buffer_channels(ctx.device, inputs.mask, inputs.fg_height, inputs.bg_height,
                                  light_point(light, cam), disk_extremes(light, cam), params.thickness,
                                  progress=ctx.progress, check_cancelled=ctx.check_cancelled)
        finite_outputs(**buffers)
        return {"buffers": buffers}
