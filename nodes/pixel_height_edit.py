"""pixgraph.PixelHeightEdit: fix a cutout's pixel height by hand (contact points, foot depth, tilt, lying
down, lift)."""
from __future__ import annotations

import numpy as np

from pixgraph_nodes import types as T
from pixgraph.node import InputError, Node, node, param, port

from ._checks import same_size
from .ops import height_edit
from .ops.lights import foot_of_mask
from .ops.height_edit import edit_pixel_height


#: how far outside the cutout a contact point may lie and be put on its edge [px]
EDGE_SLACK = 1.0


@node("pixgraph.PixelHeightEdit", version=1)
class PixelHeightEdit(Node):
    """Edit a cutout's pixel height where a predictor got it wrong (the math and its
    derivations: pixgraph_nodes.ops.height_edit). ``contact_points`` (flat list u1, v1,
    u2, v2, ... in the cutout's pixels, u right, v down): where the object touches the
    ground — one point, two for a line, three or more for several feet. ``contact_mode``
    ``shift`` keeps the input's shape up each column and subtracts a per-column
    offset, linear in u, that puts the contact points at height 0; ``upright``
    replaces it by the height above the ground line through the points. ``lying``: the
    object lies on the ground (each column's lowest pixel on it, nowhere higher than
    ``thickness`` px; 0 = half the silhouette's median column extent). ``foot_depth``
    moves the ground under the object's body that many rows in front of (> 0, toward
    the camera) or behind (< 0) its contact: a body point's height grows by it, ramped
    in over the lowest ``2 |foot_depth|`` px of height so the contact stays at 0 (a
    sitting figure's body behind its legs, a round belly or ball bulging past its
    visible bottom edge; an input lifted off the ground moves by the whole depth:
    lift it with ``lift`` here instead). ``tilt`` leans it away from (> 0) or toward (< 0) the camera
    about its contact, for a camera looking down by ``elevation``; a sideways lean needs
    no edit. ``lift`` raises it off the ground. At its defaults (no contact points, no
    foot depth, tilt, lift or lying) the height passes through unchanged.

    The page (``pixgraph serve``) draws each contact point as a handle on the placed
    cutout (an empty list: one hollow handle just under the cutout's foot; "+ contact" adds
    points, "- contact" removes the last), the top's ground point as the tilt handle
    (drag it up: taller, down: shorter, by leaning the object; lying down, the same
    handle sets the thickness), the body's ground point as the foot-depth handle (a
    circle on the pixel nearest the mask's centroid: drag it up, the body is taller),
    and "lying down" as a toggle.
    """

    class Inputs:
        height: T.PixelHeight = port(doc="pixel height to edit [px] (e.g. CutoutHeight.height)")
        mask: T.Mask = port(doc="cutout coverage (heights are 0 outside it)")

    class Params:
        contact_points: list[float] = param([], unit="px",
                                            doc="u1, v1, u2, v2, ...: where the object touches the ground "
                                                "(cutout pixels; empty: keep the input's contact)")
        contact_mode: str = param("shift", choices=("shift", "upright"),
                                  doc="shift: keep the shape up each column, put the contact points at 0; upright: "
                                      "height above the ground line through the points")
        tilt: float = param(0.0, min=-80.0, max=80.0, unit="deg",
                            doc="lean away from (> 0) or toward (< 0) the camera about the contact")
        elevation: float = param(20.0, min=0.0, max=89.0, unit="deg",
                                 doc="how far the camera looks down (for tilt)")
        lying: bool = param(False, doc="the object lies on the ground")
        thickness: float = param(0.0, min=0.0, unit="px",
                                 doc="lying: the object's height above the ground (0: half the median "
                                     "column extent)")
        lift: float = param(0.0, min=0.0, unit="px", doc="raise the object this far off the ground")
        foot_depth: float = param(0.0, unit="px",
                                  doc="the ground under the body lies this many rows in front of (> 0) or "
                                      "behind (< 0) the contact; its heights grow by it (not when lying)")

    class Outputs:
        height: T.PixelHeight = port(doc="edited pixel height [px], 0 outside the mask")

    # 2: defaults pass through; 3: shift is a per-column offset; 4: close points: their mean; 5: foot_depth
    impl_version = "6"   # 6: points up to EDGE_SLACK px outside the cutout are put on its edge

    #: what a shell's page draws (read by pixgraph_serve): contact points, the tilt handle
    #: (lying: the thickness), the body's foot-depth ring, the lying toggle, by these
    #: params; ``mask`` names the input with the coverage in the edit's pixels;
    #: ``placed_by`` the params of the downstream node of kind "place" that puts those
    #: pixels on the canvas (``frame`` maps them)
    handles = {"kind": "height_edit", "points": "contact_points", "mode": "contact_mode", "tilt": "tilt",
               "elevation": "elevation", "lying": "lying", "lift": "lift", "depth": "foot_depth",
               "thickness": "thickness", "mask": "mask", "output": "height",
               "placed_by": ("foot", "scale", "flip")}
    #: the geometry of those handles (ops/height_edit.py), for shells that do not import nodes
    frame = staticmethod(height_edit.placed_frame)
    top_point = staticmethod(height_edit.top_point)
    body_point = staticmethod(height_edit.body_point)
    foot_point = staticmethod(foot_of_mask)

    def compute(self, ctx, inputs, params):
        h = np.asarray(inputs.height, np.float32)
        m = np.asarray(inputs.mask, np.float32)
        if m.ndim == 3:
            m = m[..., 0]
        same_size(height=h, mask=m)
        pts = params.contact_points
        if len(pts) % 2:
            raise InputError(f"param 'contact_points': expected pairs u, v (an even count), got {len(pts)} numbers")
        H, W = h.shape
        P = np.asarray(pts, np.float64).reshape(-1, 2)
        # at a working resolution (a page's previews) the cutout has round(size x scale)
        # pixels, up to half a pixel fewer than its size x the scale: a point on its edge
        # (where a page puts a contact dragged below the foot) comes out up to EDGE_SLACK
        # px outside. Such points are put on the edge; points further out are refused.
        s = EDGE_SLACK
        out = P[(P[:, 0] < -s) | (P[:, 0] > W + s) | (P[:, 1] < -s) | (P[:, 1] > H + s)]
        if len(out):
            raise InputError(f"param 'contact_points': point(s) {out.tolist()} outside the {W}x{H} cutout")
        P = np.clip(P, 0.0, [W, H])
        try:
            return {"height": edit_pixel_height(h, m > 0.5, P, params.contact_mode, params.tilt,
                                                params.elevation, params.lying, params.thickness, params.lift,
                                                params.foot_depth)}
        except ValueError as e:
            raise InputError(f"param '{'foot_depth' if 'foot_depth' in str(e) else 'tilt'}': {e}") from None
