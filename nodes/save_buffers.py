"""pixgraph.SaveBuffers: write named channels (e.g. the SSN++ buffers) to one EXR."""
from __future__ import annotations

from pathlib import Path
import pathlib

from pixgraph_nodes import types as T
from pixgraph.node import InputError, Node, node, param, port

from .ops.imageio import write_exr_channels


@node("pixgraph.SaveBuffers", version=1)
class SaveBuffers(Node):
    """Write every channel of a Buffers value to one multichannel float EXR, named as
    in the value, in its order."""

    class Inputs:
        buffers: T.Buffers = port(doc="named float32 (H, W) channels")

    class Params:
        path: Path = param(None, writes=True, doc="output .exr (relative to the graph file)")
        half: bool = param(False, doc="store 16-bit half floats instead of 32-bit")

    class Outputs:
        path: T.Any = port(doc="the path written (str)")

    side_effects = True
    impl_version = "1"

    def compute(self, ctx, inputs, params):
        p = params.path  # a pixgraph.paths.WritePath: the writer creates folders without following symlinks
        if not pathlib.Path(p).is_absolute() and getattr(ctx, "graph_dir", None):
            p = str(pathlib.Path(ctx.graph_dir) / p)
        if pathlib.Path(p).suffix.lower() != ".exr":
            raise InputError(f"SaveBuffers writes OpenEXR; {p} does not end in .exr")
        return {"path": write_exr_channels(p, dict(inputs.buffers), 16 if params.half else 32)}
