"""Thin parts of large cutouts (issue 24, seventh session; docs/height-record.md, "Measured:
thin parts"): a part thinner than a work-size pixel has no work-size pixel of its
own, and ``masked_resize`` used to give it the plain bilinear value there, about 0
(a 3-px stick held up by a 2,400-px figure: 13 px where it stands 1,000-2,000 px
high). ``fill_thin`` gives those *lost* pixels a height."""
import numpy as np
import pytest

from pixgraph_nodes.ops import height_work_size as hw
from pixgraph_nodes.ops.heightmaps import contact_line_height
from pixgraph_nodes.ops.resample import resize
from pixgraph_nodes.ops.upsample import masked_resize
from pixgraph_lab.height.thin_study import FILLS  # the rule's candidates (contact shipped)


def test_masked_resize_reports_the_pixels_with_no_inside_pixel_within_reach():
    rng = np.random.default_rng(3)
    H, W, h, w = 240, 200, 30, 25
    mask_hi = np.zeros((H, W), bool)
    mask_hi[60:200, 40:120] = True            # a body: 8 work pixels wide
    mask_hi[10:60, 150:152] = True            # a 2-px stick: 1/4 of a work pixel
    mask_hi[100:104, 120:150] = True          # the arm holding it
    mask_lo = resize(mask_hi.astype(np.float32), (h, w)) > 0.5
    lo = rng.uniform(0, 50, (h, w)).astype(np.float32)
    plain = masked_resize(lo, mask_lo.astype(np.float32), mask_hi, (H, W))
    out, lost = masked_resize(lo, mask_lo.astype(np.float32), mask_hi, (H, W), return_lost=True)
    assert np.array_equal(out, plain)                     # the map itself is unchanged
    den = resize(mask_lo.astype(np.float32), (H, W))      # the inside weight a pixel gets
    assert np.array_equal(lost, mask_hi & (den <= 1e-3))
    assert lost[10:60, 150:152].mean() > 0.9 and not lost[60:200, 40:120].any()
    # banded and boxed the same
    box = (5, 210, 30, 170)
    o2, l2 = masked_resize(lo, mask_lo.astype(np.float32), mask_hi, (H, W), band=17, box=box, return_lost=True)
    assert np.array_equal(o2, out[5:210, 30:170]) and np.array_equal(l2, lost[5:210, 30:170])


def _figure():
    """A flat upright figure standing on row 200 (its last row 199) with a 1-px stick held at
    its side: every pixel's true height is the contact line's, 199.5 - row."""
    m = np.zeros((220, 200), bool)
    m[100:200, 50:150] = True                 # body and legs
    m[110:115, 150:160] = True                # arm
    m[30:110, 158] = True                     # the stick, above the hand
    rows = np.arange(220, dtype=np.float32)[:, None] + np.zeros((1, 200), np.float32)
    true = np.where(m, 199.5 - rows, 0.0).astype(np.float32)
    lost = np.zeros_like(m)
    lost[30:110, 158] = True
    return m, true, lost


@pytest.mark.parametrize("lift", [0.0, 30.0])
def test_an_attached_lost_part_stands_where_what_holds_it_stands(lift):
    # the covered pixels' heights (the work size's map) put the figure `lift` px above the
    # ground; the lost stick takes the level of the arm it is attached to, + 1 px per row up
    m, true, lost = _figure()
    h = np.where(m & ~lost, true + lift, 0.0).astype(np.float32)
    heur = contact_line_height(m)
    for how in ("attached", "attached_ground"):
        out = hw.fill_thin(h.copy(), m, lost, heur, FILLS[how])
        np.testing.assert_allclose(out[lost], true[lost] + lift, atol=1e-4)
        assert np.array_equal(out[~lost], h[~lost])
    # the contact line is the figure's, whatever the map says
    out = hw.fill_thin(h.copy(), m, lost, heur, "contact")
    np.testing.assert_allclose(out[lost], true[lost], atol=1e-4)


def test_a_lost_part_standing_on_the_ground_or_alone():
    m, true, _ = _figure()
    m[150:200, 170] = True                    # a 1-px leg standing on the ground, attached to nothing
    m[10:20, 20] = True                       # a speck floating alone
    lost = np.zeros_like(m)
    lost[150:200, 170] = lost[10:20, 20] = True
    h = np.where(m & ~lost, 40.0, 0.0).astype(np.float32)   # a wrong, flat map elsewhere
    heur = contact_line_height(m)
    rows = np.arange(220, dtype=np.float32)[:, None] + np.zeros((1, 200), np.float32)
    # attached: no covered neighbour -> the contact line
    out = hw.fill_thin(h.copy(), m, lost, heur, FILLS["attached"])
    np.testing.assert_allclose(out[lost], heur[lost])
    # attached_ground: the leg reaching the silhouette's lowest rows stands there itself
    out = hw.fill_thin(h.copy(), m, lost, heur, FILLS["attached_ground"])
    np.testing.assert_allclose(out[150:200, 170], 199.5 - rows[150:200, 170], atol=1e-4)
    np.testing.assert_allclose(out[10:20, 20], heur[10:20, 20])


