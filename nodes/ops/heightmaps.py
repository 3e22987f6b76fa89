"""Pixel-height maps: background templates, cutout heuristics, files and resizing.

Every function returns float32 ``(H, W)`` pixel height in pixels (design.md §2):
the image distance between a point and its foot on the ground, ``0`` on the ground.

Background templates
--------------------
Walls are vertical planes standing on a floor/wall *junction line*. With the
no-pitch camera a vertical 3D line projects to an image column, so the foot of a
wall pixel ``(u, v)`` is the junction pixel of the same column and
``h = max(0, v_wall(u) - v)``. A straight junction on the ground is a straight image
line, so a corner of walls is a piecewise-linear ``v_wall``:

- ``ground``: all zeros;
- ``back_wall``: one straight junction (a row and a slope, or two points);
- ``wall_corner``: two junction lines meeting at a corner point;
- ``two_corners``: a back wall between two corners with side walls outside.

``steps`` and ``curved`` are defined in 3D (world units, the camera's scale) and
ray-cast through the camera, so they are exactly consistent with reconstruction:

- ``steps``: a staircase rising away from the camera; riser ``k`` is the vertical
  plane at depth ``D_k`` (constant Z), tread ``k`` the horizontal plane at height
  ``Y_k = k * rise``. On a tread ``h = Y_k (v - horizon) / (H_cam - Y_k)``; on a riser
  at depth ``D_k``, ``h = f H_cam / D_k + horizon - v``.
- ``curved``: a cove: floor, a quarter-cylinder of radius ``R`` and a back wall at
  depth ``D_w``; a smooth floor-to-wall transition.

Cutout heuristics
-----------------
For an upright object standing on the ground, each pixel's height is its distance in
rows to the object's contact line (``contact_line_height``). A learned model can take
this place through the ``HeightPredictor`` protocol.
"""
from __future__ import annotations

import math
import os
import pathlib
from typing import Protocol, runtime_checkable

import numpy as np

from .camera import Camera

BACKGROUND_KINDS = ("ground", "back_wall", "wall_corner", "two_corners", "steps", "curved")


# -- walls from a junction polyline ---------------------------------------------

