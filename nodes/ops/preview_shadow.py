"""A cheap soft shadow for previews: the hard shadow widened by a penumbra estimate.

The classical soft shadow (``shadow.soft_shadow``, 64 light samples) costs 64
hard shadows; a preview may add about one. What a disk light's softness does to
a hard shadow is, to first order, a penumbra whose half-width grows linearly
with the distance between the occluder and the receiver:

    half-width ~ softness * d,   softness = light radius / light distance

(similar triangles; ``softness.softness_of``: radius over the distance from the
light's centre to the object's centre, tan(angular radius) for a directional
light). This is the estimate of percentage-closer soft shadows (PCSS): trace
the hard shadow of the light's centre once, keeping for each shadowed receiver
the distance ``d`` [px, in (u, v, h) pixel-height space] to the cutout point
that blocks it (:func:`hard_shadow_distance`, one march per pixel, as
``buffers.relative_distance``), then :func:`penumbra_blur`:

1. blocker search: each pixel averages ``d`` over the shadowed pixels within
   ``reach = ceil(softness * max d)`` pixels, at most ``MAX_REACH`` of the
   image's longer side (so lit pixels just outside the hard shadow find the
   occluders that cast the penumbra over them);
2. each pixel whose neighbourhood within ``reach`` holds both shadow and light
   takes the mean darkness of a square box of half-size
   ``round(softness * mean d)`` around it (a box over a straight hard edge gives
   the linear ramp a disk light's penumbra roughly is).

2'. (a candidate, not what ``pixgraph.PreviewShadow`` uses: its version 4 did, and
   version 5 went back to the square box after it left seams on a wall; docs/server.md,
   "A stretched penumbra") with a geometry, a background pixel's
   box is stretched along the penumbra's long axis in the image:
   :func:`penumbra_axes` casts the blocking point from the disk's 4 extreme
   points onto the receiver's tangent plane, which gives the penumbra's
   ellipse, and the pixel averages over a few square boxes of half-size the
   minor half-axis spread along the major one
   (``benchmarks/preview_shadow_bench.py``'s ``pcss_aniso``). With a device
   these boxes are summed by the OpenCL kernel ``swept_boxes`` (8 pixels a work
   item), :func:`_swept_boxes` is its numpy reference.

Both are box sums over summed-area tables, restricted to the pixels of the
receiver's own side of the cutout's outline (the shadow on the background and
the self-shadow on the cutout are different surfaces, as in
``upsample.masked_resize``), and only on the shadow's bounding box grown by
``reach``. Guarantees (tests/test_preview_shadow.py): softness 0 (a point light)
gives exactly the hard shadow; the darkness stays in [0, 1]; a pixel whose
same-side neighbourhood within ``reach`` is all shadow stays at 1 (the umbra's
core), one with no shadow there stays at 0 (the shadow never spreads farther
than ``reach``). Accuracy and cost against the 64-sample soft shadow:
``benchmarks/preview_shadow_bench.py`` (docs/server.md, "Previews of soft
shadows").

Units: pixels. Arrays: float32 (H, W).
"""
from __future__ import annotations

import functools
import math

import numpy as np

from pixgraph.device import load_kernel_source

from . import shadow as S

#: the penumbra's reach is at most this fraction of the image's longer side
#: (a huge light on a long shadow: the box sums stay bounded; on the 60 scenes of
#: benchmarks/preview_shadow_bench.py no cap gave the same RMSE, mean and max)
MAX_REACH = 0.125


