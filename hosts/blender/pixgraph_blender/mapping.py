"""Blender -> pixgraph: camera, light and the graph the panel runs. No ``bpy`` here
(plain numbers in, plain values out), so it is tested without Blender too.

Blender's world is Z-up in metres; pixgraph's camera world (design notes §2) is
Y-up with the camera at ``(0, H_cam, 0)`` looking down ``-Z`` and the ground at
``Y = 0``. For a camera with no pitch and no roll, Blender's camera-local axes
(x right, y up, -z forward) are pixgraph's axes up to the height offset, so a world
point ``p`` maps to ``(x_c, p_z, z_c)`` where ``(x_c, y_c, z_c)`` is ``p`` in the
camera's local frame. Blender's ground must be the plane ``z = 0``.
"""
from __future__ import annotations

import math

import numpy as np

#: how far from level a camera may be (degrees of pitch or roll) and still be taken as level
LEVEL_TOLERANCE_DEG = 0.05


class HostError(ValueError):
    """Something in the Blender scene that pixgraph cannot use; the message says what to change."""


def camera_params(*, lens_mm: float, sensor_width_mm: float, sensor_height_mm: float, sensor_fit: str,
                  shift_x: float, shift_y: float, width: int, height: int, matrix_world,
                  cam_type: str = "PERSP", pixel_aspect: float = 1.0) -> dict:
    """pixgraph.Camera params (width, height, hfov, horizon, cam_height) of a Blender camera.

    lens_mm, sensor_*_mm: the camera's focal length and sensor; sensor_fit
    ``AUTO``/``HORIZONTAL``/``VERTICAL`` as in Blender. shift_x, shift_y: lens shift
    in Blender's units (fractions of the fitted image side). width, height: the
    image size in pixels (the background's). matrix_world: the camera's 4x4 world
    matrix. Raises ``HostError`` for what pixgraph's camera cannot represent: an
    orthographic or panoramic camera, pitch or roll (tilt-shift with ``shift_y``
    instead), a horizontal shift, non-square pixels, a camera at or below the ground.
    """
    if cam_type != "PERSP":
        raise HostError(f"the camera is {cam_type.lower()}; pixgraph needs a perspective camera")
    if abs(pixel_aspect - 1.0) > 1e-6:
        raise HostError(f"pixel aspect {pixel_aspect:g} is not 1; pixgraph needs square pixels")
    if abs(shift_x) > 1e-6:
        raise HostError(f"camera shift X is {shift_x:g}; pixgraph's camera has no horizontal shift (set it to 0)")
    M = np.asarray(matrix_world, dtype=np.float64)
    R = M[:3, :3] / np.linalg.norm(M[:3, :3], axis=0)       # rotation without scale
    forward, up = -R[:, 2], R[:, 1]
    pitch = math.degrees(math.asin(max(-1.0, min(1.0, forward[2]))))
    right = R[:, 0]
    roll = math.degrees(math.asin(max(-1.0, min(1.0, right[2]))))
    if abs(pitch) > LEVEL_TOLERANCE_DEG or abs(roll) > LEVEL_TOLERANCE_DEG or up[2] <= 0:
        raise HostError(f"the camera is pitched {pitch:+.2f} deg and rolled {roll:+.2f} deg; pixgraph needs a "
                        "level camera (rotation X = 90, Y = 0): move the horizon with shift Y instead")
    cam_height = float(M[2, 3])
    if not cam_height > 0:
        raise HostError(f"the camera is at z = {cam_height:g}; it must be above the ground plane z = 0")
    fit = sensor_fit
    if fit == "AUTO":
        fit = "HORIZONTAL" if width >= height else "VERTICAL"
        sensor = sensor_width_mm                         # AUTO fits the sensor width to the larger side
    else:
        sensor = sensor_width_mm if fit == "HORIZONTAL" else sensor_height_mm
    fitted = width if fit == "HORIZONTAL" else height   # pixels that the sensor size spans
    focal_px = lens_mm * fitted / sensor
    hfov = math.degrees(2.0 * math.atan(width / 2.0 / focal_px))
    # shift_y > 0 moves the frame up, so the horizon (the principal row of a level camera) moves down
    horizon = height / 2.0 + shift_y * fitted
    return {"width": int(width), "height": int(height), "hfov": hfov, "horizon": horizon,
            "cam_height": cam_height}


def to_pixgraph(matrix_world, point) -> np.ndarray:
    """A Blender world point in pixgraph's camera world (level camera; see the module doc)."""
    M = np.asarray(matrix_world, dtype=np.float64)
    R = M[:3, :3] / np.linalg.norm(M[:3, :3], axis=0)
    p = np.asarray(point, dtype=np.float64)
    local = R.T @ (p - M[:3, 3])
    return np.array([local[0], p[2], local[2]])


def direction_to_pixgraph(matrix_world, direction) -> np.ndarray:
    """A Blender world direction in pixgraph's camera world."""
    M = np.asarray(matrix_world, dtype=np.float64)
    R = M[:3, :3] / np.linalg.norm(M[:3, :3], axis=0)
    d = np.asarray(direction, dtype=np.float64)
    local = R.T @ d
    return np.array([local[0], d[2], local[2]])


