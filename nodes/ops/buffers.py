"""SSN++ buffer channels (PixHt-Lab, CVPR 2023, Sec. 3.2 and Fig. 5; design.md §3).

The 3D-aware inputs of the neural soft-shadow renderer, all float32 (H, W):

* ``cutout_height``: the cutout's pixel height inside the mask (mask > 0.5), 0
  outside (pixels).
* ``bg_gradient_x``, ``bg_gradient_y``: d(bg_height)/du and d(bg_height)/dv
  (pixels per pixel): central differences, one-sided at the image border and
  next to non-finite heights, 0 where the height itself is non-finite.
* ``hard_shadow``: the hard shadow of the disk light's centre, as **darkness**:
  1 = shadow, 0 = lit (SSN++ consumes darkness; ``1 - shadow.hard_shadow(...)``).
* ``sparse_hard_shadow_0`` .. ``_3``: darkness of the hard shadows of the disk's
  four extreme points (the outer boundary of the penumbra), same launch.
* ``relative_distance``: for receivers shadowed by the centre, the distance in
  (u, v, h) pixel units between the receiver (its pixel centre and its height)
  and the occluder point that blocks it (the cutout surface point (u, v,
  fg_height) at the first blocking sample of the march from the receiver); 0
  where lit. Longer distance = softer shadow.

Light points are ``(u, v, h, s)`` as in :mod:`shadow`. Receivers, thickness,
several cutouts and non-finite inputs behave as in :mod:`shadow`.
"""
from __future__ import annotations

import numpy as np

from . import shadow as S

#: Channel order of the stacked buffer (the kernel writes planes in this order).
CHANNELS: tuple[str, ...] = (
    "cutout_height",
    "bg_gradient_x",
    "bg_gradient_y",
    "hard_shadow",
    "sparse_hard_shadow_0",
    "sparse_hard_shadow_1",
    "sparse_hard_shadow_2",
    "sparse_hard_shadow_3",
    "relative_distance",
)


def _lights(light_center, light_extremes) -> np.ndarray:
    c = S.light_array(light_center)
    e = np.asarray(light_extremes, dtype=np.float64)
    if e.shape != (4, 4):
        raise ValueError(f"light_extremes must be (4, 4) rows (u, v, h, s), got {e.shape}")
    return np.concatenate([c[None], S.light_samples_array(e)], axis=0)


def stack(channels: dict) -> np.ndarray:
    """The channels as one float32 (C, H, W) array in CHANNELS order."""
    return np.stack([channels[k] for k in CHANNELS], axis=0).astype(np.float32)


def bg_gradient_ref(bg: np.ndarray):
    """(d bg/du, d bg/dv) of a background height buffer that holds NO_SURFACE
    where non-finite: central differences, one-sided where a neighbour is
    missing, 0 where the pixel itself is missing. float32 (H, W) each."""
    ok = bg > S.M.NO_SURFACE_TEST
    b = np.where(ok, bg, 0.0).astype(np.float64)

    def along(axis):
        n = b.shape[axis]
        fwd_ok = np.zeros_like(ok)
        bwd_ok = np.zeros_like(ok)
        fwd = np.zeros_like(b)
        bwd = np.zeros_like(b)
        sl = lambda a, c: tuple(slice(a, c) if i == axis else slice(None) for i in range(2))
        if n > 1:
            fwd_ok[sl(0, n - 1)] = ok[sl(1, n)]
            fwd[sl(0, n - 1)] = b[sl(1, n)]
            bwd_ok[sl(1, n)] = ok[sl(0, n - 1)]
            bwd[sl(1, n)] = b[sl(0, n - 1)]
        g = np.where(fwd_ok & bwd_ok, 0.5 * (fwd - bwd),
                     np.where(fwd_ok, fwd - b, np.where(bwd_ok, b - bwd, 0.0)))
        return np.where(ok, g, 0.0).astype(np.float32)

    return along(1), along(0)


def buffer_channels_ref(mask, fg_height, bg_height, light_center, light_extremes,
                        thickness=1.0) -> dict[str, np.ndarray]:
    """Numpy reference of :func:`buffer_channels` (same keys and conventions)."""
    prep = S.Prepared(mask, fg_height, bg_height, thickness)
    lights = _lights(light_center, light_extremes)
    H, W = prep.H, prep.W
    out = {}
    out["cutout_height"] = np.where(prep.surf > S.M.NO_SURFACE_TEST, prep.surf, 0.0).astype(np.float32)
    gx, gy = bg_gradient_ref(prep.bg)
    out["bg_gradient_x"], out["bg_gradient_y"] = gx, gy
    blocked, hu, hv, hs = S.trace_ref(prep, lights[0])
    out["hard_shadow"] = blocked.astype(np.float32)
    for e in range(4):
        out[f"sparse_hard_shadow_{e}"] = S.trace_ref(prep, lights[1 + e])[0].astype(np.float32)
    i, j = np.mgrid[0:H, 0:W]
    ru, rv = j + 0.5, i + 0.5
    with np.errstate(invalid="ignore"):
        dist = np.sqrt((hu - ru) ** 2 + (hv - rv) ** 2 + (hs - prep.recv) ** 2)
    out["relative_distance"] = np.where(blocked, dist, 0.0).astype(np.float32)
    return out


def buffer_channels(device, mask, fg_height, bg_height, light_center, light_extremes,
                    thickness=1.0, *, progress=None, check_cancelled=None) -> dict[str, np.ndarray]:
    """The SSN++ buffer channels (see the module docstring), in one kernel launch.

    mask (H, W) cutout where > 0.5; fg_height, bg_height (H, W) pixel heights
    (pixels); light_center (4,) the disk light's centre (u, v, h, s);
    light_extremes (4, 4) its four extreme points; thickness (pixels).
    Returns a dict of float32 (H, W) arrays keyed by CHANNELS. progress,
    check_cancelled: called between bands of rows (``shadow.soft_shadow``).
    """
    scene = S.ShadowScene(device, mask, fg_height, bg_height, thickness)
    return channels_on(scene, light_center, light_extremes, progress, check_cancelled)


def launch_channels(scene: "S.ShadowScene", lights_buf, progress=None, check_cancelled=None):
    """Enqueue the buffer-channels kernel on a prepared scene; returns (event, buffer)
    with the (C, H, W) planes in CHANNELS order (banded with callbacks)."""
    p = scene.prep
    out = scene.out_buffer("channels", len(CHANNELS) * p.H * p.W * 4)
    # five hard shadows per pixel (the centre and the four extremes)
    ev = scene.launch_banded("buffer_channels", scene.recv, scene.bg_buffer(), lights_buf, out, cost=5,
                             progress=progress, check_cancelled=check_cancelled)
    return ev, out


def channels_on(scene: "S.ShadowScene", light_center, light_extremes, progress=None,
                check_cancelled=None) -> dict[str, np.ndarray]:
    """:func:`buffer_channels` on an already uploaded :class:`shadow.ShadowScene`."""
    lights = _lights(light_center, light_extremes)
    ev, out = launch_channels(scene, scene.samples_buffer(lights), progress, check_cancelled)
    scene.last_event = ev
    host = scene._read(out, (len(CHANNELS), scene.prep.H, scene.prep.W), ev)
    return {name: host[c] for c, name in enumerate(CHANNELS)}
