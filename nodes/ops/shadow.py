"""Hard and soft shadows by marching in pixel-height space (design.md §3).

SSG's hard-shadow algorithm, as used by PixHt-Lab (CVPR 2023, Sec. 3.3): for each
receiver pixel r walk the image segment toward (or away from) the light's image
point, one pixel along the major axis; at each step q on the cutout, the ray's
height is the linear interpolation of r.h and L.h ((u, v, h) space keeps lines);
the receiver is in shadow when the ray passes behind the cutout surface by at
most ``thickness`` pixels, or changes side of the surface between two
consecutive cutout samples of one continuous surface. Where the surface's foot
(v + h) jumps by more than ``thickness + FLIP_JUMP`` pixels between the two
samples -- the outline of a cutout in front of another, or of a part in front
of the rest -- a side change is the ray passing through the gap, not a
crossing, and does not count (SSG's rule counts it and draws a phantom wedge
joining the front cutout to its shadow on the one behind). A run of samples on
the cutout is traced half a step beyond its first and last samples where the
cutout's pixel stands upright (``run_end_hits``, ``pixel_upright``: the ray's
depth behind the surface over that half step, the surface's foot taken
constant), so a part one sample wide blocks the rays that pass through it
between two samples: without it a thin part's shadow shrank with the resolution
(a 1-px bar's shadow 189/234/256 px^2 at 128/256/512 px, now 279/278/278;
tests/test_shadow_thin_parts.py), and a proxy lost thin parts a photo's full
trace has. Each walk is clipped to the cutout's bounding box and to the bands of
heights and feet the cutout spans (march.h), so receivers whose ray never meets
the cutout cost a few flops.

Units: all positions and heights in pixels. Arrays: float32 (H, W).

Light points are float arrays ``(u, v, h, s)``:

* ``s = +1``: march from the receiver toward (u, v) and stop there.
* ``s = -1``: the light is behind the camera plane (or a directional light
  pointing toward the camera): march from the receiver *away* from (u, v); the
  ray height is the same linear function along the line through (r.u, r.v, r.h)
  and (u, v, h), extrapolated; no far end (the cutout's box ends the march).
* ``s = 0`` (extension): (u, v, h) is a direction in (u, v, h) space, for a light at
  infinity parallel to the image plane (its image point is at infinity).

Other s values are snapped to the nearest of these. A light with a non-finite
component occludes nothing (all lit). Receivers whose own height is non-finite
are reported lit; non-finite cutout heights do not occlude.

Receivers are all pixels: inside the mask (mask > 0.5) at the cutout's height
``fg_height`` (so cutouts shadow each other and themselves, guarded by
``thickness``; a receiver's own pixel is never sampled, which avoids self-shadow
acne), outside at ``bg_height``. The background itself never occludes.

Several cutouts: pass one mask and one ``fg_height`` that already merge them
(e.g. ``mask = max(m_i)``, ``fg_height`` = the height of the front-most cutout at
each pixel); merging is the caller's job. The bounding box is that of the merged
mask.

``thickness`` is in pixels like everything else: when an image is resized by s,
scale it by s too (measured on the figure scene of the tests, three lights: the
shadows at 128 and 256 px overlap with IoU 0.79-0.93 at a fixed 1 px, 0.94-0.98
with the thickness scaled).
A larger thickness makes thin (pixel-height) cutouts cast fuller shadows.

Speed (kernels; the numpy reference clips to the same box and bands, or with
``clip_to_cutout=False`` to the image only, and walks every remaining sample,
so the tests compare them): each march is clipped to the cutout's box,
its height band and its foot band (v + h) with Liang-Barsky; segments that
cannot reach that box are rejected without a division; inside, runs of samples
whose ray foot is provably in front of or far behind every cutout pixel of an
8x8 tile neighbourhood are skipped (march.h: ph_span_skippable). All three are
exact up to float rounding: the kernels give the reference's result
(tests/test_shadow_ref.py).
"""
from __future__ import annotations

import functools

import numpy as np

from pixgraph.device import load_kernel_source

from . import march as M

