"""Refraction through a transparent cutout, traced in pixel-height space: the numpy
reference (``refraction_numpy``) next to the OpenCL wrapper (``refraction_cl``,
kernel ``rt_refract`` in ``reflection.cl``). Model and units: ``reflection.py``.
"""
from __future__ import annotations

import numpy as np

from . import march
from .camera import Camera, reconstruct
from .reflection import SOLID, _buf, _program, _read, _Surface, check_shapes, setup_rays, trace_closest
from .reflection_math import F32, fresnel_dielectric, refract, uvh_direction, view_directions


def local_radius(geo: dict, mask: np.ndarray, max_radius: float = np.inf) -> np.ndarray:
    """Radius of curvature (world units) of a reconstructed surface at each pixel:
    ``|dP| / |dn|`` between the two neighbours along u and along v (central
    differences), the smaller of the two (the most curved direction), for pixels
    at least two pixels inside ``mask``; the rim takes the mean of the nearest such
    pixels. Exact for a sphere. 0 where the surface is flat (no finite
    radius below ``max_radius``) or no interior pixel exists. float32 (H, W)."""
    P = geo["position"].astype(np.float64)
    n = geo["normal"].astype(np.float64)
    inside = (np.asarray(mask) > 0) & (geo["valid"] > 0.5)
    H, W = inside.shape

    def erode(m):
        e = m.copy()
        e[1:-1, 1:-1] &= m[:-2, 1:-1] & m[2:, 1:-1] & m[1:-1, :-2] & m[1:-1, 2:]
        e[[0, -1], :] = False
        e[:, [0, -1]] = False
        return e

    # twice: the rim pixels' normals mix in the outside (reconstruct differences
    # cross the mask edge), so neighbours must be one pixel in from the rim
    interior = erode(erode(inside))
    R = np.full((H, W), np.inf)
    for ax in (0, 1):
        dP = np.linalg.norm(np.roll(P, -1, ax) - np.roll(P, 1, ax), axis=-1)
        dn = np.linalg.norm(np.roll(n, -1, ax) - np.roll(n, 1, ax), axis=-1)
        with np.errstate(divide="ignore", invalid="ignore"):
            R = np.minimum(R, np.where(dn > 1e-9, dP / np.where(dn > 1e-9, dn, 1.0), np.inf))
    R = np.where(interior & (R < max_radius), R, 0.0)
    have = interior & (R > 0)
    if not have.any():
        return np.zeros((H, W), np.float32)
    # fill the rim from the nearest interior pixel (a few rings of 3x3 growth)
    out = np.where(have, R, 0.0)
    known = have.copy()
    for _ in range(max(H, W)):
        todo = inside & ~known
        if not todo.any():
            break
        pad = np.pad(out, 1)
        kpad = np.pad(known, 1)
        acc = np.zeros((H, W))
        cnt = np.zeros((H, W))
        for di in (0, 1, 2):
            for dj in (0, 1, 2):
                k = kpad[di:di + H, dj:dj + W]
                acc += np.where(k, pad[di:di + H, dj:dj + W], 0.0)
                cnt += k
        grow = todo & (cnt > 0)
        if not grow.any():
            break
        out[grow] = acc[grow] / cnt[grow]
        known |= grow
    return np.where(inside, out, 0.0).astype(np.float32)


