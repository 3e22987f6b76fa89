"""Numpy reference of ``march.h``: the pieces shared by every pixel-height tracer.

Each function mirrors the OpenCL helper of the same name (``ph_`` prefix dropped)
and works elementwise on numpy arrays (one element per ray), in float32 like
the kernels, so references and kernels agree except on rounding ties.

Conventions (design.md §2): u right, v down, pixels, pixel ``[i, j]`` centred at
``(j + 0.5, i + 0.5)``; a point of pixel-height space is ``(u, v, h)``, its foot is
``(u, v + h)``. A march samples the ray ``o + t d`` at
``p_k = o + k * step``, ``step = d / max(|d_u|, |d_v|)``: one pixel per step along
the image major axis, ``k = 1, 2, ...`` (``k = 0``, the origin's own pixel, is
skipped).
"""
from __future__ import annotations

import dataclasses

import numpy as np

F32 = np.float32

#: Height (pixels) marking "no occluding surface" in a surface buffer; anything
#: <= NO_SURFACE_TEST counts as absent (mirrors PH_NO_SURFACE; a sentinel, not NaN,
#: because NaN tests break under -cl-fast-relaxed-math).
NO_SURFACE = F32(-1.0e30)
NO_SURFACE_TEST = F32(-1.0e29)
#: Rays whose image direction is shorter than this (pixels) are refused: the
#: receiver sits on the light's image point.
MIN_IMAGE_LENGTH = F32(1.0e-4)
#: Largest foot difference (pixels) between neighbouring pixels that
#: surface_height still blends (larger: a depth discontinuity).
INTERP_JUMP = F32(2.0)
#: A ray point is behind a surface only when lower by more than this (pixels).
BEHIND_EPS = F32(1.0e-3)
#: k bound of a ray without a far end (before clipping to a finite box).
K_UNBOUNDED = 1_000_000_000


def surface_buffer(mask, height) -> np.ndarray:
    """The occluder buffer the tracers read: ``height`` (pixels) where
    ``mask > 0.5`` and the height is finite, NO_SURFACE elsewhere. float32 (H, W)."""
    mask = np.asarray(mask)
    height = np.asarray(height, dtype=np.float32)
    ok = (mask > 0.5) & np.isfinite(height)
    return np.where(ok, height, NO_SURFACE).astype(np.float32)


def clip_slab(o, d, lo, hi, t0, t1):
    """Liang-Barsky for one axis: narrow ``[t0, t1]`` to where ``o + t d`` lies in
    the closed slab ``[lo, hi]``. Returns ``(t0, t1, ok)``; ``ok`` False when empty
    (also for ``d == 0`` with ``o`` outside the slab)."""
    o, d, lo, hi, t0, t1 = (np.asarray(x, dtype=np.float32) for x in (o, d, lo, hi, t0, t1))
    zero = d == 0
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        inv = F32(1.0) / np.where(zero, F32(1.0), d)
        ta = (lo - o) * inv
        tb = (hi - o) * inv
    a = np.minimum(ta, tb)
    b = np.maximum(ta, tb)
    n0 = np.where(zero, t0, np.maximum(t0, a))
    n1 = np.where(zero, t1, np.minimum(t1, b))
    ok = np.where(zero, (o >= lo) & (o <= hi) & (t0 <= t1), n0 <= n1)
    return n0, n1, ok


def clip_rect(ou, ov, du, dv, rect, t0, t1):
    """Clip the image ray ``(ou, ov) + t (du, dv)`` to the closed rectangle
    ``rect = (u0, v0, u1, v1)`` (pixels). Returns ``(t0, t1, ok)``. For a cutout
    spanning rows i0..i1 and columns j0..j1 use ``(j0, i0, j1 + 1, i1 + 1)``."""
    t0, t1, ok1 = clip_slab(ou, du, rect[0], rect[2], t0, t1)
    t0, t1, ok2 = clip_slab(ov, dv, rect[1], rect[3], t0, t1)
    return t0, t1, ok1 & ok2


