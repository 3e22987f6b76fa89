"""pixgraph.BackgroundHeight: background pixel height from a template with a few handles."""
from __future__ import annotations

from pixgraph_nodes import types as T
from pixgraph.node import InputError, Node, node, param, port

from .ops import heightmaps as hm


@node("pixgraph.BackgroundHeight", version=1)
class BackgroundHeight(Node):
    """Background pixel height from a template: ground, walls on a junction line, steps, cove.

    Wall templates (back_wall, wall_corner, two_corners) are drawn in the image: the
    floor/wall junction line, and h = max(0, v_wall(u) - v) above it. ``steps`` and
    ``curved`` are 3D shapes in world units (the camera's cam_height sets the scale)
    ray-cast through the camera. To load a map from a file use pixgraph.LoadPixelHeight.
    """

    class Inputs:
        camera: T.Camera = port(doc="camera; gives the image size and, for steps/curved, the projection")

    class Params:
        kind: str = param("ground", choices=hm.BACKGROUND_KINDS, doc="template")
        junction_row: float = param(300.0, min=-1e6, max=1e6, unit="px",
                                    doc="back_wall: junction row at the image centre column")
        junction_slope: float = param(0.0, min=-100.0, max=100.0, unit="px/px",
                                      doc="back_wall: junction slope dv/du")
        junction_points: list[float] = param([], min=-1e6, max=1e6, unit="px",
                                             doc="walls: explicit junction polyline u0, v0, u1, v1, ... "
                                                 "(overrides the other wall handles when given)")
        corner: list[float] = param([256.0, 300.0], length=2, min=-1e6, max=1e6, unit="px",
                                    doc="wall_corner: the corner (u, v); two_corners: the left corner")
        corner2: list[float] = param([384.0, 300.0], length=2, min=-1e6, max=1e6, unit="px",
                                     doc="two_corners: the right corner (u, v)")
        left_slope: float = param(-0.3, min=-100.0, max=100.0, unit="px/px",
                                  doc="corners: junction slope dv/du left of the (left) corner")
        right_slope: float = param(0.3, min=-100.0, max=100.0, unit="px/px",
                                   doc="corners: junction slope dv/du right of the (right) corner")
        step_distance: float = param(3.0, min=1e-6, unit="world units",
                                     doc="steps: depth of the first riser from the camera")
        step_rise: float = param(0.15, min=0.0, unit="world units", doc="steps: riser height")
        step_run: float = param(0.35, min=1e-6, unit="world units", doc="steps: tread depth")
        step_count: int = param(4, min=0, max=1000, doc="steps: number of risers")
        wall_distance: float = param(4.0, min=1e-6, unit="world units",
                                     doc="curved: depth of the back wall plane")
        cove_radius: float = param(1.0, min=0.0, unit="world units",
                                   doc="curved: radius of the floor-to-wall cove")

    class Outputs:
        height: T.PixelHeight = port(doc="background pixel height [px]")

    impl_version = "1"
    disk_cache = False      # large and cheaper to recompute than to read back from disk
    #: what a shell's page draws (read by pixgraph_serve): the template's handles, i.e. these
    #: params by ``kind`` (points ``corner``/``corner2``, slopes, the junction row, the
    #: junction_points that override them)
    handles = {"kind": "background", "params": ("kind", "corner", "corner2", "left_slope", "right_slope",
                                                "junction_row", "junction_slope", "junction_points")}

    def compute(self, ctx, inputs, params):
        cam = inputs.camera
        W, H = cam.width, cam.height
        k = params.kind
        pts = params.junction_points
        if pts and k in ("back_wall", "wall_corner", "two_corners"):
            if len(pts) < 4 or len(pts) % 2:
                raise InputError(f"param 'junction_points': needs an even count >= 4 of numbers, got {len(pts)}")
            try:
                h = hm.wall_from_junction(W, H, list(zip(pts[0::2], pts[1::2])))
            except ValueError as e:  # e.g. two points at one u: the user's numbers, not a bug
                raise InputError(f"param 'junction_points': {e}") from None
        elif k == "ground":
            h = hm.ground(W, H)
        elif k == "back_wall":
            h = hm.back_wall(W, H, params.junction_row, params.junction_slope)
        elif k == "wall_corner":
            h = hm.wall_corner(W, H, params.corner, params.left_slope, params.right_slope)
        elif k == "two_corners":
            h = hm.two_corners(W, H, params.corner, params.corner2, params.left_slope, params.right_slope)
        elif k == "steps":
            h = hm.steps(cam, params.step_distance, params.step_rise, params.step_run, params.step_count)
        elif k == "curved":
            h = hm.curved(cam, params.wall_distance, min(params.cove_radius, params.wall_distance))
        else:  # pragma: no cover - choices are checked by the param declaration
            raise ValueError(k)
        return {"height": h}
