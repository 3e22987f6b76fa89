/* shadow.cl -- hard shadows, soft shadows and SSN++ buffer channels by marching
 * in pixel-height space (SSG's algorithm, design.md §3; PixHt-Lab Sec. 3.2-3.3).
 * Numpy reference: shadow.py (hard_shadow_ref, soft_shadow_ref) and buffers.py
 * (buffer_channels_ref).
 *
 * Inputs prepared on the host (shadow.py: ShadowScene):
 *   surf  (H, W) occluder height in pixels: the cutout's pixel height where the
 *         mask is on and the height finite, PH_NO_SURFACE elsewhere.
 *   recv  (H, W) receiver height in pixels: the cutout's height inside the mask,
 *         the background's outside; PH_NO_SURFACE for a non-finite height (such
 *         receivers are reported lit).
 *   rect  (u0, v0, u1, v1) pixel edges of the cutout's bounding box, and
 *   h_lo, h_hi: the ray heights that can hit the cutout (min height - thickness,
 *         max height, each widened by shadow.py's EDGE_BAND for the run edges), and
 *         f_lo, f_hi: the same for the ray's foot v + h. Every march is clipped to
 *         that box and foot band (march.h), plus a second margin sample each side.
 *   tiles (TH, TW) float2 foot bounds for exact skipping (march.h, tile_bounds).
 *   light (u, v, h, s): s = +1 march from the receiver toward (u, v) and stop
 *         there; s = -1 the light is behind the camera plane: march away from
 *         (u, v), the height extrapolated along the same (u, v, h) line, no far
 *         end; s = 0 (extension) (u, v, h) is a direction in (u, v, h) space (a
 *         light at infinity parallel to the image plane). The host maps
 *         non-finite lights to (0, 0, 0, 0), which every march refuses (lit).
 */
#include "march.h"

/* A side flip between consecutive cutout samples counts as a crossing only when
 * their surface feet differ by at most thickness + PH_FLIP_JUMP pixels
 * (ph_continuous): 1 px of slack for slanted surfaces and minor-axis steps. */
#define PH_FLIP_JUMP 1.0f

/* The march from receiver (ru, rv, rh) to light point L. Returns 0 when the ray
 * has no image extent (receiver on the light's image point, or an invalid
 * light): then the receiver is lit -- the only possible occluder would sit on
 * the receiver's own pixel, which a receiver never occludes. */
inline int light_march(float ru, float rv, float rh, float4 L, ph_march *m)
{
    if (L.w > 0.5f)
        return ph_march_setup(ru, rv, rh, L.x - ru, L.y - rv, L.z - rh, 1.0f, m);
    if (L.w < -0.5f)
        return ph_march_setup(ru, rv, rh, ru - L.x, rv - L.y, rh - L.z, 1.0e30f, m);
    return ph_march_setup(ru, rv, rh, L.x, L.y, L.z, 1.0e30f, m);
}

/* The cutout as the tracers see it: occluder heights, the coarse tile bounds
 * (march.h), the cutout's box and height band, and the thickness. */
typedef struct {
    __global const float *surf;
    __global const float2 *tiles;
    int W, H, TW, TH, tile;
    float4 rect;
    float h_lo, h_hi, f_lo, f_hi, thickness;
    float jump; /* largest surface-foot change between samples of one surface */
} occluder;

inline int march_loop(const occluder *o, ph_march *m, int *hit_k, float *hit_s);

/* Trace one shadow ray. Returns 1 when blocked, with *hit_k the first blocking
 * sample (nearest the receiver) and *hit_s the cutout height there (pixels).
 * Runs of samples that provably cannot occlude are skipped a tile span at a
 * time (ph_span_skippable); the result equals the sample-by-sample march of
 * the numpy reference. */