@dataclasses.dataclass
class March:
    """Rays sampled one pixel per major-axis step (arrays, one element per ray).

    Sample k is at ``(u + k su, v + k sv)`` with height ``h + k sh`` (pixels);
    samples ``k_lo .. k_hi`` (inclusive) remain; ``major_u`` is True where the
    march steps along u.
    """
    u: np.ndarray
    v: np.ndarray
    h: np.ndarray
    su: np.ndarray
    sv: np.ndarray
    sh: np.ndarray
    k_lo: np.ndarray
    k_hi: np.ndarray
    major_u: np.ndarray

    def sample_u(self, k):
        return (self.u + np.asarray(k, np.float32) * self.su).astype(np.float32)

    def sample_v(self, k):
        return (self.v + np.asarray(k, np.float32) * self.sv).astype(np.float32)

    def ray_height(self, k):
        """Ray height (pixels) at sample k: linear in k."""
        return (self.h + np.asarray(k, np.float32) * self.sh).astype(np.float32)


def march_setup(ou, ov, oh, du, dv, dh, t_max) -> tuple[March, np.ndarray]:
    """DDA set-up of rays ``o + t d``, ``0 < t <= t_max`` (``inf`` allowed).

    Samples ``k = 1 .. floor(t_max * major)``. Returns ``(march, ok)``; ``ok`` False
    where the image direction is shorter than MIN_IMAGE_LENGTH (receiver on the
    light's image point) or no sample exists."""
    ou, ov, oh, du, dv, dh = (np.asarray(x, dtype=np.float32) for x in (ou, ov, oh, du, dv, dh))
    shape = np.broadcast(ou, ov, oh, du, dv, dh, t_max).shape
    ou, ov, oh, du, dv, dh = (np.broadcast_to(x, shape) for x in (ou, ov, oh, du, dv, dh))
    t_max = np.broadcast_to(np.asarray(t_max, dtype=np.float32), shape)
    adu, adv = np.abs(du), np.abs(dv)
    major = np.maximum(adu, adv)
    good = major >= MIN_IMAGE_LENGTH
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        inv = F32(1.0) / np.where(good, major, F32(1.0))
        su = np.where(good, du * inv, F32(0)).astype(np.float32)
        sv = np.where(good, dv * inv, F32(0)).astype(np.float32)
        sh = np.where(good, dh * inv, F32(0)).astype(np.float32)
        kmax = (t_max * major).astype(np.float32)
    big = ~(kmax < F32(K_UNBOUNDED))
    k_hi = np.where(big, K_UNBOUNDED, np.floor(np.where(big, 0, kmax))).astype(np.int64)
    k_hi = np.where(good, k_hi, 0)
    k_lo = np.ones(shape, np.int64)
    m = March(ou.copy(), ov.copy(), oh.copy(), su, sv, sh, k_lo, k_hi, adu >= adv)
    return m, good & (k_hi >= k_lo)


def _narrow(m: March, ok, t0, t1) -> np.ndarray:
    """Narrow the sample range to parameter [t0, t1] plus one margin sample each
    side where ``ok``; empty it elsewhere (mirror of ph_march_narrow)."""
    with np.errstate(invalid="ignore"):
        a = np.where(ok, np.ceil(t0), 0).astype(np.int64) - 1
        b = np.where(ok, np.floor(t1), 0).astype(np.int64) + 1
    m.k_lo = np.where(ok, np.maximum(m.k_lo, a), m.k_lo)
    m.k_hi = np.where(ok, np.minimum(m.k_hi, b), m.k_lo - 1)
    return m.k_lo <= m.k_hi


def march_clip_box(m: March, rect, h_lo, h_hi) -> np.ndarray:
    """Clip the sample range to the box ``rect x [h_lo, h_hi]`` in (u, v, h), keeping
    one extra sample on each side (a side flip can straddle the box). Updates
    ``m.k_lo``/``m.k_hi`` in place; returns ``ok`` (some sample left)."""
    t0 = (m.k_lo - 1).astype(np.float32)
    t1 = (m.k_hi + 1).astype(np.float32)
    t0, t1, ok = clip_rect(m.u, m.v, m.su, m.sv, rect, t0, t1)
    t0, t1, ok2 = clip_slab(m.h, m.sh, h_lo, h_hi, t0, t1)
    ok &= ok2
    return _narrow(m, ok, t0, t1)


def lerp_height(rh, lh, t):
    """Ray height between receiver height rh (t = 0) and light height lh (t = 1),
    extrapolated outside [0, 1] (pixels)."""
    rh, lh, t = (np.asarray(x, dtype=np.float32) for x in (rh, lh, t))
    return (rh + t * (lh - rh)).astype(np.float32)


