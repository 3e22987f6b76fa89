"""pixgraph.Refraction: the background seen through a transparent cutout."""
from __future__ import annotations

from pixgraph_nodes import types as T
from pixgraph.node import Node, node, param, port

from ._checks import finite, finite_outputs, pixel_heights, rgba, same_size
from .ops.refraction import refraction_proxy
from .ops.upsample import AUTO_MAX_SIDE


@node("pixgraph.Refraction", version=1)
class Refraction(Node):
    """The background seen through a transparent cutout (glass ball, bottle), traced in pixel-height space.

    Refracts each view ray at the front surface of the object by Snell's law, with normals reconstructed from its pixel height,
    and trace it in pixel-height space to the background surface (ground, walls),
    whose colour it takes. Total internal reflection (possible for ``eta < 1``, e.g.
    an air bubble) reflects instead. With ``fresnel`` the front-surface reflection is
    added with the exact dielectric Fresnel weight. A single pixel-height map has no
    back surface: ``local_sphere`` takes it from the sphere of the front surface's
    local curvature (exact for a ball, an approximation for other solids), ``none``
    keeps one interface. Output: a premultiplied layer covering the object, to put
    over the background.

    All inputs share the camera's size and the glass is RGBA; pixel heights must
    be finite and >= 0 (the glass's where its alpha > 0), else the node stops
    with an input error. Glass with no coverage gives a transparent layer. Large
    images work in bands of rows: they report progress and stop at the next band
    when the run is cancelled. Images longer than ``proxy`` trace the rays on a
    smaller copy and look the colours up at full resolution (docs/reflection.md
    has the error: small inside the glass, larger on its rim).
    """

    class Inputs:
        camera: T.Camera = port(doc="pixel-height camera")
        glass: T.Image = port(doc="the transparent object; its alpha is the coverage")
        glass_height: T.PixelHeight = port(doc="pixel height of the object's front surface [px]")
        background: T.Image = port(doc="background colour, linear light")
        bg_height: T.PixelHeight = port(doc="background pixel height [px]")

    class Params:
        eta: float = param(1.5, min=0.1, max=4.0, doc="IOR of the object relative to its surroundings")
        tint: list[float] = param([1.0, 1.0, 1.0], length=3, min=0.0, max=1.0,
                                  doc="transmittance per channel")
        fresnel: bool = param(True, doc="add the front-surface reflection with Fresnel weights")
        back_surface: str = param("local_sphere", choices=("local_sphere", "none"),
                                  doc="local_sphere: a solid object; the ray refracts out again at the back "
                                      "of the sphere of the surface's local curvature (exact for a ball); "
                                      "none: front interface only")
        accelerate: bool = param(True, cache=False, doc="max-height pyramid skipping (same result)")
        proxy: int = param(AUTO_MAX_SIDE, min=0, max=1 << 20, unit="px, longer side",
                           doc="images whose longer side exceeds this trace the rays on a copy of this longer "
                               "side; where they land is enlarged edge-aware and the colours are looked up in "
                               "the full-resolution background (0: never; docs/reflection.md has the error)")

    class Outputs:
        layer: T.Image = port(doc="refraction, premultiplied linear RGBA")
        tir: T.Mask = port(doc="1 where total internal reflection happened")

    impl_version = "2"   # 2: proxy resolution above `proxy` px

    def compute(self, ctx, inputs, params):
        same_size(inputs.camera, glass=inputs.glass, glass_height=inputs.glass_height,
                  background=inputs.background, bg_height=inputs.bg_height)
        rgba(glass=inputs.glass)
        finite(glass=inputs.glass, background=inputs.background)
        pixel_heights(inputs.glass[..., 3] > 0, glass_height=inputs.glass_height)
        pixel_heights(bg_height=inputs.bg_height)
        side = max(inputs.bg_height.shape) if params.proxy == 0 else max(16, params.proxy)
        r = refraction_proxy(ctx.device, inputs.camera, inputs.glass, inputs.glass_height, inputs.background,
                             inputs.bg_height, max_side=side, eta=params.eta, tint=params.tint,
                             fresnel=params.fresnel, hiz=params.accelerate, back_surface=params.back_surface,
                             progress=ctx.progress, check_cancelled=ctx.check_cancelled)
        finite_outputs(layer=r["layer"])
        return {"layer": r["layer"], "tir": r["tir"].astype("float32")}
