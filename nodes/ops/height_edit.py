"""Editing a cutout's pixel height by hand: contact points, foot depth, tilt, lying down, lift.

Plain numpy; the node is ``pixgraph.PixelHeightEdit`` (nodes/pixel_height_edit.py).
Pixel coordinates: ``u`` to the right, ``v`` down, pixel (row r, column c) has its
centre at ``(u, v) = (c + 0.5, r + 0.5)``; heights are in pixels (the vertical
image distance from an object point down to its foot on the ground).

``edit_pixel_height(height, mask, ...)`` applies, in this order:

1. **Contact points** ``[(u1, v1), ...]`` (where the object touches the ground:
   one point, two for a line, three or more for several feet):

   * ``contact_mode="shift"`` keeps the map's shape up each column and
     subtracts a per-column offset ``c(u)``, linear across the columns, that
     brings the contact points to height 0: a constant for one point (its
     height), the line through both points' heights for two, the least-squares
     line ``a + b u`` for three or more; points that span less than
     ``ONE_PLACE`` of the object's width (its mask's columns) are one place and
     get their mean (a pole's front and back foot: a line through two points a
     pixel apart would tilt the map by their height difference per pixel).
     ``c`` does not vary with the
     row ``v``: the contact says how far the object floats or sinks, not how its
     height grows up a column, so feet at different rows (front and back feet)
     cannot take away the map's own slope up the object (a plane ``a + b u +
     d v`` through three feet did: ``d`` times the object's pixel height, often
     the whole map).
   * ``contact_mode="upright"`` replaces the map by the height above the
     ground line through the points (the contact-line model of an upright object
     facing the camera): ``h = v_line(u) - v`` with ``v_line`` the row of the
     line at column ``u`` — horizontal through one point, through two, the
     least-squares line ``v = a + b u`` through three or more.

2. **Lying down** (``lying=True``): an object lying on the ground has each
   column's lowest pixel on the ground and is nowhere higher than its thickness:
   ``h = min(v_bottom(u) - v, thickness)``, ``v_bottom(u)`` the bottom edge of the
   column's lowest mask pixel; ``thickness`` [px] <= 0 means half the median
   column extent of the silhouette. Replaces steps 1's result (contact points
   are ignored: every column touches the ground).

2b. **Foot depth** ``foot_depth`` [px] (not when lying): where the ground under
   the object's body lies, relative to its contact. A map from the contact
   line (or a learned one) puts the foot of every point of a column on the
   contact's row; but a sitting teddy's body stands behind its legs, a duck's
   round belly bulges toward the camera past its visible bottom edge, a ball's
   lowest visible pixels are its front, not its contact. With the body's
   ground ``D`` rows lower in the image than the contact (in front of it,
   toward the camera; ``D < 0``: behind it, higher in the image) a body point's
   foot moves ``D`` rows down, so its height grows by ``D``. The heights near
   the contact keep it at 0, so the change is ramped in over the lowest ``2|D|``
   px of height:

   ``h' = h + D * clip(h / (2 |D|), 0, 1)``

   (slope 3/2 (``D > 0``) or 1/2 (``D < 0``) below ``2|D|``, ``h + D`` above).
   Strictly increasing and continuous, so the page can invert it at any
   point; the contact stays at 0. The ramp is measured from height 0: an input
   whose contact is already above the ground (``CutoutHeight``'s ``contact:
   lifted``) moves by the whole ``D``, contact included; lift the object with
   this node's ``lift`` (step 4, after the foot depth) instead. A point of height ``h0`` goes up to ``1.5 h0``
   or down to ``h0 / 2``. The page's body handle is the covered pixel nearest
   the mask's centroid (``body_point``), with a guide down to the ground under
   it; dragging it sets ``D`` (``depth_for_height``, the inverse at that point).

3. **Tilt** ``tilt_deg`` (leaning away from the camera > 0, toward it < 0) about
   the contact, for a camera looking down by ``elevation_deg``: a point of an
   upright object that leans back by phi is farther away the higher it is, so the
   same image row above the contact is a smaller height. With an orthographic
   view from elevation alpha a point at height y and depth offset y tan(phi) is
   ``r = y cos(alpha) + y tan(phi) sin(alpha)`` rows above its contact and its
   pixel height is ``y cos(alpha)``, so heights scale by
   ``g = 1 / (1 + tan(phi) tan(alpha))``. (A sideways lean, in the image plane,
   changes no pixel height: a point's foot is straight below it in the image
   whatever the lean, at the contact's row for an object facing the camera.)

4. **Lift** ``lift`` [px]: added to every pixel (the object floats; its former
   contact is ``lift`` px above the ground).

Finally heights are clipped to >= 0 and set to 0 outside ``mask``. With nothing
to edit (no contact points, no foot depth, not lying, no tilt, no lift) the input passes through
unchanged (``is_identity``): a graph with the node at its defaults renders exactly
as one without it.

**For a page drawing the handles** (``PixelHeightEdit.handles``): ``placed_frame``
maps the edit's pixels (the cutout's) to the canvas the cutout is placed on (the
similarity of ``placement``: ``X = foot_u +- s (x - ax)``, ``Y = foot_v + s (y -
ay)``, anchor ``(ax, ay)`` the mask's foot); ``top_point`` is the object's top and
its height before the tilt, from which ``tilt_for_height`` gives the tilt that
puts the top's ground point at a dragged height (the inverse of step 3); lying,
the same handle sets the thickness (``thickness_for_height``: the top's height
is ``g min(extent, thickness) + lift``). ``body_point`` is the body handle's
pixel and its height before the foot depth, tilt and lift, from which
``depth_for_height`` gives the foot depth that puts its ground point at a
dragged height (step 2b inverted).
"""
from __future__ import annotations