def hard_shadow_distance_ref(mask, fg_height, bg_height, light, thickness=1.0):
    """Numpy reference of :func:`hard_shadow_distance`: ``(darkness, distance)``,
    float32 (H, W) each: darkness 1 where the light point ``(u, v, h, s)`` is
    blocked, 0 lit; distance [px] from the receiver (pixel centre, height) to the
    first blocking cutout point in (u, v, h), 0 where lit."""
    prep = S.Prepared(mask, fg_height, bg_height, thickness)
    blocked, hu, hv, hs = S.trace_ref(prep, light)
    i, j = np.mgrid[0:prep.H, 0:prep.W]
    with np.errstate(invalid="ignore"):
        dist = np.sqrt((hu - (j + 0.5)) ** 2 + (hv - (i + 0.5)) ** 2 + (hs - prep.recv) ** 2)
    return blocked.astype(np.float32), np.where(blocked, dist, 0.0).astype(np.float32)


@functools.lru_cache(maxsize=1)
def kernel_source() -> str:
    """preview_shadow.cl with shadow.cl and march.h inlined."""
    return load_kernel_source(__file__, "preview_shadow.cl")


class PreviewScene(S.ShadowScene):
    """A ``shadow.ShadowScene`` whose program also has ``hard_shadow_distance``."""

    def __init__(self, device, mask, fg_height, bg_height, thickness=1.0):
        super().__init__(device, mask, fg_height, bg_height, thickness)
        self.prg = device.program(kernel_source(), S.BUILD_OPTIONS)

    def hard_shadow_distance(self, light, progress=None, check_cancelled=None):
        """``(darkness, distance)`` of :func:`hard_shadow_distance_ref`, one launch
        (banded with the callbacks, as ``ShadowScene.launch_banded``)."""
        p = self.prep
        if p.empty:
            z = np.zeros((p.H, p.W), np.float32)
            return z, z.copy()
        out = self.out_buffer("hard_distance", 2 * p.H * p.W * 4)
        ev = self.launch_banded("hard_shadow_distance", self.recv, S._f4(S.light_array(light)), out,
                                progress=progress, check_cancelled=check_cancelled)
        self.last_event = ev
        host = self._read(out, (2, p.H, p.W), ev)
        return host[0], host[1]


def hard_shadow_distance(device, mask, fg_height, bg_height, light, thickness=1.0, *,
                         progress=None, check_cancelled=None):
    """Hard shadow of one light point with each shadowed receiver's blocker distance
    (OpenCL; :func:`hard_shadow_distance_ref` is the reference). Inputs as
    ``shadow.hard_shadow``; returns ``(darkness, distance)`` float32 (H, W)."""
    return PreviewScene(device, mask, fg_height, bg_height, thickness).hard_shadow_distance(
        light, progress, check_cancelled)


def _sat(a: np.ndarray) -> np.ndarray:
    """Summed-area tables of planes a (k, h, w): (k, h + 1, w + 1) float64 with a zero
    first row and column (columns summed in float32: exact for sums of 0/1 up to 2^24)."""
    k, h, w = a.shape
    z = np.zeros((k, h + 1, w + 1), np.float64)
    np.cumsum(np.cumsum(a, axis=1, dtype=np.float32), axis=2, dtype=np.float64, out=z[:, 1:, 1:])
    return z


def _box_fixed(z: np.ndarray, ri: int, rj: int) -> np.ndarray:
    """Sums over the boxes of half-sizes ri (rows) and rj (columns) around the pixels of a
    table's image that lie at least that far inside it: (k, h - 2 ri, w - 2 rj)."""
    ni, nj = 2 * ri + 1, 2 * rj + 1
    return z[:, ni:, nj:] - z[:, :-ni, nj:] - z[:, ni:, :-nj] + z[:, :-ni, :-nj]


