"""Kernel nodes check their inputs before launching (issue 11, items 3 and 5).

Sizes that do not fit each other or the camera, images without alpha, and
impossible values (NaN, inf or negative pixel heights, degenerate or overflowing
lights) are bad input: exit 2 with one line naming the node and the input or
param, never a kernel reading outside its buffers, never exit 1, never NaN out.
Most cases run the CLI in-process (``cli.main``); a few run it as a subprocess.
"""
import os
import pathlib
import subprocess
import sys
import textwrap
import warnings

import numpy as np
import pytest

from pixgraph.cli import main
from pixgraph.session import Session
from pixgraph_nodes.ops.imageio import write_image

ROOT = pathlib.Path(__file__).resolve().parents[1]
N = 48          # the camera's size in these graphs (pixels)
HORIZON = 8.0

# the kernel nodes and the inputs each takes from the scene below
KERNEL_NODES = {
    "pixgraph.HardShadow": "mask: obj.alpha, fg_height: fg.height, bg_height: bg.height, light: light.light, "
                           "camera: cam.camera",
    "pixgraph.SoftShadow": "mask: obj.alpha, fg_height: fg.height, bg_height: bg.height, light: light.light, "
                           "camera: cam.camera",
    "pixgraph.BufferChannels": "mask: obj.alpha, fg_height: fg.height, bg_height: bg.height, "
                               "light: light.light, camera: cam.camera",
    "pixgraph.SoftShadowSSN": "mask: obj.alpha, fg_height: fg.height, bg_height: bg.height, "
                              "light: light.light, camera: cam.camera",
    "pixgraph.Reflection": "camera: cam.camera, cutout: obj.image, fg_height: fg.height, bg_height: bg.height",
    "pixgraph.Refraction": "camera: cam.camera, glass: obj.image, glass_height: fg.height, "
                           "background: photo.image, bg_height: bg.height",
}
FIRST_OUTPUT = {"pixgraph.HardShadow": "lit", "pixgraph.SoftShadow": "lit", "pixgraph.BufferChannels": "buffers",
                "pixgraph.SoftShadowSSN": "darkness", "pixgraph.Reflection": "layer",
                "pixgraph.Refraction": "layer"}


