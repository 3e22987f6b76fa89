"""pixgraph.Merge: combine two images in linear light, premultiplied alpha."""
from __future__ import annotations

import numpy as np

from pixgraph_nodes import types as T
from pixgraph.node import Node, node, param, port


def to_rgba(image: np.ndarray) -> np.ndarray:
    """(H, W), (H, W, 1..4) -> (H, W, 4) premultiplied: grey spreads to RGB, missing alpha is 1."""
    img = np.asarray(image, np.float32)
    if img.ndim == 2:
        img = img[:, :, None]
    h, w, c = img.shape
    ones = np.ones((h, w, 1), np.float32)
    if c == 1:
        return np.concatenate([img, img, img, ones], axis=2)
    if c == 2:
        return np.concatenate([img[:, :, :1]] * 3 + [img[:, :, 1:]], axis=2)
    if c == 3:
        return np.concatenate([img, ones], axis=2)
    return img


def merge(a: np.ndarray, b: np.ndarray, mode: str, opacity: float) -> np.ndarray:
    """A onto B, premultiplied RGBA (H, W, 4) out.

    over: ``A + B (1 - A_alpha)``; add: ``A + B``; multiply: ``A B``; mix: ``A``.
    The result is then faded towards B: ``B + opacity (result - B)``.
    """
    a, b = to_rgba(a), to_rgba(b)
    if a.shape != b.shape:
        raise ValueError(f"A is {a.shape[1]}x{a.shape[0]} but B is {b.shape[1]}x{b.shape[0]} pixels")
    if mode == "over":
        out = a + b * (1.0 - a[:, :, 3:4])
    elif mode == "add":
        out = a + b
    elif mode == "multiply":
        out = a * b
    elif mode == "mix":
        out = a
    else:
        raise ValueError(f"unknown merge mode {mode!r}")
    return (b + np.float32(opacity) * (out - b)).astype(np.float32)


@node("pixgraph.Merge", version=1)
class Merge(Node):
    """Combine A onto B (over, add, multiply or mix), faded by opacity."""

    class Inputs:
        a: T.Image = port(doc="foreground / first operand")
        b: T.Image = port(doc="background / second operand")

    class Params:
        mode: str = param("over", choices=["over", "add", "multiply", "mix"], doc="how A combines with B")
        opacity: float = param(1.0, min=0.0, max=1.0, doc="0 gives B, 1 the full operation")

    class Outputs:
        image: T.Image = port(doc="(H, W, 4) premultiplied RGBA")

    impl_version = "1"

    def compute(self, ctx, inputs, params):
        return {"image": merge(inputs.a, inputs.b, params.mode, params.opacity)}
