"""Run inside the bpy venv (tests/test_blender_addon.py does): install the add-on zip
into a headless Blender, build a small scene, run the add-on's operator, and print
a JSON report of what Blender holds afterwards (pixels, colour spaces, projections).

    python addon_scene.py ADDON_ZIP WORKDIR [extension|legacy [install-only]]
"""
import json
import math
import os
import sys

import bpy
import numpy as np
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Vector

zip_path, work = sys.argv[1], sys.argv[2]
W = H = 128
report = {"blender": bpy.app.version_string}

# -- the add-on, installed from its zip as a user would -----------------------------
mode = sys.argv[3] if len(sys.argv) > 3 else "extension"
if mode == "legacy":          # Blender < 4.2 style: Preferences > Add-ons > Install (bl_info)
    bpy.ops.preferences.addon_install(filepath=zip_path, overwrite=True)
    bpy.ops.preferences.addon_enable(module="pixgraph_blender")
    module = "pixgraph_blender"
else:                         # Blender 4.2+: an extension (blender_manifest.toml)
    bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
    module = "bl_ext.user_default.pixgraph"
import importlib  # noqa: E402

pixgraph_blender = importlib.import_module(module)
mapping = importlib.import_module(module + ".mapping")
report["mode"] = mode
report["registered"] = hasattr(bpy.types.Scene, "pixgraph") and hasattr(bpy.ops.pixgraph, "composite")
if len(sys.argv) > 4 and sys.argv[4] == "install-only":
    print("REPORT " + json.dumps({**report, "addon_file": pixgraph_blender.__file__}))
    sys.exit(0)
report["addon_file"] = pixgraph_blender.__file__

scene = bpy.context.scene
scene.render.resolution_x, scene.render.resolution_y = W, H
scene.render.resolution_percentage = 100
scene.view_settings.view_transform = "Standard"
scene.view_settings.look = "None"
scene.render.dither_intensity = 0.0          # exact 8-bit values in the render
scene.display_settings.display_device = "sRGB"

# -- a level camera 1.2 m above the ground, horizon raised by a lens shift ----------
cam_data = bpy.data.cameras.new("cam")
cam_data.lens, cam_data.sensor_width, cam_data.sensor_fit = 35.0, 36.0, "AUTO"
cam_data.shift_y = -0.2
cam = bpy.data.objects.new("cam", cam_data)
cam.location = (0.3, -0.5, 1.2)
cam.rotation_euler = (math.radians(90), 0.0, math.radians(10))   # level, turned 10 deg
scene.collection.objects.link(cam)
scene.camera = cam

# -- a point light front-left of the object, 0.15 m soft radius ---------------------
light_data = bpy.data.lights.new("lamp", "POINT")
light_data.shadow_soft_size = 0.15
lamp = bpy.data.objects.new("lamp", light_data)
lamp.location = (-1.2, 1.0, 2.6)
scene.collection.objects.link(lamp)
bpy.context.view_layer.update()

# -- images: an 8-bit sRGB background (value 128) and an 8-bit cutout box -----------
bg = bpy.data.images.new("plate", W, H, alpha=False, float_buffer=False)
bg.colorspace_settings.name = "sRGB"
bg.pixels.foreach_set(np.tile([128 / 255, 128 / 255, 128 / 255, 1.0], W * H).astype(np.float32))
cut = bpy.data.images.new("figure", W, H, alpha=True, float_buffer=False)
rgba = np.zeros((H, W, 4), np.float32)                       # rows from the top
top, bottom, left, right = 58, 100, 54, 70                   # the box stands on row 100
rgba[top:bottom, left:right] = [200 / 255, 50 / 255, 30 / 255, 1.0]
cut.pixels.foreach_set(rgba[::-1].ravel())
box = dict(top=top, bottom=bottom, left=left, right=right)

s = scene.pixgraph
s.background, s.cutout, s.light = bg, cut, lamp
s.template, s.samples, s.opacity = "ground", 32, 0.85
s.thickness = 1.0                                            # a flat card: one pixel deep

# -- run the operator as a script would (blocking) ----------------------------------
result = bpy.ops.pixgraph.composite()
report["operator"] = sorted(result)
comp = bpy.data.images[s.composite_name]
shadow = bpy.data.images[s.shadow_name]


def pixels(img):
    a = np.empty(img.size[0] * img.size[1] * 4, np.float32)
    img.pixels.foreach_get(a)
    return a.reshape(img.size[1], img.size[0], 4)[::-1]     # rows from the top