F32 = np.float32
#: A side flip between consecutive cutout samples counts only when their surface
#: feet (v + h) differ by at most thickness + FLIP_JUMP pixels (march.h:
#: ph_continuous); mirrors PH_FLIP_JUMP in shadow.cl.
FLIP_JUMP = 1.0
#: A cutout pixel whose foot (row centre + height) differs from the next row's by
#: at most this (pixels) stands upright (``pixel_upright``): the runs of samples on
#: it are traced half a step beyond their first and last samples
#: (``run_end_hits``), so that a thin part blocks the rays that pass through it
#: between two samples, at any resolution. Mirrors PH_UPRIGHT_STEP in shadow.cl.
UPRIGHT_STEP = F32(0.5)
#: The cutout's height band is widened by this (pixels) each side: a run's edge
#: reaches half a step past its sample, where an upright surface's height differs
#: by up to half a pixel (measured along v).
EDGE_BAND = 1.0
#: Stand-in for "no far end" of a march (s = -1 or 0), in units of t.
_T_FAR = F32(1.0e30)
#: Pixel-light-sample pairs per band of a banded launch (ShadowScene.bands):
#: 10-20 ns each where the marches walk the cutout on a shared 2-core PoCL
#: CPU, so a band takes well under 0.1 s and a cancelled run stops within one;
#: each band adds one launch and one wait (benchmarks/shadow_bench.py, banded).
BAND_WORK = 1 << 22
#: Narrowest piece of a row a banded launch makes (pixels): narrower launches
#: leave cores idle.
BAND_MIN_WIDTH = 128


def _cl():
    import pyopencl as cl
    return cl


def light_array(light) -> np.ndarray:
    """A light point as float32 (4,) ``(u, v, h, s)`` with s snapped to {-1, 0, 1};
    a non-finite light becomes ``(0, 0, 0, 0)``, which every march refuses (lit)."""
    a = np.asarray(light, dtype=np.float64).reshape(-1)
    if a.shape != (4,):
        raise ValueError(f"a light point is (u, v, h, s), got shape {np.shape(light)}")
    return light_samples_array(a[None])[0]


