"""Start a real ``pixgraph serve`` process on 127.0.0.1 for the API and browser tests."""
from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import sys
import time
from urllib.parse import parse_qs, urlsplit

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
GRAPHS = os.path.join(REPO, "graphs")
CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
#: how the browser tests start Debian's chromium (no background connections: the machine has no network)
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]


@contextlib.contextmanager
def chromium_browser(*extra_args: str):
    """Debian's chromium driven by Playwright, closed afterwards; under CI a missing
    chromium fails the test ('./setup.sh test' installs it), elsewhere it skips."""
    import pytest

    if not os.path.exists(CHROMIUM):
        if os.environ.get("CI"):
            pytest.fail("Debian's chromium is missing: './setup.sh test' installs it")
        pytest.skip("Debian's chromium is not installed ('./setup.sh test' installs it)")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=[*CHROMIUM_ARGS, *extra_args])
        try:
            yield b
        finally:
            b.close()


def copy_scene(dest: str, graph: str = "wall_corner_shadow.yaml") -> str:
    """The example graph and the assets it uses, copied into ``dest``; returns the graph's path."""
    os.makedirs(os.path.join(dest, "assets"), exist_ok=True)
    for name in ("figure.png", "room_corner.jpg"):
        shutil.copy(os.path.join(GRAPHS, "assets", name), os.path.join(dest, "assets", name))
    shutil.copy(os.path.join(GRAPHS, graph), os.path.join(dest, graph))
    return os.path.join(dest, graph)


@contextlib.contextmanager
def start_server(graph: str, *args: str, timeout: float = 120.0, env: dict | None = None):
    """``pixgraph serve GRAPH --port 0 ARGS`` in a subprocess; yields (base URL, token or
    None, process). The base URL has no ``?token=``."""
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONUNBUFFERED="1", **(env or {}))
    proc = subprocess.Popen([sys.executable, "-m", "pixgraph", "serve", graph, "--port", "0", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        deadline = time.monotonic() + timeout
        line = proc.stdout.readline()
        if "http://" not in line:
            proc.kill()
            raise RuntimeError(f"pixgraph serve did not start: {line!r} {proc.stderr.read()[-2000:]}")
        printed = urlsplit(line.split(" at ", 1)[1].strip())
        token = (parse_qs(printed.query).get("token") or [None])[0]
        assert time.monotonic() < deadline
        yield f"{printed.scheme}://{printed.netloc}", token, proc
    finally:
        if proc.poll() is None:
            proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


@contextlib.contextmanager
def running_server(graph: str, *args: str, timeout: float = 120.0):
    """``pixgraph serve GRAPH --port 0 --no-token ARGS``; yields (base URL, process).
    Without the token (for clients that do not carry it); the token is tested with
    ``start_server``."""
    with start_server(graph, "--no-token", *args, timeout=timeout) as (url, _, proc):
        yield url, proc
