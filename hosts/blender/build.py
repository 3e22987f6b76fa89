"""Build the installable add-on zip: python hosts/blender/build.py [-o DIR]

Writes DIR/pixgraph_blender-VERSION.zip (default DIR: dist/) with the folder
``pixgraph_blender/`` inside: Blender 4.2+ installs it as an extension
(blender_manifest.toml) and older ones as a legacy add-on (bl_info). pixgraph
itself is not bundled: it is installed into Blender's Python (docs/blender.md).
"""
from __future__ import annotations

import argparse
import pathlib
import tomllib
import zipfile

HERE = pathlib.Path(__file__).resolve().parent
SRC = HERE / "pixgraph_blender"


def build(out_dir: pathlib.Path) -> pathlib.Path:
    version = tomllib.loads((SRC / "blender_manifest.toml").read_text())["version"]
    out_dir.mkdir(parents=True, exist_ok=True)
    zpath = out_dir / f"pixgraph_blender-{version}.zip"
    with zipfile.ZipFile(zpath, "w", zipfile.ZIP_DEFLATED) as z:
        for f in sorted(SRC.rglob("*")):
            if f.is_file() and "__pycache__" not in f.parts and f.suffix != ".pyc":
                z.write(f, f"pixgraph_blender/{f.relative_to(SRC).as_posix()}")
    return zpath


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-o", "--out", default=str(HERE.parents[1] / "dist"), help="output folder (default dist/)")
    print(build(pathlib.Path(ap.parse_args(argv).out)))


if __name__ == "__main__":
    main()
