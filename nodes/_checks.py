"""Input checks shared by the built-in nodes (not a node module: its name starts with _).

Every OpenCL node calls these before it launches anything: its kernels index
every buffer with one width and height, so sizes that do not fit would be read
outside a buffer, and impossible values would come back as NaN. Both are the
user's data, so both are ``InputError`` (exit 2) naming the input.
"""
from __future__ import annotations

import os
import weakref

import numpy as np

from pixgraph.node import InputError
from pixgraph_nodes.types import Shape
from .ops.memo import frozen


def same_size(camera=None, **arrays) -> tuple[int, int]:
    """The common (H, W) of the named arrays (and the camera's image size, if given).

    Raises ``InputError`` naming every input whose size differs, so the user
    learns which connection is wrong instead of an error deep inside a kernel.
    """
    sizes = {name: tuple(a.shape[:2]) for name, a in arrays.items() if a is not None}
    if camera is not None:
        sizes["camera"] = (camera.height, camera.width)
    distinct = set(sizes.values())
    if len(distinct) > 1:
        listing = ", ".join(f"{n} {w}x{h}" for n, (h, w) in sizes.items())
        raise InputError(f"inputs must have the same size (width x height): {listing}")
    return next(iter(distinct)) if distinct else (0, 0)


def source(path: str, node_id: str) -> str:
    """``"'cutout.png' (node 'cutout')"``: a file as errors name it (relative to the
    current folder when inside it)."""
    rel = os.path.relpath(path)
    return f"{path if rel.startswith('..') else rel!r} (node {node_id!r})"


def npy_finite(path, message: str) -> None:
    """Raise ``InputError(message)`` when an ``.npy`` file holds NaN or inf. The file
    is memory-mapped, not decoded, so ``validate`` finds it before anything runs;
    other formats are checked when they are read."""
    if str(path).lower().endswith(".npy"):
        a = np.load(path, mmap_mode="r", allow_pickle=False)
        if a.dtype.kind == "f" and not np.isfinite(a).all():
            raise InputError(message)


def file_shape(path: str, node_id: str) -> Shape:
    """The ``Shape`` of an image or ``.npy`` file from its header; an unreadable file
    is an ``InputError`` naming it."""
    from .ops.imageio import read_header

    try:
        h, w, c = read_header(path)
    except (OSError, ValueError) as e:
        raise InputError(f"cannot read {source(path, node_id)}: {str(e).splitlines()[0]}") from None
    return Shape(h, w, c, source(path, node_id))


def no_alpha(shape: Shape) -> str:
    """The message for a cutout without an alpha channel (an RGB file, e.g. a JPEG),
    wherever its coverage would be used (PlaceCutout's cutout, LoadImage's alpha)."""
    return (f"the cutout {shape.described()} has no alpha channel ({shape.channels} channels): "
            "use an RGBA image (PNG, EXR) or connect a mask (pixgraph.LoadMask)")


def rgba(**images) -> None:
    """Raise ``InputError`` unless each named image has 4 channels (colour + alpha)."""
    for name, a in images.items():
        if a is not None and (a.ndim != 3 or a.shape[2] != 4):
            got = "1 channel" if a.ndim == 2 else f"{a.shape[2]} channels"
            raise InputError(f"input {name!r} must be RGBA (4 channels, its alpha is the coverage), got {got}")


#: (check, id of a frozen array) -> weak reference to that array, for arrays that passed
_PASSED: dict[tuple[str, int], weakref.ref] = {}


def _passed(check: str, a) -> bool:
    """``a`` is a frozen array that already passed ``check``: a batch's later rows feed
    the same upstream arrays (a 20-megapixel photo, its heights) to every row's nodes,
    whose checks need not read them again."""
    ref = _PASSED.get((check, id(a)))
    return ref is not None and ref() is a and frozen(a)


def _remember(check: str, a) -> None:
    if isinstance(a, np.ndarray) and frozen(a):
        key = (check, id(a))
        _PASSED[key] = weakref.ref(a, lambda _, key=key: _PASSED.pop(key, None))


def finite(**arrays) -> None:
    """Raise ``InputError`` naming the first array that holds NaN or inf (colours,
    masks, layers: a NaN pixel would spread through every effect to the output).
    A frozen array that passed before is not read again."""
    for name, a in arrays.items():
        if a is None or _passed("finite", a):
            continue
        a = np.asarray(a)
        if a.size == 0 or np.isfinite(a.min()) and np.isfinite(a.max()):  # a NaN makes the minimum NaN
            _remember("finite", a)
            continue
        bad = ~np.isfinite(a)
        n = int(np.count_nonzero(bad))
        if n:
            i, j = np.unravel_index(int(np.argmax(bad.reshape(bad.shape[0], bad.shape[1], -1).any(-1))),
                                    bad.shape[:2])
            raise InputError(f"input {name!r}: {n} value(s) NaN or infinite (first at pixel u={j}, v={i})")
        _remember("finite", a)


def pixel_heights(where=None, **maps) -> None:
    """Raise ``InputError`` unless every named pixel-height map is finite and >= 0.

    A pixel height is a distance in pixels from a point to its foot on the
    ground: NaN, infinite or negative values (a point below the ground) are
    impossible and would make the tracers' results meaningless. ``where``: a
    boolean (H, W) of the pixels that matter (e.g. the cutout's mask: its height
    map is unused outside it), or a function that makes it, called only when a
    map is not valid everywhere (a 20 MP mask costs a full pass); default all. A
    frozen map that was valid everywhere before is not read again.
    """
    for name, h in maps.items():
        if h is None or _passed("pixel_heights", h):
            continue
        h = np.asarray(h)
        # two reductions, no full-size temporaries: a NaN makes the minimum NaN
        if h.size == 0 or (h.min() >= 0 and h.max() < np.inf):
            _remember("pixel_heights", h)  # valid everywhere: valid under any ``where``
            continue
        finite = np.isfinite(h)
        bad = ~finite | (np.where(finite, h, 0.0) < 0.0)
        if callable(where):
            where = where()
        if where is not None:
            bad &= where
        n = int(np.count_nonzero(bad))
        if n:
            i, j = np.unravel_index(int(np.argmax(bad)), bad.shape)
            kind = "NaN" if np.isnan(h[i, j]) else ("infinite" if not np.isfinite(h[i, j]) else "negative")
            raise InputError(f"input {name!r}: {n} pixel height(s) not finite or negative (first: {kind} "
                             f"at pixel u={j}, v={i}); pixel heights must be finite and >= 0 pixels")


def inside(mask) -> np.ndarray:
    """The pixels a mask covers (> 0.5), as the tracers decide."""
    return np.asarray(mask) > 0.5


def finite_outputs(**arrays) -> None:
    """Raise ``RuntimeError`` (a bug in the node, exit 1) when an output the node
    declares finite holds NaN or inf: never hand one on silently."""
    for name, a in arrays.items():
        a = np.asarray(a)
        if a.size == 0 or np.isfinite(a.min()) and np.isfinite(a.max()):   # two reductions, no temporary
            continue
        if not np.all(np.isfinite(a)):
            raise RuntimeError(f"output {name!r} holds {int(np.count_nonzero(~np.isfinite(a)))} "
                               "non-finite value(s) (a bug: please report it with the graph)")