def test_no_lost_pixel_no_change():
    m, true, _ = _figure()
    h = true.copy()
    for how in FILLS.values():
        assert hw.fill_thin(h, m, np.zeros_like(m), contact_line_height(m), how) is h
    with pytest.raises(ValueError, match="unknown thin fill"):
        hw.fill_thin(h.copy(), m, m.copy(), contact_line_height(m), "nearest")


# -- end to end: the shipped predictor -------------------------------------------------------

@pytest.fixture(scope="module")
def predictor():
    pytest.importorskip("torch")
    from pixgraph_nodes.ops import learned_height as lh
    return lh.LearnedHeightPredictor()


def test_the_shipped_fill_is_the_contact_line():
    # chosen by the rule (docs/height-record.md, "Measured: thin parts of large cutouts")
    assert hw.THIN_FILL == "contact"


def test_the_reviews_stick_gets_its_height(predictor):
    # a 3-px stick held 1,000 px above the hand of a flat upright figure 2,400 px tall (f 6):
    # everything stands upright in one plane, so the true height is the contact line's. At
    # the work size the stick has no pixel of its own; the old path gave it the plain
    # bilinear value (2,108 px off on average, 0 px high where it stands 1,600-2,600 px).
    # The contact line is exact here, and the pin's shift fades to 0 long before the
    # stick's rows (pin_fade box heights above the foot), so 1 px is float rounding's room.
    from pixgraph_lab.height.thin_study import lost_pixels, stick_figure
    rgba, true, mask, stick = stick_figure()
    lost = lost_pixels(predictor, rgba)
    assert lost[stick].mean() > 0.95 and not lost[~stick].any()
    r = predictor.predict_full(rgba)
    assert r["work_scale"] == pytest.approx(6.0, abs=0.1)
    err = np.abs(r["height"][lost] - true[lost])
    assert err.max() <= 1.0, err.max()
    old = hw.predict_at_work_size(predictor, rgba, thin_fill="none")["height"]
    assert np.abs(old[lost] - true[lost]).mean() > 1500          # what it was
    # only the lost pixels moved (no contact band pixel is lost: the pin's shift is the same)
    assert np.array_equal(r["height"][~lost], old[~lost])


@pytest.mark.parametrize("k", [16, 24])
def test_a_cutout_without_lost_pixels_gets_the_same_map_as_before(predictor, k):
    # held-out cutouts with a hard alpha enlarged 16x and 24x (every part at least k px wide,
    # f 1.3-5.7): those with no lost pixel get the map bit for bit as the path before the fill.
    # (A convex corner's one pixel can be lost: the work-size pixel there is a quarter
    # covered. With their soft alpha, block-enlarged rims of alpha just above 0.5, k px wide,
    # fall under the threshold at the work size: 45-5,180 lost px on six of them.)
    from pixgraph_lab.height.thin_study import lost_pixels
    from test_learned_height import REAL, heldout
    checked = 0
    for s in heldout(REAL)[:6]:
        a = (s["alpha"] > 0.5).astype(np.float32)
        rgba = np.concatenate([s["image"] * a[..., None], a[..., None]], -1)
        rgba = np.repeat(np.repeat(rgba, k, axis=0), k, axis=1)
        if lost_pixels(predictor, rgba).any():
            continue
        checked += 1
        new = predictor.predict_full(rgba)
        assert new["work_scale"] > 1
        old = hw.predict_at_work_size(predictor, rgba, thin_fill="none")
        for key in ("height", "auto_height", "heuristic"):
            assert np.array_equal(new[key], old[key]), key
    assert checked >= 3, checked


def test_a_lifted_cutouts_thin_part_is_lifted_with_it(predictor):
    # contact: lifted puts the whole cutout `lift` px above its foot (the covered pixels and
    # the heuristic output are pinned there); the lost stick must be lifted with the hand
    # that holds it, not left at the contact line's ground-standing heights (300 px under
    # the hand, a step in the shadow where the stick leaves the hand)
    from pixgraph_lab.height.thin_study import lost_pixels, stick_figure
    rgba, true, mask, stick = stick_figure()
    lost = lost_pixels(predictor, rgba)
    assert lost.any()
    r = predictor.predict_full(rgba, contact="lifted", lift=300.0)
    err = np.abs(r["height"][lost] - (true[lost] + 300.0))
    assert err.max() <= 1.0, err.max()
    # lift 0 is the ground's map, bit for bit
    assert np.array_equal(predictor.predict_full(rgba, contact="lifted", lift=0.0)["height"],
                          predictor.predict_full(rgba)["height"])
