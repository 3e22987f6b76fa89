"""pixgraph.PlaceCutout: put a cutout of any size onto the background's canvas."""
from __future__ import annotations

import dataclasses

import numpy as np

from pixgraph_nodes import types as T
from pixgraph.node import InputError, Node, node, param, port
from pixgraph_nodes.types import Shape

from .ops.heightmaps import contact_line_height
from .ops.placement import place_cutout, resize_map


@dataclasses.dataclass(frozen=True)
class PlacedShape(Shape):
    """What a check before running knows of a placed cutout's coverage: its canvas
    size, the foot (u, v) and the cutout's height on the canvas [px]."""

    foot: tuple[float, float] | None = None
    placed_height: float | None = None


@node("pixgraph.PlaceCutout", version=1)
class PlaceCutout(Node):
    """Place a cutout (an RGBA image of any size) on the background's canvas: its foot
    lands on ``foot`` (background pixels), scaled by ``scale``, optionally mirrored,
    cropped at the canvas border. Everything downstream works on the canvas size.

    The cutout's foot is the centre of its lowest row of pixels, at that row's bottom
    edge (the point the Light's ``mask_foot`` aims at). Colour is resampled
    premultiplied; pixel heights are resampled weighted by alpha and multiplied by
    ``scale``. A pixel-height map of another size than the cutout (same aspect) is
    first resized to it, heights scaled with it. Without a height input the output
    height is the contact-line heuristic of the placed alpha (pixgraph.CutoutHeight).

    A hard mask (a binary matte, as the PixHt-Lab authors ship) enlarged gets a
    clean antialiased outline (``edge: smooth``): the smooth contour of the
    slightly blurred mask, one canvas pixel wide, instead of its pixel staircase.

    A cutout without an alpha channel (RGB, e.g. a JPEG) is an error unless a
    ``mask`` gives its coverage: never a silent full-frame cutout.
    """

    class Inputs:
        cutout: T.Image = port(doc="RGBA cutout, linear premultiplied, any size")
        background: T.Image = port(doc="the plate: only its size is used (the canvas)")
        mask: T.Mask = port(optional=True, doc="coverage of the cutout (its size); replaces its alpha")
        height: T.PixelHeight = port(optional=True,
                                     doc="cutout pixel height [cutout px]; another size is resized")

    class Params:
        foot: list[float] = param([256.0, 448.0], length=2, unit="px",
                                  doc="background pixel (u, v) where the cutout stands")
        scale: float = param(1.0, min=1e-3, max=100.0, doc="size of the cutout on the canvas, x its pixels")
        flip: bool = param(False, doc="mirror the cutout left-right")
        edge: str = param("smooth", choices=("smooth", "bilinear"),
                          doc="smooth: a hard (binary) mask enlarged gets a clean antialiased outline, not its "
                              "pixel staircase; bilinear: plain resampling")

    class Outputs:
        image: T.Image = port(doc="cutout colour on the canvas, premultiplied (canvas size)")
        alpha: T.Mask = port(doc="cutout coverage on the canvas")
        height: T.PixelHeight = port(doc="cutout pixel height on the canvas [canvas px], 0 outside")

    impl_version = "3"   # 2: jumps found by second differences (steep faces blended); 3: smooth hard edges
    disk_cache = False      # large and cheaper to recompute than to read back from disk
    #: what a shell's page draws (read by pixgraph_serve): the placed cutout, by the
    #: box its ``coverage`` output covers, moved by the ``foot`` and ``scale`` params
    handles = {"kind": "place", "coverage": "alpha", "params": ("foot", "scale")}

    def infer(self, ctx, inputs, params):
        """Checks from file headers: alpha or mask, sizes, and a foot that keeps the
        cutout on the canvas."""
        cut, bg, mask, height = inputs.cutout, inputs.background, inputs.mask, inputs.height
        if cut is not None:
            if cut.height < 2 or cut.width < 2:
                raise InputError(f"the cutout {cut.described()} is too small to place (at least 2x2)")
            if mask is None and cut.channels is not None and cut.channels not in (2, 4):
                raise InputError(f"the cutout {cut.described()} has no alpha channel ({cut.channels} channels): "
                                 "use an RGBA image (PNG, EXR) or connect a mask (pixgraph.LoadMask)")
            if mask is not None and (mask.height, mask.width) != (cut.height, cut.width):
                raise InputError(f"mask {mask.described()} and cutout {cut.described()} differ in size")
            if height is not None and abs((cut.height / height.height) / (cut.width / height.width) - 1) > 0.02:
                raise InputError(f"pixel height {height.described()} and cutout {cut.described()} have different "
                                 "aspect ratios: the map is not of this cutout")
        if bg is None:
            return {}
        u, v = params.foot
        if cut is not None:
            # the foot is inside the cutout, so a cutout at least partly on the canvas
            # has its foot within one scaled cutout size of it
            w, h = cut.width * params.scale, cut.height * params.scale
            off = u < -w or u > bg.width + w or v < 0 or v > bg.height + h
        else:
            off = not (0 <= u <= bg.width and 0 <= v <= bg.height)
        if off:
            what = f"the cutout {cut.described()}" if cut is not None else "the cutout"
            raise InputError(f"foot {[u, v]} at scale {params.scale} puts {what} outside the canvas "
                             f"{bg.described()}")
        source = f"{cut.source} placed on {bg.source}" if cut is not None else bg.source
        out = {o: Shape(bg.height, bg.width, c, source) for o, c in (("image", 4), ("height", 1))}
        out["alpha"] = PlacedShape(bg.height, bg.width, 1, source, (u, v),
                                   cut.height * params.scale if cut is not None else None)
        return out

    def compute(self, ctx, inputs, params):
        img = np.asarray(inputs.cutout, dtype=np.float32)
        if img.ndim == 2:
            img = img[:, :, None]
        h, w = img.shape[:2]
        if h < 2 or w < 2:
            raise InputError(f"the cutout is {w}x{h} px: too small to place (at least 2x2)")
        has_alpha = img.shape[2] in (2, 4)
        if inputs.mask is not None:
            mask = np.asarray(inputs.mask, dtype=np.float32)
            if mask.shape != (h, w):
                raise InputError(f"mask {mask.shape[1]}x{mask.shape[0]} and cutout {w}x{h} differ in size")
            colour = img[:, :, :-1] if has_alpha else img
            if has_alpha:  # straight colour again, then premultiplied by the given mask
                a0 = img[:, :, -1:]
                colour = np.where(a0 > 0, colour / np.maximum(a0, 1e-12), 0.0)
            alpha = np.clip(mask, 0.0, 1.0)
            img = np.concatenate([colour * alpha[:, :, None], alpha[:, :, None]], axis=2).astype(np.float32)
        elif not has_alpha:
            raise InputError(f"the cutout ({w}x{h}, {img.shape[2]} channels) has no alpha channel: "
                             "use an RGBA image (PNG, EXR) or connect a mask (pixgraph.LoadMask)")
        else:
            alpha = np.clip(img[:, :, -1], 0.0, 1.0)
        if not (alpha > 0.5).any():
            raise InputError(f"the cutout's alpha is empty ({w}x{h}, no pixel over 0.5): nothing to place")
        height = inputs.height
        if height is not None:
            height = np.asarray(height, dtype=np.float32)
            if not np.all(np.isfinite(height)):
                raise InputError("the cutout's pixel height has NaN or infinite values")
            try:
                height = resize_map(height, (h, w))
            except ValueError as e:
                raise InputError(str(e)) from None
        H, W = np.asarray(inputs.background).shape[:2]
        out_img, out_a, out_h = place_cutout(img, alpha, height, (H, W), params.foot, params.scale, params.flip,
                                            smooth_edge=params.edge == "smooth")
        if not (out_a > 0.5).any():
            raise InputError(f"the placed cutout lies outside the {W}x{H} canvas (foot {list(params.foot)}, "
                             f"scale {params.scale}): move its foot inside")
        if out_h is None:
            out_h = contact_line_height(out_a)
        return {"image": out_img, "alpha": out_a, "height": out_h}
