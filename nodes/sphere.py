"""pixgraph.Sphere: a procedural ball on the ground (cutout colour, alpha, pixel height)."""
from __future__ import annotations

from pixgraph_nodes import types as T
from pixgraph.node import InputError, Node, node, param, port

from .ops.sphere import sphere_cutout


@node("pixgraph.Sphere", version=1)
class Sphere(Node):
    """A procedural ball resting on the ground, as a cutout with exact pixel height.

    Premultiplied colour, coverage (4x4 samples per pixel) and the pixel height of
    the visible front surface from a ray cast through the camera. Use it as the
    glass object of pixgraph.Refraction.
    """

    class Inputs:
        camera: T.Camera = port(doc="pixel-height camera")

    class Params:
        center_u: float = param(256.0, min=-1e5, max=1e5, unit="px", doc="column of the contact point")
        contact_v: float = param(400.0, min=-1e5, max=1e5, unit="px",
                                 doc="row of the contact point (below the horizon)")
        radius: float = param(0.25, min=1e-6, max=1e6, unit="world units", doc="sphere radius")
        color: list[float] = param([1.0, 1.0, 1.0], length=3, min=0.0, max=1.0, doc="linear colour")

    class Outputs:
        image: T.Image = port(doc="premultiplied linear RGBA")
        alpha: T.Mask = port(doc="coverage")
        height: T.PixelHeight = port(doc="front-surface pixel height [px]")

    impl_version = "1"

    def compute(self, ctx, inputs, params):
        try:
            rgba, h = sphere_cutout(inputs.camera, params.center_u, params.contact_v, params.radius, params.color)
        except ValueError as e:  # a contact point at or above the horizon: the params, not the node
            raise InputError(f"params 'contact_v', 'radius': {e}") from None
        return {"image": rgba, "alpha": rgba[..., 3].copy(), "height": h}