import math

import numpy as np

from .light_screen import object_top


def _points(points) -> np.ndarray:
    P = np.asarray(points, np.float64).reshape(-1, 2) if len(points) else np.zeros((0, 2))
    if not np.isfinite(P).all():
        raise ValueError("contact points must be finite")
    return P


def sample_height(height: np.ndarray, u: float, v: float) -> float:
    """Bilinear sample of a pixel-height map at pixel coordinates (u, v) (module doc)."""
    H, W = height.shape
    x = min(max(u - 0.5, 0.0), W - 1.0)
    y = min(max(v - 0.5, 0.0), H - 1.0)
    x0, y0 = int(math.floor(x)), int(math.floor(y))
    x1, y1 = min(x0 + 1, W - 1), min(y0 + 1, H - 1)
    fx, fy = x - x0, y - y0
    return float((1 - fy) * ((1 - fx) * height[y0, x0] + fx * height[y0, x1])
                 + fy * ((1 - fx) * height[y1, x0] + fx * height[y1, x1]))


#: contact points spanning less than this fraction of the object's width are one place
ONE_PLACE = 0.1


def contact_correction(height: np.ndarray, points, width: float | None = None) -> np.ndarray:
    """The per-column offset c(u) (H, W) that ``contact_mode="shift"`` subtracts (module
    doc); ``width`` [px]: the object's width (default: the map's)."""
    P = _points(points)
    H, W = height.shape
    u = np.broadcast_to(np.arange(W) + 0.5, (H, W))
    if len(P) == 0:
        return np.zeros((H, W))
    hs = np.array([sample_height(height, pu, pv) for pu, pv in P])
    if len(P) == 1 or np.ptp(P[:, 0]) < max(ONE_PLACE * (W if width is None else width), 1e-9):
        return np.full((H, W), hs.mean())
    b, a = np.polyfit(P[:, 0], hs, 1)
    return a + b * u


def ground_line(points) -> tuple[float, float]:
    """(a, b) of the ground line ``v = a + b u`` through the contact points (module doc)."""
    P = _points(points)
    if len(P) == 0:
        raise ValueError("contact_mode 'upright' needs at least one contact point")
    if len(P) == 1 or np.ptp(P[:, 0]) < 1e-9:
        return float(P[:, 1].mean()), 0.0
    b, a = np.polyfit(P[:, 0], P[:, 1], 1)
    return float(a), float(b)


def lying_height(mask: np.ndarray, thickness: float = 0.0) -> np.ndarray:
    """``min(v_bottom(u) - v, thickness)`` over the mask (module doc, step 2) [px]."""
    m = np.asarray(mask, bool)
    H, W = m.shape
    cols = m.any(0)
    out = np.zeros((H, W))
    if not cols.any():
        return out
    bottom = H - np.argmax(m[::-1], axis=0)          # bottom edge row of each column's lowest pixel
    top = np.argmax(m, axis=0)
    if thickness <= 0:
        thickness = 0.5 * float(np.median((bottom - top)[cols]))
    v = np.arange(H)[:, None] + 0.5
    return np.where(m, np.minimum(np.maximum(bottom[None, :] - v, 0.0), thickness), 0.0)


