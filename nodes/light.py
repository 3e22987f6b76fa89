"""pixgraph.Light: a point, directional or disk light from artist controls or a shadow tip."""
from __future__ import annotations

import math

import numpy as np

from pixgraph_nodes import types as T
from pixgraph.node import InputError, Node, node, param, port

from .ops import light_screen, lights

#: a placed cutout taller than this many camera heights is noted by the check
TALL = 5.0


@node("pixgraph.Light", version=1)
class Light(Node):
    """A light placed by azimuth/elevation/distance around the object's foot, or by
    dragging the shadow tip.

    azimuth 0 puts the light on the camera's side (the shadow falls back, onto the
    wall), 90 to the right, 180 behind the object. Elevations at or below the
    horizon are raised to 1 degree (with a warning). Softness is the disk ``radius``
    (point/disk lights, world units) or the ``angular_radius`` (directional, degrees).
    """

    class Inputs:
        camera: T.Camera = port(doc="camera used to place the target and the shadow tip in 3D")
        mask: T.Mask = port(optional=True, doc="cutout; its foot is the target when target_mode is mask_foot")

    class Params:
        kind: str = param("disk", choices=lights.KINDS, doc="light type")
        placement: str = param("controls", choices=("controls", "shadow_tip"),
                               doc="azimuth/elevation around the target, or the shadow tip handles")
        azimuth: float = param(20.0, min=-360.0, max=360.0, unit="deg",
                               doc="around the vertical; 0 = camera side, 90 = right")
        elevation: float = param(45.0, min=-90.0, max=90.0, unit="deg", doc="above the horizontal")
        distance: float = param(4.0, min=1e-6, max=1e9, unit="world units",
                                doc="from the target (point/disk lights; directional lights are at infinity: "
                                    "use kind directional for a farther light)")
        radius: float = param(0.3, min=0.0, max=1e9, unit="world units", doc="disk light radius (softness)")
        angular_radius: float = param(0.0, min=0.0, max=60.0, unit="deg",
                                      doc="directional light's angular radius (softness)")
        facing: str = param("target", choices=lights.FACINGS, doc="disk faces the target, or faces down")
        target_mode: str = param("mask_foot", choices=("mask_foot", "pixel"),
                                 doc="target: the mask's foot (needs mask), or target_uv")
        target_uv: list[float] = param([256.0, 400.0], length=2, unit="px",
                                       doc="target pixel on the ground (target_mode pixel)")
        tip_uv: list[float] = param([150.0, 420.0], length=2, unit="px",
                                    doc="shadow_tip: the shadow tip on the ground")
        top_uvh: list[float] = param([256.0, 150.0, 250.0], length=3, unit="px",
                                     doc="shadow_tip: the object's top point (u, v) and its pixel height")

    class Outputs:
        light: T.Light = port(doc="the light (pixgraph_nodes.ops.lights.Light)")

    impl_version = "1"

    #: what a shell's page draws and drags (read by pixgraph_serve): the light is moved
    #: by its shadow tip, the ground point where the shadow of the object's top falls.
    #: ``tip``/``top``/``placement``/``elevation`` name this node's params (``elevation_min``:
    #: the lowest elevation that has an effect in the controls placement); ``object``
    #: names the inputs, on the node this light feeds, that hold the object's mask and
    #: pixel height; ``camera`` names this node's camera input.
    handles = {"kind": "light", "tip": "tip_uv", "top": "top_uvh", "placement": "placement",
               "tip_placement": "shadow_tip", "elevation": "elevation", "azimuth": "azimuth",
               "object": ("mask", "fg_height"), "camera": "camera",
               # placed by azimuth/elevation, a light below this is raised to it (a shell's
               # elevation slider starts here: below, it would move nothing)
               "elevation_min": lights.MIN_ELEVATION_DEG}
    #: the screen geometry of those handles (ops/light_screen.py), for shells that do not import nodes;
    #: ``tip_angles`` (the light's azimuth and elevation seen from the top, for a tip) and
    #: ``tip_at_angles`` (its inverse) keep ``azimuth``/``elevation`` true in shadow_tip placement
    object_top = staticmethod(light_screen.object_top)
    shadow_tip = staticmethod(light_screen.shadow_tip)
    tip_at_elevation = staticmethod(light_screen.tip_at_elevation)
    tip_angles = staticmethod(lights.tip_angles)
    tip_at_angles = staticmethod(light_screen.tip_at_angles)

    def infer(self, ctx, inputs, params):
        """Sizes as every node checks them, and a note when the camera's horizon does
        not fit the cutout's placement: a foot on the ground lies below the horizon,
        and an object standing far taller than the camera's height is likely a
        horizon set too close above its foot."""
        cam, mask = inputs.camera, inputs.mask
        if cam is not None and mask is not None and (cam.height, cam.width) != (mask.height, mask.width):
            raise InputError(f"inputs differ in size: camera {cam.described()}, mask {mask.described()}")
        horizon, foot = getattr(cam, "horizon", None), getattr(mask, "foot", None)
        if horizon is None or foot is None:
            return {}
        v = float(foot[1])
        if v <= horizon:
            ctx.log(f"the cutout's foot (row {v:g}) is at or above the camera's horizon (row {horizon:g}): a "
                    "point on the ground lies below the horizon, so its shadow cannot fall on the floor; "
                    "move the horizon above the foot (see docs/own-photo.md, 'The horizon')")
        elif getattr(mask, "placed_height", None) and mask.placed_height / (v - horizon) > TALL:
            ctx.log(f"the cutout ({mask.placed_height:g} px tall) stands {v - horizon:g} px below the horizon: "
                    f"it would be {mask.placed_height / (v - horizon):.0f} times as tall as the camera is high; "
                    "check the horizon (see docs/own-photo.md, 'The horizon')")
        return {}

    def affects(self, params):
        """Only the active placement's handles are in the key: dragging the shadow tip
        leaves a light placed by azimuth/elevation cached, and the reverse."""
        names = {"kind", "placement", "radius", "angular_radius", "facing", "camera"}
        if params.kind != "directional":
            names.add("distance")
        if params.placement == "shadow_tip":
            return names | {"tip_uv", "top_uvh"}
        names |= {"azimuth", "elevation", "target_mode"}
        return names | ({"mask"} if params.target_mode == "mask_foot" else {"target_uv"})

    def compute(self, ctx, inputs, params):
        cam = inputs.camera
        dist = math.inf if params.kind == "directional" else params.distance
        if params.placement == "shadow_tip":
            try:
                light = lights.from_shadow_tip(cam, params.tip_uv, params.top_uvh, dist, params.kind,
                                               params.radius, params.angular_radius, params.facing)
            except ValueError as e:  # a tip above the horizon, a top without height, tip under top
                raise InputError(f"params 'tip_uv', 'top_uvh': {e}") from None
            return {"light": _checked(light, cam)}
        if params.target_mode == "mask_foot":
            if inputs.mask is None:
                raise InputError("target_mode mask_foot needs the mask input (or use target_mode pixel)")
            if not (np.asarray(inputs.mask) > 0.5).any():
                raise InputError("target_mode mask_foot needs a non-empty mask (or use target_mode pixel)")
            uv = lights.foot_of_mask(inputs.mask)
        else:
            uv = tuple(params.target_uv)
        P, ok = cam.back_project(uv[0], uv[1], 0.0)
        if not ok:
            raise InputError(f"light target {uv} is at or above the horizon ({cam.horizon}): "
                             "it has no point on the ground")
        try:
            light = lights.from_controls(np.asarray(P), params.azimuth, params.elevation, dist, params.kind,
                                         params.radius, params.angular_radius, params.facing)
        except ValueError as e:
            raise InputError(f"params 'distance', 'radius': {e}") from None
        return {"light": _checked(light, cam)}


def _checked(light, cam):
    """The light, once its image in pixel-height space is known to be finite."""
    if not np.all(np.isfinite(lights.light_point(light, cam))):
        raise InputError("params 'distance', 'radius': the light's image in pixel-height space is not finite")
    return light
