"""A large cutout's learned pixel height predicted at a work size, then brought
back to full size (``LearnedHeightPredictor.predict_full``'s path for a cutout
whose square crop is larger than ``WORK_SIDE``).

Everything in the predictor beyond the network (the contact pin, the foot
snap's tolerance, the confidence signals and their thresholds) was chosen on
256 x 256 renders, and several of those are in pixels; and a 12 MP cutout took
2.2 s at its own size, most of it full-size colour conversion and resizing for
a 64^2 network input. A cutout whose crop side is larger than ``work_side`` is
shrunk by ``f = side / work_side`` (antialiased bilinear on the linear
premultiplied RGBA, reading only the covered box: ``resample.shrink_part``),
predicted there, and the map brought back to full size:

* heights are vertical lengths, so they scale by ``f``;
* the map is enlarged inside the outline only (``upsample.masked_resize``: a
  full-size pixel interpolates the work-size pixels on its own side of the
  cutout's outline), then the contact is pinned again on the full-size mask
  (``pin_contact``, lift in full-size px) and the foot snap runs with its
  tolerance x ``f``;
* the contact line (``heuristic``) is computed at full size, pinned the same way;
* the confidence, signal and auto's choice are the work size's; ``est_mae_*``
  are scaled by ``f`` into full-size px;
* a cutout thinner than a work-size pixel everywhere (no shrunk pixel reaches
  the threshold) is predicted at its own size instead;
* a thin *part* of a large cutout (a stick held up, an antenna, a lamp's stem:
  full-size mask pixels with no work-size mask pixel within the enlargement's
  reach, ``masked_resize``'s ``lost``) takes the contact line's height there,
  plus ``lift`` with ``contact: lifted`` (``fill_thin``, ``THIN_FILL``) before
  the pin; it got the plain bilinear value, about 0. A cutout without such pixels gets the same map as before, bit for bit.

Shipped with ``WORK_SIDE = 512`` by a non-inferiority rule fixed before its
fresh validation samples existed (docs/height-record.md, "Measured: large cutouts at
512 px"): on 280 fresh samples enlarged 4x / 8x its learned MAE differed from
the full-size path's by -0.003 / -0.001 px (upper 95 % bounds +0.031 / +0.045
px, margin 0.156), its confidence was 0.012-0.013 off the actual win rate
(full-size path 0.029 / 0.052) and at 8x it took 0.67x the time. With the cut to
the covered box (``_on_covered_box``, added after the decision) the same samples
give bounds +0.036 / +0.041 px, a confidence 0.015 / 0.020 off and 0.26-0.30x the
time at 8x. At 256 px
(the first candidate) it had cost 0.3-0.8 % of MAE on the old validation set.
"""
from __future__ import annotations

import numpy as np

from .heightmaps import contact_line_height
from .learned_height import crop_box, pin_contact, snap_feet
from .resample import nonzero_box, shrink_part
from .upsample import masked_resize

#: how the full-size pixels with no work-size pixel of their own (a part thinner than a
#: work-size pixel: ``upsample.masked_resize``'s ``lost``) get their height
#: (``fill_thin``). ``contact`` shipped by the rule of docs/height-record.md ("Measured: thin
#: parts of large cutouts"): over the stick figure and the 29 of 30 renders at 3072^2 with thin
#: rods that lose pixels, MAE over the lost pixels 117 px (none, the path before: 1,569; attached: 277;
#: the candidates that lost are in ``pixgraph_lab.height.thin_study``)
THIN_FILL = "contact"

#: the largest square crop [px] the predictor runs at (the validation renders are
#: 256 x 256, crop sides 74-245 px, 5th-95th percentile; 256 was the first
#: candidate, which missed its rule)
WORK_SIDE = 512


def work_shape(H: int, W: int, side: int, work_side: int = WORK_SIDE):
    """(f, (h, w)): the shrink factor and the work size of an (H, W) image whose
    cutout's square crop is ``side`` px, or (1.0, (H, W)) when it is small enough."""
    if side <= work_side:
        return 1.0, (H, W)
    f = side / float(work_side)
    return f, (max(1, int(round(H / f))), max(1, int(round(W / f))))


