"""A procedural sphere (a glass ball) standing on the ground, as a cutout with pixel height.

Units: image in pixels; the sphere's radius in world units (the camera's scale,
``cam_height`` = camera height above the ground).
"""
from __future__ import annotations

import numpy as np

from .camera import Camera


def _hit(camera: Camera, u, v, centre, radius):
    """Nearest ray-sphere hit of the view rays through image points (u, v):
    ``(P, hit)`` with P (..., 3) world points (the closest point on the sphere to
    the ray where it misses) and hit bool (...)."""
    o = np.array([0.0, camera.cam_height, 0.0])
    r = camera.ray(u, v)
    r = r / np.linalg.norm(r, axis=-1, keepdims=True)
    oc = o - centre
    b = np.sum(r * oc, axis=-1)
    c = np.dot(oc, oc) - radius * radius
    disc = b * b - c
    hit = (disc >= 0) & (-b - np.sqrt(np.maximum(disc, 0)) > 0)
    t = -b - np.sqrt(np.maximum(disc, 0.0))
    q = o + np.maximum(-b, 0.0)[..., None] * r          # closest approach to the centre
    qc = q - centre
    qn = np.linalg.norm(qc, axis=-1, keepdims=True)
    p_miss = centre + radius * qc / np.where(qn > 0, qn, 1.0)
    P = np.where(hit[..., None], o + t[..., None] * r, p_miss)
    return P, hit


def sphere_cutout(camera: Camera, center_u: float, contact_v: float, radius: float,
                  color=(1.0, 1.0, 1.0), supersample: int = 4):
    """A sphere of ``radius`` (world units) resting on the ground with its contact
    point at image ``(center_u, contact_v)`` (pixels; must be below the horizon).

    Returns ``(rgba, height)``: float32 (H, W, 4) premultiplied linear colour
    (``color`` times coverage; coverage from ``supersample``^2 samples per pixel)
    and float32 (H, W) pixel height of the visible front surface [px], 0 outside.
    """
    if not contact_v > camera.horizon:
        raise ValueError(f"the sphere's contact row {contact_v} must lie below the horizon {camera.horizon}")
    (P0,), _ = camera.back_project([center_u], [contact_v], [0.0])
    centre = np.array([P0[0], radius, P0[2]])
    H, W = camera.height, camera.width
    rgba = np.zeros((H, W, 4), np.float32)
    height = np.zeros((H, W), np.float32)
    # only the pixels of the sphere's image can be hit: the rays are traced in the
    # bounding box of its bounding cube's projected corners (exact when the cube is
    # in front of the camera: the image of a convex body lies in the convex hull of
    # its box's image), plus a pixel for the supersamples
    r0, r1, c0, c1 = 0, H, 0, W
    corners = centre + radius * np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    cuvh, cD = camera.project(corners)
    if np.all(cD > 0) and np.all(np.isfinite(cuvh)):
        c0, c1 = max(0, int(np.floor(cuvh[:, 0].min())) - 1), min(W, int(np.ceil(cuvh[:, 0].max())) + 1)
        r0, r1 = max(0, int(np.floor(cuvh[:, 1].min())) - 1), min(H, int(np.ceil(cuvh[:, 1].max())) + 1)
        if c1 <= c0 or r1 <= r0:
            return rgba, height
    u, v = camera.pixel_grid()
    u, v = u[r0:r1, c0:c1], v[r0:r1, c0:c1]
    cov = np.zeros(u.shape)
    n = int(supersample)
    for a in range(n):
        for b in range(n):
            _, hit = _hit(camera, u - 0.5 + (a + 0.5) / n, v - 0.5 + (b + 0.5) / n, centre, radius)
            cov += hit
    cov /= n * n
    P, _ = _hit(camera, u, v, centre, radius)
    uvh, D = camera.project(P)
    height[r0:r1, c0:c1] = np.where(cov > 0, uvh[..., 2], 0.0)
    rgba[r0:r1, c0:c1, :3] = cov[..., None] * np.asarray(color, np.float32)
    rgba[r0:r1, c0:c1, 3] = cov
    return rgba, height
