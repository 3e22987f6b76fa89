"""The glossy reflection at a proxy resolution (ops/reflection_proxy.py, Reflection's
``proxy`` param) against the full-resolution trace."""
import sys
import pathlib

import numpy as np
import pytest

from pixgraph_nodes.ops.reflection import reflection_cl
from pixgraph_nodes.ops.reflection_proxy import proxy_reflection

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "benchmarks"))
from reflection_bench import scene  # noqa: E402  (the figure moved up on a flat floor, 512^2)

KW = dict(roughness=0.2, eta=1.5, min_spp=16, max_spp=16, thickness=4.0)


@pytest.fixture(scope="module")
def full(device):
    cam, cut, fg, bg = scene()
    return (cam, cut, fg, bg), reflection_cl(device, cam, cut, fg, bg, **KW)["layer"]


def test_a_proxy_half_the_size_is_within_the_sampling_noise(device, full):
    (cam, cut, fg, bg), ref = full
    r = proxy_reflection(device, cam, cut, fg, bg, max_side=256, **KW)
    assert r["proxy"] == (256, 256) and r["layer"].shape == (512, 512, 4)
    assert r["spp"].shape == (512, 512) and r["spp"].max() == 16
    out = cut[..., 3] < 0.5
    assert ref[out].sum() > 500                                  # a real reflection is compared
    err = float(np.sqrt(np.mean((r["layer"] - ref)[out] ** 2)))
    noise = float(np.sqrt(np.mean((reflection_cl(device, cam, cut, fg, bg, seed=1, **KW)["layer"] - ref)[out] ** 2)))
    # measured (32 spp): 0.0011 at 256 px, 0.0018 at 128 px; two seeds at full size differ by 0.0010
    assert err < 0.0025 and err < 2.0 * noise
    assert abs(r["layer"][out].sum() / ref[out].sum() - 1) < 0.06   # the reflection keeps its energy
    assert (r["layer"] >= 0).all() and (r["layer"][..., 3] <= 1.0 + 1e-6).all()


def test_no_proxy_at_or_below_its_size_nor_for_a_mirror(device, full):
    (cam, cut, fg, bg), ref = full
    assert np.array_equal(proxy_reflection(device, cam, cut, fg, bg, max_side=512, **KW)["layer"], ref)
    mirror = dict(KW, roughness=0.0)
    want = reflection_cl(device, cam, cut, fg, bg, **mirror)["layer"]
    assert np.array_equal(proxy_reflection(device, cam, cut, fg, bg, max_side=128, **mirror)["layer"], want)
    with pytest.raises(ValueError, match="at least 16"):
        proxy_reflection(device, cam, cut, fg, bg, max_side=8, **KW)


def test_the_proxy_pieces_give_the_numbers_of_the_whole_image_versions():
    """The box-limited shrink, scene and the tiled enlargement are exactly resize,
    Window.scene and masked_resize (per channel) of the whole image."""
    from pixgraph_nodes.ops.reflection_proxy import enlarge_sparse, proxy_scene, shrink_in_box
    from pixgraph_nodes.ops.resample import Window, resize
    from pixgraph_nodes.ops.upsample import masked_resize
    rng = np.random.default_rng(3)
    h, w, H, W = 37, 53, 190, 251
    lo = rng.random((h, w, 4)).astype(np.float32) * (rng.random((h, w, 1)) < 0.3)
    lo[:10] = 0.0
    m_lo = (rng.random((h, w)) < 0.4).astype(np.float32)
    m_hi = rng.random((H, W)) < 0.4
    wt = rng.random((H, W)).astype(np.float32)
    got = enlarge_sparse(lo, m_lo, m_hi, (H, W), weight=wt, tile=32)
    want = np.stack([np.maximum(masked_resize(lo[..., c], m_lo, m_hi.astype(np.float32), (H, W)), 0)
                     for c in range(4)], -1) * wt[..., None]
    np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-7)
    assert (got[:40] == 0).all()                       # tiles over an empty proxy stay 0
    # an outline in one place: the tiles away from it take the one-sided (plain) path
    m_lo = np.zeros((h, w), np.float32)
    m_lo[20:30, 30:40] = 1.0
    m_hi = np.zeros((H, W), bool)
    m_hi[100:150, 150:200] = True
    got = enlarge_sparse(lo, m_lo, m_hi, (H, W), tile=32)
    want = np.stack([np.maximum(masked_resize(lo[..., c], m_lo, m_hi.astype(np.float32), (H, W)), 0)
                     for c in range(4)], -1)
    np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-7)
    img = np.zeros((413, 297, 4), np.float32)
    img[100:180, 50:90] = rng.random((80, 40, 4))
    for shape in [(80, 60), (77, 59)]:
        want = np.stack([resize(np.ascontiguousarray(img[..., c]), shape) for c in range(4)], -1)
        np.testing.assert_allclose(shrink_in_box(img, shape), want, rtol=1e-6, atol=1e-7)
        win = Window.whole(413, 297, max(shape))
        mask = img[..., 3]
        fg = rng.random((413, 297)).astype(np.float32) * 50
        bg = rng.random((413, 297)).astype(np.float32) * 10
        for a, b in zip(proxy_scene(win, mask, fg, bg), win.scene(mask, fg, bg)):
            np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-6)


