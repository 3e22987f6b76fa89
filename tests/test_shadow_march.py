"""march.h helpers against their numpy mirror march.py, and their contracts."""
import numpy as np
import pyopencl as cl
import pytest

from pixgraph.device import load_kernel_source
from pixgraph_nodes.ops import march as M
from pixgraph_nodes.ops import shadow as S


def test_clip_slab_and_rect_contract():
    # ray from (0.5, 0.5) direction (2, 1) against rect u in [3, 5], v in [0, 10]
    t0, t1, ok = M.clip_rect(0.5, 0.5, 2.0, 1.0, (3, 0, 5, 10), 0.0, 100.0)
    assert ok and t0 == pytest.approx(1.25) and t1 == pytest.approx(2.25)
    # parallel to an axis and outside: empty
    _, _, ok = M.clip_rect(0.5, 20.0, 1.0, 0.0, (3, 0, 5, 10), 0.0, 100.0)
    assert not ok
    # pointing away: empty for t >= 0
    _, _, ok = M.clip_rect(0.5, 0.5, -1.0, 0.0, (3, 0, 5, 10), 0.0, 100.0)
    assert not ok


def test_march_setup_steps_one_pixel_on_major_axis():
    m, ok = M.march_setup(10.5, 20.5, 3.0, 30.0, -12.0, 6.0, 1.0)
    assert ok
    assert m.su == 1.0 and m.sv == pytest.approx(-0.4) and m.sh == pytest.approx(0.2)
    assert m.k_lo == 1 and m.k_hi == 30
    assert m.sample_u(30) == pytest.approx(40.5) and m.sample_v(30) == pytest.approx(8.5)
    assert m.ray_height(30) == pytest.approx(9.0)          # reaches the light's height
    # receiver on the light's image point: refused
    _, ok = M.march_setup(10.5, 20.5, 3.0, 0.0, 0.0, 5.0, 1.0)
    assert not ok
    # no far end
    m, ok = M.march_setup(0.5, 0.5, 0.0, 1.0, 1.0, 0.0, np.inf)
    assert ok and m.k_hi == M.K_UNBOUNDED


def test_march_clip_box_keeps_a_margin_sample():
    m, ok = M.march_setup(0.5, 0.5, 0.0, 100.0, 0.0, 0.0, 1.0)
    ok = M.march_clip_box(m, (10, 0, 20, 1), -1.0, 1.0)
    # samples u = 0.5 + k in [10, 20] are k = 10..19; one margin sample each side
    assert ok and m.k_lo == 9 and m.k_hi == 20
    # height band never reached: empty
    m, _ = M.march_setup(0.5, 0.5, 50.0, 100.0, 0.0, 0.0, 1.0)
    assert not M.march_clip_box(m, (10, 0, 20, 1), -1.0, 10.0)


def test_occlusion_rule():
    surf = np.float32(10.0)
    # behind by 0.5 <= thickness 1: occluded
    assert M.occludes(9.5, surf, 1.0, M.side(9.5, surf), 0)
    # behind by 3 > thickness, no previous sample: not occluded
    assert not M.occludes(7.0, surf, 1.0, M.side(7.0, surf), 0)
    # ... but a flip from in front to far behind is
    assert M.occludes(7.0, surf, 1.0, M.side(7.0, surf), -1)
    # on the surface (coplanar ray) counts as in front: no acne
    assert M.side(10.0, surf) == -1
    # no surface: never occludes and resets the side
    assert M.side(0.0, M.NO_SURFACE) == 0
    assert not M.occludes(0.0, M.NO_SURFACE, 1.0, 0, 1)


def test_surface_height_interpolates_minor_axis_only_inside_the_surface():
    surf = np.full((4, 4), M.NO_SURFACE, np.float32)
    surf[1, 2], surf[2, 2] = 5.0, 5.5          # feet 6.5 and 8.0: one slanted surface
    # u-major sample at column 2, v = 2.0 (half way between row centres 1.5 and 2.5)
    assert M.surface_height(surf, 2.5, 2.0, True) == pytest.approx(5.25)
    # a depth discontinuity (feet 6.5 and 32.5) is not blended: the containing pixel
    surf[2, 2] = 30.0
    assert M.surface_height(surf, 2.5, 2.1, True) == pytest.approx(30.0)
    assert M.surface_height(surf, 2.5, 1.9, True) == pytest.approx(5.0)
    # v = 1.2: pixel row 1 contains it, neighbour row 0 has no surface -> row 1's height
    assert M.surface_height(surf, 2.5, 1.2, True) == pytest.approx(5.0)
    # outside the surface / image
    assert M.surface_height(surf, 0.5, 2.0, True) <= M.NO_SURFACE_TEST
    assert M.surface_height(surf, -0.5, 2.0, True) <= M.NO_SURFACE_TEST