def light_samples_array(samples) -> np.ndarray:
    """Light samples as float32 (N, 4), each sanitised like :func:`light_array`."""
    a = np.asarray(samples, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 4:
        raise ValueError(f"light samples are (N, 4) rows (u, v, h, s), got shape {a.shape}")
    a = a.copy()
    a[:, 3] = np.where(a[:, 3] > 0.5, 1.0, np.where(a[:, 3] < -0.5, -1.0, 0.0))
    bad = ~np.all(np.isfinite(a), axis=1) | ~np.all(np.abs(a[:, :3]) < 1e30, axis=1)
    a[bad] = 0.0
    return a.astype(np.float32)


def _check_thickness(thickness) -> float:
    t = float(thickness)
    if not t >= 0.0:
        raise ValueError(f"thickness must be >= 0 pixels, got {thickness}")
    return min(t, 1.0e20)  # inf: any depth behind the surface occludes


class Prepared:
    """Host-side preparation shared by the reference and the kernels.

    surf: occluder heights (NO_SURFACE off the cutout); recv: receiver heights
    (cutout inside the mask, background outside; NO_SURFACE where non-finite);
    bg: background heights (NO_SURFACE where non-finite); rect: the cutout's
    bounding box as pixel edges (u0, v0, u1, v1); h_lo, h_hi: the ray heights
    that can hit the cutout, f_lo, f_hi: the same for the ray's foot v + h;
    empty: no cutout pixel at all.
    """

    def __init__(self, mask, fg_height, bg_height, thickness=1.0):
        # C order: the kernels read the buffers row-major; a transposed or
        # Fortran-ordered view (a host's array, a resize's axis swap) would be
        # uploaded as its raw memory, i.e. transposed
        mask = np.ascontiguousarray(mask)
        fg = np.ascontiguousarray(fg_height, dtype=np.float32)
        bg = np.ascontiguousarray(bg_height, dtype=np.float32)
        if mask.ndim != 2 or fg.shape != mask.shape or bg.shape != mask.shape:
            raise ValueError(f"mask, fg_height and bg_height must share one (H, W) shape, got "
                             f"{mask.shape}, {fg.shape}, {bg.shape}")
        self.thickness = _check_thickness(thickness)
        self.H, self.W = mask.shape
        inside = mask > 0.5
        occ = inside & np.isfinite(fg)
        self.surf = np.where(occ, fg, M.NO_SURFACE).astype(np.float32, copy=False)
        recv = np.where(inside, fg, bg).astype(np.float32, copy=False)
        recv[~np.isfinite(recv)] = M.NO_SURFACE
        self.recv = recv
        self._bg_in = bg
        self._bg = None
        rows = np.flatnonzero(occ.any(axis=1))
        self.empty = rows.size == 0
        if self.empty:
            self.rect = np.zeros(4, np.float32)
            self.h_lo = self.h_hi = self.f_lo = self.f_hi = F32(0)
        else:
            cols = np.flatnonzero(occ.any(axis=0))
            r0, r1, c0, c1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
            self.rect = np.array([c0, r0, c1, r1], np.float32)
            crop, present = self.surf[r0:r1, c0:c1], occ[r0:r1, c0:c1]
            big = np.float32(3e38)
            h_min = float(np.where(present, crop, big).min())
            h_max = float(np.where(present, crop, -big).max())
            foot = crop.astype(np.float64) + (np.arange(r0, r1) + 0.5)[:, None]
            f_min = float(np.where(present, foot, np.inf).min()) - float(M.FOOT_MARGIN)
            f_max = float(np.where(present, foot, -np.inf).max()) + float(M.FOOT_MARGIN)
            # below min height - reach a sample is behind every surface beyond the
            # thickness; reach >= BEHIND_EPS because a sample up to BEHIND_EPS below
            # a surface still counts as in front (and can start a side flip)
            reach = max(self.thickness, float(M.BEHIND_EPS))
            self.h_lo = F32(h_min - reach - EDGE_BAND)
            self.h_hi = F32(h_max + EDGE_BAND)
            self.f_lo = F32(f_min - reach)
            self.f_hi = F32(f_max)

    @property
    def bg(self) -> np.ndarray:
        """Background heights, NO_SURFACE where non-finite (computed on first use)."""
        if self._bg is None:
            bg = self._bg_in
            self._bg = np.where(np.isfinite(bg), bg, M.NO_SURFACE).astype(np.float32)
        return self._bg


# --------------------------------------------------------------------------
# numpy reference
# --------------------------------------------------------------------------

def light_march_ref(ru, rv, rh, light):
    """Marches from receivers (arrays) to one light point (mirror of light_march)."""
    lu, lv, lh, s = (F32(x) for x in light)
    if s > 0.5:
        return M.march_setup(ru, rv, rh, lu - ru, lv - rv, lh - rh, F32(1.0))
    if s < -0.5:
        return M.march_setup(ru, rv, rh, ru - lu, rv - lv, rh - lh, _T_FAR)
    return M.march_setup(ru, rv, rh, lu, lv, lh, _T_FAR)


def trace_ref(prep: Prepared, light, clip_to_cutout: bool = True):
    """Trace every receiver toward one light (numpy, vectorised over receivers).

    clip_to_cutout: clip each march to the cutout's box (as the kernels do);
    False clips only to the image (the plain algorithm; used to test that the
    clip changes nothing).
    Returns ``(blocked, hit_u, hit_v, hit_s)``: bool (H, W), and for blocked
    receivers the image position and cutout height (pixels) of the first
    blocking sample (NaN elsewhere).
    """
    H, W = prep.H, prep.W
    light = light_array(light)
    blocked = np.zeros((H, W), bool)
    hit = np.full((3, H, W), np.nan, np.float32)
    if prep.empty:
        return blocked, hit[0], hit[1], hit[2]
    ii, jj = np.nonzero(prep.recv > M.NO_SURFACE_TEST)
    ru = (jj + 0.5).astype(np.float32)
    rv = (ii + 0.5).astype(np.float32)
    rh = prep.recv[ii, jj]
    m, ok = light_march_ref(ru, rv, rh, light)
    if clip_to_cutout:
        k_lo0, k_hi0 = m.k_lo.copy(), m.k_hi.copy()
        ok &= M.march_clip_box(m, prep.rect, prep.h_lo, prep.h_hi)
        ok &= M.march_clip_foot(m, prep.f_lo, prep.f_hi)
        # a second margin sample each side: the edges of a run (run_end_hits) at the
        # clipped range's ends then cannot block, so clipping changes nothing
        m.k_lo, m.k_hi = np.maximum(m.k_lo - 1, k_lo0), np.minimum(m.k_hi + 1, k_hi0)
    else:
        ok &= M.march_clip_box(m, (0, 0, W, H), F32(-1e30), F32(1e30))
    sel = np.flatnonzero(ok)
    # state of the previous sample k - 1: side for the flip test (0: none), on the
    # cutout, its surface foot, depth d = surface height - ray height, whether it
    # continued the surface of k - 2, whether its run edges may be tested, and its
    # position and surface height (for the hit). Before the first sample of an
    # unclipped march, "k - 1" is the receiver's own pixel when it lies on the
    # cutout: the run of its own surface does not start at k = 1 (no edge there),
    # and the receiver itself is never tested.
    own = prep.surf[ii[sel], jj[sel]]
    start_here = (m.k_lo[sel] == 1) & (own > M.NO_SURFACE_TEST)
    z = np.zeros(sel.size, np.float32)
    st = {"prev": np.zeros(sel.size, np.int8), "pon": start_here,
          "pfoot": np.where(start_here, (rv[sel] + own).astype(np.float32), F32(0)).astype(np.float32),
          "pd": z, "pcont": np.zeros(sel.size, bool), "ptest": np.zeros(sel.size, bool),
          "pu": z, "pv": z, "ps": z}
    jump = F32(prep.thickness + FLIP_JUMP)
    T = prep.thickness

    def record(where, u, v, s_):
        b = sel[where]
        blocked[ii[b], jj[b]] = True
        hit[0, ii[b], jj[b]] = u[where]
        hit[1, ii[b], jj[b]] = v[where]
        hit[2, ii[b], jj[b]] = s_[where]

    def edges(cont):
        """run_end_hits of sample k - 1 (``cont``: k continues its surface)."""
        df = (m.sv[sel] + m.sh[sel]).astype(np.float32)
        test = st["pon"] & st["ptest"]
        up = np.zeros(sel.size, bool)
        if test.any():
            up[test] = pixel_upright(prep.surf, st["pu"][test], st["pv"][test])
        return run_end_hits(test, cont, st["pcont"], up, st["pd"], df, T)

    n = 0
    while sel.size:
        k = m.k_lo[sel] + n
        live = k <= m.k_hi[sel]
        if not live.all():
            # the last sample of these marches ends its run
            e_hit = ~live & edges(np.zeros(sel.size, bool))
            record(e_hit, st["pu"], st["pv"], st["ps"])
            sel, k = sel[live], k[live]
            st = {key: a[live] for key, a in st.items()}
        if not sel.size:
            break
        kf = k.astype(np.float32)
        u = (m.u[sel] + kf * m.su[sel]).astype(np.float32)
        v = (m.v[sel] + kf * m.sv[sel]).astype(np.float32)
        s = M.surface_height(prep.surf, u, v, m.major_u[sel])
        h = (m.h[sel] + kf * m.sh[sel]).astype(np.float32)
        sd = M.side(h, s)
        foot = (v + s).astype(np.float32)
        # one surface with k - 1: a side change across a depth discontinuity is no crossing
        cont = st["pon"] & (sd != 0) & M.continuous(st["pfoot"], foot, jump)
        prev_hit = edges(cont)
        occ = M.occludes(h, s, T, sd, np.where(cont, st["prev"], 0).astype(np.int8)) & ~prev_hit
        record(prev_hit, st["pu"], st["pv"], st["ps"])
        record(occ, u, v, s)
        keep = ~(occ | prev_hit)
        sel = sel[keep]
        st = {"prev": sd[keep], "pon": (sd != 0)[keep], "pfoot": foot[keep], "pd": (s - h).astype(np.float32)[keep],
              "pcont": cont[keep], "ptest": np.ones(sel.size, bool), "pu": u[keep], "pv": v[keep], "ps": s[keep]}
        n += 1
    return blocked, hit[0], hit[1], hit[2]


def pixel_upright(surf: np.ndarray, u, v) -> np.ndarray:
    """Whether the cutout's surface at the pixels of image points (u, v) stands upright
    (mirror of shadow.cl: pixel_upright): its foot (row centre + height) changes by at
    most UPRIGHT_STEP px to the pixel below (or, without one on the cutout, above).
    A pixel with neither (a part one pixel tall) counts as upright: a surface lying
    on the ground changes its foot by 1 px per row."""
    H, W = surf.shape
    i = np.floor(np.asarray(v, np.float32)).astype(np.int64)
    j = np.floor(np.asarray(u, np.float32)).astype(np.int64)
    s = surf[i, j]
    below = np.where(i + 1 < H, surf[np.minimum(i + 1, H - 1), j], M.NO_SURFACE)
    above = np.where(i >= 1, surf[np.maximum(i - 1, 0), j], M.NO_SURFACE)
    has_b, has_a = below > M.NO_SURFACE_TEST, above > M.NO_SURFACE_TEST
    step_b = np.abs(F32(1.0) + below - s)
    step_a = np.abs(F32(1.0) + s - above)
    return np.where(has_b, step_b <= UPRIGHT_STEP, np.where(has_a, step_a <= UPRIGHT_STEP, True))


def edge_hit(d, df, sigma, thickness) -> np.ndarray:
    """Occlusion within the half step beyond a sample at a run's edge (mirror of
    shadow.cl: edge_hit). d: surface height - ray height at the sample (px); df: the
    ray's foot step per sample (sv + sh, px); sigma: -1 the half step before the
    sample, +1 after. The surface is taken upright over the half step (its foot
    constant), the ray's foot moves by sigma df / 2: blocked when the depth
    d(tau) = d - tau df, tau from 0 to sigma / 2, passes in (BEHIND_EPS, thickness]."""
    d = np.asarray(d, np.float32)
    e = (d - F32(sigma) * (F32(0.5) * np.asarray(df, np.float32))).astype(np.float32)
    return (np.maximum(d, e) > M.BEHIND_EPS) & (np.minimum(d, e) <= F32(thickness))


def run_end_hits(test, cont, pcont, upright, pd, df, thickness) -> np.ndarray:
    """Whether sample k - 1 blocks within its half steps at the edges of its run
    (mirror of shadow.cl: run_end_hit), decided at sample k. test: k - 1 is on the
    cutout (and is a sample, not the receiver); cont: k continues its surface;
    pcont: k - 1 continued the surface of k - 2; upright: :func:`pixel_upright` of
    k - 1. A run's first sample is tested before it, its last after it, with the
    upright half step of :func:`edge_hit`, where the surface stands upright; a
    surface lying on the ground is left as the samples show it (the upright half
    step would shade rays grazing it)."""
    t = test & upright
    return (t & ~pcont & edge_hit(pd, df, -1, thickness)) | (t & ~cont & edge_hit(pd, df, 1, thickness))


def hard_shadow_ref(mask, fg_height, bg_height, light, thickness=1.0, *,
                    clip_to_cutout: bool = True) -> np.ndarray:
    """Numpy reference of :func:`hard_shadow`: lit float32 (H, W), 1 lit, 0 shadow.
    ``clip_to_cutout=False`` walks the whole image segment (slow, same result)."""
    prep = Prepared(mask, fg_height, bg_height, thickness)
    blocked, *_ = trace_ref(prep, light, clip_to_cutout)
    return np.where(blocked, 0.0, 1.0).astype(np.float32)


def soft_shadow_ref(mask, fg_height, bg_height, light_samples, thickness=1.0) -> np.ndarray:
    """Numpy reference of :func:`soft_shadow`: the lit fraction float32 (H, W)."""
    prep = Prepared(mask, fg_height, bg_height, thickness)
    samples = light_samples_array(light_samples)
    if samples.shape[0] == 0:
        return np.ones((prep.H, prep.W), np.float32)
    acc = np.zeros((prep.H, prep.W), np.float64)
    for L in samples:
        acc += trace_ref(prep, L)[0]
    return (1.0 - acc / samples.shape[0]).astype(np.float32)


# --------------------------------------------------------------------------
# OpenCL
# --------------------------------------------------------------------------

#: Build options: none -- IEEE arithmetic. The kernels would tolerate
#: -cl-fast-relaxed-math (no NaN/inf tests; sentinels instead), but on PoCL it
#: makes vector division approximate (1/1 = 0.99999994 in float8), so the
#: vectorised soft-shadow set-up drifted from the scalar march on exact ties
#: (5% of a test image), and saved 0-12% CPU in our measurements.
BUILD_OPTIONS: tuple[str, ...] = ()


@functools.lru_cache(maxsize=1)
def kernel_source() -> str:
    """shadow.cl with march.h inlined (read once per process)."""
    return load_kernel_source(__file__, "shadow.cl")


def program(device):
    """The built shadow program (cached per device by ``device.program``)."""
    return device.program(kernel_source(), BUILD_OPTIONS)


def _kernel(prg, name):
    """A kernel object of `prg`, created once per program and thread (creating
    one costs ~1 ms on PoCL; set_args on a shared one would race between threads)."""
    import threading
    cl = _cl()
    cache = prg.__dict__.setdefault("_pixgraph_kernels", {})
    key = (name, threading.get_ident())
    kern = cache.get(key)
    if kern is None:
        kern = cache[key] = cl.Kernel(prg, name)
    return kern


def _f4(x):
    import pyopencl.cltypes as cltypes
    return cltypes.make_float4(*(float(v) for v in x))


class ShadowScene:
    """One scene (mask, cutout and background heights) uploaded once to a device,
    traced against any number of lights without further uploads.

    The module functions :func:`hard_shadow`, :func:`soft_shadow` and
    ``buffers.buffer_channels`` build one per call; keep one yourself to trace
    many lights (interactive light dragging) or for benchmarks. One scene
    reuses its output buffers between launches: use it from one thread at a
    time (the module functions are safe to call from several threads).
    """

    def __init__(self, device, mask, fg_height, bg_height, thickness=1.0):
        cl = _cl()
        self.device = device
        self.prep = Prepared(mask, fg_height, bg_height, thickness)
        self.prg = program(device)
        mf = cl.mem_flags
        ctx = device.context
        p = self.prep
        self.surf = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=p.surf)
        self.recv = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=p.recv)
        tiles = M.tile_bounds(p.surf, M.TILE, p.rect if not p.empty else None)
        self.TH, self.TW = tiles.shape[:2]
        self.tiles = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=tiles)
        self._bg = None
        self._out = {}
        self.last_event = None

    @property
    def shape(self):
        return self.prep.H, self.prep.W

    def bg_buffer(self):
        if self._bg is None:
            cl = _cl()
            self._bg = cl.Buffer(self.device.context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR,
                                 hostbuf=self.prep.bg)
        return self._bg

    def out_buffer(self, name, nbytes):
        """A device output buffer reused between launches of the same size."""
        cl = _cl()
        buf = self._out.get(name)
        if buf is None or buf.size != nbytes:
            buf = cl.Buffer(self.device.context, cl.mem_flags.WRITE_ONLY, nbytes)
            self._out[name] = buf
        return buf

    def occluder_args(self):
        """The kernels' leading OCCLUDER_ARGS (shadow.cl), in order."""
        p = self.prep
        return (self.surf, self.tiles, np.int32(p.W), np.int32(p.H), np.int32(self.TW),
                np.int32(self.TH), np.int32(M.TILE), _f4(p.rect), np.float32(p.h_lo),
                np.float32(p.h_hi), np.float32(p.f_lo), np.float32(p.f_hi), np.float32(p.thickness))

    def launch(self, name, *args, region=None):
        """Enqueue kernel `name` over (W, H) with the occluder args then `args`;
        ``region=(x0, y0, nx, ny)`` covers only that rectangle of pixels (a global
        offset: each pixel is computed exactly as in a whole-image launch)."""
        kern = _kernel(self.prg, name)
        kern.set_args(*self.occluder_args(), *args)
        p = self.prep
        x0, y0, nx, ny = region if region is not None else (0, 0, p.W, p.H)
        return _cl().enqueue_nd_range_kernel(self.device.queue, kern, (nx, ny), None,
                                             global_work_offset=(x0, y0) if (x0 or y0) else None)

    def bands(self, cost=1.0):
        """The pieces of a banded launch, ``(x0, y0, nx, ny)`` in order: bands of
        whole rows holding about ``BAND_WORK / cost`` pixels, or, when one row
        is more work than that, pieces of single rows (at least BAND_MIN_WIDTH
        pixels wide, so that every core still gets work)."""
        p = self.prep
        per_band = BAND_WORK / max(float(cost), 1.0)
        rows = int(min(p.H, per_band / p.W))
        if rows >= 1:
            return [(0, y0, p.W, min(rows, p.H - y0)) for y0 in range(0, p.H, rows)]
        cols = int(min(p.W, max(BAND_MIN_WIDTH, per_band)))
        return [(x0, y0, min(cols, p.W - x0), 1) for y0 in range(p.H) for x0 in range(0, p.W, cols)]

    def launch_banded(self, name, *args, cost=1.0, progress=None, check_cancelled=None):
        """Enqueue kernel `name` in bands (:meth:`bands`) and wait for each, so that
        a long launch reports ``progress(fraction, message)`` and honours
        ``check_cancelled()`` between bands; returns the last band's event.

        cost: work per pixel relative to one hard shadow (e.g. the light sample
        count). The bands change nothing in the result (see :meth:`launch`).
        Without either callback the image is one launch, as before.
        """
        p = self.prep
        if progress is None and check_cancelled is None:
            return self.launch(name, *args)
        ev, done, total = None, 0, p.W * p.H
        for region in self.bands(cost):
            if check_cancelled is not None:
                check_cancelled()
            ev = self.launch(name, *args, region=region)
            ev.wait()
            done += region[2] * region[3]
            if progress is not None:
                progress(done / total, name.replace("_", " "))
        return ev

    def launch_hard(self, light, progress=None, check_cancelled=None):
        """Enqueue the hard-shadow kernel; returns (event, output buffer) (banded
        with callbacks, as :meth:`launch_soft`)."""
        p = self.prep
        out = self.out_buffer("hard", p.H * p.W * 4)
        return self.launch_banded("hard_shadow", self.recv, _f4(light_array(light)), out,
                                  progress=progress, check_cancelled=check_cancelled), out

    def soft_inputs(self, light_samples):
        """Upload light samples (N, 4) for the soft-shadow kernel: structure of
        arrays padded to a multiple of 8 with refused lights, plus the bounds of
        the samples with s = +1 and of those with s = -1 (one test per kind then
        rejects every sample for receivers whose rays miss the cutout's box;
        shadow.cl: soft_shadow's ``kinds``)."""
        import pyopencl.cltypes as cltypes
        samples = light_samples_array(light_samples)
        n = samples.shape[0]
        n8 = max(8, -(-n // 8) * 8)
        soa = np.zeros((4, n8), np.float32)
        soa[:, :n] = samples.T
        s = samples[:, 3]
        # a zeroed (invalid) sample is lit by every march: it needs no bit
        invalid = np.all(samples == 0.0, axis=1)
        kinds = 0
        bounds = []
        for bit, sel in ((1, s > 0.5), (2, s < -0.5)):
            if sel.any():
                kinds |= bit
                u, v, h = samples[sel, 0], samples[sel, 1], samples[sel, 2]
                f = v + h
                bounds.append(cltypes.make_float8(u.min(), u.max(), v.min(), v.max(), h.min(), h.max(),
                                                  f.min(), f.max()))
            else:
                bounds.append(cltypes.make_float8(0, 0, 0, 0, 0, 0, 0, 0))
        if np.any((np.abs(s) <= 0.5) & ~invalid):
            kinds |= 4
        return (self.samples_buffer(soa), np.int32(n), np.int32(n8), np.int32(kinds), *bounds)

    def launch_soft(self, inputs, progress=None, check_cancelled=None):
        """Enqueue the soft-shadow kernel on inputs from :meth:`soft_inputs`;
        returns (event, output buffer). With ``progress`` or ``check_cancelled``
        it runs in bands of rows (:meth:`launch_banded`) and returns when done."""
        p = self.prep
        out = self.out_buffer("soft", p.H * p.W * 4)
        return self.launch_banded("soft_shadow", self.recv, *inputs, out, cost=int(inputs[1]),
                                  progress=progress, check_cancelled=check_cancelled), out

    def _read(self, buf, shape, after=None):
        """Blocking read of a device buffer, after event `after` (so an
        out-of-order queue a host hands in is safe too)."""
        cl = _cl()
        host = np.empty(shape, np.float32)
        cl.enqueue_copy(self.device.queue, host, buf, wait_for=[after] if after is not None else None)
        return host

    def samples_buffer(self, samples: np.ndarray):
        cl = _cl()
        return cl.Buffer(self.device.context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR,
                         hostbuf=np.ascontiguousarray(samples, np.float32))

    def hard_shadow(self, light, progress=None, check_cancelled=None) -> np.ndarray:
        p = self.prep
        if p.empty:
            return np.ones((p.H, p.W), np.float32)
        ev, out = self.launch_hard(light, progress, check_cancelled)
        self.last_event = ev
        return self._read(out, (p.H, p.W), ev)

    def soft_shadow(self, light_samples, progress=None, check_cancelled=None) -> np.ndarray:
        p = self.prep
        samples = light_samples_array(light_samples)
        if p.empty or samples.shape[0] == 0:
            return np.ones((p.H, p.W), np.float32)
        ev, out = self.launch_soft(self.soft_inputs(samples), progress, check_cancelled)
        self.last_event = ev
        return self._read(out, (p.H, p.W), ev)


def hard_shadow(device, mask, fg_height, bg_height, light, thickness=1.0, *,
                progress=None, check_cancelled=None) -> np.ndarray:
    """Hard shadow of the cutout from one light point (OpenCL).

    mask: (H, W), cutout where > 0.5. fg_height, bg_height: float (H, W) pixel
    heights of the cutout and the background (pixels). light: (u, v, h, s), see
    the module docstring. thickness: how far (pixels) a ray may pass behind the
    cutout surface and still count as blocked.
    Returns lit float32 (H, W): 1 lit, 0 shadow. An empty mask returns all ones
    without launching. progress, check_cancelled: as :func:`soft_shadow`.
    """
    return ShadowScene(device, mask, fg_height, bg_height, thickness).hard_shadow(
        light, progress, check_cancelled)


def soft_shadow(device, mask, fg_height, bg_height, light_samples, thickness=1.0, *,
                progress=None, check_cancelled=None) -> np.ndarray:
    """Soft shadow: the fraction of light samples (N, 4) that reach each pixel,
    float32 (H, W) in [0, 1] (1 fully lit). Invalid (non-finite) samples count
    as reaching the pixel; N = 0 gives all ones.

    One kernel launch; with ``progress(fraction, message)`` or
    ``check_cancelled()`` (a node's ``ctx.progress`` and ``ctx.check_cancelled``)
    it runs in bands of rows of about ``BAND_WORK`` pixel-samples each, calling
    them between bands (same result: every pixel is computed the same way)."""
    return ShadowScene(device, mask, fg_height, bg_height, thickness).soft_shadow(
        light_samples, progress, check_cancelled)
