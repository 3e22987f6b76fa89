"""pixgraph.CutoutHeight: cutout pixel height from the contact-line heuristic or a
learned predictor."""
from __future__ import annotations

import functools
import hashlib
import importlib.util
import pathlib

import numpy as np

from pixgraph_nodes import types as T
from pixgraph.node import InputError, Node, node, param, port

from ._checks import same_size
from .ops.heightmaps import ContactLinePredictor

NO_TORCH = ("method 'learned' needs torch, which is not installed (pip install torch); "
            "using the contact-line heuristic instead")


@functools.lru_cache(maxsize=2)
def _learned(path: str, mtime_ns: int):
    # keyed on mtime too, so retrained weights are picked up without a restart
    from .ops.learned_height import LearnedHeightPredictor
    return LearnedHeightPredictor(path)


def learned_predictor():
    """The shipped learned predictor (``weights/cutout_height.pt``), loaded once;
    None when torch is missing."""
    try:
        import torch  # noqa: F401
    except ImportError:
        return None
    from .ops.learned_height import WEIGHTS
    if not WEIGHTS.exists():
        raise FileNotFoundError(f"no shipped cutout-height weights {WEIGHTS}")
    return _learned(str(WEIGHTS), WEIGHTS.stat().st_mtime_ns)


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


def _weights_version() -> str:
    """What the learned method's result depends on besides its inputs: the shipped
    weights' digest, or that torch is missing (then it falls back to the contact line,
    and that result must not be served later as a learned one)."""
    if importlib.util.find_spec("torch") is None:
        return "no-torch"
    path = pathlib.Path(__file__).parent / "weights" / "cutout_height.pt"
    return hashlib.sha256(path.read_bytes()).hexdigest()[:12] if path.exists() else "no-weights"


@node("pixgraph.CutoutHeight", version=1)
class CutoutHeight(Node):
    """Pixel height of a cutout standing on the ground. ``contact_line`` (default, alpha
    only): distance in rows to one line fitted to the object's lowest pixels, right for
    upright objects; ``column_bottom``: to each column's lowest pixel (see
    pixgraph_nodes.ops.heightmaps.contact_line_height); ``learned``: a small U-Net
    trained on rendered cutouts (upright, tilted, lying, overhanging objects) reads the
    colour (``image``) and alpha, any size (pixgraph_nodes.ops.learned_height; needs
    torch, else falls back to contact_line with a log message). A file-based height map
    comes from pixgraph.LoadPixelHeight instead.
    """

    class Inputs:
        mask: T.Mask = port(doc="cutout coverage")
        image: T.Image = port(optional=True, doc="cutout colour (linear, premultiplied when it has "
                                                 "alpha), same size as mask; needed by method learned")

    class Params:
        method: str = param("contact_line", choices=("contact_line", "column_bottom", "learned"),
                            doc="contact_line / column_bottom: where each column's foot is; "
                                "learned: the trained predictor")
        tolerance: float = param(2.0, min=0.0, unit="px",
                                 doc="contact_line: columns whose bottom is this close to the lowest "
                                     "row take part in the fit")

    class Outputs:
        height: T.PixelHeight = port(doc="cutout pixel height [px], 0 outside the mask")

    impl_version = "2+" + _weights_version()  # 2: method learned

    def compute(self, ctx, inputs, params):
        mask = np.asarray(inputs.mask, dtype=np.float32)
        if params.method == "learned":
            if inputs.image is None:
                raise InputError("method 'learned' reads the cutout's colour: connect input 'image' "
                                 "(e.g. image: cutout.image)")
            same_size(mask=mask, image=inputs.image)
            predictor = learned_predictor()
            if predictor is not None:
                return {"height": predictor.predict(cutout_rgba(mask, inputs.image))}
            ctx.log(NO_TORCH)
            predictor = ContactLinePredictor("contact_line", params.tolerance)
        else:
            predictor = ContactLinePredictor(params.method, params.tolerance)
        rgba = np.zeros(mask.shape + (4,), np.float32)
        rgba[..., 3] = mask
        return {"height": predictor.predict(rgba)}
