"""Reflection and refraction traced in pixel-height space (PixHt-Lab Sec. 3.3).

Numpy references next to the OpenCL kernels of ``reflection.cl`` (same names,
``rt_`` prefix dropped), plus the host-side wrappers the nodes call. The sampling
and material math is in ``reflection_math.py``, refraction in ``refraction.py``,
the proxy resolution of large images in ``reflection_proxy.py``; their names are
importable from here too.

Units: image coordinates ``u`` (right), ``v`` (down) and pixel height ``h`` in
pixels, pixel centres at ``+0.5``; 3D directions are unit vectors in the world
frame (y up, ground ``Y = 0``, camera at ``(0, H_cam, 0)`` looking down ``-Z``).

**3D ray to (u, v, h).** The projection ``(u, v, h) = (W/2 + f X/D, horizon +
f (H_cam - Y)/D, f Y/D)`` is homogeneous with the common denominator ``D = -Z``,
so a 3D ray ``P + t d`` maps to the straight (u, v, h) ray ``p0 + s e`` with

    e = Nd + d_z p0,   Nd = (W/2 (-d_z) + f d_x, horizon (-d_z) - f d_y, f d_y),
    s = t / (D0 - t d_z).

When ``d_z < 0`` (away from the camera) the ray ends at its vanishing point
``Nd / (-d_z)`` (foot on the horizon) at ``s = 1/(-d_z)``; otherwise its image runs
away from the vanishing point without end. The depth ``D0`` cancels: only the
origin's ``(u, v, h)`` and ``d`` matter.

**Planar mirror closed form.** Reflecting ``P = (X, Y, Z)`` over the ground gives
``(X, -Y, Z)``: same ``u`` and ``D``, ``v' = horizon + f (H_cam + Y)/D = v + 2h`` and
``h' = -h``. A cutout point ``(u, v, h)`` appears in a flat mirror floor at
``(u, v + 2h)``: the cutout flipped about its foot line. The reflected view ray of
a ground pixel runs straight up its own column with ray height ``(v_r - v)/2``
at row ``v``; :func:`planar_mirror` evaluates that column march for every pixel at
once by scattering each cutout pixel to the receiver rows it is hit from.

**Material model.** Isotropic GGX with ``alpha = roughness**2``, Smith
height-correlated masking-shadowing, visible-normal (VNDF, Heitz 2018) importance
sampling; the sample weight is ``F(wo.m) G2(wo, wi) / G1(wo)`` and a direction below
the surface is rejected (weight 0, never traced). Fresnel: *exact* unpolarised
dielectric reflectance with IOR ``eta`` (not Schlick), or Schlick with a coloured
``f0`` for conductors.
"""
from __future__ import annotations

import numpy as np

from . import march
from .camera import Camera, reconstruct
from .reflection_math import (F32, UNBOUNDED, basis, fresnel_dielectric, fresnel_schlick,  # noqa: F401
                              ggx_d, ggx_sample_weight, pcg, rand, reflect, refract, sample2,
                              sample_vndf, smith_lambda, uvh_direction, view_directions)

#: thickness (pixels) of a solid surface: everything behind the background is inside it
SOLID = F32(1.0e30)


# ---------------------------------------------------------------------------
# surfaces and the max-height pyramid
# ---------------------------------------------------------------------------

