/* The stretched penumbra's box sums (preview_shadow.py, penumbra_blur's geometry), a
 * candidate PreviewShadow does not run (docs/server.md, "A stretched penumbra"): a
 * program of its own, so the node's build neither carries nor compiles it.
 * _swept_boxes is the numpy reference, float for float: the same operations in the
 * same order, no contraction into fused multiply-adds. Each work item takes 8 of
 * the pixels step 1 found mixed on the background side, in the lanes of vector
 * types (PoCL runs a scalar version of this item by item: several times slower).
 * Needs doubles: the summed-area tables are float64, as the reference's. */
#ifdef cl_khr_fp64
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#pragma OPENCL FP_CONTRACT OFF

#define PS_MAX_BOXES 6

inline float8 ps_gather_f(__global const float *p, int8 k)
{
    return (float8)(p[k.s0], p[k.s1], p[k.s2], p[k.s3], p[k.s4], p[k.s5], p[k.s6], p[k.s7]);
}

inline double8 ps_gather_d(__global const double *p, int8 k)
{
    return (double8)(p[k.s0], p[k.s1], p[k.s2], p[k.s3], p[k.s4], p[k.s5], p[k.s6], p[k.s7]);
}

/* the box sum of a table from its corners (i0, i1 row offsets, j0, j1 columns) */
inline double8 ps_box(__global const double *z, int8 i0, int8 i1, int8 j0, int8 j1)
{
    return ((ps_gather_d(z, i1 + j1) - ps_gather_d(z, i0 + j1)) - ps_gather_d(z, i1 + j0)) + ps_gather_d(z, i0 + j0);
}

/* z: the crop's tables (at least 2 planes of zw columns, zplane values apart; plane 0
 * the same-side weight, plane 1 the darkness; padded by Ri rows and Rj columns); bg:
 * the background's pixel heights (H, W); pi, pj (8 x items): crop pixel (i, j), image
 * pixel (i + o0, j + p0); dbar: step 1's mean blocker distance [px]; keep: the darkness
 * a pixel whose ellipse is under a pixel keeps; light: the centre (u, v, h), sgn the
 * sign of its s; ext (16): the disk's 4 extreme points (u, v, h, s); out: the
 * darkness. The per-pixel arrays are padded to a multiple of 8. */
