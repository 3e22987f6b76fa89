"""pixgraph.Reconstruct3D: 3D positions, normals and depth from pixel height (paper Eq. 3-4)."""
from __future__ import annotations

from pixgraph_nodes import types as T
from pixgraph.node import Node, node, port

from .ops.geometry import reconstruct_geometry


@node("pixgraph.Reconstruct3D", version=1)
class Reconstruct3D(Node):
    """Back-project every pixel through the camera using its pixel height.

    A pixel whose foot (v + h) is at or above the horizon has no 3D point: it is
    marked invalid (valid = 0) and its position, normal and depth are 0; no point is
    ever placed behind the camera.
    """

    class Inputs:
        camera: T.Camera = port(doc="pixel-height camera, same size as the map")
        height: T.PixelHeight = port(doc="pixel height [px]")

    class Outputs:
        geometry: T.Geometry = port(doc="positions, normals, depth, valid and the camera")
        positions: T.Image = port(doc="float32 (H, W, 3) world positions [world units]")
        normals: T.Image = port(doc="float32 (H, W, 3) unit normals (+Y ground, +Z facing the camera)")
        depth: T.Image = port(doc="float32 (H, W) depth D = -Z [world units]")
        valid: T.Mask = port(doc="1 where the pixel could be reconstructed")

    impl_version = "1"

    def compute(self, ctx, inputs, params):
        g = reconstruct_geometry(inputs.camera, inputs.height)
        return {"geometry": g, "positions": g.position, "normals": g.normal, "depth": g.depth,
                "valid": g.valid}
