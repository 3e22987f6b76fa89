"""pixgraph.SoftShadowSSN: SSN++, the neural soft-shadow renderer (PixHt-Lab Sec. 3.2)."""
from __future__ import annotations

import functools
import pathlib

import numpy as np

from pixgraph_nodes import types as T
from pixgraph.node import InputError, Node, node, param, port

from ._checks import finite_outputs, inside
from ._shadow_ports import SOFT_PREVIEW, ShadowInputs, ShadowOutputs, check_inputs, thickness_param
from .ops.lights import disk_extremes, light_point

WEIGHTS = pathlib.Path(__file__).parent / "weights"


def _ssn():
    """``ops.ssn``, imported when SSN++ first runs: it needs torch (the ``ssn`` extra),
    which a graph without this node never loads."""
    try:
        from .ops import ssn
    except ModuleNotFoundError as e:
        if e.name != "torch":
            raise
        raise ModuleNotFoundError("pixgraph.SoftShadowSSN needs torch: pip install 'pixgraph[ssn]'",
                                  name="torch") from None
    return ssn


@functools.lru_cache(maxsize=4)
def _load(path: str, mtime_ns: int):
    # keyed on mtime too, so retrained weights are picked up without a restart
    return _ssn().load_model(path)


def load_shipped(name: str):
    """The shipped model ``name`` (``weights/<name>.pt``), loaded once per process."""
    path = WEIGHTS / f"{name}.pt"
    if not path.exists():
        raise FileNotFoundError(f"no shipped SSN++ weights {path.name} in {WEIGHTS}")
    return _load(str(path), path.stat().st_mtime_ns)


def torch_settings():
    """(threads, device) SSN++ runs with: ``ssn.inference_threads()`` and
    ``ssn.inference_device()`` (the host's PIXGRAPH_TORCH_THREADS and
    PIXGRAPH_TORCH_DEVICE); a bad setting is an input error naming the variable."""
    ssn = _ssn()
    try:
        return ssn.inference_threads(), ssn.inference_device()
    except ValueError as e:  # the host's setting, not the node's fault
        raise InputError(str(e)) from None


@node("pixgraph.SoftShadowSSN", version=1)
class SoftShadowSSN(Node):
    """Soft shadow from SSN++: the 3D-aware buffer channels (cutout pixel height,
    background gradient, hard and sparse hard shadows, relative distance) and the
    light's softness run through a small trained U-Net (on CUDA when torch has it, else the CPU). Same ports as
    pixgraph.SoftShadow; its cost does not grow with the light's size.

    All inputs share the camera's size; pixel heights must be finite and >= 0
    (the cutout's inside its mask), else the node stops with an input error. An
    empty mask casts no shadow (darkness 0). Torch runs with
    ``PIXGRAPH_TORCH_THREADS`` intra-op threads (default: 1 per 4 CPUs, 1 to
    4), restored afterwards, on the device ``PIXGRAPH_TORCH_DEVICE`` names (auto,
    cpu, cuda, cuda:N; default auto: CUDA when torch has it). Progress is reported after the buffer channels
    (banded, cancellable) and after the network.

    Any image size: the network runs on a window around the cutout and its shadow,
    at the scale it was trained for, and the result is pasted back edge-aware
    (darkness 0 outside the window). A light softer or harder than the training
    data's (radius / distance outside 0.015-0.45) is clamped, with a warning in
    the run's log (docs/ssn.md)."""

    class Inputs(ShadowInputs):
        light: T.Light = port(doc="the disk light; radius over distance to the object is the softness")

    class Params:
        model: str = param("ssnpp", choices=("ssnpp",), doc="shipped weights to use")
        # not unit "px": the window is at the trained scale whatever the run's working resolution
        thickness: float = thickness_param(doc="occluder thickness of the buffer channels' hard shadows, "
                                            "in pixels of the network's window (the trained scale)",
                                           unit="window px")

    class Outputs(ShadowOutputs):
        """The shared two (``_shadow_ports.ShadowOutputs``)."""

    # bump when the shipped weights or the inference change (2: NHWC layout; 3: softness clamped to 1;
    # 4: window at the trained scale, softness clamped to the trained range; 5: v2 weights;
    # 6: v3 weights)
    impl_version = "6"
    #: a cheaper node type with the same ports that stands in for this one in previews
    preview = SOFT_PREVIEW
    #: ... told that this node's thickness is in pixels of SSN++'s window (the stand-in,
    #: pixgraph.PreviewShadow, converts it to image pixels with the window's scale)
    preview_params = {"method": "ssn"}
    #: shells may switch this node among the registered types declaring the same handles kind
    handles = {"kind": "shadow"}

    def compute(self, ctx, inputs, params):
        check_inputs(inputs)
        cam, light = inputs.camera, inputs.light
        if not inside(inputs.mask).any():  # nothing casts a shadow
            darkness = np.zeros(inputs.mask.shape, np.float32)
            return {"lit": 1.0 - darkness, "darkness": darkness}
        ssn = _ssn()
        try:
            softness = ssn.softness_of(light, cam, inputs.mask, inputs.fg_height)
        except ValueError as e:
            raise InputError(f"input 'fg_height': {e}") from None
        threads, torch_device = torch_settings()
        model = load_shipped(params.model)
        from .ops import ssn_crop
        darkness, info = ssn_crop.render(ctx.device, model, inputs.mask, inputs.fg_height, inputs.bg_height,
                                         light_point(light, cam), disk_extremes(light, cam), softness,
                                         params.thickness, threads=threads, torch_device=torch_device,
                                         progress=lambda f, m="": ctx.progress(0.5 * f, m),
                                         check_cancelled=ctx.check_cancelled)
        if info.clamped:
            lo, hi = ssn_crop.SOFTNESS_RANGE
            ctx.log(f"warning: light softness (radius / distance) {softness:.3g} is outside the trained "
                    f"range {lo:g}-{hi:g}: the network was run at {info.softness:g}")
        ctx.log(f"{info.describe()}; network on torch's {torch_device}")
        finite_outputs(darkness=darkness)
        ctx.progress(1.0, "SSN++")
        return {"lit": 1.0 - darkness, "darkness": darkness}