np.save(os.path.join(work, "composite.npy"), pixels(comp))
np.save(os.path.join(work, "shadow.npy"), pixels(shadow))
report["composite"] = {"size": list(comp.size), "is_float": comp.is_float,
                       "colorspace": comp.colorspace_settings.name}
report["shadow"] = {"size": list(shadow.size), "is_float": shadow.is_float,
                    "colorspace": shadow.colorspace_settings.name}


# -- where Blender itself says the object's foot and its shadow are -----------------
def to_pixel(p):
    """Blender's own projection of a world point to (column, row from the top) pixels."""
    c = world_to_camera_view(scene, cam, Vector(p))
    return [c.x * W, (1.0 - c.y) * H]


def ground_point(u, v):
    """The ground (z = 0) point seen at pixel (u, v), by Blender's camera frame."""
    frame = [cam.matrix_world @ corner for corner in cam_data.view_frame(scene=scene)]
    # view_frame: top-right, bottom-right, bottom-left, top-left (on a plane in front)
    tr, br, bl, tl = frame
    x, y = u / W, v / H
    p = tl + (tr - tl) * x + (bl - tl) * y
    o = cam.matrix_world.translation
    d = p - o
    t = -o.z / d.z
    return o + d * t


foot_u, foot_v = (left + right) / 2.0, float(bottom)
F = ground_point(foot_u, foot_v)
D = F - cam.matrix_world.translation
D.z = 0.0
# the box's top edge: the same depth as the foot, straight up (a billboard facing the camera)
o = cam.matrix_world.translation
frame = [cam.matrix_world @ c for c in cam_data.view_frame(scene=scene)]
tr, br, bl, tl = frame
ptop = tl + (tr - tl) * (foot_u / W) + (bl - tl) * (top / H)
# the point on the ray through (foot_u, top) above F: same horizontal distance as F
dtop = ptop - o
k = D.length / Vector((dtop.x, dtop.y, 0.0)).length
T = o + dtop * k
L = lamp.matrix_world.translation
t = L.z / (L.z - T.z)
tip = L + (T - L) * t                                # the top's shadow on the ground
report["foot_world"] = list(F)
report["top_height"] = T.z
report["foot_px"] = to_pixel(F)
report["tip_px"] = to_pixel(tip)
report["expected_foot_px"] = [foot_u, foot_v]

# the add-on's camera mapping against Blender's projection, for a few ground and air points
cam_params = mapping.camera_params(lens_mm=cam_data.lens, sensor_width_mm=cam_data.sensor_width,
                                   sensor_height_mm=cam_data.sensor_height, sensor_fit=cam_data.sensor_fit,
                                   shift_x=cam_data.shift_x, shift_y=cam_data.shift_y, width=W, height=H,
                                   matrix_world=[list(r) for r in cam.matrix_world])
from pixgraph_nodes.ops.camera import Camera  # noqa: E402

pg = Camera(**cam_params)
pairs = []
for p in [F, tip, Vector((1.0, 4.0, 0.0)), Vector((-0.5, 2.5, 0.7)), Vector((0.8, 6.0, 1.5))]:
    uvh, _ = pg.project(mapping.to_pixgraph([list(r) for r in cam.matrix_world], list(p)))
    pairs.append({"blender": to_pixel(p), "pixgraph": [float(uvh[0]), float(uvh[1])]})
report["projection_pairs"] = pairs
report["camera_params"] = cam_params

# progress and cancellation, through the add-on's Job (what the modal operator runs in
# a thread; a modal operator needs a window, which headless Blender has not)
s.samples = 40                               # a new key: the shadow and composite run again
job = pixgraph_blender.Job(bpy.context)
seen = []
on_event = job.on_event
job.on_event = lambda e: (on_event(e), seen.append([type(e).__name__, job.fraction]))
job.run()
report["progress"] = seen
progress_ran = sorted(pixgraph_blender.session().last_run.ran)
report["progress_error"] = None if job.error is None else repr(job.error)
s.samples = 41
job = pixgraph_blender.Job(bpy.context)
job.cancel.cancel()                          # Esc before the first node
job.run()
report["cancelled"] = pixgraph_blender._message(job.error) if job.error else None
report["rerun_after_samples"] = progress_ran
s.samples = 32

