#!/usr/bin/env bash
# Install pixgraph and what it needs on a fresh machine.
#   ./setup.sh          the package, SSN++ (the `ssn` extra: torch) to run every example graph, and
#                       the `serve` extra (starlette, uvicorn, Pillow) for `pixgraph serve`
#   ./setup.sh test     plus the lab, test, ground-truth (Mitsuba) and batch (Dask) extras, the
#                       separate bpy venv the Blender add-on test runs in (hosts/blender/bpy_env.py),
#                       and Debian's chromium for the browser test of 'pixgraph serve'
# Debian's PoCL is installed when apt is available and we are root: it is ~2x
# faster than the PoCL inside the pyopencl wheel, and that one (LLVM 14) cannot
# build kernels at all on CPUs newer than it knows ("unknown target CPU").
set -euo pipefail
cd "$(dirname "$0")"
extras="[ssn,serve]"
[ "${1:-}" = "test" ] && extras="[ssn,serve,lab,test,datagen,batch]"

debs=()
dpkg -s pocl-opencl-icd >/dev/null 2>&1 || debs+=(pocl-opencl-icd)
# Mitsuba's fast llvm variants want libLLVM; without it the generator falls back to scalar_rgb.
[ "${1:-}" = "test" ] && ! dpkg -s libllvm19 >/dev/null 2>&1 && debs+=(libllvm19)
# The browser test drives Debian's chromium with Playwright (Playwright's own browser downloads are not used).
[ "${1:-}" = "test" ] && ! dpkg -s chromium >/dev/null 2>&1 && debs+=(chromium)
if [ ${#debs[@]} -gt 0 ] && command -v apt-get >/dev/null && [ "$(id -u)" = 0 ]; then
  echo "setup: apt-get install ${debs[*]}" >&2
  apt-get update -qq >/dev/null && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${debs[@]}" >/dev/null \
    || echo "setup: could not install ${debs[*]} with apt; continuing with pip's PoCL" >&2
fi
pip install -q -e ".${extras}"
# The Blender add-on test runs in its own venv (bpy 5.0 wheel, Python 3.11, numpy < 2);
# built once (downloads bpy; ~1.2 GB on disk), then reused.
if [ "${1:-}" = "test" ]; then python hosts/blender/bpy_env.py; fi
