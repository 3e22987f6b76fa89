/* reflection.cl -- closest-hit tracing in pixel-height space, glossy reflection
 * (GGX) and refraction (Snell + Fresnel). Numpy reference: reflection.py (same
 * names without the "rt_" prefix). PixHt-Lab Sec. 3.3, design.md §2-3.
 *
 * Units: u, v, h in pixels (u right, v down, pixel centres at +0.5); 3D
 * directions are unit vectors in the world frame (y up, camera looking down -Z).
 *
 * A 3D ray from a point with image (u0, v0, h0) along direction d maps to the
 * (u, v, h) ray  p(s) = p0 + s e,  e = Nd + d.z p0,
 *     Nd = (W/2 (-d.z) + f d.x,  horizon (-d.z) - f d.y,  f d.y),
 * with s = t / (D0 - t d.z) for the 3D parameter t (D0 the origin's depth): the
 * projection is homogeneous with denominator D, so the image is straight and h is
 * linear in s. When the ray points away from the camera (d.z < 0) it ends at
 * the vanishing point Nd / (-d.z) at s = 1 / (-d.z); toward the camera (d.z >= 0)
 * its image runs away from the vanishing point without end. The depth D0 drops
 * out, so only the origin's (u, v, h) and d are needed.
 *
 * Nothing here relies on -cl-fast-relaxed-math (no NaN/inf tests).
 */
#include "march.h"

#define RT_PI 3.14159265358979f
/* thickness (pixels) of a solid surface: anything behind the background's
 * surface is inside it (ground, walls) */
#define RT_SOLID 1.0e30f
/* t_max standing for "no far end" (finite for fast-math safety) */
#define RT_UNBOUNDED 1.0e30f