inline int shadow_trace(const occluder *o, ph_march *m, int *hit_k, float *hit_s)
{
    /* Fast path for receivers on the cutout that shade themselves (back-lit
     * parts): the first sample, by the thickness rule alone, before any
     * clipping. It is also the first sample of the full march (prev_side 0),
     * so a hit here is the march's first hit. */
    if (m->k_hi >= 1) {
        float s1 = ph_surface_height(o->surf, o->W, o->H, ph_sample_u(m, 1), ph_sample_v(m, 1),
                                     m->major_u);
        float r1 = ph_ray_height(m, 1);
        if (ph_occludes(r1, s1, o->thickness, ph_side(r1, s1), 0)) {
            *hit_k = 1;
            *hit_s = s1;
            return 1;
        }
    }
    /* the foot band first: one slab, and the most selective for upright cutouts */
    int k_lo0 = m->k_lo, k_hi0 = m->k_hi;
    if (!ph_march_clip_foot(m, o->f_lo, o->f_hi)) return 0;
    if (!ph_march_clip_box(m, o->rect, o->h_lo, o->h_hi)) return 0;
    /* a second margin sample each side: the edges of a run at the ends of the
     * clipped range then cannot block (march_loop), so clipping changes nothing */
    m->k_lo = max(m->k_lo - 1, k_lo0);
    m->k_hi = min(m->k_hi + 1, k_hi0);
    return march_loop(o, m, hit_k, hit_s);
}

/* Occlusion within the half step beyond a sample at a run's edge (numpy:
 * shadow.py edge_hit). d: surface height - ray height at the sample (px); df: the
 * ray's foot step per sample (sv + sh); sigma -1: the half step before the sample,
 * +1 after. The surface is upright over the half step (its foot constant) and the
 * ray's foot moves by sigma df / 2: blocked when the depth d - tau df, tau from 0
 * to sigma / 2, passes in (PH_BEHIND_EPS, thickness]. */
inline int edge_hit(float d, float df, float sigma, float thickness)
{
    float e = d - sigma * (0.5f * df);
    return fmax(d, e) > PH_BEHIND_EPS && fmin(d, e) <= thickness;
}

/* A cutout pixel whose foot (row centre + height) differs from the next row's by at
 * most this (px) stands upright (shadow.py: UPRIGHT_STEP). */
#define PH_UPRIGHT_STEP 0.5f

/* 1 when the cutout's surface at the pixel of image point (u, v) stands upright
 * (numpy: shadow.py pixel_upright): its foot changes by at most PH_UPRIGHT_STEP to
 * the pixel below (or, without one on the cutout, above); a pixel with neither
 * counts as upright. A surface lying on the ground changes its foot by 1 per row. */
inline int pixel_upright(const occluder *o, float u, float v)
{
    int i = (int)floor(v), j = (int)floor(u);
    float s = o->surf[i * o->W + j];
    float b = i + 1 < o->H ? o->surf[(i + 1) * o->W + j] : PH_NO_SURFACE;
    if (b > PH_NO_SURFACE_TEST) return fabs(1.0f + b - s) <= PH_UPRIGHT_STEP;
    float a = i >= 1 ? o->surf[(i - 1) * o->W + j] : PH_NO_SURFACE;
    if (a > PH_NO_SURFACE_TEST) return fabs(1.0f + s - a) <= PH_UPRIGHT_STEP;
    return 1;
}

/* 1 when sample k - 1 (at pu, pv) blocks within the half steps at the edges of its
 * run, decided at sample k (numpy: shadow.py run_end_hits). test: k - 1 is a sample
 * on the cutout; cont: k continues its surface; pcont: k - 1 continued the surface
 * of k - 2. A run's first sample is tested before it, its last after it, where the
 * surface stands upright. */
inline int run_end_hit(const occluder *o, int test, int cont, int pcont, float pu, float pv, float pd,
                       float df)
{
    if (!test || (pcont && cont)) return 0;
    if (!pixel_upright(o, pu, pv)) return 0;
    return (!pcont && edge_hit(pd, df, -1.0f, o->thickness)) || (!cont && edge_hit(pd, df, 1.0f, o->thickness));
}

/* The sample loop of shadow_trace over m's (clipped) range k_lo .. k_hi: the
 * occlusion test of ph_occludes at each sample (side flips only within one
 * continuous surface), and the edges of each run of samples on the cutout
 * (run_end_hit), so that a part one sample wide blocks at any resolution. */
