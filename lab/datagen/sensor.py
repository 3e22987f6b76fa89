"""Our camera as a Mitsuba 3 sensor, and a path-traced check of the ray-cast shadow.

``mitsuba_sensor(camera)``: a ``perspective`` sensor that is exactly
``nodes/ops/camera.Camera``: horizontal fov ``hfov`` (``fov_axis = x``), no pitch
(looking down -Z from ``(0, H_cam, 0)`` with +Y up) and the horizon placed by a
vertical lens shift ``principal_point_offset_y = (H/2 - horizon) / H`` (units of
the image height; the sign was measured: tests/test_datagen.py checks that the
sensor's rays equal ``Camera.ray`` for sub-pixel positions and that a rendered
emitter lands on ``Camera.project``'s pixel).

``render_direct_darkness``: renders the background (white diffuse) lit only by the
disk area light with Mitsuba's ``direct`` integrator, with and without the object
(black), and returns ``1 - I_with / I_without``: for a diffuse receiver under
direct light only, radiance is proportional to irradiance, so this is an
independent, physically based estimate of the same irradiance ratio that
``render.py`` computes by shadow rays.
"""
from __future__ import annotations

import numpy as np

from pixgraph_nodes.ops.camera import Camera

from .raycast import _mesh, select_variant
from .scene import DiskLight, SceneSpec, background_meshes


def principal_point_offset_y(camera: Camera) -> float:
    return (camera.height / 2.0 - camera.horizon) / camera.height


def mitsuba_sensor(camera: Camera, spp: int = 16) -> dict:
    """Mitsuba sensor dict (for ``mi.load_dict``) equal to ``camera`` (module doc)."""
    import mitsuba as mi
    select_variant()
    return {
        "type": "perspective", "fov": float(camera.hfov), "fov_axis": "x",
        "principal_point_offset_x": 0.0, "principal_point_offset_y": principal_point_offset_y(camera),
        "near_clip": 1e-3, "far_clip": 1e4,
        "to_world": mi.ScalarTransform4f().look_at(origin=[0, camera.cam_height, 0],
                                                   target=[0, camera.cam_height, -1], up=[0, 1, 0]),
        "film": {"type": "hdrfilm", "width": camera.width, "height": camera.height,
                 "rfilter": {"type": "box"}, "pixel_format": "rgb"},
        "sampler": {"type": "independent", "sample_count": int(spp)},
    }


def sensor_ray_directions(camera: Camera, u, v) -> np.ndarray:
    """Unit directions (N, 3) of the Mitsuba sensor's rays through image points (u, v) [px]."""
    import mitsuba as mi
    s = mi.load_dict(mitsuba_sensor(camera))
    u = np.asarray(u, np.float32).ravel()
    v = np.asarray(v, np.float32).ravel()
    ray, _ = s.sample_ray(mi.Float(0.0), mi.Float(0.5), mi.Point2f(u / camera.width, v / camera.height),
                          mi.Point2f(0.5, 0.5))
    return np.array(ray.d, np.float64).T


def disk_emitter(light: DiskLight, radiance: float = 1.0) -> dict:
    """A one-sided Mitsuba ``disk`` shape with an ``area`` emitter facing ``light.normal``."""
    import mitsuba as mi
    C = [float(x) for x in light.center]
    n = light.normal / np.linalg.norm(light.normal)
    up = [0, 1, 0] if abs(n[1]) < 0.99 else [1, 0, 0]
    T = mi.ScalarTransform4f().look_at(origin=C, target=[C[i] + float(n[i]) for i in range(3)], up=up)
    return {"type": "disk", "to_world": T @ mi.ScalarTransform4f().scale([light.radius, light.radius, 1.0]),
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": radiance}}}


def render_direct_darkness(spec: SceneSpec, light: DiskLight, spp: int = 256, seed: int = 0):
    """Path-traced darkness (H, W) = 1 - I_with / I_without (0 where I_without ~ 0)
    and the two radiance images; see module doc."""
    import mitsuba as mi
    select_variant()

    def scene(with_obj: bool):
        d = {"type": "scene", "integrator": {"type": "direct"}, "sensor": mitsuba_sensor(spec.camera, spp),
             "light": disk_emitter(light)}
        # two-sided: Mitsuba's diffuse BSDF is black from the back and our template
        # meshes are not consistently wound; under direct light only the ratio
        # I_with / I_without does not depend on the albedo
        bsdf = mi.load_dict({"type": "twosided", "material": {"type": "diffuse"}})
        for i, (V, F) in enumerate(background_meshes(spec.bg_kind, spec.bg_params, spec.base)):
            d[f"bg{i}"] = _mesh(f"bg{i}", V, F, bsdf)
        if with_obj:
            d["obj"] = _mesh("obj", spec.obj_V, spec.obj_F)
        return mi.load_dict(d)

    imgs = []
    for with_obj in (False, True):
        img = np.array(mi.render(scene(with_obj), seed=seed), np.float64)[..., :3].mean(-1)
        imgs.append(img)
    i0, i1 = imgs
    dark = np.where(i0 > 1e-6 * max(i0.max(), 1e-12), 1.0 - i1 / np.where(i0 > 0, i0, 1.0), 0.0)
    return dark, i0, i1