def max_pyramid(surf: np.ndarray):
    """Min/max-height pyramid of a surface buffer (``march.surface_buffer``).

    Level 0 is ``surf`` itself (not stored). Level ``l >= 1`` holds, per 2^l x 2^l
    tile, the (min, max) of ``surf`` dilated by one pixel (the march interpolates
    the surface between minor-axis neighbours, which may lie in the next tile);
    (+1e30, -1e30) for empty tiles. Levels go up to a single tile.
    Returns ``(pyr, lvl, nlev)``: float32 (tiles, 2) levels one after another,
    int32 (nlev, 3) rows of (width, height, offset in tiles) (row 0 describes
    level 0, offset unused), and the level count.
    """
    surf = np.asarray(surf, np.float32)
    H, W = surf.shape
    present = surf > march.NO_SURFACE_TEST
    hi = surf.copy()
    lo = np.where(present, surf, -march.NO_SURFACE).astype(np.float32)
    phi = np.pad(hi, 1, constant_values=march.NO_SURFACE)
    plo = np.pad(lo, 1, constant_values=-march.NO_SURFACE)
    for di in (0, 1, 2):
        for dj in (0, 1, 2):
            np.maximum(hi, phi[di:di + H, dj:dj + W], out=hi)
            np.minimum(lo, plo[di:di + H, dj:dj + W], out=lo)
    levels = [(W, H, 0)]
    chunks = []
    off = 0
    while max(hi.shape) > 1:
        h, w = hi.shape
        ph = np.pad(hi, ((0, h % 2), (0, w % 2)), constant_values=march.NO_SURFACE)
        pl = np.pad(lo, ((0, h % 2), (0, w % 2)), constant_values=-march.NO_SURFACE)
        hi = np.maximum(np.maximum(ph[0::2, 0::2], ph[0::2, 1::2]), np.maximum(ph[1::2, 0::2], ph[1::2, 1::2]))
        lo = np.minimum(np.minimum(pl[0::2, 0::2], pl[0::2, 1::2]), np.minimum(pl[1::2, 0::2], pl[1::2, 1::2]))
        levels.append((hi.shape[1], hi.shape[0], off))
        chunks.append(np.stack([lo.ravel(), hi.ravel()], -1))
        off += hi.size
    pyr = np.concatenate(chunks).astype(np.float32) if chunks else np.zeros((1, 2), np.float32)
    return pyr, np.asarray(levels, np.int32), len(levels)


def surface_box(surf: np.ndarray, thickness: float):
    """Bounding box of a surface buffer for march clipping: ``(rect, h_lo, h_hi)``
    with rect = (u0, v0, u1, v1) pixel edges; None when the surface is empty."""
    present = surf > march.NO_SURFACE_TEST
    if not present.any():
        return None
    rows = np.flatnonzero(present.any(axis=1))
    cols = np.flatnonzero(present.any(axis=0))
    hs = surf[present]
    rect = (float(cols[0]), float(rows[0]), float(cols[-1] + 1), float(rows[-1] + 1))
    return rect, float(max(hs.min() - thickness, -SOLID)), float(hs.max())


# ---------------------------------------------------------------------------
# numpy reference of the closest-hit march (plain, no pyramid)
# ---------------------------------------------------------------------------

def setup_rays(p0, e, s_max, W, H, box=None, h_lo=-SOLID, h_hi=SOLID):
    """March set-up of (u, v, h) rays ``p0 + s e`` clipped to the image and a box
    (mirror of ``rt_setup``). Returns ``(march.March, ok)``."""
    p0 = np.asarray(p0, np.float32).reshape(-1, 3)
    e = np.asarray(e, np.float32).reshape(-1, 3)
    m, ok = march.march_setup(p0[:, 0], p0[:, 1], p0[:, 2], e[:, 0], e[:, 1], e[:, 2],
                              np.asarray(s_max, np.float32).reshape(-1))
    ok &= march.march_clip_box(m, (0.0, 0.0, float(W), float(H)), -SOLID, SOLID)
    if box is not None:
        ok &= march.march_clip_box(m, box, h_lo, h_hi)
    return m, ok


def trace_closest(surf: np.ndarray, m: march.March, ok: np.ndarray, thickness: float, with_k: bool = False):
    """Closest hit of every march against a pixel-height surface (plain marching).

    Returns ``(hit, last)``: flat pixel index of the first sample where the ray
    passes behind the surface by at most ``thickness`` pixels or crosses it between
    two consecutive surface samples (``march.occludes``), -1 for none; and the last
    in-image sample pixel visited (-1 for none). ``with_k``: also the sample index
    of the hit, or with none of the last in-image sample (-1 for none), as
    ``rt_trace_k``'s ``kout``: ``(hit, last, k)``."""
    H, W = surf.shape
    n = m.u.shape[0]
    hit = np.full(n, -1, np.int64)
    last = np.full(n, -1, np.int64)
    prev = np.zeros(n, np.int8)
    kout = np.full(n, -1, np.int64)
    active = ok & (m.k_lo <= m.k_hi)
    if not active.any():
        return (hit, last, kout) if with_k else (hit, last)
    k = m.k_lo.astype(np.int64).copy()
    while active.any():
        idx = np.flatnonzero(active)
        kk = k[idx]
        sub = march.March(m.u[idx], m.v[idx], m.h[idx], m.su[idx], m.sv[idx], m.sh[idx],
                          m.k_lo[idx], m.k_hi[idx], m.major_u[idx])
        u = sub.sample_u(kk)
        v = sub.sample_v(kk)
        j = np.floor(u).astype(np.int64)
        i = np.floor(v).astype(np.int64)
        inside = (j >= 0) & (j < W) & (i >= 0) & (i < H)
        pix = np.where(inside, i * W + j, -1)
        last[idx] = np.where(inside, pix, last[idx])
        kout[idx] = np.where(inside, kk, kout[idx])
        sh = march.surface_height(surf, u, v, sub.major_u)
        rh = sub.ray_height(kk)
        side = march.side(rh, sh)
        occ = march.occludes(rh, sh, thickness, side, prev[idx])
        hit[idx[occ]] = pix[occ]
        prev[idx] = side
        k[idx] += 1
        active[idx[occ]] = False
        active &= k <= m.k_hi
    return (hit, last, kout) if with_k else (hit, last)


