"""A test-only node pack for the engine tests (namespace ``t``).

``make_registry(calls)`` builds a fresh Registry whose nodes append their node id
to ``calls`` each time they compute, so tests can count what ran.
"""
from __future__ import annotations

import dataclasses
import pathlib
import time

import numpy as np

from pixgraph import types as _engine_types
from pixgraph.node import node, param, port
from pixgraph.registry import Registry


class T:
    """The engine tests' own port types (the engine knows no images: the node
    pack's live in ``pixgraph_nodes.types``)."""

    Any = _engine_types.Any
    Scalar = _engine_types.Scalar

    class Image(_engine_types.PortType):
        """float32 (H, W[, C]) array."""

        describe = "test image"
        sized = True
        finite = True

        @classmethod
        def validate(cls, value):
            _engine_types.check_array(value, (2, 3), "Image")

        @classmethod
        def write(cls, path, value):
            """The array in numpy's .npy format, whatever the file's extension."""
            cls.validate(value)
            with open(path, "wb") as f:
                np.save(f, value)
            return path

    class Mask(Image):
        """float32 (H, W): an Image with one channel (feeds Image inputs, not the reverse)."""

        describe = "test mask"

        @classmethod
        def validate(cls, value):
            _engine_types.check_array(value, (2,), "Mask")


@dataclasses.dataclass(frozen=True)
class Pose:
    """A frozen dataclass value, like Camera/Light, to test disk storage."""
    azimuth: float
    elevation: float
    weights: np.ndarray


