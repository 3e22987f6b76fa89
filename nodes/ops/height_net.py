"""The learned cutout-height network (``learned_height.build_model``) for
inference in numpy alone: no torch needed to predict a pixel height.

The network is a small U-Net at 64 x 64 (base 16, 4 levels: ~1.9 M
parameters, ~0.44 GFLOP per crop). Its weights come from
``weights/cutout_height.npz``, written from the checkpoint ``cutout_height.pt``
by ``python -m pixgraph_lab.height.export --npz`` (the same arrays, see
``write_npz``), and each BatchNorm is folded into the convolution before it at
load time in float32, the same arithmetic as ``learned_height.fold_batchnorm``.

Activations are float32, channels last (N, H, W, C), so that a 3 x 3
convolution is three matrix products on numpy's BLAS, one per kernel row (each
pixel's row neighbours side by side, ``conv3x3``).
The other layers are the plain functions below: ReLU, 2 x 2 max pooling,
bilinear x2 upsampling as torch's ``F.interpolate(scale_factor=2,
mode="bilinear", align_corners=False)``, concatenation and the 1 x 1 head.

``resize_chw`` is the resize the predictor's pre- and post-processing use
(``learned_height.prepare`` / ``paste``): bilinear with half-pixel centres,
with or without antialiasing, each axis a small banded matrix; it equals torch's
``F.interpolate(mode="bilinear", align_corners=False, antialias=...)`` up to
float rounding (tests/test_height_net.py).

``blas_threads``: the BLAS of numpy uses every core by default; the predictor
runs with one BLAS thread (like its one torch thread; on the shared 2-core
machine two threads took ~2x as long under load), set through OpenBLAS's own
call when numpy's BLAS is the OpenBLAS its wheel bundles, else through
threadpoolctl when it is installed, else left as it is.
"""
from __future__ import annotations

import contextlib
import ctypes
import glob
import hashlib
import json
import os
import pathlib
import threading

import numpy as np

#: BatchNorm2d's default epsilon (the training model's)
BN_EPS = 1e-5


# ----------------------------------------------------------------------------- layers

def conv3x3(x: np.ndarray, w: np.ndarray, b: np.ndarray) -> np.ndarray:
    """3 x 3 convolution, stride 1, zero padding 1 (torch's ``Conv2d(cin, cout, 3, padding=1)``).

    x: (N, H, W, C) float32; w: (9 C, C_out), rows ordered (dy, dx, c) with dy,
    dx in 0..2 the kernel's row and column (``conv_matrix``); b: (C_out,).
    Returns (N, H, W, C_out) float32.

    Each pixel gets its row neighbours' channels beside its own (``xs``: (N, H + 2,
    W, 3 C), one zero row above and below); in that array, flattened over (row,
    column), the pixels one row down are W places further on, so the kernel's three
    rows are three contiguous slices and the convolution three matrix products
    ((N, H W, 3 C) x (3 C, C_out)), summed. Copies 3 C instead of 9 C floats per pixel
    (an im2col of all nine neighbours took ~1.4x as long at 64 x 64, 1.8x for 48 channels)."""
    N, H, W, C = x.shape
    xs = np.zeros((N, H + 2, W, 3, C), np.float32)
    xs[:, 1:H + 1, :, 1] = x
    xs[:, 1:H + 1, 1:, 0] = x[:, :, :-1]           # the left neighbour (dx = 0), zero in column 0
    xs[:, 1:H + 1, :-1, 2] = x[:, :, 1:]           # the right neighbour (dx = 2)
    flat = xs.reshape(N, (H + 2) * W, 3 * C)
    w3 = w.reshape(3, 3 * C, -1)                   # per kernel row dy: rows (dx, c)
    P = H * W
    out = np.matmul(flat[:, :P], w3[0])            # output row r reads padded row r (input row r - 1)
    out += np.matmul(flat[:, W:W + P], w3[1])
    out += np.matmul(flat[:, 2 * W:2 * W + P], w3[2])
    out += b
    return out.reshape(N, H, W, -1)


