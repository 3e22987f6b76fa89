"""SSN++: the neural soft-shadow renderer (PixHt-Lab Sec. 3.2).

A small U-Net (3x3 conv blocks with GroupNorm and GELU, skip connections, as
SSG's backbone) that maps the buffer channels of ``ops.buffers`` to a soft shadow
darkness map (1 = full shadow).

The light's softness really conditions the network (the authors' released
backbone never reads it): every conv block is modulated by FiLM, a per-channel
scale and shift predicted from the softness, so one set of weights renders a
small and a large light differently.

Softness is the disk light's angular radius ``radius / distance`` (dimensionless,
about 0.015 .. 0.5): it is what decides the penumbra width for a given
occluder-receiver distance, independently of the camera.

Channel sets (the paper's Table 2 ablation):
    ssg     cutout_height, hard_shadow
    sparse  + sparse_hard_shadow_0..3
    reldist + relative_distance
    ssnpp   + bg_gradient_x, bg_gradient_y   (the full SSN++)
"""
from __future__ import annotations

import contextlib
import copy
import dataclasses
import json
import os
import pathlib
import weakref

import numpy as np
import torch
from torch import nn
import torch.nn.functional as F

from .bands import threads_from_env, usable_cpus

VARIANTS: dict[str, tuple[str, ...]] = {
    "ssg": ("cutout_height", "hard_shadow"),
    "sparse": ("cutout_height", "hard_shadow", "sparse_hard_shadow_0", "sparse_hard_shadow_1",
               "sparse_hard_shadow_2", "sparse_hard_shadow_3"),
}
VARIANTS["reldist"] = VARIANTS["sparse"] + ("relative_distance",)
VARIANTS["ssnpp"] = VARIANTS["reldist"] + ("bg_gradient_x", "bg_gradient_y")

#: resolution the network runs at (pixels); inputs are resized to it and back
RESOLUTION = 256

#: Softness the network is fed at most (radius / distance). Training covered
#: 0.015 .. 0.45; up to 1 (a disk as wide as its distance) it extrapolates
#: smoothly, beyond it is clamped: an absurd light (radius 1e300) then gives
#: the softest shadow the model knows, never NaN.
SOFTNESS_MAX = 1.0

#: Environment variable a host sets to choose torch's intra-op threads for
#: inference (a positive integer); see :func:`inference_threads`.
THREADS_ENV = "PIXGRAPH_TORCH_THREADS"

#: Environment variable a host sets to choose the torch device SSN++ runs on:
#: ``auto`` (the default: CUDA when torch has it, else the CPU), ``cpu``, ``cuda``
#: or ``cuda:N``; see :func:`inference_device`.
DEVICE_ENV = "PIXGRAPH_TORCH_DEVICE"

# Buffer channels in pixel units are brought to O(1) before entering the
# network. Pixel heights and distances are divided by the image size, so the
# same scene at another resolution gives the same input (heights scale with s).
_SCALE_BY_SIZE = {"cutout_height", "relative_distance"}
# The background gradient is a slope (pixels per pixel): about 0 on the ground,
# -1 on a wall. Beyond +-2 it marks a depth discontinuity (a step's edge), where
# its size says nothing more, so it is clipped.
_GRADIENT = {"bg_gradient_x", "bg_gradient_y"}
_GRADIENT_CLIP = 2.0


@dataclasses.dataclass(frozen=True)
class SSNConfig:
    """Architecture of one SSN++ model.

    variant: which buffer channels it reads (a key of ``VARIANTS``).
    base: channels of the first level; level k has ``base * 2**k``.
    levels: number of down-sampling steps.
    """

    variant: str = "ssnpp"
    base: int = 16
    levels: int = 4

    @property
    def channels(self) -> tuple[str, ...]:
        return VARIANTS[self.variant]