def make_nodes(calls: list):
    @node("t.Source", version=1)
    class Source:
        """A constant (size, size) image."""
        class Params:
            value: float = param(1.0, min=-1000.0, max=1000.0, doc="pixel value")
            size: int = param(4, min=1, max=4096, unit="px", doc="side length")
            label: str = param("a", choices=["a", "b", "c"], doc="unused choice")
            chatty: bool = param(False, cache=False, doc="does not change the result")
        class Outputs:
            out: T.Image = port(doc="constant image")

        def compute(self, ctx, inputs, params):
            calls.append(ctx.node_id)
            return {"out": np.full((params.size, params.size), params.value, np.float32)}

    @node("t.Add", version=1)
    class Add:
        """a + b + k."""
        class Inputs:
            a: T.Image = port(doc="first")
            b: T.Image = port(optional=True, doc="second (optional)")
        class Params:
            k: float = param(0.0, min=-1000.0, max=1000.0, doc="constant added")
        class Outputs:
            out: T.Image = port(doc="sum")

        def compute(self, ctx, inputs, params):
            calls.append(ctx.node_id)
            b = inputs.b if inputs.b is not None else 0.0
            return {"out": (inputs.a + b + params.k).astype(np.float32)}

    @node("t.Scale", version=2)
    class Scale:
        """x * factor; also outputs the mean as a Scalar."""
        class Inputs:
            x: T.Image = port(doc="input")
        class Params:
            factor: float = param(1.0, min=0.0, max=100.0, doc="multiplier")
        class Outputs:
            out: T.Image = port(doc="scaled")
            mean: T.Scalar = port(doc="mean of the result")
        impl_version = "3"

        def compute(self, ctx, inputs, params):
            calls.append(ctx.node_id)
            out = (inputs.x * params.factor).astype(np.float32)
            return {"out": out, "mean": float(out.mean())}

    @node("t.ToMask", version=1)
    class ToMask:
        """First channel as a Mask."""
        class Inputs:
            x: T.Image = port()
        class Outputs:
            mask: T.Mask = port()

        def compute(self, ctx, inputs, params):
            calls.append(ctx.node_id)
            x = inputs.x
            return {"mask": np.clip(x if x.ndim == 2 else x[..., 0], 0, 1).astype(np.float32)}

    @node("t.NeedsMask", version=1)
    class NeedsMask:
        """Only takes a Mask."""
        class Inputs:
            m: T.Mask = port()
        class Outputs:
            out: T.Mask = port()

        def compute(self, ctx, inputs, params):
            calls.append(ctx.node_id)
            return {"out": inputs.m}

    @node("t.FileLen", version=1)
    class FileLen:
        """Byte length of a file, as a (1, 1) image."""
        class Params:
            path: pathlib.Path = param(None, doc="file to measure")
        class Outputs:
            out: T.Image = port()

        def compute(self, ctx, inputs, params):
            calls.append(ctx.node_id)
            return {"out": np.full((1, 1), len(pathlib.Path(params.path).read_bytes()), np.float32)}

    @node("t.MakePose", version=1)
    class MakePose:
        """A frozen dataclass output."""
        class Params:
            azimuth: float = param(30.0, doc="deg")
        class Outputs:
            pose: T.Any = port()

        def compute(self, ctx, inputs, params):
            calls.append(ctx.node_id)
            return {"pose": Pose(params.azimuth, 45.0, np.arange(3, dtype=np.float32))}

    @node("t.Opaque", version=1)
    class Opaque:
        """An output that cannot be stored on disk (a lambda)."""
        class Outputs:
            fn: T.Any = port()

        def compute(self, ctx, inputs, params):
            calls.append(ctx.node_id)
            return {"fn": lambda x: x}

    @node("t.WrongType", version=1)
    class WrongType:
        """Declares an Image but returns a list."""
        class Outputs:
            out: T.Image = port()

        def compute(self, ctx, inputs, params):
            calls.append(ctx.node_id)
            return {"out": [1, 2, 3]}

    @node("t.Boom", version=1)
    class Boom:
        """Always raises."""
        class Inputs:
            x: T.Image = port(optional=True)
        class Outputs:
            out: T.Image = port()

        def compute(self, ctx, inputs, params):
            calls.append(ctx.node_id)
            raise ZeroDivisionError("kaboom")

    @node("t.Slow", version=1)
    class Slow:
        """Reports progress in steps and checks for cancellation between them."""
        class Inputs:
            x: T.Image = port()
        class Params:
            steps: int = param(4, min=1, max=1000)
            delay: float = param(0.0, min=0.0, max=10.0, unit="s", cache=False)
        class Outputs:
            out: T.Image = port()

        def compute(self, ctx, inputs, params):
            calls.append(ctx.node_id)
            for i in range(params.steps):
                ctx.check_cancelled()
                time.sleep(params.delay)
                ctx.progress((i + 1) / params.steps, f"step {i + 1}")
            return {"out": inputs.x}

    @node("t.Touch", version=1)
    class Touch:
        """A sink: writes the sum of its input to a text file."""
        class Inputs:
            x: T.Image = port()
        class Params:
            path: pathlib.Path = param(None, writes=True, doc="file written")
        class Outputs:
            path: T.Any = port(doc="the path written")
        side_effects = True

        def compute(self, ctx, inputs, params):
            calls.append(ctx.node_id)
            pathlib.Path(params.path).write_text(str(float(inputs.x.sum())))
            return {"path": params.path}

    @node("t.UsesDevice", version=1)
    class UsesDevice:
        """Touches ctx.device."""
        class Outputs:
            name: T.Any = port()

        def compute(self, ctx, inputs, params):
            calls.append(ctx.node_id)
            return {"name": ctx.device.name}

    @node("t.Where", version=1)
    class Where:
        """Logs, and outputs the folder relative paths resolve against."""
        class Outputs:
            folder: T.Any = port()

        def compute(self, ctx, inputs, params):
            calls.append(ctx.node_id)
            ctx.log(f"resolving against {ctx.graph_dir}")
            return {"folder": ctx.graph_dir}

    return [Where, Source, Add, Scale, ToMask, NeedsMask, FileLen, MakePose, Opaque, WrongType, Boom, Slow,
            Touch, UsesDevice]


def make_registry(calls: list | None = None) -> Registry:
    reg = Registry()
    for cls in make_nodes(calls if calls is not None else []):
        reg.add(cls, source="tests.engine_testnodes")
    return reg
