"""The learned cutout pixel-height predictor (method 'learned' of pixgraph.CutoutHeight):
shipped weights on held-out cutouts, size invariance, learned heights without torch."""
import json
import pathlib
import subprocess
import sys

import numpy as np
import pytest

from pixgraph.node import InputError, Namespace
from pixgraph_nodes import cutout_height as ch
from pixgraph_nodes.cutout_height import CutoutHeight
from pixgraph_nodes.ops.heightmaps import contact_line_height

torch = pytest.importorskip("torch")
from pixgraph_nodes.ops import learned_height as lh  # noqa: E402

DATA = pathlib.Path(__file__).parent / "fixtures" / "height_heldout.npz"
# the real-cutout test split (pybullet_data's named meshes, never trained on): the first 8
# samples of `generate --mix real --split test`, cropped and halved (lab/height/fixture.py --first 8)
REAL = pathlib.Path(__file__).parent / "fixtures" / "height_real_heldout.npz"


class Ctx:
    device = None
    graph_dir = None

    def __init__(self):
        self.logs = []

    def log(self, message):
        self.logs.append(message)

    def progress(self, *a):
        pass

    def check_cancelled(self):
        pass


def params(**over):
    return Namespace(CutoutHeight.spec.coerce_params(over))


def srgb_decode(x):
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def heldout(path=DATA):
    """The committed held-out cutouts (lab/height/fixture.py: test-split objects,
    first two of each pose, cropped and halved; ``REAL``: the real-cutout test split)."""
    z = np.load(path)
    out = []
    for k in sorted(f for f in z.files if f.endswith("_meta")):
        s = k[:-5]
        a = z[s + "_alpha"].astype(np.float32) / 255
        rgb = srgb_decode(z[s + "_rgb"].astype(np.float32) / 255)
        out.append({"image": (rgb * a[..., None]).astype(np.float32), "alpha": a.astype(np.float32),
                    "mask": z[s + "_mask"], "height": z[s + "_height"].astype(np.float32),
                    "meta": json.loads(str(z[k]))})
    return out


def run_node(image, alpha, method="learned", ctx=None):
    ctx = ctx or Ctx()
    return CutoutHeight().compute(ctx, Namespace({"mask": alpha, "image": image}), params(method=method))["height"]


def _maes(samples):
    learned, heur = [], []
    for s in samples:
        m = s["mask"]
        h_l = run_node(s["image"], s["alpha"])
        assert h_l.shape == s["alpha"].shape and h_l.dtype == np.float32
        assert np.all(h_l[s["alpha"] <= 0.5] == 0)
        learned.append(np.abs(h_l[m] - s["height"][m]).mean())
        heur.append(np.abs(contact_line_height(s["alpha"])[m] - s["height"][m]).mean())
    return np.array(learned), np.array(heur)


def test_shipped_weights_on_the_second_models_random_shapes():
    # the second model's held-out random shapes (rotated random_urdfs meshes, the figure):
    # the models trained mostly on things people cut out are worse here than the second
    # model (1.83 px): the third 2.98 vs the contact line's 2.81 px (better on 4 of 8),
    # the fourth 2.29 px (better on 6 of 8), the shipped fifth 2.61 px (better on 6 of 8)
    # -- a regression kept visible
    samples = heldout()
    assert len(samples) == 8
    learned, heur = _maes(samples)
    assert learned.mean() < heur.mean(), (learned, heur)
    assert (learned < heur).sum() >= 5, (learned, heur)


def test_shipped_weights_beat_the_contact_line_on_heldout_cutouts():
    samples = heldout(REAL)
    assert len(samples) == 8 and all(s["meta"]["object"].startswith("named:") for s in samples)
    learned, heur = _maes(samples)
    # on these objects (never seen in training) the network must be clearly better
    # than the heuristic on average, and a sane fraction of their heights
    assert learned.mean() < 0.9 * heur.mean(), (learned, heur)
    tall = np.array([s["height"][s["mask"]].max() for s in samples])
    assert np.mean(learned / tall) < 0.2, learned / tall