class FiLMBlock(nn.Module):
    """conv3x3 -> GroupNorm -> FiLM(softness) -> GELU, twice."""

    def __init__(self, cin: int, cout: int, cond: int):
        super().__init__()
        self.conv1 = nn.Conv2d(cin, cout, 3, padding=1)
        self.norm1 = nn.GroupNorm(min(8, cout // 4) or 1, cout)
        self.conv2 = nn.Conv2d(cout, cout, 3, padding=1)
        self.norm2 = nn.GroupNorm(min(8, cout // 4) or 1, cout)
        self.film = nn.Linear(cond, 4 * cout)
        # start as identity modulation so training begins from a plain U-Net
        nn.init.zeros_(self.film.weight)
        nn.init.zeros_(self.film.bias)

    def forward(self, x, c):
        g1, b1, g2, b2 = self.film(c)[:, :, None, None].chunk(4, dim=1)
        x = F.gelu(self.norm1(self.conv1(x)) * (1 + g1) + b1)
        return F.gelu(self.norm2(self.conv2(x)) * (1 + g2) + b2)


class SSN(nn.Module):
    """U-Net from buffer channels (B, C, H, W) and softness (B,) to darkness (B, 1, H, W) in [0, 1].

    H and W must be divisible by ``2**levels``.
    """

    def __init__(self, config: SSNConfig = SSNConfig()):
        super().__init__()
        self.config = config
        cin = len(config.channels)
        cond = 32
        # softness enters through a small MLP on (s, log s): the penumbra
        # width is roughly proportional to s, but lights span 1.5 decades.
        self.cond = nn.Sequential(nn.Linear(2, cond), nn.GELU(), nn.Linear(cond, cond), nn.GELU())
        widths = [config.base * 2 ** k for k in range(config.levels + 1)]
        self.down = nn.ModuleList()
        prev = cin
        for w in widths:
            self.down.append(FiLMBlock(prev, w, cond))
            prev = w
        self.up = nn.ModuleList()
        for w in reversed(widths[:-1]):
            self.up.append(FiLMBlock(prev + w, w, cond))
            prev = w
        self.head = nn.Conv2d(prev, 1, 1)

    def forward(self, x: torch.Tensor, softness: torch.Tensor) -> torch.Tensor:
        s = softness.reshape(-1, 1).to(x.dtype)
        c = self.cond(torch.cat([s * 10.0, torch.log(s.clamp_min(1e-3))], dim=1))
        skips = []
        for i, block in enumerate(self.down):
            if i > 0:
                x = F.max_pool2d(x, 2)
            x = block(x, c)
            skips.append(x)
        skips.pop()
        for block in self.up:
            x = F.interpolate(x, scale_factor=2, mode="bilinear", align_corners=False)
            x = block(torch.cat([x, skips.pop()], dim=1), c)
        return torch.sigmoid(self.head(x))


def count_params(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())


def count_flops(model: SSN, size: int = RESOLUTION) -> int:
    """Multiply-adds x 2 of the convolutions and linears for one (size x size) sample."""
    flops = 0
    hooks = []

    def conv_hook(m, inp, out):
        nonlocal flops
        k = m.kernel_size[0] * m.kernel_size[1] * (m.in_channels // m.groups)
        flops += 2 * k * out.numel()

    def lin_hook(m, inp, out):
        nonlocal flops
        flops += 2 * m.in_features * out.numel()

    for m in model.modules():
        if isinstance(m, nn.Conv2d):
            hooks.append(m.register_forward_hook(conv_hook))
        elif isinstance(m, nn.Linear):
            hooks.append(m.register_forward_hook(lin_hook))
    with torch.no_grad():
        model(torch.zeros(1, len(model.config.channels), size, size), torch.tensor([0.1]))
    for h in hooks:
        h.remove()
    return flops


def stack_channels(buffers: dict[str, np.ndarray], channels: tuple[str, ...],
                   norm: float | None = None) -> np.ndarray:
    """Buffer channels (each float (H, W), pixel units) -> network input float32 (C, H, W).

    Pixel-height-like channels are divided by ``norm`` pixels (default the
    image height) so that a resized scene gives the same input; shadows are
    already in [0, 1]; the background gradient is dimensionless and clipped to +-2.
    """
    H = float(norm) if norm else next(iter(buffers.values())).shape[0]
    out = []
    for name in channels:
        x = np.nan_to_num(np.asarray(buffers[name], dtype=np.float32), nan=0.0, posinf=0.0, neginf=0.0)
        if name in _SCALE_BY_SIZE:
            x = x / float(H)
        elif name in _GRADIENT:
            x = np.clip(x, -_GRADIENT_CLIP, _GRADIENT_CLIP)
        out.append(x)
    return np.stack(out)


def save_model(model: SSN, path: str | pathlib.Path, meta: dict) -> None:
    """Weights (float16 to keep the shipped file small) and their config + provenance."""
    path = pathlib.Path(path)
    state = {k: v.half() if v.is_floating_point() else v for k, v in model.state_dict().items()}
    torch.save({"config": dataclasses.asdict(model.config), "state": state, "meta": meta}, path)
    path.with_suffix(".json").write_text(json.dumps(
        {"config": dataclasses.asdict(model.config), **meta}, indent=2, sort_keys=True) + "\n")


def load_model(path: str | pathlib.Path) -> SSN:
    blob = torch.load(path, map_location="cpu", weights_only=True)
    model = SSN(SSNConfig(**blob["config"]))
    model.load_state_dict({k: v.float() for k, v in blob["state"].items()})
    model.eval()
    # oneDNN's convolutions run faster on NHWC tensors on the CPU (same results
    # to ~1e-5); ``predict`` hands the input over in the same layout
    return model.to(memory_format=torch.channels_last)


def inference_threads() -> int:
    """Torch intra-op threads for one SSN++ inference.

    ``PIXGRAPH_TORCH_THREADS`` when set (a host's choice; ValueError if it is
    not a whole number of at least 1), else 1 thread per 4 CPUs this process may use
    (at least 1, at most 4). Torch's own default (one thread per core) fights
    PoCL's workers and any busy neighbour for the cores: its threads meet at a
    barrier after every layer, so one preempted thread stalls them all.
    Measured on a shared 2-core machine (benchmarks/ssn_threads_bench.py, 512^2
    scene, medians): inference with 1 thread 158 ms, 269 ms next to a busy
    process (1.7x); with torch's default 2 threads 1869 ms and 1996 ms
    (docs/ssn.md has the table).
    """
    return threads_from_env(THREADS_ENV, max(1, min(4, usable_cpus() // 4)))


def inference_device() -> torch.device:
    """The torch device for SSN++ inference: ``PIXGRAPH_TORCH_DEVICE`` (``auto``,
    ``cpu``, ``cuda`` or ``cuda:N``; ValueError naming the variable for anything
    else, or for a CUDA device this torch build or machine does not have), by
    default ``auto``: the first CUDA device when ``torch.cuda.is_available()``,
    else the CPU. The network is small (0.54 M parameters); on the CPU it costs
    most of the node's time, on a GPU a few milliseconds."""
    raw = os.environ.get(DEVICE_ENV, "").strip().lower() or "auto"
    if raw == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if raw == "cpu":
        return torch.device("cpu")
    kind, _, index = raw.partition(":")
    if kind != "cuda" or (index and not index.isdigit()):
        raise ValueError(f"{DEVICE_ENV} must be auto, cpu, cuda or cuda:N, got {raw!r}")
    if not torch.cuda.is_available():
        raise ValueError(f"{DEVICE_ENV}={raw} but this torch ({torch.__version__}) finds no CUDA device; "
                         f"use auto or cpu")
    n = torch.cuda.device_count()
    if index and int(index) >= n:
        raise ValueError(f"{DEVICE_ENV}={raw} but torch finds {n} CUDA device(s)")
    return torch.device(raw if index else "cuda")


#: model -> {device: its copy there}; weak, so a model its owner drops goes with its copies
_on_device: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def model_on(model: SSN, device: torch.device) -> SSN:
    """``model`` itself when it is on ``device``; else a copy on ``device``, made once
    per model and device (the shipped model is loaded once per process on the CPU)."""
    device = torch.device(device)
    if device.type == "cuda" and device.index is None:      # "cuda" is the current CUDA device,
        device = torch.device("cuda", torch.cuda.current_device())  # which torch calls != cuda:0
    if next(model.parameters()).device == device:
        return model
    copies = _on_device.setdefault(model, {})
    if str(device) not in copies:
        copies[str(device)] = copy.deepcopy(model).to(device)
    return copies[str(device)]


@contextlib.contextmanager
def torch_threads(n: int):
    """Run the block with ``n`` torch intra-op threads, then restore the host's setting
    (torch's thread count is per process: a host's own torch work keeps its own)."""
    before = torch.get_num_threads()
    if n != before:
        torch.set_num_threads(n)
    try:
        yield
    finally:
        if n != before:
            torch.set_num_threads(before)


def predict(model: SSN, buffers: dict[str, np.ndarray], softness: float,
            threads: int | None = None, device: torch.device | str | None = None) -> np.ndarray:
    """Soft-shadow darkness (H, W) float32 in [0, 1] for one sample at any resolution.

    The buffers are resized to ``RESOLUTION`` (pixel-unit channels are
    normalised by ``stack_channels``), run through the network, and the result
    is resized back. ``softness`` is clamped to [0, SOFTNESS_MAX] (ValueError
    when NaN). threads, device: as for :func:`run_network`.
    """
    softness = float(softness)
    if softness != softness:
        raise ValueError("softness is NaN")
    softness = min(max(softness, 0.0), SOFTNESS_MAX)
    x = torch.from_numpy(stack_channels(buffers, model.config.channels))[None]
    H, W = x.shape[-2:]
    if (H, W) != (RESOLUTION, RESOLUTION):
        x = F.interpolate(x, size=(RESOLUTION, RESOLUTION), mode="bilinear", align_corners=False)
    return _forward(model, x, softness, threads, device, out_size=(H, W))


def run_network(model: SSN, buffers: dict[str, np.ndarray], softness: float,
                norm: float | None = None, threads: int | None = None,
                device: torch.device | str | None = None) -> np.ndarray:
    """Darkness (H, W) float32 in [0, 1] with the network run at the buffers' own
    size (no resizing: H and W must be multiples of ``2**levels``); pixel-unit
    channels are divided by ``norm`` px (see ``stack_channels``). ``ssn_crop``
    runs it on a window at the trained scale, where ``norm = RESOLUTION``.
    threads: torch intra-op threads (default :func:`inference_threads`; they
    matter on the CPU only); device: torch's (default :func:`inference_device`)."""
    x = torch.from_numpy(stack_channels(buffers, model.config.channels, norm))[None]
    m = 2 ** model.config.levels
    if x.shape[-2] % m or x.shape[-1] % m:
        raise ValueError(f"run_network needs sides divisible by {m}, got {tuple(x.shape[-2:])}")
    return _forward(model, x, float(softness), threads, device)


def _forward(model: SSN, x: torch.Tensor, softness: float, threads, device, out_size=None) -> np.ndarray:
    """The network on ``x`` (1, C, h, w) on the CPU -> darkness (H, W) float32 in
    [0, 1] on the CPU, resized to ``out_size`` when it is given and differs."""
    device = torch.device(device) if device is not None else inference_device()
    net = model_on(model, device)
    with torch_threads(threads or inference_threads()), torch.inference_mode():
        x = x.to(device).contiguous(memory_format=torch.channels_last)
        y = net(x, torch.tensor([softness], device=device))
        if out_size is not None and tuple(out_size) != tuple(y.shape[-2:]):
            y = F.interpolate(y, size=tuple(out_size), mode="bilinear", align_corners=False)
        return y[0, 0].clamp(0, 1).cpu().numpy().astype(np.float32)


# the definition lives in a torch-free module (pixgraph.Shadow's method choice needs
# it without SSN++); re-exported here, where the training code and the node read it
from .softness import softness_of  # noqa: E402,F401
