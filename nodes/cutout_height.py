"""pixgraph.CutoutHeight: cutout pixel height from the contact-line heuristic or a
learned predictor."""
from __future__ import annotations

import functools
import hashlib
import pathlib

import numpy as np

from pixgraph_nodes import types as T
from pixgraph.node import InputError, Node, node, param, port

from ._checks import same_size
from .ops.heightmaps import ContactLinePredictor

@functools.lru_cache(maxsize=2)
def _learned(path: str, mtime_ns: int, npz_mtime_ns: int):
    # keyed on the files' mtimes too, so retrained weights are picked up without a restart
    from .ops.learned_height import LearnedHeightPredictor
    return LearnedHeightPredictor(path)


def learned_predictor():
    """The shipped learned predictor (``weights/cutout_height.pt``, its network run in
    numpy from ``cutout_height.npz`` unless ``learned_height.choose_backend`` picks
    torch), loaded once."""
    from .ops.learned_height import WEIGHTS
    npz = WEIGHTS.with_suffix(".npz")
    if not WEIGHTS.exists() and not npz.exists():
        raise FileNotFoundError(f"no shipped cutout-height weights {WEIGHTS}")
    mt = [p.stat().st_mtime_ns if p.exists() else 0 for p in (WEIGHTS, npz)]
    return _learned(str(WEIGHTS), *mt)


def cutout_rgba(mask: np.ndarray, image: np.ndarray) -> np.ndarray:
    """Premultiplied (H, W, 4) of the cutout: the image's straight colour (its own
    alpha divided out when it has one) with ``mask`` as alpha."""
    img = np.asarray(image, np.float32)
    if img.ndim == 2:
        img = img[..., None]
    rgb = img[..., :3] if img.shape[2] >= 3 else np.repeat(img[..., :1], 3, axis=2)
    if img.shape[2] in (2, 4):
        a = img[..., -1:]
        rgb = np.where(a > 0, rgb / np.maximum(a, 1e-6), 0.0)
    m = np.clip(np.asarray(mask, np.float32), 0, 1)
    return np.concatenate([rgb * m[..., None], m[..., None]], axis=2).astype(np.float32)


def predict_on_covered_box(predictor, mask: np.ndarray, image: np.ndarray, **kw) -> dict:
    """``predictor.predict_full(cutout_rgba(mask, image), **kw)``, the RGBA made for the
    mask's covered box only (``height_work_size.covered_box``, the cut the predictor
    makes itself: the same heights, bit for bit) and the maps pasted back: a matte at
    a photo's size costs what its cutout costs (a 400-px object on a 20 MP canvas:
    0.6 s -> 0.05 s, most of it was ``cutout_rgba`` of the whole canvas)."""
    from .ops.height_work_size import covered_box, paste_maps
    box = covered_box(mask)
    if box is None:
        return predictor.predict_full(cutout_rgba(mask, image), **kw)
    r0, r1, c0, c1 = box
    part = predictor.predict_full(cutout_rgba(mask[r0:r1, c0:c1], np.asarray(image)[r0:r1, c0:c1]), **kw)
    return paste_maps(part, box, mask.shape)


def _weights_version() -> str:
    """What the learned method's result depends on besides its inputs: the shipped
    weights' digest (the .npz the numpy network reads is exported from the .pt and
    refuses to load when it is not that .pt's: ``height_net.load_npz``; the numpy and
    torch networks agree to float rounding, tests/test_height_net.py)."""
    path = pathlib.Path(__file__).parent / "weights" / "cutout_height.pt"
    return hashlib.sha256(path.read_bytes()).hexdigest()[:12] if path.exists() else "no-weights"


