"""Sampling and material math of the pixel-height reflection and refraction tracers
(``reflection.py``, ``refraction.py``): random numbers, 3D rays in (u, v, h), GGX,
Fresnel, Snell. Each function is the numpy mirror of the ``rt_`` function of the
same name in ``reflection.cl`` (the model and the units: ``reflection.py``).
"""
from __future__ import annotations

import math

import numpy as np

from .camera import Camera

F32 = np.float32
UNBOUNDED = F32(1.0e30)
_U32 = np.uint32


# ---------------------------------------------------------------------------
# random numbers (bit-exact mirror of rt_pcg / rt_rand)
# ---------------------------------------------------------------------------

def pcg(v) -> np.ndarray:
    """PCG integer hash of uint32 values (wrapping arithmetic)."""
    v = np.asarray(v, dtype=_U32)
    with np.errstate(over="ignore"):
        state = v * _U32(747796405) + _U32(2891336453)
        word = ((state >> ((state >> _U32(28)) + _U32(4))) ^ state) * _U32(277803737)
    return (word >> _U32(22)) ^ word


def rand(seed, pix, sample, dim) -> np.ndarray:
    """Uniform float32 in [0, 1), one per (seed, pixel, sample, dimension)."""
    with np.errstate(over="ignore"):
        x = pcg(pcg(pcg(_U32(seed) + _U32(dim)) + np.asarray(sample, _U32)) + np.asarray(pix, _U32))
    return ((x >> _U32(8)).astype(np.float32) * F32(1.0 / 16777216.0)).astype(np.float32)


#: R2 sequence increments (1/g, 1/g^2), g the plastic number, as 32-bit fixed point
R2_STEP = (_U32(3242174889), _U32(2447445413))


def sample2(seed, pix, n):
    """Low-discrepancy 2D sample ``n`` of each pixel (mirror of ``rt_sample2``): the R2
    sequence with a per-pixel random shift (Cranley-Patterson rotation). Returns
    two float32 arrays in [0, 1)."""
    pix = np.asarray(pix, _U32)
    n = np.asarray(n, _U32)
    off = (rand(seed, pix, 0, 0), rand(seed, pix, 0, 1))
    out = []
    with np.errstate(over="ignore"):
        for a, o in zip(R2_STEP, off):
            r = ((n * a) >> _U32(8)).astype(np.float32) * F32(1.0 / 16777216.0) + o
            out.append((r - np.floor(r)).astype(np.float32))
    return out[0], out[1]


# ---------------------------------------------------------------------------
# 3D ray -> (u, v, h) ray
# ---------------------------------------------------------------------------

def uvh_direction(camera: Camera, p0, d):
    """(u, v, h) direction ``e`` and far end ``s_max`` of 3D rays.

    p0: (..., 3) image point ``(u, v, h)`` of the ray origins [px].
    d: (..., 3) world directions (need not be unit).
    Returns ``(e, s_max)``: e (..., 3) [px per unit s], s_max (...) (``UNBOUNDED``
    where the ray points toward the camera or parallel to the image plane).
    """
    p0 = np.asarray(p0, np.float64)
    d = np.asarray(d, np.float64)
    f = camera.focal
    mdz = -d[..., 2]
    nd = np.stack([0.5 * camera.width * mdz + f * d[..., 0],
                   camera.horizon * mdz - f * d[..., 1],
                   f * d[..., 1]], axis=-1)
    e = nd - mdz[..., None] * p0
    with np.errstate(divide="ignore"):
        s_max = np.where(mdz > 0, np.minimum(1.0 / np.where(mdz > 0, mdz, 1.0), UNBOUNDED), UNBOUNDED)
    return e, s_max


def view_directions(camera: Camera) -> np.ndarray:
    """Unit view ray (camera -> scene) of every pixel centre, float64 (H, W, 3)."""
    u, v = camera.pixel_grid()
    r = camera.ray(u, v)
    return r / np.linalg.norm(r, axis=-1, keepdims=True)


# ---------------------------------------------------------------------------
# BRDF and interface math
# ---------------------------------------------------------------------------

def fresnel_dielectric(cos_i, eta) -> np.ndarray:
    """Exact unpolarised Fresnel reflectance; ``eta = n_t / n_i``, cos_i in [0, 1].

    ``((1 - eta)/(1 + eta))**2`` at normal incidence, 1 at grazing incidence and 1
    under total internal reflection (``eta < 1`` past the critical angle)."""
    c = np.clip(np.asarray(cos_i, np.float64), 0.0, 1.0)
    eta = np.asarray(eta, np.float64)
    g2 = eta * eta - 1.0 + c * c
    tir = g2 <= 0.0
    g = np.sqrt(np.where(tir, 1.0, g2))
    with np.errstate(divide="ignore", invalid="ignore"):
        a = (g - c) / (g + c)
        b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
        F = 0.5 * a * a * (1.0 + b * b)
    return np.where(tir, 1.0, np.clip(F, 0.0, 1.0))


def fresnel_schlick(cos_i, f0) -> np.ndarray:
    """Schlick's approximation with normal-incidence reflectance ``f0`` (..., 3)."""
    m = 1.0 - np.clip(np.asarray(cos_i, np.float64), 0.0, 1.0)
    f0 = np.asarray(f0, np.float64)
    return f0 + (1.0 - f0) * (m ** 5)[..., None]