def foot_depth_height(height: np.ndarray, depth: float) -> np.ndarray:
    """``h + D clip(h / (2 |D|), 0, 1)`` [px] (module doc, step 2b); ``D = depth`` [px], 0: unchanged."""
    h = np.asarray(height, np.float64)
    d = float(depth)
    if d == 0.0:
        return h
    return h + d * np.clip(h / (2.0 * abs(d)), 0.0, 1.0)


def foot_depth_inverse(edited: float, depth: float) -> float:
    """The height [px] before step 2b of a point whose height after it is ``edited`` >= 0
    (the ramp's end ``2|D|`` maps to ``2|D| + D``)."""
    d, e = float(depth), float(edited)
    if d == 0.0:
        return e
    end = 2.0 * abs(d)
    return e - d if e >= end + d else e * end / (end + d)


def body_point(mask: np.ndarray, edited: np.ndarray, tilt_deg: float = 0.0, elevation_deg: float = 20.0,
               lift: float = 0.0, depth: float = 0.0) -> tuple[float, float, float, float] | None:
    """(u, v, h, h0) [px] of the body handle: the centre of the covered pixel (coverage
    > 0.5) nearest the mask's centroid, its edited height ``h`` and ``h0``, its height
    before the foot depth, tilt and lift (``h = g f_D(h0) + lift``, steps 2b-4); None
    for an empty mask or a body point at height 0 (no foot depth moves it)."""
    m = np.asarray(mask)
    m = (m[..., 0] if m.ndim == 3 else m) > 0.5
    ys, xs = np.nonzero(m)
    if len(ys) == 0:
        return None
    k = int(np.argmin((ys - ys.mean()) ** 2 + (xs - xs.mean()) ** 2))
    r, c = int(ys[k]), int(xs[k])
    e = np.asarray(edited)
    h = float((e[..., 0] if e.ndim == 3 else e)[r, c])
    h0 = foot_depth_inverse((h - float(lift)) / tilt_gain(tilt_deg, elevation_deg), depth)
    if not h0 > 0:
        return None
    return c + 0.5, r + 0.5, h, h0


def depth_for_height(h0: float, target: float, gain: float = 1.0, lift: float = 0.0) -> float:
    """The foot depth [px] that gives a point of height ``h0`` before it the height
    ``target`` [px] (``target = gain f_D(h0) + lift``, step 2b inverted: ``D = (target -
    lift) / gain - h0`` while ``|D| <= h0 / 2``, where ``f_D(h0) = h0 + D``), within
    ``[-h0 / 2, h0 / 2]``: a point can go down to half or up to 1.5 times its height."""
    if h0 <= 0 or gain <= 0:
        return 0.0
    return float(np.clip((float(target) - float(lift)) / float(gain) - h0, -h0 / 2.0, h0 / 2.0))


#: the flattest lying thickness [px] a drag gives (thickness 0 is the default, half the
#: median column extent: a drag to the ground must not jump to it)
MIN_THICKNESS = 0.01


def thickness_for_height(target: float, gain: float = 1.0, lift: float = 0.0) -> float:
    """Lying: the thickness [px] that gives the top the height ``target`` [px] (``target
    = gain thickness + lift`` where the top's column is at least that tall); at least
    ``MIN_THICKNESS``."""
    return max(MIN_THICKNESS, (float(target) - float(lift)) / float(gain)) if gain > 0 else MIN_THICKNESS


def tilt_gain(tilt_deg: float, elevation_deg: float) -> float:
    """``1 / (1 + tan(tilt) tan(elevation))`` (module doc, step 3)."""
    d = 1.0 + math.tan(math.radians(tilt_deg)) * math.tan(math.radians(elevation_deg))
    if d <= 1e-6:
        raise ValueError(f"tilt {tilt_deg} deg toward a camera looking down {elevation_deg} deg: "
                         "the object would lie in the view ray (need tan(tilt) tan(elevation) > -1)")
    return 1.0 / d


def is_identity(points=(), tilt_deg: float = 0.0, lying: bool = False, lift: float = 0.0,
                foot_depth: float = 0.0) -> bool:
    """True when ``edit_pixel_height`` has nothing to do: the input passes through (module doc)."""
    return (len(points) == 0 and not lying and float(tilt_deg) == 0.0 and float(lift) == 0.0
            and float(foot_depth) == 0.0)