def junction_rows(width: int, points) -> np.ndarray:
    """Row ``v_wall(u)`` [px] of a piecewise-linear junction at every pixel-centre column.

    points: sequence of (u, v) [px], at least two, sorted by u (sorted here); the
    first and last segments are extended linearly to the image border.
    Returns float64 (width,).
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(pts) < 2:
        raise ValueError(f"a junction line needs at least two points, got {len(pts)}")
    pts = pts[np.argsort(pts[:, 0], kind="stable")]
    if np.any(np.diff(pts[:, 0]) <= 0):
        raise ValueError(f"junction points need distinct u, got {pts[:, 0].tolist()}")
    u = np.arange(width, dtype=np.float64) + 0.5
    seg = np.clip(np.searchsorted(pts[:, 0], u, side="right") - 1, 0, len(pts) - 2)
    u0, v0 = pts[seg, 0], pts[seg, 1]
    u1, v1 = pts[seg + 1, 0], pts[seg + 1, 1]
    return v0 + (u - u0) * (v1 - v0) / (u1 - u0)


def wall_from_junction(width: int, height: int, points) -> np.ndarray:
    """Walls standing on a junction polyline: ``h = max(0, v_wall(u) - v)``, float32 (H, W)."""
    vw = junction_rows(width, points)
    v = np.arange(height, dtype=np.float64)[:, None] + 0.5
    return np.maximum(0.0, vw[None, :] - v).astype(np.float32)


def ground(width: int, height: int) -> np.ndarray:
    """A ground plane only: zeros, float32 (H, W)."""
    return np.zeros((height, width), np.float32)


def back_wall(width: int, height: int, row: float, slope: float = 0.0, points=None) -> np.ndarray:
    """A back wall on a straight junction: through ``(W/2, row)`` with ``slope`` = dv/du,
    or through ``points`` ((u0, v0), (u1, v1)) when given."""
    if points is None:
        c = width / 2.0
        points = ((c - 1.0, row - slope), (c + 1.0, row + slope))
    return wall_from_junction(width, height, points)


def wall_corner(width: int, height: int, corner, left_slope: float, right_slope: float) -> np.ndarray:
    """Two walls meeting at ``corner`` (u, v) [px]; the junction leaves it with slope
    ``left_slope`` (dv/du) to the left and ``right_slope`` to the right. A concave
    corner seen from inside has left_slope < 0 < right_slope."""
    cu, cv = corner
    return wall_from_junction(width, height, ((cu - 1.0, cv - left_slope), (cu, cv),
                                              (cu + 1.0, cv + right_slope)))


def two_corners(width: int, height: int, corner_left, corner_right, left_slope: float,
                right_slope: float) -> np.ndarray:
    """A back wall between ``corner_left`` and ``corner_right`` (u, v) [px] with side walls
    leaving them at ``left_slope`` / ``right_slope`` (dv/du)."""
    (lu, lv), (ru, rv) = corner_left, corner_right
    return wall_from_junction(width, height, ((lu - 1.0, lv - left_slope), (lu, lv), (ru, rv),
                                              (ru + 1.0, rv + right_slope)))


# -- templates defined in 3D ------------------------------------------------------

def _view_slope(camera: Camera) -> np.ndarray:
    """t = (v - horizon) / f for each row's pixel centre: the view ray's drop in height
    per unit depth (Y(D) = H_cam - t D). float64 (H, 1)."""
    v = np.arange(camera.height, dtype=np.float64)[:, None] + 0.5
    return (v - camera.horizon) / camera.focal


def steps(camera: Camera, first_distance: float, rise: float, run: float, count: int) -> np.ndarray:
    """Pixel height of a staircase rising away from the camera, float32 (H, W).

    first_distance: depth D_1 of the first riser from the camera [world units].
    rise: height of each riser [world units]; run: depth of each tread [world units].
    count: number of risers; the top tread extends to infinity.
    Riser k (1-based) is the plane Z = -D_k, D_k = first_distance + (k - 1) run, from
    Y = (k - 1) rise to k rise; tread k is Y = k rise between D_k and D_{k+1}.
    Pixels whose ray hits nothing (above the horizon) get 0.
    """
    if count < 0 or rise < 0 or run <= 0 or first_distance <= 0:
        raise ValueError("steps need count >= 0, rise >= 0, run > 0 and first_distance > 0")
    H, f = camera.cam_height, camera.focal
    t = _view_slope(camera)[:, 0]                     # per row: the same for every column
    Dhit = np.full(t.shape, np.nan)
    Yhit = np.full(t.shape, np.nan)
    done = np.zeros(t.shape, bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        for k in range(1, count + 1):
            Dk = first_distance + (k - 1) * run
            Yk, Yprev = k * rise, (k - 1) * rise
            y_at = H - t * Dk                          # ray height at riser k
            hits = ~done & (y_at <= Yk)
            tread = hits & (y_at < Yprev)              # dropped below the previous tread first
            Dt = (H - Yprev) / t
            Dhit = np.where(tread, Dt, np.where(hits, Dk, Dhit))
            Yhit = np.where(tread, Yprev, np.where(hits, y_at, Yhit))
            done |= hits
        Ytop = count * rise
        last = ~done & (t > 0)
        Dhit = np.where(last, (H - Ytop) / t, Dhit)
        Yhit = np.where(last, Ytop, Yhit)
        h = np.where(np.isfinite(Dhit) & (Dhit > 0), f * Yhit / Dhit, 0.0)
    return np.repeat(h[:, None], camera.width, axis=1).astype(np.float32)


def curved(camera: Camera, wall_distance: float, radius: float) -> np.ndarray:
    """Pixel height of a cove: floor, quarter-cylinder and back wall, float32 (H, W).

    wall_distance: depth D_w of the back wall plane Z = -D_w [world units].
    radius: cove radius R [world units], 0 <= R <= wall_distance; the arc's axis is the
    horizontal line at depth D_w - R, height R, so the surface is C1 (tangent to the
    floor at depth D_w - R and to the wall at height R).
    """
    if not (wall_distance > 0 and 0 <= radius <= wall_distance):
        raise ValueError("curved needs wall_distance > 0 and 0 <= radius <= wall_distance")
    H, f, R = camera.cam_height, camera.focal, radius
    t = _view_slope(camera)[:, 0]
    Dc = wall_distance - R
    with np.errstate(divide="ignore", invalid="ignore"):
        Dfloor = np.where(t > 0, H / t, np.inf)
        on_floor = Dfloor <= Dc
        # arc: (D - Dc)^2 + (H - t D - R)^2 = R^2. The circle's inside is the room's
        # air (its centre is in front of the cove), so the ray meets the surface where
        # it *leaves* the circle: the larger root, if it is in the lower-right quarter.
        a = 1.0 + t * t
        b = -2.0 * Dc - 2.0 * t * (H - R)
        c = Dc * Dc + (H - R) ** 2 - R * R
        disc = b * b - 4 * a * c
        Darc = (-b + np.sqrt(np.maximum(disc, 0.0))) / (2 * a)
        Yarc = H - t * Darc
        on_arc = ~on_floor & (disc >= 0) & (Darc >= Dc - 1e-12) & (Yarc <= R + 1e-12) & (R > 0)
        D = np.where(on_floor, Dfloor, np.where(on_arc, Darc, wall_distance))
        Y = np.where(on_floor, 0.0, np.where(on_arc, Yarc, H - t * wall_distance))
        h = np.where(D > 0, f * Y / D, 0.0)
    return np.repeat(h[:, None], camera.width, axis=1).astype(np.float32)


# -- cutouts ------------------------------------------------------------------------

@runtime_checkable
class HeightPredictor(Protocol):
    """Anything that turns a cutout into its pixel height: a heuristic or a learned model.

    ``predict(rgba)``: rgba float32 (H, W, 4) linear premultiplied (alpha in channel 3)
    -> float32 (H, W) pixel height [px], 0 outside the object.
    """

    def predict(self, rgba: np.ndarray) -> np.ndarray: ...


def contact_line_height(mask: np.ndarray, method: str = "contact_line", tolerance: float = 2.0,
                        threshold: float = 0.5) -> np.ndarray:
    """Pixel height of an upright object standing on the ground, float32 (H, W).

    Each pixel inside the mask gets its distance in rows to the contact line below
    it, ``h = max(0, v_contact(u) - v)``, with ``v`` the pixel centre and the contact
    at the *bottom edge* of the lowest object pixels (a rectangle whose last row is
    r has v_contact = r + 1). Pixels outside the mask get 0.

    method:
      ``"contact_line"`` (default): one straight contact line for the whole object,
        least-squares fitted to the bottom pixels of the columns whose lowest mask
        row lies within ``tolerance`` rows of the object's lowest row, and extended
        under every column. Chosen as default because an object touches the ground
        in one place: with per-column bottoms, a figure's raised arm, the gap
        between its legs or a vase's overhanging rim would be "standing on the
        ground" at that column and get pixel heights near 0, which casts shadows
        detached from the body.
      ``"column_bottom"``: the lowest mask row of each column separately. Right for
        objects that touch the ground along their whole silhouette bottom (a
        sloping dune, a row of objects), wrong for overhangs.
    """
    m = np.asarray(mask, dtype=np.float32) > threshold
    h = np.zeros(m.shape, np.float32)
    if not m.any():
        return h
    rows = np.arange(m.shape[0])
    has = m.any(axis=0)
    # lowest mask row per column (bottom edge = row + 1)
    bottom = np.where(has, m.shape[0] - np.argmax(m[::-1], axis=0), -1).astype(np.float64)
    u = np.arange(m.shape[1], dtype=np.float64) + 0.5
    if method == "column_bottom":
        vc = bottom
    elif method == "contact_line":
        low = bottom.max()
        sel = has & (bottom >= low - tolerance)
        us, vs = u[sel], bottom[sel]
        if us.max() - us.min() < 2.0:
            vc = np.full(u.shape, low)
        else:
            slope, icpt = np.polyfit(us, vs, 1)
            vc = icpt + slope * u
    else:
        raise ValueError(f"method must be contact_line or column_bottom, got {method!r}")
    v = rows[:, None].astype(np.float64) + 0.5
    h = np.where(m, np.maximum(0.0, vc[None, :] - v), 0.0)
    return h.astype(np.float32)


class ContactLinePredictor:
    """The contact-line heuristic as a ``HeightPredictor`` (uses only the alpha)."""

    def __init__(self, method: str = "contact_line", tolerance: float = 2.0):
        self.method = method
        self.tolerance = tolerance

    def predict(self, rgba: np.ndarray) -> np.ndarray:
        rgba = np.asarray(rgba, dtype=np.float32)
        alpha = rgba[..., 3] if rgba.ndim == 3 and rgba.shape[2] == 4 else rgba
        return contact_line_height(alpha, self.method, self.tolerance)


# -- resizing and files ---------------------------------------------------------------

def resize_pixel_height(h: np.ndarray, s: float) -> np.ndarray:
    """A pixel-height map for the image resized by ``s``: resampled to
    ``round(H s) x round(W s)`` (bilinear, pixel centres aligned) and every height
    multiplied by ``s``, because a pixel height is itself a length in pixels."""
    h = np.asarray(h, dtype=np.float64)
    if not (s > 0 and math.isfinite(s)):
        raise ValueError(f"scale must be positive, got {s}")
    H, W = h.shape
    nH, nW = max(1, round(H * s)), max(1, round(W * s))
    ys = np.clip((np.arange(nH) + 0.5) * H / nH - 0.5, 0, H - 1)
    xs = np.clip((np.arange(nW) + 0.5) * W / nW - 0.5, 0, W - 1)
    y0 = np.floor(ys).astype(int); x0 = np.floor(xs).astype(int)
    y1 = np.minimum(y0 + 1, H - 1); x1 = np.minimum(x0 + 1, W - 1)
    fy = (ys - y0)[:, None]; fx = (xs - x0)[None, :]
    top = h[y0][:, x0] * (1 - fx) + h[y0][:, x1] * fx
    bot = h[y1][:, x0] * (1 - fx) + h[y1][:, x1] * fx
    return ((top * (1 - fy) + bot * fy) * s).astype(np.float32)


def load_pixel_height(path: str | os.PathLike, scale: float = 1.0) -> np.ndarray:
    """Read a pixel-height map from a file, float32 (H, W) pixels.

    ``.npy``: the array (first channel if 3-D) times ``scale``.
    EXR / float TIFF: the first channel times ``scale`` (values are pixels).
    PNG / integer TIFF (8 or 16 bit): the stored value normalised to [0, 1]
    (e.g. v / 65535) times ``scale``, so ``scale`` is the height of full white [px].
    Colour is never sRGB-decoded: these are measurements, not colours.
    """
    p = pathlib.Path(path)
    if p.suffix.lower() == ".npy":
        from .imageio import ImageFileError, max_pixels

        try:  # the header alone first: refuse an oversized array before reading it
            a = np.load(p, allow_pickle=False, mmap_mode="r")
        except (ValueError, OSError, EOFError) as e:
            raise ImageFileError(f"cannot read {p}: {e}"[:300]) from None
        if a.size > max_pixels() or a.dtype.kind not in "biuf":
            raise ImageFileError(f"{p}: array {a.dtype} {a.shape} is not numeric or exceeds the limit of "
                                 f"{max_pixels()} values (PIXGRAPH_MAX_PIXELS)"[:300])
        a = np.array(a)
    else:
        from .imageio import read_image
        a, _ = read_image(p, colorspace="linear", alpha="premultiplied")
    a = np.asarray(a, dtype=np.float64)
    if a.ndim == 3:
        a = a[..., 0]
    if a.ndim != 2:
        raise ValueError(f"{p}: expected a 2-D pixel-height map, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{p}: pixel height has non-finite values")
    return (a * scale).astype(np.float32)
