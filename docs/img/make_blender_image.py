"""docs/img/blender_wall_corner.jpg: the add-on's result in headless Blender (bpy 5.0).

    python docs/img/make_blender_image.py

Runs tests/blender/addon_scene.py in the bpy venv (hosts/blender/bpy_env.py): its
last phase sets up the README's main job in Blender (camera, panel light, wall
corner) and renders the add-on's composite through the compositor (Standard view).
Left: that render; right: the add-on's shadow pass (white = lit).
"""
import os
import pathlib
import subprocess
import sys
import tempfile

import numpy as np
import OpenImageIO as oiio

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "hosts" / "blender"))
import bpy_env  # noqa: E402
import build  # noqa: E402

with tempfile.TemporaryDirectory() as tmp:
    tmp = pathlib.Path(tmp)
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp / "user"))
    subprocess.run([str(bpy_env.ensure()), str(ROOT / "tests" / "blender" / "addon_scene.py"),
                    str(build.build(tmp / "dist")), str(tmp)], check=True, env=env, capture_output=True)
    render = oiio.ImageBuf(str(tmp / "example.png")).get_pixels(oiio.FLOAT)[..., :3]
    lit = 1.0 - np.repeat(np.load(tmp / "example_shadow.npy")[..., None], 3, axis=2)
h = render.shape[0]
img = np.concatenate([render, np.ones((h, 8, 3), np.float32), lit.astype(np.float32)], axis=1)
buf = oiio.ImageBuf(oiio.ImageSpec(img.shape[1], h, 3, oiio.FLOAT))
buf.set_pixels(oiio.ROI(), img)
small = oiio.ImageBufAlgo.resize(buf, roi=oiio.ROI(0, img.shape[1] // 2, 0, h // 2, 0, 1, 0, 3))
small.write(str(ROOT / "docs" / "img" / "blender_wall_corner.jpg"), oiio.UINT8)