def surface_height(surf: np.ndarray, u, v, major_u) -> np.ndarray:
    """Surface height (pixels) at image points (u, v) of march samples.

    ``surf`` is a float32 (H, W) buffer from :func:`surface_buffer`. The pixel
    containing (u, v) decides presence (NO_SURFACE outside the image or where it
    has none); along the minor axis the height is interpolated linearly between
    the two nearest pixel centres when both have a surface, else the containing
    pixel's height is used; nor across a depth discontinuity (neighbour feet
    differing by more than INTERP_JUMP pixels), where a blend would be a surface
    that exists nowhere."""
    H, W = surf.shape
    u = np.asarray(u, np.float32)
    v = np.asarray(v, np.float32)
    major_u = np.asarray(major_u, bool)
    j = np.floor(u).astype(np.int64)
    i = np.floor(v).astype(np.int64)
    inside = (j >= 0) & (j < W) & (i >= 0) & (i < H)
    jc, ic = np.clip(j, 0, W - 1), np.clip(i, 0, H - 1)
    s = surf[ic, jc]
    present = inside & (s > NO_SURFACE_TEST)
    # minor-axis neighbours
    y = (v - F32(0.5)).astype(np.float32)
    x = (u - F32(0.5)).astype(np.float32)
    i0 = np.floor(y).astype(np.int64)
    j0 = np.floor(x).astype(np.int64)
    fy = (y - i0.astype(np.float32)).astype(np.float32)
    fx = (x - j0.astype(np.float32)).astype(np.float32)
    # u-major: rows i0, i0 + 1 in column j
    oku = (i0 >= 0) & (i0 + 1 < H)
    a_u = surf[np.clip(i0, 0, H - 1), jc]
    b_u = surf[np.clip(i0 + 1, 0, H - 1), jc]
    oku &= (a_u > NO_SURFACE_TEST) & (b_u > NO_SURFACE_TEST)
    with np.errstate(invalid="ignore", over="ignore"):
        oku &= np.abs(F32(1.0) + b_u - a_u) <= INTERP_JUMP
    # v-major: columns j0, j0 + 1 in row i
    okv = (j0 >= 0) & (j0 + 1 < W)
    a_v = surf[ic, np.clip(j0, 0, W - 1)]
    b_v = surf[ic, np.clip(j0 + 1, 0, W - 1)]
    okv &= (a_v > NO_SURFACE_TEST) & (b_v > NO_SURFACE_TEST)
    with np.errstate(invalid="ignore", over="ignore"):
        okv &= np.abs(b_v - a_v) <= INTERP_JUMP
    with np.errstate(invalid="ignore", over="ignore"):
        interp_u = (a_u + fy * (b_u - a_u)).astype(np.float32)
        interp_v = (a_v + fx * (b_v - a_v)).astype(np.float32)
    val = np.where(major_u, np.where(oku, interp_u, s), np.where(okv, interp_v, s))
    return np.where(present, val, NO_SURFACE).astype(np.float32)


def side(ray_h, surf_h) -> np.ndarray:
    """1 behind (ray lower than the surface by more than BEHIND_EPS), -1 in front
    or on it, 0 no surface. int8 array."""
    ray_h = np.asarray(ray_h, np.float32)
    surf_h = np.asarray(surf_h, np.float32)
    present = surf_h > NO_SURFACE_TEST
    behind = ray_h < surf_h - BEHIND_EPS
    return np.where(present, np.where(behind, 1, -1), 0).astype(np.int8)


def continuous(foot_prev, foot, jump) -> np.ndarray:
    """Mirror of ph_continuous: True where two consecutive surface samples with
    feet (v + surf_h, pixels) differ by at most ``jump`` pixels (one continuous
    surface); a larger jump is a depth discontinuity, where a side change is the
    ray passing through the gap, not a crossing (pass prev_side = 0 then)."""
    with np.errstate(invalid="ignore", over="ignore"):
        return np.abs(np.asarray(foot, np.float32) - np.asarray(foot_prev, np.float32)) <= np.float32(jump)