# ---------------------------------------------------------------------------
# planar mirror closed form
# ---------------------------------------------------------------------------

def planar_mirror(camera: Camera, surf: np.ndarray, thickness: float) -> np.ndarray:
    """Closest hit of the mirror reflection of every ground pixel of a flat floor.

    Exact closed form of the column march: the reflected view ray of the ground
    pixel at row ``r`` (index) climbs its own column with ray height ``(r - q)/2`` at
    row ``q < r`` (pixels between centres), so sample ``q`` is behind the cutout
    when ``r < m(q) - 2 eps`` with ``m(q) = q + 2 fg(q)`` (the mirror row
    ``v + 2h`` of the cutout pixel), within the thickness when
    ``r >= m(q) - 2 thickness``, and consecutive samples ``q + 1, q`` cross the
    surface when ``r`` lies between ``m'(q)`` and ``m'(q+1)``. Each cutout pixel
    scatters its row index to the receiver rows of those intervals; the largest
    (first along the march) wins. Cost O(mask pixels x interval length).

    Returns int64 (H, W) hit pixel index, -1 for none. Valid for receivers on flat
    ground (normal +Y); the caller decides where that holds.
    """
    H, W = surf.shape
    eps = float(march.BEHIND_EPS)
    present = surf > march.NO_SURFACE_TEST
    best = np.full((H, W), -1, np.int64)
    q, c = np.nonzero(present)
    if q.size == 0:
        return best
    fg = surf[q, c].astype(np.float64)
    mprime = q + 2.0 * fg - 2.0 * eps
    # the ray ends at its vanishing point: row centre q + .5 >= 2 horizon - (r + .5)
    r_vp = np.ceil(2.0 * camera.horizon - q - 1.0)

    def scatter(lo, hi, qq, cc):
        # integer receivers r in [lo, hi) (reals), r <= H - 1
        r0 = np.ceil(lo).astype(np.int64)
        r1 = np.minimum(np.ceil(hi).astype(np.int64), H)
        n = np.maximum(r1 - r0, 0)
        if n.sum() == 0:
            return
        rep = np.repeat(np.arange(n.size), n)
        offs = np.arange(rep.size) - np.repeat(np.cumsum(n) - n, n)
        rr = r0[rep] + offs
        key = rr * W + cc[rep]
        val = qq[rep]
        # largest q per receiver: sort by (key, q) and keep each key's last entry
        order = np.lexsort((val, key))
        key, val = key[order], val[order]
        last = np.ones(key.size, bool)
        last[:-1] = key[1:] != key[:-1]
        flat = best.reshape(-1)
        flat[key[last]] = np.maximum(flat[key[last]], val[last])

    # within the thickness at q itself (the first sample is q = r - 1)
    lo = np.maximum.reduce([q + 2.0 * fg - 2.0 * thickness, q + 1.0, r_vp])
    scatter(lo, mprime, q, c)
    # crossing between the previous sample q + 1 (also a surface sample) and q
    nb = (q + 1 < H)
    qn, cn, mpn = q[nb], c[nb], mprime[nb]
    has = present[qn + 1, cn]
    qn, cn, mpn = qn[has], cn[has], mpn[has]
    fg1 = surf[qn + 1, cn].astype(np.float64)
    mp1 = (qn + 1) + 2.0 * fg1 - 2.0 * eps
    lo = np.maximum.reduce([np.minimum(mpn, mp1), qn + 2.0, r_vp[nb][has]])
    scatter(lo, np.maximum(mpn, mp1), qn, cn)
    return np.where(best >= 0, best * W + np.arange(W)[None, :], -1)


