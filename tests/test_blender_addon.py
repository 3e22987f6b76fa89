"""The Blender add-on in the real ``bpy`` wheel (5.0.x, in its own venv: numpy < 2).

Builds the add-on zip, installs it into a headless Blender as a user would, runs
its operator on a 128x128 scene (an 8-bit sRGB plate, a cutout box, a level camera
with a lens shift, a soft point light) and checks the pixels of the Blender images
it wrote, then renders the composite through Blender's compositor.
The first run builds the venv (downloads bpy); ``-m 'not blender'`` skips this.
"""
from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys
import time

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "hosts" / "blender"))
import bpy_env  # noqa: E402
import build  # noqa: E402

pytestmark = pytest.mark.blender

TINT = np.array([0.08, 0.09, 0.12])     # pixgraph.Composite's default tint
OPACITY = 0.85


def srgb_to_linear(c):
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(c):
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)


def _run_scene(work, *args):
    """Run tests/blender/addon_scene.py in the bpy venv with a fresh Blender user folder."""
    t0 = time.perf_counter()
    python = bpy_env.ensure(log=lambda m: print(m, file=sys.stderr))
    venv_s = time.perf_counter() - t0
    zip_path = build.build(work / "dist")
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(work / "blender-user"))
    env.setdefault("XDG_CACHE_HOME", str(work / "xdg"))
    t0 = time.perf_counter()
    proc = subprocess.run([str(python), str(ROOT / "tests" / "blender" / "addon_scene.py"), str(zip_path), str(work),
                           *args], capture_output=True, text=True, env=env, timeout=600)
    print(f"bpy venv {venv_s:.1f} s, Blender scene {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    line = next((ln for ln in proc.stdout.splitlines() if ln.startswith("REPORT ")), None)
    assert proc.returncode == 0 and line, proc.stdout[-3000:] + proc.stderr[-3000:]
    return json.loads(line[len("REPORT "):])


def test_legacy_addon_install_registers(tmp_path):
    report = _run_scene(tmp_path, "legacy", "install-only")
    assert report["registered"] and report["mode"] == "legacy"
    assert report["addon_file"].endswith("scripts/addons/pixgraph_blender/__init__.py")


@pytest.fixture(scope="module")
def blender_run(tmp_path_factory):
    work = tmp_path_factory.mktemp("blender")
    report = _run_scene(work, "extension")
    arrays = {k: np.load(work / f"{k}.npy") for k in ("composite", "shadow", "render", "example", "example_cli",
                                                      "example_shadow", "example_cli_shadow")}
    return report, arrays


def test_operator_wrote_linear_composite_and_data_shadow(blender_run):
    report, _ = blender_run
    assert report["blender"].startswith("5.0")
    assert report["mode"] == "extension" and report["registered"]
    assert report["addon_file"].endswith("extensions/user_default/pixgraph/__init__.py")   # the installed zip
    assert report["operator"] == ["FINISHED"]
    assert report["composite"] == {"size": [128, 128], "is_float": True, "colorspace": "Linear Rec.709"}
    assert report["shadow"] == {"size": [128, 128], "is_float": True, "colorspace": "Non-Color"}


def test_camera_maps_to_blenders_projection(blender_run):
    report, _ = blender_run
    cam = report["camera_params"]
    assert cam["hfov"] == pytest.approx(2 * np.degrees(np.arctan(18 / 35)), abs=1e-6)
    assert cam["horizon"] == pytest.approx(64 - 0.2 * 128, abs=1e-4)
    assert cam["cam_height"] == pytest.approx(1.2, abs=1e-6)
    for pair in report["projection_pairs"]:             # ground points and points in the air
        np.testing.assert_allclose(pair["pixgraph"], pair["blender"], atol=1e-3)
    np.testing.assert_allclose(report["foot_px"], report["expected_foot_px"], atol=1e-3)


def test_pitched_camera_is_a_clear_error(blender_run):
    report, _ = blender_run
    assert "pitched -10.00 deg" in report["pitched_error"] and "level camera" in report["pitched_error"]
    assert report["pitched_operator"].startswith("Error: the camera is pitched")


def _segment(report, *fractions):
    foot, tip = np.array(report["foot_px"]), np.array(report["tip_px"])
    return [foot + f * (tip - foot) for f in fractions]


def _at(a, uv):
    return a[int(uv[1]), int(uv[0])]


def test_shadow_where_blender_geometry_puts_it(blender_run):
    report, arrays = blender_run
    comp, shadow = arrays["composite"][..., :3], arrays["shadow"][..., 0]
    box = report["box"]
    bg = srgb_to_linear(128 / 255)                       # the 8-bit sRGB plate, in linear light
    inside = np.zeros(shadow.shape, bool)
    inside[box["top"]:box["bottom"], box["left"]:box["right"]] = True
    # the shadow pass is grey data in all channels; the composite is the plate darkened by it
    np.testing.assert_array_equal(arrays["shadow"][..., 1], shadow)
    expect = bg * (1 - OPACITY * shadow[..., None] * (1 - TINT))
    np.testing.assert_allclose(comp[~inside], expect[~inside], atol=2e-5)
    # umbra: from just past the cutout to near the tip of the top's shadow (Blender's geometry)
    for uv in _segment(report, 0.5, 0.7, 0.85):
        assert not _at(inside, uv)
        assert _at(shadow, uv) > 0.95, uv
        np.testing.assert_allclose(_at(comp, uv) / bg, 1 - OPACITY * (1 - TINT), atol=0.01)  # 0.218.. of the plate
    # lit: well beyond the tip, on the far side of the foot, and in front of the object
    for uv in _segment(report, 1.4, -0.6) + [np.array([62.0, 115.0]), np.array([10.0, 120.0])]:
        assert _at(shadow, uv) < 0.02, uv
        np.testing.assert_allclose(_at(comp, uv), bg, atol=0.002)
    # the whole shadow lies between the foot's row and the horizon, right of the object's left edge
    ys, xs = np.nonzero(shadow > 0.5)
    assert ys.max() < box["bottom"] and ys.min() > report["camera_params"]["horizon"]
    assert xs.min() >= box["left"]
    # the cutout is the 8-bit sRGB red, decoded to linear
    np.testing.assert_allclose(comp[80, 62], srgb_to_linear(np.array([200, 50, 30]) / 255), atol=1e-5)


def test_compositor_renders_the_composite_in_standard_view(blender_run):
    report, arrays = blender_run
    render, comp = arrays["render"][..., :3], arrays["composite"][..., :3]
    assert render[120, 10] * 255 == pytest.approx([128, 128, 128], abs=0.01)   # the plate comes back as it went in
    assert render[80, 62] * 255 == pytest.approx([200, 50, 30], abs=0.01)
    umbra = _segment(report, 0.7)[0]
    np.testing.assert_allclose(_at(render, umbra) * 255, linear_to_srgb(_at(comp, umbra)) * 255, atol=0.51)
    assert (_at(render, umbra) * 255 < 70).all()


def test_progress_reaches_one_and_cancel_is_reported(blender_run):
    report, _ = blender_run
    assert report["progress_error"] is None
    kinds = [k for k, _ in report["progress"]]
    assert kinds[0] == "RunStarted" and kinds[-1] == "RunFinished"
    fractions = [f for _, f in report["progress"]]
    assert fractions == sorted(fractions) and fractions[-1] == pytest.approx(1.0)
    assert report["rerun_after_samples"] == ["comp", "shadow"]   # the rest came from the session's cache
    assert report["cancelled"] == "cancelled"


def test_readme_main_job_in_blender_matches_the_graph_file(blender_run):
    # the add-on with Blender's camera and the panel's light on graphs/assets, against
    # `graphs/wall_corner_shadow.yaml` run from its file: same camera, light, template
    report, arrays = blender_run
    assert report["example_operator"] == ["FINISHED"]
    shadow, cli_shadow = arrays["example_shadow"], arrays["example_cli_shadow"]
    assert shadow.shape == cli_shadow.shape == (512, 512)
    assert cli_shadow.max() > 0.9 and (cli_shadow > 0.5).sum() > 2000       # a real shadow to compare
    np.testing.assert_allclose(shadow, cli_shadow, atol=1e-6)                # measured: identical
    # composite: Blender decodes the JPEG plate itself (measured identical with bpy 5.0.1;
    # another libjpeg could differ by a code value, which this tolerance allows)
    diff = np.abs(arrays["example"] - arrays["example_cli"])
    assert diff.mean() < 1e-4 and np.percentile(diff, 99.9) < 0.01


def test_learned_cutout_height_in_blender_without_torch(blender_run):
    # the panel's "Cutout height: Learned" runs the numpy network in Blender's own Python
    # (the bpy venv has no torch): the node says it used the learned map and the shadow moves
    report, _ = blender_run
    assert report["learned_operator"] == ["FINISHED"]
    assert any("learned height (confidence" in line for line in report["learned_said"]), report["learned_said"]
    assert report["learned_shadow_change"] > 0.01
    assert report["torch_imported"] is False