def refraction_numpy(camera: Camera, glass: np.ndarray, glass_height: np.ndarray,
                     background: np.ndarray, bg_height: np.ndarray, *, eta=1.5,
                     tint=(1.0, 1.0, 1.0), fresnel=True, back_surface="none"):
    """Reference of ``rt_refract``. Returns ``(layer, tir)``: float32 (H, W, 4)
    premultiplied refraction layer and bool (H, W) where total internal reflection
    happened at the front surface. ``back_surface="local_sphere"`` refracts again
    at the back of the local sphere (see :func:`local_radius`)."""
    H, W = bg_height.shape
    glass = np.asarray(glass, np.float32)
    a = glass[..., 3]
    geo = reconstruct(camera, glass_height)
    view = view_directions(camera)
    n = geo["normal"].astype(np.float64)
    cos_i = -np.sum(view * n, -1)
    n = np.where((cos_i < 0)[..., None], -n, n)
    cos_i = np.abs(cos_i)
    sel = (a > 0) & (geo["valid"] > 0.5)
    idx = np.flatnonzero(sel.ravel())
    out = np.zeros((H * W, 4))
    tir_map = np.zeros(H * W, bool)
    if idx.size == 0:
        return out.reshape(H, W, 4).astype(np.float32), tir_map.reshape(H, W)
    bgs = march.surface_buffer(np.ones_like(bg_height), bg_height)
    bg_rgb = np.asarray(background, np.float32).reshape(-1, background.shape[-1])[:, :3].astype(np.float64)
    vv = view.reshape(-1, 3)[idx]
    nn = n.reshape(-1, 3)[idx]
    ci = cos_i.ravel()[idx]
    u, v = camera.pixel_grid()
    p0 = np.stack([u.ravel()[idx], v.ravel()[idx], np.asarray(glass_height, np.float32).ravel()[idx]], -1)
    d, tir = refract(vv, nn, eta)
    F = np.where(tir, 1.0, fresnel_dielectric(ci, eta) if fresnel else 0.0)
    col = np.zeros((idx.size, 3))
    t = ~tir & (F < 1.0)
    T = 1.0 - F
    q0 = p0.copy()
    if back_surface == "local_sphere":
        Rr = local_radius(geo, a).astype(np.float64).ravel()[idx]
        P = geo["position"].astype(np.float64).reshape(-1, 3)[idx]
        sph = t & (Rr > 0)
        C = P - Rr[:, None] * nn
        cos_t = -np.sum(d * nn, -1)
        Q = P + (2.0 * Rr * cos_t)[:, None] * d
        with np.errstate(divide="ignore", invalid="ignore"):
            n2 = (Q - C) / np.where(Rr > 0, Rr, 1.0)[:, None]
        c2 = np.clip(np.sum(d * n2, -1), 0.0, 1.0)
        k2 = 1.0 - eta * eta * (1.0 - c2 * c2)
        out_ok = sph & (k2 >= 0)
        d2 = eta * d + (eta * c2 - np.sqrt(np.maximum(k2, 0.0)))[:, None] * (-n2)
        d2 /= np.linalg.norm(d2, axis=-1, keepdims=True)
        d = np.where(out_ok[:, None], d2, d)
        if fresnel:
            T = np.where(out_ok, T * (1.0 - fresnel_dielectric(c2, 1.0 / eta)), T)
        qq, D = camera.project(Q)
        qq[:, 0] = np.clip(qq[:, 0], 0.0, W - 1e-3)
        qq[:, 1] = np.clip(qq[:, 1], 0.0, H - 1e-3)
        q0 = np.where((sph & (D > 1e-6))[:, None], qq, p0)
    col[t] += T[t, None] * np.asarray(tint) * _background_along(camera, q0[t], d[t], bgs, bg_rgb)
    r = F > 0
    wr = vv + 2.0 * ci[:, None] * nn
    col[r] += F[r, None] * _background_along(camera, p0[r], wr[r], bgs, bg_rgb)
    out[idx, :3] = a.ravel()[idx, None] * col
    out[idx, 3] = a.ravel()[idx]
    tir_map[idx] = tir
    return out.reshape(H, W, 4).astype(np.float32), tir_map.reshape(H, W)


def _background_along(camera, p0, d, bgs, bg_rgb):
    """Mirror of rt_background_along for many rays: background colour (N, 3)."""
    H, W = bgs.shape
    if len(p0) == 0:
        return np.zeros((0, 3))
    e, s_max = uvh_direction(camera, p0, d)
    e32 = e.astype(np.float32)
    p32 = np.asarray(p0, np.float32)
    origin = np.floor(p32[:, 1]).astype(np.int64) * W + np.floor(p32[:, 0]).astype(np.int64)
    major = np.maximum(np.abs(e32[:, 0]), np.abs(e32[:, 1]))
    good = major >= march.MIN_IMAGE_LENGTH
    with np.errstate(divide="ignore", invalid="ignore"):
        h_edge = np.where(good, p32[:, 2] + F32(0.5) * e32[:, 2] / np.where(good, major, 1),
                          np.where(e32[:, 2] < 0, -SOLID, p32[:, 2])).astype(np.float32)
    at_origin = march.side(h_edge, bgs.ravel()[origin]) == 1
    m, ok = setup_rays(p32, e32, s_max, W, H)
    ok &= ~at_origin
    hit, last = trace_closest(bgs, m, ok, SOLID)
    pix = np.where(at_origin, origin, np.where(hit >= 0, hit, np.where(last >= 0, last, origin)))
    return bg_rgb[pix]


