"""pixgraph.InputMask: a coverage mask a host application hands in as a numpy array."""
from __future__ import annotations

import numpy as np

from pixgraph_nodes import types as T
from pixgraph.node import InputError, Node, node, port

from .input_image import unbound
from .ops.imageio import host_pixels


@node("pixgraph.InputMask", version=1)
class InputMask(Node):
    """A host's mask (matte): bind an (H, W) or (H, W, 1) array, float in [0, 1] or
    unsigned integers (255 / 65535 = inside). Data, never colour-decoded; values
    outside [0, 1] are clipped. Unbound, the node is an error."""

    class Outputs:
        mask: T.Mask = port(doc="float32 (H, W) coverage in [0, 1]")

    impl_version = "1"

    def bind(self, value, params):
        return {"mask": np.clip(host_pixels(value, (1,), "a mask")[:, :, 0], 0.0, 1.0)}

    def compute(self, ctx, inputs, params):
        raise InputError(unbound(ctx.node_id))
