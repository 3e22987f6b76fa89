"""OpenCL device selection, context and queue, and a program build cache.

The engine owns one ``Device`` per session; nodes reach it as ``ctx.device`` and
never create their own context. Ops (plain functions) take a ``Device`` argument
and use only ``device.context``, ``device.queue`` and ``device.program(source)``.

Selection order: an explicit spec (API or ``--device``), else ``PIXGRAPH_DEVICE``,
else the first GPU, else the fastest CPU platform (Debian's PoCL before the pip
``pocl-binary-distribution`` one, measured ~2x faster on the same kernel).
A spec is ``"PLATFORM_INDEX:DEVICE_INDEX"`` or a case-insensitive substring of
``"platform name / platform version / device name"``.
"""
from __future__ import annotations

import dataclasses
import hashlib
import os
import pathlib
import tempfile
import threading


class DeviceError(RuntimeError):
    """No usable OpenCL device, or a spec that matches none."""


def ensure_cache_dir() -> None:
    """Give PoCL and pyopencl a writable cache directory.

    Both honour ``XDG_CACHE_HOME``; without a writable one PoCL finds no device.
    When HOME's cache is not writable, point it at a temporary directory.
    """
    xdg = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    try:
        pathlib.Path(xdg).mkdir(parents=True, exist_ok=True)
        probe = tempfile.NamedTemporaryFile(dir=xdg, delete=True)
        probe.close()
    except OSError:
        user = os.getuid() if hasattr(os, "getuid") else os.environ.get("USERNAME", "user")  # no getuid on Windows
        fallback = os.path.join(tempfile.gettempdir(), f"pixgraph-cache-{user}")
        os.makedirs(fallback, exist_ok=True)
        os.environ["XDG_CACHE_HOME"] = fallback


@dataclasses.dataclass(frozen=True)
class DeviceInfo:
    platform_index: int
    device_index: int
    platform: str
    platform_version: str
    name: str
    kind: str  # "GPU", "CPU" or "OTHER"
    compute_units: int

    @property
    def spec(self) -> str:
        return f"{self.platform_index}:{self.device_index}"

    def describe(self) -> str:
        return f"[{self.spec}] {self.kind} {self.name} ({self.platform}, {self.platform_version}, {self.compute_units} CUs)"


def _cl():
    ensure_cache_dir()
    import pyopencl as cl

    return cl


def list_devices() -> list[DeviceInfo]:
    """Every OpenCL device of every platform. Empty when none is found."""
    cl = _cl()
    out = []
    try:
        platforms = cl.get_platforms()
    except cl.Error:
        return []
    for pi, p in enumerate(platforms):
        try:
            devices = p.get_devices()
        except cl.Error:
            continue
        for di, d in enumerate(devices):
            kind = "GPU" if d.type & cl.device_type.GPU else "CPU" if d.type & cl.device_type.CPU else "OTHER"
            out.append(DeviceInfo(pi, di, p.name, p.version, d.name.strip(), kind, d.max_compute_units))
    return out


def no_device_hint(system: str | None = None, machine: str | None = None) -> str:
    """What to install for OpenCL on this platform (``platform.system()``/``machine()``).

    pip's ``pocl-binary-distribution`` wheel exists only for Linux x86-64 (pixgraph
    depends on it there); everywhere else the system's OpenCL is used.
    """
    import platform

    system = system or platform.system()
    machine = (machine or platform.machine()).lower()
    if system == "Darwin":
        how = ("macOS ships OpenCL (Apple's, deprecated but present); if it lists no device, "
               "install PoCL: brew install pocl")
    elif system == "Windows":
        how = ("install your GPU vendor's driver (NVIDIA, AMD and Intel drivers include OpenCL), "
               "or Intel's CPU OpenCL runtime, or PoCL from conda-forge: conda install pocl")
    elif system == "Linux" and machine in ("x86_64", "amd64"):
        how = ("pip install pocl-binary-distribution (a pixgraph dependency here), or on "
               "Debian/Ubuntu: apt-get install pocl-opencl-icd")
    else:
        how = (f"no PoCL wheel exists for {system} {machine}: install your system's OpenCL, e.g. "
               "apt-get install pocl-opencl-icd (Debian/Ubuntu), or a GPU vendor's driver")
    return how + "; and make sure XDG_CACHE_HOME is writable"


def _rank(info: DeviceInfo) -> tuple:
    # GPU first; among CPU platforms prefer Debian's PoCL (its version string says
    # "debian") over the pip wheel; then more compute units.
    return (info.kind != "GPU", "debian" not in info.platform_version.lower(), -info.compute_units,
            info.platform_index, info.device_index)


_PROBE_SOURCE = "__kernel void probe(__global float *a) { a[get_global_id(0)] *= 2.0f; }"


