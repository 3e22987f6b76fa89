"""A learned cutout pixel-height predictor: cutout colour + alpha -> pixel height.

The network (a small U-Net, ``build_model``) never sees the image at its own
size. ``prepare`` crops a square around the cutout's bounding box (side
``(1 + 2 MARGIN)`` x the box's longer side, zero outside the image), resizes it
to ``size`` x ``size`` (bilinear, antialiased) and makes six channels:

* colour: sRGB-encoded straight colour x alpha (3; the cutout on black),
* alpha (1),
* the contact-line heuristic's height (``heightmaps.contact_line_height``,
  computed at the input's size) divided by the box height ``bh`` [px] (1),
* the row coordinate ``(v_bottom - v) / bh`` with ``v_bottom`` the box's bottom
  edge (1: "how far above the lowest pixel").

The target and the output are the pixel height divided by ``bh``. Dividing by
``bh`` makes the target independent of image size and object size: the same
object photographed at twice the resolution has twice the pixel height and
twice the box height. ``predict`` multiplies back by ``bh`` and pastes the map
into the input's frame (normalised convolution with the cutout's mask so the
zeros outside the object never bleed into edge pixels).

Inference needs numpy alone: the network runs in numpy (``height_net``, weights
``cutout_height.npz`` exported from the checkpoint) or in torch
(``LearnedHeightPredictor``'s ``backend``), and the resizing of ``prepare`` /
``paste`` is numpy's (``height_net.resize_chw``, torch's bilinear resize up to
float rounding). torch is imported only by the torch backend and for training
(``build_model``), so importing this module (and the node that uses it) works
without torch.
"""
from __future__ import annotations

import contextlib
import json
import math
import pathlib

import numpy as np

from . import height_net
from .heightmaps import contact_line_height
from .resample import nonzero_box

MARGIN = 0.1          # crop margin on each side, fraction of the box's longer side
IN_CHANNELS = 6
WEIGHTS = pathlib.Path(__file__).resolve().parent.parent / "weights" / "cutout_height.pt"
#: where ``LearnedHeightPredictor`` runs the network by default: ``numpy`` (``height_net``)
#: or ``torch``. Chosen by measurement (``benchmarks/height_bench.py --backend both``;
#: docs/height.md, "How it works"); torch is also taken, on its GPU, when the process has
#: already imported torch and torch sees a GPU
DEFAULT_BACKEND = "numpy"


