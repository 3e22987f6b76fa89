"""Thin parts at any resolution (issue 22): a part one sample wide blocks the rays
that pass through it between two samples, so its shadow no longer shrinks when the
image does (a proxy traced at a fifth of a photo's size lost the shadows of thin
parts). The tracer traces half a step beyond the first and last samples of each
run on an upright surface (shadow.cl: run_end_hit)."""
import numpy as np
import pytest

from pixgraph_nodes.ops import shadow as S
from pixgraph_nodes.ops.resample import resize


def _bar(N, width=1.0):
    """A vertical bar ``width`` px wide at 128 px (scaled with N), standing upright
    on the ground at row 100/128: contact-line heights, background the ground."""
    s = N / 128
    mask = np.zeros((N, N), np.float32)
    c0 = int(64 * s)
    mask[int(30 * s):int(100 * s), c0:c0 + max(1, int(width * s))] = 1
    v = np.arange(N)[:, None] + 0.5
    fg = np.where(mask > 0, 100 * s - v, 0).astype(np.float32)
    return mask, fg, np.zeros((N, N), np.float32)


def _area(device, N, light, thickness=2.0):
    """Shadow area of the bar [px at 128], the hard shadow traced at N px."""
    m, fg, bg = _bar(N)
    s = N / 128
    lit = S.hard_shadow(device, m, fg, bg, (light[0] * s, light[1] * s, light[2] * s, 1.0), thickness * s)
    d = np.where(m > 0.5, 0.0, 1.0 - lit)
    return float(resize(d.astype(np.float32), (128, 128)).sum())


# lights whose rays cross the bar steeply (the ray's foot moves several px per
# sample): before the run edges, the shadow areas at 128/256/512 px were
# 189/234/256 and 164/200/218 (px at 128)
@pytest.mark.parametrize("light", [(0.0, 100.0, 60.0), (-40.0, 110.0, 80.0), (10.0, 60.0, 40.0)])
def test_a_one_pixel_bar_casts_the_same_shadow_at_n_and_2n(device, light):
    a = [_area(device, N, light) for N in (128, 256, 512)]
    assert a[0] > 50
    assert abs(a[1] - a[0]) <= 0.03 * a[1] and abs(a[2] - a[1]) <= 0.03 * a[2], a


def test_the_kernel_traces_the_run_edges_as_the_reference(device):
    for light in ((0.0, 100.0, 60.0, 1.0), (-40.0, 110.0, 80.0, 1.0), (200.0, 20.0, -60.0, -1.0)):
        m, fg, bg = _bar(128)
        ref = S.hard_shadow_ref(m, fg, bg, light, 2.0)
        assert (ref < 1).sum() > 50
        assert np.array_equal(S.hard_shadow(device, m, fg, bg, light, 2.0), ref)
        assert np.array_equal(S.hard_shadow_ref(m, fg, bg, light, 2.0, clip_to_cutout=False), ref)


def test_edge_hit_is_the_depth_interval_over_the_half_step():
    T = 2.0
    # depth 2.5 at the sample (beyond the thickness): the half step after it, with the
    # ray's foot moving +2 per sample, reaches depth 1.5: blocked; before it, 3.5: not
    assert S.edge_hit(2.5, 2.0, 1, T) and not S.edge_hit(2.5, 2.0, -1, T)
    # in front by 0.5: the half step before reaches 0.5 behind
    assert S.edge_hit(-0.5, 2.0, -1, T) and not S.edge_hit(-0.5, 2.0, 1, T)
    # a ray parallel to the surface's foot (df 0) changes nothing
    assert not S.edge_hit(-0.5, 0.0, -1, T) and not S.edge_hit(2.5, 0.0, 1, T)


@pytest.mark.parametrize("light", [(3000.0, 95.0, 5.0, 1.0), (80.0, -3000.0, 30.0, 1.0), (-2000.0, 60.0, 40.0, 1.0)])
def test_a_cutout_lying_on_the_ground_casts_nothing_with_grazing_light(device, light):
    """A flat cutout lying on the ground (heights 0 over a disk, receivers the ground)
    is part of the ground: no shadow on it or around it, however low the light.
    The run edges apply only where the surface stands upright (the foot changes by
    1 px per row here); applied everywhere, they shaded 1,036 of its pixels and 42
    around it for the first light."""
    N = 160
    y, x = np.mgrid[0:N, 0:N] + 0.5
    mask = (((x - 80) ** 2 + (y - 90) ** 2) < 30 ** 2).astype(np.float32)
    zero = np.zeros((N, N), np.float32)
    for th in (1.0, 3.0):
        assert S.hard_shadow(device, mask, zero, zero, light, th).min() == 1.0
        assert S.hard_shadow_ref(mask, zero, zero, light, th).min() == 1.0


def test_pixel_upright():
    surf = np.full((6, 4), -1.0e30, np.float32)
    surf[1:5, 0] = [40.0, 39.0, 38.0, 37.0]      # upright: the foot stays at 41.5
    surf[1:5, 1] = 0.0                           # lying: the foot moves 1 px per row
    surf[2, 2] = 7.0                             # one pixel tall: upright
    got = S.pixel_upright(surf, np.array([0.5, 0.5, 1.5, 2.5]), np.array([1.5, 4.5, 3.5, 2.5]))
    assert got.tolist() == [True, True, False, True]
