"""The light's screen geometry: where, in the image, a light's handle is.

A light is dragged by its *shadow tip*: the ground point where the shadow of the
object's top falls. ``lights.from_shadow_tip`` makes the light from a tip; the
functions here are the rest of that geometry, in image pixels (``u`` right,
``v`` down, ``h`` pixel height above the ground point below, as ``camera.py``):

- ``object_top``: the object's top point ``(u, v, h)`` from its mask and pixel heights;
- ``shadow_tip``: the inverse of ``from_shadow_tip``, the tip a given light puts the
  top's shadow at;
- ``tip_at_elevation``: the tip on the same ground direction from the top's foot
  at which the light, seen from the top, has a given elevation.
- ``tip_at_angles``: the tip at which the light, seen from the top, has a given
  azimuth and elevation (the inverse of ``lights.tip_angles``).

Plain functions of a ``Camera`` and a ``Light`` (``pixgraph.Light`` exposes them
to shells such as ``pixgraph serve`` without their importing this package).
"""
from __future__ import annotations

import math

import numpy as np


def object_top(mask: np.ndarray, fg_height: np.ndarray) -> tuple[float, float, float] | None:
    """(u, v, h) [px] of the object's top: the centre of the middle covered pixel of the
    mask's highest covered row (coverage > 0.5), and the pixel height there; None
    for an empty mask."""
    m = np.asarray(mask)
    if m.ndim == 3:
        m = m[:, :, 0]
    m = m > 0.5
    rows = np.nonzero(m.any(axis=1))[0]
    if rows.size == 0:
        return None
    row = int(rows[0])
    cols = np.nonzero(m[row])[0]
    col = int(cols[len(cols) // 2])
    h = np.asarray(fg_height)
    h = h[:, :, 0] if h.ndim == 3 else h
    return float(col + 0.5), float(row + 0.5), float(h[row, col])


def shadow_tip(camera, light, top_uvh) -> tuple[float, float] | None:
    """Image point (u, v) [px] where ``light`` casts the shadow of ``top_uvh`` (u, v, h)
    onto the ground plane; None when there is none in front of the camera (no top,
    h <= 0, a light at or below the top's height)."""
    if top_uvh is None or top_uvh[2] <= 0:
        return None
    P, ok = camera.back_project(*top_uvh)
    if not ok:
        return None
    if light.kind == "directional":
        d = np.asarray(light.direction, dtype=np.float64)
        if d[1] <= 1e-9:
            return None
        T = P - d * (P[1] / d[1])
    else:
        L = np.asarray(light.position, dtype=np.float64)
        if L[1] <= P[1] + 1e-9:
            return None
        T = L + (P - L) * (L[1] / (L[1] - P[1]))
    uvh, D = camera.project(T)
    if not (D > 0 and np.all(np.isfinite(uvh))):
        return None
    return float(uvh[0]), float(uvh[1])


def tip_at_elevation(camera, tip_uv, top_uvh, elevation_deg: float) -> tuple[float, float]:
    """The ground point (u, v) [px], in the direction of ``tip_uv`` from the foot of the
    top point, from which the top is seen at ``elevation_deg`` above the horizontal
    (so a light on the line from it through the top has that elevation).

    Raises ValueError for an elevation outside [0.5, 90) degrees, a tip or top above
    the horizon, or a tip that would leave the ground in view."""
    _check_elevation(elevation_deg)
    P, okp = camera.back_project(*top_uvh)
    T, okt = camera.back_project(tip_uv[0], tip_uv[1], 0.0)
    if not (okp and okt):
        raise ValueError("the shadow tip or the object's top is above the horizon")
    d = T - np.array([P[0], 0.0, P[2]])
    n = math.hypot(d[0], d[2])
    d = d / n if n > 1e-9 else np.array([0.0, 0.0, -1.0])
    return _tip_along(camera, P, d, elevation_deg, f"at elevation {elevation_deg}")


def tip_at_angles(camera, top_uvh, azimuth_deg: float, elevation_deg: float) -> tuple[float, float]:
    """The ground point (u, v) [px] where a light at ``azimuth_deg`` and ``elevation_deg``
    seen from the top point (``lights.from_controls``' angles: azimuth 0 toward the
    camera, 90 to the right) casts the top's shadow: ``lights.tip_angles`` of it gives
    those angles back.

    Raises ValueError for an elevation outside [0.5, 90) degrees, a top above the
    horizon or without height, or a tip that would leave the ground in view."""
    _check_elevation(elevation_deg)
    P, ok = camera.back_project(*top_uvh)
    if not ok or top_uvh[2] <= 0:
        raise ValueError("the object's top needs a height > 0 and its foot below the horizon")
    az = math.radians(azimuth_deg)
    d = np.array([-math.sin(az), 0.0, -math.cos(az)])         # from the top's foot, away from the light
    return _tip_along(camera, P, d, elevation_deg, f"at azimuth {azimuth_deg}, elevation {elevation_deg}")


#: [lo, hi) degrees of the elevations ``tip_at_elevation`` and ``tip_at_angles`` accept:
#: at 90 the tip is the top's foot (no ground direction left), toward 0 it runs off to
#: the horizon; a shell's elevation slider reads it as ``tip_at_elevation.elevation_range``
TIP_ELEVATION_RANGE = (0.5, 90.0)


def _check_elevation(elevation_deg: float) -> None:
    lo, hi = TIP_ELEVATION_RANGE
    if not lo <= elevation_deg < hi:
        raise ValueError(f"elevation must be in [{lo:g}, {hi:g}) degrees, got {elevation_deg}")


tip_at_elevation.elevation_range = TIP_ELEVATION_RANGE
tip_at_angles.elevation_range = TIP_ELEVATION_RANGE


def _tip_along(camera, P, d, elevation_deg: float, what: str) -> tuple[float, float]:
    """The image point of the ground point ``P[1] / tan(elevation)`` along the unit ground
    direction ``d`` from the foot of the 3D top ``P``: where the top is seen at that
    elevation. ValueError (starting with ``what``) when it leaves the ground in view."""
    new = np.array([P[0], 0.0, P[2]]) + d * (P[1] / math.tan(math.radians(elevation_deg)))
    uvh, D = camera.project(new)
    if not (D > 0 and np.all(np.isfinite(uvh))):
        raise ValueError(f"{what} the shadow tip leaves the ground in view")
    return float(uvh[0]), float(uvh[1])