def controls_toward(target, direction) -> tuple[float, float]:
    """(azimuth, elevation) in degrees of a direction from ``target``, in pixgraph.Light's
    convention (azimuth 0 toward the camera, +Z; 90 right, +X; elevation above horizontal)."""
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    elevation = math.degrees(math.asin(max(-1.0, min(1.0, d[1]))))
    azimuth = math.degrees(math.atan2(d[0], d[2])) if math.hypot(d[0], d[2]) > 1e-12 else 0.0
    return azimuth, elevation


def light_params(camera: dict, matrix_world, target_uv, *, kind: str, location=None, direction=None,
                 radius: float = 0.0, angular_radius_deg: float = 0.0) -> dict:
    """pixgraph.Light params that put a Blender light where it is in Blender.

    The Light node places a light around a target on the ground; the target is the
    ground point seen at ``target_uv`` (the cutout's foot) and the controls are
    computed from it, so the light's 3D position is exactly Blender's.
    kind ``point``/``disk`` need ``location`` (world); ``directional`` needs
    ``direction`` (world, from the scene toward the light).
    """
    from pixgraph_nodes.ops.camera import Camera

    cam = Camera(**camera)
    P, ok = cam.back_project(target_uv[0], target_uv[1], 0.0)
    if not ok:
        raise HostError(f"the cutout's foot {tuple(round(x, 1) for x in target_uv)} is at or above the horizon "
                        f"(row {cam.horizon:.1f}); it must stand on the ground below the horizon")
    P = np.asarray(P)
    params = {"kind": kind, "placement": "controls", "target_mode": "pixel",
              "target_uv": [float(target_uv[0]), float(target_uv[1])]}
    if kind == "directional":
        az, el = controls_toward(P, direction_to_pixgraph(matrix_world, direction))
        params.update(azimuth=az, elevation=el, angular_radius=float(angular_radius_deg))
    else:
        L = to_pixgraph(matrix_world, location)
        if L[1] <= 0:
            raise HostError("the light is at or below the ground plane z = 0")
        az, el = controls_toward(P, L - P)
        params.update(azimuth=az, elevation=el, distance=float(np.linalg.norm(L - P)), radius=float(radius))
    return params


#: background templates the panel offers, and the BackgroundHeight params each uses
TEMPLATE_PARAMS = {
    "ground": (),
    "back_wall": ("junction_row", "junction_slope"),
    "wall_corner": ("corner", "left_slope", "right_slope"),
}


def build_graph(builder, *, camera: dict, light: dict, template: dict, samples: int, opacity: float,
                background_colorspace: str, background_alpha: str, cutout_colorspace: str, cutout_alpha: str,
                tint=(0.08, 0.09, 0.12), thickness: float = 6.0, height_method: str = "contact_line"):
    """The panel's graph: host inputs ``background`` and ``cutout`` (bind their arrays),
    outputs ``composite`` (linear RGB) and ``shadow`` (darkness, 1 = full shadow).

    builder: ``Session.builder()``. opacity, tint: pixgraph.Composite's. thickness:
    pixgraph.SoftShadow's occluder thickness in pixels (6, as the example graphs:
    lab/thickness_study.py with contact-line heights). template:
    BackgroundHeight params (``kind`` and its handles, pixels of the background image).
    height_method: pixgraph.CutoutHeight's ``method`` (``learned`` and ``auto`` read the
    cutout's colour too; they run in numpy, so Blender's Python needs no torch).
    """
    b = builder
    b.add("pixgraph.InputImage", "background", colorspace=background_colorspace, alpha=background_alpha)
    b.add("pixgraph.InputImage", "cutout", colorspace=cutout_colorspace, alpha=cutout_alpha)
    b.add("pixgraph.Camera", "cam", **camera)
    b.add("pixgraph.CutoutHeight", "fg_h", method=height_method)
    b.add("pixgraph.BackgroundHeight", "bg_h", **template)
    b.add("pixgraph.Light", "light", **light)
    b.add("pixgraph.SoftShadow", "shadow", samples=samples, thickness=thickness)
    b.add("pixgraph.Composite", "comp", opacity=opacity, tint=[float(t) for t in tint])
    b.connect("cutout.alpha", "fg_h.mask")
    if height_method in ("learned", "auto"):
        b.connect("cutout.image", "fg_h.image")
    b.connect("cam.camera", "bg_h.camera")
    b.connect("cam.camera", "light.camera")
    for src, dst in [("cutout.alpha", "mask"), ("fg_h.height", "fg_height"), ("bg_h.height", "bg_height"),
                     ("light.light", "light"), ("cam.camera", "camera")]:
        b.connect(src, f"shadow.{dst}")
    for src, dst in [("background.image", "background"), ("cutout.image", "cutout"), ("cutout.alpha", "alpha"),
                     ("shadow.darkness", "shadow")]:
        b.connect(src, f"comp.{dst}")
    b.output("composite", "comp.image")
    b.output("shadow", "shadow.darkness")
    return b.build()


def foot_uv(alpha) -> tuple[float, float]:
    """(u, v) pixels of the cutout's foot (rows from the top), as pixgraph.Light finds it."""
    from pixgraph_nodes.ops.lights import foot_of_mask

    try:
        return foot_of_mask(alpha)
    except ValueError:
        raise HostError("the cutout image has no opaque pixels (alpha > 0.5)") from None
