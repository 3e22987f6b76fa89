"""Image files the server takes: their size from the header (no pixel decoded), for
``--max-pixels``, and uploads stored in the upload folder."""
from __future__ import annotations

import os
import secrets

from .errors import ServeError


def header_pixels(path: str, shown: str | None = None, strict: bool = True) -> int:
    """Width x height (x depth) of an image file from its header (no pixel decoded),
    or of a ``.npy`` array's first two dimensions; a ServeError 400 naming ``shown``
    (default the file's name) when it cannot be read, or 0 with ``strict=False``."""
    import OpenImageIO as oiio

    shown = shown or os.path.basename(path)
    if path.lower().endswith(".npy"):
        import numpy as np

        try:
            with open(path, "rb") as f:
                fmt = np.lib.format
                read = fmt.read_array_header_1_0 if fmt.read_magic(f) == (1, 0) else fmt.read_array_header_2_0
                shape = read(f)[0]
        except (OSError, ValueError):
            if strict:
                raise ServeError(400, f"cannot read array {shown}: not a .npy file") from None
            return 0
        return int(np.prod(shape[:2], dtype=object)) if len(shape) >= 2 else 0
    inp = oiio.ImageInput.open(path)
    if inp is None:
        why = oiio.geterror().replace(path, shown).replace(os.path.basename(path), shown)
        if not strict:
            return 0
        raise ServeError(400, f"cannot read image {shown}: {why}")
    spec = inp.spec()
    inp.close()
    return int(spec.width) * int(spec.height) * max(int(spec.depth), 1)


def store_upload(folder_path: str, name: str, raw: bytes, max_pixels: int) -> tuple[str, int]:
    """Write an uploaded image (``name`` already checked) into ``folder_path``, after
    checking its header against ``max_pixels``; returns (path, pixels).
    The bytes go to a temporary of their own (a random name with the image's
    extension, created with ``O_EXCL | O_NOFOLLOW``), checked, and renamed to
    ``name``: two uploads of one name at once never share a file, and a symlink in
    the folder is never written through."""
    from pixgraph.paths import Folder

    stem, ext = os.path.splitext(name)
    tmp = f".{stem}.tmp-{os.getpid()}-{secrets.token_hex(4)}{ext}"
    pixels = []

    def check(written):
        n = header_pixels(os.path.join(folder.path, written), shown=name)
        if n > max_pixels:
            raise ServeError(413, f"uploaded image of {n} pixels is over the server's limit of "
                                  f"{max_pixels} (pixgraph serve --max-pixels N raises it)")
        pixels.append(n)
    with Folder.at(folder_path) as folder:
        folder.write_replace(name, raw, tmp, 0o600, check)
    return os.path.join(folder_path, name), pixels[0]
