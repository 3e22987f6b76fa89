"""Where tracers fail: odd lights, empty masks, border cutouts, non-finite heights.
Outputs must stay finite, in [0, 1], with the right shape; no crash."""
import numpy as np
import pytest

import _shadow_scenes as sc
from pixgraph_nodes.ops import buffers as B
from pixgraph_nodes.ops import shadow as S

H, W = 64, 80
MASK, FG, BG = sc.figure(H, W)

LIGHTS = {
    "far-away": (1e7, -1e7, 1e7, 1),
    "at-horizon-grazing": (-500.0, 0.3 * H, 1.0, 1),       # barely above the ground
    "below-ground": (0.2 * W, 0.9 * H, -20.0, 1),
    "just-above-the-top": (0.1 * W, 0.0, float(FG.max()) + 0.01, 1),
    "behind-camera-grazing": (0.5 * W, 0.1 * H, -1e-4, -1),
    "behind-camera-huge": (1e9, 1e9, -1e9, -1),
    "direction": (0.0, -1.0, 1.0, 0),
    "zero-direction": (0.0, 0.0, 0.0, 0),
    "on-a-pixel-centre": (40.5, 30.5, 100.0, 1),
    "nan": (np.nan, 10.0, 10.0, 1),
    "inf": (np.inf, 10.0, 10.0, 1),
    "nan-sign": (10.0, 10.0, 10.0, np.nan),
    "odd-sign": (10.0, 10.0, 50.0, 0.7),
}


def check(lit, shape=(H, W)):
    assert lit.shape == shape and lit.dtype == np.float32
    assert np.all(np.isfinite(lit))
    assert lit.min() >= 0.0 and lit.max() <= 1.0


@pytest.mark.parametrize("name", list(LIGHTS))
def test_odd_lights(device, name):
    light = LIGHTS[name]
    lit = S.hard_shadow(device, MASK, FG, BG, light)
    check(lit)
    ref = S.hard_shadow_ref(MASK, FG, BG, light)
    assert (lit != ref).mean() <= 0.01
    if name in ("nan", "inf", "zero-direction"):
        assert np.all(lit == 1.0)            # documented: invalid lights occlude nothing
    if name == "on-a-pixel-centre":
        assert lit[30, 40] == 1.0            # the receiver on the light's image point is lit


def test_empty_mask_is_all_lit_without_launch(device):
    empty = np.zeros((H, W), np.float32)
    assert np.all(S.hard_shadow(device, empty, FG, BG, LIGHTS["direction"]) == 1.0)
    assert np.all(S.soft_shadow(device, empty, FG, BG, np.array([LIGHTS["direction"]] * 3)) == 1.0)
    ch = B.buffer_channels(device, empty, FG, BG, LIGHTS["direction"], np.array([LIGHTS["direction"]] * 4))
    for k in B.CHANNELS:
        assert np.all(np.isfinite(ch[k]))
    assert np.all(ch["hard_shadow"] == 0) and np.all(ch["cutout_height"] == 0)


def test_cutout_touching_the_border(device):
    mask = np.zeros((H, W), np.float32)
    mask[:, :6] = 1                      # full-height strip on the left edge
    mask[H - 10:, W - 8:] = 1            # block in the bottom-right corner
    fg = np.where(mask > 0.5, sc.upright(mask), 0).astype(np.float32)
    shadowed = []
    for light in [(0.9 * W, 0.2 * H, 0.8 * H, 1), (-0.5 * W, 0.5 * H, 0.5 * H, 1), (0.5 * W, -H, -H, -1)]:
        lit = S.hard_shadow(device, mask, fg, BG, light)
        check(lit)
        assert (lit != S.hard_shadow_ref(mask, fg, BG, light)).mean() <= 0.01
        shadowed.append(((lit == 0) & (mask < 0.5)).sum())
    assert shadowed[1] > 50        # the light from the left throws the strip's shadow right


def test_non_finite_heights(device):
    fg = FG.copy()
    bg = BG.copy()
    fg[MASK > 0.5] = np.where(np.random.default_rng(0).random((MASK > 0.5).sum()) < 0.1, np.nan, fg[MASK > 0.5])
    fg[10, :] = np.inf
    bg[:, 3] = np.nan
    bg[5, :] = -np.inf
    light = (0.2 * W, 0.3 * H, 0.6 * H, 1)
    lit = S.hard_shadow(device, MASK, fg, bg, light)
    check(lit)
    assert (lit == 0).any()                               # the rest still casts
    assert np.all(lit[:, 3][MASK[:, 3] < 0.5] == 1.0)     # NaN receivers are lit
    assert (lit != S.hard_shadow_ref(MASK, fg, bg, light)).mean() <= 0.01
    soft = S.soft_shadow(device, MASK, fg, bg, np.array([light, LIGHTS["nan"], LIGHTS["direction"]]))
    check(soft)
    ch = B.buffer_channels(device, MASK, fg, bg, light, np.array([light] * 4))
    for k in B.CHANNELS:
        assert np.all(np.isfinite(ch[k])), k


def test_thickness_extremes(device):
    light = (0.2 * W, 0.3 * H, 0.6 * H, 1)
    thin = S.hard_shadow(device, MASK, FG, BG, light, thickness=0.0)
    thick = S.hard_shadow(device, MASK, FG, BG, light, thickness=np.inf)
    check(thin)
    check(thick)
    # a thicker cutout blocks at least what a thinner one blocks
    assert np.all(thick <= thin) and (thick < thin).any()
    with pytest.raises(ValueError):
        S.hard_shadow(device, MASK, FG, BG, light, thickness=-1.0)
    with pytest.raises(ValueError):
        S.hard_shadow(device, MASK, FG, BG, light, thickness=np.nan)


def test_bad_shapes_are_loud(device):
    with pytest.raises(ValueError):
        S.hard_shadow(device, MASK, FG[:10], BG, (1, 1, 1, 1))
    with pytest.raises(ValueError):
        S.hard_shadow(device, MASK, FG, BG, (1, 1, 1))
    with pytest.raises(ValueError):
        S.soft_shadow(device, MASK, FG, BG, np.zeros((3, 3)))


def test_no_samples_is_all_lit(device):
    assert np.all(S.soft_shadow(device, MASK, FG, BG, np.zeros((0, 4))) == 1.0)
