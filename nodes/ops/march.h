/* march.h -- OpenCL helpers shared by every pixel-height tracer (shadow,
 * reflection, refraction). Numpy mirror: march.py (same names without the
 * "ph_" prefix). Include with  #include "march.h"  (load_kernel_source inlines it).
 *
 * Conventions (design.md §2): u right, v down, in pixels; pixel [i, j] has its
 * centre at (u, v) = (j + 0.5, i + 0.5). A point of pixel-height space is
 * (u, v, h), h in pixels; the foot of (u, v, h) is (u, v + h). 3D lines stay lines
 * in (u, v, h), so a ray is  p(t) = o + t * d  and its height is linear in t.
 *
 * A march samples a ray at one pixel per step along its image major axis:
 *     p_k = o + k * step,  step = d / max(|d.u|, |d.v|),  k integer,
 * so that a receiver at a pixel centre visits the pixel centres of the major
 * axis exactly (step.u or step.v is exactly +-1).
 *
 * Contents, in order of use:
 *   ph_march_setup          DDA set-up of a ray (one pixel per major-axis step)
 *   ph_clip_slab/_rect      Liang-Barsky clipping (image, cutout bounding box)
 *   ph_march_clip_box       clip a march to a box x height band (+1 margin sample)
 *   ph_march_clip_foot      ... to a band of feet v + h (+1 margin sample)
 *   ph_segments_may_hit     division-free rejection of segments missing a box
 *   ph_sample_u/_v, ph_ray_height, ph_ray_foot, ph_lerp_height
 *   ph_surface_height       surface height at a sample (minor-axis blend)
 *   ph_side, ph_continuous, ph_occludes   the occlusion test with thickness
 *   ph_span_end, ph_span_skippable        exact skipping with a tile map
 *
 * Nothing here needs -cl-fast-relaxed-math or breaks under it: there are no NaN
 * or inf tests; callers replace non-finite data by sentinels on the host
 * (PH_NO_SURFACE). (Our shadow kernels build without it: see shadow.py.)
 */
#ifndef PIXGRAPH_MARCH_H
#define PIXGRAPH_MARCH_H

/* Height value (pixels) that marks "no occluding surface here" in a surface
 * height buffer (outside the cutout mask, or a non-finite input height). Any
 * height <= PH_NO_SURFACE_TEST is treated as absent. A sentinel instead of NaN
 * because NaN tests are unreliable under -cl-fast-relaxed-math. */
#define PH_NO_SURFACE (-1.0e30f)
#define PH_NO_SURFACE_TEST (-1.0e29f)

/* A ray whose image direction is shorter than this (pixels) has no image
 * extent: the receiver sits on the light's image point. Marches refuse it. */
#define PH_MIN_IMAGE_LENGTH 1.0e-4f

/* Largest foot difference (pixels) between two neighbouring pixels that
 * ph_surface_height still blends: upright surfaces have equal feet, slanted
 * and horizontal ones differ by about 1-2 px per pixel. */
#define PH_INTERP_JUMP 2.0f

/* A ray point is "behind" a surface only when it is lower than the surface by
 * more than this (pixels). Rays that run along their own surface (coplanar)
 * then count as in front consistently, which avoids self-shadow acne from
 * float rounding. */
#define PH_BEHIND_EPS 1.0e-3f

/* Upper bound for k when the ray has no far end (t_max infinite); any clip to a
 * finite box brings it down to at most max(W, H) + 2. */
#define PH_K_UNBOUNDED 1000000000

/* One march: origin o (u, v, h), per-step increment step (u, v, h), and the
 * inclusive integer range [k_lo, k_hi] of samples still to visit. Empty when
 * k_lo > k_hi. */
typedef struct {
    float u, v, h;
    float su, sv, sh;
    int k_lo, k_hi;
    int major_u; /* 1: steps along u (step.u = +-1); 0: along v (step.v = +-1) */
} ph_march;

/* Liang-Barsky for one axis: narrow [*t0, *t1] to the parameters t where
 * o + t * d lies in the closed slab [lo, hi]. Returns 0 when the interval becomes
 * empty (also for d == 0 with o outside the slab), 1 otherwise. lo may be
 * -huge and hi +huge (finite) for a one-sided slab. */
inline int ph_clip_slab(float o, float d, float lo, float hi, float *t0, float *t1)
{
    if (d == 0.0f) {
        return (o >= lo && o <= hi) && (*t0 <= *t1);
    }
    float inv = 1.0f / d;
    float ta = (lo - o) * inv;
    float tb = (hi - o) * inv;
    if (ta > tb) { float tmp = ta; ta = tb; tb = tmp; }
    *t0 = fmax(*t0, ta);
    *t1 = fmin(*t1, tb);
    return *t0 <= *t1;
}