def shrink_cutout(rgba: np.ndarray, shape) -> np.ndarray:
    """The linear premultiplied (H, W, 4) cutout resized to ``shape`` (antialiased
    bilinear), reading only the box of its covered pixels."""
    box = nonzero_box(rgba[..., 3] > 0)
    if box is None:
        return np.zeros(tuple(shape) + (4,), np.float32)
    r0, r1, c0, c1 = box
    return shrink_part(np.asarray(rgba[r0:r1, c0:c1], np.float32), (r0, c0), rgba.shape[:2], shape)


def fill_thin(height: np.ndarray, mask: np.ndarray, lost: np.ndarray, heuristic: np.ndarray,
              how=THIN_FILL) -> np.ndarray:
    """``height`` [px] (H, W) with its ``lost`` pixels (inside ``mask``, no work-size
    pixel of their own) filled, in place; the others untouched.

    ``how``: ``"contact"``, the contact line ``heuristic`` [px] there; ``"none"``,
    nothing (the path before); or a function ``how(height, mask, lost, heuristic)``
    returning the filled map (the other candidates of the study,
    ``pixgraph_lab.height.thin_study.FILLS``)."""
    if how == "none" or not lost.any():
        return height
    if callable(how):
        return how(height, mask, lost, heuristic)
    if how != "contact":
        raise ValueError(f"unknown thin fill {how!r}: 'contact', 'none' or a function")
    lr, lc = np.nonzero(lost)
    height[lr, lc] = heuristic[lr, lc]
    return height


def enlarge_prediction(out: dict, f: float, mask: np.ndarray, mask_small: np.ndarray, contact: str,
                       lift: float, pin_fade, foot_snap, thin_fill=None) -> dict:
    """``predict_full``'s result at the work size -> at full size (module doc), with
    ``thin_lost`` (bool, full size): the pixels with no work-size pixel of their own.

    ``mask`` / ``mask_small``: the cutout (alpha > threshold) at full and work
    size; ``lift`` [full-size px]; ``pin_fade``, ``foot_snap``: the predictor's;
    ``thin_fill``: ``fill_thin``'s ``how`` (None: ``THIN_FILL``)."""
    H, W = mask.shape
    res = dict(out)
    box = nonzero_box(mask)
    thin_fill = THIN_FILL if thin_fill is None else thin_fill
    heur = contact_line_height(mask).astype(np.float32)
    thin_lost = np.zeros((H, W), bool)

    def up(h_small):
        full = np.zeros((H, W), np.float32)
        if box is not None:
            r0, r1, c0, c1 = box
            part, lost = masked_resize(np.asarray(h_small, np.float32) * f, mask_small.astype(np.float32),
                                       mask, (H, W), box=box, return_lost=True)
            thin_lost[r0:r1, c0:c1] = lost
            if lost.any():                              # (on the box: rows are only compared)
                # the contact line of a cutout standing on the ground, raised by ``lift``
                # (contact: lifted) like the rest of the map: the pin that follows is a
                # fixed shift, it does not move a lost stick up to the hand that holds it
                part = fill_thin(part, mask[r0:r1, c0:c1], lost, heur[r0:r1, c0:c1] + np.float32(lift),
                                 thin_fill)
            full[r0:r1, c0:c1] = part
        full = np.where(mask, np.maximum(full, 0.0), 0.0).astype(np.float32)
        if contact != "free":
            full = pin_contact(full, mask, lift, fade=pin_fade)
            if contact == "ground" and foot_snap:
                full = snap_feet(full, mask, float(foot_snap["tol"]) * f, bool(foot_snap.get("hull", False)))
        return full

    res["height"] = up(out["height"])
    res["heuristic"] = pin_contact(heur, mask, lift) if contact != "free" else heur
    for k in ("est_mae_learned", "est_mae_heuristic"):
        if res.get(k) is not None:
            res[k] = float(res[k]) * f
    res["auto_height"] = res["height"] if out.get("use_learned", True) else res["heuristic"]
    res["work_scale"] = f
    res["thin_lost"] = thin_lost        # the pixels ``fill_thin`` filled
    return res