inline int march_loop(const occluder *o, ph_march *m, int *hit_k, float *hit_s)
{
    /* the previous sample k - 1: side for flips, on the cutout, whether its edges may
     * be tested, whether it continued k - 2, foot, depth, position, height. Before
     * an unclipped march's first sample, k - 1 is the receiver's own pixel when it
     * lies on the cutout: its surface's run does not start at k = 1, and the
     * receiver itself is never tested. */
    int prev = 0, pon = 0, ptest = 0, pcont = 0;
    float pfoot = 0.0f, pd = 0.0f, pu = 0.0f, pv = 0.0f, ps = 0.0f;
    if (m->k_lo == 1) {
        float s0 = o->surf[(int)floor(m->v) * o->W + (int)floor(m->u)];
        if (s0 > PH_NO_SURFACE_TEST) {
            pon = 1;
            pfoot = m->v + s0;
        }
    }
    float df = m->sv + m->sh;
    float ext = 0.5f * fabs(df);
    int k = m->k_lo;
    int next_test = k;
    while (k <= m->k_hi) {
        float u = ph_sample_u(m, k), v = ph_sample_v(m, k);
        float s = ph_surface_height(o->surf, o->W, o->H, u, v, m->major_u);
        float rh = ph_ray_height(m, k);
        int sd = ph_side(rh, s);
        float foot = v + s;
        /* one surface with k - 1: a side change across a depth discontinuity is no crossing */
        int cont = pon && sd != 0 && ph_continuous(pfoot, foot, o->jump);
        if (run_end_hit(o, pon && ptest, cont, pcont, pu, pv, pd, df)) {
            *hit_k = k - 1;
            *hit_s = ps;
            return 1;
        }
        if (ph_occludes(rh, s, o->thickness, sd, cont ? prev : 0)) {
            *hit_k = k;
            *hit_s = s;
            return 1;
        }
        prev = sd;
        pon = sd != 0;
        ptest = 1;
        pcont = cont;
        pfoot = foot;
        pd = s - rh;
        pu = u;
        pv = v;
        ps = s;
        if (k == next_test) {
            int e = min(m->k_hi, ph_span_end(m, k, o->tile));
            if (e > k + 1 && ph_span_skippable(o->tiles, o->TW, o->TH, o->tile, m, k, e, o->thickness, ext)) {
                k = e;        /* evaluate e next, as the first of a new run */
                prev = 0;
                pon = 0;
                next_test = e + 1;
                continue;
            }
            next_test = e + 1;
        }
        ++k;
    }
    /* the last sample ends its run */
    if (run_end_hit(o, pon && ptest, 0, pcont, pu, pv, pd, df)) {
        *hit_k = k - 1;
        *hit_s = ps;
        return 1;
    }
    return 0;
}

/* 0 when no segment from the receiver to a light point within bounds lb
 * (march.h: ph_segments_may_hit) can reach the cutout's box. */
inline int may_hit(const occluder *o, float ru, float rv, float rh, float8 lb)
{
    return ph_segments_may_hit(ru, rv, rh, lb, o->rect, o->h_lo, o->h_hi, o->f_lo, o->f_hi);
}

/* 1 unless the ray r + t (r - L), t > 0, of every light point L with s = -1 within
 * bounds lb (as may_hit's) provably misses the cutout's box: conservative, one
 * coordinate c (u, v, h and the foot v + h) at a time -- along such a ray c runs
 * from r_c away from L_c, so it can reach [lo, hi] only upward (some L_c < r_c,
 * r_c <= hi), downward (some L_c > r_c, r_c >= lo) or staying (r_c inside). */
inline int may_hit_away(const occluder *o, float ru, float rv, float rh, float8 lb)
{
    float rf = rv + rh;
#define PH_AWAY(r, lmin, lmax, lo, hi) \
    (((lmin) < (r) && (r) <= (hi)) || ((lmax) > (r) && (r) >= (lo)) || ((r) >= (lo) && (r) <= (hi)))
    return PH_AWAY(ru, lb.s0, lb.s1, o->rect.x, o->rect.z)
        && PH_AWAY(rv, lb.s2, lb.s3, o->rect.y, o->rect.w)
        && PH_AWAY(rh, lb.s4, lb.s5, o->h_lo, o->h_hi)
        && PH_AWAY(rf, lb.s6, lb.s7, o->f_lo, o->f_hi);
#undef PH_AWAY
}

/* Bounds (u, u, v, v, h, h, foot, foot) of one light point, for may_hit. */
inline float8 point_bounds(float4 L)
{
    float f = L.y + L.z;
    return (float8)(L.x, L.x, L.y, L.y, L.z, L.z, f, f);
}

/* 1 when receiver (ru, rv, rh) is blocked from light L; then *m is its march,
 * *hit_k the first blocking sample and *hit_s the cutout height there. */
inline int trace_light(const occluder *o, float ru, float rv, float rh, float4 L,
                       ph_march *m, int *hit_k, float *hit_s)
{
    /* cheap exact rejection of segments that miss the cutout's box (s = +1) */
    if (L.w > 0.5f && !may_hit(o, ru, rv, rh, point_bounds(L))) return 0;
    if (!light_march(ru, rv, rh, L, m)) return 0;
    return shadow_trace(o, m, hit_k, hit_s);
}