/* Clip the image ray (ou, ov) + t (du, dv) to the closed rectangle
 * rect = (u0, v0, u1, v1) in pixels: narrows [*t0, *t1], returns 0 when empty.
 * For the image use (0, 0, W, H); for a cutout whose mask pixels span rows
 * i0..i1 and columns j0..j1 use (j0, i0, j1 + 1, i1 + 1) (pixel edges). */
inline int ph_clip_rect(float ou, float ov, float du, float dv, float4 rect,
                        float *t0, float *t1)
{
    return ph_clip_slab(ou, du, rect.x, rect.z, t0, t1)
        && ph_clip_slab(ov, dv, rect.y, rect.w, t0, t1);
}

/* Set up a DDA march of the ray (ou, ov, oh) + t (du, dv, dh), 0 < t <= t_max
 * (t_max may be INFINITY; pass it as a huge float to stay fast-math safe).
 * Samples k = 1 .. floor(t_max * major): k = 0 is the origin's own pixel and is
 * skipped (a receiver never occludes itself at its own position).
 * Returns 0 (and an empty march) when the image direction is shorter than
 * PH_MIN_IMAGE_LENGTH: the ray runs along the view ray of its own pixel. */
inline int ph_march_setup(float ou, float ov, float oh, float du, float dv, float dh,
                          float t_max, ph_march *m)
{
    float adu = fabs(du), adv = fabs(dv);
    float major = fmax(adu, adv);
    m->u = ou; m->v = ov; m->h = oh;
    m->major_u = adu >= adv;
    m->k_lo = 1;
    m->k_hi = 0;
    if (!(major >= PH_MIN_IMAGE_LENGTH)) {
        m->su = 0.0f; m->sv = 0.0f; m->sh = 0.0f;
        return 0;
    }
    float inv = 1.0f / major;
    /* exact +-1 on the major axis: x / |x| is exact in IEEE arithmetic */
    m->su = du * inv;
    m->sv = dv * inv;
    m->sh = dh * inv;
    float kmax = t_max * major;
    m->k_hi = kmax >= (float)PH_K_UNBOUNDED ? PH_K_UNBOUNDED : (int)floor(kmax);
    return m->k_hi >= m->k_lo;
}

/* Narrow a march's sample range to the samples of parameter [t0, t1] plus one
 * margin sample on each side; ok = 0 (the clip found nothing) empties it.
 * Returns 0 when no sample remains. Shared by the ph_march_clip_* functions. */
inline int ph_march_narrow(ph_march *m, int ok, float t0, float t1)
{
    if (!ok) {
        m->k_hi = m->k_lo - 1;
        return 0;
    }
    int a = (int)ceil(t0) - 1;
    int b = (int)floor(t1) + 1;
    if (a > m->k_lo) m->k_lo = a;
    if (b < m->k_hi) m->k_hi = b;
    return m->k_lo <= m->k_hi;
}

/* Clip a march's sample range to the 3D box rect x [h_lo, h_hi] in (u, v, h)
 * space, keeping one extra sample on each side: a side flip between two
 * consecutive samples can straddle the box (and it absorbs rounding at the
 * edges). Returns 0 when no sample remains. Use rect = the cutout's bounding
 * rectangle (pixel edges, see ph_clip_rect) and [h_lo, h_hi] = the range of
 * ray heights that can hit the cutout, e.g. [min fg - thickness, max fg]. */
inline int ph_march_clip_box(ph_march *m, float4 rect, float h_lo, float h_hi)
{
    float t0 = (float)m->k_lo - 1.0f, t1 = (float)m->k_hi + 1.0f;
    int ok = ph_clip_rect(m->u, m->v, m->su, m->sv, rect, &t0, &t1)
             && ph_clip_slab(m->h, m->sh, h_lo, h_hi, &t0, &t1);
    return ph_march_narrow(m, ok, t0, t1);
}

/* Image position (pixels) of sample k. */
inline float ph_sample_u(const ph_march *m, int k) { return m->u + (float)k * m->su; }
inline float ph_sample_v(const ph_march *m, int k) { return m->v + (float)k * m->sv; }

/* Ray height (pixels) at sample k: linear in k because (u, v, h) keeps lines. */
inline float ph_ray_height(const ph_march *m, int k) { return m->h + (float)k * m->sh; }

/* Linear interpolation of the ray height between a receiver height rh (t = 0)
 * and a light height lh (t = 1); t < 0 or t > 1 extrapolates (lights behind the
 * camera march to t < 0). */
inline float ph_lerp_height(float rh, float lh, float t) { return rh + t * (lh - rh); }

