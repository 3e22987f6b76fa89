"""What the shadow-family nodes share (not a node module: its name starts with _):
their five inputs, their two outputs, the ``thickness`` param, the check of those
inputs and the preview stand-in of the soft ones.

``HardShadow``, ``SoftShadow``, ``SoftShadowSSN``, ``Shadow`` and
``BufferChannels`` declare ``class Inputs(ShadowInputs)`` (a node may restate one
port to give it its own doc), ``thickness: float = thickness_param()`` and call
``check_inputs(inputs)`` before they trace anything; the shadow nodes (``PreviewShadow``
too) declare ``class Outputs(ShadowOutputs)``, so a preview stand-in has the ports of
the node it stands in for by construction.
"""
from __future__ import annotations

from pixgraph.node import param, port
from pixgraph_nodes import types as T

from ._checks import finite, inside, pixel_heights, same_size

THICKNESS_DOC = "how far a ray may pass behind the cutout surface and still be blocked"

#: pixgraph.Shadow's ``method`` choices, which its preview stand-in (pixgraph.PreviewShadow)
#: declares too: the preview swap keeps the params the stand-in declares
SHADOW_METHODS = ("auto", "hard", "soft", "ssn")


#: the node type that stands in for the soft shadows (SoftShadow, SoftShadowSSN, Shadow) in
#: previews: a soft shadow at about one hard shadow's cost that follows the light's radius
#: (benchmarks/preview_shadow_bench.py; docs/server.md, "Previews of soft shadows")
SOFT_PREVIEW = "pixgraph.PreviewShadow"


class ShadowInputs:
    """The cutout, both pixel-height maps, the light and the camera."""

    mask: T.Mask = port(doc="cutout coverage (occluder where > 0.5)")
    fg_height: T.PixelHeight = port(doc="cutout pixel height [px]")
    bg_height: T.PixelHeight = port(doc="background pixel height [px]")
    light: T.Light = port(doc="the light")
    camera: T.Camera = port(doc="camera that converts the light to pixel-height space")


class ShadowOutputs:
    """The shadow twice: as light seen and as darkness (what Composite takes)."""

    lit: T.Mask = port(doc="1 - darkness")
    darkness: T.Mask = port(doc="1 - lit: 1 = full shadow (what Composite takes)")


def thickness_param(doc: str = THICKNESS_DOC, unit: str = "px"):
    """The ``thickness`` param: default 1, in [0, 1000], in image pixels (``unit="px"``: a
    scaled run multiplies it by the working resolution) unless ``unit`` says otherwise."""
    return param(1.0, min=0.0, max=1000.0, unit=unit, doc=doc)


def check_inputs(inputs) -> None:
    """``InputError`` naming the input unless the mask and both height maps have the
    camera's size, the mask is finite, and the pixel heights are finite and >= 0
    (the cutout's inside its mask)."""
    same_size(inputs.camera, mask=inputs.mask, fg_height=inputs.fg_height, bg_height=inputs.bg_height)
    finite(mask=inputs.mask)
    pixel_heights(inside(inputs.mask), fg_height=inputs.fg_height)
    pixel_heights(bg_height=inputs.bg_height)