def smith_lambda(cos_t, alpha) -> np.ndarray:
    """GGX Smith Lambda; cos_t = cosine to the macro normal."""
    c2 = np.maximum(np.asarray(cos_t, np.float64) ** 2, 1e-12)
    t2 = np.maximum(1.0 - c2, 0.0) / c2
    return 0.5 * (-1.0 + np.sqrt(1.0 + alpha * alpha * t2))


def ggx_d(cos_m, alpha) -> np.ndarray:
    """GGX normal distribution D(m) [1/sr] for microfacet normals at cosine cos_m."""
    c2 = np.asarray(cos_m, np.float64) ** 2
    a2 = alpha * alpha
    return np.where(c2 > 0, a2 / (math.pi * (c2 * (a2 - 1.0) + 1.0) ** 2), 0.0)


def sample_vndf(wo, alpha, u1, u2) -> np.ndarray:
    """Visible GGX normals (Heitz 2018) in the local frame (n = +z), wo (..., 3), wo_z > 0."""
    wo = np.asarray(wo, np.float64)
    vh = np.stack([alpha * wo[..., 0], alpha * wo[..., 1], wo[..., 2]], axis=-1)
    vh /= np.linalg.norm(vh, axis=-1, keepdims=True)
    lensq = vh[..., 0] ** 2 + vh[..., 1] ** 2
    inv = 1.0 / np.sqrt(np.where(lensq > 0, lensq, 1.0))
    t1 = np.where((lensq > 0)[..., None],
                  np.stack([-vh[..., 1] * inv, vh[..., 0] * inv, np.zeros_like(lensq)], axis=-1),
                  np.array([1.0, 0.0, 0.0]))
    t2 = np.cross(vh, t1)
    r = np.sqrt(u1)
    phi = 2.0 * math.pi * u2
    p1 = r * np.cos(phi)
    p2 = r * np.sin(phi)
    s = 0.5 * (1.0 + vh[..., 2])
    p2 = (1.0 - s) * np.sqrt(np.maximum(1.0 - p1 * p1, 0.0)) + s * p2
    nh = p1[..., None] * t1 + p2[..., None] * t2 + np.sqrt(np.maximum(0.0, 1.0 - p1 * p1 - p2 * p2))[..., None] * vh
    m = np.stack([alpha * nh[..., 0], alpha * nh[..., 1], np.maximum(1e-6, nh[..., 2])], axis=-1)
    return m / np.linalg.norm(m, axis=-1, keepdims=True)


def reflect(wo, m) -> np.ndarray:
    """Mirror of wo (pointing away from the surface) about m: ``2 (wo.m) m - wo``."""
    return 2.0 * np.sum(wo * m, axis=-1, keepdims=True) * m - wo


def refract(view, n, eta):
    """Snell refraction of ``view`` (toward the surface, unit) through a surface with
    unit normal ``n`` (toward the viewer); ``eta`` = IOR inside / outside.

    Returns ``(direction, tir)``: the refracted unit direction, or the reflected one
    where total internal reflection happens (``tir`` True)."""
    view = np.asarray(view, np.float64)
    n = np.asarray(n, np.float64)
    cos_i = -np.sum(view * n, axis=-1, keepdims=True)
    r = 1.0 / np.asarray(eta, np.float64)
    k = 1.0 - r * r * (1.0 - cos_i * cos_i)
    tir = k < 0
    wt = r * view + (r * cos_i - np.sqrt(np.where(tir, 0.0, k))) * n
    wt /= np.linalg.norm(wt, axis=-1, keepdims=True)
    wr = view + 2.0 * cos_i * n
    return np.where(tir, wr, wt), tir[..., 0]


def basis(n):
    """Orthonormal (b1, b2) completing unit normals n (..., 3) (Duff et al. 2017)."""
    n = np.asarray(n, np.float64)
    sgn = np.where(n[..., 2] >= 0, 1.0, -1.0)
    a = -1.0 / (sgn + n[..., 2])
    b = n[..., 0] * n[..., 1] * a
    b1 = np.stack([1.0 + sgn * n[..., 0] ** 2 * a, sgn * b, -sgn * n[..., 0]], axis=-1)
    b2 = np.stack([b, sgn + n[..., 1] ** 2 * a, -n[..., 1]], axis=-1)
    return b1, b2


def ggx_sample_weight(wol, alpha, u1, u2, eta=1.5, conductor=False, f0=(1.0, 1.0, 1.0)):
    """One VNDF sample per local outgoing direction ``wol`` (..., 3), ``wol_z > 0``.

    Returns ``(wil, weight)``: the sampled incoming direction (local) and the
    estimator weight ``f cos / pdf = F G2 / G1`` (..., 3), 0 below the surface.
    For ``alpha = 0``: the mirror direction and weight F."""
    wol = np.asarray(wol, np.float64)
    if alpha > 0:
        m = sample_vndf(wol, alpha, u1, u2)
    else:
        m = np.broadcast_to(np.array([0.0, 0.0, 1.0]), wol.shape)
    cm = np.sum(wol * m, axis=-1)
    wil = 2.0 * cm[..., None] * m - wol
    ok = (wil[..., 2] > 0) & (cm > 0)
    F = fresnel_schlick(cm, f0) if conductor else np.repeat(fresnel_dielectric(cm, eta)[..., None], 3, -1)
    if alpha > 0:
        lo = smith_lambda(wol[..., 2], alpha)
        li = smith_lambda(wil[..., 2], alpha)
        F = F * ((1.0 + lo) / (1.0 + lo + li))[..., None]
    return wil, np.where(ok[..., None], F, 0.0)