/* Height of a surface (pixels) at image point (u, v) of a march sample, from a
 * row-major (H, W) height buffer that holds PH_NO_SURFACE where there is none.
 * The pixel containing (u, v) decides presence (returns PH_NO_SURFACE when it is
 * outside the image or has no surface). Along the minor axis the height is
 * interpolated linearly between the two nearest pixel centres when both carry
 * a surface, so planar surfaces are reproduced exactly (no acne on tilted
 * marches); otherwise the containing pixel's height is used. Nor does it
 * interpolate across a depth discontinuity -- neighbours whose feet (row centre
 * + height) differ by more than PH_INTERP_JUMP pixels, e.g. the edge of a cutout
 * in front of another: a blend of the two would be a surface that exists
 * nowhere (and casts phantom shadows). */
inline float ph_surface_height(__global const float *surf, int W, int H,
                               float u, float v, int major_u)
{
    int j = (int)floor(u), i = (int)floor(v);
    if (j < 0 || j >= W || i < 0 || i >= H) return PH_NO_SURFACE;
    float s = surf[i * W + j];
    if (s <= PH_NO_SURFACE_TEST) return PH_NO_SURFACE;
    if (major_u) {
        float y = v - 0.5f;
        int i0 = (int)floor(y);
        float f = y - (float)i0;
        if (i0 < 0 || i0 + 1 >= H) return s;
        float a = surf[i0 * W + j], b = surf[(i0 + 1) * W + j];
        if (a <= PH_NO_SURFACE_TEST || b <= PH_NO_SURFACE_TEST) return s;
        if (fabs(1.0f + b - a) > PH_INTERP_JUMP) return s;   /* feet (i0+.5)+a, (i0+1.5)+b */
        return a + f * (b - a);
    } else {
        float x = u - 0.5f;
        int j0 = (int)floor(x);
        float f = x - (float)j0;
        if (j0 < 0 || j0 + 1 >= W) return s;
        float a = surf[i * W + j0], b = surf[i * W + j0 + 1];
        if (a <= PH_NO_SURFACE_TEST || b <= PH_NO_SURFACE_TEST) return s;
        if (fabs(b - a) > PH_INTERP_JUMP) return s;          /* same row: feet differ by b - a */
        return a + f * (b - a);
    }
}

/* Side of a ray point relative to a surface at the same image point:
 *  1  behind (ray lower than the surface by more than PH_BEHIND_EPS: its foot
 *     lies farther from the camera than the surface's),
 * -1  in front of or on the surface,
 *  0  no surface there (surf_h <= PH_NO_SURFACE_TEST). */
inline int ph_side(float ray_h, float surf_h)
{
    if (surf_h <= PH_NO_SURFACE_TEST) return 0;
    return (ray_h < surf_h - PH_BEHIND_EPS) ? 1 : -1;
}

/* 1 when two consecutive surface samples with feet (v + surf_h, pixels)
 * foot_prev and foot can belong to one continuous surface: the feet differ by
 * at most `jump` pixels. A larger jump is a depth discontinuity -- the edge of a
 * cutout in front of another, or of a part in front of the rest -- and a ray
 * that changes side there passes through the gap between the two surfaces
 * rather than crossing one: tracers pass prev_side = 0 to ph_occludes then. */
inline int ph_continuous(float foot_prev, float foot, float jump)
{
    return fabs(foot - foot_prev) <= jump;
}

/* Occlusion test against a pixel-height surface with thickness (pixels).
 * side = ph_side(ray_h, surf_h) of this sample, prev_side = that of the previous
 * sample (k - 1; 0 when it had no surface or this is the first sample).
 * Occluded when the ray passes behind the surface by at most `thickness`, or
 * when it changed side between two consecutive surface samples (it crossed the
 * surface between them: steep surfaces or large height steps). */
inline int ph_occludes(float ray_h, float surf_h, float thickness, int side, int prev_side)
{
    if (side == 0) return 0;
    if (side == 1 && surf_h - ray_h <= thickness) return 1;
    return prev_side != 0 && prev_side != side;
}

/* Foot coordinate (pixels) of a ray point: v + h. Behind/in front of a surface
 * compares heights at the same image point, so it compares feet too:
 * ray_h - surf_h = (v + ray_h) - (v + surf_h). For an upright cutout the
 * surface's foot is (nearly) constant, which makes foot bounds tight. */
inline float ph_ray_foot(const ph_march *m, int k)
{
    return (m->v + m->h) + (float)k * (m->sv + m->sh);
}

/* Clip a march's sample range to the rays whose foot v + h lies in
 * [f_lo, f_hi], keeping one extra sample on each side (as ph_march_clip_box).
 * With [f_lo, f_hi] = [min foot - thickness, max foot] of the cutout (pixels,
 * see tile_bounds in march.py for the foot of a sample) no occluding sample is
 * dropped. Returns 0 when no sample remains. */