def predict_at_work_size(predictor, rgba: np.ndarray, threshold: float = 0.5, contact: str = "ground",
                         lift: float = 0.0, work_side: int = WORK_SIDE, signals: bool = False,
                         thin_fill: str | None = None) -> dict:
    """``predictor.predict_at_own_size(rgba, ...)`` (``LearnedHeightPredictor``), a
    cutout whose square crop is larger than ``work_side`` predicted at that size
    (module doc; ``work_scale`` and ``thin_lost`` in the result).

    The input is first cut to its covered pixels (alpha > 0) and the maps pasted
    back: a cutout delivered on a canvas much larger than itself (a matte at the
    photo's size) costs what the cutout costs and gets the same heights as the
    tight cutout (``_on_covered_box``). ``thin_fill``: ``fill_thin``'s ``how`` (None:
    ``THIN_FILL``)."""
    rgba = np.asarray(rgba, np.float32)
    return _on_covered_box(rgba, lambda part: _predict(predictor, part, threshold, contact, lift, work_side,
                                                       signals, thin_fill))


def covered_box(alpha: np.ndarray):
    """(r0, r1, c0, c1): the box of ``alpha > 0`` widened to start on an even row and
    column (``_on_covered_box``), or None when ``alpha`` is empty or the box is all of it."""
    H, W = alpha.shape[:2]
    box = nonzero_box(np.asarray(alpha) > 0)
    if box is None:
        return None
    r0, r1, c0, c1 = box
    r0, c0 = r0 - r0 % 2, c0 - c0 % 2
    return None if (r0, r1, c0, c1) == (0, H, 0, W) else (r0, r1, c0, c1)


def paste_maps(out: dict, box, shape) -> dict:
    """``out`` with its maps of the box's shape pasted into zeros of ``shape`` (H, W); a
    map under two keys (``auto_height`` is ``height`` where auto takes the learned map)
    stays one array."""
    r0, r1, c0, c1 = box
    done = {}
    for k, v in out.items():
        if isinstance(v, np.ndarray) and v.shape == (r1 - r0, c1 - c0):
            if id(v) not in done:                 # (v kept with it: its id stays its own)
                full = np.zeros(tuple(shape), v.dtype)
                full[r0:r1, c0:c1] = v
                done[id(v)] = (v, full)
            out[k] = done[id(v)][1]
    return out


def _on_covered_box(rgba: np.ndarray, fn) -> dict:
    """``fn(rgba cut to its covered box)`` with its full-size maps (the arrays of the
    cut's shape) pasted back into zeros of the input's size; the whole input when
    it is empty or already the box (``covered_box``, ``paste_maps``).

    The cut starts on an even row and column: ``crop_box`` centres the network's
    square crop with ``round``, which rounds halves to even, so a cut by an odd
    number of pixels could move that crop by one pixel, and the network is not
    blind to such a shift (one held-out 40 x 30 cutout: 1.5 vs 3.4 px MAE). Cut by
    even numbers, the path at the cutout's own size gives the whole input's
    numbers exactly."""
    box = covered_box(rgba[..., 3])
    if box is None:
        return fn(rgba)
    r0, r1, c0, c1 = box
    return paste_maps(fn(np.ascontiguousarray(rgba[r0:r1, c0:c1])), box, rgba.shape[:2])


def _predict(predictor, rgba, threshold, contact, lift, work_side, signals, thin_fill=None) -> dict:
    mask = np.clip(rgba[..., 3], 0.0, 1.0) > threshold
    box = crop_box(mask)
    f, shape = work_shape(*mask.shape, box[6], work_side) if box else (1.0, None)
    if f <= 1.0:
        return predictor.predict_at_own_size(rgba, threshold, contact, lift, signals)
    small = shrink_cutout(rgba, shape)
    mask_small = np.clip(small[..., 3], 0.0, 1.0) > threshold
    if not mask_small.any():
        # thinner than a work-size pixel everywhere (a 3-px leaning pole 4,000 px tall:
        # no shrunk pixel reaches the threshold): at the work size the cutout would be
        # empty, its map 0 and its confidence None, so it is predicted at its own size
        return predictor.predict_at_own_size(rgba, threshold, contact, lift, signals)
    lv = float(lift) if contact == "lifted" else 0.0
    out = predictor.predict_at_own_size(small, threshold, contact, lv / f, signals)
    return enlarge_prediction(out, f, mask, mask_small, contact, lv, predictor.pin_fade, predictor.foot_snap,
                              thin_fill)
