"""pixgraph.Camera: the pixel-height camera (no pitch, horizon set by lens shift)."""
from __future__ import annotations

import dataclasses

from pixgraph_nodes import types as T
from pixgraph.node import InputError, Node, node, param, port
from pixgraph_nodes.types import Shape

from .ops.camera import Camera as CameraValue


#: the horizon row the default suits: a third of the way down a 480-px photo [px]
DEFAULT_HORIZON = 120.0


@dataclasses.dataclass(frozen=True)
class CameraShape(Shape):
    """What a check before running knows of a camera: its image size and its horizon
    row [px] (a node that places things on the ground can tell a foot above it)."""

    horizon: float | None = None


@node("pixgraph.Camera", version=1)
class Camera(Node):
    """Pixel-height camera: image size, horizontal field of view, horizon row and height.

    The size comes from the ``image`` input (the background photo) when ``width`` and
    ``height`` are 0, the default, so a user never types it; given both ways, they
    must agree.

    The horizon is the artist's main perspective control (PixHt-Lab's tilt-shift
    camera): moving it changes how shadows stretch without tilting the geometry.
    """

    class Inputs:
        image: T.Image = port(optional=True, doc="the background: the camera takes its size")

    class Params:
        width: int = param(0, min=0, max=65536, unit="px", doc="image width; 0: the image input's")
        height: int = param(0, min=0, max=65536, unit="px", doc="image height; 0: the image input's")
        hfov: float = param(50.0, min=1.0, max=170.0, unit="deg", doc="horizontal field of view")
        horizon: float = param(DEFAULT_HORIZON, min=-100000.0, max=100000.0, unit="px",
                               doc="image row of the horizon (may lie outside the image)")
        cam_height: float = param(1.0, min=1e-6, max=1e6, unit="world units",
                                  doc="camera height above the ground; only scales the 3D scene")

    class Outputs:
        camera: T.Camera = port(doc="the camera value (pixgraph_nodes.ops.camera.Camera)")

    impl_version = "1"
    #: what a shell's page draws (read by pixgraph_serve): the image size and the horizon row
    handles = {"kind": "camera", "size": ("width", "height"), "row": "horizon"}

    def infer(self, ctx, inputs, params):
        img = inputs.image
        if img is not None:
            if (params.width or img.width, params.height or img.height) != (img.width, img.height):
                raise InputError(f"camera size {params.width}x{params.height} differs from its image "
                                 f"{img.described()}: leave width and height at 0 to take the image's size")
            if params.horizon == DEFAULT_HORIZON and img.height >= 2 * 480:   # twice the photo it suits
                ctx.log(f"horizon left at its default row {DEFAULT_HORIZON:g}, which suits a 480-px-tall photo, "
                        f"on the {img.described()}: set the horizon row (see docs/own-photo.md, 'The horizon')")
            return {"camera": CameraShape(img.height, img.width, None, img.source, params.horizon)}
        if params.width and params.height:
            return {"camera": CameraShape(params.height, params.width, None,
                                          f"node {ctx.node_id!r} (width, height)", params.horizon)}
        return {}  # size from an image of unknown size (a host input): checked when it runs

    def compute(self, ctx, inputs, params):
        width, height = params.width, params.height
        if inputs.image is not None:
            ih, iw = inputs.image.shape[:2]
            if (width or iw, height or ih) != (iw, ih):
                raise InputError(f"camera size {width}x{height} differs from its image {iw}x{ih}: "
                                 "leave width and height at 0 to take the image's size")
            width, height = iw, ih
        elif not (width and height):
            raise InputError("the camera needs width and height, or an image input to take them from")
        return {"camera": CameraValue(width, height, params.hfov, params.horizon, params.cam_height)}
