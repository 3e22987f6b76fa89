"""pixgraph.LoadPixelHeight: a pixel-height map from a file (npy, EXR, 16-bit PNG)."""
from __future__ import annotations

import pathlib
from pathlib import Path

import numpy as np

from pixgraph_nodes import types as T
from pixgraph.node import InputError, Node, node, param, port
from pixgraph_nodes.types import Shape

from ._checks import file_shape, npy_finite
from .ops.heightmaps import load_pixel_height
from .ops.resample import at_scale


@node("pixgraph.LoadPixelHeight", version=1)
class LoadPixelHeight(Node):
    """Read a cutout or background pixel-height map from a file.

    .npy and float EXR/TIFF hold pixels (times ``scale``); 8/16-bit PNG/TIFF hold a
    value normalised to [0, 1] times ``scale`` (the height of full white, pixels).
    """

    class Params:
        path: Path = param(None, doc="file: .npy, .exr, .tif or .png (relative to the graph file)")
        scale: float = param(1.0, min=0.0, doc="multiplier to pixels (for PNG: height of full white)")

    class Outputs:
        height: T.PixelHeight = port(doc="pixel height [px]")

    impl_version = "1"
    disk_cache = False      # the file is its own cache
    uses_scale = True       # read at the run's working resolution, heights in its pixels

    def bind(self, value, params):
        """A host's (H, W) float array in pixels instead of the file (times ``scale``)."""
        from .input_pixel_height import InputPixelHeight

        h = InputPixelHeight().bind(value, params)["height"]
        return {"height": h * params.scale if params.scale != 1.0 else h}

    def infer(self, ctx, inputs, params):
        shape = file_shape(params.path, ctx.node_id)
        npy_finite(params.path, f"param 'path': {shape.source}: pixel height has non-finite values")
        return {"height": Shape(shape.height, shape.width, 1, shape.source)}

    def compute(self, ctx, inputs, params):
        p = pathlib.Path(params.path)
        if not p.is_absolute() and getattr(ctx, "graph_dir", None):
            p = pathlib.Path(ctx.graph_dir) / p
        try:
            height = load_pixel_height(p, params.scale)
        except (OSError, ValueError) as e:  # the file's content is the user's data
            raise InputError(f"param 'path': {str(e).splitlines()[0]}") from None
        if not np.all(np.isfinite(height)):
            raise InputError(f"param 'scale': {params.scale} times the file's heights overflows float32")
        if ctx.scale != 1.0:   # a vertical length: in pixels of the scaled image
            small = at_scale(height, ctx.scale)
            height = (small * np.float32(small.shape[0] / height.shape[0])).astype(np.float32)
        return {"height": height}