def placed_frame(mask: np.ndarray, foot, scale: float, flip: bool = False) -> tuple[float, float, float, float]:
    """(sx, tx, sy, ty): the cutout pixel (x, y) lands on the canvas at ``(sx x + tx,
    sy y + ty)`` when placed with its foot at ``foot`` [canvas px], scaled by ``scale``,
    mirrored when ``flip`` (ops/placement.py's similarity, anchor = the mask's foot)."""
    from .lights import foot_of_mask

    m = np.asarray(mask)
    ax, ay = foot_of_mask(m[..., 0] if m.ndim == 3 else m)
    sx = -float(scale) if flip else float(scale)
    return sx, float(foot[0]) - sx * ax, float(scale), float(foot[1]) - float(scale) * ay


def top_point(mask: np.ndarray, edited: np.ndarray, tilt_deg: float = 0.0, elevation_deg: float = 20.0,
              lift: float = 0.0) -> tuple[float, float, float, float] | None:
    """(u, v, h, h0) [px] of the object's top: the middle pixel of the mask's highest
    row, its edited height ``h``, and ``h0`` its height before tilt and lift
    (``h = g h0 + lift``, step 3); None for an empty mask or a top at height 0."""
    top = object_top(mask, edited)   # the same point as the Light node's handle
    if top is None:
        return None
    u, v, h = top
    h0 = (h - float(lift)) / tilt_gain(tilt_deg, elevation_deg)
    if not h0 > 0:
        return None
    return u, v, h, h0


#: the tallest ``tilt_for_height`` makes an object: this many times its height before the tilt
MAX_GAIN = 10.0


def tilt_for_height(h0: float, target: float, lift: float = 0.0, elevation_deg: float = 20.0,
                    limit_deg: float = 80.0) -> float:
    """The tilt [deg] that gives a point of height ``h0`` before tilt the height
    ``target`` [px] (``target = g h0 + lift``, step 3 inverted:
    ``tan(tilt) = (h0 / (target - lift) - 1) / tan(elevation)``), within +-``limit_deg``
    and at most ``MAX_GAIN`` times taller (toward the camera the gain grows without
    bound as the object nears the view ray)."""
    ta = math.tan(math.radians(elevation_deg))
    want = float(target) - float(lift)
    if h0 <= 0 or ta < 1e-9:
        return 0.0
    if want <= 1e-6:
        return limit_deg
    lowest = max(-limit_deg, math.degrees(math.atan((1.0 / MAX_GAIN - 1.0) / ta)))
    return float(np.clip(math.degrees(math.atan((h0 / want - 1.0) / ta)), lowest, limit_deg))


def edit_pixel_height(height: np.ndarray, mask: np.ndarray, points=(), contact_mode: str = "shift",
                      tilt_deg: float = 0.0, elevation_deg: float = 20.0, lying: bool = False,
                      thickness: float = 0.0, lift: float = 0.0, foot_depth: float = 0.0) -> np.ndarray:
    """The edited pixel height (H, W) float32 [px] (module doc)."""
    if not math.isfinite(float(foot_depth)):
        raise ValueError(f"foot_depth must be finite, got {foot_depth}")
    if is_identity(points, tilt_deg, lying, lift, foot_depth):
        if np.shape(height) != np.shape(mask):
            raise ValueError(f"height {np.shape(height)} and mask {np.shape(mask)} differ in size")
        return np.asarray(height, np.float32)
    h = np.asarray(height, np.float64)
    m = np.asarray(mask) > 0.5 if np.asarray(mask).dtype != bool else np.asarray(mask)
    if h.shape != m.shape:
        raise ValueError(f"height {h.shape} and mask {m.shape} differ in size")
    if contact_mode not in ("shift", "upright"):
        raise ValueError(f"contact_mode must be 'shift' or 'upright', not {contact_mode!r}")
    P = _points(points)
    H, W = h.shape
    v, u = np.mgrid[0:H, 0:W] + 0.5
    if lying:
        h = lying_height(m, thickness)
    elif len(P) and contact_mode == "upright":
        a, b = ground_line(P)
        h = a + b * u - v
    elif len(P):
        cols = np.flatnonzero(m.any(axis=0))
        h = h - contact_correction(h, P, float(cols[-1] - cols[0] + 1) if len(cols) else None)
    if not lying:
        h = foot_depth_height(np.where(m, h, 0.0), foot_depth)
    h = tilt_gain(tilt_deg, elevation_deg) * h + float(lift)
    return np.where(m, np.maximum(h, 0.0), 0.0).astype(np.float32)
