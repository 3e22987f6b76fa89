"""pixgraph.Shadow: the cutout's shadow by the cheapest method that meets an accuracy target."""
from __future__ import annotations

import numpy as np

from pixgraph_nodes import types as T
from pixgraph.node import InputError, Node, node, param, port

from ._checks import finite_outputs, inside
from ._shadow_ports import (SHADOW_METHODS, SOFT_PREVIEW, ShadowInputs, ShadowOutputs, check_inputs,
                            thickness_param)
from .ops import choose as C
from .ops.softness import softness_of
from .ops.lights import disk_extremes, disk_samples, light_point
from .ops.upsample import AUTO_MAX_SIDE, lit_and_darkness, proxy_soft_shadow_parts
from .ssn_soft_shadow import SoftShadowSSN


def _has_torch() -> bool:
    import importlib.util
    return importlib.util.find_spec("torch") is not None


@node("pixgraph.Shadow", version=1)
class Shadow(Node):
    """Shadow of a cutout, by the method the scene needs ("model no more than a scene
    needs"). ``method: auto`` picks the cheapest of the hard shadow, the classical
    soft shadow with 4-64 light samples and SSN++ whose 90th-percentile RMSE against
    ray-traced ground truth, measured on the benchmark for this light's softness
    and this kind of receiver (wall or ground), is at most ``max_rmse``; the choice
    and why are in the run's log and in ``pixgraph explain`` (docs/auto.md).
    ``hard``, ``soft`` (``samples``) and ``ssn`` force a method."""

    class Inputs(ShadowInputs):
        light: T.Light = port(doc="the light; its radius / distance is the softness")

    class Params:
        method: str = param("auto", choices=SHADOW_METHODS,
                            doc="auto: cheapest expected to meet max_rmse; or force one")
        max_rmse: float = param(0.06, min=0.0, max=1.0,
                                doc="auto's accuracy target: RMSE of darkness against ground truth that at "
                                    "most 10% of the benchmark's similar scenes exceeded")
        samples: int = param(64, min=1, max=65536, doc="light samples of method soft")
        thickness: float = thickness_param(doc="occluder thickness of the pixel-height tracer (method ssn, "
                                               "forced or chosen by auto: in pixels of SSN++'s window, "
                                               "as pixgraph.SoftShadowSSN reads it)")
        proxy: int = param(AUTO_MAX_SIDE, min=0, max=1 << 20, unit="px, longer side",
                           doc="classical shadows of images longer than this are traced at this size (0: never)")

    class Outputs(ShadowOutputs):
        """The shared two (``_shadow_ports.ShadowOutputs``)."""

    # the choice depends on the shipped table: a new table is a new implementation
    # the result depends on the shipped table and, through method ssn, on SSN++'s weights and inference
    impl_version = "1+table." + C.table_digest() + "+ssn." + SoftShadowSSN.impl_version
    # a scaled run multiplies ``thickness`` (declared in image px): method ssn divides it back out
    uses_scale = True
    #: a cheaper node type with the same ports that stands in for this one in previews
    preview = SOFT_PREVIEW
    #: shells may switch this node among the registered types declaring the same handles kind
    handles = {"kind": "shadow"}

    def describe(self, params) -> str:
        """What ``pixgraph explain`` shows before the run (the choice needs the inputs)."""
        if params["method"] != "auto":
            return f"method {params['method']} (forced)"
        table = C.load_table()
        n = sum(table.get("provenance", {}).get("data", {}).values()) or "?"
        return (f"method auto: at run time, the cheapest of {', '.join(table['methods'])} whose 90th-percentile "
                f"RMSE <= {params['max_rmse']:g} for the light's softness and the receiver "
                f"(table weights/{C.TABLE.name}, {n} benchmark samples)")

    def compute(self, ctx, inputs, params):
        check_inputs(inputs)
        light, cam = inputs.light, inputs.camera
        H, W = inputs.mask.shape
        if not inside(inputs.mask).any():  # nothing casts a shadow
            lit = np.ones((H, W), np.float32)
            return {"lit": lit, "darkness": 1.0 - lit}
        method = params.method
        if method == "auto":
            try:
                softness, receiver, _ = C.scene_features(ctx.device, inputs.mask, inputs.fg_height,
                                                          inputs.bg_height, light, cam, params.thickness)
            except ValueError as e:
                raise InputError(f"input 'fg_height': {e}") from None
            table = C.load_table()
            methods = [m for m in table["methods"] if m != "ssn" or _has_torch()]
            if len(methods) < len(table["methods"]):
                ctx.log("ssn is not a candidate: torch is not installed (pip install 'pixgraph[ssn]')")
            c = C.choose(table, softness, receiver, H * W, params.max_rmse, methods)
            ctx.log(f"auto chose {c.method}: {c.reason}; light softness {softness:.3g}, {receiver} receiver, "
                    f"{W}x{H}: expected RMSE mean {c.expected_mean:.3f}, p90 {c.expected_p90:.3f}, "
                    f"~{c.ms:.0f} ms")
            if not c.met:
                ctx.log(f"warning: no method is expected to meet max_rmse {params.max_rmse:g} here")
            method = c.method
        elif method == "soft":
            method = f"soft:{params.samples}"
        side = max(H, W) if params.proxy == 0 else params.proxy
        if method == "ssn":
            from .ops import ssn_crop                     # torch: imported only when SSN++ runs
            from .ssn_soft_shadow import load_shipped, torch_settings
            softness = softness_of(light, cam, inputs.mask, inputs.fg_height)
            threads, torch_device = torch_settings()
            # SSN++ reads the thickness in its window's pixels, which do not scale with the run
            darkness, _ = ssn_crop.render(ctx.device, load_shipped("ssnpp"), inputs.mask, inputs.fg_height,
                                          inputs.bg_height, light_point(light, cam), disk_extremes(light, cam),
                                          softness, params.thickness / ctx.scale, threads=threads,
                                          torch_device=torch_device,
                                          check_cancelled=ctx.check_cancelled)
            finite_outputs(darkness=darkness)
            return {"lit": 1.0 - darkness, "darkness": darkness}
        if method == "hard" or not light.is_area:
            samples = light_point(light, cam)[None]
        else:
            samples = disk_samples(light, cam, int(method.split(":")[1]), 0)
        parts = proxy_soft_shadow_parts(ctx.device, inputs.mask, inputs.fg_height, inputs.bg_height, samples,
                                        params.thickness, side, progress=ctx.progress,
                                        check_cancelled=ctx.check_cancelled)
        lit, darkness = lit_and_darkness(*parts, np.shape(inputs.mask))
        finite_outputs(lit=lit)
        return {"lit": lit, "darkness": darkness}
