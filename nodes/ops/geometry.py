"""The Geometry value: a per-pixel 3D reconstruction from pixel height (Reconstruct3D)."""
from __future__ import annotations

import dataclasses

import numpy as np

from .camera import Camera, reconstruct


@dataclasses.dataclass(frozen=True, eq=False)
class Geometry:
    """Per-pixel 3D reconstruction of one pixel-height map through one camera.

    position: float32 (H, W, 3) world points [world units], 0 where invalid.
    normal: float32 (H, W, 3) unit normals, ``normalize(dP/dv x dP/du)``: +Y on the
        ground, +Z (toward the camera) on an upright plane facing it; 0 where invalid.
    depth: float32 (H, W) ``D = -Z`` [world units], 0 where invalid.
    valid: float32 (H, W) 1 where the foot ``v + h`` lies strictly below the horizon;
        pixels at or above it have no 3D point (never one behind the camera).
    camera: the camera it was reconstructed with.
    """

    position: np.ndarray
    normal: np.ndarray
    depth: np.ndarray
    valid: np.ndarray
    camera: Camera

    @property
    def nbytes(self) -> int:
        return int(self.position.nbytes + self.normal.nbytes + self.depth.nbytes + self.valid.nbytes)


def reconstruct_geometry(camera: Camera, pixel_height: np.ndarray) -> Geometry:
    """Reconstruct3D of a pixel-height map (float (H, W) px, the camera's size)."""
    r = reconstruct(camera, pixel_height)
    for a in r.values():
        a.setflags(write=False)  # values flowing between nodes are shared: never mutate
    return Geometry(r["position"], r["normal"], r["depth"], r["valid"], camera)
