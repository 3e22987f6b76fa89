"""SSN++ on any image: a crop around the cutout and its shadow, at the trained scale.

The network was trained on 256x256 renders whose object is 0.25-0.7 of the
image tall (64-180 px) and whose light softness (radius / distance) is
0.015-0.45 (docs/ground-truth.md). Squeezing a whole photo into 256x256 feeds it
objects of another size and shape (a 1300x893 frame is squashed 1.5x
horizontally) and shows it image corners it never learned to leave alone.
Instead :func:`render`:

1. **locates the shadow**: the union of the cutout and the hard shadows of the
   disk light's centre and its 4 extreme points, traced on a copy of the scene
   whose longer side is ``EXTENT_SIDE`` px (cheap; the soft shadow of the disk
   lies within about this union);
2. **chooses the window** (:func:`choose_window`): scale ``k`` so that the
   cutout is ``OBJECT_PX`` tall as in training (unchanged if it already is),
   the located extent plus a margin of ``PAD`` network px clipped to the image,
   at least ``MIN_SIDE`` network px each way (a multiple of 16, both axes the
   same scale: no squashing), centred on the extent and slid inside the image;
3. **runs the buffer channels and the network on the window** at that scale
   (pixel heights and the light's image points are mapped by the window's
   affine map, ``resample.Window``);
4. **gates the darkness to the shadow's reach**: network output farther than
   about ``REACH_PX`` network px from the union of the 5 hard shadows is faded
   to 0, which removes darkening of empty image regions and part of the grey
   ring the network draws around the cutout where no hard shadow falls;
5. **pastes back** edge-aware (``upsample.masked_resize`` against the
   full-resolution mask: the background's darkness never mixes with the
   network's meaningless values inside the cutout, which made a grey halo),
   with darkness 0 outside the window.

A 256x256 image whose object is 64-180 px tall and whose shadow stays inside
the image runs exactly as before (the window is the image, scale 1).
"""
from __future__ import annotations

import dataclasses

import numpy as np
import torch
import torch.nn.functional as F

from . import ssn
from .buffers import buffer_channels
from .resample import Window, ceil_to
from .shadow import soft_shadow
# the cutout height [network px] kept in the window (the training objects' range) and the
# scale that gives it: torch-free, beside the softness (PreviewShadow reads them too)
from .softness import OBJECT_PX, network_scale  # noqa: F401 (re-exported)
from .upsample import masked_resize

#: light softness (radius / distance) of the training data; outside it the node
#: clamps and logs a warning
SOFTNESS_RANGE = (0.015, 0.45)
#: smallest window side [network px] (the training images' size)
MIN_SIDE = ssn.RESOLUTION
#: largest window side [network px]; a larger extent is shrunk to fit
MAX_SIDE = 1024
#: margin around the shadow's extent [network px]
PAD = 16
#: darkness fades to 0 between REACH_PX / 2 and 3 REACH_PX / 2 network px off
#: the hard shadows' union (4 is the best of 2, 4, 8, 16, 32 on the benchmarks:
#: docs/ssn.md, "Any image size")
REACH_PX = 4
#: longer side [px] of the copy on which the shadow's extent is located
EXTENT_SIDE = 512


@dataclasses.dataclass(frozen=True)
class CropInfo:
    window: Window
    extent: tuple[int, int, int, int]   # (x0, y0, x1, y1) image px, half-open
    softness: float                     # as used (clamped)
    softness_in: float                  # as measured
    object_px: float                    # cutout height in the image [px]

    @property
    def clamped(self) -> bool:
        return self.softness != self.softness_in

    def describe(self) -> str:
        w = self.window
        return (f"SSN++ on a {w.out_w}x{w.out_h} window of image px [{w.x0}:{w.x0 + w.w}, {w.y0}:{w.y0 + w.h}] "
                f"(scale {w.ky:.3g}, cutout {self.object_px * w.ky:.0f} px tall), softness {self.softness:.3g}")


def clamp_softness(s: float) -> float:
    lo, hi = SOFTNESS_RANGE
    return float(min(max(s, lo), hi)) if s > 0 else lo


def _reach_points(light_center, light_extremes) -> np.ndarray:
    return np.vstack([np.asarray(light_center, np.float32)[None], np.asarray(light_extremes, np.float32)])


def shadow_extent(device, mask, fg_height, bg_height, light_center, light_extremes,
                  thickness=1.0) -> tuple[int, int, int, int]:
    """Bounding box (x0, y0, x1, y1) [image px, half-open] of the cutout and the
    hard shadows of the light's centre and extreme points, clipped to the image."""
    mask = np.asarray(mask)
    H, W = mask.shape
    win = Window.whole(H, W, EXTENT_SIDE)
    m, fg, bg = win.scene(mask, fg_height, bg_height)
    lit = soft_shadow(device, m, fg, bg, win.light_points(_reach_points(light_center, light_extremes)),
                      thickness * win.ky)
    ys, xs = np.nonzero((lit < 1.0 - 1e-6) | (m > 0.5))
    if ys.size == 0:
        raise ValueError("the cutout mask is empty")
    # one proxy pixel of margin for the resampling
    x0 = int(np.floor((xs.min() - 1) / win.kx)); x1 = int(np.ceil((xs.max() + 2) / win.kx))
    y0 = int(np.floor((ys.min() - 1) / win.ky)); y1 = int(np.ceil((ys.max() + 2) / win.ky))
    return max(x0, 0), max(y0, 0), min(x1, W), min(y1, H)


