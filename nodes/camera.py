"""pixgraph.Camera: the pixel-height camera (no pitch, horizon set by lens shift)."""
from __future__ import annotations

from pixgraph import types as T
from pixgraph.node import node, param, port

from .ops.camera import Camera as CameraValue


@node("pixgraph.Camera", version=1)
class Camera:
    """Pixel-height camera: image size, horizontal field of view, horizon row and height.

    The horizon is the artist's main perspective control (PixHt-Lab's tilt-shift
    camera): moving it changes how shadows stretch without tilting the geometry.
    """

    class Params:
        width: int = param(512, min=1, max=65536, unit="px", doc="image width")
        height: int = param(512, min=1, max=65536, unit="px", doc="image height")
        hfov: float = param(50.0, min=1.0, max=170.0, unit="deg", doc="horizontal field of view")
        horizon: float = param(120.0, min=-100000.0, max=100000.0, unit="px",
                               doc="image row of the horizon (may lie outside the image)")
        cam_height: float = param(1.0, min=1e-6, max=1e6, unit="world units",
                                  doc="camera height above the ground; only scales the 3D scene")

    class Outputs:
        camera: T.Camera = port(doc="the camera value (pixgraph_nodes.ops.camera.Camera)")

    impl_version = "1"

    def compute(self, ctx, inputs, params):
        return {"camera": CameraValue(params.width, params.height, params.hfov, params.horizon,
                                      params.cam_height)}
