"""Results remembered for frozen input arrays (nodes/ops/memo.py): the proxy scene of a
soft shadow and the cutout's box in Composite are reused only for the same live,
read-only arrays, and give the numbers a fresh computation gives."""
import numpy as np

from _shadow_scenes import figure
from pixgraph_nodes.ops import composite as C
from pixgraph_nodes.ops import upsample as U
from pixgraph_nodes.ops.camera import Camera
from pixgraph_nodes.ops.lights import disk_light, disk_samples
from pixgraph_nodes.ops.memo import FrozenMemo, frozen


def _freeze(*arrays):
    for a in arrays:
        a.flags.writeable = False
    return arrays


def test_memo_hits_only_the_same_live_frozen_arrays():
    memo = FrozenMemo(size=2)
    a, b = _freeze(np.arange(6.0), np.ones(3))
    memo.put((a, b), "x", 41)
    assert memo.get((a, b), "x") == 41
    assert memo.get((a, b), "y") is None                     # another extra
    assert memo.get((a.copy(), b), "x") is None              # equal numbers, another array
    w = np.arange(6.0)                                        # writable: never remembered
    memo.put((w,), None, 1)
    assert memo.get((w,), None) is None
    v = a[1:]                                                 # a view of a frozen array is frozen
    v.flags.writeable = False
    assert frozen(v) and not frozen(np.arange(3.0)[1:])
    c = np.arange(4.0)
    _freeze(c)
    memo.put((c,), None, 7)
    c.flags.writeable = True                                  # its owner thaws it: not trusted any more
    assert memo.get((c,), None) is None
    d, e = _freeze(np.zeros(2), np.zeros(3))
    memo.put((d,), None, 1)
    memo.put((e,), None, 2)                                   # size 2: (a, b) "x" is the oldest, dropped
    assert memo.get((a, b), "x") is None and memo.get((e,), None) == 2


def _scene(n=640):
    m, fg, bg = figure(n, n)
    cam = Camera(n, n, 50.0, horizon=0.25 * n)
    foot = cam.back_project(np.array([n / 2]), np.array([0.88 * n]), np.array([0.0]))[0][0]
    return m, fg, bg, cam, foot


def test_a_soft_shadow_of_frozen_inputs_reuses_its_proxy_scene_and_matches_a_fresh_one(device, monkeypatch):
    m, fg, bg, cam, foot = _scene()
    m, fg, bg = _freeze(m.astype(np.float32), fg.astype(np.float32), bg.astype(np.float32))
    lights = [disk_samples(disk_light(tuple(foot + [dx, 2.5, -2.0]), 0.3, target=tuple(foot)), cam, 8)
              for dx in (-1.5, 1.0)]
    fresh = [U.proxy_soft_shadow(device, m.copy(), fg.copy(), bg.copy(), S, 1.0, 256) for S in lights]
    calls = []
    real = U.proxy_scene
    monkeypatch.setattr(U, "proxy_scene", lambda *a: calls.append(1) or real(*a))
    U._SCENES._items.clear()
    for S, want in zip(lights, fresh):
        full, box, part = U.proxy_soft_shadow_parts(device, m, fg, bg, S, 1.0, 256)
        assert full is None and box is not None
        lit, dark = U.lit_and_darkness(full, box, part, m.shape)
        np.testing.assert_array_equal(lit, want)
        np.testing.assert_array_equal(dark, np.float32(1.0) - want)
    assert len(calls) == 1                                    # the second light reused the scene
    # new heights (a new array): a new scene, and the shadow changes with them
    fg2 = fg * np.float32(0.5)
    fg2.flags.writeable = False
    lower = U.proxy_soft_shadow(device, m, fg2, bg, lights[0], 1.0, 256)
    assert len(calls) == 2 and not np.array_equal(lower, fresh[0])
    # at or below the proxy side: the plain trace, whole
    full, box, part = U.proxy_soft_shadow_parts(device, m, fg, bg, lights[0], 1.0, 4096)
    assert box is None and part is None and full.shape == m.shape


def test_composite_reuses_a_frozen_cutouts_box_and_never_a_writable_ones():
    rng = np.random.default_rng(3)
    H, W = 120, 160
    alpha = np.zeros((H, W), np.float32)
    alpha[30:90, 50:110] = rng.uniform(0.2, 1.0, (60, 60))
    fg = alpha[..., None] * rng.uniform(0, 1, (H, W, 3)).astype(np.float32)
    dark = np.zeros((H, W), np.float32)
    dark[80:100, 20:140] = 0.5
    _freeze(alpha, fg)
    C._BOXES._items.clear()
    for seed in range(3):                                     # a light sweep: new backgrounds/shadows, same cutout
        bg = np.random.default_rng(seed).uniform(0, 1, (H, W, 3)).astype(np.float32)
        want = bg * (1 - 0.8 * dark[..., None] * (1 - np.float32(0.1)))
        want = fg + want * (1 - alpha[..., None])
        np.testing.assert_allclose(C.composite(bg, fg, alpha, dark, 0.8, (0.1, 0.1, 0.1)), want, atol=1e-6)
    assert len(C._BOXES._items) == 1
    # a writable cutout moved between calls: its new box is used
    a2 = np.zeros((H, W), np.float32)
    f2 = np.zeros((H, W, 3), np.float32)
    bg = np.full((H, W, 3), 0.5, np.float32)
    a2[0:10, 0:10], f2[0:10, 0:10] = 1.0, 0.2
    np.testing.assert_allclose(C.composite(bg, f2, a2)[5, 5], 0.2)
    a2[:], f2[:] = 0.0, 0.0
    a2[100:110, 150:160], f2[100:110, 150:160] = 1.0, 0.9
    out = C.composite(bg, f2, a2)
    np.testing.assert_allclose(out[105, 155], 0.9)
    np.testing.assert_allclose(out[5, 5], 0.5)
