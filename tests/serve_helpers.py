"""Start a real ``pixgraph serve`` process on 127.0.0.1 for the API and browser tests."""
from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import sys
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
GRAPHS = os.path.join(REPO, "graphs")


def copy_scene(dest: str, graph: str = "wall_corner_shadow.yaml") -> str:
    """The example graph and the assets it uses, copied into ``dest``; returns the graph's path."""
    os.makedirs(os.path.join(dest, "assets"), exist_ok=True)
    for name in ("figure.png", "room_corner.jpg"):
        shutil.copy(os.path.join(GRAPHS, "assets", name), os.path.join(dest, "assets", name))
    shutil.copy(os.path.join(GRAPHS, graph), os.path.join(dest, graph))
    return os.path.join(dest, graph)


@contextlib.contextmanager
def running_server(graph: str, *args: str, timeout: float = 120.0):
    """``pixgraph serve GRAPH --port 0 ARGS`` in a subprocess; yields (base URL, process)."""
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONUNBUFFERED="1")
    proc = subprocess.Popen([sys.executable, "-m", "pixgraph", "serve", graph, "--port", "0", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        deadline = time.monotonic() + timeout
        line = proc.stdout.readline()
        if "http://" not in line:
            proc.kill()
            raise RuntimeError(f"pixgraph serve did not start: {line!r} {proc.stderr.read()[-2000:]}")
        url = line.split(" at ", 1)[1].strip().rstrip("/")
        assert time.monotonic() < deadline
        yield url, proc
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
