"""Resampling a pixel-height scene to another scale and window, and back.

Used to run an effect at a scale other than the image's: SSN++ on a crop at
the scale it was trained for (``ssn_crop``), the classical soft shadow at a
proxy resolution (``upsample``).

A :class:`Window` is an axis-aligned rectangle of the image, ``x0, y0`` its
top-left pixel edge and ``w x h`` its size in image pixels (it may reach past
the image: what lies outside is padded), resampled to ``out_w x out_h``
pixels. Coordinates are continuous with pixel centres at ``i + 0.5`` (as
``Camera.pixel_grid``), so a point ``(u, v)`` of the image is
``((u - x0) kx, (v - y0) ky)`` in the window, ``kx = out_w / w``,
``ky = out_h / h``; pixel heights are vertical lengths and scale by ``ky``.
This map is affine in (u, v, h), so it keeps the straight rays of the
pixel-height tracer: a hard shadow traced in the window is the image's hard
shadow resampled (up to the resampling of the occluder itself).

Arrays are float32 (H, W); resizing is bilinear, antialiased when shrinking
(a triangle filter widened by the shrink factor, taps outside the image
dropped and the rest renormalised: what torch's ``interpolate(mode="bilinear",
antialias=True)`` and PIL compute), in numpy: no torch needed.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np


@dataclasses.dataclass(frozen=True)
class Window:
    """A rectangle of the image [px] and the size it is resampled to [px]."""

    x0: int
    y0: int
    w: int
    h: int
    out_w: int
    out_h: int

    def __post_init__(self):
        if min(self.w, self.h, self.out_w, self.out_h) < 1:
            raise ValueError(f"empty window {self}")

    @property
    def kx(self) -> float:
        return self.out_w / self.w

    @property
    def ky(self) -> float:
        return self.out_h / self.h

    @classmethod
    def whole(cls, H: int, W: int, max_side: int) -> "Window":
        """The whole image, shrunk so that its longer side is ``max_side`` (never enlarged)."""
        s = min(1.0, max_side / max(H, W))
        return cls(0, 0, W, H, max(1, round(W * s)), max(1, round(H * s)))

    def light_points(self, points) -> np.ndarray:
        """Light points (N, 4) or (4,) ``(u, v, h, s)`` of the image in window pixels.
        Points (s = +-1) are translated and scaled; directions (s = 0) only scaled."""
        p = np.array(points, dtype=np.float64, copy=True)
        q = p.reshape(-1, 4)
        is_point = np.abs(q[:, 3]) > 0.5
        q[:, 0] = np.where(is_point, q[:, 0] - self.x0, q[:, 0]) * self.kx
        q[:, 1] = np.where(is_point, q[:, 1] - self.y0, q[:, 1]) * self.ky
        q[:, 2] = q[:, 2] * self.ky
        return q.reshape(p.shape).astype(np.float32)

    def crop(self, a: np.ndarray, pad: str = "constant") -> np.ndarray:
        """The window's pixels of ``a`` (image size) at image scale, (h, w); outside
        the image padded with zeros (``pad="constant"``) or the nearest edge (``"edge"``)."""
        a = np.asarray(a, dtype=np.float32)
        H, W = a.shape
        xa, ya = max(self.x0, 0), max(self.y0, 0)
        xb, yb = min(self.x0 + self.w, W), min(self.y0 + self.h, H)
        if xa >= xb or ya >= yb:
            if pad == "edge":
                raise ValueError("window does not overlap the image")
            return np.zeros((self.h, self.w), np.float32)
        inner = a[ya:yb, xa:xb]
        widths = ((ya - self.y0, self.y0 + self.h - yb), (xa - self.x0, self.x0 + self.w - xb))
        if widths == ((0, 0), (0, 0)):
            return inner
        return np.pad(inner, widths, mode=pad)

    def shrink(self, a: np.ndarray, pad: str = "constant") -> np.ndarray:
        """``crop`` then resize to (out_h, out_w)."""
        return resize(self.crop(a, pad), (self.out_h, self.out_w))

    def scene(self, mask, fg_height, bg_height, band: int = 512):
        """The pixel-height scene in the window: (mask float32 in {0, 1}, fg_height,
        bg_height) at (out_h, out_w), heights in window pixels.

        The mask is area-averaged and thresholded at 0.5; the cutout's height is
        averaged over cutout pixels only (no mixing with the background's);
        non-finite background heights become 0 before resizing.

        Same numbers as ``shrink`` of each map, made ``band`` input rows at a
        time (the column pass of the separable resize is row by row), so a 4096^2
        image's scene needs no full-size float copies of its three maps."""
        mask_c, fg_c, bg_c = self._crop_raw(mask), self._crop_raw(fg_height), self._crop_raw(bg_height, "edge")
        h = mask_c.shape[0]
        planes = np.empty((3, h, self.out_w), np.float32)       # cover, fg sum, bg after the column pass
        for r0 in range(0, h, band):
            r = slice(r0, min(h, r0 + band))
            inside = (np.asarray(mask_c[r]) > 0.5).astype(np.float32)
            fg = np.where(inside > 0, np.nan_to_num(np.asarray(fg_c[r], np.float32)), 0.0).astype(np.float32)
            bg = np.nan_to_num(np.asarray(bg_c[r], np.float32), nan=0.0, posinf=0.0, neginf=0.0)
            for k, a in enumerate((inside, fg, bg)):
                planes[k, r] = _resize_axis(a, self.out_w, 1)
        cover, fg_sum, bg_w = (np.ascontiguousarray(_resize_axis(planes[k], self.out_h, 0)) for k in range(3))
        m = (cover > 0.5).astype(np.float32)
        fg_w = np.where(cover > 1e-6, fg_sum / np.maximum(cover, 1e-6), 0.0) * self.ky * m
        return m, fg_w.astype(np.float32), (bg_w * self.ky).astype(np.float32)

    def _crop_raw(self, a, pad: str = "constant") -> np.ndarray:
        """``crop`` without converting the dtype: a view when the window lies inside."""
        a = np.asarray(a)
        H, W = a.shape
        xa, ya = max(self.x0, 0), max(self.y0, 0)
        xb, yb = min(self.x0 + self.w, W), min(self.y0 + self.h, H)
        if xa >= xb or ya >= yb or (xa, ya, xb, yb) != (self.x0, self.y0, self.x0 + self.w, self.y0 + self.h):
            return self.crop(a, pad)
        return a[ya:yb, xa:xb]

    def paste(self, a_win: np.ndarray, H: int, W: int, fill: float = 0.0) -> np.ndarray:
        """Place a window-scale map back into an (H, W) image (bilinear), ``fill`` outside
        the window. Use :func:`upsample.masked_resize` first for edge-aware results."""
        a = resize(np.asarray(a_win, np.float32), (self.h, self.w)) if a_win.shape != (self.h, self.w) else a_win
        out = np.full((H, W), fill, np.float32)
        xa, ya = max(self.x0, 0), max(self.y0, 0)
        xb, yb = min(self.x0 + self.w, W), min(self.y0 + self.h, H)
        if xa < xb and ya < yb:
            out[ya:yb, xa:xb] = a[ya - self.y0:yb - self.y0, xa - self.x0:xb - self.x0]
        return out


def _axis_weights(n_in: int, n_out: int):
    """(index (n_out, taps), weight (n_out, taps)) of a 1-D bilinear resize."""
    scale = n_in / n_out
    support = max(scale, 1.0)                      # triangle half-width in input px
    centre = (np.arange(n_out) + 0.5) * scale - 0.5
    taps = int(np.ceil(2 * support)) + 1
    first = np.floor(centre - support).astype(np.int64) + 1
    idx = first[:, None] + np.arange(taps)[None, :]
    w = np.maximum(0.0, 1.0 - np.abs(idx - centre[:, None]) / support)
    w[(idx < 0) | (idx >= n_in)] = 0.0
    w /= np.maximum(w.sum(axis=1, keepdims=True), 1e-12)
    return np.clip(idx, 0, n_in - 1), w.astype(np.float32)


def _resize_axis(a: np.ndarray, n_out: int, axis: int) -> np.ndarray:
    if a.shape[axis] == n_out:
        return a
    idx, w = _axis_weights(a.shape[axis], n_out)
    a = np.moveaxis(a, axis, -1)
    out = np.empty(a.shape[:-1] + (n_out,), np.float32)
    step = max(1, (1 << 24) // max(1, n_out * idx.shape[1]))   # rows per chunk: ~64 MB of taps
    for r in range(0, a.shape[0], step):
        out[r:r + step] = np.einsum("rot,ot->ro", a[r:r + step][:, idx], w)
    return np.moveaxis(out, -1, axis)


def shrink(a: np.ndarray, shape: tuple[int, int], band: int = 64) -> np.ndarray:
    """``resize`` of an (H, W) or (H, W, C) array to a ``shape`` no larger on either
    axis (the same antialiased bilinear weights), made rows first: each tap reads whole
    rows (all channels at once), then the columns of the few output rows, in bands of
    output rows on the shared pool (ops/bands.py): the page's first preview of a 20 MP
    photo is about 3x faster for it (docs/server.md, "At photo size"); the sums differ
    from ``resize``'s only in float rounding (their order)."""
    from .bands import for_bands
    a = np.asarray(a, np.float32)
    h, w = (int(x) for x in shape)
    ridx, rwt = _axis_weights(a.shape[0], h)
    cidx, cwt = _axis_weights(a.shape[1], w)
    out = np.empty((h, w) + a.shape[2:], np.float32)
    tail = (1,) * (a.ndim - 1)
    sub = "rot...,ot->ro..."

    def rows(r0, r1):
        acc = np.zeros((r1 - r0,) + a.shape[1:], np.float32)
        for t in range(ridx.shape[1]):
            acc += a[ridx[r0:r1, t]] * rwt[r0:r1, t].reshape((-1,) + tail)
        out[r0:r1] = acc if a.shape[1] == w else np.einsum(sub, acc[:, cidx], cwt)
    for_bands(rows, 0, h, band)
    return out


def resize(a: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Bilinear resize of a float (H, W) map to ``shape`` (antialiased when shrinking)."""
    a = np.asarray(a, dtype=np.float32)
    shape = tuple(int(s) for s in shape)
    if a.shape == shape:
        return a
    return np.ascontiguousarray(_resize_axis(_resize_axis(a, shape[1], 1), shape[0], 0))


def nonzero_box(nonzero: np.ndarray):
    """(r0, r1, c0, c1) of the True pixels of a (H, W) bool array (ints), or None: a
    cutout and its effects cover a small part of a large photo, and only that box is
    worked on. The columns are searched on the box's rows only."""
    rows = np.flatnonzero(nonzero.any(axis=1))
    if rows.size == 0:
        return None
    r0, r1 = int(rows[0]), int(rows[-1]) + 1
    cols = np.flatnonzero(nonzero[r0:r1].any(axis=0))
    return r0, r1, int(cols[0]), int(cols[-1]) + 1


def nonzero_pixels(image: np.ndarray) -> np.ndarray:
    """``(image != 0).any(axis=2)`` of a float32 (H, W, C) image, bool (H, W), from the
    bits: a float is nonzero (NaN included) when any bit but its sign is set, and
    with C even two channels are tested as one 64-bit word (a reduction over a
    short last axis is slow in numpy)."""
    a = np.ascontiguousarray(image, np.float32)
    if a.shape[2] % 2:
        return (a != 0).any(axis=2)
    q = a.view(np.uint64)
    acc = q[..., 0].copy()
    for k in range(1, q.shape[2]):
        acc |= q[..., k]
    return (acc & np.uint64(0x7FFFFFFF7FFFFFFF)) != 0


def image_box(image: np.ndarray):
    """``nonzero_box`` of the pixels of a float32 (H, W, C) image with a channel != 0
    (NaN included), or None, with no full-size temporaries: the rows from one OR
    over each row's bits, the columns from the box's rows only."""
    a = np.ascontiguousarray(image, np.float32)
    H, W, C = a.shape
    bits = a.view(np.uint32)
    magnitude = np.uint32(0x7FFFFFFF)          # all bits but the sign: -0.0 == 0
    if H * W * C == 0:
        return None
    rows = np.flatnonzero(np.bitwise_or.reduce(bits.reshape(H, W * C), axis=1) & magnitude)
    if rows.size == 0:
        return None
    r0, r1 = int(rows[0]), int(rows[-1]) + 1
    cols = np.flatnonzero((np.bitwise_or.reduce(bits[r0:r1], axis=0) & magnitude).any(axis=1))
    return r0, r1, int(cols[0]), int(cols[-1]) + 1


def shrink_part(part: np.ndarray, origin, full_shape, shape) -> np.ndarray:
    """``resize`` to ``shape`` of a (H, W, C) image that is 0 outside ``part``, the
    block of it whose top-left pixel is ``origin`` (row, col): each output pixel
    from the same taps and weights as ``resample.resize`` (columns, then rows)."""
    H, W = full_shape
    h, w = (int(s_) for s_ in shape)
    C = part.shape[2]
    out = np.zeros((h, w, C), np.float32)
    R0, C0 = (int(o) for o in origin)
    R1, C1 = R0 + part.shape[0], C0 + part.shape[1]
    ridx, rwt = _axis_weights(H, h) if H != h else (np.arange(H)[:, None], np.ones((H, 1), np.float32))
    cidx, cwt = _axis_weights(W, w) if W != w else (np.arange(W)[:, None], np.ones((W, 1), np.float32))
    orow = np.flatnonzero(((ridx >= R0) & (ridx < R1) & (rwt > 0)).any(axis=1))
    ocol = np.flatnonzero(((cidx >= C0) & (cidx < C1) & (cwt > 0)).any(axis=1))
    if orow.size == 0 or ocol.size == 0:
        return out
    o0, o1, p0, p1 = orow[0], orow[-1] + 1, ocol[0], ocol[-1] + 1
    ri, rw = ridx[o0:o1], rwt[o0:o1]
    ci, cw = cidx[p0:p1], cwt[p0:p1]
    lo, hi = int(ri.min()), int(ri.max()) + 1          # input rows read (may reach outside the part: 0)
    clo, chi = int(ci.min()), int(ci.max()) + 1
    block = np.zeros((hi - lo, chi - clo, C), np.float32)
    a, b = max(lo, R0), min(hi, R1)
    c, d = max(clo, C0), min(chi, C1)
    block[a - lo:b - lo, c - clo:d - clo] = part[a - R0:b - R0, c - C0:d - C0]
    for k in range(C):
        colpass = np.einsum("rot,ot->ro", np.ascontiguousarray(block[:, :, k])[:, ci - clo], cw)
        out[o0:o1, p0:p1, k] = np.einsum("otx,ot->ox", colpass[ri - lo], rw)
    return out


def ceil_to(x: float, m: int) -> int:
    return int(m * math.ceil(x / m - 1e-9))


def scaled_size(H: int, W: int, scale: float) -> tuple[int, int]:
    """(H, W) of an image at working resolution ``scale`` (``ctx.scale``): each side
    rounded, at least 1 px. Loaders and everything that must agree with them use this."""
    return max(1, int(round(H * scale))), max(1, int(round(W * scale)))


def at_scale(a: np.ndarray, scale: float) -> np.ndarray:
    """An image (H, W) or (H, W, C) at working resolution ``scale`` (``scaled_size``),
    antialiased bilinear per channel (linear data: premultiplied colour, alpha,
    masks); the array itself at scale 1. Pixel heights need ``* ky`` as well."""
    a = np.asarray(a)
    H, W = a.shape[:2]
    shape = scaled_size(H, W, scale)
    if shape == (H, W):
        return a
    if shape[0] <= H and shape[1] <= W:
        return shrink(a, shape)
    if a.ndim == 2:
        return resize(a, shape)
    out = np.empty(shape + (a.shape[2],), np.float32)
    for c in range(a.shape[2]):
        out[:, :, c] = resize(np.ascontiguousarray(a[:, :, c]), shape)
    return out