def test_tile_bounds_hold_the_foot_of_the_neighbourhood():
    surf = np.full((20, 20), M.NO_SURFACE, np.float32)
    surf[3, 3] = 5.0        # foot 3.5 + 5 = 8.5
    surf[12, 12] = 9.0      # foot 12.5 + 9 = 21.5
    t = M.tile_bounds(surf, 8)
    mg = float(M.FOOT_MARGIN)
    assert t.shape == (3, 3, 2)
    assert t[0, 0, 0] == pytest.approx(8.5 - mg) and t[0, 0, 1] == pytest.approx(21.5 + mg)  # (1,1) neighbours (0,0)
    assert t[2, 2, 0] == pytest.approx(21.5 - mg) and t[2, 2, 1] == pytest.approx(21.5 + mg)
    assert t[0, 2, 0] == pytest.approx(21.5 - mg)        # (0,2) neighbours (1,1) too
    empty = M.tile_bounds(np.full((8, 8), M.NO_SURFACE, np.float32), 8)
    assert empty[0, 0, 0] > 1e29 and empty[0, 0, 1] < -1e29


def test_march_clip_foot():
    # ray along u at v = 0.5 rising 1 px per step: foot = 0.5 + 0.5 + k
    m, _ = M.march_setup(0.5, 0.5, 0.5, 100.0, 0.0, 100.0, 1.0)
    assert M.march_clip_foot(m, 10.0, 20.0)
    assert m.k_lo == 8 and m.k_hi == 20
    assert M.ray_foot(m, 9) == pytest.approx(10.0)


_PROBE = r'''
#include "march.h"
__kernel void probe(__global const float *rays, __global const float *surf, int W, int H,
                    float4 rect, float h_lo, float h_hi, __global int *ks, __global float *hs)
{
    int g = get_global_id(0);
    __global const float *r = rays + 7 * g;
    ph_march m;
    int ok = ph_march_setup(r[0], r[1], r[2], r[3], r[4], r[5], r[6], &m);
    ok = ok && ph_march_clip_box(&m, rect, h_lo, h_hi);
    ks[3 * g] = ok; ks[3 * g + 1] = m.k_lo; ks[3 * g + 2] = m.k_hi;
    int k = m.k_lo + 1;
    hs[2 * g] = ph_surface_height(surf, W, H, ph_sample_u(&m, k), ph_sample_v(&m, k), m.major_u);
    hs[2 * g + 1] = ph_ray_height(&m, k);
}
'''


def test_march_h_matches_march_py(device):
    """The OpenCL helpers and the numpy mirror give the same sample ranges and heights."""
    src = load_kernel_source(S.__file__, "march.h") + _PROBE.replace('#include "march.h"', "")
    prg = device.program(src)
    rng = np.random.default_rng(3)
    H, W, n = 40, 50, 4000
    surf = np.where(rng.random((H, W)) < 0.5, rng.uniform(0, 30, (H, W)), M.NO_SURFACE).astype(np.float32)
    rays = np.stack([rng.integers(0, W, n) + 0.5, rng.integers(0, H, n) + 0.5, rng.uniform(0, 20, n),
                     rng.normal(0, 30, n), rng.normal(0, 30, n), rng.normal(0, 20, n),
                     np.where(rng.random(n) < 0.5, 1.0, 1e30)], axis=1).astype(np.float32)
    rect = (10.0, 5.0, 41.0, 30.0)
    mf = cl.mem_flags
    rb = cl.Buffer(device.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=rays)
    sb = cl.Buffer(device.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=surf)
    kb = cl.Buffer(device.context, mf.WRITE_ONLY, n * 3 * 4)
    hb = cl.Buffer(device.context, mf.WRITE_ONLY, n * 2 * 4)
    import pyopencl.cltypes as ct
    prg.probe(device.queue, (n,), None, rb, sb, np.int32(W), np.int32(H), ct.make_float4(*rect),
              np.float32(-1.0), np.float32(25.0), kb, hb)
    ks = np.empty((n, 3), np.int32)
    hs = np.empty((n, 2), np.float32)
    cl.enqueue_copy(device.queue, ks, kb)
    cl.enqueue_copy(device.queue, hs, hb)

    m, ok = M.march_setup(*rays[:, :7].T)
    ok &= M.march_clip_box(m, rect, -1.0, 25.0)
    same_ok = ks[:, 0].astype(bool) == ok
    assert same_ok.mean() > 0.995
    both = ok & ks[:, 0].astype(bool)
    assert both.sum() > 500
    assert np.mean((ks[both, 1] == m.k_lo[both]) & (ks[both, 2] == m.k_hi[both])) > 0.995
    k = m.k_lo + 1
    sh = M.surface_height(surf, m.sample_u(k), m.sample_v(k), m.major_u)
    close = np.isclose(hs[both, 0], sh[both], atol=1e-3, rtol=1e-5)
    assert close.mean() > 0.99
    assert np.allclose(hs[both, 1], m.ray_height(k)[both], atol=1e-3, rtol=1e-5)


