// The composite's per-pixel math on the device (numpy reference: composite.py,
// _shadow_rows and _over_rows). Images are float32, row-major (rows, cols,
// channels) with channels interleaved. ``out`` holds a box of the result (the
// union of the boxes the shadow and the layers touch): ``out_w`` pixels wide,
// ``C`` channels, the first ``ncol`` of them colour (3, or 1 for grey) and, when
// C > ncol, the next one alpha. Each launch covers one input's box, ``w`` x ``h``
// pixels, whose pixel (0, 0) is the out box's pixel (ox, oy).
// No contraction into fused multiply-adds: each step rounds as numpy's does, so
// the results are numpy's, bit for bit, on a device with IEEE float32 arithmetic
// (the host builds with -cl-fp32-correctly-rounded-divide-sqrt where the device
// has it; elsewhere a grey composite's mean of three may differ by 2.5 ulp).
#pragma OPENCL FP_CONTRACT OFF

// bg * (1 + clip(d, 0, 1) * k_c) per colour channel, k_c = -opacity (1 - tint_c)
__kernel void shadow_box(__global float *out, const int out_w, const int C, const int ncol,
                         __global const float *d, const float k0, const float k1, const float k2,
                         const int w, const int h, const int ox, const int oy)
{
    const int x = get_global_id(0);
    const int y = get_global_id(1);
    if (x >= w || y >= h) return;
    const float s = fmin(fmax(d[(size_t)y * w + x], 0.0f), 1.0f);
    __global float *o = out + ((size_t)(y + oy) * out_w + (x + ox)) * C;
    const float k[3] = {k0, k1, k2};
    for (int c = 0; c < ncol; ++c) {
        const float t = s * k[c];
        const float factor = t + 1.0f;
        o[c] = o[c] * factor;
    }
}

// premultiplied over: out = out * (1 - a) + fg per colour channel, out alpha
// (C > ncol) = out_a * (1 - a) + a, with a = clip(alpha, 0, 1). ``fg`` has ``nfc``
// channels (its box, w x h); its colours are its first min(nfc, 3) (``nf``): one
// channel is grey, and a grey out (ncol 1) takes the mean of three. The coverage
// is channel ``alpha_channel`` of fg when that is >= 0, else the (w x h) ``alpha``.
__kernel void over_box(__global float *out, const int out_w, const int C, const int ncol,
                       __global const float *fg, const int nfc, const int nf,
                       __global const float *alpha, const int alpha_channel,
                       const int w, const int h, const int ox, const int oy)
{
    const int x = get_global_id(0);
    const int y = get_global_id(1);
    if (x >= w || y >= h) return;
    const size_t p = (size_t)y * w + x;
    __global const float *f = fg + p * nfc;
    const float a = fmin(fmax(alpha_channel >= 0 ? f[alpha_channel] : alpha[p], 0.0f), 1.0f);
    const float keep = 1.0f - a;
    __global float *o = out + ((size_t)(y + oy) * out_w + (x + ox)) * C;
    if (ncol == 3) {
        for (int c = 0; c < 3; ++c) {
            const float kept = o[c] * keep;
            o[c] = kept + f[nf == 3 ? c : 0];
        }
    } else {
        const float col = nf == 3 ? ((f[0] + f[1]) + f[2]) / 3.0f : f[0];
        const float kept = o[0] * keep;
        o[0] = kept + col;
    }
    if (C > ncol) {
        const float kept = o[ncol] * keep;
        o[ncol] = kept + a;
    }
}