__kernel void swept_boxes(__global const double *z, const int zw, const int zplane,
                          __global const float *bg, const int W, const int H,
                          __global const int *pi, __global const int *pj, __global const double *dbar,
                          __global const float *keep, const int o0, const int p0,
                          const int Ri, const int Rj, const double softness,
                          const float4 light, const float sgn, __global const float *ext,
                          __global float *out)
{
    int g = get_global_id(0);
    int8 i = vload8(g, pi), j = vload8(g, pj);
    int8 gi = i + o0, gj = j + p0;
    /* _receiver_slope: central differences, one-sided at the border */
    int8 jm = max(gj - 1, 0), jp = min(gj + 1, W - 1), im = max(gi - 1, 0), ip = min(gi + 1, H - 1);
    int8 row = gi * W;
    float8 gu = (ps_gather_f(bg, row + jp) - ps_gather_f(bg, row + jm)) / convert_float8(max(jp - jm, 1));
    float8 gv = (ps_gather_f(bg, ip * W + gj) - ps_gather_f(bg, im * W + gj)) / convert_float8(max(ip - im, 1));
    float8 h = ps_gather_f(bg, row + gj);
    float8 u = convert_float8(convert_double8(gj) + 0.5), v = convert_float8(convert_double8(gi) + 0.5);
    double8 db = vload8(g, dbar);
    /* penumbra_axes */
    float8 du = light.x - u, dv = light.y - v, dh = light.z - h;
    float8 t = (sgn * convert_float8(db)) / sqrt(du * du + dv * dv + dh * dh);
    float8 tu = t * du, tv = t * dv, th = t * dh;
    float8 rhs = gu * tu + gv * tv - th;
    float8 ou[4], ov[4];
    for (int k = 0; k < 4; k++) {
        float8 wu = (u + tu) - ext[4 * k], wv = (v + tv) - ext[4 * k + 1], wh = (h + th) - ext[4 * k + 2];
        float8 lam = rhs / (wh - gu * wu - gv * wv);
        ou[k] = tu + lam * wu;
        ov[k] = tv + lam * wv;
    }
    float8 a1u = (ou[0] - ou[1]) * 0.5f, a1v = (ov[0] - ov[1]) * 0.5f;
    float8 a2u = (ou[2] - ou[3]) * 0.5f, a2v = (ov[2] - ov[3]) * 0.5f;
    float8 p = a1u * a1u + a2u * a2u, q = a1u * a1v + a2u * a2v, r2 = a1v * a1v + a2v * a2v;
    float8 mm = (p + r2) * 0.5f, hp = (p - r2) * 0.5f;
    float8 d = sqrt(hp * hp + q * q);
    float8 md = mm - d;
    float8 major = sqrt(mm + d), minor = sqrt(select(md, (float8)0.0f, md < 0.0f));   /* NaN stays NaN */
    int8 hpos = hp >= 0.0f;
    float8 xu = select(q, d + hp, hpos), xv = select(d - hp, q, hpos);
    float8 nn = sqrt(xu * xu + xv * xv);
    float8 cu = select((float8)1.0f, xu / nn, nn > 0.0f), cv = select((float8)0.0f, xv / nn, nn > 0.0f);
    /* _swept_boxes */
    int8 ok = isfinite(major) & isfinite(minor) & isfinite(cu) & isfinite(cv);
    float8 iso = convert_float8(softness * db);
    major = select(iso, major, ok); minor = select(iso, minor, ok);
    cu = select((float8)1.0f, cu, ok); cv = select((float8)0.0f, cv, ok);
    major = fmin(major, (float)max(Ri, Rj));
    minor = fmin(minor, major);
    /* rint as convert_*_rte (PoCL's rint is a library call): the values rounded here
     * are finite and far inside int's range */
    float8 nf = fmin((float)PS_MAX_BOXES, 1.0f + ceil((major - minor) / fmax(minor, 0.5f)));
    int8 n = select((int8)0, convert_int8(nf), convert_int8_rte(major) >= 1);
    float8 gap = convert_float8(max(n - 1, 1));
    float8 spacing = select((float8)0.0f, 2.0f * (major - minor) / gap, n > 1);
    int8 r = min(max(convert_int8_rte(minor), convert_int8(ceil(spacing / 2.0f))), min(Ri, Rj));
    double8 span = select((double8)0.0, fmax(convert_double8(major) - convert_double8(r), 0.0),
                          convert_long8(n > 1));
    double8 su = span * convert_double8(cu), sv = span * convert_double8(cv);
    double8 gapd = convert_double8(gap);
    double8 sdu = 2.0 * su / gapd, sdv = 2.0 * sv / gapd;
    int8 ci = i + Ri, cj = j + Rj;
    double8 den = 0.0, num = 0.0;
    int nmax = max(max(max(n.s0, n.s1), max(n.s2, n.s3)), max(max(n.s4, n.s5), max(n.s6, n.s7)));
    __global const double *z1 = z + zplane;
    for (int k = 0; k < nmax; k++) {     /* a lane's boxes k >= n add nothing (but stay in the tables) */
        int8 oi = clamp(convert_int8_rte((double)k * sdv - sv), r - Ri, Ri - r);
        int8 oj = clamp(convert_int8_rte((double)k * sdu - su), r - Rj, Rj - r);
        int8 i0 = (ci + oi - r) * zw, i1 = (ci + oi + r + 1) * zw, j0 = cj + oj - r, j1 = cj + oj + r + 1;
        long8 on = convert_long8((int8)k < n);
        den += select((double8)0.0, ps_box(z, i0, i1, j0, j1), on);
        num += select((double8)0.0, ps_box(z1, i0, i1, j0, j1), on);
    }
    float8 res = convert_float8(clamp(num / fmax(den, 1.0), 0.0, 1.0));
    vstore8(select(vload8(g, keep), res, n != 0), g, out);
}
#endif
