"""Input checks shared by the built-in nodes (not a node module: its name starts with _)."""
from __future__ import annotations

from pixgraph.node import InputError


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