def conv1x1(x: np.ndarray, w: np.ndarray, b: np.ndarray) -> np.ndarray:
    """1 x 1 convolution: x (N, H, W, C), w (C, C_out), b (C_out,) -> (N, H, W, C_out)."""
    N, H, W, C = x.shape
    out = x.reshape(-1, C) @ w
    out += b
    return out.reshape(N, H, W, -1)


def relu(x: np.ndarray) -> np.ndarray:
    """max(x, 0), in place."""
    return np.maximum(x, 0.0, out=x)


def max_pool2(x: np.ndarray) -> np.ndarray:
    """2 x 2 max pooling, stride 2 (torch's ``F.max_pool2d(x, 2)``: an odd last row or
    column is dropped). x: (N, H, W, C) -> (N, H // 2, W // 2, C)."""
    H, W = x.shape[1] // 2 * 2, x.shape[2] // 2 * 2
    return np.maximum(np.maximum(x[:, 0:H:2, 0:W:2], x[:, 0:H:2, 1:W:2]),
                      np.maximum(x[:, 1:H:2, 0:W:2], x[:, 1:H:2, 1:W:2]))


def _upsample2_axis(x: np.ndarray, axis: int, out: np.ndarray | None = None) -> np.ndarray:
    """x2 along ``axis``, bilinear with half-pixel centres: output pixel i samples the
    input at (i + 0.5) / 2 - 0.5, clamped to the first pixel; so output 2j is
    0.25 x[j-1] + 0.75 x[j] and output 2j+1 is 0.75 x[j] + 0.25 x[j+1], each
    neighbour index clamped to the array (edge pixels repeat). Computed as
    x[j] -+ d with d = (x[j] - x[j-1]) / 4 (the same up to float rounding)."""
    if out is None:                  # in x's own axis order (a moved axis would leave it strided)
        shape = list(x.shape)
        shape[axis] *= 2
        out = np.empty(shape, np.float32)
    res = out
    x, out = np.moveaxis(x, axis, 0), np.moveaxis(out, axis, 0)
    n = x.shape[0]
    ev, od = out[0::2], out[1::2]
    if n == 1:
        ev[...] = x
        od[...] = x
        return res
    d = x[1:] - x[:-1]
    d *= 0.25
    np.subtract(x[1:], d, out=ev[1:])
    ev[0] = x[0]
    np.add(x[:-1], d, out=od[:-1])
    od[-1] = x[-1]
    return res


