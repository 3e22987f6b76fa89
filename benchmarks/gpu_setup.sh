# Sourced by gpu_machine.sh and gpu_before_after.sh on a GPU machine without a network: registers
# NVIDIA's OpenCL for pyopencl's ICD loader and defines `install_deps DIR`, which installs
# pixgraph's dependencies from the wheels carried in .whl/ into DIR (beside the machine's own
# numpy and torch). The wheels, fetched once on a machine with a network (Python 3.12, Linux
# x86-64, as the GPU machine's python3):
#   pip download --python-version 3.12 --only-binary=:all: --platform manylinux_2_28_x86_64 \
#       --platform manylinux2014_x86_64 --platform manylinux_2_17_x86_64 -d .whl --no-deps $GPU_DEPS
GPU_DEPS="pyopencl pytools platformdirs siphash24 typing_extensions OpenImageIO isal tqdm networkx jsonschema
  jsonschema-specifications referencing rpds-py attrs PyYAML Pillow starlette uvicorn h11 click anyio sniffio idna
  httpx httpcore certifi setuptools wheel
  pytest pluggy iniconfig packaging pygments"   # pytest: gpu_before_after.sh runs tests/test_composite_device.py
NVIDIA_OPENCL=${NVIDIA_OPENCL:-/usr/local/nvidia/lib64/libnvidia-opencl.so.1}   # where the lent machines have it
if [ ! -f /etc/OpenCL/vendors/nvidia.icd ]; then
  test -f "$NVIDIA_OPENCL" || { echo "no $NVIDIA_OPENCL: set NVIDIA_OPENCL to NVIDIA's OpenCL library" >&2; exit 3; }
  mkdir -p /etc/OpenCL/vendors && echo "$NVIDIA_OPENCL" > /etc/OpenCL/vendors/nvidia.icd || exit 3
fi

install_deps() {   # install_deps DIR
  # shellcheck disable=SC2086  # the list splits into package names
  python3 -m pip install -q --upgrade --target "$1" --no-index --no-deps --find-links .whl $GPU_DEPS
}