def occludes(ray_h, surf_h, thickness, side_now, prev_side) -> np.ndarray:
    """Occluded where the ray is behind the surface by at most ``thickness``
    (pixels), or changed side between two consecutive surface samples."""
    ray_h = np.asarray(ray_h, np.float32)
    surf_h = np.asarray(surf_h, np.float32)
    with np.errstate(invalid="ignore", over="ignore"):
        within = (side_now == 1) & ((surf_h - ray_h) <= F32(thickness))
    flip = (side_now != 0) & (prev_side != 0) & (prev_side != side_now)
    return within | flip


#: Tile size (pixels) of the coarse foot-bounds map used by the kernels to skip
#: runs of samples that cannot occlude (march.h: ph_span_skippable).
TILE = 8
#: Widening (pixels) of the foot bounds: a sample reading its containing pixel's
#: height off the pixel centre has its foot within 0.5 px of the centre's.
FOOT_MARGIN = np.float32(0.501)


def ray_foot(m: "March", k):
    """Foot v + h (pixels) of the ray at sample k (mirror of ph_ray_foot)."""
    k = np.asarray(k, np.float32)
    return ((m.v + m.h) + k * (m.sv + m.sh)).astype(np.float32)


def march_clip_foot(m: March, f_lo, f_hi) -> np.ndarray:
    """Clip the sample range to rays whose foot v + h is in [f_lo, f_hi], one
    margin sample each side (mirror of ph_march_clip_foot). Returns ``ok``."""
    t0 = (m.k_lo - 1).astype(np.float32)
    t1 = (m.k_hi + 1).astype(np.float32)
    t0, t1, ok = clip_slab((m.v + m.h).astype(np.float32), (m.sv + m.sh).astype(np.float32),
                           f_lo, f_hi, t0, t1)
    return _narrow(m, ok, t0, t1)


def foot_range(surf: np.ndarray):
    """(min, max) foot (i + 0.5) + surf over the surface, widened by FOOT_MARGIN
    (pixels); None when there is no surface."""
    present = surf > NO_SURFACE_TEST
    if not present.any():
        return None
    i = np.nonzero(present)[0]
    f = (i + 0.5).astype(np.float64) + surf[present]
    return float(f.min()) - float(FOOT_MARGIN), float(f.max()) + float(FOOT_MARGIN)