def test_heights_scale_with_the_input_size():
    s = heldout(REAL)[0]
    h1 = run_node(s["image"], s["alpha"])
    # the same cutout at twice the size (each pixel repeated 2x2): heights double
    big = lambda a: np.repeat(np.repeat(a, 2, axis=0), 2, axis=1)  # noqa: E731
    h2 = run_node(big(s["image"]), big(s["alpha"]))
    assert h2.shape == (2 * h1.shape[0], 2 * h1.shape[1])
    m = s["mask"]
    assert h2[big(m)].sum() / big(h1)[big(m)].sum() == pytest.approx(2.0, rel=0.05)
    # and a 3x larger canvas with the cutout somewhere in it: same heights (position-free)
    H, W = s["alpha"].shape
    canvas_a = np.zeros((3 * H, 3 * W), np.float32)
    canvas_i = np.zeros((3 * H, 3 * W, 3), np.float32)
    canvas_a[H:2 * H, 2 * W:3 * W] = s["alpha"]
    canvas_i[H:2 * H, 2 * W:3 * W] = s["image"]
    h3 = run_node(canvas_i, canvas_a)
    np.testing.assert_allclose(h3[H:2 * H, 2 * W:3 * W], h1, atol=0.02 * h1.max())
    assert np.all(h3[:H] == 0)


def test_upright_box_is_close_to_its_contact_line():
    # an upright box seen face-on: every pixel's height is its distance to the bottom
    # edge (analytic); the learned model must agree within a few percent of its height
    a = np.zeros((200, 160), np.float32)
    a[40:170, 50:110] = 1.0
    v = np.arange(200, dtype=np.float32)[:, None] + 0.5
    true = np.where(a > 0, 170 - v, 0)
    u = np.arange(160)[None, :] / 160.0
    img = np.stack([0.6 * a * (0.5 + 0.5 * u), 0.3 * a, 0.2 * a], -1).astype(np.float32)
    h = run_node(img, a)
    err = np.abs(h - true)[a > 0].mean()
    assert err < 0.06 * 130, err


def test_learned_needs_the_image_and_matching_sizes():
    a = np.zeros((40, 30), np.float32)
    a[10:30, 10:20] = 1
    with pytest.raises(InputError, match="image"):
        CutoutHeight().compute(Ctx(), Namespace({"mask": a, "image": None}), params(method="learned"))
    with pytest.raises(InputError, match="same size"):
        run_node(np.zeros((41, 30, 3), np.float32), a)
    assert np.all(run_node(np.zeros((40, 30, 3), np.float32), np.zeros((40, 30), np.float32)) == 0)


def test_without_torch_learned_runs_the_numpy_network(monkeypatch):
    # torch hidden (`import torch` raises ImportError): the learned method still runs its
    # network (in numpy, ops/height_net.py), the same map as torch's
    s = heldout(REAL)[0]
    ref = lh.LearnedHeightPredictor(backend="torch").predict(ch.cutout_rgba(s["alpha"], s["image"]))
    monkeypatch.setitem(sys.modules, "torch", None)
    ch._learned.cache_clear()
    try:
        assert lh.choose_backend(lh.WEIGHTS) == "numpy"
        ctx = Ctx()
        h = run_node(s["image"], s["alpha"], ctx=ctx)
    finally:
        ch._learned.cache_clear()
    m = s["alpha"] > 0.5
    assert np.abs(h - contact_line_height(s["alpha"]))[m].max() > 1.0        # not the contact line
    np.testing.assert_allclose(h, ref, atol=1e-3)
    assert ctx.logs[0].startswith("learned: learned height")


