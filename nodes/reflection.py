"""pixgraph.Reflection: glossy reflection of the cutout on the background (PixHt-Lab Sec. 3.3)."""
from __future__ import annotations

import numpy as np

from pixgraph_nodes import types as T
from pixgraph.node import Node, node, param, port

from ._checks import finite, finite_outputs, inside, pixel_heights, rgba, same_size
from .ops.reflection_proxy import AUTO_MAX_SIDE, proxy_reflection


@node("pixgraph.Reflection", version=1)
class Reflection(Node):
    """Reflection of the cutout in the background surface, traced in pixel-height space.

    The receiver is the background (positions and normals reconstructed from its
    pixel height). Isotropic GGX (``alpha = roughness^2``) sampled by visible
    normals, never below the surface; Fresnel is the exact dielectric reflectance
    with IOR ``eta``, or Schlick with a coloured ``f0`` for a conductor. Each pixel
    near the reflection takes samples until the standard error of its estimate is
    below ``noise`` (between ``min_spp`` and ``max_spp``; estimated from four
    interleaved low-discrepancy sub-sequences), pixels whose 4-sample probe finds
    no hit within 4 pixels stay empty; roughness 0 is a mirror traced with one
    sample, and on flat ground it uses the exact planar closed form (the cutout
    flipped about its foot line). Output: a premultiplied linear RGBA layer to put
    over the background. A photo has more than one surface: ``receivers: ground``
    and/or a ``receiver`` mask keep the reflection on the floor (a wall template
    would otherwise mirror the cutout too).

    All inputs share the camera's size and the cutout is RGBA; pixel heights must
    be finite and >= 0 (the cutout's inside its mask), else the node stops with
    an input error. An empty cutout reflects nothing (a transparent layer). Long
    runs work in bands of image rows: they report progress and stop at the next
    band when the run is cancelled. Glossy reflections of images longer than
    ``proxy`` are traced at a proxy resolution (docs/reflection.md has the error).
    """

    class Inputs:
        camera: T.Camera = port(doc="pixel-height camera")
        cutout: T.Image = port(doc="cutout colour, premultiplied linear RGBA")
        fg_height: T.PixelHeight = port(doc="cutout pixel height [px]")
        bg_height: T.PixelHeight = port(doc="background pixel height [px] (the receiver)")
        mask: T.Mask = port(optional=True, doc="cutout mask (default: the cutout's alpha)")
        receiver: T.Mask = port(optional=True,
                                doc="where the background reflects (e.g. the floor only); default everywhere")

    class Params:
        roughness: float = param(0.0, min=0.0, max=1.0, doc="GGX roughness (alpha = roughness^2); 0 = mirror")
        material: str = param("dielectric", choices=("dielectric", "conductor"),
                              doc="Fresnel: exact dielectric (eta) or Schlick with f0 (metal)")
        eta: float = param(1.5, min=1.0, max=4.0, doc="index of refraction of the floor (dielectric)")
        f0: list[float] = param([0.95, 0.93, 0.88], length=3, min=0.0, max=1.0,
                                doc="normal-incidence reflectance per channel (conductor)")
        strength: float = param(1.0, min=0.0, max=10.0, doc="multiplier of the reflection")
        thickness: float = param(4.0, min=0.0, max=10000.0, unit="px", doc="cutout thickness")
        noise: float = param(0.005, min=1e-5, max=1.0,
                             doc="target standard error of each pixel's estimate (linear RGBA)")
        min_spp: int = param(16, min=1, max=65536,
                             doc="samples before the noise test (min_spp = max_spp: fixed count)")
        max_spp: int = param(128, min=1, max=65536, doc="sample cap per pixel")
        seed: int = param(0, min=0, max=2**31 - 1, doc="random seed")
        receivers: str = param("all", choices=("all", "ground"),
                               doc="ground: only background pixels on the ground (pixel height 0) reflect, "
                                   "so a wall does not mirror the cutout; combined with the receiver input")
        accelerate: bool = param(True, cache=False,
                                 doc="max-height pyramid skipping (same result, fewer steps)")
        proxy: int = param(AUTO_MAX_SIDE, min=0, max=1 << 20, unit="px, longer side",
                           doc="glossy reflections (roughness > 0) of images whose longer side exceeds this "
                               "are traced on a copy of this longer side and enlarged edge-aware against the "
                               "full-resolution mask (0: never)")

    class Outputs:
        layer: T.Image = port(doc="reflection, premultiplied linear RGBA")
        stats: T.Buffers = port(doc="per pixel: spp (samples used), steps (march iterations)")

    impl_version = "4"   # 2: low-discrepancy (R2) samples; 3: proxy resolution above `proxy` px;
                         # 4: receivers masked off are not traced
    #: a 20 MP layer and its stats are 475 MiB, remade from the proxy in a few
    #: seconds (docs/reflection.md): memory cache only
    disk_cache = False

    def compute(self, ctx, inputs, params):
        same_size(inputs.camera, cutout=inputs.cutout, fg_height=inputs.fg_height, bg_height=inputs.bg_height,
                  mask=inputs.mask, receiver=inputs.receiver)
        rgba(cutout=inputs.cutout)
        finite(cutout=inputs.cutout, mask=inputs.mask)
        pixel_heights(lambda: inside(inputs.cutout[..., 3] if inputs.mask is None else inputs.mask),
                      fg_height=inputs.fg_height)
        pixel_heights(bg_height=inputs.bg_height)
        finite(receiver=inputs.receiver)
        side = max(inputs.bg_height.shape) if params.proxy == 0 else max(16, params.proxy)
        receiver = _receiver_mask(inputs.receiver, inputs.bg_height, params.receivers)
        r = proxy_reflection(ctx.device, inputs.camera, inputs.cutout, inputs.fg_height, inputs.bg_height,
                             max_side=side, roughness=params.roughness, eta=params.eta,
                             conductor=params.material == "conductor", f0=params.f0,
                             strength=params.strength, thickness=params.thickness,
                             min_spp=params.min_spp, max_spp=params.max_spp, target_se=params.noise,
                             seed=params.seed, mask=inputs.mask, hiz=params.accelerate, receive=receiver,
                             progress=ctx.progress, check_cancelled=ctx.check_cancelled)
        finite_outputs(layer=r["layer"])
        return {"layer": r["layer"],
                "stats": {"spp": r["spp"], "steps": r["steps"]}}    # float32 from proxy_reflection


def _receiver_mask(receiver, bg_height, receivers: str):
    """Coverage of the surfaces that reflect, float32 (H, W), or None for all of them."""
    out = None if receiver is None else np.clip(np.asarray(receiver, dtype=np.float32), 0.0, 1.0)
    if receivers == "ground":
        ground = (np.asarray(bg_height) <= 0.5).astype(np.float32)   # the floor: no height above it
        out = ground if out is None else out * ground
    return out
