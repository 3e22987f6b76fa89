"""Make the pictures of docs/tutorial.md from the tutorial's own commands.

    python docs/img/make_tutorial_images.py      # from the repository root

Runs `pixgraph run` exactly as the tutorial shows (outputs under out/), then puts
pairs of results side by side, cropped to the shadow, with a caption on each.
"""
from __future__ import annotations

import os
import subprocess

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import OpenImageIO as oiio  # noqa: E402

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
GRAPH = "graphs/wall_corner_shadow.yaml"

#: output file -> the --set overrides of its command (the tutorial's commands)
RUNS = {
    "out/light_small.png": ["light.radius=0.05"],
    "out/light_large.png": ["light.radius=0.5", "shadow.samples=128"],
    "out/wrong_corner.png": ["bg_h.corner=[200,330]"],
    "out/wall_corner.png": [],
}

#: picture -> ((output file, caption), ...) and the crop (rows, columns)
PICTURES = {
    "docs/img/tutorial_light_size.png": (
        (("out/light_small.png", "--set light.radius=0.05"),
         ("out/light_large.png", "--set light.radius=0.5 --set shadow.samples=128")),
        (slice(140, 470), slice(150, 470))),
    "docs/img/tutorial_corner_handles.png": (
        (("out/wall_corner.png", "corner: [300, 300] (matches the photo)"),
         ("out/wrong_corner.png", "--set bg_h.corner=[200,330] (does not)")),
        (slice(140, 470), slice(150, 470))),
}


def read(path: str) -> np.ndarray:
    buf = oiio.ImageBuf(os.path.join(ROOT, path))
    if buf.has_error:
        raise RuntimeError(buf.geterror())
    return buf.get_pixels(oiio.FLOAT)[..., :3]


def main() -> None:
    for out, sets in RUNS.items():
        cmd = ["pixgraph", "run", "-q", GRAPH, *[a for s in sets for a in ("--set", s)], "-o", f"final={out}"]
        print(" ".join(cmd))
        subprocess.run(cmd, cwd=ROOT, check=True)
    for picture, (panels, (rows, cols)) in PICTURES.items():
        fig, axes = plt.subplots(1, len(panels), figsize=(3.0 * len(panels), 3.4), dpi=100)
        for ax, (path, caption) in zip(axes, panels):
            ax.imshow(np.clip(read(path)[rows, cols], 0, 1), interpolation="lanczos")
            ax.set_title(caption, fontsize=7.5, family="monospace")
            ax.axis("off")
        fig.tight_layout(pad=0.6)
        fig.savefig(os.path.join(ROOT, picture))
        plt.close(fig)
        print(f"{picture}: {os.path.getsize(os.path.join(ROOT, picture)) // 1024} KB")


if __name__ == "__main__":
    main()
