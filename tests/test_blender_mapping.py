"""The add-on's Blender -> pixgraph mapping, without Blender (numbers in, numbers out).
The same mapping against Blender's own projection: tests/test_blender_addon.py."""
from __future__ import annotations

import importlib.util
import math
import pathlib

import numpy as np
import pytest

_path = pathlib.Path(__file__).resolve().parents[1] / "hosts" / "blender" / "pixgraph_blender" / "mapping.py"
_spec = importlib.util.spec_from_file_location("pixgraph_blender_mapping", _path)
mapping = importlib.util.module_from_spec(_spec)   # the add-on's module; it does not import bpy
_spec.loader.exec_module(mapping)

from pixgraph_nodes.ops import lights  # noqa: E402
from pixgraph_nodes.ops.camera import Camera  # noqa: E402


def level(yaw_deg=0.0, loc=(0.0, 0.0, 1.5)):
    """4x4 world matrix of a level Blender camera (rotation X 90, Z yaw)."""
    y = math.radians(yaw_deg)
    Rz = np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
    Rx = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]])           # 90 deg about X
    M = np.eye(4)
    M[:3, :3] = Rz @ Rx
    M[:3, 3] = loc
    return M


def params(**kw):
    base = dict(lens_mm=50.0, sensor_width_mm=36.0, sensor_height_mm=24.0, sensor_fit="AUTO", shift_x=0.0,
                shift_y=0.0, width=1920, height=1080, matrix_world=level())
    base.update(kw)
    return mapping.camera_params(**base)


def test_focal_length_and_sensor_give_hfov():
    assert params()["hfov"] == pytest.approx(2 * math.degrees(math.atan(18 / 50)))
    # portrait with AUTO fit: the sensor width spans the image height
    p = params(width=1080, height=1920)
    f_px = 50 * 1920 / 36
    assert p["hfov"] == pytest.approx(2 * math.degrees(math.atan(540 / f_px)))
    # VERTICAL fit uses the sensor height across the image height
    p = params(sensor_fit="VERTICAL")
    assert p["hfov"] == pytest.approx(2 * math.degrees(math.atan(960 / (50 * 1080 / 24))))


def test_shift_y_moves_the_horizon_in_units_of_the_fitted_side():
    assert params()["horizon"] == 540
    assert params(shift_y=0.1)["horizon"] == pytest.approx(540 + 192)       # frame up, horizon down
    assert params(shift_y=-0.1, sensor_fit="VERTICAL")["horizon"] == pytest.approx(540 - 108)
    assert params(matrix_world=level(30, (2, 3, 1.7)))["cam_height"] == pytest.approx(1.7)


@pytest.mark.parametrize("kw, needle", [
    (dict(cam_type="ORTHO"), "perspective camera"),
    (dict(shift_x=0.05), "shift X"),
    (dict(pixel_aspect=2.0), "square pixels"),
    (dict(matrix_world=level(loc=(0, 0, -1))), "above the ground"),
])
def test_what_pixgraph_cannot_represent_is_a_clear_error(kw, needle):
    with pytest.raises(mapping.HostError, match=needle):
        params(**kw)


def test_pitch_and_roll_are_refused_with_the_angle():
    M = level()
    t = math.radians(5)
    pitch = np.array([[1, 0, 0], [0, math.cos(t), -math.sin(t)], [0, math.sin(t), math.cos(t)]])
    M[:3, :3] = pitch @ M[:3, :3]
    with pytest.raises(mapping.HostError, match=r"pitched \+5.00 deg"):
        params(matrix_world=M)
    R = level()
    roll = np.array([[math.cos(t), 0, math.sin(t)], [0, 1, 0], [-math.sin(t), 0, math.cos(t)]])
    R[:3, :3] = roll @ R[:3, :3]
    with pytest.raises(mapping.HostError, match="rolled"):
        params(matrix_world=R)


