"""Refraction through a transparent cutout, traced in pixel-height space: the numpy
references (``refraction_numpy``, ``refraction_hits_numpy``) next to the OpenCL
wrappers (``refraction_cl``, ``refraction_hits_cl``; kernels ``rt_refract`` and
``rt_refract_hits`` in ``reflection.cl``), and the proxy resolution of large images
(``refraction_proxy``: rays traced at a proxy, colours looked up at full size).
Model and units: ``reflection.py``.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from . import march
from .camera import Camera, reconstruct
from .reflection import SOLID, _buf, _program, _read, _Surface, check_shapes, setup_rays, trace_closest
from .reflection_math import F32, fresnel_dielectric, refract, uvh_direction, view_directions
from .resample import Window, nonzero_box, shrink_part
from .upsample import AUTO_MAX_SIDE, masked_resize, proxy_bg_height


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


def _rays(camera: Camera, glass, glass_height, eta, fresnel, back_surface):
    """The rays of every glass pixel, as ``rt_refract_rays``: a dict with ``idx`` (flat
    pixel indices), ``p0`` (N, 3) front point (u, v, h), ``q0``/``d`` the transmitted
    ray's origin and direction, ``T`` its weight (0: none), ``wr`` the front-surface
    reflection and ``F`` its weight, ``tir`` (N,) bool."""
    H, W = glass_height.shape
    a = np.asarray(glass, np.float32)[..., 3]
    geo = reconstruct(camera, glass_height)
    view = view_directions(camera)
    n = geo["normal"].astype(np.float64)
    cos_i = -np.sum(view * n, -1)
    n = np.where((cos_i < 0)[..., None], -n, n)
    cos_i = np.abs(cos_i)
    idx = np.flatnonzero(((a > 0) & (geo["valid"] > 0.5)).ravel())
    vv = view.reshape(-1, 3)[idx]
    nn = n.reshape(-1, 3)[idx]
    ci = cos_i.ravel()[idx]
    u, v = camera.pixel_grid()
    p0 = np.stack([u.ravel()[idx], v.ravel()[idx], np.asarray(glass_height, np.float32).ravel()[idx]], -1)
    d, tir = refract(vv, nn, eta)
    F = np.where(tir, 1.0, fresnel_dielectric(ci, eta) if fresnel else 0.0)
    t = ~tir & (F < 1.0)
    T = np.where(t, 1.0 - F, 0.0)
    q0 = p0.copy()
    if back_surface == "local_sphere" and idx.size:
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
    wr = vv + 2.0 * ci[:, None] * nn
    return {"idx": idx, "p0": p0, "q0": q0, "d": d, "T": T, "wr": wr, "F": F, "tir": tir, "alpha": a}


def refraction_numpy(camera: Camera, glass: np.ndarray, glass_height: np.ndarray,
                     background: np.ndarray, bg_height: np.ndarray, *, eta=1.5,
                     tint=(1.0, 1.0, 1.0), fresnel=True, back_surface="none"):
    """Reference of ``rt_refract``. Returns ``(layer, tir)``: float32 (H, W, 4)
    premultiplied refraction layer and bool (H, W) where total internal reflection
    happened at the front surface. ``back_surface="local_sphere"`` refracts again
    at the back of the local sphere (see :func:`local_radius`)."""
    H, W = bg_height.shape
    r = _rays(camera, glass, glass_height, eta, fresnel, back_surface)
    idx, a = r["idx"], r["alpha"]
    out = np.zeros((H * W, 4))
    tir_map = np.zeros(H * W, bool)
    if idx.size == 0:
        return out.reshape(H, W, 4).astype(np.float32), tir_map.reshape(H, W)
    bgs = march.surface_buffer(np.ones_like(bg_height), bg_height)
    bg_rgb = np.asarray(background, np.float32).reshape(-1, background.shape[-1])[:, :3].astype(np.float64)
    col = np.zeros((idx.size, 3))
    t, rf = r["T"] > 0, r["F"] > 0
    col[t] += r["T"][t, None] * np.asarray(tint) * bg_rgb[_background_pix(camera, r["q0"][t], r["d"][t], bgs)]
    col[rf] += r["F"][rf, None] * bg_rgb[_background_pix(camera, r["p0"][rf], r["wr"][rf], bgs)]
    out[idx, :3] = a.ravel()[idx, None] * col
    out[idx, 3] = a.ravel()[idx]
    tir_map[idx] = r["tir"]
    return out.reshape(H, W, 4).astype(np.float32), tir_map.reshape(H, W)


def refraction_hits_numpy(camera: Camera, glass: np.ndarray, glass_height: np.ndarray, bg_height: np.ndarray,
                          *, eta=1.5, fresnel=True, back_surface="none"):
    """Reference of ``rt_refract_hits``: where each glass pixel's rays meet the
    background. Returns ``(pos, wts)``: float32 (H, W, 4) ``(u_T, v_T, u_R, v_R)``
    [px, continuous; the pixel's own centre where there is no such ray] and
    float32 (H, W, 2) ``(T, F)`` the rays' weights (0 off the glass)."""
    H, W = bg_height.shape
    u, v = camera.pixel_grid()
    pos = np.stack([u, v, u, v], -1).astype(np.float64).reshape(-1, 4)
    wts = np.zeros((H * W, 2))
    r = _rays(camera, glass, glass_height, eta, fresnel, back_surface)
    idx = r["idx"]
    if idx.size:
        bgs = march.surface_buffer(np.ones_like(bg_height), bg_height)
        t, rf = r["T"] > 0, r["F"] > 0
        pos[idx[t], :2] = _background_pos(camera, r["q0"][t], r["d"][t], bgs)[0]
        pos[idx[rf], 2:] = _background_pos(camera, r["p0"][rf], r["wr"][rf], bgs)[0]
        wts[idx, 0], wts[idx, 1] = r["T"], r["F"]
    return pos.reshape(H, W, 4).astype(np.float32), wts.reshape(H, W, 2).astype(np.float32)


def _background_pos(camera, p0, d, bgs):
    """Mirror of ``rt_background_pos`` for many rays: ``(pos, pix)``, the continuous
    image position (N, 2) [px] where each ray meets the background and the pixel
    whose colour ``rt_background_along`` takes (N,)."""
    H, W = bgs.shape
    if len(p0) == 0:
        return np.zeros((0, 2)), np.zeros(0, np.int64)
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
    hit, last, k = trace_closest(bgs, m, ok, SOLID, with_k=True)
    pix = np.where(at_origin, origin, np.where(hit >= 0, hit, np.where(last >= 0, last, origin)))
    kk = np.maximum(k, 0)
    q = np.stack([m.sample_u(kk), m.sample_v(kk)], -1).astype(np.float64)
    # at a hit: the crossing between the last sample in front and the first behind
    kp = np.maximum(kk - 1, 0)
    qp = np.stack([m.sample_u(kp), m.sample_v(kp)], -1).astype(np.float64)
    d1 = m.ray_height(kk) - march.surface_height(bgs, q[:, 0].astype(np.float32), q[:, 1].astype(np.float32),
                                                 m.major_u)
    d0 = m.ray_height(kp) - march.surface_height(bgs, qp[:, 0].astype(np.float32), qp[:, 1].astype(np.float32),
                                                 m.major_u)
    interp = (hit >= 0) & (kk > m.k_lo) & (d0 > 0) & (d1 < d0)
    with np.errstate(divide="ignore", invalid="ignore"):
        tq = np.where(interp, d0 / np.where(interp, d0 - d1, 1.0), 1.0)
    q = np.where(interp[:, None], qp + tq[:, None] * (q - qp), q)
    edge = (hit < 0) & (k >= 0)
    q[:, 0] = np.where(edge, np.clip(q[:, 0], 0.0, W - 1e-3), q[:, 0])
    q[:, 1] = np.where(edge, np.clip(q[:, 1], 0.0, H - 1e-3), q[:, 1])
    pos = np.where((at_origin | (k < 0))[:, None], p32[:, :2].astype(np.float64), q)
    return pos, pix


def _background_pix(camera, p0, d, bgs):
    """Mirror of rt_background_along for many rays: the pixel whose colour it takes (N,)."""
    return _background_pos(camera, p0, d, bgs)[1]


def _inputs(camera, glass, glass_height, bg_height, background=None):
    """The tracers' arrays as float32, checked to share the camera's size (ValueError
    naming them otherwise): (glass, glass_height, bg_height, background or None)."""
    arrays = dict(glass=glass, glass_height=glass_height, background=background, bg_height=bg_height)
    arrays = {k: np.asarray(v, np.float32) for k, v in arrays.items() if v is not None}
    check_shapes(camera, **arrays)
    return arrays["glass"], arrays["glass_height"], arrays["bg_height"], arrays.get("background")


def _setup(device, camera, glass, glass_height, bg_height, back_surface, hiz, normal=None, radius=None):
    """Uploads shared by rt_refract and rt_refract_hits: ``(prg, head, keep)`` with
    ``head`` the kernels' common leading arguments (through ``nlev``) and ``keep``
    what must stay alive until the last launch. ``normal`` (H, W, 3) and
    ``radius`` (H, W) replace those reconstructed from ``glass_height`` (the
    proxy passes the full-resolution ones, shrunk)."""
    import pyopencl as cl
    ctx = device.context
    H, W = bg_height.shape
    if back_surface not in ("none", "local_sphere"):
        raise ValueError(f"back_surface must be 'none' or 'local_sphere', got {back_surface!r}")
    geo = reconstruct(camera, glass_height)
    if normal is not None:
        geo["normal"] = np.ascontiguousarray(normal, np.float32)
    bgs = march.surface_buffer(np.ones_like(bg_height), bg_height)
    S = _Surface(cl, ctx, bgs, float(SOLID), hiz)
    if back_surface != "local_sphere":
        radius = np.zeros((H, W), np.float32)
    elif radius is None:
        radius = local_radius(geo, glass[..., 3])
    head = [np.int32(W), np.int32(H), np.float32(camera.focal),
            np.float32(camera.horizon), np.float32(camera.cam_height), _buf(cl, ctx, glass[..., 3]),
            _buf(cl, ctx, glass_height), _buf(cl, ctx, geo["normal"]),
            _buf(cl, ctx, geo["valid"]), _buf(cl, ctx, geo["position"]), _buf(cl, ctx, radius),
            S.d_surf, S.d_pyr, S.d_lvl, np.int32(S.nlev)]
    return _program(device), head, S


def _launch(device, kern, H, W, band_rows, progress, check_cancelled):
    """Run ``kern`` (arguments set) over (W, H), in bands of rows when progress or
    cancellation is asked for."""
    import pyopencl as cl
    queue = device.queue
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
    glass, glass_height, bg_height, bg = _inputs(camera, glass, glass_height, bg_height, background)
    H, W = bg_height.shape
    if bg.ndim == 2:
        bg = bg[..., None]
    rgb = np.zeros((H, W, 4), np.float32)
    rgb[..., :3] = bg[..., :3] if bg.shape[-1] >= 3 else bg[..., :1]
    prg, head, keep = _setup(device, camera, glass, glass_height, bg_height, back_surface, hiz)
    mf = cl.mem_flags
    d_out = cl.Buffer(ctx, mf.WRITE_ONLY, H * W * 16)
    d_flags = cl.Buffer(ctx, mf.WRITE_ONLY, H * W * 4)
    d_steps = cl.Buffer(ctx, mf.WRITE_ONLY, H * W * 4)
    kern = prg.rt_refract
    # held until the last launch: a kernel's arguments do not keep buffers alive
    args = head + [_buf(cl, ctx, rgb), np.float32(eta), np.asarray(tuple(tint) + (0.0,), np.float32),
                   np.int32(bool(fresnel)), d_out, d_flags, d_steps]
    kern.set_args(*args)
    _launch(device, kern, H, W, band_rows, progress, check_cancelled)
    out, flags, steps = _read(cl, queue, (d_out, (H, W, 4), np.float32), (d_flags, (H, W), np.int32),
                              (d_steps, (H, W), np.int32))
    del keep
    return {"layer": out, "tir": (flags & 4) != 0, "hit": (flags & 1) != 0, "steps": steps}


def refraction_hits_cl(device, camera: Camera, glass, glass_height, bg_height, *, eta=1.5, fresnel=True,
                       hiz=True, back_surface="none", band_rows=None, progress=None, check_cancelled=None,
                       normal=None, radius=None):
    """``rt_refract_hits`` on the device (numpy reference :func:`refraction_hits_numpy`):
    a dict with ``pos`` float32 (H, W, 4) ``(u_T, v_T, u_R, v_R)`` [px] where the
    transmitted and the reflected ray meet the background (the pixel's centre
    where there is no such ray), ``wts`` float32 (H, W, 2) their weights ``(T, F)``,
    ``tir``, ``hit`` and ``steps`` as :func:`refraction_cl`'s. ``normal`` (H, W, 3),
    ``radius`` (H, W): the glass's normals and local radius [world units] to use
    instead of those reconstructed from ``glass_height``."""
    import pyopencl as cl
    ctx, queue = device.context, device.queue
    glass, glass_height, bg_height, _ = _inputs(camera, glass, glass_height, bg_height)
    H, W = bg_height.shape
    prg, head, keep = _setup(device, camera, glass, glass_height, bg_height, back_surface, hiz, normal, radius)
    mf = cl.mem_flags
    d_pos = cl.Buffer(ctx, mf.WRITE_ONLY, H * W * 16)
    d_wts = cl.Buffer(ctx, mf.WRITE_ONLY, H * W * 16)
    d_flags = cl.Buffer(ctx, mf.WRITE_ONLY, H * W * 4)
    d_steps = cl.Buffer(ctx, mf.WRITE_ONLY, H * W * 4)
    kern = prg.rt_refract_hits
    kern.set_args(*(head + [np.float32(eta), np.int32(bool(fresnel)), d_pos, d_wts, d_flags, d_steps]))
    _launch(device, kern, H, W, band_rows, progress, check_cancelled)
    pos, wts, flags, steps = _read(cl, queue, (d_pos, (H, W, 4), np.float32), (d_wts, (H, W, 4), np.float32),
                                   (d_flags, (H, W), np.int32), (d_steps, (H, W), np.int32))
    del keep
    return {"pos": pos, "wts": wts[..., :2], "tir": (flags & 4) != 0, "hit": (flags & 1) != 0, "steps": steps}


def refraction_proxy(device, camera: Camera, glass, glass_height, background, bg_height, *,
                     max_side: int = AUTO_MAX_SIDE, eta=1.5, tint=(1.0, 1.0, 1.0), fresnel=True, hiz=True,
                     back_surface="none", progress=None, check_cancelled=None) -> dict:
    """:func:`refraction_cl` of a large image with the rays traced at a proxy whose
    longer side is ``max_side`` px (at or below it: ``refraction_cl`` itself).

    What the glass shows is the background, as sharp as the photo; where each
    pixel's rays land is smooth. So the proxy traces *where* they meet the
    background (``rt_refract_hits``), the displacement of each hit from the
    pixel's own centre and the rays' weights are enlarged edge-aware against
    the full-resolution coverage (``upsample.masked_resize``: rim pixels take
    only the glass's own proxy pixels), and the colours are looked up in the
    full-resolution background there (bilinear). With ``eta = 1`` nothing moves
    and the result is the background exactly, at any proxy size.

    The proxy is the same 3D scene (camera field of view kept, pixel heights in
    proxy rows); its coverage is the area-averaged alpha, the glass's height the
    mean over glass pixels. Returns :func:`refraction_cl`'s dict at full size
    (``tir``, ``hit`` and ``steps`` of the nearest proxy pixel) plus ``proxy``."""
    glass, glass_height, bg_height, bg = _inputs(camera, glass, glass_height, bg_height, background)
    H, W = bg_height.shape
    if max_side < 16:
        raise ValueError(f"a proxy needs a longer side of at least 16 px, got {max_side}")
    win = Window.whole(H, W, max_side)
    kw = dict(eta=eta, fresnel=fresnel, hiz=hiz, back_surface=back_surface, progress=progress,
              check_cancelled=check_cancelled)
    if (win.out_h, win.out_w) == (H, W):
        return dict(refraction_cl(device, camera, glass, glass_height, bg, bg_height, tint=tint, **kw),
                    proxy=(H, W))
    h, w = win.out_h, win.out_w
    a = glass[..., 3]
    layer = np.zeros((H, W, 4), np.float32)
    tir = np.zeros((H, W), bool)
    hit = np.zeros((H, W), bool)
    steps = np.zeros((H, W), np.int32)
    on = a > 0
    box = nonzero_box(on)
    if box is None:
        return {"layer": layer, "tir": tir, "hit": hit, "steps": steps, "proxy": (h, w)}
    r0, r1, c0, c1 = box
    # the proxy scene: coverage area-averaged, the glass's height averaged over glass pixels
    ins = on[r0:r1, c0:c1]
    part = np.stack([a[r0:r1, c0:c1], ins.astype(np.float32),
                     np.where(ins, np.nan_to_num(glass_height[r0:r1, c0:c1]), 0.0).astype(np.float32)], 2)
    n_full, R_full = _box_geometry(camera, glass_height, a, (r0, r1, c0, c1), back_surface == "local_sphere")
    part = np.concatenate([part, n_full * ins[..., None], (R_full * (R_full > 0))[..., None],
                           (ins & (R_full > 0)).astype(np.float32)[..., None]], axis=2)
    shrunk = np.moveaxis(shrink_part(part, (r0, c0), (H, W), (h, w)), 2, 0)
    cov, cover, hsum = shrunk[:3]
    # the full-resolution normals and local radius, averaged over each proxy pixel's glass
    n_lo = np.moveaxis(shrunk[3:6], 0, 2)
    n_len = np.linalg.norm(n_lo, axis=2, keepdims=True)
    n_lo = np.where(n_len > 1e-6, n_lo / np.maximum(n_len, 1e-6), 0.0).astype(np.float32)
    R_lo = np.where(shrunk[7] > 1e-6, shrunk[6] / np.maximum(shrunk[7], 1e-6), 0.0).astype(np.float32)
    g_lo = np.zeros((h, w, 4), np.float32)
    g_lo[..., 3] = np.where(cover > 1e-6, cov, 0.0)
    gh_lo = (np.where(cover > 1e-6, hsum / np.maximum(cover, 1e-6), 0.0) * win.ky).astype(np.float32)
    bg_lo = proxy_bg_height(win, bg_height)
    cam = dataclasses.replace(camera, width=w, height=h, horizon=camera.horizon * win.ky)
    r = refraction_hits_cl(device, cam, g_lo, gh_lo, bg_lo, normal=n_lo, radius=R_lo, **kw)
    # displacement of each hit from the pixel's own centre, in full-resolution pixels
    u, v = np.meshgrid(np.arange(w, dtype=np.float32) + 0.5, np.arange(h, dtype=np.float32) + 0.5)
    kx, ky = W / w, H / h
    planes = [(r["pos"][..., 0] - u) * kx, (r["pos"][..., 1] - v) * ky, r["wts"][..., 0]]
    if fresnel or eta < 1.0:
        planes += [(r["pos"][..., 2] - u) * kx, (r["pos"][..., 3] - v) * ky, r["wts"][..., 1]]
    planes.append(r["tir"].astype(np.float32))
    side_lo = (g_lo[..., 3] > 0.5).astype(np.float32)
    box = (r0, r1, c0, c1)
    big = [masked_resize(p, side_lo, a, (H, W), box=box) for p in planes]
    # glass whose foot lies below the horizon (reconstruct's validity; elsewhere 0, as refraction_cl)
    gh_box = glass_height[r0:r1, c0:c1].astype(np.float64)
    v_mid = np.arange(r0, r1, dtype=np.float64)[:, None] + 0.5
    sel = ins & np.isfinite(gh_box) & (v_mid + gh_box - camera.horizon > 1e-9)
    yy, xx = np.nonzero(sel)
    uc, vc = xx + c0 + 0.5, yy + r0 + 0.5
    alpha = ins * a[r0:r1, c0:c1]
    col = np.zeros((yy.size, 3), np.float32)
    col += big[2][sel][:, None] * np.asarray(tint, np.float32) * _bilinear(
        bg, uc + big[0][sel], vc + big[1][sel])
    if len(planes) == 7:
        col += big[5][sel][:, None] * _bilinear(bg, uc + big[3][sel], vc + big[4][sel])
    sub = layer[r0:r1, c0:c1]
    sub[sel, :3] = alpha[sel, None] * col
    sub[sel, 3] = alpha[sel]
    tir[r0:r1, c0:c1] = (big[-1] > 0.5) & sel
    iy = np.minimum((np.arange(r0, r1) * h) // H, h - 1)
    ix = np.minimum((np.arange(c0, c1) * w) // W, w - 1)
    hit[r0:r1, c0:c1] = r["hit"][:, ix][iy] & sel
    steps[r0:r1, c0:c1] = np.where(sel, r["steps"][:, ix][iy], 0)
    return {"layer": layer, "tir": tir, "hit": hit, "steps": steps, "proxy": (h, w)}


def _box_geometry(camera: Camera, glass_height, alpha, box, radius: bool):
    """Normals (h, w, 3) and local radius (h, w) [world units; 0 without ``radius``]
    of the glass over ``box`` = (r0, r1, c0, c1) at full resolution: the numbers of
    ``reconstruct`` and :func:`local_radius` on the whole image, computed on the box
    and a margin of 3 pixels (what their differences and erosions read)."""
    from .camera import surface_normals
    H, W = glass_height.shape
    r0, r1, c0, c1 = box
    R0, R1, C0, C1 = max(0, r0 - 3), min(H, r1 + 3), max(0, c0 - 3), min(W, c1 + 3)
    hh = np.asarray(glass_height[R0:R1, C0:C1], np.float64)
    u, v = np.meshgrid(np.arange(C0, C1, dtype=np.float64) + 0.5, np.arange(R0, R1, dtype=np.float64) + 0.5)
    P, valid = camera.back_project(u, v, hh)
    valid &= np.isfinite(hh)
    n = surface_normals(P, valid)
    geo = {"position": np.where(valid[..., None], P, 0.0), "normal": n, "valid": valid.astype(np.float32)}
    rad = (local_radius(geo, alpha[R0:R1, C0:C1]) if radius
           else np.zeros(hh.shape, np.float32))
    sl = (slice(r0 - R0, r1 - R0), slice(c0 - C0, c1 - C0))
    return n[sl].astype(np.float32), rad[sl].astype(np.float32)


def _bilinear(image: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Colours (N, 3) of ``image`` (H, W, C) at continuous image points (u, v) [px,
    pixel centres at +0.5], bilinear, clamped at the border (one channel: grey)."""
    H, W = image.shape[:2]
    img = image if image.ndim == 3 else image[..., None]
    x = np.clip(np.asarray(u, np.float64) - 0.5, 0.0, W - 1.0)
    y = np.clip(np.asarray(v, np.float64) - 0.5, 0.0, H - 1.0)
    x0 = np.minimum(np.floor(x).astype(np.int64), W - 2) if W > 1 else np.zeros(x.shape, np.int64)
    y0 = np.minimum(np.floor(y).astype(np.int64), H - 2) if H > 1 else np.zeros(y.shape, np.int64)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    x1, y1 = np.minimum(x0 + 1, W - 1), np.minimum(y0 + 1, H - 1)
    nc = 3 if img.shape[2] >= 3 else 1
    c = [img[yy, xx, :nc].astype(np.float64) for yy, xx in ((y0, x0), (y0, x1), (y1, x0), (y1, x1))]
    out = (c[0] * (1 - fx) + c[1] * fx) * (1 - fy) + (c[2] * (1 - fx) + c[3] * fx) * fy
    return (out if nc == 3 else np.repeat(out, 3, axis=1)).astype(np.float32)