def upsample2(x: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Bilinear x2 upsampling of (N, H, W, C) -> (N, 2H, 2W, C), as torch's
    ``F.interpolate(scale_factor=2, mode="bilinear", align_corners=False)`` (up to
    float rounding); ``out``: where to write it (e.g. the first channels of a
    concatenation)."""
    return _upsample2_axis(_upsample2_axis(x, 1), 2, out)


# ----------------------------------------------------------------------------- resizing

def bilinear_matrix(n_in: int, n_out: int, antialias: bool) -> np.ndarray:
    """(n_out, n_in) float32: the weights of a 1-D bilinear resize with half-pixel
    centres (output pixel i is centred on input coordinate c = (i + 0.5) n_in / n_out - 0.5).

    ``antialias`` (torch's ``antialias=True``): a triangle filter whose half-width is
    the shrink factor (1 when enlarging), taps outside the array dropped and the
    weights renormalised, so a shrink averages every input pixel it covers.
    Without it (torch's default): the two input pixels around c, c clamped to
    >= 0 and the second index to the array (a shrink skips pixels). Enlarging,
    the two agree."""
    scale = n_in / n_out
    centre = (np.arange(n_out, dtype=np.float64) + 0.5) * scale - 0.5
    m = np.zeros((n_out, n_in), np.float64)
    if antialias:
        support = max(scale, 1.0)
        j = np.arange(n_in, dtype=np.float64)
        m = np.maximum(0.0, 1.0 - np.abs(j[None, :] - centre[:, None]) / support)
        m /= np.maximum(m.sum(axis=1, keepdims=True), 1e-300)
    else:
        c = np.maximum(centre, 0.0)
        i0 = np.minimum(np.floor(c).astype(np.int64), n_in - 1)
        i1 = np.minimum(i0 + 1, n_in - 1)
        l1 = c - i0
        rows = np.arange(n_out)
        np.add.at(m, (rows, i0), 1.0 - l1)
        np.add.at(m, (rows, i1), l1)
    return m.astype(np.float32)


def _band_blocks(m: np.ndarray, block: int = 16):
    """(r0, r1, lo, hi) per block of ``block`` rows of a banded (n_out, n_in) matrix:
    rows r0..r1-1 have their nonzero weights in columns lo..hi-1."""
    out = []
    for r0 in range(0, m.shape[0], block):
        r1 = min(r0 + block, m.shape[0])
        nz = np.flatnonzero(m[r0:r1].any(axis=0))
        lo, hi = (int(nz[0]), int(nz[-1]) + 1) if nz.size else (0, 1)
        out.append((r0, r1, lo, hi))
    return out


def _rows(m: np.ndarray, a: np.ndarray) -> np.ndarray:
    """m @ a over a's second-last axis, (n_out, n_in) x (C, n_in, w) -> (C, n_out, w), each
    block of output rows from the input rows its band reaches (the other weights are 0)."""
    out = np.empty(a.shape[:-2] + (m.shape[0], a.shape[-1]), np.float32)
    for r0, r1, lo, hi in _band_blocks(m):
        out[..., r0:r1, :] = np.matmul(m[r0:r1, lo:hi], a[..., lo:hi, :])
    return out


def _cols(a: np.ndarray, m: np.ndarray) -> np.ndarray:
    """a @ m.T over a's last axis, (C, h, n_in) x (n_out, n_in).T -> (C, h, n_out), banded as ``_rows``."""
    out = np.empty(a.shape[:-1] + (m.shape[0],), np.float32)
    for r0, r1, lo, hi in _band_blocks(m):
        out[..., r0:r1] = np.matmul(a[..., lo:hi], m[r0:r1, lo:hi].T)
    return out


def resize_chw(a: np.ndarray, shape: tuple[int, int], antialias: bool = True) -> np.ndarray:
    """(C, h, w) float32 -> (C, H, W): bilinear, antialiased when shrinking if
    ``antialias`` (``bilinear_matrix``), rows and columns each a product with a
    banded matrix (in blocks of output pixels, each reading only the input pixels
    its weights reach). Equals torch's ``F.interpolate(a[None], size=shape,
    mode="bilinear", align_corners=False, antialias=antialias)[0]`` up to float
    rounding."""
    a = np.asarray(a, np.float32)
    C, h, w = a.shape
    H, W = (int(s) for s in shape)
    if (H, W) == (h, w):
        return a.copy()
    mr = bilinear_matrix(h, H, antialias)            # (H, h)
    mc = bilinear_matrix(w, W, antialias)            # (W, w)
    # the side that shrinks more goes first, so the second product works on fewer pixels
    if H * w <= h * W:
        return _cols(_rows(mr, a), mc)
    return _rows(mr, _cols(a, mc))


# ----------------------------------------------------------------------------- weights

def conv_matrix(weight: np.ndarray) -> np.ndarray:
    """A torch convolution weight (C_out, C_in, k, k) -> the (k k C_in, C_out) matrix
    ``conv3x3`` / ``conv1x1`` multiply by (rows ordered kernel row, kernel column, channel)."""
    co, ci, kh, kw = weight.shape
    return np.ascontiguousarray(np.transpose(weight, (2, 3, 1, 0)).reshape(kh * kw * ci, co))


def fold(weight, gamma, beta, mean, var, eps: float = BN_EPS):
    """A bias-free convolution followed by an eval-mode BatchNorm as one convolution:
    weight W gamma / s, bias beta - gamma mean / s, s = sqrt(var + eps); all float32,
    the arithmetic of ``learned_height.fold_batchnorm``. Returns (weight, bias)."""
    f = np.float32
    gamma, beta, mean, var = (np.asarray(v, f) for v in (gamma, beta, mean, var))
    scale = gamma / np.sqrt(var + f(eps))
    w = np.asarray(weight, f) * scale[:, None, None, None]
    b = beta + (np.zeros_like(mean) - mean) * scale
    return w.astype(f), b.astype(f)


def pt_digest(path) -> str:
    """sha256 (hex) of a file: the .npz records its checkpoint's, so a checkpoint
    retrained without a new export is noticed (``load_npz``)."""
    return hashlib.sha256(pathlib.Path(path).read_bytes()).hexdigest()


def write_npz(state: dict, config: dict | str, path, source_digest: str | None = None) -> pathlib.Path:
    """The numpy network's weight file from a checkpoint's state dict (``{name: array}``,
    the torch names of ``build_model``, ``num_batches_tracked`` left out), unchanged in
    value and dtype (the shipped checkpoint is float16: stored as float16, folded at
    load in float32, so the numpy forward uses exactly the weights torch's folded
    model uses, at float16's size), plus the config JSON and the checkpoint's digest."""
    arrays = {k: np.asarray(v) for k, v in state.items() if not k.endswith("num_batches_tracked")}
    cfg = config if isinstance(config, str) else json.dumps(config)
    arrays["__config__"] = np.array(cfg)
    arrays["__source_sha256__"] = np.array(source_digest or "")
    path = pathlib.Path(path)
    with open(path, "wb") as f:
        np.savez(f, **arrays)
    return path


def load_npz(path, check_against=None):
    """(arrays, config) of a ``write_npz`` file; ``check_against``: the checkpoint it was
    exported from, when that file exists: a different digest raises ValueError (the
    .pt was replaced without running the export)."""
    path = pathlib.Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
        cfg = json.loads(str(arrays.pop("__config__")))
    except FileNotFoundError:
        raise
    except Exception as e:  # noqa: BLE001 - numpy's own messages name no file (zip, pickle, EOF, JSON)
        raise ValueError(f"{path}: not the numpy network's weights ({type(e).__name__}: "
                         f"{str(e).split('.')[0]}): write them again with "
                         "`python -m pixgraph_lab.height.export --npz`") from None
    src = str(arrays.pop("__source_sha256__", ""))
    if check_against is not None and src and pathlib.Path(check_against).exists():
        if pt_digest(check_against) != src:
            raise ValueError(f"{path} was exported from another checkpoint than {check_against} "
                             f"(sha256 {src[:12]}...): run `python -m pixgraph_lab.height.export --npz`")
    return arrays, cfg


class HeightNet:
    """The folded U-Net of ``learned_height.build_model`` in numpy.

    ``arrays``: the checkpoint's state dict as numpy arrays (``load_npz``);
    ``config``: its ``base``, ``levels`` and ``outputs``. Calling it on (N, 6, S, S)
    float32 (S divisible by 2**levels) returns (N, S, S) (outputs 1: height / bh)
    or (N, outputs, S, S) (channel 0 the height / bh, then the error heads), as the
    torch model does."""

    def __init__(self, arrays: dict, config: dict):
        self.levels = int(config["levels"])
        self.outputs = int(config.get("outputs", 1))
        self.down = [self._block(arrays, f"down.{k}") for k in range(self.levels + 1)]
        self.up = [self._block(arrays, f"up.{k}") for k in range(self.levels)]
        self.head = (conv_matrix(np.asarray(arrays["head.weight"], np.float32)),
                     np.asarray(arrays["head.bias"], np.float32))
        self.n_params = sum(int(np.prod(v.shape)) for k, v in arrays.items())

    @staticmethod
    def _block(arrays, prefix):
        """Two (folded conv, bias) pairs: Sequential indices 0/1 and 3/4 (conv, BatchNorm)."""
        out = []
        for c, n in ((0, 1), (3, 4)):
            w, b = fold(arrays[f"{prefix}.{c}.weight"], arrays[f"{prefix}.{n}.weight"],
                        arrays[f"{prefix}.{n}.bias"], arrays[f"{prefix}.{n}.running_mean"],
                        arrays[f"{prefix}.{n}.running_var"])
            out.append((conv_matrix(w), b))
        return out

    @staticmethod
    def _run_block(x, block):
        for w, b in block:
            x = relu(conv3x3(x, w, b))
        return x

    def encode(self, x: np.ndarray) -> list[np.ndarray]:
        """(N, 6, S, S) inputs -> the down path's outputs, channels last: level k is
        (N, S / 2^k, S / 2^k, base 2^k) after its ReLU (the skips, and the bottleneck last)."""
        h = np.ascontiguousarray(np.moveaxis(np.asarray(x, np.float32), 1, 3))   # channels last
        skips = []
        for k, blk in enumerate(self.down):
            h = self._run_block(h if k == 0 else max_pool2(h), blk)
            skips.append(h)
        return skips

    def __call__(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, np.float32)
        heur = x[:, 4]
        skips = self.encode(x)
        h = skips.pop()
        for k in reversed(range(self.levels)):
            skip = skips.pop()
            N, H2, W2, cs = skip.shape
            cu = h.shape[3]
            cat = np.empty((N, H2, W2, cu + cs), np.float32)     # torch.cat([upsampled, skip], 1)
            upsample2(h, out=cat[..., :cu])
            cat[..., cu:] = skip
            h = self._run_block(cat, self.up[k])
        y = np.moveaxis(conv1x1(h, *self.head), 3, 1)            # (N, outputs, S, S)
        y0 = y[:, 0] + heur                                      # the residual over the heuristic channel
        if self.outputs == 1:
            return np.ascontiguousarray(y0)
        return np.concatenate([y0[:, None], y[:, 1:]], axis=1)


# ----------------------------------------------------------------------------- BLAS threads

_lock = threading.Lock()
_openblas = None          # (set, get) ctypes functions of numpy's OpenBLAS, False when not found


def _openblas_calls():
    """numpy's OpenBLAS thread calls (set, get), or None: a wheel's bundled OpenBLAS
    (numpy.libs / numpy/.dylibs) exports them with a scipy_openblas prefix and a 64 suffix."""
    global _openblas
    if _openblas is None:
        _openblas = False
        import numpy
        here = pathlib.Path(numpy.__file__).parent
        for lib in sorted(glob.glob(str(here.parent / "numpy.libs" / "*openblas*"))
                          + glob.glob(str(here / ".dylibs" / "*openblas*"))):
            try:
                dll = ctypes.CDLL(lib)
            except OSError:
                continue
            for pre, suf in (("scipy_openblas_", "64_"), ("scipy_openblas_", ""), ("openblas_", "64_"),
                             ("openblas_", "")):
                try:
                    s, g = getattr(dll, f"{pre}set_num_threads{suf}"), getattr(dll, f"{pre}get_num_threads{suf}")
                except AttributeError:
                    continue
                s.argtypes, s.restype, g.restype = [ctypes.c_int], None, ctypes.c_int
                _openblas = (s, g)
                break
            if _openblas:
                break
    return _openblas or None


_active = [0, 0, None]     # [blocks inside blas_threads now, the count before the first, threadpoolctl's limiter]


@contextlib.contextmanager
def blas_threads(n: int | None):
    """Run the block with at most ``n`` BLAS threads (None: leave as is): numpy's
    OpenBLAS through its own call (``_openblas_calls``), else threadpoolctl when it is
    importable, else nothing. The setting is process-wide: blocks that overlap (threads)
    share it, the first one in sets it and the last one out restores the count from
    before the first (also through threadpoolctl, whose own blocks each restore what
    they saw on entry: overlapping ones left the process at ``n`` for good)."""
    if not n:
        yield
        return
    calls = _openblas_calls()
    if calls is None:
        try:
            from threadpoolctl import threadpool_limits
        except ImportError:
            yield
            return

        def set_(k):
            _active[2] = threadpool_limits(limits=int(k), user_api="blas")
            _active[2].__enter__()

        def restore(_):
            lim, _active[2] = _active[2], None
            lim.__exit__(None, None, None)
        get = None
    else:
        set_, get = calls
        restore = set_
    with _lock:
        if _active[0] == 0:
            _active[1] = get() if get else None
            set_(int(n))
        elif get:
            set_(int(n))
        _active[0] += 1
    try:
        yield
    finally:
        with _lock:
            _active[0] -= 1
            if _active[0] == 0:
                restore(_active[1])


def blas_info() -> str:
    """What ``blas_threads`` acts on (for benchmark reports)."""
    c = _openblas_calls()
    if c:
        return f"numpy's OpenBLAS ({c[1]()} threads outside the predictor)"
    try:
        import threadpoolctl  # noqa: F401
        return "threadpoolctl"
    except ImportError:
        return "not controlled (numpy's BLAS is not a bundled OpenBLAS and threadpoolctl is missing)"
