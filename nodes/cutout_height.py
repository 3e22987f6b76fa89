"""pixgraph.CutoutHeight: cutout pixel height from a predictor (heuristic for now)."""
from __future__ import annotations

import numpy as np

from pixgraph import types as T
from pixgraph.node import node, param, port

from .ops.heightmaps import ContactLinePredictor


@node("pixgraph.CutoutHeight", version=1)
class CutoutHeight:
    """Pixel height of an upright cutout standing on the ground: distance in rows to its
    contact line (``contact_line``: one line fitted to the object's lowest pixels, the
    default; ``column_bottom``: each column's lowest pixel). See
    pixgraph_nodes.ops.heightmaps.contact_line_height for why. A file-based height map
    comes from pixgraph.LoadPixelHeight instead.
    """

    class Inputs:
        mask: T.Mask = port(doc="cutout coverage")

    class Params:
        method: str = param("contact_line", choices=("contact_line", "column_bottom"),
                            doc="where each column's foot is")
        tolerance: float = param(2.0, min=0.0, unit="px",
                                 doc="contact_line: columns whose bottom is this close to the lowest "
                                     "row take part in the fit")

    class Outputs:
        height: T.PixelHeight = port(doc="cutout pixel height [px], 0 outside the mask")

    impl_version = "1"

    def compute(self, ctx, inputs, params):
        predictor = ContactLinePredictor(params.method, params.tolerance)
        mask = np.asarray(inputs.mask, dtype=np.float32)
        rgba = np.zeros(mask.shape + (4,), np.float32)
        rgba[..., 3] = mask
        return {"height": predictor.predict(rgba)}
