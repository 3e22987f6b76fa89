"""Synthetic pixel-height scenes for the shadow and buffer tests (not a test module).

All heights in pixels. An upright cutout standing on the ground with its
contact row b has pixel height ``b - i`` at row i (its feet at ``v + h = b + 0.5``).
"""
from __future__ import annotations

import numpy as np


def rows_cols(H, W):
    i = np.arange(H, dtype=np.float64)[:, None] * np.ones((1, W))
    j = np.ones((H, 1)) * np.arange(W, dtype=np.float64)[None, :]
    return i, j


def upright(mask: np.ndarray) -> np.ndarray:
    """Pixel height of an upright cutout: distance (rows) to its lowest mask row."""
    H, W = mask.shape
    rows = np.flatnonzero((mask > 0.5).any(axis=1))
    if rows.size == 0:
        return np.zeros((H, W), np.float32)
    b = rows[-1]
    i, _ = rows_cols(H, W)
    return np.where(mask > 0.5, b - i, 0.0).astype(np.float32)


def wall_bg(H, W, v_wall):
    """Ground + back wall standing on the junction row v_wall: h = max(0, v_wall - v)."""
    i, _ = rows_cols(H, W)
    return np.maximum(0.0, v_wall - (i + 0.5)).astype(np.float32)


def pole(H, W, u_left, width, top, bottom):
    """A few-pixel-wide upright rectangle: columns u_left .. u_left+width-1, rows
    top .. bottom (inclusive). Returns (mask, fg_height); fg = bottom - i."""
    mask = np.zeros((H, W), np.float32)
    mask[top:bottom + 1, u_left:u_left + width] = 1.0
    return mask, upright(mask)


def ellipse(H, W, cu, cv, ru, rv):
    i, j = rows_cols(H, W)
    return ((((j + 0.5 - cu) / ru) ** 2 + ((i + 0.5 - cv) / rv) ** 2) <= 1.0).astype(np.float32)


def figure(H, W, scale=1.0):
    """A standing figure-like cutout (head, body, arms, legs) about half the image
    tall, on a ground + wall background. Returns (mask, fg_height, bg_height)."""
    s = min(H, W) / 256.0 * scale
    cu, foot = W * 0.5, H * 0.88
    m = np.zeros((H, W), np.float32)
    m = np.maximum(m, ellipse(H, W, cu, foot - 118 * s, 14 * s, 16 * s))         # head
    m = np.maximum(m, ellipse(H, W, cu, foot - 70 * s, 26 * s, 36 * s))          # body
    m = np.maximum(m, ellipse(H, W, cu - 30 * s, foot - 72 * s, 7 * s, 28 * s))  # arms
    m = np.maximum(m, ellipse(H, W, cu + 30 * s, foot - 72 * s, 7 * s, 28 * s))
    i, j = rows_cols(H, W)
    for du in (-12 * s, 12 * s):                                                 # legs
        leg = (np.abs(j + 0.5 - (cu + du)) <= 6 * s) & (i + 0.5 >= foot - 45 * s) & (i + 0.5 <= foot)
        m = np.maximum(m, leg.astype(np.float32))
    # stands on the continuous contact line v = foot: h = foot - v at pixel centres
    fg = np.where(m > 0.5, np.maximum(0.0, foot - (i + 0.5)), 0.0).astype(np.float32)
    return m, fg, wall_bg(H, W, H * 0.45)


def blobs(H, W, seed):
    """A few random upright ellipses and rectangles merged front-most first
    (a larger contact row is nearer the camera and wins). Returns (mask, fg)."""
    rng = np.random.default_rng(seed)
    mask = np.zeros((H, W), np.float32)
    fg = np.zeros((H, W), np.float32)
    foot = np.full((H, W), -np.inf)
    for _ in range(rng.integers(2, 4)):
        if rng.random() < 0.5:
            m = ellipse(H, W, rng.uniform(0.25, 0.75) * W, rng.uniform(0.4, 0.7) * H,
                        rng.uniform(0.05, 0.15) * W, rng.uniform(0.1, 0.25) * H)
        else:
            u0, v0 = int(rng.uniform(0.2, 0.7) * W), int(rng.uniform(0.2, 0.6) * H)
            m = np.zeros((H, W), np.float32)
            m[v0:v0 + int(rng.uniform(0.1, 0.3) * H), u0:u0 + int(rng.uniform(0.03, 0.15) * W)] = 1
        h = upright(m)
        rows = np.flatnonzero(m.any(axis=1))
        b = rows[-1] if rows.size else 0
        win = (m > 0.5) & (b > foot)
        fg = np.where(win, h, fg)
        foot = np.where(win, b, foot)
        mask = np.maximum(mask, m)
    return mask, fg.astype(np.float32)


def jitter_samples(center, radius, n, rng, stratified=False):
    """n light points (u, v, h, s) spread over a disk of `radius` pixels in the
    (u, h) plane around `center` (u, v, h, s): uniform random, or stratified
    (one jittered sample per cell of a sqrt(n) x sqrt(n) grid, mapped to the disk
    by the polar map)."""
    c = np.asarray(center, np.float64)
    if stratified:
        k = int(round(np.sqrt(n)))
        assert k * k == n
        a, b = np.meshgrid(np.arange(k), np.arange(k))
        x = (a.ravel() + rng.random(n)) / k
        y = (b.ravel() + rng.random(n)) / k
    else:
        x, y = rng.random(n), rng.random(n)
    r = radius * np.sqrt(x)
    t = 2 * np.pi * y
    out = np.tile(c, (n, 1))
    out[:, 0] += r * np.cos(t)
    out[:, 2] += r * np.sin(t)
    return out.astype(np.float32)