def choose_window(H: int, W: int, extent, object_px: float) -> Window:
    """The network's window for an (H, W) image (see the module docstring)."""
    k = network_scale(object_px)
    x0, y0, x1, y1 = extent
    for _ in range(3):
        pad = PAD / k
        ex0, ey0 = max(x0 - pad, 0.0), max(y0 - pad, 0.0)
        ex1, ey1 = min(x1 + pad, float(W)), min(y1 + pad, float(H))
        need = max(ex1 - ex0, ey1 - ey0) * k
        if need <= MAX_SIDE:
            break
        k *= MAX_SIDE / need
    out_w = min(MAX_SIDE, max(MIN_SIDE, ceil_to((ex1 - ex0) * k, 16)))
    out_h = min(MAX_SIDE, max(MIN_SIDE, ceil_to((ey1 - ey0) * k, 16)))
    w, h = max(1, round(out_w / k)), max(1, round(out_h / k))

    def place(lo, hi, size, n):
        start = round((lo + hi) / 2 - size / 2)
        return int(np.clip(start, 0, n - size)) if size <= n else int(np.clip(start, n - size, 0))

    return Window(place(ex0, ex1, w, W), place(ey0, ey1, h, H), w, h, out_w, out_h)


def reach_gate(channels: dict, mask_win: np.ndarray | None = None, reach_px: float = REACH_PX) -> np.ndarray:
    """1 on and near the union of the hard shadows of the light's centre and
    extreme points (buffer channels) on the background (outside ``mask_win``;
    the cutout's self-shadow does not count), fading to 0 between reach_px / 2
    and 3 reach_px / 2 px from it; float32 (h, w)."""
    union = np.zeros(channels["hard_shadow"].shape, bool)
    for name in ("hard_shadow", "sparse_hard_shadow_0", "sparse_hard_shadow_1", "sparse_hard_shadow_2",
                 "sparse_hard_shadow_3"):
        union |= channels[name] > 0.5
    if mask_win is not None:
        union &= ~(np.asarray(mask_win) > 0.5)
    r = max(1, int(round(reach_px)))
    box = r + 1 if r % 2 == 0 else r + 2        # odd, about r wide: the fade
    t = torch.from_numpy(union.astype(np.float32))[None, None]
    # separable square dilation and box blur (a 2D window costs r x more)
    grown = F.max_pool2d(F.max_pool2d(t, (1, 2 * r + 1), 1, (0, r)), (2 * r + 1, 1), 1, (r, 0))
    soft = F.avg_pool2d(grown, (1, box), 1, (0, box // 2), count_include_pad=False)
    soft = F.avg_pool2d(soft, (box, 1), 1, (box // 2, 0), count_include_pad=False)
    return soft[0, 0].numpy()


def render(device, model, mask, fg_height, bg_height, light_center, light_extremes, softness,
           thickness=1.0, gate: bool = True, *, threads=None, torch_device=None, progress=None,
           check_cancelled=None) -> tuple[np.ndarray, CropInfo]:
    """SSN++ darkness float32 (H, W) in [0, 1] for an image of any size, and how it was run.

    light_center (4,), light_extremes (4, 4): the disk light in the image's
    pixel-height space (``lights.light_point``, ``lights.disk_extremes``);
    softness: radius / distance (``ssn.softness_of``), clamped to SOFTNESS_RANGE;
    thickness: of the buffer channels' hard shadows, in network pixels (the
    scale the model was trained at). threads, torch_device: torch's (``ssn.run_network``'s
    ``threads`` and ``device``; ``device`` is the OpenCL device of the buffer channels);
    progress, check_cancelled: passed to the buffer channels' banded trace.
    """
    mask = np.asarray(mask)
    H, W = mask.shape
    inside = mask > 0.5
    rows = np.flatnonzero(inside.any(axis=1))
    if rows.size == 0:
        raise ValueError("the cutout mask is empty")
    object_px = float(rows[-1] - rows[0] + 1)
    k = network_scale(object_px)
    if max(H, W) * k <= MIN_SIDE:    # the window is the whole image whatever the extent
        extent = (0, 0, W, H)
    else:
        extent = shadow_extent(device, mask, fg_height, bg_height, light_center, light_extremes, thickness / k)
    win = choose_window(H, W, extent, object_px)
    info = CropInfo(win, extent, clamp_softness(softness), float(softness), object_px)
    m, fg, bg = win.scene(mask, fg_height, bg_height)
    channels = buffer_channels(device, m, fg, bg, win.light_points(light_center),
                               win.light_points(light_extremes), thickness, progress=progress,
                               check_cancelled=check_cancelled)
    if check_cancelled is not None:
        check_cancelled()
    d = ssn.run_network(model, channels, info.softness, norm=ssn.RESOLUTION, threads=threads,
                        device=torch_device)
    if gate:
        d = d * reach_gate(channels, m)
    d_img = masked_resize(d, m, win.crop(inside.astype(np.float32)), (win.h, win.w))
    return np.clip(win.paste(d_img, H, W), 0.0, 1.0).astype(np.float32), info