/* 1 when receiver (ru, rv, rh) is blocked from light L. */
inline int blocked(const occluder *o, float ru, float rv, float rh, float4 L)
{
    ph_march m;
    int k; float s;
    return trace_light(o, ru, rv, rh, L, &m, &k, &s);
}

#define OCCLUDER_ARGS \
    __global const float *surf, __global const float2 *tiles, const int W, const int H, \
    const int TW, const int TH, const int tile, const float4 rect, const float h_lo, \
    const float h_hi, const float f_lo, const float f_hi, const float thickness
#define OCCLUDER_INIT(o) \
    occluder o; o.surf = surf; o.tiles = tiles; o.W = W; o.H = H; o.TW = TW; o.TH = TH; \
    o.tile = tile; o.rect = rect; o.h_lo = h_lo; o.h_hi = h_hi; o.f_lo = f_lo; o.f_hi = f_hi; \
    o.thickness = thickness; o.jump = thickness + PH_FLIP_JUMP

/* lit (H, W): 1 lit, 0 shadow. NDRange (W, H). */
__kernel void hard_shadow(OCCLUDER_ARGS, __global const float *recv, const float4 light,
                          __global float *lit)
{
    int j = get_global_id(0), i = get_global_id(1);
    if (j >= W || i >= H) return;
    OCCLUDER_INIT(o);
    float rh = recv[i * W + j];
    float out = 1.0f;
    if (rh > PH_NO_SURFACE_TEST && blocked(&o, (float)j + 0.5f, (float)i + 0.5f, rh, light))
        out = 0.0f;
    lit[i * W + j] = out;
}

/* ---- soft shadow, 8 samples at a time -------------------------------------
 * The lit fraction (H, W) in [0, 1]: the mean of the hard shadows of n light
 * samples, all in one launch. The set-up and clipping of 8 sample rays run as
 * float8 arithmetic (the same operations as ph_march_setup, ph_march_clip_foot
 * and ph_march_clip_box, lane by lane), then each ray that survives marches
 * alone (march_loop). About 20% less CPU than one sample at a time on PoCL.
 * Exact IEEE division matters here: -cl-fast-relaxed-math turns the vector
 * 1/x into an approximation (1/1 = 0.99999994), which moves ties. Samples come as structure of arrays
 * soa[0..3][n8] = u, v, h, s, padded to n8 = 8 * ceil(n / 8) with (0, 0, 0, 0)
 * (a march every set-up refuses). */

/* Vector Liang-Barsky slab, the semantics of ph_clip_slab per lane; ok: -1 true. */
inline void vclip_slab(float8 o, float8 d, float lo, float hi, float8 *t0, float8 *t1, int8 *ok)
{
    int8 zero = d == (float8)(0.0f);
    float8 inv = (float8)(1.0f) / select(d, (float8)(1.0f), zero);
    float8 ta = ((float8)(lo) - o) * inv, tb = ((float8)(hi) - o) * inv;
    float8 a = fmin(ta, tb), b = fmax(ta, tb);
    int8 inside = (o >= (float8)(lo)) & (o <= (float8)(hi));
    *t0 = select(fmax(*t0, a), *t0, zero);
    *t1 = select(fmin(*t1, b), *t1, zero);
    *ok &= select((int8)(-1), inside, zero) & (*t0 <= *t1);
}

/* Integer sample range with one margin sample each side (as ph_march_clip_*). */
inline void vrange(float8 t0, float8 t1, int8 ok, int8 *k_lo, int8 *k_hi)
{
    int8 a = convert_int8(ceil(select((float8)(0.0f), t0, ok))) - 1;
    int8 b = convert_int8(floor(select((float8)(0.0f), t1, ok))) + 1;
    *k_lo = select(*k_lo, max(*k_lo, a), ok);
    *k_hi = select(*k_lo - 1, min(*k_hi, b), ok);
}