def flat_ground(bg_height: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Receivers where the planar closed form is exact: ground (h = 0) whose 3x3
    neighbourhood is ground too (so the reconstructed normal is exactly +Y)."""
    h = np.asarray(bg_height)
    z = np.pad(h == 0, 1, constant_values=True)
    H, W = h.shape
    ok = np.ones((H, W), bool)
    for di in (0, 1, 2):
        for dj in (0, 1, 2):
            ok &= z[di:di + H, dj:dj + W]
    return ok & (np.asarray(valid) > 0.5)


# ---------------------------------------------------------------------------
# numpy reference of the reflection estimator (fixed sample count)
# ---------------------------------------------------------------------------

def _receivers(camera: Camera, bg_height):
    geo = reconstruct(camera, bg_height)
    view = view_directions(camera)
    n = geo["normal"].astype(np.float64)
    wo = -view
    cos_o = np.sum(n * wo, axis=-1)
    ok = (geo["valid"] > 0.5) & (cos_o > 1e-4)
    return geo, n, wo, cos_o, ok


def reflection_numpy(camera: Camera, cutout: np.ndarray, fg_height: np.ndarray,
                     bg_height: np.ndarray, *, roughness=0.0, eta=1.5, conductor=False,
                     f0=(1.0, 1.0, 1.0), strength=1.0, thickness=4.0, spp=16, seed=0,
                     mask=None) -> np.ndarray:
    """Reference of ``rt_reflect`` with a fixed sample count (no adaptivity).

    cutout: (H, W, 4) premultiplied linear RGBA; its alpha is the mask unless
    ``mask`` is given. Returns float32 (H, W, 4) premultiplied reflection layer.
    Same random numbers as the kernel, so they agree up to float rounding."""
    H, W = bg_height.shape
    cutout = np.asarray(cutout, np.float32)
    surf = march.surface_buffer(cutout[..., 3] if mask is None else mask, fg_height)
    box = surface_box(surf, thickness)
    out = np.zeros((H, W, 4), np.float64)
    if box is None:
        return out.astype(np.float32)
    geo, n, wo, cos_o, ok = _receivers(camera, bg_height)
    alpha = float(roughness) ** 2
    idx = np.flatnonzero(ok.ravel())
    nn = n.reshape(-1, 3)[idx]
    wwo = wo.reshape(-1, 3)[idx]
    b1, b2 = basis(nn)
    wol = np.stack([np.sum(wwo * b1, -1), np.sum(wwo * b2, -1), np.sum(wwo * nn, -1)], -1)
    u, v = camera.pixel_grid()
    p0 = np.stack([u.ravel()[idx], v.ravel()[idx], np.asarray(bg_height, np.float32).ravel()[idx]], -1)
    flat_rgba = cutout.reshape(-1, 4).astype(np.float64)
    nsamp = spp if alpha > 0 else 1
    acc = np.zeros((idx.size, 4))
    for s in range(nsamp):
        u1, u2 = (x.astype(np.float64) for x in sample2(seed, idx, s))
        wil, w = ggx_sample_weight(wol, alpha, u1, u2, eta, conductor, f0)
        wi = wil[:, :1] * b1 + wil[:, 1:2] * b2 + wil[:, 2:] * nn
        e, s_max = uvh_direction(camera, p0, wi)
        m, okm = setup_rays(p0, e, s_max, W, H, *box)
        okm &= np.any(w > 0, axis=-1)
        hit, _ = trace_closest(surf, m, okm, thickness)
        got = hit >= 0
        col = flat_rgba[np.where(got, hit, 0)]
        c = np.concatenate([w * col[:, :3], w.mean(-1, keepdims=True) * col[:, 3:]], -1)
        acc += np.where(got[:, None], strength * c, 0.0)
    out.reshape(-1, 4)[idx] = acc / nsamp
    return out.astype(np.float32)


# ---------------------------------------------------------------------------
# OpenCL wrappers
# ---------------------------------------------------------------------------

class _Kernels:
    """Kernels of the built program, a fresh ``cl.Kernel`` per call: kernel objects
    carry their arguments, so sharing one between threads would race."""

    def __init__(self, prg):
        self._prg = prg

    def __getattr__(self, name):
        import pyopencl as cl
        return cl.Kernel(self._prg, name)


def _program(device):
    from pixgraph.device import load_kernel_source
    return _Kernels(device.program(load_kernel_source(__file__, "reflection.cl")))


def _buf(cl, ctx, array, flags=None):
    mf = cl.mem_flags
    a = np.ascontiguousarray(array)
    return cl.Buffer(ctx, (flags or mf.READ_ONLY) | mf.COPY_HOST_PTR, hostbuf=a)


def _read(cl, queue, *buffers):
    """Copy ``(device buffer, shape, dtype)`` triples back to new host arrays."""
    out = [np.empty(shape, dtype) for _, shape, dtype in buffers]
    for (d, _, _), host in zip(buffers, out):
        cl.enqueue_copy(queue, host, d)
    queue.finish()
    return out


class _Surface:
    """A surface buffer with its pyramid and box, uploaded once."""

    def __init__(self, cl, ctx, surf, thickness, hiz=True):
        self.surf = np.ascontiguousarray(surf, np.float32)
        pyr, lvl, nlev = max_pyramid(self.surf)
        self.nlev = nlev if hiz else 1
        box = surface_box(self.surf, thickness)
        self.empty = box is None
        rect, self.h_lo, self.h_hi = box if box else ((0.0, 0.0, 0.0, 0.0), 0.0, 0.0)
        self.box = np.array(rect, np.float32)
        self.d_surf = _buf(cl, ctx, self.surf)
        self.d_pyr = _buf(cl, ctx, pyr)
        self.d_lvl = _buf(cl, ctx, lvl.ravel())


def trace_rays_cl(device, surf, p0, e, s_max, thickness, *, hiz=True, clip_box=True):
    """Closest hits of (u, v, h) rays on the device (test/benchmark entry).

    Returns ``(hit, last, steps)`` int32 arrays (hit/last flat pixel indices, -1 none;
    steps = march loop iterations)."""
    import pyopencl as cl
    ctx, queue = device.context, device.queue
    H, W = surf.shape
    S = _Surface(cl, ctx, surf, thickness, hiz)
    rays = np.concatenate([np.asarray(p0, np.float32).reshape(-1, 3), np.asarray(e, np.float32).reshape(-1, 3),
                           np.asarray(s_max, np.float32).reshape(-1, 1)], 1)
    n = rays.shape[0]
    outs = [np.empty(n, np.int32) for _ in range(3)]
    d_out = [cl.Buffer(ctx, cl.mem_flags.WRITE_ONLY, max(4 * n, 4)) for _ in range(3)]
    if clip_box and not S.empty:
        box, lo, hi = S.box, S.h_lo, S.h_hi
    else:
        box, lo, hi = np.array([0, 0, W, H], np.float32), -float(SOLID), float(SOLID)
    prg = _program(device)
    prg.rt_trace_rays(queue, (max(n, 1),), None, np.int32(W), np.int32(H), np.int32(n), _buf(cl, ctx, rays),
                      S.d_surf, S.d_pyr, S.d_lvl, np.int32(S.nlev), np.float32(thickness),
                      np.asarray(box, np.float32),
                      np.float32(lo), np.float32(hi), *d_out)
    for h, d in zip(outs, d_out):
        cl.enqueue_copy(queue, h, d)
    queue.finish()
    return tuple(outs)


def reflection_cl(device, camera: Camera, cutout, fg_height, bg_height, *, roughness=0.0, eta=1.5,
                  conductor=False, f0=(1.0, 1.0, 1.0), strength=1.0, thickness=4.0, min_spp=16,
                  max_spp=256, target_se=0.002, seed=0, mask=None, hiz=True, planar=True,
                  probe_spp=4, probe_radius=4, band_rows=64, receive=None, progress=None,
                  check_cancelled=None):
    """Glossy reflection layer of the cutout on the background, on the device.

    Sampling: ``min_spp == max_spp`` takes that many samples everywhere. Otherwise
    adaptive: every receiver is probed with ``probe_spp`` samples; those within
    ``probe_radius`` pixels of a probe hit take ``min_spp`` to ``max_spp`` samples,
    stopping when the standard error of every channel is <= ``target_se``
    (linear RGBA units); the rest stay 0. Roughness 0: one sample.

    Returns a dict: ``layer`` float32 (H, W, 4) premultiplied linear RGBA, ``spp``
    int32 (H, W) samples in each pixel's estimate (0 where none were needed; an
    adaptive pixel also spent its probe's samples), ``steps`` int32 (H, W) march
    iterations of all passes, ``planar`` bool (H, W) pixels done by the
    closed form. ``planar`` (roughness 0 only) uses :func:`planar_mirror` on flat
    ground, where it is exact. ``receive``: bool (H, W) of the receivers to trace
    (None: all); the others stay 0 and cost nothing (a wall that is masked off
    afterwards). Work is enqueued in bands of ``band_rows`` rows so
    that progress and cancellation are checked between bands."""
    import pyopencl as cl
    ctx, queue = device.context, device.queue
    cutout = np.asarray(cutout, np.float32)
    fg_height = np.asarray(fg_height, np.float32)
    bg_height = np.asarray(bg_height, np.float32)
    check_shapes(camera, cutout=cutout, fg_height=fg_height, bg_height=bg_height,
                 mask=None if mask is None else np.asarray(mask))
    H, W = bg_height.shape
    surf = march.surface_buffer(cutout[..., 3] if mask is None else mask, fg_height)
    layer = np.zeros((H, W, 4), np.float32)
    spp = np.zeros((H, W), np.int32)
    steps = np.zeros((H, W), np.int32)
    done = np.zeros((H, W), bool)
    if surface_box(surf, thickness) is None:
        return {"layer": layer, "spp": spp, "steps": steps, "planar": done}
    # receivers: the foot below the horizon (as camera.back_project decides)
    v_centre = np.arange(H, dtype=np.float64)[:, None] + 0.5
    bgh = np.asarray(bg_height, np.float64)
    valid = np.isfinite(bgh) & (v_centre + bgh - camera.horizon > 1e-9)
    # pixels not to trace; `valid` itself stays whole (rt_normal differences read it)
    off = ~valid if receive is None else ~(valid & np.asarray(receive, bool))
    alpha = float(roughness) ** 2
    if alpha == 0.0 and planar:
        done = flat_ground(bg_height, valid)
        hit = planar_mirror(camera, surf, thickness)
        got = np.flatnonzero((done & (hit >= 0)).ravel())
        # n = +Y on flat ground: cos_o = -view_y = (v - horizon) / |view|
        u = (got % W).astype(np.float64) + 0.5
        v = (got // W).astype(np.float64) + 0.5
        f = camera.focal
        cos_o = (v - camera.horizon) / np.sqrt((u - W / 2.0) ** 2 + (camera.horizon - v) ** 2 + f * f)
        w = (fresnel_schlick(cos_o, f0) if conductor
             else np.repeat(fresnel_dielectric(cos_o, eta)[..., None], 3, -1))
        col = cutout.reshape(-1, 4)[hit.ravel()[got]]
        c = np.concatenate([w * col[:, :3], w.mean(-1, keepdims=True) * col[:, 3:]], -1)
        layer.reshape(-1, 4)[got] = np.where((cos_o > 1e-4)[:, None], strength * c, 0.0)
        layer[off] = 0.0
        spp = (done & ~off).astype(np.int32)
        if (done | off).all():
            return {"layer": layer, "spp": spp, "steps": steps, "planar": done}
    S = _Surface(cl, ctx, surf, thickness, hiz)
    prg = _program(device)
    mf = cl.mem_flags
    d_out = cl.Buffer(ctx, mf.WRITE_ONLY, H * W * 16)
    d_spp = cl.Buffer(ctx, mf.WRITE_ONLY, H * W * 4)
    d_steps = cl.Buffer(ctx, mf.WRITE_ONLY, H * W * 4)
    # receiver normals are computed in the kernel (rt_normal) from the heights
    common = [_buf(cl, ctx, np.where(valid, bgh, 0.0).astype(np.float32)),
              _buf(cl, ctx, valid.astype(np.float32))]
    rest = [S.d_surf, S.d_pyr, S.d_lvl, np.int32(S.nlev), S.box, np.float32(S.h_lo), np.float32(S.h_hi),
            _buf(cl, ctx, cutout), np.float32(thickness), np.float32(alpha), np.int32(bool(conductor)),
            np.float32(eta), np.asarray(tuple(f0) + (0.0,), np.float32), np.float32(strength)]
    min_spp = max(1, int(min_spp))
    max_spp = max(min_spp, int(max_spp))

    def run(skip, lo, hi, p0, p1):
        args = common + [_buf(cl, ctx, skip.astype(np.uint8))] + rest + [
            np.int32(lo), np.int32(hi), np.float32(target_se), np.uint32(seed), d_out, d_spp, d_steps]
        for y0 in range(0, H, band_rows):
            if check_cancelled is not None:
                check_cancelled()
            rows = min(band_rows, H - y0)
            if not (~skip[y0:y0 + rows]).any():
                continue
            prg.rt_reflect(queue, (W, rows), None, np.int32(W), np.int32(H), np.int32(y0),
                           np.float32(camera.focal), np.float32(camera.horizon),
                           np.float32(camera.cam_height), *args)
            queue.finish()
            if progress is not None:
                progress(p0 + (p1 - p0) * (y0 + rows) / H, "reflection")
        return _read(cl, queue, (d_out, (H, W, 4), np.float32), (d_spp, (H, W), np.int32),
                     (d_steps, (H, W), np.int32))

    skip = done | off
    if alpha == 0.0:
        band_rows = H
    if alpha > 0.0 and max_spp > min_spp and probe_spp < min_spp:
        # Adaptive: a pixel whose first few samples all miss has standard error 0,
        # yet its lobe may reach the cutout with a small probability (measured: 86 %
        # of the error of a 1-pass run came from such pixels stopped at zero).
        # So first probe every pixel with `probe_spp` samples; pixels within
        # `probe_radius` of any hit are sampled adaptively (from sample 0 again,
        # the sequence is deterministic); the others keep the probe's zero.
        out1, s1, st1 = run(skip, probe_spp, probe_spp, 0.0, 0.2)
        hot = (out1 != 0).any(-1)
        for _ in range(int(probe_radius)):
            g = np.pad(hot, 1)
            hot = (g[:-2, 1:-1] | g[2:, 1:-1] | g[1:-1, :-2] | g[1:-1, 2:] | g[:-2, :-2] | g[:-2, 2:]
                   | g[2:, :-2] | g[2:, 2:] | hot)
        out2, s2, st2 = run(skip | ~hot, min_spp, max_spp, 0.2, 1.0)
        out = np.where(hot[..., None], out2, out1)
        s_out = np.where(hot, s2, s1)
        st_out = st1 + np.where(hot, st2, 0)
    else:
        out, s_out, st_out = run(skip, min_spp, max_spp, 0.0, 1.0)
    layer = np.where(done[..., None], layer, np.where(off[..., None], 0.0, out)).astype(np.float32)
    spp = np.where(done, spp, np.where(off, 0, s_out)).astype(np.int32)
    steps = np.where(off, 0, st_out).astype(np.int32)
    return {"layer": layer, "spp": spp, "steps": steps, "planar": done}


def check_shapes(camera: Camera, **arrays) -> None:
    """Raise ValueError unless every array (its first two axes) and the camera have
    one (H, W) size, and arrays named in ``RGBA_INPUTS`` have 4 channels: the
    kernels index every buffer with the camera's W and H, so a smaller buffer
    would be read outside its memory."""
    want = (camera.height, camera.width)
    bad = [f"{k} {a.shape[1]}x{a.shape[0]}" for k, a in arrays.items()
           if a is not None and tuple(a.shape[:2]) != want]
    if bad:
        raise ValueError(f"sizes differ from the camera's {want[1]}x{want[0]} (width x height): {', '.join(bad)}")
    for k in RGBA_INPUTS:
        a = arrays.get(k)
        if a is not None and (a.ndim != 3 or a.shape[2] != 4):
            raise ValueError(f"{k} must be RGBA (H, W, 4), got shape {a.shape}")


#: inputs whose alpha (channel 3) the wrappers read
RGBA_INPUTS = ("cutout", "glass")


#: names that moved to refraction.py, still importable from here
_REFRACTION = ("local_radius", "refraction_numpy", "refraction_cl")


def __getattr__(name):
    if name in _REFRACTION:
        from . import refraction
        return getattr(refraction, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
