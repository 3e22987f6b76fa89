"""pixgraph.MergeCutouts: two cutouts as one occluder, so each casts shadows on the other."""
from __future__ import annotations

from pixgraph_nodes import types as T
from pixgraph.node import Node, node, port

from .ops.cutouts import merge_cutouts


@node("pixgraph.MergeCutouts", version=1)
class MergeCutouts(Node):
    """Merge two cutouts (mask, pixel height, premultiplied colour) placed in the same
    image. Where they overlap, the one whose foot is lower in the image (closer to the
    camera) is in front. Chain the node for more cutouts."""

    class Inputs:
        mask_a: T.Mask = port(doc="first cutout's coverage")
        height_a: T.PixelHeight = port(doc="first cutout's pixel height [px]")
        image_a: T.Image = port(doc="first cutout's premultiplied colour")
        mask_b: T.Mask = port(doc="second cutout's coverage")
        height_b: T.PixelHeight = port(doc="second cutout's pixel height [px]")
        image_b: T.Image = port(doc="second cutout's premultiplied colour")

    class Outputs:
        mask: T.Mask = port(doc="union coverage (max)")
        height: T.PixelHeight = port(doc="pixel height of the front cutout at each pixel")
        image: T.Image = port(doc="colours composited back to front")

    impl_version = "1"

    def compute(self, ctx, inputs, params):
        m, h, img = merge_cutouts([inputs.mask_a, inputs.mask_b], [inputs.height_a, inputs.height_b],
                                  [inputs.image_a, inputs.image_b])
        return {"mask": m, "height": h, "image": img}