/* ---- random numbers: a PCG integer hash, mirrored bit-exactly in numpy ---- */
inline uint rt_pcg(uint v)
{
    uint state = v * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

/* uniform in [0, 1): one number per (seed, pixel, sample, dimension) */
inline float rt_rand(uint seed, uint pix, uint sample, uint dim)
{
    uint x = rt_pcg(rt_pcg(rt_pcg(seed + dim) + sample) + pix);
    return (float)(x >> 8) * (1.0f / 16777216.0f);
}

/* 2D low-discrepancy sample n of a pixel: the R2 sequence (Roberts 2018,
 * additive recurrence by the plastic number) shifted by a per-pixel random
 * offset (Cranley-Patterson rotation), so each pixel's estimate stays unbiased
 * and independent of its neighbours while its samples fill the square evenly. */
inline float2 rt_sample2_offset(uint seed, uint pix)
{
    return (float2)(rt_rand(seed, pix, 0u, 0u), rt_rand(seed, pix, 0u, 1u));
}

inline float2 rt_sample2(float2 off, uint n)
{
    /* n * alpha mod 1 in 32-bit fixed point: exact, no float drift for large n */
    uint a1 = n * 3242174889u, a2 = n * 2447445413u;
    float2 r = (float2)((float)(a1 >> 8), (float)(a2 >> 8)) * (1.0f / 16777216.0f) + off;
    return r - floor(r);
}

/* ---- 3D ray -> (u, v, h) ray ---- */
/* e (pixel-height space direction per unit s) and s_max of the ray from the image
 * point p0 = (u0, v0, h0) along world direction d. */
inline float3 rt_uvh_direction(float3 p0, float3 d, float W, float horizon, float f,
                               float *s_max)
{
    float mdz = -d.z;
    float3 nd = (float3)(0.5f * W * mdz + f * d.x, horizon * mdz - f * d.y, f * d.y);
    *s_max = mdz > 0.0f ? fmin(1.0f / mdz, RT_UNBOUNDED) : RT_UNBOUNDED;
    return nd - mdz * p0;
}

/* ---- microfacet BRDF pieces (isotropic GGX, alpha = roughness^2) ---- */
/* exact unpolarised Fresnel reflectance of a dielectric interface; eta = n_t / n_i
 * (the IOR of the far side relative to the near side), cos_i >= 0. Returns 1
 * under total internal reflection. */
inline float rt_fresnel_dielectric(float cos_i, float eta)
{
    float c = clamp(cos_i, 0.0f, 1.0f);
    float g2 = eta * eta - 1.0f + c * c;
    if (g2 <= 0.0f) return 1.0f;
    float g = sqrt(g2);
    float a = (g - c) / (g + c);
    float b = (c * (g + c) - 1.0f) / (c * (g - c) + 1.0f);
    return clamp(0.5f * a * a * (1.0f + b * b), 0.0f, 1.0f);
}

/* Schlick's approximation with a coloured normal-incidence reflectance (metals) */
inline float3 rt_fresnel_schlick(float cos_i, float3 f0)
{
    float m = 1.0f - clamp(cos_i, 0.0f, 1.0f);
    float m5 = m * m * m * m * m;
    return f0 + (1.0f - f0) * m5;
}

/* Smith Lambda for GGX, cos_t = cosine to the macro normal */
inline float rt_smith_lambda(float cos_t, float a)
{
    float c2 = fmax(cos_t * cos_t, 1e-12f);
    float t2 = fmax(1.0f - c2, 0.0f) / c2;
    return 0.5f * (-1.0f + sqrt(1.0f + a * a * t2));
}

/* visible-normal sample (Heitz 2018) in the local frame (n = +z); wo.z > 0 */
inline float3 rt_sample_vndf(float3 wo, float a, float u1, float u2)
{
    float3 vh = normalize((float3)(a * wo.x, a * wo.y, wo.z));
    float lensq = vh.x * vh.x + vh.y * vh.y;
    float3 t1 = lensq > 0.0f ? (float3)(-vh.y, vh.x, 0.0f) * rsqrt(lensq) : (float3)(1.0f, 0.0f, 0.0f);
    float3 t2 = cross(vh, t1);
    float r = sqrt(u1);
    float phi = 2.0f * RT_PI * u2;
    float p1 = r * cos(phi);
    float p2 = r * sin(phi);
    float s = 0.5f * (1.0f + vh.z);
    p2 = (1.0f - s) * sqrt(fmax(1.0f - p1 * p1, 0.0f)) + s * p2;
    float3 nh = p1 * t1 + p2 * t2 + sqrt(fmax(0.0f, 1.0f - p1 * p1 - p2 * p2)) * vh;
    return normalize((float3)(a * nh.x, a * nh.y, fmax(1e-6f, nh.z)));
}

/* orthonormal basis (b1, b2, n) (Duff et al. 2017) */
inline void rt_basis(float3 n, float3 *b1, float3 *b2)
{
    float sgn = n.z >= 0.0f ? 1.0f : -1.0f;
    float a = -1.0f / (sgn + n.z);
    float b = n.x * n.y * a;
    *b1 = (float3)(1.0f + sgn * n.x * n.x * a, sgn * b, -sgn * n.x);
    *b2 = (float3)(b, sgn + n.y * n.y * a, -n.y);
}

/* ---- closest hit against a pixel-height surface, with a max-height pyramid ---- */
/* surf: (H, W) heights (pixels) with PH_NO_SURFACE where there is no surface.
 * pyr: levels 1..nlev-1 of the (min, max) of surf dilated by one pixel (the
 * minor-axis interpolation of ph_surface_height reads the neighbour pixel) over
 * 2^l x 2^l tiles, two floats per tile ((+1e30, -1e30) when empty);
 * lvl[3 l + 0..2] = width, height, offset (in tiles) of level l in pyr.
 * Returns the hit pixel index (i W + j) or -1; *last = the last in-image sample
 * pixel visited (or left unchanged); *steps counts loop iterations.
 *
 * Hierarchical skipping (screen-space Hi-Z): at level l the samples of the march
 * that fall in the current 2^l tile are found in closed form (the march is
 * linear); if the ray height at both ends of that run (h is linear, so its
 * extremes are at the ends) is above the tile's maximum, every sample in the run
 * is in front of the surface (side -1 or 0); if it is below the tile's minimum by
 * more than the thickness, every sample is behind it out of reach (side 1 or 0).
 * Either way none can hit, and the side after the run is that of its last
 * sample. Then we jump past the run and climb a level; otherwise we descend.
 * The side after a skip is exact, so the result is the same as plain marching
 * (a front skip is never tried while the previous side is "behind", nor a
 * behind skip while it is "in front": the next sample could be a crossing). */
inline int rt_trace_k(const ph_march *m, __global const float *surf,
                      __global const float *pyr, __global const int *lvl, int nlev,
                      int W, int H, float thickness, int *last, int *steps, int *kout)
{
    int prev = 0;
    int k = m->k_lo;
    int level = nlev > 1 ? 1 : 0;
    while (k <= m->k_hi) {
        *steps += 1;
        float u = ph_sample_u(m, k), v = ph_sample_v(m, k);
        int j = (int)floor(u), i = (int)floor(v);
        int inside = j >= 0 && j < W && i >= 0 && i < H;
        if (level >= 1 && inside) {
            int T = 1 << level;
            int tj = j >> level, ti = i >> level;
            int t = lvl[3 * level + 2] + ti * lvl[3 * level] + tj;
            float tmin = pyr[2 * t], tmax = pyr[2 * t + 1];
            /* last sample of the run inside this tile, from each axis */
            /* the tile clipped to the image: samples outside it are never skipped */
            float u_lo = (float)(tj * T), u_hi = (float)min(tj * T + T, W);
            float v_lo = (float)(ti * T), v_hi = (float)min(ti * T + T, H);
            float kb = (float)m->k_hi;
            if (m->su > 0.0f) kb = fmin(kb, ceil((u_hi - m->u) / m->su) - 1.0f);
            else if (m->su < 0.0f) kb = fmin(kb, floor((u_lo - m->u) / m->su));
            if (m->sv > 0.0f) kb = fmin(kb, ceil((v_hi - m->v) / m->sv) - 1.0f);
            else if (m->sv < 0.0f) kb = fmin(kb, floor((v_lo - m->v) / m->sv));
            int kend = (int)kb;
            /* guard rounding: the run's last sample must really lie in the tile */
            while (kend > k) {
                int jj = (int)floor(ph_sample_u(m, kend)), ii = (int)floor(ph_sample_v(m, kend));
                if ((jj >> level) == tj && (ii >> level) == ti && jj >= 0 && ii >= 0
                    && jj < W && ii < H) break;
                kend -= 1;
            }
            float ha = ph_ray_height(m, k), hb = ph_ray_height(m, kend);
            /* in front of every surface sample of the run (needs prev != behind:
             * sample k could be a crossing), or behind all of them beyond the
             * thickness (needs prev != in front) */
            int front = prev != 1 && fmin(ha, hb) > tmax;
            int behind = prev != -1 && fmax(ha, hb) < tmin - fmax(thickness, PH_BEHIND_EPS);
            if (kend > k && (front || behind)) {
                int jj = (int)floor(ph_sample_u(m, kend)), ii = (int)floor(ph_sample_v(m, kend));
                *last = ii * W + jj;
                *kout = kend;
                prev = surf[ii * W + jj] > PH_NO_SURFACE_TEST ? (front ? -1 : 1) : 0;
                k = kend + 1;
                if (level + 1 < nlev) level += 1;
                continue;
            }
            level -= 1;
            if (level >= 1) continue;
        }
        float sh = ph_surface_height(surf, W, H, u, v, m->major_u);
        float rh = ph_ray_height(m, k);
        int side = ph_side(rh, sh);
        if (inside) { *last = i * W + j; *kout = k; }
        if (ph_occludes(rh, sh, thickness, side, prev)) { *kout = k; return i * W + j; }
        prev = side;
        k += 1;
        level = nlev > 1 ? 1 : 0;
    }
    return -1;
}

/* rt_trace_k without the sample index */
inline int rt_trace(const ph_march *m, __global const float *surf,
                    __global const float *pyr, __global const int *lvl, int nlev,
                    int W, int H, float thickness, int *last, int *steps)
{
    int k;
    return rt_trace_k(m, surf, pyr, lvl, nlev, W, H, thickness, last, steps, &k);
}

/* March set-up of the ray p0 + s e, clipped to the image and to the surface's
 * bounding box [box] x [h_lo, h_hi] (pixels). Returns 0 when nothing is left. */
inline int rt_setup(float3 p0, float3 e, float s_max, int W, int H, float4 box,
                    float h_lo, float h_hi, ph_march *m)
{
    if (!ph_march_setup(p0.x, p0.y, p0.z, e.x, e.y, e.z, s_max, m)) return 0;
    if (!ph_march_clip_box(m, (float4)(0.0f, 0.0f, (float)W, (float)H), -RT_SOLID, RT_SOLID)) return 0;
    return ph_march_clip_box(m, box, h_lo, h_hi);
}

/* ---- test/benchmark entry: closest hit of arbitrary (u, v, h) rays ---- */
__kernel void rt_trace_rays(int W, int H, int n_rays,
                            __global const float *rays,   /* per ray: u v h  eu ev eh  s_max */
                            __global const float *surf,
                            __global const float *pyr, __global const int *lvl, int nlev,
                            float thickness, float4 box, float h_lo, float h_hi,
                            __global int *hit, __global int *last, __global int *steps)
{
    int r = get_global_id(0);
    if (r >= n_rays) return;
    __global const float *q = rays + 7 * r;
    float3 p0 = (float3)(q[0], q[1], q[2]);
    float3 e = (float3)(q[3], q[4], q[5]);
    ph_march m;
    int lst = -1, st = 0, hh = -1;
    if (rt_setup(p0, e, q[6], W, H, box, h_lo, h_hi, &m))
        hh = rt_trace(&m, surf, pyr, lvl, nlev, W, H, thickness, &lst, &st);
    hit[r] = hh;
    last[r] = lst;
    steps[r] = st;
}

/* ---- receiver geometry (mirror of camera.reconstruct) ---- */
/* 3D point (world units) of pixel (x, y) with pixel height h: Eq. 3-4 with the
 * no-pitch camera, w = H_cam / (v + h - horizon). */
inline float3 rt_back_project(int x, int y, float h, float W, float f, float horizon, float cam_height)
{
    float u = (float)x + 0.5f, v = (float)y + 0.5f;
    float w = cam_height / (v + h - horizon);
    return (float3)(w * (u - 0.5f * W), cam_height + w * (horizon - v), -f * w);
}

/* Unit normal normalize(dP/dv x dP/du) at pixel (x, y), differences over valid
 * neighbours only: central where both exist, one-sided otherwise, 0 when none
 * (as camera.surface_normals, in float32). */
inline float3 rt_normal(__global const float *hh, __global const float *valid, int x, int y,
                        int W, int H, float f, float horizon, float cam_height)
{
    int idx = y * W + x;
    float3 P = rt_back_project(x, y, hh[idx], (float)W, f, horizon, cam_height);
    float3 d[2];
    for (int axis = 0; axis < 2; ++axis) {
        int dx = axis == 0, dy = axis == 1;
        int xf = x + dx, yf = y + dy, xb = x - dx, yb = y - dy;
        int okf = xf < W && yf < H && valid[yf * W + xf] > 0.5f;
        int okb = xb >= 0 && yb >= 0 && valid[yb * W + xb] > 0.5f;
        float3 pf = okf ? rt_back_project(xf, yf, hh[yf * W + xf], (float)W, f, horizon, cam_height) : P;
        float3 pb = okb ? rt_back_project(xb, yb, hh[yb * W + xb], (float)W, f, horizon, cam_height) : P;
        d[axis] = (okf && okb) ? 0.5f * (pf - pb) : (pf - pb);
    }
    float3 n = cross(d[1], d[0]);
    float len = length(n);
    return len > 0.0f ? n / len : (float3)(0.0f);
}

/* ---- glossy reflection of the cutout on the background ---- */
/* One work item per receiver pixel (rows y0 .. y0 + rows - 1). Receiver: the
 * background surface at the pixel centre, normal n (world, rt_normal: the same
 * differences as reconstruct, computed here instead of on the host).
 * Estimator per sample (VNDF importance sampling): m ~ D_v(wo), wi = reflect(wo, m),
 *     weight = F(wo . m) G2(wo, wi) / G1(wo)
 * and 0 when wi is below the surface (rejected, never traced). Roughness 0: the
 * mirror direction, weight F(wo . n), one sample. The sample value is
 * strength * (weight * rgb, mean(weight) * alpha) of the cutout pixel the
 * reflected ray hits (premultiplied linear RGBA), 0 on a miss.
 * Adaptive: stop once n >= min_spp and the standard error of the mean of every
 * channel is <= target_se (or n = max_spp). The samples are a low-discrepancy
 * sequence, whose error falls faster than sigma / sqrt(n): that formula
 * overestimates it severalfold and spends samples where none are needed. So the
 * error is estimated as in randomized QMC from replicates: the four interleaved
 * sub-sequences n = 0, 1, 2, 3 (mod 4) are each a shifted R2 sequence, and the
 * standard error of the full mean is taken as the spread of their four means
 * over sqrt(4) (checked when n is a multiple of 4). */
__kernel void rt_reflect(int W, int H, int y0, float f, float horizon, float cam_height,
                         __global const float *bg_h,
                         __global const float *valid, __global const uchar *skip,
                         __global const float *surf, __global const float *pyr,
                         __global const int *lvl, int nlev, float4 box, float h_lo, float h_hi,
                         __global const float4 *cutout, float thickness,
                         float alpha, int conductor, float eta, float3 f0, float strength,
                         int min_spp, int max_spp, float target_se, uint seed,
                         __global float4 *out, __global int *spp_out, __global int *steps_out)
{
    int x = get_global_id(0), y = y0 + (int)get_global_id(1);
    if (x >= W || y >= H) return;
    int idx = y * W + x;
    float4 mean = (float4)(0.0f);
    int n = 0, steps = 0;
    int receive = valid[idx] > 0.5f && skip[idx] == 0;
    float3 nn = receive ? rt_normal(bg_h, valid, x, y, W, H, f, horizon, cam_height) : (float3)(0.0f);
    float3 wo = -normalize((float3)((float)x + 0.5f - 0.5f * (float)W, horizon - ((float)y + 0.5f), -f));
    float cos_o = dot(nn, wo);
    if (receive && cos_o > 1e-4f) {
        float3 b1, b2;
        rt_basis(nn, &b1, &b2);
        float3 wol = (float3)(dot(wo, b1), dot(wo, b2), cos_o);
        float3 p0 = (float3)((float)x + 0.5f, (float)y + 0.5f, bg_h[idx]);
        float4 s1 = (float4)(0.0f);
        float4 q0 = (float4)(0.0f), q1 = (float4)(0.0f), q2 = (float4)(0.0f), q3 = (float4)(0.0f);
        float lambda_o = rt_smith_lambda(cos_o, alpha);
        float2 off = rt_sample2_offset(seed, (uint)idx);
        int nmax = alpha > 0.0f ? max_spp : 1;
        while (n < nmax) {
            float3 ml = (float3)(0.0f, 0.0f, 1.0f);
            if (alpha > 0.0f) {
                float2 xi = rt_sample2(off, (uint)n);
                ml = rt_sample_vndf(wol, alpha, xi.x, xi.y);
            }
            float cm = dot(wol, ml);
            float3 wil = 2.0f * cm * ml - wol;
            float4 c = (float4)(0.0f);
            if (wil.z > 0.0f && cm > 0.0f) {
                float3 w3 = conductor ? rt_fresnel_schlick(cm, f0)
                                      : (float3)(rt_fresnel_dielectric(cm, eta));
                if (alpha > 0.0f)
                    w3 *= (1.0f + lambda_o) / (1.0f + lambda_o + rt_smith_lambda(wil.z, alpha));
                float3 wi = wil.x * b1 + wil.y * b2 + wil.z * nn;
                float s_max;
                float3 e = rt_uvh_direction(p0, wi, (float)W, horizon, f, &s_max);
                ph_march m;
                int lst = -1;
                /* the cutout's box lies inside the image: clipping to it alone is enough */
                if (ph_march_setup(p0.x, p0.y, p0.z, e.x, e.y, e.z, s_max, &m)
                    && ph_march_clip_box(&m, box, h_lo, h_hi)) {
                    int hit = rt_trace(&m, surf, pyr, lvl, nlev, W, H, thickness, &lst, &steps);
                    if (hit >= 0) {
                        float4 col = cutout[hit];
                        float wa = (w3.x + w3.y + w3.z) * (1.0f / 3.0f);
                        c = strength * (float4)(w3 * col.xyz, wa * col.w);
                    }
                }
            }
            switch (n & 3) {
                case 0: q0 += c; break;
                case 1: q1 += c; break;
                case 2: q2 += c; break;
                default: q3 += c; break;
            }
            n += 1;
            s1 += c;
            if (n >= min_spp && (n & 3) == 0) {
                float inv_q = 4.0f / (float)n;              /* 1 / samples per sub-sequence */
                float4 mu = s1 / (float)n;
                float4 d0 = q0 * inv_q - mu, d1 = q1 * inv_q - mu, d2 = q2 * inv_q - mu, d3 = q3 * inv_q - mu;
                /* variance of the sub-means (3 dof) / 4 = squared standard error */
                float4 se2 = (d0 * d0 + d1 * d1 + d2 * d2 + d3 * d3) * (1.0f / 12.0f);
                float v = fmax(fmax(se2.x, se2.y), fmax(se2.z, se2.w));
                if (v <= target_se * target_se) break;
            }
        }
        mean = s1 / (float)max(n, 1);
    }
    out[idx] = mean;
    spp_out[idx] = n;
    steps_out[idx] = steps;
}

/* ---- refraction through the front surface of a transparent cutout ---- */

/* Whether the ray p0 + s e is already behind the background (height bg0 at its
 * origin's pixel) where it leaves that pixel: the ray's height at the pixel's
 * edge along its major axis (a ray nearly along the view ray: going down, behind;
 * else its own height). Shared by rt_background_along and rt_background_pos. */
inline int rt_behind_at_origin(float3 p0, float3 e, float bg0)
{
    float major = fmax(fabs(e.x), fabs(e.y));
    float h_edge;
    if (major >= PH_MIN_IMAGE_LENGTH) h_edge = p0.z + 0.5f * e.z / major;
    else h_edge = e.z < 0.0f ? -RT_SOLID : p0.z;
    return ph_side(h_edge, bg0) == 1;
}

/* Where the ray p0 + s e meets the background, as a continuous image position
 * (u, v) [px]: at a hit, the crossing interpolated between the last sample in front
 * of the surface and the first behind it (linear in the height difference); a
 * ray already behind at its origin's pixel edge: p0 itself; a ray that leaves
 * the image: its last in-image sample. *pix: the pixel rt_background_along
 * takes the colour of. A smooth function of the ray, so it can be traced at a
 * proxy resolution and enlarged. */
inline float2 rt_background_pos(float3 p0, float3 e, float s_max, int W, int H,
                                __global const float *bgs, __global const float *pyr,
                                __global const int *lvl, int nlev, int *steps, int *hitflag, int *pix)
{
    int origin = (int)floor(p0.y) * W + (int)floor(p0.x);
    int behind = rt_behind_at_origin(p0, e, bgs[origin]);
    *hitflag = 1;
    *pix = origin;
    if (behind) return p0.xy;
    ph_march m;
    int lst = origin, k = -1;
    if (ph_march_setup(p0.x, p0.y, p0.z, e.x, e.y, e.z, s_max, &m)
        && ph_march_clip_box(&m, (float4)(0.0f, 0.0f, (float)W, (float)H), -RT_SOLID, RT_SOLID)) {
        int hit = rt_trace_k(&m, bgs, pyr, lvl, nlev, W, H, RT_SOLID, &lst, steps, &k);
        if (hit >= 0) {
            *pix = hit;
            float2 q = (float2)(ph_sample_u(&m, k), ph_sample_v(&m, k));
            if (k > m.k_lo) {
                float2 qp = (float2)(ph_sample_u(&m, k - 1), ph_sample_v(&m, k - 1));
                float d1 = ph_ray_height(&m, k) - ph_surface_height(bgs, W, H, q.x, q.y, m.major_u);
                float d0 = ph_ray_height(&m, k - 1) - ph_surface_height(bgs, W, H, qp.x, qp.y, m.major_u);
                if (d0 > 0.0f && d1 < d0) q = qp + (d0 / (d0 - d1)) * (q - qp);
            }
            return q;
        }
    }
    *hitflag = 0;
    *pix = lst;
    if (k < 0) return p0.xy;
    return (float2)(clamp(ph_sample_u(&m, k), 0.0f, (float)W - 1e-3f),
                    clamp(ph_sample_v(&m, k), 0.0f, (float)H - 1e-3f));
}

/* Background colour seen along the (u, v, h) ray p0 + s e: the first background
 * pixel where the ray goes behind the background surface (solid: ground, walls).
 * The origin's own pixel counts when the ray is already behind the surface at
 * the pixel's edge (a ray nearly along the view ray hits at its own pixel: with
 * eta = 1 nothing moves). A ray that leaves the image without a hit takes the
 * colour of the last background pixel it crossed (screen-space fallback). */
inline float4 rt_background_along(float3 p0, float3 e, float s_max, int W, int H,
                                   __global const float *bgs, __global const float *pyr,
                                   __global const int *lvl, int nlev,
                                   __global const float4 *bg_rgb, int *steps, int *hitflag)
{
    int pix;
    rt_background_pos(p0, e, s_max, W, H, bgs, pyr, lvl, nlev, steps, hitflag, &pix);
    return bg_rgb[pix];
}

/* The rays of one glass pixel (shared by rt_refract and rt_refract_hits): the
 * transmitted ray from *q0 along *wt with weight *T (0: none), the front-surface
 * reflection from *p0 along *wr with weight *F (0: none). Returns 0 when the
 * pixel is not glass; sets *tir under total internal reflection at the front. */
inline int rt_refract_rays(int x, int y, int W, int H, float f, float horizon, float cam_height,
                           __global const float *coverage, __global const float *gh,
                           __global const float *gn, __global const float *gvalid,
                           __global const float *gpos, __global const float *gradius,
                           float eta, int fresnel, float3 *q0, float3 *wt, float *T,
                           float3 *p0, float3 *wr, float *F, int *tir)
{
    int idx = y * W + x;
    *T = 0.0f;
    *F = 0.0f;
    *tir = 0;
    if (!(coverage[idx] > 0.0f && gvalid[idx] > 0.5f)) return 0;
    float3 nn = (float3)(gn[3 * idx], gn[3 * idx + 1], gn[3 * idx + 2]);
    float3 view = normalize((float3)((float)x + 0.5f - 0.5f * (float)W, horizon - ((float)y + 0.5f), -f));
    float3 wo = -view;
    float cos_i = dot(nn, wo);
    if (cos_i < 0.0f) { nn = -nn; cos_i = -cos_i; }   /* silhouette: face the viewer */
    *p0 = (float3)((float)x + 0.5f, (float)y + 0.5f, gh[idx]);
    float r = 1.0f / eta;                               /* n_outside / n_inside */
    float k = 1.0f - r * r * (1.0f - cos_i * cos_i);
    *F = k < 0.0f ? 1.0f : (fresnel ? rt_fresnel_dielectric(cos_i, eta) : 0.0f);
    *wr = 2.0f * cos_i * nn - wo;
    if (k >= 0.0f && *F < 1.0f) {
        float3 w = normalize(r * view + (r * cos_i - sqrt(k)) * nn);
        float3 q = *p0;
        float t = 1.0f - *F;
        float R = gradius[idx];
        if (R > 0.0f) {
            /* back surface of the local sphere (radius R, centre P - R n): the
             * ray leaves it after the chord 2 R cos_t and refracts out again */
            float3 P = (float3)(gpos[3 * idx], gpos[3 * idx + 1], gpos[3 * idx + 2]);
            float3 C = P - R * nn;
            float cos_t = -dot(w, nn);
            float3 Q = P + (2.0f * R * cos_t) * w;
            float3 n2 = (Q - C) / R;                        /* outward */
            float c2 = clamp(dot(w, n2), 0.0f, 1.0f);
            float k2 = 1.0f - eta * eta * (1.0f - c2 * c2);
            if (k2 >= 0.0f) {
                w = normalize(eta * w + (eta * c2 - sqrt(k2)) * (-n2));
                if (fresnel) t *= 1.0f - rt_fresnel_dielectric(c2, 1.0f / eta);
            }
            float D = -Q.z;
            if (D > 1e-6f)
                q = (float3)(0.5f * (float)W + f * Q.x / D, horizon + f * (cam_height - Q.y) / D, f * Q.y / D);
            q.x = clamp(q.x, 0.0f, (float)W - 1e-3f);
            q.y = clamp(q.y, 0.0f, (float)H - 1e-3f);
        }
        *q0 = q;
        *wt = w;
        *T = t;
    } else {
        *tir = 1;                                       /* total internal reflection */
    }
    return 1;
}

/* One work item per pixel. glass: coverage (cutout alpha) > 0 marks the
 * transparent object; gn its front-surface normal (world), gh its pixel height,
 * gpos its 3D position (world units). gradius > 0: the object is solid and its
 * back surface is taken from the local sphere of that radius (world units) at
 * the front point (exact for a ball); 0: only the front interface.
 * eta: IOR of the object relative to the surrounding medium. Refracted direction by
 * Snell's law; under total internal reflection (only possible for eta < 1) the
 * reflected direction takes all the energy. With fresnel != 0 the result is
 * (1 - F) T + F R (F exact dielectric Fresnel at the front surface); else T (R
 * under TIR). out = coverage * (tint * that colour, 1), premultiplied. */
__kernel void rt_refract(int W, int H, float f, float horizon, float cam_height,
                         __global const float *coverage, __global const float *gh,
                         __global const float *gn, __global const float *gvalid,
                         __global const float *gpos, __global const float *gradius,
                         __global const float *bgs, __global const float *pyr,
                         __global const int *lvl, int nlev,
                         __global const float4 *bg_rgb, float eta, float3 tint, int fresnel,
                         __global float4 *out, __global int *flags, __global int *steps_out)
{
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= W || y >= H) return;
    int idx = y * W + x;
    int steps = 0, flag = 0, tir, hf;
    float4 res = (float4)(0.0f);
    float3 q0, wt, p0, wr;
    float T, F, s_max;
    if (rt_refract_rays(x, y, W, H, f, horizon, cam_height, coverage, gh, gn, gvalid, gpos, gradius,
                        eta, fresnel, &q0, &wt, &T, &p0, &wr, &F, &tir)) {
        float3 col = (float3)(0.0f);
        if (T > 0.0f) {
            float3 e = rt_uvh_direction(q0, wt, (float)W, horizon, f, &s_max);
            col += T * tint * rt_background_along(q0, e, s_max, W, H, bgs, pyr, lvl, nlev, bg_rgb, &steps, &hf).xyz;
            flag |= hf;
        }
        if (tir) flag |= 4;
        if (F > 0.0f) {
            float3 e = rt_uvh_direction(p0, wr, (float)W, horizon, f, &s_max);
            col += F * rt_background_along(p0, e, s_max, W, H, bgs, pyr, lvl, nlev, bg_rgb, &steps, &hf).xyz;
            flag |= hf << 1;
        }
        res = coverage[idx] * (float4)(col, 1.0f);
    }
    out[idx] = res;
    flags[idx] = flag;
    steps_out[idx] = steps;
}