/* Number of the 8 sample rays (lanes) from receiver r that the cutout blocks. */
inline int blocked_x8(const occluder *o, float ru, float rv, float rh,
                      float8 lu, float8 lv, float8 lh, float8 ls)
{
    int8 front = ls > (float8)(0.5f), back = ls < (float8)(-0.5f);
    float8 Ru = (float8)(ru), Rv = (float8)(rv), Rh = (float8)(rh);
    /* light_march */
    float8 du = select(select(lu, Ru - lu, back), lu - Ru, front);
    float8 dv = select(select(lv, Rv - lv, back), lv - Rv, front);
    float8 dh = select(select(lh, Rh - lh, back), lh - Rh, front);
    float8 t_max = select((float8)(1.0e30f), (float8)(1.0f), front);
    /* per-sample segment rejection (s = +1), as ph_segments_may_hit */
    float8 lf = lv + lh;
    float rf = rv + rh;
    int8 may = (fmin(Ru, lu) <= (float8)(o->rect.z)) & (fmax(Ru, lu) >= (float8)(o->rect.x))
             & (fmin(Rv, lv) <= (float8)(o->rect.w)) & (fmax(Rv, lv) >= (float8)(o->rect.y))
             & (fmin(Rh, lh) <= (float8)(o->h_hi)) & (fmax(Rh, lh) >= (float8)(o->h_lo))
             & (fmin((float8)(rf), lf) <= (float8)(o->f_hi)) & (fmax((float8)(rf), lf) >= (float8)(o->f_lo));
    int8 ok = ~front | may;
    /* ph_march_setup */
    float8 adu = fabs(du), adv = fabs(dv);
    float8 major = fmax(adu, adv);
    ok &= major >= (float8)(PH_MIN_IMAGE_LENGTH);
    float8 inv = (float8)(1.0f) / select((float8)(1.0f), major, ok);
    float8 su = du * inv, sv = dv * inv, sh = dh * inv;
    float8 kmax = t_max * major;
    int8 big = kmax >= (float8)((float)PH_K_UNBOUNDED);
    int8 k_hi = select(convert_int8(floor(select(kmax, (float8)(0.0f), big))), (int8)(PH_K_UNBOUNDED), big);
    int8 k_lo = (int8)(1);
    int8 k_hi0 = k_hi;
    ok &= k_hi >= k_lo;
    /* ph_march_clip_foot */
    float8 t0 = convert_float8(k_lo - 1), t1 = convert_float8(k_hi + 1);
    vclip_slab((float8)(rf), sv + sh, o->f_lo, o->f_hi, &t0, &t1, &ok);
    vrange(t0, t1, ok, &k_lo, &k_hi);
    ok &= k_lo <= k_hi;
    /* ph_march_clip_box: rect and height band, one margin */
    t0 = convert_float8(k_lo - 1);
    t1 = convert_float8(k_hi + 1);
    vclip_slab(Ru, su, o->rect.x, o->rect.z, &t0, &t1, &ok);
    vclip_slab(Rv, sv, o->rect.y, o->rect.w, &t0, &t1, &ok);
    vclip_slab(Rh, sh, o->h_lo, o->h_hi, &t0, &t1, &ok);
    vrange(t0, t1, ok, &k_lo, &k_hi);
    ok &= k_lo <= k_hi;
    /* the second margin sample each side (as shadow_trace) */
    k_lo = max(k_lo - 1, (int8)(1));
    k_hi = min(k_hi + 1, k_hi0);
    int8 major_u = adu >= adv;
    int nb = 0;
    for (int q = 0; q < 8; ++q) {
        if (!((int *)&ok)[q]) continue;
        ph_march m;
        m.u = ru; m.v = rv; m.h = rh;
        m.su = ((float *)&su)[q]; m.sv = ((float *)&sv)[q]; m.sh = ((float *)&sh)[q];
        m.k_lo = ((int *)&k_lo)[q]; m.k_hi = ((int *)&k_hi)[q];
        m.major_u = ((int *)&major_u)[q] != 0;
        int k; float s;
        nb += march_loop(o, &m, &k, &s);
    }
    return nb;
}

/* Soft shadow, samples 8 at a time (see above). NDRange (W, H).
 * kinds: bit 1 some samples have s = +1 (front_bounds: their bounds), bit 2 some
 * have s = -1 (back_bounds), bit 4 some are directions (s = 0) or invalid: then no
 * receiver is rejected before its marches. A receiver none of whose sample rays can
 * reach the cutout's box (may_hit, may_hit_away) is lit at once. */