inline int ph_march_clip_foot(ph_march *m, float f_lo, float f_hi)
{
    float t0 = (float)m->k_lo - 1.0f, t1 = (float)m->k_hi + 1.0f;
    return ph_march_narrow(m, ph_clip_slab(m->v + m->h, m->sv + m->sh, f_lo, f_hi, &t0, &t1), t0, t1);
}

/* Conservative whole-segment rejection, no division: 0 when no point of the
 * segments from receiver r = (ru, rv, rh) to any light point inside the bounds
 * lb = (u_min, u_max, v_min, v_max, h_min, h_max, foot_min, foot_max) can meet
 * the box rect x [h_lo, h_hi] with feet in [f_lo, f_hi] -- every coordinate
 * (and the foot v + h) is linear along a segment, so the segments' range in each
 * is the hull of r's value and lb's interval. 1 means "may hit": march. */
inline int ph_segments_may_hit(float ru, float rv, float rh, float8 lb, float4 rect,
                               float h_lo, float h_hi, float f_lo, float f_hi)
{
    float rf = rv + rh;
    return fmin(ru, lb.s0) <= rect.z && fmax(ru, lb.s1) >= rect.x
        && fmin(rv, lb.s2) <= rect.w && fmax(rv, lb.s3) >= rect.y
        && fmin(rh, lb.s4) <= h_hi && fmax(rh, lb.s5) >= h_lo
        && fmin(rf, lb.s6) <= f_hi && fmax(rf, lb.s7) >= f_lo;
}

/* ---- coarse skipping (exact) -------------------------------------------------
 * A tile map bounds the surface's foot v + h: the surface buffer is cut in
 * tiles of `tile` x `tile` pixels (tile row ti covers pixel rows
 * ti*tile .. ti*tile+tile-1) and tiles[ti * TW + tj] = (min, max) of the foot
 * (i + 0.5) + surf[i, j] over that tile AND its 8 neighbours, widened by
 * PH_FOOT_MARGIN, (+1e30, -1e30) where there is no surface (march.py:
 * tile_bounds). The margin covers a sample that reads its containing pixel's
 * height off the pixel centre (|v - (i + 0.5)| <= 0.5); interpolated heights
 * have their foot between the two pixel feet.
 * A "span" is the run of samples from k to the last sample in the same
 * major-axis tile column; along it the minor coordinate moves by less than one
 * tile (|slope| <= 1), so the dilated tile of sample k bounds every surface
 * the span can read (including the minor-axis interpolation). */
#define PH_FOOT_MARGIN 0.501f

/* floor(a / b) for b > 0 */
inline int ph_floordiv(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

/* Last sample index of the span that starts at sample k. */
inline int ph_span_end(const ph_march *m, int k, int tile)
{
    if (m->major_u) {
        int j = (int)floor(ph_sample_u(m, k));
        int t0 = ph_floordiv(j, tile) * tile;
        return k + (m->su > 0.0f ? t0 + tile - 1 - j : j - t0);
    } else {
        int i = (int)floor(ph_sample_v(m, k));
        int t0 = ph_floordiv(i, tile) * tile;
        return k + (m->sv > 0.0f ? t0 + tile - 1 - i : i - t0);
    }
}

/* 1 when no sample of k..e (inside one span) can occlude or take part in a
 * side flip with a neighbour inside the span: at every sample the ray's foot
 * is at or beyond (nearer the camera than) the largest surface foot -- the ray
 * is in front --, or short of the smallest by more than
 * max(thickness, PH_BEHIND_EPS) -- behind, beyond the thickness.
 * A tracer may then jump from k to e and evaluate e with prev_side = 0: all of
 * k..e are on one side or have no surface, so no flip happens inside.
 * ext (px, >= 0) widens the ray's foot range each side (shadow.cl: the half
 * steps beyond the samples at the edges of a run); 0 for the samples alone. */
inline int ph_span_skippable(__global const float2 *tiles, int TW, int TH, int tile,
                             const ph_march *m, int k, int e, float thickness, float ext)
{
    int ti = ph_floordiv((int)floor(ph_sample_v(m, k)), tile);
    int tj = ph_floordiv((int)floor(ph_sample_u(m, k)), tile);
    ti = clamp(ti, 0, TH - 1);
    tj = clamp(tj, 0, TW - 1);
    float2 b = tiles[ti * TW + tj];
    float fa = ph_ray_foot(m, k), fb = ph_ray_foot(m, e);
    float lo = fmin(fa, fb) - ext, hi = fmax(fa, fb) + ext;
    return lo >= b.y || hi < b.x - fmax(thickness, PH_BEHIND_EPS);
}

#endif /* PIXGRAPH_MARCH_H */