def _box_at(z: np.ndarray, i: np.ndarray, j: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Sums over the boxes of half-size r[m] around pixels (i[m], j[m]) of a table's
    image (k, ...), boxes inside it."""
    w = z.shape[2]
    i0, i1, j0, j1 = (i - r) * w, (i + r + 1) * w, j - r, j + r + 1
    a, b, c, d = i1 + j1, i0 + j1, i1 + j0, i0 + j0
    # np.take on each flat plane: several times faster than fancy indexing of (k, h, w)
    return np.stack([np.take(p, a) - np.take(p, b) - np.take(p, c) + np.take(p, d)
                     for p in z.reshape(z.shape[0], -1)])


def penumbra_axes(u, v, h, grad_u, grad_v, blocker, light, extremes):
    """The penumbra a disk light casts at receiver points: the half-axes of the
    ellipse the light's disk maps to on the receiver, seen through the blocker.

    u, v, h: receiver pixel centres and pixel height [px] (arrays of one shape);
    grad_u, grad_v: the receiver surface's slope dh/du, dh/dv there (0 on the
    ground); blocker: the distance [px, (u, v, h) space] from the receiver to the
    blocking point along the march toward ``light``, the light's centre
    ``(u, v, h, s)``; extremes: (4, 4) the disk's right, left, top and bottom
    points in pixel-height space (``lights.disk_extremes``).

    The blocking point b lies on the receiver's march; the shadow of b cast from
    an extreme point E falls where the line E-b meets the receiver's tangent plane
    (a projective statement, so it holds for ``s = -1`` and lights at infinity
    too); its offset from the receiver, half of right minus left and of top minus
    bottom, are two conjugate half-axes of the penumbra's ellipse (first order in
    the light's size). Returns ``(major, minor, cos, sin)``: the half-axes [px] and
    the unit direction of the major one in the image; non-finite where the
    geometry degenerates (the caller falls back to the square box).
    """
    L = np.asarray(light, np.float64)
    E = np.asarray(extremes, np.float32)[:4, :3, None]             # (4, 3, 1)
    sgn = -1.0 if L[3] < 0 else 1.0
    f32 = np.float32
    u, v, h = (np.asarray(x, f32) for x in (u, v, h))
    gu, gv = np.asarray(grad_u, f32), np.asarray(grad_v, f32)
    du, dv, dh = f32(L[0]) - u, f32(L[1]) - v, f32(L[2]) - h
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        t = (f32(sgn) * np.asarray(blocker, f32)) / np.sqrt(du * du + dv * dv + dh * dh)
        tu, tv, th = t * du, t * dv, t * dh                   # b - r
        # the tangent plane h' = h + gu (u' - u) + gv (v' - v) at the receiver r; the line
        # b + lam (b - E) meets it at lam = (gu tu + gv tv - th) / ((b - E)_h - g . (b - E)_uv)
        rhs = gu * tu + gv * tv - th
        wu, wv, wh = (u + tu) - E[:, 0], (v + tv) - E[:, 1], (h + th) - E[:, 2]   # (4, N)
        lam = rhs / (wh - gu * wu - gv * wv)
        ou, ov = tu + lam * wu, tv + lam * wv                     # offsets from r, (4, N)
        a1u, a1v = (ou[0] - ou[1]) * f32(0.5), (ov[0] - ov[1]) * f32(0.5)
        a2u, a2v = (ou[2] - ou[3]) * f32(0.5), (ov[2] - ov[3]) * f32(0.5)
        # principal axes of {x a1 + y a2 : x^2 + y^2 <= 1}: eigen of [a1 a2][a1 a2]^T
        p, q, r = a1u * a1u + a2u * a2u, a1u * a1v + a2u * a2v, a1v * a1v + a2v * a2v
        m, hp = (p + r) * f32(0.5), (p - r) * f32(0.5)
        d = np.sqrt(hp * hp + q * q)             # (np.hypot is ten times slower)
        major, minor = np.sqrt(m + d), np.sqrt(np.maximum(m - d, f32(0.0)))
        # the major eigenvector: (d + (p - r)/2, q), or (q, d - (p - r)/2) when p < r
        xu, xv = np.where(hp >= 0, d + hp, q), np.where(hp >= 0, q, d - hp)
        n = np.sqrt(xu * xu + xv * xv)
        cu, cv = np.where(n > 0, xu / n, f32(1.0)), np.where(n > 0, xv / n, f32(0.0))
    return major, minor, cu, cv


def _receiver_slope(bg: np.ndarray, i: np.ndarray, j: np.ndarray):
    """``(h, dh/du, dh/dv)`` of the background height map at pixels (i, j), float32:
    central differences (one-sided at the image's border)."""
    H, W = bg.shape
    flat = bg.reshape(-1)
    jm, jp = np.maximum(j - 1, 0), np.minimum(j + 1, W - 1)
    im, ip = np.maximum(i - 1, 0), np.minimum(i + 1, H - 1)
    row, col = i * W, j
    gu = (np.take(flat, row + jp) - np.take(flat, row + jm)) / np.maximum(jp - jm, 1).astype(np.float32)
    gv = (np.take(flat, ip * W + col) - np.take(flat, im * W + col)) / np.maximum(ip - im, 1).astype(np.float32)
    return np.take(flat, row + col), gu, gv


#: most boxes a stretched penumbra is swept with (``penumbra_blur`` with a geometry)
MAX_BOXES = 6


def penumbra_blur(darkness, distance, inside, softness: float, geometry=None, device=None) -> np.ndarray:
    """The soft shadow estimated from a hard one (module docstring, steps 1-2).

    darkness: float (H, W) in [0, 1], the hard shadow (1 shadow); distance: float
    (H, W) blocker distance [px] where shadowed (ignored elsewhere); inside: bool
    (H, W), the cutout (its pixels average only cutout pixels, the others only
    background pixels; outside the image counts as neither); softness: light
    radius over distance (>= 0).
    geometry: None (the square box of half-size ``softness x d``), or
    ``(bg_height, light, extremes)``: the background's pixel heights (H, W) [px],
    the light's centre (4,) and its disk's extreme points (4, 4) in pixel-height
    space; then the background's penumbra is stretched (module docstring, step 2';
    only the pixels step 1 would change change, so the module docstring's
    guarantees hold):
    ``penumbra_axes`` gives each pixel's ellipse and the box is swept along its
    major axis (the cutout's self-shadow keeps the square box).
    device: None (numpy throughout) or a ``pixgraph.device.Device``: the stretched
    boxes are summed by the OpenCL kernel ``swept_boxes`` (preview_swept.cl; equal
    to the numpy reference ``_swept_boxes`` to float rounding), where the device has
    doubles (else numpy).
    Returns darkness float32 (H, W) in [0, 1]; softness 0 returns ``darkness``.
    """
    dark = np.clip(np.asarray(darkness, np.float32), 0.0, 1.0)
    H, W = dark.shape
    dist = np.asarray(distance, np.float32)
    inside = np.asarray(inside, bool)
    if dist.shape != dark.shape or inside.shape != dark.shape:
        raise ValueError(f"darkness, distance and inside must share one shape, got "
                         f"{dark.shape}, {dist.shape}, {inside.shape}")
    softness = float(softness)
    if not math.isfinite(softness) or softness < 0:
        raise ValueError(f"softness must be finite and >= 0, got {softness}")
    out = dark.copy()
    shadowed = (dark > 0.0) & np.isfinite(dist)
    if softness == 0.0 or not shadowed.any():
        return out
    cap = max(1, int(MAX_REACH * max(H, W)))
    search = min(cap, math.ceil(softness * float(dist[shadowed].max())))     # step 1's reach
    if search < 1:
        return out
    reach_i = reach_j = search
    if geometry is not None:
        bg, light, extremes = geometry
        bg = np.ascontiguousarray(bg, np.float32)
        if bg.shape != dark.shape:
            raise ValueError(f"geometry's bg_height must have the darkness's shape {dark.shape}, got {bg.shape}")
        # the background's boxes reach as far as the ellipses of its shadowed pixels
        # extend along each image axis (on a grid of at most about 4000 of them: the
        # reach only bounds the boxes), one pixel more
        src = shadowed & ~inside
        step = max(1, math.ceil(math.sqrt(np.count_nonzero(src) / 4000.0)))
        si, sj = np.nonzero(src[::step, ::step])
        si, sj = si * step, sj * step
        if si.size:
            hb, gu, gv = _receiver_slope(bg, si, sj)
            a, b, cu, cv = penumbra_axes(sj + 0.5, si + 0.5, hb, gu, gv, dist[si, sj], light, extremes)
            ext_u = np.sqrt((a * cu) ** 2 + (b * cv) ** 2)
            ext_v = np.sqrt((a * cv) ** 2 + (b * cu) ** 2)
            ok = np.isfinite(ext_u) & np.isfinite(ext_v)
            if ok.any():
                reach_j = min(cap, max(search, math.ceil(1.0 + float(ext_u[ok].max()))))
                reach_i = min(cap, max(search, math.ceil(1.0 + float(ext_v[ok].max()))))
    for side, swept in ((~inside, geometry is not None), (inside, False)):
        src = shadowed & side
        if not src.any():
            continue
        Ri, Rj = (reach_i, reach_j) if swept else (search, search)
        rows, cols = np.flatnonzero(src.any(axis=1)), np.flatnonzero(src.any(axis=0))
        # the pixels that may change lie within step 1's reach of a shadowed pixel; they
        # read up to Ri rows and Rj columns farther: a zero-padded crop, so that every box
        # lies inside it
        o0, o1 = max(0, rows[0] - search), min(H, rows[-1] + 1 + search)
        p0, p1 = max(0, cols[0] - search), min(W, cols[-1] + 1 + search)
        r0, r1, c0, c1 = max(0, o0 - Ri), min(H, o1 + Ri), max(0, p0 - Rj), min(W, p1 + Rj)
        planes = np.zeros((3, o1 - o0 + 2 * Ri, p1 - p0 + 2 * Rj), np.float32)
        at = (slice(None), slice(r0 - o0 + Ri, r1 - o0 + Ri), slice(c0 - p0 + Rj, c1 - p0 + Rj))
        wgt = side[r0:r1, c0:c1]
        planes[at] = [wgt, np.where(src[r0:r1, c0:c1], dark[r0:r1, c0:c1], 0.0),
                      np.where(src[r0:r1, c0:c1], dark[r0:r1, c0:c1] * dist[r0:r1, c0:c1], 0.0)]
        z = _sat(planes)
        ei, ej = Ri - search, Rj - search
        nw, na, nb = _box_fixed(z[:, ei:z.shape[1] - ei, ej:z.shape[2] - ej], search, search)
        # both shadow and light of this side within step 1's reach (an all-shadow box
        # keeps 1; a swept box reaches farther but changes only these pixels)
        mixed = side[o0:o1, p0:p1] & (na > 0.0) & (na < nw - 1e-6)
        i, j = np.nonzero(mixed)
        dbar = nb[i, j] / na[i, j]
        if swept:
            boxes = _swept_boxes_cl if device is not None and _has_doubles(device) else _swept_boxes
            out[i + o0, j + p0] = boxes(z, i, j, o0, p0, dbar, softness, Ri, Rj, bg, light, extremes,
                                        out[i + o0, j + p0], device=device)
            continue
        r = np.minimum(np.rint(softness * dbar), search).astype(np.int64)
        k = r >= 1
        i, j, r = i[k], j[k], r[k]
        den, num = _box_at(z[:2], i + Ri, j + Rj, r)
        out[i + o0, j + p0] = np.clip(num / np.maximum(den, 1.0), 0.0, 1.0)
    return out


#: work items (of 8 pixels) per work-group of the ``swept_boxes`` kernel
SWEPT_GROUP = 16


def _has_doubles(device) -> bool:
    """Whether ``device`` runs the ``swept_boxes`` kernel (it needs cl_khr_fp64)."""
    return "cl_khr_fp64" in device.queue.device.extensions


def _swept_boxes_cl(z, i, j, o0, p0, dbar, softness, Ri, Rj, bg, light, extremes, keep, *, device):
    """:func:`_swept_boxes` by the OpenCL kernel ``swept_boxes`` (preview_swept.cl),
    8 pixels a work item; the same arguments, the same result to float rounding."""
    cl = S._cl()
    n = int(i.size)
    res = np.asarray(keep, np.float32).copy()
    if n == 0:
        return res
    prg = device.program(load_kernel_source(__file__, "preview_swept.cl"), S.BUILD_OPTIONS)
    mf, ctx = cl.mem_flags, device.context
    z = np.ascontiguousarray(z, np.float64)
    bg = np.ascontiguousarray(bg, np.float32)
    # the tables and the heights are read where they lie (no copy on a CPU device)
    zb = cl.Buffer(ctx, mf.READ_ONLY | mf.USE_HOST_PTR, hostbuf=z)
    bgb = cl.Buffer(ctx, mf.READ_ONLY | mf.USE_HOST_PTR, hostbuf=bg)
    # 8 pixels a work item, work-groups of a fixed size (PoCL compiles a kernel anew for
    # each work-group size it picks, and the count of pixels changes from call to call):
    # the per-pixel arrays padded with copies of the last pixel
    items = -(-n // (8 * SWEPT_GROUP)) * SWEPT_GROUP
    pad = np.minimum(np.arange(8 * items), n - 1)
    ins = [cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=np.ascontiguousarray(np.asarray(a)[pad], t))
           for a, t in ((i, np.int32), (j, np.int32), (dbar, np.float64), (res, np.float32))]
    L = np.asarray(light, np.float64)
    ext = np.zeros((4, 4), np.float32)
    ext[:, :3] = np.asarray(extremes, np.float32)[:4, :3]
    extb = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=ext)
    out = np.empty(8 * items, np.float32)
    outb = cl.Buffer(ctx, mf.WRITE_ONLY, out.nbytes)
    import pyopencl.cltypes as cltypes
    lf4 = cltypes.make_float4(float(np.float32(L[0])), float(np.float32(L[1])), float(np.float32(L[2])), 0.0)
    ev = S._kernel(prg, "swept_boxes")(
        device.queue, (items,), (SWEPT_GROUP,), zb, np.int32(z.shape[2]), np.int32(z.shape[1] * z.shape[2]),
        bgb, np.int32(bg.shape[1]), np.int32(bg.shape[0]), *ins, np.int32(o0), np.int32(p0),
        np.int32(Ri), np.int32(Rj), np.float64(softness), lf4, np.float32(-1.0 if L[3] < 0 else 1.0), extb, outb)
    cl.enqueue_copy(device.queue, out, outb, wait_for=[ev])
    return out[:n]


