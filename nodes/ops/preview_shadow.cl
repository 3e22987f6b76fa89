/* A preview's soft shadow (preview_shadow.py): the hard shadow of the light's
 * centre with, per shadowed receiver, the distance to the occluder point that
 * blocks it, in one launch. The march is shadow.cl's (included whole). */
#include "shadow.cl"

/* out (2, H, W): plane 0 darkness of the centre (1 shadow, 0 lit), plane 1
 * |receiver - first blocking occluder point| in (u, v, h) pixels where
 * shadowed, 0 where lit (buffer_channels' relative_distance). NDRange (W, H). */
__kernel void hard_shadow_distance(OCCLUDER_ARGS, __global const float *recv, const float4 light,
                                   __global float *out)
{
    int j = get_global_id(0), i = get_global_id(1);
    if (j >= W || i >= H) return;
    OCCLUDER_INIT(o);
    int idx = i * W + j;
    float rh = recv[idx];
    float dark = 0.0f, dist = 0.0f;
    if (rh > PH_NO_SURFACE_TEST) {
        ph_march m;
        int k; float hs;
        if (trace_light(&o, (float)j + 0.5f, (float)i + 0.5f, rh, light, &m, &k, &hs)) {
            float du = (float)k * m.su, dv = (float)k * m.sv, dh = hs - rh;
            dark = 1.0f;
            dist = sqrt(du * du + dv * dv + dh * dh);
        }
    }
    out[idx] = dark;
    out[W * H + idx] = dist;
}