def refraction_cl(device, camera: Camera, glass, glass_height, background, bg_height, *, eta=1.5,
                  tint=(1.0, 1.0, 1.0), fresnel=True, hiz=True, back_surface="none", band_rows=None,
                  progress=None, check_cancelled=None):
    """Refraction layer of a transparent cutout on the device. ``back_surface``:
    ``"none"`` (front interface only) or ``"local_sphere"`` (refract out again at the
    back of the local sphere: a solid ball or bottle).

    All images share the camera's size (ValueError otherwise). With ``progress``
    or ``check_cancelled`` the kernel runs in bands of ``band_rows`` rows (default:
    about 2^18 pixels a band), calling them between bands; the result is the same.

    Returns a dict: ``layer`` float32 (H, W, 4) premultiplied, ``tir`` bool (H, W)
    (total internal reflection at the front surface), ``hit`` bool (H, W) (the
    transmitted or TIR ray found the background inside the image), ``steps``."""
    import pyopencl as cl
    ctx, queue = device.context, device.queue
    glass = np.asarray(glass, np.float32)
    bg = np.asarray(background, np.float32)
    glass_height = np.asarray(glass_height, np.float32)
    bg_height = np.asarray(bg_height, np.float32)
    check_shapes(camera, glass=glass, glass_height=glass_height, background=bg, bg_height=bg_height)
    H, W = bg_height.shape
    if bg.ndim == 2:
        bg = bg[..., None]
    rgb = np.zeros((H, W, 4), np.float32)
    rgb[..., :3] = bg[..., :3] if bg.shape[-1] >= 3 else bg[..., :1]
    geo = reconstruct(camera, glass_height)
    bgs = march.surface_buffer(np.ones_like(bg_height), bg_height)
    S = _Surface(cl, ctx, bgs, float(SOLID), hiz)
    prg = _program(device)
    mf = cl.mem_flags
    d_out = cl.Buffer(ctx, mf.WRITE_ONLY, H * W * 16)
    d_flags = cl.Buffer(ctx, mf.WRITE_ONLY, H * W * 4)
    d_steps = cl.Buffer(ctx, mf.WRITE_ONLY, H * W * 4)
    if back_surface not in ("none", "local_sphere"):
        raise ValueError(f"back_surface must be 'none' or 'local_sphere', got {back_surface!r}")
    radius = (local_radius(geo, glass[..., 3]) if back_surface == "local_sphere"
              else np.zeros((H, W), np.float32))
    kern = prg.rt_refract
    # held until the last launch: a kernel's arguments do not keep buffers alive
    args = [np.int32(W), np.int32(H), np.float32(camera.focal),
            np.float32(camera.horizon), np.float32(camera.cam_height), _buf(cl, ctx, glass[..., 3]),
            _buf(cl, ctx, glass_height), _buf(cl, ctx, geo["normal"]),
            _buf(cl, ctx, geo["valid"]), _buf(cl, ctx, geo["position"]), _buf(cl, ctx, radius),
            S.d_surf, S.d_pyr, S.d_lvl, np.int32(S.nlev),
            _buf(cl, ctx, rgb), np.float32(eta), np.asarray(tuple(tint) + (0.0,), np.float32),
            np.int32(bool(fresnel)), d_out, d_flags, d_steps]
    kern.set_args(*args)
    banded = progress is not None or check_cancelled is not None
    rows = H if not banded else max(1, min(H, int(band_rows or (1 << 18) // W)))
    for y0 in range(0, H, rows):
        n = min(rows, H - y0)
        if check_cancelled is not None:
            check_cancelled()
        ev = cl.enqueue_nd_range_kernel(queue, kern, (W, n), None, global_work_offset=(0, y0) if y0 else None)
        if banded:
            ev.wait()
            if progress is not None:
                progress((y0 + n) / H, "refraction")
    out, flags, steps = _read(cl, queue, (d_out, (H, W, 4), np.float32), (d_flags, (H, W), np.int32),
                              (d_steps, (H, W), np.int32))
    return {"layer": out, "tir": (flags & 4) != 0, "hit": (flags & 1) != 0, "steps": steps}