@node("pixgraph.CutoutHeight", version=1)
class CutoutHeight(Node):
    """Pixel height of a cutout standing on the ground. ``contact_line`` (default, alpha
    only): distance in rows to one line fitted to the object's lowest pixels, right for
    upright objects; ``column_bottom``: to each column's lowest pixel (see
    pixgraph_nodes.ops.heightmaps.contact_line_height); ``learned``: a small U-Net
    trained on rendered cutouts (people, animals, figurines, furniture, products,
    vehicles, random shapes) reads the colour (``image``) and alpha, any size (a cutout
    larger than 512 px is predicted at 512 px and its map enlarged: ops/height_work_size.py)
    (pixgraph_nodes.ops.learned_height; the network runs in numpy, no torch needed:
    ops/height_net.py); ``auto``: the learned height unless the checkpoint's confidence
    rule (a per-cutout signal and threshold chosen on validation) says the contact
    line is likely better, then the contact line (docs/height.md, "The contact,
    confidence and auto"). The contact is a constraint: for
    ``learned`` and ``auto`` the cutout's lowest pixels are pinned to height 0
    (``contact: ground``) or to ``lift`` px (``contact: lifted``, an object that does not
    touch the ground: a held object, a hanging lamp); the heuristics are 0 there by
    construction and get ``lift`` added. Output ``confidence``: the estimated chance
    (0-1) that the learned map is better than the contact line (its win rate at this
    cutout's signal on renders of kinds it was never trained on: about 0.6 for any
    cutout), NaN when the network was not run. A
    file-based height map comes from pixgraph.LoadPixelHeight instead.
    """

    class Inputs:
        mask: T.Mask = port(doc="cutout coverage")
        image: T.Image = port(optional=True, doc="cutout colour (linear, premultiplied when it has "
                                                 "alpha), same size as mask; needed by method learned")

    class Params:
        method: str = param("contact_line", choices=("contact_line", "column_bottom", "learned", "auto"),
                            doc="contact_line / column_bottom: where each column's foot is; "
                                "learned: the trained predictor; auto: learned unless its confidence "
                                "rule says contact_line is likely better")
        contact: str = param("ground", choices=("ground", "lifted"),
                             doc="ground: the cutout's lowest pixels touch the ground (height 0); "
                                 "lifted: they are lift px above it (the object does not touch the ground)")
        lift: float = param(0.0, min=0.0, unit="px",
                            doc="contact lifted: pixel height of the cutout's lowest pixels")
        tolerance: float = param(2.0, min=0.0, unit="px",
                                 doc="contact_line: columns whose bottom is this close to the lowest "
                                     "row take part in the fit")

    class Outputs:
        height: T.PixelHeight = port(doc="cutout pixel height [px], 0 outside the mask")
        confidence: T.Scalar = port(doc="learned / auto: the estimated chance (0-1) that the learned height "
                                        "beats the contact line; NaN when the network did not run")

    impl_version = "8+" + _weights_version()  # 2: method learned; 3: auto, contact, confidence; 4: foot snap,
    # confidence rule; 5: auto's fallback pins the contact line's contact like the learned map's; 6: a cutout
    # whose crop is larger than 512 px is predicted at 512 px, the confidence signals in 256-px units; 7: one
    # thinner than a 512-px work pixel everywhere is predicted at its own size (it was 0 everywhere); 8: a thin
    # part of a large cutout (no work-size pixel of its own) takes the contact line's height (it was about 0)

    def compute(self, ctx, inputs, params):
        mask = np.asarray(inputs.mask, dtype=np.float32)
        lift = float(params.lift) if params.contact == "lifted" else 0.0
        if params.method in ("learned", "auto"):
            if inputs.image is None:
                raise InputError(f"method '{params.method}' reads the cutout's colour: connect input 'image' "
                                 "(e.g. image: cutout.image)")
            same_size(mask=mask, image=inputs.image)
            predictor = learned_predictor()
            r = predict_on_covered_box(predictor, mask, inputs.image, contact=params.contact, lift=lift)
            conf = r["confidence"]
            if conf is None:
                conf = float("nan")
                if params.method == "auto":
                    ctx.log("auto: the shipped weights have no confidence heads; using the learned height")
            # auto's choice: the checkpoint's confidence rule (predict_full), else confidence >= 0.5
            use = r.get("use_learned", not conf < 0.5)
            if params.method == "learned" or use:
                ctx.log(f"{params.method}: learned height (confidence {conf:.2f})")
                return {"height": r["height"], "confidence": float(conf)}
            why = (f"signal {r['signal']:.3g} above the threshold chosen on validation" if "signal" in r
                   else f"confidence {conf:.2f} < 0.5")
            ctx.log(f"auto: contact line ({why}; the learned map beat it on {conf:.0%} of similar "
                    "validation cutouts)" if "signal" in r else f"auto: contact line ({why})")
            # the contact line under the same contact constraint as the learned map (what
            # the studies measured as auto): its contact pixels pinned to the ground (or lift)
            from pixgraph_nodes.ops.learned_height import pin_contact
            h = self._heuristic(mask, "contact_line", params.tolerance)
            return {"height": pin_contact(h, mask > 0.5, lift), "confidence": float(conf)}
        h = self._heuristic(mask, params.method, params.tolerance)
        return {"height": self._lift(h, mask, lift), "confidence": float("nan")}

    @staticmethod
    def _heuristic(mask, method, tolerance):
        rgba = np.zeros(mask.shape + (4,), np.float32)
        rgba[..., 3] = mask
        return ContactLinePredictor(method, tolerance).predict(rgba)

    @staticmethod
    def _lift(h, mask, lift):
        if lift == 0.0:
            return h
        return np.where(mask > 0.5, h + np.float32(lift), 0.0).astype(np.float32)
