"""A separate virtual environment with the real ``bpy`` wheel and pixgraph, for
testing the add-on headless: python hosts/blender/bpy_env.py [--print-python]

bpy 5.0.x runs on Python 3.11 and needs numpy < 2, so it cannot share the project's
environment. The venv lives in ``$PIXGRAPH_BPY_VENV`` or
``$XDG_CACHE_HOME/pixgraph-bpy-venv`` (``~/.cache`` without XDG_CACHE_HOME; beside, not inside, the disk cache folder, which pixgraph refuses to share with other files) and is
reused while its stamp (the requirements and pyproject.toml) is unchanged; pixgraph
is installed editable from this working tree, so code changes need no rebuild.
The first build downloads bpy (a few hundred MB); about 1.2 GB on disk.
"""
from __future__ import annotations

import hashlib
import os
import pathlib
import shutil
import subprocess
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[2]
REQUIREMENTS = ["bpy==5.0.*", "numpy<2"]
PYTHON = "3.11"


def venv_dir() -> pathlib.Path:
    if os.environ.get("PIXGRAPH_BPY_VENV"):
        return pathlib.Path(os.environ["PIXGRAPH_BPY_VENV"])
    cache = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return pathlib.Path(cache) / "pixgraph-bpy-venv"


def _stamp() -> str:
    h = hashlib.sha256("\n".join(REQUIREMENTS).encode())
    h.update((ROOT / "pyproject.toml").read_bytes())
    h.update(str(ROOT).encode())
    return h.hexdigest()


def _base_python() -> str:
    """A Python 3.11 interpreter to create the venv from."""
    if sys.version_info[:2] == (3, 11):
        return getattr(sys, "_base_executable", sys.executable)
    found = shutil.which(f"python{PYTHON}")
    if found is None:
        raise RuntimeError(f"bpy 5.0 needs Python {PYTHON}; none found (python{PYTHON} not on PATH)")
    return found


def ensure(log=print) -> pathlib.Path:
    """The venv's python, building or updating the venv when needed."""
    d = venv_dir()
    py = d / "bin" / "python"
    stamp_file = d / "pixgraph-stamp"
    stamp = _stamp()
    if py.exists() and stamp_file.exists() and stamp_file.read_text() == stamp:
        return py
    t0 = time.perf_counter()
    if not py.exists():
        log(f"bpy venv: creating {d}")
        subprocess.run([_base_python(), "-m", "venv", "--clear", str(d)], check=True)
    log(f"bpy venv: installing {' '.join(REQUIREMENTS)} and pixgraph (editable, {ROOT})")
    subprocess.run([str(py), "-m", "pip", "install", "-q", *REQUIREMENTS, "-e", str(ROOT)], check=True)
    stamp_file.write_text(stamp)
    log(f"bpy venv: ready in {time.perf_counter() - t0:.1f} s")
    return py


if __name__ == "__main__":
    python = ensure(log=lambda m: print(m, file=sys.stderr))
    if "--print-python" in sys.argv:
        print(python)
