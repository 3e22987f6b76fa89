"""The training augmentation's one-axis stretch (``train.augment(..., stretch)``,
issue 24, eleventh session): it changes an object's proportions and leaves the
targets consistent with the row channel, as the module doc of train.py says."""
import numpy as np
import pytest

torch = pytest.importorskip("torch")
from pixgraph_lab.height import train  # noqa: E402

S, B = 32, 96
TOP, BOTTOM, LEFT, RIGHT = 8, 24, 12, 20      # a 16 x 8 upright box


def batch():
    """An upright flat box (its heights = its row channel: (bottom - v) / bh)."""
    v = np.arange(S) + 0.5
    ramp = np.repeat(((BOTTOM - v) / (BOTTOM - TOP))[:, None], S, axis=1)
    m = np.zeros((S, S), np.float32)
    m[TOP:BOTTOM, LEFT:RIGHT] = 1.0
    x = np.zeros((B, 6, S, S), np.float32)
    x[:, :3] = 0.5 * m
    x[:, 3] = m
    x[:, 4] = ramp * m
    x[:, 5] = ramp
    t = np.repeat((ramp * m)[None], B, 0)
    w = np.repeat(m[None], B, 0)
    return torch.from_numpy(x), torch.from_numpy(t.astype(np.float32)), torch.from_numpy(w)


def aspects(alpha):
    """Per sample: the spread of the covered rows over that of the covered columns
    (2 for the 16 x 8 box at any zoom)."""
    a = alpha.numpy()
    rr, cc = np.meshgrid(np.arange(S), np.arange(S), indexing="ij")
    n = a.sum((1, 2))
    out = []
    for i in range(a.shape[0]):
        mr, mc = (a[i] * rr).sum() / n[i], (a[i] * cc).sum() / n[i]
        sr = np.sqrt((a[i] * (rr - mr) ** 2).sum() / n[i])
        sc = np.sqrt((a[i] * (cc - mc) ** 2).sum() / n[i])
        out.append(sr / sc)
    return np.array(out)


@pytest.mark.parametrize("stretch", [1.0, 1.5])
def test_targets_follow_the_row_channel(stretch):
    x, t, w = batch()
    x2, t2, w2 = train.augment(x, t, w, torch.Generator().manual_seed(3), stretch)
    inner = (w2 > 0.999).numpy()
    assert inner.sum() > B * 40
    # a flat upright box: target = heuristic = row channel wherever it is fully covered
    np.testing.assert_allclose(t2.numpy()[inner], x2[:, 5].numpy()[inner], atol=2e-3)
    np.testing.assert_allclose(x2[:, 4].numpy()[inner], x2[:, 5].numpy()[inner], atol=2e-3)


def test_stretch_changes_proportions_within_its_range():
    x, t, w = batch()
    alpha = train.augment(x, t, w, torch.Generator().manual_seed(3))[0][:, 3]
    plain = aspects(alpha) / 2
    x2, _, _ = train.augment(x, t, w, torch.Generator().manual_seed(3), 1.5)
    ratio = aspects(x2[:, 3]) / 2
    # zoom alone keeps the proportions (up to resampling)
    assert np.abs(np.log(plain)).max() < 0.06
    # the stretch: about half the samples changed, by at most 1.5 either way
    changed = np.abs(np.log(ratio)) > 0.08
    assert 0.3 < changed.mean() < 0.7
    assert np.abs(np.log(ratio)).max() < np.log(1.5) + 0.06
    assert (ratio > 1.15).any() and (ratio < 1 / 1.15).any()      # both axes shrunk
    # shrunk, not enlarged: the same seed draws the same zoom and shift first, so a
    # changed sample covers about 1 / k of its unstretched area
    area = (x2[:, 3].sum((1, 2)) / alpha.sum((1, 2))).numpy()
    assert area.max() < 1.02 and area[changed].max() < 0.95


def test_a_stretch_below_one_is_refused(tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        train.main(["--data", str(tmp_path), "--out", str(tmp_path / "run"), "--stretch", "0.7"])
    assert e.value.code == 2 and "--stretch 0.7: a factor >= 1" in capsys.readouterr().err