def test_the_faster_pieces_give_the_numbers_of_their_plain_numpy_references():
    """image_box / nonzero_pixels (from the bits), the integer block mean, the
    nearest-neighbour stats, enlarge_sparse with per-tile maps and cutout_scene
    searched within a box: the same numbers as the plain expressions they replace."""
    from pixgraph_nodes.ops.reflection_proxy import _block_mean, _edges, _nearest, enlarge_sparse
    from pixgraph_nodes.ops.resample import Window, image_box, nonzero_box, nonzero_pixels
    from pixgraph_nodes.ops.upsample import cutout_scene
    rng = np.random.default_rng(5)
    for C in (4, 3):
        img = np.zeros((61, 47, C), np.float32)
        assert image_box(img) is None and not nonzero_pixels(img).any()
        img[7, 9, C - 1] = -0.0                              # -0.0 == 0: not a pixel
        img[8, 9, 0] = -0.0                                  # (either half of a 64-bit pair)
        assert image_box(img) is None
        img[12:30, 5:20] = rng.random((18, 15, C)) * (rng.random((18, 15, C)) < 0.3)
        img[40, 33, 1] = np.nan                              # NaN != 0
        img[50, 2, 0] = -1e-30
        ref = (img != 0).any(axis=2)
        np.testing.assert_array_equal(nonzero_pixels(img), ref)
        assert image_box(img) == nonzero_box(ref) == (12, 51, 2, 34)
    for (H, W), (h, w) in [((190, 251), (37, 53)), ((100, 80), (20, 16)), ((64, 64), (64, 64))]:
        a = rng.random((H, W)) < 0.3
        re, ce = _edges(H, h), _edges(W, w)
        s = np.add.reduceat(np.add.reduceat(a.astype(np.float32), re, axis=0), ce, axis=1)
        n = np.diff(np.append(re, H))[:, None] * np.diff(np.append(ce, W))[None, :]
        np.testing.assert_array_equal(_block_mean(a, (h, w)), (s / n).astype(np.float32))
        small = rng.integers(0, 200, (h, w)).astype(np.int32)
        iy, ix = np.minimum((np.arange(H) * h) // H, h - 1), np.minimum((np.arange(W) * w) // W, w - 1)
        got = _nearest(small, (H, W))
        assert got.dtype == np.float32
        np.testing.assert_array_equal(got, small[:, ix][iy])
    h, w, H, W = 37, 53, 190, 251
    lo = rng.random((h, w, 4)).astype(np.float32) * (rng.random((h, w, 1)) < 0.3)
    m_lo = (rng.random((h, w)) < 0.4).astype(np.float32)
    m_hi = rng.random((H, W)) < 0.4
    wt = rng.random((H, W)).astype(np.float32)
    want = enlarge_sparse(lo, m_lo, m_hi, (H, W), weight=wt, tile=32)
    got = enlarge_sparse(lo, m_lo, lambda r, c: m_hi[r, c], (H, W), weight=lambda r, c: wt[r, c], tile=32)
    np.testing.assert_array_equal(got, want)
    mask = np.zeros((H, W), np.float32)
    mask[60:120, 80:130] = rng.random((60, 50))
    fg = rng.random((H, W)).astype(np.float32) * 40
    win = Window.whole(H, W, 64)
    for a, b in zip(cutout_scene(win, mask, fg, within=(50, 125, 70, 140)), cutout_scene(win, mask, fg)):
        np.testing.assert_array_equal(a, b)


def test_the_host_part_gives_the_numbers_of_the_plain_expressions(monkeypatch):
    """proxy_reflection's work around the trace (the trace replaced by a recorder):
    the proxy scene of the given mask (which may reach past the cutout's colour) or
    of the alpha, the receivers' proxy, and the enlargement against the plain
    whole-image expressions (Window.scene, the float block mean, array maps)."""
    from pixgraph_nodes.ops import reflection_proxy as RP
    from pixgraph_nodes.ops.resample import Window
    cam, cut, fg, bg = scene()
    H, W = bg.shape
    rng = np.random.default_rng(7)
    mask = (cut[..., 3] > 0.3).astype(np.float32)
    mask[20:60, 10:200] = 1.0                     # partly off the cutout's colour box
    recv = np.clip(rng.random((H, W)) * 2 - 0.3, 0, 1).astype(np.float32)
    recv[:, :100] = 0.0
    seen = {}

    def traced(h, w):                             # the lower half, sparse: empty and busy tiles
        busy = (np.arange(h)[:, None] >= h // 2) & (np.arange(w)[None, :] % 3 == 0)
        return np.random.default_rng(1).random((h, w, 4)).astype(np.float32) * busy[..., None]

    def trace(device, cam_lo, cut_lo, fg_lo, bg_lo, *, mask, receive, **kw):
        h, w = mask.shape
        seen.update(mask=mask, fg=fg_lo, receive=receive)
        return {"layer": traced(h, w), "spp": np.full((h, w), 16, np.int32), "steps": np.ones((h, w), np.int32)}
    monkeypatch.setattr(RP, "reflection_cl", trace)
    for m_in, r_in in [(None, None), (mask, None), (mask, recv)]:
        seen.clear()
        got = RP.proxy_reflection(None, cam, cut, fg, bg, max_side=128, mask=m_in, receive=r_in, **KW)
        win = Window.whole(H, W, 128)
        m_full = cut[..., 3] if m_in is None else m_in
        m, fg_lo, _ = win.scene(m_full, fg, bg)
        np.testing.assert_allclose(seen["mask"], m, rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(seen["fg"], fg_lo, rtol=1e-6, atol=1e-6)
        lo = traced(*m.shape)
        side_lo, side_hi = seen["mask"], m_full
        if r_in is not None:
            on = r_in > 0
            re, ce = RP._edges(H, m.shape[0]), RP._edges(W, m.shape[1])
            s = np.add.reduceat(np.add.reduceat(on.astype(np.float32), re, axis=0), ce, axis=1)
            frac = s / (np.diff(np.append(re, H))[:, None] * np.diff(np.append(ce, W))[None, :])
            np.testing.assert_array_equal(seen["receive"], RP._grow(frac > 0))
            side_lo = np.maximum(seen["mask"], (frac < 0.5).astype(np.float32))
            side_hi = (m_full > 0.5) | ~on
        else:
            assert seen["receive"] is None
        want = RP.enlarge_sparse(lo, side_lo, side_hi, (H, W), weight=r_in)
        assert want.any()
        np.testing.assert_array_equal(got["layer"], want)
        assert got["spp"].dtype == np.float32 and (got["spp"] == 16).all()


def test_receivers_masked_off_are_not_traced(device, full):
    """receive=: the pixels masked off cost nothing and stay 0; the others get the
    numbers of the full trace (their samples are the same), except within the
    adaptive probe's reach of the mask's edge."""
    (cam, cut, fg, bg), ref = full
    receive = np.zeros((512, 512), bool)
    receive[:, :300] = True
    r = reflection_cl(device, cam, cut, fg, bg, receive=receive, **KW)
    assert (r["layer"][~receive] == 0).all() and (r["spp"][~receive] == 0).all()
    assert (r["steps"][~receive] == 0).all()
    inner = np.zeros_like(receive)
    inner[:, :290] = True
    assert ref[inner].sum() > 100
    np.testing.assert_array_equal(r["layer"][inner], ref[inner])
    # through the proxy: the weight is applied at full resolution
    wgt = receive.astype(np.float32)
    p = proxy_reflection(device, cam, cut, fg, bg, max_side=256, receive=wgt, **KW)
    assert (p["layer"][~receive] == 0).all()
    q = proxy_reflection(device, cam, cut, fg, bg, max_side=256, **KW)
    deep = np.zeros_like(receive)
    deep[:, :270] = True
    d = np.abs(p["layer"][deep] - q["layer"][deep]).max()
    assert d < 1e-6
