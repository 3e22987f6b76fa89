"""Make the example graphs' assets procedurally (run from anywhere):

    python graphs/assets/make_assets.py

- ``figure.png``: a 512x512 RGBA cutout of a standing mannequin, shaded, straight alpha.
- ``figure_far.png``: the same cutout standing 150 rows higher (further back on a
  ground plane), so that its reflection on a glossy floor stays in the frame.
- ``room_ground.jpg``, ``room_corner.jpg``, ``room_steps.jpg``: 512x512 "photos" of
  a floor, a wall corner and a staircase, rendered from the *same* pixel-height
  templates and camera as the graphs that use them (floor boards, plaster walls,
  soft light from the graphs' light direction, ambient occlusion at the junctions),
  so the traced shadow lands on geometry that matches the picture.

Everything is deterministic (fixed seeds). The graphs' Camera/BackgroundHeight
params must stay in step with SCENES below.
"""
from __future__ import annotations

import math
import pathlib

import numpy as np

from pixgraph_nodes.ops import heightmaps as hm
from pixgraph_nodes.ops.camera import Camera
from pixgraph_nodes.ops.geometry import reconstruct_geometry
from pixgraph_nodes.ops.imageio import write_image

HERE = pathlib.Path(__file__).resolve().parent

SIZE = 512
CAMERA = dict(width=SIZE, height=SIZE, hfov=50.0, horizon=120.0, cam_height=1.0)
#: where the figure stands (bottom edge of its lowest pixels) and its height, pixels
FOOT_UV = (256.0, 440.0)
FIGURE_PX = 270.0

SCENES = {
    "room_ground": dict(kind="ground", light=(-50.0, 35.0)),
    "room_corner": dict(kind="wall_corner", corner=(300.0, 300.0), left_slope=-0.35, right_slope=0.45,
                        light=(-25.0, 32.0)),
    "room_steps": dict(kind="steps", step_distance=2.2, step_rise=0.12, step_run=0.3, step_count=5,
                       light=(-40.0, 40.0)),
}


# -- the cutout --------------------------------------------------------------------