def test_tile_bounds_limited_to_the_box_are_the_same():
    import _shadow_scenes as sc
    for seed in range(4):
        m, fg = sc.blobs(77, 93, seed)
        p = S.Prepared(m, fg, np.zeros_like(fg))
        assert np.array_equal(M.tile_bounds(p.surf, 8), M.tile_bounds(p.surf, 8, p.rect))


def test_span_skipping_and_segment_rejection_are_conservative():
    """Whenever a span is declared skippable, no sample in it occludes and its
    samples are all on one side (or have no surface); whenever segments are
    rejected, no sample of the full march occludes."""
    import _shadow_scenes as sc
    rng = np.random.default_rng(5)
    checked = skipped = rejected = 0
    for seed in range(4):
        H, W = 70, 90
        mask, fg = sc.blobs(H, W, seed)
        fg = (fg + rng.normal(0, 2, fg.shape) * (seed % 2)).astype(np.float32)
        surf = M.surface_buffer(mask, fg)
        tiles = M.tile_bounds(surf, M.TILE)
        rect = (0, 0, W, H)
        n = 1200
        ru = rng.integers(0, W, n) + 0.5
        rv = rng.integers(0, H, n) + 0.5
        rh = rng.uniform(0, 40, n)
        L = np.stack([rng.uniform(-W, 2 * W, n), rng.uniform(-H, 2 * H, n), rng.uniform(-20, 80, n)], 1)
        m, ok = M.march_setup(ru, rv, rh, L[:, 0] - ru, L[:, 1] - rv, L[:, 2] - rh, 1.0)
        M.march_clip_box(m, rect, -1e30, 1e30)
        thickness = 1.0
        occ = surf > M.NO_SURFACE_TEST
        f = (np.nonzero(occ)[0] + 0.5) + surf[occ]
        hs = surf[occ]
        may = M.segments_may_hit(ru, rv, rh, np.stack([L[:, 0], L[:, 0], L[:, 1], L[:, 1], L[:, 2], L[:, 2],
                                                        L[:, 1] + L[:, 2], L[:, 1] + L[:, 2]]),
                                 (0, 0, W, H), hs.min() - 1.0, hs.max(), f.min() - 1.5, f.max() + 0.5)
        for r in np.flatnonzero(ok):
            mr = M.March(*(getattr(m, a)[r] for a in ("u", "v", "h", "su", "sv", "sh", "k_lo", "k_hi",
                                                        "major_u")))
            ks = np.arange(mr.k_lo, mr.k_hi + 1)
            if ks.size == 0:
                continue
            s = M.surface_height(surf, mr.sample_u(ks), mr.sample_v(ks), mr.major_u)
            h = mr.ray_height(ks)
            sd = M.side(h, s)
            prev = np.concatenate([[0], sd[:-1]])
            hit = M.occludes(h, s, thickness, sd, prev)
            if not may[r]:
                rejected += 1
                assert not hit.any()
            k = mr.k_lo
            while k <= mr.k_hi:
                e = min(int(M.span_end(mr, k)), mr.k_hi)
                if e > k + 1 and M.span_skippable(tiles, mr, k, e, thickness):
                    skipped += 1
                    a, b = k - mr.k_lo, e - mr.k_lo
                    sides = set(sd[a:b + 1].tolist()) - {0}
                    assert len(sides) <= 1
                    assert not M.occludes(h[a:b + 1], s[a:b + 1], thickness, sd[a:b + 1], 0).any()
                checked += 1
                k = e + 1
    assert checked > 1000 and skipped > 200 and rejected > 200, (checked, skipped, rejected)
