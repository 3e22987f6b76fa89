"""Make the assets of graphs/own_photo.yaml (run from anywhere):

    python graphs/assets/make_own_photo.py

What a user brings, made with our own tools (make_assets.py's renderers):

- ``own_photo.jpg``: a 640x480 "photo" of a plaster wall standing on an oak floor,
  the wall/floor junction slightly tilted, lit from the left; its camera is
  pixgraph's default (hfov 50, horizon row 120), so the user decides nothing about it.
- ``own_cutout.png``: a plain RGBA PNG of a standing figure at its own size
  (cropped to the figure plus a margin), straight alpha, sRGB: nothing else is given
  (no pixel height, no placement, not the photo's size).

Deterministic. ``JUNCTION`` is where the wall meets the floor in the photo: the
graph's ``bg_h.junction_points`` are the user's reading of it.

    python graphs/assets/make_own_photo.py --doc-image

also runs graphs/own_photo.yaml (as is, and placed further right, smaller and
mirrored) and writes docs/img/own_photo.jpg, the picture of docs/own-photo.md.
"""
from __future__ import annotations

import pathlib
import sys

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import make_assets as MA  # noqa: E402

from pixgraph_nodes.ops.imageio import write_image  # noqa: E402

CAMERA = dict(width=640, height=480, hfov=50.0, horizon=120.0, cam_height=1.0)
JUNCTION = [[0.0, 262.0], [640.0, 292.0]]          # (u, v) at the photo's left and right borders
SCENE = dict(kind="back_wall", junction_points=JUNCTION, light=(-35.0, 35.0))


def main() -> None:
    photo = MA.render_background("own_photo", SCENE, CAMERA)
    write_image(HERE / "own_photo.jpg", photo)
    fig = MA.make_figure(light_dir=(-0.6, 0.55, 0.58))
    a = fig[..., 3]
    rows, cols = np.nonzero(a > 0)
    m = 6
    crop = fig[rows.min() - m:rows.max() + 1 + m, cols.min() - m:cols.max() + 1 + m].copy()
    crop[..., :3] *= crop[..., 3:]                  # write_image takes premultiplied linear colour
    write_image(HERE / "own_cutout.png", crop)
    for name in ("own_photo.jpg", "own_cutout.png"):
        p = HERE / name
        print(f"{name}: {p.stat().st_size / 1024:.0f} KB")


def doc_image() -> None:
    from pixgraph.session import Session

    graph = HERE.parent / "own_photo.yaml"
    s = Session(disk_cache=None)
    a = s.run(graph)["final"]
    b = s.run(graph, params={"place.foot": [420, 330], "place.scale": 0.6, "place.flip": True})["final"]
    gap = np.ones((a.shape[0], 8, 3), np.float32)
    out = HERE.parents[1] / "docs" / "img" / "own_photo.jpg"
    write_image(out, np.ascontiguousarray(np.concatenate([a, gap, b], axis=1)[::2, ::2]))
    print(f"{out.name}: {out.stat().st_size / 1024:.0f} KB")


if __name__ == "__main__":
    main()
    if "--doc-image" in sys.argv[1:]:
        doc_image()