def _capsule(p, a, b, r):
    """Signed distance from points p (..., 3) to the capsule a-b of radius r."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    ba = b - a
    t = np.clip(((p - a) @ ba) / (ba @ ba), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[..., None] * ba), axis=-1) - r


def _smin(a, b, k):
    """Smooth minimum (polynomial, radius k): rounded joints between body parts."""
    h = np.clip(0.5 + 0.5 * (b - a) / k, 0.0, 1.0)
    return b * (1 - h) + a * h - k * h * (1 - h)


# (start, end, radius, colour index) in figure units: 1 = FIGURE_PX, y up, z toward camera
_PARTS = [
    ((-0.055, 0.03, 0.02), (-0.045, 0.44, 0.0), 0.042, 0),    # left leg
    ((0.055, 0.03, 0.02), (0.045, 0.44, 0.0), 0.042, 0),      # right leg
    ((-0.06, 0.015, 0.07), (-0.055, 0.02, 0.0), 0.028, 2),    # left shoe
    ((0.06, 0.015, 0.07), (0.055, 0.02, 0.0), 0.028, 2),      # right shoe
    ((0.0, 0.46, 0.0), (0.0, 0.74, 0.0), 0.095, 1),           # torso
    ((-0.11, 0.74, 0.0), (-0.17, 0.47, 0.05), 0.034, 1),      # left arm, hanging
    ((0.11, 0.74, 0.0), (0.25, 0.58, 0.06), 0.034, 1),        # right arm, bent out
    ((0.25, 0.58, 0.06), (0.31, 0.74, 0.08), 0.03, 3),        # right forearm, raised
    ((0.0, 0.78, 0.0), (0.0, 0.84, 0.0), 0.035, 3),           # neck
    ((0.0, 0.92, 0.0), (0.0, 0.925, 0.0), 0.075, 3),          # head
]
_COLOURS = np.array([[0.10, 0.11, 0.16], [0.70, 0.16, 0.10], [0.05, 0.05, 0.05], [0.80, 0.56, 0.42]])


def _figure_sdf(p):
    d = None
    col = None
    best = None
    for a, b, r, c in _PARTS:
        di = _capsule(p, a, b, r)
        if d is None:
            d, best, col = di, di, np.full(di.shape, c)
        else:
            col = np.where(di < best, c, col)
            best = np.minimum(best, di)
            d = _smin(d, di, 0.02)
    return d, col


def make_figure(light_dir=(-0.55, 0.6, 0.58), ss: int = 2) -> np.ndarray:
    """Straight-alpha RGBA float32 (512, 512, 4), sRGB-ready linear colour in [0, 1]."""
    n = SIZE * ss
    u = (np.arange(n) + 0.5) / ss
    uu, vv = np.meshgrid(u, u)
    x = (uu - FOOT_UV[0]) / FIGURE_PX
    y = (FOOT_UV[1] - vv) / FIGURE_PX
    box = (np.abs(x) < 0.45) & (y > -0.01) & (y < 1.02)
    px, py = x[box], y[box]
    # orthographic rays along -z: sphere tracing from z = 0.5
    z = np.full(px.shape, 0.5)
    hit = np.zeros(px.shape, bool)
    for _ in range(80):
        p = np.stack([px, py, z], -1)
        d, _ = _figure_sdf(p)
        hit |= d < 1e-4
        z = np.where(hit, z, z - np.maximum(d, 1e-4))
        if np.all(hit | (z < -0.5)):
            break
    p = np.stack([px, py, z], -1)
    e = 1e-3
    grad = np.stack([(_figure_sdf(p + dv)[0] - _figure_sdf(p - dv)[0])
                     for dv in np.eye(3) * e], -1)
    nrm = grad / np.maximum(np.linalg.norm(grad, axis=-1, keepdims=True), 1e-9)
    _, col = _figure_sdf(p)
    L = np.asarray(light_dir) / np.linalg.norm(light_dir)
    diffuse = np.clip(nrm @ L, 0.0, 1.0)
    sky = 0.5 + 0.5 * nrm[:, 1]                                 # hemisphere fill from above
    rim = np.clip(1.0 - nrm[:, 2], 0.0, 1.0) ** 3 * 0.15        # soft rim at grazing angles
    shade = 0.85 * diffuse + 0.22 * sky + rim
    rgb = _COLOURS[col] * shade[:, None]
    # contact darkening at the feet: the floor's light does not reach under the shoes
    rgb *= (0.55 + 0.45 * np.clip(py / 0.05, 0.0, 1.0))[:, None]
    img = np.zeros((n, n, 4))
    full = np.zeros((box.sum(), 4))
    full[:, :3] = rgb
    full[:, 3] = 1.0
    full[~hit] = 0.0
    img[box] = full
    # box-filter the supersamples: premultiplied average, then back to straight alpha
    img = img.reshape(SIZE, ss, SIZE, ss, 4).mean(axis=(1, 3))
    a = img[..., 3:]
    img[..., :3] = np.where(a > 0, img[..., :3] / np.maximum(a, 1e-9), 0.0)
    return np.clip(img, 0.0, 1.0).astype(np.float32)


# -- the backgrounds -------------------------------------------------------------------

def _noise(shape, seed, scale):
    """Smooth value noise: bilinear upsampling of a coarse random grid, in [0, 1]."""
    rng = np.random.default_rng(seed)
    gh, gw = max(2, shape[0] // scale + 2), max(2, shape[1] // scale + 2)
    g = rng.random((gh, gw))
    ys = np.arange(shape[0]) / scale
    xs = np.arange(shape[1]) / scale
    y0, x0 = ys.astype(int), xs.astype(int)
    fy, fx = (ys - y0)[:, None], (xs - x0)[None, :]
    fy, fx = fy * fy * (3 - 2 * fy), fx * fx * (3 - 2 * fx)
    return (g[y0][:, x0] * (1 - fx) * (1 - fy) + g[y0][:, x0 + 1] * fx * (1 - fy)
            + g[y0 + 1][:, x0] * (1 - fx) * fy + g[y0 + 1][:, x0 + 1] * fx * fy)


def background_height(cam: Camera, scene: dict) -> np.ndarray:
    k = scene["kind"]
    if k == "back_wall":
        return hm.wall_from_junction(cam.width, cam.height, scene["junction_points"])
    if k == "ground":
        return hm.ground(cam.width, cam.height)
    if k == "wall_corner":
        return hm.wall_corner(cam.width, cam.height, scene["corner"], scene["left_slope"], scene["right_slope"])
    if k == "steps":
        return hm.steps(cam, scene["step_distance"], scene["step_rise"], scene["step_run"], scene["step_count"])
    raise ValueError(k)


def render_background(name: str, scene: dict | None = None, camera: dict | None = None) -> np.ndarray:
    """Linear RGB float32 (H, W, 3) of one scene (``SCENES[name]`` and the 512x512
    ``CAMERA`` unless given)."""
    scene = SCENES[name] if scene is None else scene
    cam = Camera(**(CAMERA if camera is None else camera))
    h = background_height(cam, scene)
    g = reconstruct_geometry(cam, h)
    P, N, valid = g.position.astype(np.float64), g.normal.astype(np.float64), g.valid > 0
    az, el = (math.radians(a) for a in scene["light"])
    L = np.array([math.cos(el) * math.sin(az), math.sin(el), math.cos(el) * math.cos(az)])
    floor = valid & (N[..., 1] > 0.7)
    wall = valid & ~floor
    X, Y, Z = P[..., 0], P[..., 1], P[..., 2]
    rgb = np.zeros(h.shape + (3,))
    # floor: oak boards running away from the camera, 0.12 wide, with grain and seams
    board = np.floor(X / 0.12)
    rng = np.random.default_rng(7)
    tone = rng.uniform(0.85, 1.15, 4096)[(board.astype(int) % 4096)]
    grain = 0.9 + 0.1 * np.sin(X * 180.0 + 3.0 * np.sin(Z * 7.0 + board))
    seam = np.clip(np.abs((X / 0.12) - np.round(X / 0.12)) * 0.12 / 0.004, 0.0, 1.0)
    wood = np.array([0.42, 0.26, 0.14])
    boards = tone * grain * (0.55 + 0.45 * seam)
    # far away the boards are finer than a pixel: fade to their mean instead of aliasing
    far = np.clip((g.depth - 3.0) / 8.0, 0.0, 1.0)
    boards = boards * (1 - far) + 0.85 * far
    rgb[floor] = wood[None] * boards[floor][:, None]
    # walls: warm plaster with a soft mottle
    mott = 0.93 + 0.07 * _noise(h.shape, 3, 24)
    plaster = np.array([0.62, 0.55, 0.46])
    rgb[wall] = plaster[None] * mott[wall][:, None]
    # steps: painted treads, stone risers
    if scene["kind"] == "steps":
        tread = floor & (Y > 1e-4)
        rgb[tread] = np.array([0.55, 0.52, 0.48])[None] * mott[tread][:, None]
        rgb[wall] = np.array([0.45, 0.43, 0.40])[None] * mott[wall][:, None]
    # light: the graph's light direction (diffuse) plus a sky fill, darker far away
    diffuse = np.clip((N * L).sum(-1), 0.0, 1.0)
    light = 0.9 * diffuse + 0.35 * (0.6 + 0.4 * N[..., 1])
    # ambient occlusion along the floor/wall junction: dim within ~0.3 world units of it
    if scene["kind"] == "wall_corner":
        cu, cv = scene["corner"]
        vw = hm.junction_rows(cam.width, ((cu - 1, cv - scene["left_slope"]), (cu, cv),
                                          (cu + 1, cv + scene["right_slope"])))
        J, _ = cam.back_project(np.arange(cam.width) + 0.5, vw, np.zeros(cam.width))
        dist = np.where(floor, np.abs(Z - J[None, :, 2]), Y)
        light *= 0.65 + 0.35 * np.clip(dist / 0.3, 0.0, 1.0) ** 0.7
    rgb *= light[..., None]
    # above the horizon with no surface: a studio backdrop gradient
    v = np.arange(h.shape[0])[:, None] + 0.5
    sky = np.stack([0.55 - 0.1 * v / 512, 0.6 - 0.1 * v / 512, 0.68 - 0.1 * v / 512], -1) * np.ones((1, h.shape[1], 1))
    rgb = np.where(valid[..., None], rgb, sky)
    return np.clip(rgb, 0.0, 1.0).astype(np.float32)


def main() -> None:
    fig = make_figure()
    # write_image takes premultiplied linear colour; our figure is straight-alpha linear
    pre = fig.copy()
    pre[..., :3] *= pre[..., 3:]
    write_image(HERE / "figure.png", pre)
    far = np.zeros_like(pre)
    far[:-150] = pre[150:]
    write_image(HERE / "figure_far.png", far)
    for name in SCENES:
        write_image(HERE / f"{name}.jpg", render_background(name))
    for p in sorted(HERE.iterdir()):
        if p.suffix in (".png", ".jpg"):
            print(f"{p.name}: {p.stat().st_size / 1024:.0f} KB")


if __name__ == "__main__":
    main()