def tile_bounds(surf: np.ndarray, tile: int = TILE, rect=None) -> np.ndarray:
    """Coarse foot bounds of a surface buffer for exact skipping in the kernels.

    Returns float32 (TH, TW, 2): for each tile of ``tile`` x ``tile`` pixels the
    (min, max) of the foot ``(i + 0.5) + surf[i, j]`` (pixels) over the tile and
    its 8 neighbours, widened by FOOT_MARGIN; (+1e30, -1e30) where there is no
    surface. ``TH = ceil(H / tile)``. ``rect`` (u0, v0, u1, v1), the surface's
    bounding box in pixel edges, only limits the work (tiles outside it are empty).
    """
    H, W = surf.shape
    TH, TW = -(-H // tile), -(-W // tile)
    big = np.float32(1e30)
    out = np.empty((TH, TW, 2), np.float32)
    out[..., 0] = big
    out[..., 1] = -big
    if rect is None:
        t0, t1, s0, s1 = 0, TH, 0, TW
    else:
        t0, t1 = int(rect[1]) // tile, -(-int(rect[3]) // tile)
        s0, s1 = int(rect[0]) // tile, -(-int(rect[2]) // tile)
    if t1 <= t0 or s1 <= s0:
        return out
    nh, nw = t1 - t0, s1 - s0
    pad = np.full((nh * tile, nw * tile), NO_SURFACE, np.float32)
    part = surf[t0 * tile:t1 * tile, s0 * tile:s1 * tile]
    pad[:part.shape[0], :part.shape[1]] = part
    present = pad > NO_SURFACE_TEST
    foot = pad + (np.arange(t0 * tile, t1 * tile, dtype=np.float32) + np.float32(0.5))[:, None]
    blocks = foot.reshape(nh, tile, nw, tile).transpose(0, 2, 1, 3).reshape(nh, nw, -1)
    pres = present.reshape(nh, tile, nw, tile).transpose(0, 2, 1, 3).reshape(nh, nw, -1)
    tmin = np.where(pres, blocks, big).min(axis=2)
    tmax = np.where(pres, blocks, -big).max(axis=2)
    # dilate by one tile into a frame one tile wider on each side
    pmin = np.pad(tmin, 2, constant_values=big)
    pmax = np.pad(tmax, 2, constant_values=-big)
    dmin = np.full((nh + 2, nw + 2), big, np.float32)
    dmax = np.full((nh + 2, nw + 2), -big, np.float32)
    for a in range(3):
        for b in range(3):
            dmin = np.minimum(dmin, pmin[a:a + nh + 2, b:b + nw + 2])
            dmax = np.maximum(dmax, pmax[a:a + nh + 2, b:b + nw + 2])
    some = dmax > -big / 2
    dmin = np.where(some, dmin - FOOT_MARGIN, big)
    dmax = np.where(some, dmax + FOOT_MARGIN, -big)
    # place the frame (tile rows t0-1 .. t1, cols s0-1 .. s1), clipped to the map
    r0, c0 = t0 - 1, s0 - 1
    rr0, cc0 = max(r0, 0), max(c0, 0)
    rr1, cc1 = min(t1 + 1, TH), min(s1 + 1, TW)
    out[rr0:rr1, cc0:cc1, 0] = dmin[rr0 - r0:rr1 - r0, cc0 - c0:cc1 - c0]
    out[rr0:rr1, cc0:cc1, 1] = dmax[rr0 - r0:rr1 - r0, cc0 - c0:cc1 - c0]
    return out


def segments_may_hit(ru, rv, rh, lb, rect, h_lo, h_hi, f_lo, f_hi) -> np.ndarray:
    """Mirror of ph_segments_may_hit: False where no segment from receiver
    (ru, rv, rh) to a light point within ``lb = (u_min, u_max, v_min, v_max,
    h_min, h_max, foot_min, foot_max)`` can meet the box ``rect x [h_lo, h_hi]``
    with feet in ``[f_lo, f_hi]`` (all pixels)."""
    ru, rv, rh = (np.asarray(x, np.float32) for x in (ru, rv, rh))
    rf = rv + rh
    return ((np.minimum(ru, lb[0]) <= rect[2]) & (np.maximum(ru, lb[1]) >= rect[0])
            & (np.minimum(rv, lb[2]) <= rect[3]) & (np.maximum(rv, lb[3]) >= rect[1])
            & (np.minimum(rh, lb[4]) <= h_hi) & (np.maximum(rh, lb[5]) >= h_lo)
            & (np.minimum(rf, lb[6]) <= f_hi) & (np.maximum(rf, lb[7]) >= f_lo))


def span_end(m: March, k, tile: int = TILE) -> np.ndarray:
    """Mirror of ph_span_end: the last sample index of the span starting at k
    (the run of samples in the same major-axis tile column)."""
    k = np.asarray(k, np.int64)
    j = np.floor(m.sample_u(k)).astype(np.int64)
    i = np.floor(m.sample_v(k)).astype(np.int64)
    tj, ti = (j // tile) * tile, (i // tile) * tile
    end_u = k + np.where(m.su > 0, tj + tile - 1 - j, j - tj)
    end_v = k + np.where(m.sv > 0, ti + tile - 1 - i, i - ti)
    return np.where(m.major_u, end_u, end_v)


def span_skippable(tiles: np.ndarray, m: March, k, e, thickness, tile: int = TILE, ext: float = 0.0) -> np.ndarray:
    """Mirror of ph_span_skippable: True where no sample of k..e can occlude or
    flip side (the ray's foot is beyond every surface foot of the tile
    neighbourhood, or short of all of them by more than max(thickness, BEHIND_EPS));
    ``ext`` [px] widens the ray's foot range each side (shadow.cl: the half steps at
    the edges of a run)."""
    TH, TW = tiles.shape[:2]
    ti = np.clip(np.floor(m.sample_v(k)).astype(np.int64) // tile, 0, TH - 1)
    tj = np.clip(np.floor(m.sample_u(k)).astype(np.int64) // tile, 0, TW - 1)
    b = tiles[ti, tj]
    fa, fb = ray_foot(m, k), ray_foot(m, e)
    lo, hi = np.minimum(fa, fb) - F32(ext), np.maximum(fa, fb) + F32(ext)
    return (lo >= b[..., 1]) | (hi < b[..., 0] - max(float(thickness), float(BEHIND_EPS)))
