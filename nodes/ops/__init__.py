"""Math of the effects: plain functions on arrays, OpenCL kernels next to numpy references."""