/* rt_refract's rays, returning where they meet the background instead of its
 * colour (the proxy resolution of large images: refraction_proxy in
 * refraction.py enlarges these positions and looks the colours up at full
 * size). pos = (u, v) of the transmitted ray's hit, (u, v) of the reflected
 * ray's (rt_background_pos; the pixel's own centre where there is no such ray);
 * wts = (T, F, 0, 0) their weights; flags as rt_refract's. */
__kernel void rt_refract_hits(int W, int H, float f, float horizon, float cam_height,
                              __global const float *coverage, __global const float *gh,
                              __global const float *gn, __global const float *gvalid,
                              __global const float *gpos, __global const float *gradius,
                              __global const float *bgs, __global const float *pyr,
                              __global const int *lvl, int nlev, float eta, int fresnel,
                              __global float4 *pos, __global float4 *wts,
                              __global int *flags, __global int *steps_out)
{
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= W || y >= H) return;
    int idx = y * W + x;
    int steps = 0, flag = 0, tir, hf, pix;
    float3 q0, wt, p0, wr;
    float T, F, s_max;
    float2 c = (float2)((float)x + 0.5f, (float)y + 0.5f);
    float4 ps = (float4)(c, c);
    float4 ws = (float4)(0.0f);
    if (rt_refract_rays(x, y, W, H, f, horizon, cam_height, coverage, gh, gn, gvalid, gpos, gradius,
                        eta, fresnel, &q0, &wt, &T, &p0, &wr, &F, &tir)) {
        if (T > 0.0f) {
            float3 e = rt_uvh_direction(q0, wt, (float)W, horizon, f, &s_max);
            ps.xy = rt_background_pos(q0, e, s_max, W, H, bgs, pyr, lvl, nlev, &steps, &hf, &pix);
            flag |= hf;
        }
        if (tir) flag |= 4;
        if (F > 0.0f) {
            float3 e = rt_uvh_direction(p0, wr, (float)W, horizon, f, &s_max);
            ps.zw = rt_background_pos(p0, e, s_max, W, H, bgs, pyr, lvl, nlev, &steps, &hf, &pix);
            flag |= hf << 1;
        }
        ws = (float4)(T, F, 0.0f, 0.0f);
    }
    pos[idx] = ps;
    wts[idx] = ws;
    flags[idx] = flag;
    steps_out[idx] = steps;
}
