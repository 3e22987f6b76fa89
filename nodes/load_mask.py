"""pixgraph.LoadMask: a cutout's mask (matte) from its own file (PNG, TIFF, EXR or .npy)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from pixgraph_nodes import types as T
from pixgraph.node import InputError, Node, node, param, port
from pixgraph_nodes.types import Shape

from ._checks import file_shape, npy_finite, source

from .ops.imageio import host_pixels, read_mask
from .ops.resample import at_scale


@node("pixgraph.LoadMask", version=1)
class LoadMask(Node):
    """Read a mask: PNG/TIFF/EXR (the alpha channel if the file has one, else its
    first channel, as stored: a matte is never sRGB-decoded) or ``.npy`` (the
    PixHt-Lab authors' format; bool, 0..1 or 0..255). Connect it to
    pixgraph.PlaceCutout's ``mask`` to cut out an image without alpha (a JPEG)."""

    class Params:
        path: Path = param(None, doc="mask file: .png, .tif, .exr or .npy (relative to the graph file)")

    class Outputs:
        mask: T.Mask = port(doc="float32 (H, W) coverage in [0, 1]")

    impl_version = "1"
    disk_cache = False      # the file is its own cache
    uses_scale = True       # read at the run's working resolution (ctx.scale)

    def bind(self, value, params):
        return {"mask": np.clip(host_pixels(value, (1,), "a mask")[:, :, 0], 0.0, 1.0)}

    def infer(self, ctx, inputs, params):
        shape = file_shape(params.path, ctx.node_id)
        npy_finite(params.path, f"{shape.source}: mask has NaN or infinite values")
        return {"mask": Shape(shape.height, shape.width, 1, shape.source)}

    def compute(self, ctx, inputs, params):
        try:
            mask = read_mask(params.path)
            return {"mask": mask if ctx.scale == 1.0 else np.clip(at_scale(mask, ctx.scale), 0.0, 1.0)}
        except (OSError, ValueError) as e:
            raise InputError(f"{source(params.path, ctx.node_id)}: {str(e).splitlines()[0]}") from None