# the learned cutout height in Blender's Python (numpy network, no torch)
contact_shadow = pixels(bpy.data.images[s.shadow_name])[..., 0]
s.height_method = "learned"
report["learned_operator"] = sorted(bpy.ops.pixgraph.composite())
said = pixgraph_blender.session().last_run.said
report["learned_said"] = [str(x) for x in said.get("fg_h", ())]
report["learned_shadow_change"] = float(np.abs(pixels(bpy.data.images[s.shadow_name])[..., 0] - contact_shadow).max())
report["torch_imported"] = "torch" in sys.modules
s.height_method = "contact_line"
bpy.ops.pixgraph.composite()                 # the images as the sections below expect them

# errors are messages, not crashes: a pitched camera
cam.rotation_euler = (math.radians(80), 0.0, 0.0)
bpy.context.view_layer.update()
try:
    mapping.camera_params(lens_mm=35, sensor_width_mm=36, sensor_height_mm=24, sensor_fit="AUTO", shift_x=0,
                          shift_y=0, width=W, height=H, matrix_world=[list(r) for r in cam.matrix_world])
    report["pitched_error"] = None
except mapping.HostError as e:
    report["pitched_error"] = str(e)
try:
    report["pitched_operator"] = sorted(bpy.ops.pixgraph.composite())
except RuntimeError as e:          # bpy.ops raises with the operator's ERROR report
    report["pitched_operator"] = str(e)
cam.rotation_euler = (math.radians(90), 0.0, math.radians(10))
bpy.context.view_layer.update()

# -- the compositor uses the composite image: render it through an Image node -------
tree = bpy.data.node_groups.new("pixgraph test", "CompositorNodeTree")
tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
img_node = tree.nodes.new("CompositorNodeImage")
img_node.image = comp
out_node = tree.nodes.new("NodeGroupOutput")
tree.links.new(img_node.outputs["Image"], out_node.inputs[0])
scene.compositing_node_group = tree
scene.render.use_compositing = True
scene.render.engine = "CYCLES"
scene.cycles.samples = 1
scene.cycles.device = "CPU"
scene.render.image_settings.file_format = "PNG"
scene.render.image_settings.color_mode = "RGB"
scene.render.image_settings.color_depth = "8"
scene.render.filepath = os.path.join(work, "render.png")
bpy.ops.render.render(write_still=True)
rendered = bpy.data.images.load(scene.render.filepath)
np.save(os.path.join(work, "render.npy"), pixels(rendered))
report["box"] = box

# -- the README's main job, set up in Blender, against the same graph run from its file ---
# graphs/wall_corner_shadow.yaml: 512x512, hfov 50, horizon row 120, cam_height 1, a disk
# light by azimuth/elevation around the cutout's foot, the wall-corner template.
repo = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
assets = os.path.join(repo, "graphs", "assets")
s.background = bpy.data.images.load(os.path.join(assets, "room_corner.jpg"))
s.cutout = bpy.data.images.load(os.path.join(assets, "figure.png"))
cam_data.lens = 18.0 / math.tan(math.radians(25.0))        # hfov 50 on a 36 mm sensor
cam_data.shift_y = (120.0 - 256.0) / 512.0                  # horizon at row 120
cam.location = (0.0, 0.0, 1.0)
cam.rotation_euler = (math.radians(90), 0.0, 0.0)
bpy.context.view_layer.update()
s.light = None                                              # the panel's values
s.azimuth, s.elevation, s.distance, s.radius = -25.0, 32.0, 4.0, 0.25
s.template, s.corner, s.left_slope, s.right_slope = "wall_corner", (300.0, 300.0), -0.35, 0.45
s.samples, s.opacity, s.tint, s.thickness = 48, 0.85, (0.10, 0.11, 0.14), 6.0
report["example_operator"] = sorted(bpy.ops.pixgraph.composite())
example = pixels(bpy.data.images[s.composite_name])[..., :3]
from pixgraph.session import Session  # noqa: E402

cli = Session().run(os.path.join(repo, "graphs", "wall_corner_shadow.yaml"),
                    outputs=["final", "shadow.darkness"])
np.save(os.path.join(work, "example.npy"), example)
np.save(os.path.join(work, "example_cli.npy"), cli["final"])
np.save(os.path.join(work, "example_shadow.npy"), pixels(bpy.data.images[s.shadow_name])[..., 0])
np.save(os.path.join(work, "example_cli_shadow.npy"), cli["shadow.darkness"])
scene.render.resolution_x = scene.render.resolution_y = 512
img_node.image = bpy.data.images[s.composite_name]
scene.render.filepath = os.path.join(work, "example.png")
bpy.ops.render.render(write_still=True)
print("REPORT " + json.dumps(report))
