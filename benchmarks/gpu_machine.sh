#!/bin/bash
# The 20 MP benchmarks on a GPU machine without a network (docs/server.md, "On a GPU"): pixgraph
# installed from wheels carried in .whl/ into /tmp/site (beside the machine's own numpy and torch),
# NVIDIA's OpenCL registered for pyopencl's ICD loader, then photo_bench.py (a 20 MP final, soft
# shadow and glossy floor) and serve_bench.py (the page's steps on a 20 MP photo, no browser) on
# the NVIDIA device and on the machine's PoCL.
#
# The wheels, fetched once on a machine with a network (Python 3.12, Linux x86-64, as the GPU
# machine's python3):
#   pip download --python-version 3.12 --only-binary=:all: --platform manylinux_2_28_x86_64 \
#       --platform manylinux2014_x86_64 --platform manylinux_2_17_x86_64 -d .whl --no-deps \
#       pyopencl pytools platformdirs siphash24 typing_extensions OpenImageIO isal tqdm networkx \
#       jsonschema jsonschema-specifications referencing rpds-py attrs PyYAML Pillow starlette uvicorn \
#       h11 click anyio sniffio idna httpx httpcore certifi setuptools wheel
# Then, on the GPU machine, from the repository's root: bash benchmarks/gpu_machine.sh [photo] [page]
set -u
ROOT=$PWD
WHAT=${*:-photo page}
NVIDIA_OPENCL=${NVIDIA_OPENCL:-/usr/local/nvidia/lib64/libnvidia-opencl.so.1}   # where the lent machines have it
if [ ! -f /etc/OpenCL/vendors/nvidia.icd ]; then
  test -f "$NVIDIA_OPENCL" || { echo "no $NVIDIA_OPENCL: set NVIDIA_OPENCL to NVIDIA's OpenCL library" >&2; exit 3; }
  mkdir -p /etc/OpenCL/vendors && echo "$NVIDIA_OPENCL" > /etc/OpenCL/vendors/nvidia.icd || exit 3
fi
python3 -m pip install -q --upgrade --target /tmp/site --no-index --no-deps --find-links .whl pyopencl pytools \
    platformdirs siphash24 typing_extensions OpenImageIO isal tqdm networkx jsonschema jsonschema-specifications \
    referencing rpds-py attrs PyYAML Pillow starlette uvicorn h11 click anyio sniffio idna httpx httpcore certifi \
    setuptools wheel || exit 4
PYTHONPATH=/tmp/site python3 -m pip install -q --upgrade --target /tmp/site --no-index --no-deps \
    --no-build-isolation . || exit 5
export XDG_CACHE_HOME=${XDG_CACHE_HOME:-/tmp/xdg} PYTHONPATH=/tmp/site
python3 -m pixgraph devices
failed=0
for what in $WHAT; do
  for dev in nvidia pocl; do
    echo "== $what on $dev"
    if [ "$what" = photo ]; then
      PIXGRAPH_DEVICE=$dev python3 benchmarks/photo_bench.py --case soft --case glossy --size 20mp --ext .png \
          --ext .jpg --repeat 3 || failed=1
    else   # twice each: the first open of a device builds its kernels (an empty kernel cache)
      for h in learned contact_line learned contact_line; do
        PIXGRAPH_DEVICE=$dev python3 benchmarks/serve_bench.py --photo 5120x3840 --scales 5 --height $h || failed=1
      done
    fi
  done
done
exit $failed
