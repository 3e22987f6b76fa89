"""A candidate that did not ship: the learned pixel height of a large cutout
predicted at the size the predictor was validated at (docs/height.md, "Rules
fixed before measuring: large cutouts" and "Measured: auto's blend and large
cutouts"; compared with the shipped path by ``scale_study``).

Everything in ``LearnedHeightPredictor.predict_full`` beyond the network (the
contact pin, the foot snap's tolerance, the confidence signals and their
thresholds) was chosen on 256 x 256 renders, and several of those are in
pixels. The candidate shrinks a cutout whose square crop is larger than
``WORK_SIDE`` by ``f = side / WORK_SIDE`` (antialiased bilinear on the linear
premultiplied RGBA, ``resample.shrink_part``), predicts there, and brings the
map back to full size:

* heights are vertical lengths, so they scale by ``f``;
* the map is enlarged inside the outline only (``upsample.masked_resize``: a
  full-size pixel interpolates the work-size pixels on its own side of the
  cutout's outline), then the contact is pinned again on the full-size mask
  (``pin_contact``, lift in full-size px) and the foot snap runs with its
  tolerance x ``f``;
* the contact line (``heuristic``) is computed at full size, pinned the same way;
* the confidence, signal and auto's choice are the work size's; ``est_mae_*``
  are scaled by ``f`` into full-size px.

On validation enlarged 4x and 8x its heights were 0.3-0.8 % worse than the
shipped path's (the ship rule asked for no worse), though 2.1x faster at 8x
(median 142 vs 302 ms) and with a confidence signal that does not grow with the
cutout's pixel size.
"""
from __future__ import annotations

import numpy as np

from pixgraph_nodes.ops.heightmaps import contact_line_height
from pixgraph_nodes.ops.learned_height import crop_box, pin_contact, snap_feet
from pixgraph_nodes.ops.resample import nonzero_box, shrink_part
from pixgraph_nodes.ops.upsample import masked_resize

#: the largest square crop [px] the predictor runs at: the validation renders are
#: 256 x 256 (crop sides 74-245 px, 5th-95th percentile)
WORK_SIDE = 256


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


def enlarge_prediction(out: dict, f: float, mask: np.ndarray, mask_small: np.ndarray, contact: str,
                       lift: float, pin_fade, foot_snap) -> dict:
    """``predict_full``'s result at the work size -> at full size (module doc).

    ``mask`` / ``mask_small``: the cutout (alpha > threshold) at full and work
    size; ``lift`` [full-size px]; ``pin_fade``, ``foot_snap``: the predictor's."""
    H, W = mask.shape
    res = dict(out)
    box = nonzero_box(mask)

    def up(h_small):
        full = np.zeros((H, W), np.float32)
        if box is not None:
            r0, r1, c0, c1 = box
            part = masked_resize(np.asarray(h_small, np.float32) * f, mask_small.astype(np.float32),
                                 mask, (H, W), box=box)
            full[r0:r1, c0:c1] = part
        full = np.where(mask, np.maximum(full, 0.0), 0.0).astype(np.float32)
        if contact != "free":
            full = pin_contact(full, mask, lift, fade=pin_fade)
            if contact == "ground" and foot_snap:
                full = snap_feet(full, mask, float(foot_snap["tol"]) * f, bool(foot_snap.get("hull", False)))
        return full

    res["height"] = up(out["height"])
    heur = contact_line_height(mask).astype(np.float32)
    res["heuristic"] = pin_contact(heur, mask, lift) if contact != "free" else heur
    for k in ("est_mae_learned", "est_mae_heuristic"):
        if res.get(k) is not None:
            res[k] = float(res[k]) * f
    res["auto_height"] = res["height"] if out.get("use_learned", True) else res["heuristic"]
    res["work_scale"] = f
    return res


def predict_at_work_size(predictor, rgba: np.ndarray, threshold: float = 0.5, contact: str = "ground",
                         lift: float = 0.0, work_side: int = WORK_SIDE) -> dict:
    """``predictor.predict_full(rgba, ...)``, a cutout larger than ``work_side``
    predicted at that size (module doc; ``work_scale`` in the result)."""
    rgba = np.asarray(rgba, np.float32)
    mask = np.clip(rgba[..., 3], 0.0, 1.0) > threshold
    box = crop_box(mask)
    f, shape = work_shape(*mask.shape, box[6], work_side) if box else (1.0, None)
    if f <= 1.0:
        return predictor.predict_full(rgba, threshold, contact, lift)
    small = shrink_cutout(rgba, shape)
    lv = float(lift) if contact == "lifted" else 0.0
    out = predictor.predict_full(small, threshold, contact, lv / f)
    mask_small = np.clip(small[..., 3], 0.0, 1.0) > threshold
    return enlarge_prediction(out, f, mask, mask_small, contact, lv, predictor.pin_fade, predictor.foot_snap)