def test_importing_the_node_does_not_import_torch():
    code = ("import sys; import pixgraph_nodes.cutout_height, pixgraph_nodes.ops.learned_height; "
            "print('torch' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_shipped_weights_are_small_and_documented():
    w = pathlib.Path(lh.WEIGHTS)
    assert w.stat().st_size + w.with_suffix(".npz").stat().st_size < 20e6   # issue 24: weights <= 20 MB
    prov = json.loads(w.with_suffix(".json").read_text())
    for k in ("command", "seed", "data", "steps", "seconds", "best_val_mae_px"):
        assert k in prov, k


def test_docs_height_python_example_runs(capsys):
    import re
    text = (pathlib.Path(__file__).parents[1] / "docs" / "height.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert len(blocks) == 1
    exec(compile(blocks[0], "height.md block 0", "exec"), {})
    out = capsys.readouterr().out
    top = float(re.search(r"top row: ([0-9.]+) px", out).group(1))
    assert abs(top - 79.5) < 8, out            # an upright box: the contact line is exact


def _mirrorable_cutout():
    """A held-out cutout on a canvas where its crop box is placed symmetrically:
    the crop of the mirrored canvas is exactly the mirrored crop."""
    s = heldout()[0]
    H, W = s["alpha"].shape
    pad = 7
    a = np.zeros((H, W + 2 * pad), np.float32)
    img = np.zeros((H, W + 2 * pad, 3), np.float32)
    a[:, pad:pad + W] = s["alpha"]
    img[:, pad:pad + W] = s["image"]
    box = lh.crop_box(a > 0.5)
    mbox = lh.crop_box(a[:, ::-1] > 0.5)
    Wc = a.shape[1]
    if mbox[5] != Wc - (box[5] + box[6]):       # rounding put it one pixel off: widen by one
        a = np.pad(a, ((0, 0), (0, 1)))
        img = np.pad(img, ((0, 0), (0, 1), (0, 0)))
        box, mbox = lh.crop_box(a > 0.5), lh.crop_box(a[:, ::-1] > 0.5)
    assert mbox[5] == a.shape[1] - (box[5] + box[6]) and mbox[4] == box[4]
    return img, a


def test_flip_average_is_mirror_equivariant():
    img, a = _mirrorable_cutout()
    rgba = np.concatenate([img, a[..., None]], 2)
    mirror = rgba[:, ::-1].copy()
    plain = lh.LearnedHeightPredictor(flip_average=False, heuristic_detail=False)
    flip = lh.LearnedHeightPredictor(flip_average=True, heuristic_detail=False)
    h, hm = flip.predict(rgba), flip.predict(mirror)[:, ::-1]
    m = a > 0.5
    # averaging a guess with its mirror's makes the prediction mirror-equivariant ...
    np.testing.assert_allclose(h[m], hm[m], atol=1e-3 * h.max())
    # ... which the plain network alone is not (so the check above can fail)
    p, pm = plain.predict(rgba), plain.predict(mirror)[:, ::-1]
    assert np.abs(p[m] - pm[m]).max() > 0.01 * p.max()
    # and the average lies between the two plain guesses
    lo, hi = np.minimum(p, pm) - 1e-3 * p.max(), np.maximum(p, pm) + 1e-3 * p.max()
    assert np.all((h[m] >= lo[m]) & (h[m] <= hi[m]))


def test_heuristic_detail_restores_the_full_size_contact_line():
    # a network that makes no correction (returns its contact-line channel): with
    # heuristic_detail the pasted height is the full-size contact line exactly;
    # without it, the contact line after a 64^2 round trip (blurred at steps)
    a = np.zeros((300, 220), np.float32)
    a[40:260, 30:100] = 1.0
    a[120:230, 100:190] = 1.0                  # a second block standing higher: a step
    img = np.repeat(a[..., None], 3, 2) * 0.4
    rgba = np.concatenate([img, a[..., None]], 2).astype(np.float32)
    ident = lh.LearnedHeightPredictor(heuristic_detail=True, flip_average=False)
    ident.predict_normalised = lambda x, aux=False: (x[:, 4].copy(), None) if aux else x[:, 4].copy()
    truth = contact_line_height(a)
    m = a > 0.5
    np.testing.assert_allclose(ident.predict(rgba, contact="free")[m], truth[m], atol=1e-3)
    ident.heuristic_detail = False
    assert np.abs(ident.predict(rgba, contact="free")[m] - truth[m]).max() > 2.0


def test_inference_options_come_from_the_checkpoint(tmp_path):
    ck = torch.load(lh.WEIGHTS, map_location="cpu", weights_only=True)
    cfg = json.loads(ck["config"]) if isinstance(ck["config"], str) else dict(ck["config"])
    cfg["inference"] = {"flip_average": True, "heuristic_detail": False}
    ck["config"] = json.dumps(cfg)
    torch.save(ck, tmp_path / "w.pt")
    p = lh.LearnedHeightPredictor(tmp_path / "w.pt")
    assert p.flip_average and not p.heuristic_detail
    assert not lh.LearnedHeightPredictor(tmp_path / "w.pt", flip_average=False).flip_average


def _prepare_full_size(colour, alpha, size, height=None):
    """The network input as ``prepare`` built it before it worked on the crop only: the
    six (eight) channels at full size, then each cropped (the reference it must equal)."""
    alpha = np.clip(np.asarray(alpha, np.float32), 0, 1)
    mask = alpha > 0.5
    r0, r1, c0, c1, top, left, side = box = lh.crop_box(mask)
    bh = float(r1 - r0)
    v = (np.arange(alpha.shape[0], dtype=np.float32) + 0.5)[:, None]
    stack = [*np.moveaxis(np.asarray(colour, np.float32) * alpha[..., None], 2, 0), alpha,
             contact_line_height(mask) / bh, np.broadcast_to((r1 - v) / bh, alpha.shape)]
    if height is not None:
        m = mask.astype(np.float32)
        stack += [np.asarray(height, np.float32) * m / bh, m]
    full = np.stack([lh._crop(np.asarray(s, np.float32), top, left, side) for s in stack])
    vv = (np.arange(top, top + side, dtype=np.float32) + 0.5)[:, None]
    full[5] = np.broadcast_to((r1 - vv) / bh, (side, side))    # the row ramp, also outside the image
    small = lh._resize(full, size)
    if height is None:
        return small[:6], box, bh
    w = small[7]
    return small[:6], box, bh, np.where(w > 1e-3, small[6] / np.maximum(w, 1e-6), 0.0).astype(np.float32), w


def _paste_full_size(pred, box, bh, mask):
    """``paste`` as it was: the whole (H, W) map computed, then masked (the reference;
    its resize is the numpy one paste uses, which equals torch's to float rounding:
    tests/test_height_net.py)."""
    from pixgraph_nodes.ops.height_net import resize_chw
    r0, r1, c0, c1, top, left, side = box
    H, W = mask.shape
    m_small = lh._resize(lh._crop(mask.astype(np.float32), top, left, side)[None], pred.shape[0])[0]
    big = resize_chw(np.stack([pred * m_small, m_small]).astype(np.float32), (side, side), antialias=False)
    val = np.where(big[1] > 1e-6, big[0] / np.maximum(big[1], 1e-6), 0.0)
    out = np.zeros((H, W), np.float32)
    y0, x0, y1, x1 = max(top, 0), max(left, 0), min(top + side, H), min(left + side, W)
    out[y0:y1, x0:x1] = val[y0 - top:y1 - top, x0 - left:x1 - left]
    return np.where(mask, np.maximum(out, 0.0) * bh, 0.0).astype(np.float32)


@pytest.mark.parametrize("centre,past_edge", [((60, 50, 30, 20), False), ((5, 6, 20, 15), True),
                                              ((115, 95, 25, 30), True), ((60, 1, 50, 4), True)])
def test_prepare_and_paste_on_the_crop_equal_the_full_size_reference(centre, past_edge):
    # bit-identical to stacking full-size channels first, also for crops reaching past the
    # image's edges and for a training call (height=)
    rng = np.random.default_rng(1)
    cy, cx, ry, rx = centre
    yy, xx = np.mgrid[0:120, 0:100]
    alpha = np.clip(1.3 - np.hypot((yy - cy) / ry, (xx - cx) / rx), 0, 1).astype(np.float32)
    colour = rng.uniform(0, 1, (120, 100, 3)).astype(np.float32)
    height = rng.uniform(0, 60, (120, 100)).astype(np.float32)
    mask = alpha > 0.5
    box = lh.crop_box(mask)
    top, left, side = box[4:]
    assert (top < 0 or left < 0 or top + side > 120 or left + side > 100) == past_edge
    x, got_box, bh = lh.prepare(colour, alpha, 64)
    x_ref, ref_box, bh_ref = _prepare_full_size(colour, alpha, 64)
    assert (got_box, bh) == (ref_box, bh_ref) and x.dtype == x_ref.dtype and np.array_equal(x, x_ref)
    got = lh.prepare(colour, alpha, 64, height=height)
    ref = _prepare_full_size(colour, alpha, 64, height=height)
    for k in (0, 3, 4):                                   # the input, the target, its weight
        assert got[k].dtype == ref[k].dtype and np.array_equal(got[k], ref[k]), k
    pred = rng.normal(0.5, 0.6, (64, 64)).astype(np.float32)
    out, out_ref = lh.paste(pred, box, bh, mask), _paste_full_size(pred, box, bh, mask)
    assert out.dtype == out_ref.dtype and np.array_equal(out, out_ref)


def test_auto_height_is_autos_choice_also_for_an_empty_cutout():
    # predict_full's auto_height (read by the lab's evaluations for auto): the learned map
    # where use_learned, else the (pinned) contact line; present for an empty cutout too
    p = lh.LearnedHeightPredictor()
    rgba = [np.concatenate([s["image"], s["alpha"][..., None]], -1) for s in heldout(REAL)[:2]]
    for thr, learned in ((np.inf, True), (-np.inf, False)):
        p.confidence_rule = dict(p.confidence_rule, threshold=thr)
        for x in rgba:
            r = p.predict_full(x)
            assert r["use_learned"] is learned
            assert np.array_equal(r["auto_height"], r["height"] if learned else r["heuristic"])
            assert not np.array_equal(r["height"], r["heuristic"])
    empty = p.predict_full(np.zeros((30, 20, 4), np.float32))
    assert empty["auto_height"].shape == (30, 20) and not empty["auto_height"].any()


@pytest.mark.parametrize("method,top,left", [("learned", 37, 51), ("auto", 40, 50), ("learned", 0, 0)])
def test_the_node_builds_the_cutouts_colour_on_its_covered_box_only(monkeypatch, method, top, left):
    # a matte at a photo's size (the cutout small in it): the node made the premultiplied
    # RGBA of the whole canvas (cutout_rgba: 0.6 s at 20 MP for a 400-px object) before the
    # predictor cut it to the covered box. Now it cuts first (from an even row and column,
    # as the predictor does), with the same heights as the predictor on the whole canvas
    # a held-out cutout auto takes the learned map for (its choice depends on the cutout, not where it is)
    s = next(s for s in heldout(REAL)
             if ch.learned_predictor().predict_full(ch.cutout_rgba(s["alpha"], s["image"]))["use_learned"])
    h, w = s["alpha"].shape
    H, W = h + 90, w + 130
    alpha = np.zeros((H, W), np.float32)
    image = np.full((H, W, 3), 0.5, np.float32)              # colour outside the matte: ignored
    alpha[top:top + h, left:left + w] = s["alpha"]
    image[top:top + h, left:left + w] = s["image"]
    ref = ch.learned_predictor().predict_full(ch.cutout_rgba(alpha, image))
    shapes = []
    real = ch.cutout_rgba
    monkeypatch.setattr(ch, "cutout_rgba", lambda m, i: shapes.append(m.shape) or real(m, i))
    ctx = Ctx()
    out = CutoutHeight().compute(ctx, Namespace({"mask": alpha, "image": image}), params(method=method))
    assert out["height"].shape == (H, W)
    assert ref["use_learned"]                                  # auto takes the learned map here too
    np.testing.assert_array_equal(out["height"], ref["height"])
    assert out["confidence"] == ref["confidence"]
    rows, cols = np.nonzero(s["alpha"] > 0)
    r0, c0 = top + rows.min(), left + cols.min()
    assert shapes == [(top + rows.max() + 1 - (r0 - r0 % 2), left + cols.max() + 1 - (c0 - c0 % 2))]