__kernel void soft_shadow(OCCLUDER_ARGS, __global const float *recv,
                             __global const float *soa, const int n, const int n8,
                             const int kinds, const float8 front_bounds, const float8 back_bounds,
                             __global float *lit)
{
    int j = get_global_id(0), i = get_global_id(1);
    if (j >= W || i >= H) return;
    OCCLUDER_INIT(o);
    float rh = recv[i * W + j];
    if (!(rh > PH_NO_SURFACE_TEST) || n <= 0) { lit[i * W + j] = 1.0f; return; }
    float ru = (float)j + 0.5f, rv = (float)i + 0.5f;
    if (!(kinds & 4) && !((kinds & 1) && may_hit(&o, ru, rv, rh, front_bounds))
        && !((kinds & 2) && may_hit_away(&o, ru, rv, rh, back_bounds))) {
        lit[i * W + j] = 1.0f;
        return;
    }
    int nb = 0;
    for (int g = 0; g < n8 / 8; ++g)
        nb += blocked_x8(&o, ru, rv, rh, vload8(g, soa), vload8(g, soa + n8), vload8(g, soa + 2 * n8),
                         vload8(g, soa + 3 * n8));
    lit[i * W + j] = 1.0f - (float)nb / (float)n;
}

/* SSN++ buffer channels (paper Sec. 3.2, Fig. 5), one launch. out is (9, H, W)
 * in the order of buffers.CHANNELS:
 *   0 cutout_height      cutout pixel height inside the mask, 0 outside (px)
 *   1 bg_gradient_x      d bg_height / du (px per px), central differences,
 *   2 bg_gradient_y      d bg_height / dv   one-sided at borders/invalid pixels
 *   3 hard_shadow        darkness from lights[0] (the disk centre): 1 shadow, 0 lit
 *   4..7 sparse_hard_shadow_0..3  darkness from lights[1..4] (disk extremes)
 *   8 relative_distance  |receiver - first blocking occluder point| in (u, v, h)
 *                        pixels for receivers shadowed by the centre, 0 if lit.
 * bg holds the background height with PH_NO_SURFACE where non-finite.
 * NDRange (W, H). */
__kernel void buffer_channels(OCCLUDER_ARGS, __global const float *recv,
                              __global const float *bg, __global const float4 *lights,
                              __global float *out)
{
    int j = get_global_id(0), i = get_global_id(1);
    if (j >= W || i >= H) return;
    OCCLUDER_INIT(o);
    int idx = i * W + j;
    int plane = W * H;

    float s = surf[idx];
    out[idx] = s > PH_NO_SURFACE_TEST ? s : 0.0f;

    /* background gradient; neighbours that are missing or non-finite drop out */
    float c = bg[idx];
    float gx = 0.0f, gy = 0.0f;
    if (c > PH_NO_SURFACE_TEST) {
        float l = j > 0 ? bg[idx - 1] : PH_NO_SURFACE;
        float r = j + 1 < W ? bg[idx + 1] : PH_NO_SURFACE;
        int okl = l > PH_NO_SURFACE_TEST, okr = r > PH_NO_SURFACE_TEST;
        gx = (okl && okr) ? 0.5f * (r - l) : okr ? (r - c) : okl ? (c - l) : 0.0f;
        float t = i > 0 ? bg[idx - W] : PH_NO_SURFACE;
        float b = i + 1 < H ? bg[idx + W] : PH_NO_SURFACE;
        int okt = t > PH_NO_SURFACE_TEST, okb = b > PH_NO_SURFACE_TEST;
        gy = (okt && okb) ? 0.5f * (b - t) : okb ? (b - c) : okt ? (c - t) : 0.0f;
    }
    out[plane + idx] = gx;
    out[2 * plane + idx] = gy;

    float rh = recv[idx];
    float ru = (float)j + 0.5f, rv = (float)i + 0.5f;
    float dist = 0.0f;
    float dark0 = 0.0f;
    if (rh > PH_NO_SURFACE_TEST) {
        ph_march m;
        int k; float hs;
        if (trace_light(&o, ru, rv, rh, lights[0], &m, &k, &hs)) {
            dark0 = 1.0f;
            float du = (float)k * m.su, dv = (float)k * m.sv, dh = hs - rh;
            dist = sqrt(du * du + dv * dv + dh * dh);
        }
    }
    out[3 * plane + idx] = dark0;
    for (int e = 0; e < 4; ++e) {
        float d = 0.0f;
        if (rh > PH_NO_SURFACE_TEST
            && blocked(&o, ru, rv, rh, lights[1 + e]))
            d = 1.0f;
        out[(4 + e) * plane + idx] = d;
    }
    out[8 * plane + idx] = dist;
}
