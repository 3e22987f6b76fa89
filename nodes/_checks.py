"""Input checks shared by the built-in nodes (not a node module: its name starts with _)."""
from __future__ import annotations

import os

from pixgraph.node import InputError
from pixgraph.types import Shape


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


def file_shape(path: str, node_id: str) -> Shape:
    """The ``Shape`` of an image or ``.npy`` file from its header; an unreadable file
    is an ``InputError`` naming it."""
    from .ops.imageio import read_header

    try:
        h, w, c = read_header(path)
    except (OSError, ValueError) as e:
        raise InputError(f"cannot read {source(path, node_id)}: {str(e).splitlines()[0]}") from None
    return Shape(h, w, c, source(path, node_id))
