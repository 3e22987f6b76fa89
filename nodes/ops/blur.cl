// Separable Gaussian blur, one 1D pass per launch (numpy reference: blur.py).
// Images are float32, row-major (height, width, channels) with channels
// interleaved; borders extend the edge pixel (clamp), as mode="edge" in numpy.

__kernel void gaussian_pass(__global const float *src, __global float *dst,
                            __global const float *weights, const int radius,
                            const int width, const int height, const int channels,
                            const int horizontal)
{
    const int x = get_global_id(0);
    const int y = get_global_id(1);
    if (x >= width || y >= height) return;
    for (int c = 0; c < channels; ++c) {
        float acc = 0.0f;
        for (int k = -radius; k <= radius; ++k) {
            const int xx = horizontal ? clamp(x + k, 0, width - 1) : x;
            const int yy = horizontal ? y : clamp(y + k, 0, height - 1);
            acc += weights[k + radius] * src[(yy * width + xx) * channels + c];
        }
        dst[(y * width + x) * channels + c] = acc;
    }
}