def srgb_encode(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def straight_srgb(rgba: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(straight sRGB colour in [0, 1], alpha) of a linear premultiplied RGBA (H, W, 4);
    the colour is 0 where alpha is 0 (only the covered pixels are encoded)."""
    rgba = np.asarray(rgba, np.float32)
    a = np.clip(rgba[..., 3], 0.0, 1.0)
    out = np.zeros(rgba.shape[:2] + (3,), np.float32)
    cov = a > 0
    ac = a[cov]
    out[cov] = srgb_encode(rgba[..., :3][cov] / np.maximum(ac, 1e-6)[:, None]).astype(np.float32)
    return out, a


def crop_box(mask: np.ndarray):
    """Bounding box of ``mask`` and the square crop around it.

    Returns ``(r0, r1, c0, c1, top, left, side)`` in pixels (rows r0..r1-1 and
    columns c0..c1-1 hold the mask; the crop is rows top..top+side-1) or None
    for an empty mask."""
    box = nonzero_box(np.asarray(mask, bool))
    if box is None:
        return None
    r0, r1, c0, c1 = box
    side = int(math.ceil(max(r1 - r0, c1 - c0) * (1 + 2 * MARGIN))) + 2
    top = int(round((r0 + r1) / 2 - side / 2))
    left = int(round((c0 + c1) / 2 - side / 2))
    return r0, r1, c0, c1, top, left, side


def _crop(a: np.ndarray, top: int, left: int, side: int) -> np.ndarray:
    """a[top:top+side, left:left+side] with zeros outside a."""
    H, W = a.shape[:2]
    out = np.zeros((side, side) + a.shape[2:], a.dtype)
    y0, x0 = max(top, 0), max(left, 0)
    y1, x1 = min(top + side, H), min(left + side, W)
    if y1 > y0 and x1 > x0:
        out[y0 - top:y1 - top, x0 - left:x1 - left] = a[y0:y1, x0:x1]
    return out


def _resize(a: np.ndarray, size: int) -> np.ndarray:
    """(C, h, w) float32 -> (C, size, size), bilinear, antialiased when shrinking (torch's
    ``F.interpolate(..., mode="bilinear", align_corners=False, antialias=True)`` up to
    float rounding, in numpy: ``height_net.resize_chw``)."""
    return height_net.resize_chw(a, (size, size), antialias=True)


def prepare(colour: np.ndarray, alpha: np.ndarray, size: int, threshold: float = 0.5,
            height: np.ndarray | None = None, contact_line: np.ndarray | None = None):
    """Network input (6, size, size) float32 and the crop (see module doc).

    colour: (H, W, 3) straight sRGB in [0, 1]; alpha: (H, W) coverage;
    height: optional true pixel height (H, W) [px], for training: then also
    returns the target ``height / bh`` and its weight (the resized mask), each
    (size, size). Returns ``(x, box, bh)`` or ``(x, box, bh, target, weight)``;
    ``box`` is None (and x zeros) for an empty mask. ``contact_line``:
    ``contact_line_height(alpha > threshold)`` when the caller already has it.
    """
    alpha = np.clip(np.asarray(alpha, np.float32), 0, 1)
    mask = alpha > threshold
    box = crop_box(mask)
    if box is None:
        x = np.zeros((IN_CHANNELS, size, size), np.float32)
        z = np.zeros((size, size), np.float32)
        return (x, None, 0.0) if height is None else (x, None, 0.0, z, z)
    r0, r1, c0, c1, top, left, side = box
    bh = float(r1 - r0)
    heur = contact_line_height(mask) if contact_line is None else contact_line

    def win(a):       # the square crop of a full-size array (zeros outside the image)
        return _crop(np.asarray(a, np.float32), top, left, side)
    # channels built on the crop only (a large cutout's full-size stack cost seconds)
    full = np.empty((IN_CHANNELS + (2 if height is not None else 0), side, side), np.float32)
    a_w = win(alpha)
    full[:3] = np.moveaxis(win(colour) * a_w[..., None], 2, 0)
    full[3] = a_w
    full[4] = win(heur) / bh
    # the row channel: a ramp, also outside the image (not zero)
    vv = (np.arange(top, top + side, dtype=np.float32) + 0.5)[:, None]
    full[5] = np.broadcast_to((r1 - vv) / bh, (side, side))
    if height is not None:
        m_w = win(mask)
        full[6] = win(height) * m_w / bh
        full[7] = m_w
    small = _resize(full, size)
    x = small[:IN_CHANNELS]
    if height is None:
        return x, box, bh
    w = small[IN_CHANNELS + 1]
    target = small[IN_CHANNELS] / np.maximum(w, 1e-6)
    return x, box, bh, np.where(w > 1e-3, target, 0.0).astype(np.float32), w


def paste(pred: np.ndarray, box, bh: float, mask: np.ndarray, clip: bool = True) -> np.ndarray:
    """Map the network's output (size, size) (height / bh) back to the input frame:
    (H, W) pixel height [px], 0 outside ``mask`` (and >= 0 unless ``clip`` is
    False). Normalised convolution: the output and the crop's mask are resized
    separately and divided."""
    H, W = mask.shape
    out = np.zeros((H, W), np.float32)
    if box is None:
        return out
    r0, r1, c0, c1, top, left, side = box
    m_small = _resize(_crop(mask, top, left, side).astype(np.float32)[None], pred.shape[0])[0]
    # back to the crop's size without antialiasing (torch's default bilinear: a crop smaller
    # than the network's input is sampled, not averaged)
    big = height_net.resize_chw(np.stack([pred * m_small, m_small]).astype(np.float32), (side, side),
                                antialias=False)
    y0, x0 = max(top, 0), max(left, 0)
    y1, x1 = min(top + side, H), min(left + side, W)
    num, den = (b[y0 - top:y1 - top, x0 - left:x1 - left] for b in big)
    val = np.where(den > 1e-6, num / np.maximum(den, 1e-6), 0.0)
    # the map is 0 outside the crop (and the mask): only the crop's part is computed
    out[y0:y1, x0:x1] = np.where(mask[y0:y1, x0:x1], (np.maximum(val, 0.0) if clip else val) * bh, 0.0)
    return out


def contact_band(mask: np.ndarray, band: float = 1.5) -> np.ndarray:
    """The cutout's contact pixels: mask pixels in its lowest rows, those whose
    row centre ``r + 0.5`` is within ``band`` px of the mask's bottom edge ``r1``
    (the row below its lowest row): the lowest row for band 1, two rows for 1.5."""
    rows = np.nonzero(np.asarray(mask).any(1))[0]
    out = np.zeros(np.shape(mask), bool)
    if len(rows) == 0:
        return out
    r1 = int(rows.max()) + 1
    lo = max(int(math.ceil(r1 - band - 0.5)), 0)
    out[lo:r1] = np.asarray(mask, bool)[lo:r1]
    return out


def pin_contact(height: np.ndarray, mask: np.ndarray, lift: float = 0.0, band: float = 1.5,
                fade: float | None = None) -> np.ndarray:
    """The contact as a constraint: shift a pixel-height map [px] so the mean
    over the cutout's contact pixels (``contact_band``) is ``lift`` [px] before
    clipping at 0 (0: the
    object stands on the ground; > 0: it floats that high above its foot, e.g. a
    held object or a hanging lamp). Heights stay >= 0 (clipped after the shift),
    and 0 outside ``mask``. Shifting by a constant keeps the shape above the
    contact: the predictor supplies the shape, the constraint supplies the level.
    ``fade`` (a fraction of the cutout's box height, or None): instead of a
    constant, the shift fades linearly from full at the bottom edge to 0 at
    ``fade`` box heights above it (the foot is fixed, the upper part kept where
    the predictor put it)."""
    m = np.asarray(mask, bool)
    h = np.asarray(height, np.float32)
    c = contact_band(m, band)
    if not c.any():
        return np.where(m, h, 0.0).astype(np.float32)
    off = float(h[c].mean()) - float(lift)
    if fade is not None:
        rows = np.nonzero(m.any(1))[0]
        r0, r1 = int(rows.min()), int(rows.max()) + 1
        v = np.arange(m.shape[0], dtype=np.float64)[:, None] + 0.5
        w = np.clip(1.0 - (r1 - v) / (float(fade) * (r1 - r0)), 0.0, 1.0)
        # the band's own weights are < 1: scale so the band's mean still lands on lift
        wb = float(np.broadcast_to(w, m.shape)[c].mean())
        return np.where(m, np.maximum(h - off * w / max(wb, 1e-6), 0.0), 0.0).astype(np.float32)
    return np.where(m, np.maximum(h - off, 0.0), 0.0).astype(np.float32)


def _half_hull(points) -> list[tuple[float, float]]:
    """One half of Andrew's monotone chain over ``points`` (sorted along x): the
    vertices that turn left (counter-clockwise), collinear points dropped."""
    h: list[tuple[float, float]] = []
    for p in points:
        while len(h) >= 2 and ((h[-1][0] - h[-2][0]) * (p[1] - h[-2][1])
                               - (h[-1][1] - h[-2][1]) * (p[0] - h[-2][0])) <= 0:
            h.pop()
        h.append(p)
    return h


def lower_hull_rows(bottom_edge: np.ndarray) -> np.ndarray:
    """The lower convex hull (in the image: the envelope from below, largest v)
    of a silhouette's column bottoms. ``bottom_edge``: (W,) the bottom edge of
    each column's lowest mask pixel [rows, the row below it], NaN for empty
    columns. Returns (W,) the hull's row at each column centre (NaN where
    empty). A straight or convex-from-below bottom (a base's near rim, a
    brick's two bottom edges) lies on its hull; the underside of a table top
    between its legs or the gap between two feet lies above it."""
    b = np.asarray(bottom_edge, np.float64)
    cols = np.nonzero(np.isfinite(b))[0]
    out = np.full(b.shape, np.nan)
    if len(cols) == 0:
        return out
    pts = [(float(c) + 0.5, float(b[c])) for c in cols]
    # the upper envelope of v(u): the monotone chain's half taken right to left, put back in order
    hull = _half_hull(pts[::-1])[::-1]
    hu = np.array([q[0] for q in hull]); hv = np.array([q[1] for q in hull])
    out[cols] = np.interp(cols + 0.5, hu, hv)
    return out


def snap_feet(height: np.ndarray, mask: np.ndarray, tol: float, hull: bool = False,
              fade: float = 0.25) -> np.ndarray:
    """The rest of a grounded object's contact, after ``pin_contact``.

    The contact band is only the silhouette's two lowest rows; a standing
    object also touches the ground higher in the image (the far side of a round
    base, a turned brick's two bottom edges, the back legs of a table). Every
    column whose lowest mask pixel the map already puts below ``tol`` px is
    taken to stand on the ground there (with ``hull``: only if that pixel is
    also within 1 px of the silhouette's lower convex hull, ``lower_hull_rows``):
    the column is shifted down by that pixel's height, the shift fading
    linearly to 0 at ``fade`` box heights above it, so the pixel is exactly 0 and
    the shape above it is kept. Heights stay >= 0 and 0 outside ``mask``.
    ``tol <= 0`` returns the map unchanged (masked). [px in, px out]"""
    m = np.asarray(mask, bool)
    h = np.where(m, np.asarray(height, np.float32), 0.0).astype(np.float32)
    if tol <= 0 or not m.any():
        return h
    H, W = m.shape
    has = m.any(0)
    low = (H - 1 - np.argmax(m[::-1], axis=0)).astype(np.int64)        # lowest mask row per column
    cols = np.nonzero(has)[0]
    hb = h[low[cols], cols]
    take = hb < tol
    if hull:
        edge = np.where(has, low + 1.0, np.nan)
        hr = lower_hull_rows(edge)
        take &= (hr[cols] - edge[cols]) <= 1.0
    take &= hb > 0
    if not take.any():
        return h
    rows = np.nonzero(m.any(1))[0]
    bh = float(rows.max() - rows.min() + 1)
    sel, off = cols[take], hb[take]
    v = np.arange(H, dtype=np.float64)[:, None]
    d = low[sel][None, :] - v                        # rows above each column's lowest pixel
    w = np.where(d >= 0, np.clip(1.0 - d / (fade * bh), 0.0, 1.0), 0.0)
    h[:, sel] = np.maximum(h[:, sel] - off[None, :] * w, 0.0)
    return np.where(m, h, 0.0).astype(np.float32)


def convex_hull_area(mask: np.ndarray) -> float:
    """Area [px^2] of the convex hull of a mask's pixel squares (0 for an empty mask)."""
    m = np.asarray(mask, bool)
    rows = np.nonzero(m.any(1))[0]
    if len(rows) == 0:
        return 0.0
    first = np.argmax(m[rows], axis=1)
    last = m.shape[1] - np.argmax(m[rows][:, ::-1], axis=1)
    # only a row whose left (right) edge is a running minimum (maximum) from the top or
    # from the bottom can be on the hull: any other edge point lies between a point
    # further out above it, one further out below it and its row's other edge
    keep_l = (first <= np.minimum.accumulate(first)) | (first <= np.minimum.accumulate(first[::-1])[::-1])
    keep_r = (last >= np.maximum.accumulate(last)) | (last >= np.maximum.accumulate(last[::-1])[::-1])
    pts = sorted({(float(c), float(r + d)) for r, c in zip(rows[keep_l], first[keep_l]) for d in (0, 1)}
                 | {(float(c), float(r + d)) for r, c in zip(rows[keep_r], last[keep_r]) for d in (0, 1)})
    hull = _half_hull(pts)[:-1] + _half_hull(pts[::-1])[:-1]
    x = np.array([q[0] for q in hull]); y = np.array([q[1] for q in hull])
    return float(0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


#: the largest crop side [px] of the cutouts the confidence rule was chosen on (the
#: validation renders are 256 x 256). ``LearnedHeightPredictor.signal_side`` (default
#: SIGNAL_SIDE) measures a larger cutout's signal lengths in pixels of a crop this
#: size, so its confidence is read off the bins fitted at that size (in the cutout's
#: own pixels, a cutout 8x larger landed in the top bin: docs/height-record.md, "Measured:
#: large cutouts at 512 px")
SIGNAL_SIDE = 256

SIGNALS = ("disagreement_px", "disagreement_rel", "flip_px", "head_gain_px", "overhang_share", "solidity")


def confidence_signals(height: np.ndarray, heuristic: np.ndarray, mask: np.ndarray,
                       flip_height: np.ndarray | None = None, est_mae_learned: float | None = None,
                       est_mae_heuristic: float | None = None, which=SIGNALS,
                       contact_line: np.ndarray | None = None, px_scale: float = 1.0) -> dict:
    """Per-cutout signals of how far to trust the learned map (docs/height-record.md,
    "Confidence rule"), each a float (NaN when its inputs are missing):

    * ``disagreement_px``: mean |height - heuristic| over the mask [px];
    * ``disagreement_rel``: the same divided by the mask's box height;
    * ``flip_px``: mean |height - flip_height| [px] (``flip_height``: the map
      predicted for the mirrored cutout, mirrored back);
    * ``head_gain_px``: ``est_mae_learned - est_mae_heuristic`` (the error heads) [px];
    * ``overhang_share``: the share of the mask's columns whose lowest pixel lies
      more than 2 px above the contact line (where the heuristic is wrong by design);
    * ``solidity``: mask area / its convex hull's area.

    ``px_scale``: the lengths (``disagreement_px``, ``flip_px``, ``head_gain_px``)
    are multiplied by it (``predict_full`` with ``signal_side``: ``min(1,
    signal_side / crop side)``, so a large cutout's are in pixels of the crop size
    the rule was chosen at; not shipped, see ``SIGNAL_SIDE``).
    ``which``: compute only these (the others are left out of the dict).
    ``contact_line``: ``contact_line_height(mask)`` when the caller already has it.
    """
    m = np.asarray(mask, bool)
    nan = float("nan")
    if not m.any():
        return {k: nan for k in which}
    out = {}
    if "disagreement_px" in which or "disagreement_rel" in which:
        rows = np.nonzero(m.any(1))[0]
        bh = float(rows.max() - rows.min() + 1)
        dis = float(np.abs(height[m] - heuristic[m]).mean())
        out.update(disagreement_px=dis * px_scale, disagreement_rel=dis / bh)
    if "flip_px" in which:
        out["flip_px"] = nan if flip_height is None else float(np.abs(height[m] - flip_height[m]).mean()) * px_scale
    if "head_gain_px" in which:
        out["head_gain_px"] = (nan if est_mae_learned is None
                               else float(est_mae_learned - est_mae_heuristic) * px_scale)
    if "overhang_share" in which:
        cols = np.nonzero(m.any(0))[0]
        low = m.shape[0] - 1 - np.argmax(m[::-1], axis=0)
        # the contact line's height at a column's lowest pixel centre = v_contact - (low + 0.5)
        cl = contact_line_height(m) if contact_line is None else contact_line
        hc = cl[low[cols], cols]
        out["overhang_share"] = float(np.mean(hc - 0.5 > 2.0))
    if "solidity" in which:
        out["solidity"] = float(m.sum()) / max(convex_hull_area(m), 1e-9)
    return {k: out[k] for k in which}


def confidence_value(signals: dict, rule: dict) -> float:
    """The chosen signal of a confidence rule (``config["inference"]["confidence"]``),
    oriented so that larger means "the learned map is more likely worse than the
    contact line": ``sign * signals[name]``, or for ``name == "combined"`` the
    linear combination ``b + sum w_k (signals[k] - mean_k) / std_k``."""
    if rule["signal"] == "combined":
        z = [(signals[k] - mu) / sd for k, mu, sd in zip(rule["features"], rule["mean"], rule["std"])]
        return float(rule["bias"] + np.dot(rule["weights"], z))
    return float(rule["sign"]) * float(signals[rule["signal"]])


def calibrated_confidence(value: float, rule: dict) -> float:
    """The validation win rate of the learned map among cutouts with a similar
    signal: ``rule["bins"]`` are signal quantile edges, ``rule["win_rate"]`` the
    share of validation cutouts in each bin where the learned map's MAE was below
    the contact line's."""
    k = int(np.searchsorted(rule["bins"], value, side="right"))
    return float(rule["win_rate"][min(max(k, 0), len(rule["win_rate"]) - 1)])


def split_output(y):
    """(height / bh (N, S, S), error heads (N, 2, S, S) or None) of a model output:
    a 1-output model returns the height alone; a 3-output one also returns the
    log of its predicted absolute errors of the learned and the contact-line
    height (in units of bh), ``build_model``."""
    if y.ndim == 4:
        return y[:, 0], y[:, 1:]
    return y, None


def build_model(base: int = 8, levels: int = 4, outputs: int = 1):
    """The U-Net: per level two conv3x3-BatchNorm-ReLU, max-pool down, bilinear up
    + skip concat; 6 input channels, 1 output (height / bh), added to the
    heuristic's channel (the network learns the correction). ``outputs=3`` adds
    two confidence heads (``split_output``): log |learned - true| / bh and
    log |contact line - true| / bh per pixel, and the model returns (N, 3, S, S)
    with the height in channel 0."""
    import torch
    from torch import nn
    import torch.nn.functional as F

    def block(cin, cout):
        return nn.Sequential(nn.Conv2d(cin, cout, 3, padding=1, bias=False), nn.BatchNorm2d(cout),
                             nn.ReLU(inplace=True),
                             nn.Conv2d(cout, cout, 3, padding=1, bias=False), nn.BatchNorm2d(cout),
                             nn.ReLU(inplace=True))

    class UNet(nn.Module):
        def __init__(self):
            super().__init__()
            ch = [base * 2 ** k for k in range(levels + 1)]
            self.down = nn.ModuleList([block(IN_CHANNELS, ch[0])] +
                                      [block(ch[k - 1], ch[k]) for k in range(1, levels + 1)])
            self.up = nn.ModuleList([block(ch[k + 1] + ch[k], ch[k]) for k in range(levels)])
            self.head = nn.Conv2d(ch[0], outputs, 1)

        def forward(self, x):
            heur = x[:, 4]
            skips = []
            for k, d in enumerate(self.down):
                x = d(x if k == 0 else F.max_pool2d(x, 2))
                skips.append(x)
            x = skips.pop()
            for k in reversed(range(levels)):
                x = F.interpolate(x, scale_factor=2, mode="bilinear", align_corners=False)
                x = self.up[k](torch.cat([x, skips.pop()], 1))
            # a residual over the heuristic channel: right from the start for upright objects
            y = self.head(x)
            if outputs == 1:
                return y[:, 0] + heur
            return torch.cat([(y[:, 0] + heur)[:, None], y[:, 1:]], 1)

    return UNet()


def fold_batchnorm(model):
    """The same network for inference with every BatchNorm folded into the
    convolution before it (eval mode: ``y = gamma (W x - mean) / sqrt(var + eps) + beta``
    is a convolution with weights ``W gamma / s`` and bias ``beta - gamma mean / s``,
    ``s = sqrt(var + eps)``): fewer passes over the activations, same output up to
    float rounding. Modifies and returns ``model`` (call after loading the weights)."""
    import torch
    from torch import nn

    def fold(seq):
        mods, out, i = list(seq), [], 0
        while i < len(mods):
            conv = mods[i]
            if isinstance(conv, nn.Conv2d) and i + 1 < len(mods) and isinstance(mods[i + 1], nn.BatchNorm2d):
                bn = mods[i + 1]
                scale = bn.weight / torch.sqrt(bn.running_var + bn.eps)
                new = nn.Conv2d(conv.in_channels, conv.out_channels, conv.kernel_size, conv.stride,
                                conv.padding, bias=True)
                with torch.no_grad():
                    new.weight.copy_(conv.weight * scale[:, None, None, None])
                    b0 = conv.bias if conv.bias is not None else torch.zeros_like(bn.running_mean)
                    new.bias.copy_(bn.bias + (b0 - bn.running_mean) * scale)
                out.append(new)
                i += 2
            else:
                out.append(conv)
                i += 1
        return nn.Sequential(*out)

    model.eval()
    for lst in (model.down, model.up):
        for k in range(len(lst)):
            lst[k] = fold(lst[k])
    return model


def choose_backend(path: pathlib.Path, backend: str | None = None) -> str:
    """Where ``LearnedHeightPredictor`` runs the network for the checkpoint ``path``.

    ``backend``: ``numpy`` or ``torch``, or None: the environment variable
    ``PIXGRAPH_HEIGHT_BACKEND`` when set, else torch when the process has already
    imported torch and torch sees a GPU, else ``DEFAULT_BACKEND``; a backend that
    cannot run falls back to the other one: numpy needs the exported ``.npz`` beside
    the ``.pt`` (a training run's checkpoint has none), torch must be importable."""
    import importlib.util
    import os
    import sys
    path = pathlib.Path(path)
    if backend is not None:
        if backend not in ("numpy", "torch"):
            raise ValueError(f"LearnedHeightPredictor: backend must be 'numpy' or 'torch', not {backend!r}")
        return backend
    env = os.environ.get("PIXGRAPH_HEIGHT_BACKEND", "").strip().lower()
    if env:
        if env not in ("numpy", "torch"):
            raise ValueError(f"PIXGRAPH_HEIGHT_BACKEND must be 'numpy' or 'torch', not {env!r}")
        return env
    has_npz = path.suffix == ".npz" or path.with_suffix(".npz").exists()
    torch_mod = sys.modules.get("torch")
    try:
        has_torch = torch_mod is not None or (
            "torch" not in sys.modules and importlib.util.find_spec("torch") is not None)
    except (ImportError, ValueError):
        has_torch = False
    if torch_mod is not None and has_torch and path.suffix != ".npz":
        try:
            if torch_mod.cuda.is_available():
                return "torch"
        except Exception:  # noqa: BLE001 - a broken CUDA setup: the CPU backends still work
            pass
    if DEFAULT_BACKEND == "numpy" and has_npz:
        return "numpy"
    if has_torch and path.suffix != ".npz":
        return "torch"
    if has_npz:
        return "numpy"
    raise FileNotFoundError(f"{path}: the numpy network needs {path.with_suffix('.npz')} "
                            "(python -m pixgraph_lab.height.export --npz) and torch is not installed")


class LearnedHeightPredictor:
    """``HeightPredictor`` from a trained checkpoint (``predict(rgba)`` -> (H, W) px).

    rgba: float32 (H, W, 4) linear premultiplied colour + alpha, any size.

    ``path``: the checkpoint (``.pt``; the numpy backend reads the ``.npz`` beside it)
    or the numpy weights (``.npz``). ``backend``: ``numpy`` (``height_net``; no torch
    needed), ``torch`` (on torch's GPU when it sees one) or None (``choose_backend``).
    ``threads``: the threads the network runs on, torch's or numpy's BLAS's
    (``height_net.blas_threads``); None: the library's default.
    """

    def __init__(self, path: str | pathlib.Path = WEIGHTS, threads: int | None = 1,
                 flip_average: bool | None = None, heuristic_detail: bool | None = None,
                 pin_fade: float | None | str = "checkpoint", foot_snap: dict | None | str = "checkpoint",
                 backend: str | None = None):
        path = pathlib.Path(path)
        self.path = path
        self.backend = choose_backend(path, backend)
        self._model = None
        if self.backend == "numpy":
            npz = path if path.suffix == ".npz" else path.with_suffix(".npz")
            if not npz.exists():
                raise FileNotFoundError(f"{npz}: no numpy weights for {path} "
                                        "(python -m pixgraph_lab.height.export --npz writes them)")
            arrays, cfg = height_net.load_npz(npz, check_against=path.with_suffix(".pt"))
            try:
                self.net = height_net.HeightNet(arrays, cfg)
            except (KeyError, ValueError) as e:    # another network's arrays (a missing layer, a shape)
                raise ValueError(f"{npz}: not the weights of this network ({type(e).__name__}: {e}); "
                                 "write them again with `python -m pixgraph_lab.height.export --npz`") from None
            self.device = None
        else:
            import torch
            ck = torch.load(path, map_location="cpu", weights_only=True)
            cfg = json.loads(ck["config"]) if isinstance(ck["config"], str) else ck["config"]
            self._state = ck["model"]
            self.device = torch.device("cuda" if torch.cuda.is_available() else "cpu")
            self.net = None
        self.size = int(cfg["size"])
        self.outputs = int(cfg.get("outputs", 1))
        self.config = cfg
        if self.backend == "torch":
            self.model                                   # build it now: load errors show here
        # the network is small (~0.44 GFLOP per 64^2 crop): one thread is about as fast as two
        # on an idle machine and much faster on a busy one (benchmarks/height_bench.py)
        self.threads = threads
        # inference options (``predict``); None: the checkpoint's choice (``config["inference"]``,
        # chosen on the validation split by lab/height/inference_study.py), else off
        inf = cfg.get("inference", {})
        self.flip_average = bool(inf.get("flip_average", False) if flip_average is None else flip_average)
        self.heuristic_detail = bool(inf.get("heuristic_detail", False) if heuristic_detail is None
                                     else heuristic_detail)
        # how the contact pin shifts the map (pin_contact's fade): the checkpoint's choice
        # (lab/height/inference_study.py --pin), else a constant shift
        self.pin_fade = inf.get("pin_fade", None) if pin_fade == "checkpoint" else pin_fade
        # the rest of the contact (snap_feet): the checkpoint's choice (lab/height/foot_study.py), else off
        fs = inf.get("foot_snap") if foot_snap == "checkpoint" else foot_snap
        self.foot_snap = dict(fs) if fs else None
        # auto's rule (lab/height/confidence_study.py): which signal, its threshold and calibration
        self.confidence_rule = inf.get("confidence")
        # the confidence signals' lengths in pixels of a crop at most this large (SIGNAL_SIDE), or
        # None: in the cutout's own pixels (the path before the fifth session)
        self.signal_side = SIGNAL_SIDE
        # a cutout whose square crop is larger than this [px] is predicted at this size and
        # the map brought back (height_work_size), or None: at its own size. Both shipped by
        # a rule fixed before measuring (docs/height-record.md, "Measured: large cutouts at 512 px")
        from .height_work_size import WORK_SIDE
        self.work_side = WORK_SIDE

    @property
    def model(self):
        """The folded torch model (torch backend; built on first use for the numpy one, for
        the lab scripts that evaluate or count its parameters)."""
        if self._model is None:
            import torch
            if self.net is not None and not hasattr(self, "_state"):
                ck = torch.load(self.path.with_suffix(".pt"), map_location="cpu", weights_only=True)
                self._state = ck["model"]
                self.device = torch.device("cpu")
            model = build_model(int(self.config["base"]), int(self.config["levels"]), self.outputs)
            model.load_state_dict({k: v.float() for k, v in self._state.items()})
            self._model = fold_batchnorm(model).to(self.device)   # inference only: BatchNorm folded
        return self._model

    def predict_normalised(self, x: np.ndarray, aux: bool = False):
        """(N, 6, S, S) inputs -> (N, S, S) height / bh; with ``aux`` also the
        error heads (N, 2, S, S) (None for a 1-output model)."""
        if self.backend == "numpy":
            with self._threads():
                h, e = split_output(self.net(np.ascontiguousarray(x, np.float32)))
            h = np.ascontiguousarray(h)
            return (h, e) if aux else h
        import torch
        with self._threads(), torch.inference_mode():
            h, e = split_output(self.model(torch.from_numpy(np.ascontiguousarray(x, np.float32))
                                           .to(self.device)).float())
            h = h.cpu().numpy()
            e = None if e is None else e.cpu().numpy()
        return (h, e) if aux else h

    @contextlib.contextmanager
    def _threads(self):
        if self.backend == "numpy":
            with height_net.blas_threads(self.threads):
                yield
            return
        import torch
        before = torch.get_num_threads()
        if self.threads and self.device.type == "cpu":
            torch.set_num_threads(self.threads)
        try:
            with height_net.blas_threads(self.threads):      # prepare / paste resize with numpy's BLAS
                yield
        finally:
            torch.set_num_threads(before)

    def predict(self, rgba: np.ndarray, threshold: float = 0.5, contact: str = "ground",
                lift: float = 0.0) -> np.ndarray:
        """(H, W) pixel height [px], 0 outside the cutout (alpha > threshold).

        ``contact``: ``ground`` (the object stands on the ground: its contact
        pixels are pinned to height 0, ``pin_contact``), ``lifted`` (pinned to
        ``lift`` px: an object that does not touch the ground) or ``free`` (the
        network's raw output, no constraint). See ``predict_full``.
        """
        return self.predict_full(rgba, threshold, contact, lift)["height"]

    def predict_full(self, rgba: np.ndarray, threshold: float = 0.5, contact: str = "ground",
                     lift: float = 0.0, signals: bool = False) -> dict:
        """``predict`` plus the confidence (``predict_at_own_size``); a cutout whose
        square crop is larger than ``work_side`` px is predicted at that size and
        the map brought back to full size (``height_work_size``; the result then
        has ``work_scale``, the shrink factor)."""
        if contact not in ("ground", "lifted", "free"):
            raise ValueError(f"contact must be 'ground', 'lifted' or 'free', not {contact!r}")
        if self.work_side:
            from .height_work_size import predict_at_work_size
            return predict_at_work_size(self, rgba, threshold, contact, lift, self.work_side, signals)
        return self.predict_at_own_size(rgba, threshold, contact, lift, signals)

    def predict_at_own_size(self, rgba: np.ndarray, threshold: float = 0.5, contact: str = "ground",
                            lift: float = 0.0, signals: bool = False) -> dict:
        """The prediction with the whole path at the input's pixel size: a dict with ``height`` (H, W) [px],
        ``heuristic`` (the contact-line height under the same contact
        constraint), and, for a checkpoint with confidence heads (``outputs``
        3), ``est_mae_learned`` / ``est_mae_heuristic`` [px] (the network's
        estimate of each map's mean absolute error over the cutout) and
        ``confidence`` = est_mae_heuristic / (est_mae_learned + est_mae_heuristic)
        in (0, 1): above 0.5 the learned map is expected to be the better one
        (None without heads), and ``use_learned`` (auto's choice: confidence >= 0.5).

        A checkpoint with a confidence rule (``config["inference"]["confidence"]``,
        chosen on validation by ``lab/height/confidence_study.py``) replaces that:
        ``signal`` is the rule's signal (``confidence_value`` of
        ``confidence_signals``; larger = the learned map more likely worse),
        ``use_learned`` is ``signal <= rule["threshold"]`` and ``confidence`` the
        validation win rate of the learned map at that signal
        (``calibrated_confidence``). ``auto_height``: auto's choice, ``height``
        where ``use_learned``, else ``heuristic`` (pinned like ``height``; where
        ``CutoutHeight``'s ``method: auto`` falls back it returns its own contact
        line, with its ``tolerance``, pinned the same way: the same map at the
        default tolerance).
        ``signals=True`` also returns every candidate
        signal (``signals``; runs the mirrored crop for ``flip_px``).

        ``flip_average``: the network also reads the mirrored crop and the two
        outputs (the second mirrored back) are averaged; training saw mirrored
        samples, so both are equally valid guesses. ``heuristic_detail``: the
        network's output is a correction of the contact-line channel at the
        network's size (64^2); adding back what the 64^2 round trip of that
        channel lost, ``h_contact - paste(resized h_contact)``, keeps the full-size
        heuristic's detail (steps between columns, the silhouette's edge) wherever
        the network does not correct it.
        """
        if contact not in ("ground", "lifted", "free"):
            raise ValueError(f"contact must be 'ground', 'lifted' or 'free', not {contact!r}")
        rgba = np.asarray(rgba, np.float32)
        colour, alpha = straight_srgb(rgba)
        mask = alpha > threshold
        heur = contact_line_height(mask)
        zero = np.zeros(alpha.shape, np.float32)
        out = {"height": zero, "heuristic": heur.astype(np.float32), "auto_height": zero,
               "confidence": None, "est_mae_learned": None, "est_mae_heuristic": None}
        rule = self.confidence_rule
        need_flip = signals or bool(rule and (rule["signal"] == "flip_px" or "flip_px" in rule.get("features", ())))
        lv = float(lift) if contact == "lifted" else 0.0
        with self._threads():
            x, box, bh = prepare(colour, alpha, self.size, threshold, contact_line=heur)
            if box is None:
                return out
            xs = [x, x[:, :, ::-1]] if (self.flip_average or need_flip) else [x]
            ys, e = self.predict_normalised(np.stack(xs).copy(), aux=True)
            if self.flip_average:
                pred = 0.5 * (ys[0] + ys[1][:, ::-1])
            else:
                pred = ys[0]
            h = self._finish(pred, x, box, bh, mask, heur, contact, lv)
            # the mirrored crop's own map, mirrored back (a second guess; flip_px)
            h_flip = self._finish(ys[1][:, ::-1], x, box, bh, mask, heur, contact, lv) if need_flip else None
        if e is not None:
            w = np.clip(x[3], 0, 1)
            ws = max(float(w.sum()), 1e-6)
            el = float((np.exp(e[0, 0]) * w).sum() / ws * bh)
            eh = float((np.exp(e[0, 1]) * w).sum() / ws * bh)
            out.update(est_mae_learned=el, est_mae_heuristic=eh, confidence=eh / max(el + eh, 1e-9))
        if contact != "free":
            out["heuristic"] = pin_contact(heur, mask, lv)
        out["height"] = h
        if out["confidence"] is not None:
            out["use_learned"] = out["confidence"] >= 0.5
        if rule or signals:
            which = SIGNALS if signals else tuple(rule.get("features", [rule["signal"]]))
            px_scale = min(1.0, self.signal_side / box[6]) if self.signal_side else 1.0
            sig = confidence_signals(h, out["heuristic"], mask, h_flip, out["est_mae_learned"],
                                     out["est_mae_heuristic"], which, contact_line=heur, px_scale=px_scale)
            if signals:
                out["signals"] = sig
            if rule:
                val = confidence_value(sig, rule)
                out.update(signal=val, use_learned=bool(val <= rule["threshold"]),
                           confidence=calibrated_confidence(val, rule))
        out["auto_height"] = h if out.get("use_learned", True) else out["heuristic"]
        return out

    def _finish(self, pred, x, box, bh, mask, heur, contact, lv):
        """A network output (S, S) -> the full-size map [px] under the contact constraint."""
        if not self.heuristic_detail:
            h = paste(pred, box, bh, mask)
        else:
            # paste is linear in its input for one mask: paste(pred) - paste(x[4]) in one call
            h = paste(pred - x[4], box, bh, mask, clip=False) + heur
            h = np.where(mask, np.maximum(h, 0.0), 0.0).astype(np.float32)
        if contact != "free":
            h = pin_contact(h, mask, lv, fade=self.pin_fade)
            if contact == "ground" and self.foot_snap:
                h = snap_feet(h, mask, float(self.foot_snap["tol"]), bool(self.foot_snap.get("hull", False)))
        return h
