#!/bin/bash
# The 20 MP benchmarks on a GPU machine without a network (docs/server.md, "On a GPU"): pixgraph
# installed from wheels carried in .whl/ into /tmp/site (beside the machine's own numpy and torch),
# NVIDIA's OpenCL registered for pyopencl's ICD loader, then photo_bench.py (a 20 MP final, soft
# shadow and glossy floor) and serve_bench.py (the page's steps on a 20 MP photo, no browser) on
# the NVIDIA device and on the machine's PoCL.
#
# The wheels: see gpu_setup.sh's header. Then, on the GPU machine, from the repository's root:
#   bash benchmarks/gpu_machine.sh [photo] [page]
set -u
ROOT=$PWD
WHAT=${*:-photo page}
source benchmarks/gpu_setup.sh
install_deps /tmp/site || exit 4
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