def build_problem(info: DeviceInfo) -> str | None:
    """Why ``info`` cannot build a trivial kernel, or None when it can.

    Seen in practice: the PoCL bundled with pip wheels (LLVM 14) does not know
    recent CPUs and fails every build with "unknown target CPU 'generic'".
    """
    cl = _cl()
    try:
        dev = cl.get_platforms()[info.platform_index].get_devices()[info.device_index]
        cl.Program(cl.Context([dev]), _PROBE_SOURCE).build()
    except Exception as exc:  # any failure means: do not pick this device by default
        lines = [ln.strip() for ln in str(exc).splitlines() if ln.strip()]
        return next((ln for ln in lines if "error" in ln.lower()), lines[0] if lines else type(exc).__name__)
    return None


def choose(spec: str | None = None) -> DeviceInfo:
    """Pick a device by spec, ``PIXGRAPH_DEVICE``, or the default order.

    By default the best-ranked device that can actually build a kernel wins;
    devices that cannot are skipped (and named if none can). An explicit spec
    is taken as given.
    """
    devices = list_devices()
    if not devices:
        raise DeviceError("no OpenCL device found: " + no_device_hint())
    spec = spec if spec is not None else os.environ.get("PIXGRAPH_DEVICE") or None
    if spec is None:
        problems = []
        for d in sorted(devices, key=_rank):
            problem = build_problem(d)
            if problem is None:
                return d
            problems.append(f"{d.describe()}: {problem}")
        raise DeviceError("no OpenCL device can build kernels (on Debian/Ubuntu: apt-get install "
                          "pocl-opencl-icd): " + "; ".join(problems))
    if ":" in spec and all(part.isascii() and part.isdigit() for part in spec.split(":", 1)):
        pi, di = (int(x) for x in spec.split(":", 1))
        for d in devices:
            if (d.platform_index, d.device_index) == (pi, di):
                return d
    needle = spec.lower()
    matches = [d for d in devices if needle in f"{d.platform} / {d.platform_version} / {d.name}".lower()
               or needle == d.kind.lower()]
    if not matches:
        listing = "; ".join(d.describe() for d in devices)
        raise DeviceError(f"no OpenCL device matches {spec!r} (available: {listing})")
    return min(matches, key=_rank)


class Device:
    """An OpenCL context and in-order queue, with programs built once per source.

    Build one with ``Device.open(spec)``, or hand in a host's own context and
    queue with ``Device.from_cl(context, queue)``.
    """

    def __init__(self, context, queue, info: DeviceInfo | None = None):
        self.context = context
        self.queue = queue
        self.info = info
        self._programs: dict[str, object] = {}
        self._lock = threading.Lock()

    @classmethod
    def open(cls, spec: str | None = None) -> "Device":
        cl = _cl()
        info = choose(spec)
        dev = cl.get_platforms()[info.platform_index].get_devices()[info.device_index]
        ctx = cl.Context([dev])
        return cls(ctx, cl.CommandQueue(ctx), info)

    @classmethod
    def from_cl(cls, context, queue) -> "Device":
        """Wrap a context and queue that a host application owns."""
        return cls(context, queue, None)

    @property
    def name(self) -> str:
        return self.info.describe() if self.info else self.queue.device.name.strip()

    def program(self, source: str, options: tuple[str, ...] = ()):
        """The built ``pyopencl.Program`` for ``source``; built once per device.

        pyopencl also keeps built binaries on disk (under XDG_CACHE_HOME), so a
        new process skips the compiler for a source it has seen.
        """
        key = hashlib.sha256((source + "\0" + "\0".join(options)).encode()).hexdigest()
        with self._lock:
            prg = self._programs.get(key)
            if prg is None:
                cl = _cl()
                prg = cl.Program(self.context, source)
                try:
                    prg.build(options=list(options))
                except cl.RuntimeError as exc:
                    raise DeviceError(f"{self.name}: cannot build OpenCL program: "
                                      f"{_first_error(prg, self.queue.device) or exc}") from exc
                self._programs[key] = prg
            return prg


def _first_error(program, device) -> str:
    """The compiler's first error line from a failed build, or ''."""
    try:
        import pyopencl as cl
        log = program.get_build_info(device, cl.program_build_info.LOG)
    except Exception:
        return ""
    lines = [ln.strip() for ln in str(log).splitlines() if ln.strip()]
    return next((ln for ln in lines if "error" in ln.lower()), lines[0] if lines else "")


def load_kernel_source(module_file: str, name: str) -> str:
    """Read a ``.cl`` file that sits next to a Python module, with its ``#include``s of
    sibling files inlined (so the source text, and hence the build cache key,
    changes when any included file changes)."""
    folder = pathlib.Path(module_file).parent
    seen: set[str] = set()

    def expand(fname: str) -> str:
        if fname in seen:
            return ""
        seen.add(fname)
        out = []
        for line in (folder / fname).read_text().splitlines():
            s = line.strip()
            if s.startswith("#include") and '"' in s:
                out.append(expand(s.split('"')[1]))
            else:
                out.append(line)
        return "\n".join(out)

    return expand(name)
