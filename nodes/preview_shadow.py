"""pixgraph.PreviewShadow: a soft shadow for previews, the hard shadow widened by a penumbra estimate."""
from __future__ import annotations

from pixgraph_nodes import types as T
from pixgraph.node import Node, node, param, port

from ._checks import finite_outputs, inside
from ._shadow_ports import SHADOW_METHODS, ShadowInputs, ShadowOutputs, check_inputs, thickness_param
from .ops.lights import light_point
from .ops.preview_shadow import preview_soft_shadow
from .ops.softness import softness_of, window_scale


@node("pixgraph.PreviewShadow", version=1)
class PreviewShadow(Node):
    """Soft shadow at about the cost of one hard shadow, for previews (the soft shadows
    declare it as their ``preview`` stand-in): the hard shadow of the light's centre,
    each edge pixel averaged over a box whose half-size is the light's softness (radius
    over distance) times the distance to the occluder that blocks it (PCSS's
    estimate; ``ops/preview_shadow.py``; a box stretched along the penumbra's long
    axis was tried and left out, docs/server.md). It follows the light's radius, unlike
    ``pixgraph.HardShadow``; against ``pixgraph.SoftShadow`` (64 samples) it is an
    approximation (docs/server.md, "Previews of soft shadows", has the error).

    All inputs share the camera's size; pixel heights must be finite and >= 0
    (the cutout's inside its mask), else the node stops with an input error. An
    empty mask casts no shadow (all lit); a point light, or ``method: hard`` (a
    ``pixgraph.Shadow`` forced hard), gives the hard shadow. With ``method: ssn``
    (``pixgraph.SoftShadowSSN`` declares it for its stand-in, a ``pixgraph.Shadow``
    forced to ssn keeps it) ``thickness`` is in pixels of SSN++'s window, as SSN++
    reads it, and is divided by the window's scale (``softness.window_scale``: the
    cutout's height brought to the trained 64-120 px) to image pixels; in a scaled
    run (the page's previews) first by the run's scale, which the engine multiplied
    it by (the param is declared in image pixels for the other methods)."""

    class Inputs(ShadowInputs):
        light: T.Light = port(doc="the light; its radius / distance is the softness")

    class Params:
        thickness: float = thickness_param(doc="how far a ray may pass behind the cutout surface and still "
                                               "be blocked (method ssn: in pixels of SSN++'s window)")
        # shared with pixgraph.Shadow, so that its forced hard shadow previews as hard
        method: str = param("auto", choices=SHADOW_METHODS,
                            doc="the stood-in shadow's method: hard gives the hard shadow, the others the "
                                "estimate; ssn also reads thickness in SSN++'s window pixels")

    class Outputs(ShadowOutputs):
        """The shared two (``_shadow_ports.ShadowOutputs``): those of the nodes it stands in for."""

    # 2: method ssn reads thickness in SSN++'s window pixels; 3: and undoes a scaled run's
    # factor on it (window pixels do not scale); 4: a disk light's penumbra on the background
    # is stretched along its long axis (penumbra_blur's geometry, docs/server.md); 5: the square box
    # again (4 left hard-edged patches on a wall under a low, large light: docs/server.md)
    impl_version = "5"
    # a scaled run multiplies ``thickness`` (declared in image px): method ssn divides it back
    uses_scale = True
    # no ``handles``: a stand-in, not one of the shadow methods a shell offers to switch to

    def compute(self, ctx, inputs, params):
        check_inputs(inputs)
        light, cam = inputs.light, inputs.camera
        softness = 0.0
        if light.is_area and params.method != "hard":
            try:
                softness = softness_of(light, cam, inputs.mask, inputs.fg_height)
            except ValueError as e:      # no cutout pixel below the horizon: no 3D centre
                if inside(inputs.mask).any():
                    ctx.log(f"hard shadow: {e}")
        thickness = params.thickness
        if params.method == "ssn":       # SSN++'s thickness is in its window's pixels, which do not scale
            thickness = thickness / ctx.scale / window_scale(inputs.mask)
        darkness = preview_soft_shadow(ctx.device, inputs.mask, inputs.fg_height, inputs.bg_height,
                                       light_point(light, cam), softness, thickness,
                                       progress=ctx.progress, check_cancelled=ctx.check_cancelled)
        finite_outputs(darkness=darkness)
        return {"lit": (1.0 - darkness).astype(darkness.dtype), "darkness": darkness}
