"""Soft-shadow metrics of the paper's Tables 1-2, on darkness maps (1 = full shadow).

All functions take a prediction ``p`` and ground truth ``g`` (float (H, W), darkness
in [0, 1]) and an optional ``valid`` mask (bool (H, W), True = counted). The
cutout's own pixels are not part of the comparison (the composite covers them):
pass ``valid = ~mask``.

* RMSE over the valid pixels.
* RMSE-s (scale invariant, Sun et al. 2019): ``s = <p, g> / <p, p>`` over the valid
  pixels, then the RMSE of ``s p`` against ``g``; when ``p`` is all zero
  (``<p, p> = 0``) s = 0, i.e. the RMSE of ``g`` against zero.
* SSIM (Wang et al. 2004) with an 11x11 Gaussian window (sigma 1.5, truncated at
  3.5 sigma as scikit-image does), k1 = 0.01, k2 = 0.03, data range 1, population
  (not sample) covariances, ``reflect`` (symmetric) border padding; the mean is
  taken over the SSIM map without its 5-pixel border — exactly
  ``skimage.metrics.structural_similarity(gaussian_weights=True, sigma=1.5,
  use_sample_covariance=False, data_range=1)``. With a ``valid`` mask, invalid
  pixels of ``p`` are first set equal to ``g`` (windows need every pixel) and the
  mean is over the valid pixels of the cropped map.
* ZNCC: Pearson correlation over the valid pixels; 0 when either image is
  constant there (its variance is below 1e-12).

``shadow_metrics`` returns all four for one sample; averaging over samples is the
caller's job (``evaluate.py``).
"""
from __future__ import annotations

import numpy as np

SSIM_SIGMA = 1.5
SSIM_TRUNCATE = 3.5
SSIM_K1, SSIM_K2 = 0.01, 0.03


def _prep(p, g, valid):
    p = np.asarray(p, np.float64)
    g = np.asarray(g, np.float64)
    if p.shape != g.shape:
        raise ValueError(f"prediction {p.shape} and ground truth {g.shape} differ in shape")
    if valid is None:
        valid = np.ones(p.shape, bool)
    valid = np.asarray(valid, bool)
    if valid.shape != p.shape:
        raise ValueError(f"valid mask {valid.shape} does not match images {p.shape}")
    return p, g, valid


def rmse(p, g, valid=None) -> float:
    p, g, v = _prep(p, g, valid)
    if not v.any():
        return 0.0
    return float(np.sqrt(np.mean((p[v] - g[v]) ** 2)))


def rmse_s(p, g, valid=None) -> float:
    p, g, v = _prep(p, g, valid)
    if not v.any():
        return 0.0
    pv, gv = p[v], g[v]
    pp = float(pv @ pv)
    s = float(pv @ gv) / pp if pp > 0 else 0.0
    return float(np.sqrt(np.mean((s * pv - gv) ** 2)))


def zncc(p, g, valid=None) -> float:
    p, g, v = _prep(p, g, valid)
    if not v.any():
        return 0.0
    pv, gv = p[v] - p[v].mean(), g[v] - g[v].mean()
    vp, vg = float(pv @ pv) / pv.size, float(gv @ gv) / gv.size
    if vp < 1e-12 or vg < 1e-12:
        return 0.0
    return float((pv @ gv) / pv.size / np.sqrt(vp * vg))


def gaussian_kernel(sigma: float = SSIM_SIGMA, truncate: float = SSIM_TRUNCATE) -> np.ndarray:
    """Normalised 1D Gaussian taps, radius int(truncate * sigma + 0.5) (11 taps for 1.5)."""
    r = int(truncate * sigma + 0.5)
    x = np.arange(-r, r + 1, dtype=np.float64)
    k = np.exp(-0.5 * (x / sigma) ** 2)
    return k / k.sum()


def _filter(img: np.ndarray, k: np.ndarray) -> np.ndarray:
    """Separable correlation with 'symmetric' padding (= scipy.ndimage mode 'reflect')."""
    r = len(k) // 2
    a = np.pad(img, r, mode="symmetric")
    H, W = img.shape
    tmp = np.zeros((H + 2 * r, W))
    for i, w in enumerate(k):
        tmp += w * a[:, i:i + W]
    out = np.zeros((H, W))
    for i, w in enumerate(k):
        out += w * tmp[i:i + H, :]
    return out


def ssim_map(p, g, data_range: float = 1.0) -> np.ndarray:
    """Per-pixel SSIM (H, W) with the module's constants (no cropping)."""
    p = np.asarray(p, np.float64)
    g = np.asarray(g, np.float64)
    k = gaussian_kernel()
    mp, mg = _filter(p, k), _filter(g, k)
    spp = _filter(p * p, k) - mp * mp
    sgg = _filter(g * g, k) - mg * mg
    spg = _filter(p * g, k) - mp * mg
    c1, c2 = (SSIM_K1 * data_range) ** 2, (SSIM_K2 * data_range) ** 2
    return ((2 * mp * mg + c1) * (2 * spg + c2)) / ((mp * mp + mg * mg + c1) * (spp + sgg + c2))


def ssim(p, g, valid=None) -> float:
    p, g, v = _prep(p, g, valid)
    p = np.where(v, p, g)                        # excluded pixels are set equal
    S = ssim_map(p, g)
    pad = len(gaussian_kernel()) // 2
    crop = np.zeros(S.shape, bool)
    crop[pad:S.shape[0] - pad, pad:S.shape[1] - pad] = True
    sel = crop & v
    if not sel.any():
        return 1.0
    return float(S[sel].mean())


METRICS = {"rmse": rmse, "rmse_s": rmse_s, "ssim": ssim, "zncc": zncc}


def shadow_metrics(p, g, valid=None) -> dict:
    """All four metrics of one sample: {'rmse', 'rmse_s', 'ssim', 'zncc'}."""
    return {name: fn(p, g, valid) for name, fn in METRICS.items()}
