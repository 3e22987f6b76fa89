"""The pixel-height camera (PixHt-Lab Sec. 3.1, design.md §2).

A pinhole with **no pitch** (vertical image plane) whose horizon is placed by a
vertical lens shift. World is y-up, the ground is ``Y = 0``, the camera centre is
``O' = (0, H_cam, 0)`` looking down ``-Z``.

Image coordinates: ``u`` right, ``v`` down, in pixels, pixel centres at ``+0.5``.
A pixel's ray is ``a u + b v + c`` with ``a = (1, 0, 0)``, ``b = (0, -1, 0)``,
``c = (-W/2, horizon, -f)`` and ``f = (W/2) / tan(hfov/2)`` (pixels).

Pixel height ``h`` (pixels) is the image distance between a point and its foot on
the ground; the foot of ``(u, v)`` is ``(u, v + h)``.

    back-projection  w = H_cam / (v + h - horizon)
                     P = O' + w (u - W/2, horizon - v, -f)
    projection       D = -Z (depth, world units)
                     (u, v, h) = (W/2 + f X / D, horizon + f (H_cam - Y) / D, f Y / D)

All three projected coordinates share the denominator D, so straight 3D lines stay
straight in (u, v, h) space and ``h`` is linear along an image segment.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np


@dataclasses.dataclass(frozen=True)
class Camera:
    """Pixel-height camera.

    width, height: image size in pixels.
    hfov: horizontal field of view in degrees (0 < hfov < 180).
    horizon: image row of the horizon in pixels (may lie outside the image).
    cam_height: camera height above the ground ``H_cam`` in world units; it only
        scales the reconstructed scene.
    """

    width: int
    height: int
    hfov: float = 45.0
    horizon: float = 0.0
    cam_height: float = 1.0

    def __post_init__(self):
        if self.width < 1 or self.height < 1:
            raise ValueError(f"camera size must be positive, got {self.width}x{self.height}")
        if not (0.0 < self.hfov < 180.0):
            raise ValueError(f"hfov must be in (0, 180) degrees, got {self.hfov}")
        if not (self.cam_height > 0.0 and math.isfinite(self.cam_height)):
            raise ValueError(f"cam_height must be positive, got {self.cam_height}")
        if not math.isfinite(self.horizon):
            raise ValueError(f"horizon must be finite, got {self.horizon}")

    @property
    def focal(self) -> float:
        """Focal length ``f`` in pixels."""
        return (self.width / 2.0) / math.tan(math.radians(self.hfov) / 2.0)

    def scaled(self, s: float) -> "Camera":
        """The same camera for the image resized by ``s`` (pixel heights scale by ``s`` too)."""
        return dataclasses.replace(self, width=max(1, round(self.width * s)),
                                   height=max(1, round(self.height * s)),
                                   horizon=self.horizon * s)

    def pixel_grid(self) -> tuple[np.ndarray, np.ndarray]:
        """(u, v) of every pixel centre, each float64 (height, width)."""
        u = np.arange(self.width, dtype=np.float64) + 0.5
        v = np.arange(self.height, dtype=np.float64) + 0.5
        return np.meshgrid(u, v)

    # -- the two maps --------------------------------------------------------
    def back_project(self, u, v, h):
        """3D points of image points with pixel height.

        Returns ``(P, valid)``: P float64 (..., 3) world units, valid bool (...).
        A point is valid only when its foot lies strictly below the horizon
        (``v + h > horizon``); invalid points are set to NaN, never placed
        behind the camera.
        """
        u, v, h = (np.asarray(x, dtype=np.float64) for x in (u, v, h))
        denom = v + h - self.horizon
        valid = np.isfinite(denom) & (denom > 1e-9)
        w = np.where(valid, self.cam_height / np.where(valid, denom, 1.0), np.nan)
        P = np.stack([w * (u - self.width / 2.0),
                      self.cam_height + w * (self.horizon - v),
                      -self.focal * w], axis=-1)
        return P, valid

    def project(self, P):
        """(u, v, h) in pixels of 3D points P (..., 3), and depth D = -Z.

        Returns ``(uvh, D)`` with uvh float64 (..., 3). Points behind the camera
        plane (D < 0) project through the same formulas (homogeneous division), so
        their ``h`` has the sign of ``Y / D``; callers decide what that means.
        """
        P = np.asarray(P, dtype=np.float64)
        X, Y, Z = P[..., 0], P[..., 1], P[..., 2]
        D = -Z
        with np.errstate(divide="ignore", invalid="ignore"):
            f = self.focal
            uvh = np.stack([self.width / 2.0 + f * X / D,
                            self.horizon + f * (self.cam_height - Y) / D,
                            f * Y / D], axis=-1)
        return uvh, D

    def direction_to_image(self, d):
        """Image point (u, v) of a direction ``d`` (the vanishing point), and its sign.

        Returns ``(uv, s)``: ``s = +1`` when ``d`` points away from the camera
        (``d_z < 0``), ``-1`` when toward it, ``0`` when parallel to the image
        plane (then ``uv`` is NaN: the vanishing point is at infinity).
        """
        d = np.asarray(d, dtype=np.float64)
        dz = -d[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = np.stack([self.width / 2.0 + self.focal * d[..., 0] / dz,
                           self.horizon - self.focal * d[..., 1] / dz], axis=-1)
        return uv, np.sign(dz)

    def ray(self, u, v):
        """Unnormalised view ray ``a u + b v + c`` of image points, (..., 3)."""
        u, v = np.asarray(u, dtype=np.float64), np.asarray(v, dtype=np.float64)
        return np.stack([u - self.width / 2.0, self.horizon - v, np.full(np.broadcast(u, v).shape, -self.focal)], axis=-1)

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


def reconstruct(camera: Camera, pixel_height: np.ndarray):
    """Reconstruct3D: positions, depth, normals and validity of every pixel.

    pixel_height: float (H, W) pixels, H, W equal to the camera's size.
    Returns a dict of float32 arrays: ``position`` (H, W, 3) world units,
    ``depth`` (H, W) world units, ``normal`` (H, W, 3) unit vectors, and
    ``valid`` (H, W) 1.0 where the foot lies below the horizon. Invalid pixels
    have position, depth and normal 0.

    Normals are ``normalize(dP/dv x dP/du)`` by central differences (one-sided at
    the border and next to invalid pixels): +Y on the ground, +Z toward the
    camera on an upright plane.
    """
    h = np.asarray(pixel_height, dtype=np.float64)
    if h.shape != (camera.height, camera.width):
        raise ValueError(f"pixel height is {h.shape[1]}x{h.shape[0]} but the camera is "
                         f"{camera.width}x{camera.height}")
    u, v = camera.pixel_grid()
    P, valid = camera.back_project(u, v, h)
    valid &= np.isfinite(h)
    normal = surface_normals(P, valid)
    P = np.where(valid[..., None], P, 0.0)
    return {
        "position": P.astype(np.float32),
        "depth": np.where(valid, -P[..., 2], 0.0).astype(np.float32),
        "normal": normal.astype(np.float32),
        "valid": valid.astype(np.float32),
    }


def surface_normals(P: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Unit normals ``normalize(dP/dv x dP/du)`` of a position map P (H, W, 3).

    Differences use only valid neighbours: central where both exist, one-sided
    otherwise; pixels with no valid neighbour along an axis get normal 0.
    """
    def deriv(axis: int) -> np.ndarray:
        Pf = np.where(valid[..., None], P, 0.0)
        n = P.shape[axis]
        fwd = np.zeros_like(Pf)
        bwd = np.zeros_like(Pf)
        okf = np.zeros(valid.shape, bool)
        okb = np.zeros(valid.shape, bool)
        sl = lambda a, b: tuple(slice(a, b) if i == axis else slice(None) for i in range(2))
        if n > 1:
            fwd[sl(0, n - 1)] = Pf[sl(1, n)] - Pf[sl(0, n - 1)]
            okf[sl(0, n - 1)] = valid[sl(1, n)] & valid[sl(0, n - 1)]
            bwd[sl(1, n)] = fwd[sl(0, n - 1)]
            okb[sl(1, n)] = okf[sl(0, n - 1)]
        both = okf & okb
        d = np.where(both[..., None], 0.5 * (fwd + bwd),
                     np.where(okf[..., None], fwd, np.where(okb[..., None], bwd, 0.0)))
        return d

    dPdu = deriv(1)
    dPdv = deriv(0)
    n = np.cross(dPdv, dPdu)
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        n = np.where(norm > 0, n / np.where(norm > 0, norm, 1.0), 0.0)
    return np.where(valid[..., None], n, 0.0)
