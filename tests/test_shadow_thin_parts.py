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