def scene(obj_size=N, photo_size=N, fg_size=None, bg_size=N):
    """A standing box (RGBA) with its upright pixel height on flat ground, and a photo."""
    fg_size = fg_size or obj_size
    obj = np.zeros((obj_size, obj_size, 4), np.float32)
    lo, hi = obj_size // 3, obj_size * 3 // 4
    obj[lo:hi, lo:lo + max(2, obj_size // 6)] = (0.6, 0.5, 0.4, 1.0)
    rows = np.arange(fg_size, dtype=np.float32)[:, None]
    fg = np.broadcast_to(np.maximum(hi - rows - 0.5, 0.0), (fg_size, fg_size)).astype(np.float32)
    photo = np.full((photo_size, photo_size, 3), 0.5, np.float32)
    bg = np.zeros((bg_size, bg_size), np.float32)
    return obj, fg, bg, photo


def write_graph(tmp_path, type_id, obj, fg, bg, photo, light=None, node_params=""):
    """A graph file: the scene's files, a camera, a light (params ``light`` over the
    defaults, YAML text each) and the node under test."""
    lp = {"target_mode": "pixel", "target_uv": "[24, 40]", "distance": "3", "radius": "0.3", **(light or {})}
    light_params = ", ".join(f"{k}: {v}" for k, v in lp.items())
    write_image(tmp_path / "obj.png", obj)
    write_image(tmp_path / "photo.png", photo)
    np.save(tmp_path / "fg.npy", fg)
    np.save(tmp_path / "bg.npy", bg)
    text = textwrap.dedent(f"""\
        pixgraph: 1
        nodes:
          obj: {{type: pixgraph.LoadImage, params: {{path: obj.png}}}}
          photo: {{type: pixgraph.LoadImage, params: {{path: photo.png}}}}
          fg: {{type: pixgraph.LoadPixelHeight, params: {{path: fg.npy}}}}
          bg: {{type: pixgraph.LoadPixelHeight, params: {{path: bg.npy}}}}
          cam: {{type: pixgraph.Camera, params: {{width: {N}, height: {N}, horizon: {HORIZON}}}}}
          light:
            type: pixgraph.Light
            inputs: {{camera: cam.camera}}
            params: {{{light_params}}}
          node:
            type: {type_id}
            inputs: {{{KERNEL_NODES[type_id]}}}
            params: {{{node_params}}}
        outputs: {{out: node.{FIRST_OUTPUT[type_id]}}}
        """)
    path = tmp_path / "g.yaml"
    path.write_text(text)
    return path


def run_cli(capsys, path):
    code = main(["run", str(path), "--no-disk-cache", "-q"])
    return code, capsys.readouterr().err.strip().splitlines()


@pytest.mark.parametrize("type_id", sorted(KERNEL_NODES))
def test_the_scene_runs(tmp_path, capsys, type_id):
    """The baseline every mismatch below breaks: the matching scene runs and is finite."""
    path = write_graph(tmp_path, type_id, *scene())
    out = Session(disk_cache=None).run(path)["out"]
    for a in (out.values() if isinstance(out, dict) else [out]):
        assert a.shape[:2] == (N, N) and np.isfinite(a).all()


@pytest.mark.parametrize("type_id", sorted(KERNEL_NODES))
@pytest.mark.parametrize("wrong", ["object_small", "object_large", "heights", "background"])
def test_mismatched_sizes_are_bad_input(tmp_path, capsys, type_id, wrong):
    """Each kernel node, each input in turn smaller or larger than the camera: exit 2
    naming the node and the sizes; the kernel never runs (no read outside a buffer)."""
    kw = {"object_small": dict(obj_size=8, fg_size=8), "object_large": dict(obj_size=N + 16, fg_size=N + 16),
          "heights": dict(fg_size=N // 2), "background": dict(bg_size=N + 5, photo_size=N + 5)}[wrong]
    path = write_graph(tmp_path, type_id, *scene(**kw))
    code, err = run_cli(capsys, path)
    assert code == 2, err
    assert len(err) == 1 and "Traceback" not in err[0]
    assert f"node 'node' ({type_id})" in err[0] and "same size" in err[0]
    assert f"camera {N}x{N}" in err[0]


def test_a_2048_background_under_an_8x8_glass_fails_at_once(tmp_path, capsys):
    """The issue's case (it hung for more than 90 s reading outside the glass's buffers)."""
    obj, fg, _, _ = scene(obj_size=8)
    big = np.zeros((2048, 2048), np.float32)
    path = write_graph(tmp_path, "pixgraph.Refraction", obj, fg, big, np.zeros((2048, 2048, 3), np.float32))
    code, err = run_cli(capsys, path)
    assert code == 2 and "glass 8x8" in err[0] and "background 2048x2048" in err[0]


@pytest.mark.parametrize("type_id", ["pixgraph.Reflection", "pixgraph.Refraction"])
def test_a_cutout_without_alpha_is_bad_input(tmp_path, capsys, type_id):
    obj, fg, bg, photo = scene()
    path = write_graph(tmp_path, type_id, obj[..., :3], fg, bg, photo)
    code, err = run_cli(capsys, path)
    assert code == 2 and len(err) == 1
    assert "must be RGBA" in err[0] and "got 3 channels" in err[0]


@pytest.mark.parametrize("type_id", sorted(KERNEL_NODES))
@pytest.mark.parametrize("value", [np.nan, np.inf, -3.0])
@pytest.mark.parametrize("which", ["fg", "bg"])
def test_impossible_pixel_heights_are_bad_input(tmp_path, capsys, type_id, value, which):
    """NaN, inf or negative heights where they matter: exit 2 naming the node and the input."""
    obj, fg, bg, photo = scene()
    target = fg if which == "fg" else bg
    target[30, 17] = value              # inside the object (column 16..23, rows 16..35)
    path = write_graph(tmp_path, type_id, obj, fg, bg, photo)
    code, err = run_cli(capsys, path)
    assert code == 2, err
    assert len(err) == 1
    if not np.isfinite(value):      # a .npy with NaN/inf never gets past its loader
        assert f"node '{which}' (pixgraph.LoadPixelHeight)" in err[0] and "non-finite" in err[0]
    else:
        port = {"pixgraph.Refraction": {"fg": "glass_height"}}.get(type_id, {}).get(which)
        port = port or ("fg_height" if which == "fg" else "bg_height")
        assert f"node 'node' ({type_id}): input '{port}'" in err[0]
        assert "negative at pixel u=17, v=30" in err[0]


def compute_directly(type_id, **replace):
    """Run one node's compute on the scene's values (``replace`` overrides inputs by
    port name), as any producer upstream could hand them over; no device: every
    case here must be refused before a kernel is launched."""
    from pixgraph.node import Namespace
    from pixgraph.registry import Registry
    from pixgraph_nodes.ops.camera import Camera
    from pixgraph_nodes.ops.lights import point_light

    spec = Registry.discover().get(type_id)
    obj, fg, bg, photo = scene()
    values = dict(mask=obj[..., 3].copy(), fg_height=fg, bg_height=bg, light=point_light((0.0, 2.0, -3.0)),
                  camera=Camera(N, N, 50.0, HORIZON), cutout=obj, glass=obj, glass_height=fg, background=photo,
                  receiver=None)
    values.update(replace)
    inputs = Namespace({p.name: values[p.name] if p.name in values else None for p in spec.inputs})
    params = Namespace({p.name: p.default for p in spec.params})
    return spec.cls().compute(None, inputs, params)


@pytest.mark.parametrize("type_id", sorted(KERNEL_NODES))
@pytest.mark.parametrize("value", [np.nan, np.inf])
def test_non_finite_heights_reaching_a_node_are_bad_input(type_id, value):
    """NaN/inf heights handed over by any upstream node (a predictor, a placement)
    are refused by the node itself, naming the input (the loaders and host inputs
    refuse them even earlier)."""
    from pixgraph.node import InputError

    fg = scene()[1].copy()
    fg[30, 17] = value
    port = "glass_height" if type_id == "pixgraph.Refraction" else "fg_height"
    with pytest.raises(InputError, match=rf"input '{port}'.*(NaN|infinite) at pixel u=17, v=30"):
        compute_directly(type_id, **{port: fg})


def test_heights_outside_the_mask_do_not_matter(tmp_path):
    """The cutout's height map is unused outside its mask: garbage there is fine."""
    obj, fg, bg, photo = scene()
    path = write_graph(tmp_path, "pixgraph.HardShadow", obj, fg, bg, photo)
    s = Session(disk_cache=None)
    clean = s.run(path)["out"]
    fg[0, 0] = -5.0
    assert np.array_equal(s.run(path, bind={"fg": fg})["out"], clean)
    assert (clean < 1).any()


@pytest.mark.parametrize("type_id", sorted(KERNEL_NODES))
def test_an_empty_mask_is_defined(tmp_path, type_id):
    """No cutout pixel: no shadow, no reflection, no refraction (documented), all finite."""
    obj, fg, bg, photo = scene()
    obj[...] = 0.0
    out = Session(disk_cache=None).run(write_graph(tmp_path, type_id, obj, fg, bg, photo))["out"]
    if type_id in ("pixgraph.HardShadow", "pixgraph.SoftShadow"):
        assert np.all(out == 1.0)                                   # lit
    elif type_id == "pixgraph.SoftShadowSSN":
        assert np.all(out == 0.0)                                   # darkness
    elif type_id == "pixgraph.BufferChannels":
        for k in ("hard_shadow", "sparse_hard_shadow_0", "relative_distance", "cutout_height"):
            assert np.all(out[k] == 0.0), k
    else:
        assert np.all(out == 0.0)                                   # a transparent layer


@pytest.mark.parametrize("params, field", [
    ({"distance": "1.0e+300"}, "param 'distance'"),
    ({"radius": "1.0e+300"}, "param 'radius'"),
    ({"distance": ".inf"}, "param 'distance'"),
])
def test_overflowing_lights_are_bad_input(tmp_path, capsys, params, field):
    path = write_graph(tmp_path, "pixgraph.SoftShadowSSN", *scene(), light=params)
    code, err = run_cli(capsys, path)
    assert code == 2 and len(err) == 1
    assert "node 'light'" in err[0] and field in err[0]


@pytest.mark.parametrize("tip, top, why", [
    ([24, 4], [24, 20, 10], "at or above the horizon"),     # the tip above the horizon
    ([24, 40], [24, 30, 0], "needs h > 0"),                  # a top without height
    ([24, 40], [24, 2, 3], "needs h > 0 and its foot below"),  # the top's foot above the horizon
])
def test_degenerate_shadow_tips_are_bad_input(tmp_path, capsys, tip, top, why):
    path = write_graph(tmp_path, "pixgraph.HardShadow", *scene(),
                       light={"placement": "shadow_tip", "tip_uv": str(tip), "top_uvh": str(top)})
    code, err = run_cli(capsys, path)
    assert code == 2 and len(err) == 1
    assert "node 'light'" in err[0] and "'tip_uv', 'top_uvh'" in err[0] and why in err[0]


def test_ssn_softness_is_clamped_never_nan(tmp_path, device):
    """The largest light the Light node accepts (radius 1e9 at distance 1e-6): SSN++
    clamps the softness to SOFTNESS_MAX and the composite stays finite (it was all
    NaN with radius 1e300); softness 1 and 1e15 give the same shadow."""
    from pixgraph_nodes.ops import ssn
    from pixgraph_nodes.ops.buffers import buffer_channels
    from pixgraph_nodes.ssn_soft_shadow import load_shipped

    path = write_graph(tmp_path, "pixgraph.SoftShadowSSN", *scene(), light={"radius": "1.0e+9", "distance": "1.0e-6"})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = Session(disk_cache=None).run(path)["out"]
    assert np.isfinite(out).all() and 0.0 <= out.min() and out.max() <= 1.0
    obj, fg, bg, _ = scene()
    mask = obj[..., 3]
    b = buffer_channels(device, mask, fg, bg, np.array([5.0, 5.0, 60.0, 1.0]), np.tile([5.0, 5.0, 60.0, 1.0], (4, 1)))
    model = load_shipped("ssnpp")
    at_max = ssn.predict(model, b, ssn.SOFTNESS_MAX)
    assert np.array_equal(ssn.predict(model, b, 1e15), at_max)
    assert np.array_equal(ssn.predict(model, b, float("inf")), at_max)
    with pytest.raises(ValueError, match="NaN"):
        ssn.predict(model, b, float("nan"))


def test_subprocess_exit_codes(tmp_path):
    """The real command line: a size mismatch and a NaN height file exit 2 with one
    line on stderr (test_the_scene_runs shows the same graph runs when they fit)."""
    env = dict(os.environ, XDG_CACHE_HOME=str(tmp_path / "xdg"))
    cases = []
    for name, kw, bad in (("size", dict(obj_size=8, fg_size=8), None), ("nan", {}, np.nan)):
        d = tmp_path / name
        d.mkdir()
        obj, fg, bg, photo = scene(**kw)
        if bad is not None:
            bg[3, 3] = bad
        cases.append((name, write_graph(d, "pixgraph.Refraction", obj, fg, bg, photo)))
    for name, path in cases:
        r = subprocess.run([sys.executable, "-m", "pixgraph", "run", str(path), "--no-disk-cache", "-q"],
                           capture_output=True, text=True, env=env, timeout=120)
        err = r.stderr.strip().splitlines()
        assert r.returncode == 2 and len(err) == 1, r.stderr
        assert ("node 'node'" if name == "size" else "node 'bg'") in err[0]


@pytest.mark.parametrize("type_id, port", [
    ("pixgraph.Refraction", "background"),
    ("pixgraph.Refraction", "glass"),
    ("pixgraph.Reflection", "cutout"),
])
@pytest.mark.parametrize("value", [np.nan, np.inf])
def test_non_finite_colours_are_bad_input(type_id, port, value):
    """A NaN colour from upstream would spread to the output: the node names the input."""
    from pixgraph.node import InputError

    obj, _, _, photo = scene()
    bad = (photo if port == "background" else obj).copy()
    bad[20, 18, 0] = value
    with pytest.raises(InputError, match=rf"input '{port}': 1 value\(s\) NaN or infinite \(first at pixel u=18, v=20\)"):
        compute_directly(type_id, **{port: bad})


@pytest.mark.parametrize("type_id", ["pixgraph.HardShadow", "pixgraph.SoftShadow", "pixgraph.BufferChannels",
                                     "pixgraph.SoftShadowSSN"])
def test_a_non_finite_mask_is_bad_input(type_id):
    from pixgraph.node import InputError

    mask = scene()[0][..., 3].copy()
    mask[20, 18] = np.nan
    with pytest.raises(InputError, match=r"input 'mask': 1 value\(s\) NaN or infinite \(first at pixel u=18, v=20\)"):
        compute_directly(type_id, mask=mask)


def test_a_sphere_above_the_horizon_is_bad_input(capsys):
    code = main(["run", str(ROOT / "graphs" / "crystal_ball.yaml"), "--no-disk-cache", "-q",
                 "--set", "ball.contact_v=-100"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert "node 'ball' (pixgraph.Sphere)" in err[0] and "below the horizon" in err[0]


def test_the_ops_refuse_mismatched_sizes_too(device):
    """Below the nodes, the OpenCL wrappers check sizes themselves (a script calling
    them directly never gets a read outside a buffer either)."""
    from pixgraph_nodes.ops import reflection as R
    from pixgraph_nodes.ops import shadow as S
    from pixgraph_nodes.ops.camera import Camera

    obj, fg, bg, photo = scene()
    cam = Camera(N, N, 50.0, HORIZON)
    with pytest.raises(ValueError, match="glass 8x8"):
        R.refraction_cl(device, cam, obj[:8, :8], fg[:8, :8], photo, bg)
    with pytest.raises(ValueError, match="camera's 32x32"):
        R.refraction_cl(device, Camera(32, 32, 50.0, HORIZON), obj, fg, photo, bg)
    with pytest.raises(ValueError, match="bg_height 24x24"):
        R.reflection_cl(device, cam, obj, fg, bg[:24, :24])
    with pytest.raises(ValueError, match="mask 48x40"):
        R.reflection_cl(device, cam, obj, fg, bg, mask=obj[:40, :, 3])
    with pytest.raises(ValueError, match="must be RGBA"):
        R.reflection_cl(device, cam, obj[..., :3], fg, bg)
    with pytest.raises(ValueError, match="share one"):
        S.soft_shadow(device, obj[..., 3], fg[:40], bg, np.array([[5.0, 5.0, 60.0, 1.0]]))
