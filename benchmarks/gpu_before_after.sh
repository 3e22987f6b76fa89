#!/bin/bash
# Two versions of pixgraph side by side on a GPU machine without a network (docs/server.md, "On a GPU"):
# this tree ("after") and the same tree with the files of an older revision laid over it ("before"),
# each installed into its own folder from the wheels carried in .whl/ (see gpu_setup.sh's header),
# then the Reflection node's host benchmark and the composite's (composite_bench.py: the node, its
# parts, numpy and the device side by side; twice each, interleaved) and the 20 MP finals.
#
# On the machine with the repository (REV: the older revision; only files that REV and this tree
# both have are laid over, which is what a change to existing code needs):
#   for f in $(git diff --name-only --diff-filter=M REV -- nodes pixgraph); do
#     mkdir -p .before/$(dirname $f); git show REV:$f > .before/$f; done
# then carry .whl and .before to the GPU machine and, from the repository's root there:
#   bash benchmarks/gpu_before_after.sh [.before]
set -u
OVER=${1:-.before}
test -d "$OVER" || { echo "no folder $OVER of the older revision's files" >&2; exit 2; }
source benchmarks/gpu_setup.sh
install_deps /tmp/deps || exit 4
rm -rf /tmp/before && mkdir /tmp/before && cp -r . /tmp/before/ && cp -r "$OVER"/. /tmp/before/ || exit 5
for v in after:. before:/tmp/before; do
  PYTHONPATH=/tmp/deps python3 -m pip install -q --target "/tmp/site_${v%%:*}" --no-index --no-deps \
      --no-build-isolation "${v#*:}" || exit 5
done
export XDG_CACHE_HOME=${XDG_CACHE_HOME:-/tmp/xdg} PIXGRAPH_DEVICE=${PIXGRAPH_DEVICE:-nvidia}
PYTHONPATH=/tmp/site_after:/tmp/deps python3 -m pixgraph devices
failed=0
for v in before after before after; do
  echo "== reflection host work, $v"
  PYTHONPATH=/tmp/site_$v:/tmp/deps python3 benchmarks/reflection_host_bench.py --size 20mp --repeat 3 || failed=1
done
echo "== the composite's kernels against numpy on this device (tests/test_composite_device.py)"
if PYTHONPATH=/tmp/site_after:/tmp/deps python3 -c "import pytest" 2>/dev/null; then
  PYTHONPATH=/tmp/site_after:/tmp/deps python3 -m pytest -q -p no:cacheprovider tests/test_composite_device.py || failed=1
else
  echo "no pytest on this machine: not run (composite_bench.py below prints the largest difference on the photo)"
fi
for v in before after before after; do
  echo "== composite, $v"
  PYTHONPATH=/tmp/site_$v:/tmp/deps python3 benchmarks/composite_bench.py --size 20mp --repeat 3 || failed=1
done
for v in before after; do
  echo "== 20 MP soft and glossy finals, $v"
  PYTHONPATH=/tmp/site_$v:/tmp/deps python3 benchmarks/photo_bench.py --case soft --case glossy --size 20mp \
      --ext .png --repeat 3 || failed=1
done
exit $failed