def test_light_object_lands_where_it_is_in_blender():
    M = level(25, (1.0, -2.0, 1.3))
    cam = params(matrix_world=M, width=640, height=480, shift_y=-0.15)
    lamp = np.array([-1.0, 2.5, 3.0])
    p = mapping.light_params(cam, M, (300.0, 420.0), kind="disk", location=lamp, radius=0.2)
    P, ok = Camera(**cam).back_project(*p["target_uv"], 0.0)
    assert ok
    light = lights.from_controls(np.asarray(P), p["azimuth"], p["elevation"], p["distance"], "disk", p["radius"])
    np.testing.assert_allclose(light.position, mapping.to_pixgraph(M, lamp), atol=1e-9)
    assert mapping.to_pixgraph(M, lamp)[1] == pytest.approx(3.0)        # height above the ground is kept


def test_sun_direction_gives_azimuth_and_elevation():
    M = level()                                  # looking along +Y: pixgraph +Z is Blender -Y
    cam = params(matrix_world=M)
    # a sun up 30 deg, toward the camera's right (+X) and behind the camera (-Y)
    el, az = math.radians(30), math.radians(40)
    d = [math.cos(el) * math.sin(az), -math.cos(el) * math.cos(az), math.sin(el)]
    p = mapping.light_params(cam, M, (960.0, 900.0), kind="directional", direction=d, angular_radius_deg=0.3)
    assert p["azimuth"] == pytest.approx(40.0) and p["elevation"] == pytest.approx(30.0)


def test_graph_builds_with_host_inputs():
    from pixgraph.session import Session

    s = Session()
    cam = params(width=64, height=48)
    g = mapping.build_graph(s.builder(), camera=cam, light={"kind": "disk", "target_mode": "pixel",
                                                             "target_uv": [32.0, 40.0]},
                            template={"kind": "ground"}, samples=4, opacity=0.85,
                            background_colorspace="srgb", background_alpha="straight",
                            cutout_colorspace="linear", cutout_alpha="premultiplied")
    assert set(g.outputs) == {"composite", "shadow"}
    assert {"background", "cutout"} <= set(g.nodes)


def test_build_script_makes_the_zip_the_docs_name(tmp_path):
    import sys
    import tomllib
    import zipfile

    root = _path.parents[3]
    sys.path.insert(0, str(root / "hosts" / "blender"))
    try:
        import build
    finally:
        sys.path.pop(0)
    z = build.build(tmp_path)
    assert f"dist/{z.name}" in (root / "docs" / "blender.md").read_text()
    with zipfile.ZipFile(z) as f:
        names = set(f.namelist())
        manifest = tomllib.loads(f.read("pixgraph_blender/blender_manifest.toml").decode())
        init = f.read("pixgraph_blender/__init__.py").decode()
    assert names == {"pixgraph_blender/__init__.py", "pixgraph_blender/mapping.py",
                     "pixgraph_blender/blender_manifest.toml"}
    assert manifest["id"] == "pixgraph" and manifest["blender_version_min"] == "4.2.0"
    compile(init, "__init__.py", "exec")                       # the bpy half at least parses here
    assert f'"version": ({manifest["version"].replace(".", ", ")})' in init   # bl_info agrees with the manifest


@pytest.mark.parametrize("method", ["learned", "auto"])
def test_graph_with_the_learned_height_reads_the_cutouts_colour(method):
    from pixgraph.session import Session

    s = Session()
    cam = params(width=64, height=48)
    kw = dict(camera=cam, light={"kind": "disk", "target_mode": "pixel", "target_uv": [32.0, 40.0]},
              template={"kind": "ground"}, samples=4, opacity=0.85, background_colorspace="srgb",
              background_alpha="straight", cutout_colorspace="linear", cutout_alpha="premultiplied")
    g = mapping.build_graph(s.builder(), height_method=method, **kw)
    assert g.nodes["fg_h"].params["method"] == method
    ref = g.nodes["fg_h"].inputs["image"]
    assert (ref.node, ref.output) == ("cutout", "image")
    plain = mapping.build_graph(s.builder(), **kw)
    assert "image" not in plain.nodes["fg_h"].inputs and plain.nodes["fg_h"].params["method"] == "contact_line"