def _swept_boxes(z, i, j, o0, p0, dbar, softness, Ri, Rj, bg, light, extremes, keep, device=None):
    """Step 2': the darkness at crop pixels (i, j) (image pixels (i + o0, j + p0); the
    crop's tables z are padded by Ri rows and Rj columns) averaged over n square boxes
    of half-size ``round(minor)`` whose centres are spread evenly along the major axis
    so that together they span ``major`` each way (n = 1 + ceil((major - minor) /
    minor), at most MAX_BOXES; their sums added, so overlaps count twice, as a disk's
    middle weighs more). Where the geometry degenerates the square box of half-size
    ``softness x dbar``; pixels whose ellipse is under a pixel keep ``keep``. The numpy
    reference of the kernel ``swept_boxes`` (:func:`_swept_boxes_cl`); ``device`` is
    ignored."""
    gi, gj = i + o0, j + p0
    hb, gu, gv = _receiver_slope(bg, gi, gj)
    major, minor, cu, cv = penumbra_axes(gj + 0.5, gi + 0.5, hb, gu, gv, dbar, light, extremes)
    bad = ~(np.isfinite(major) & np.isfinite(minor) & np.isfinite(cu) & np.isfinite(cv))
    if bad.any():
        iso = (softness * dbar).astype(np.float32)
        major, minor = np.where(bad, iso, major), np.where(bad, iso, minor)
        cu, cv = np.where(bad, np.float32(1.0), cu), np.where(bad, np.float32(0.0), cv)
    major = np.minimum(major, np.float32(max(Ri, Rj)))
    minor = np.minimum(minor, major)
    res = np.asarray(keep, np.float32).copy()
    n = np.minimum(MAX_BOXES, 1 + np.ceil((major - minor) / np.maximum(minor, np.float32(0.5))))
    n = np.where(np.rint(major) >= 1, n, 0).astype(np.int64)      # 0: under a pixel, kept
    # the pixels in order of decreasing n: box m is summed over a prefix of them
    order = np.concatenate([np.flatnonzero(n == c) for c in range(MAX_BOXES, 0, -1)])
    if order.size == 0:
        return res
    i, j, major, minor, cu, cv, n = (x[order] for x in (i, j, major, minor, cu, cv, n))
    # box half-size: the minor axis, at least half the centres' spacing (no gaps)
    gap = np.maximum(n - 1, 1).astype(np.float32)
    spacing = np.where(n > 1, 2.0 * (major - minor) / gap, np.float32(0.0))
    r = np.minimum(np.maximum(np.rint(minor), np.ceil(spacing / 2)), min(Ri, Rj)).astype(np.int64)
    span = np.where(n > 1, np.maximum(major - r, np.float32(0.0)), np.float32(0.0))
    # centre m of n: -span + m 2 span / (n - 1) along (cu, cv), clipped so the box stays in the tables
    su, sv = span * cu, span * cv
    du, dv = 2.0 * su / gap, 2.0 * sv / gap
    lo_i, hi_i, lo_j, hi_j = r - Ri, Ri - r, r - Rj, Rj - r
    ci, cj = i + Ri, j + Rj
    count = np.bincount(n, minlength=MAX_BOXES + 1)[::-1].cumsum()[::-1]    # count[m]: pixels with n >= m
    den = np.zeros(i.shape, np.float64)
    num = np.zeros(i.shape, np.float64)
    for m in range(int(n[0])):
        c = count[m + 1]
        oi = np.clip(np.rint(m * dv[:c] - sv[:c]), lo_i[:c], hi_i[:c]).astype(np.int64)
        oj = np.clip(np.rint(m * du[:c] - su[:c]), lo_j[:c], hi_j[:c]).astype(np.int64)
        d_, n_ = _box_at(z[:2], ci[:c] + oi, cj[:c] + oj, r[:c])
        den[:c] += d_
        num[:c] += n_
    res[order] = np.clip(num / np.maximum(den, 1.0), 0.0, 1.0)
    return res


def preview_soft_shadow(device, mask, fg_height, bg_height, light, softness, thickness=1.0, *,
                        extremes=None, progress=None, check_cancelled=None) -> np.ndarray:
    """A preview's soft shadow: darkness float32 (H, W) in [0, 1] (1 full shadow).
    light: the light's centre (u, v, h, s); softness: radius over distance (0 for
    a point light: the hard shadow exactly); extremes: None (the square box) or the
    disk's extreme points (4, 4) (``lights.disk_extremes``: the stretched penumbra of
    ``penumbra_blur``'s geometry, its boxes summed on ``device``). Other inputs as
    ``shadow.hard_shadow``."""
    dark, dist = hard_shadow_distance(device, mask, fg_height, bg_height, light, thickness,
                                      progress=progress, check_cancelled=check_cancelled)
    geometry = None if extremes is None else (bg_height, light, extremes)
    return penumbra_blur(dark, dist, np.asarray(mask) > 0.5, softness, geometry, device=device)
