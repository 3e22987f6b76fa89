"""Server memory under many concurrent downloads of one output: the file is encoded
once and streamed in pieces, so 50 concurrent GETs of a 1024 x 1024 RGBA noise image
(a PNG that does not compress) cost at most twice what one GET costs.

Memory is the server process's peak resident set (``VmHWM``), reset before each
phase through ``/proc/PID/clear_refs``; glibc is told to give large blocks back
(``MALLOC_MMAP_THRESHOLD_``) so that one phase's freed memory cannot hide the next
one's. ``benchmarks/serve_bench.py --memory`` measures the 4096 x 4096 case."""
import asyncio
import sys

import httpx
import numpy as np
import pytest
from PIL import Image

from serve_helpers import start_server

GRAPH = """pixgraph: 1
nodes:
  img: {type: pixgraph.LoadImage, params: {path: a.png}}
outputs: {final: img.image}
"""


def _status(pid: int, field: str) -> int:
    """A ``/proc/PID/status`` field in bytes."""
    for line in open(f"/proc/{pid}/status"):
        if line.startswith(field + ":"):
            return int(line.split()[1]) * 1024
    raise KeyError(field)


def _reset_peak(pid: int) -> int:
    """Reset the peak RSS to the current one; returns the current RSS."""
    with open(f"/proc/{pid}/clear_refs", "w") as f:
        f.write("5")
    return _status(pid, "VmRSS")


async def _gets(url: str, path: str, n: int) -> list[int]:
    limits = httpx.Limits(max_connections=n, max_keepalive_connections=n)
    async with httpx.AsyncClient(base_url=url, timeout=300, limits=limits) as c:
        rs = await asyncio.gather(*[c.get(path) for _ in range(n)])
    return [len(r.content) for r in rs if r.status_code == 200]


def measure(url: str, pid: int, n: int, value_path: str) -> tuple[int, int]:
    """Run the graph on ``value_path``, then ``n`` concurrent GETs of its PNG: (peak RSS
    growth during the GETs [bytes], PNG size [bytes])."""
    run = httpx.post(url + "/api/run", json={"params": {"img.path": value_path}}, timeout=300).json()
    base = _reset_peak(pid)
    sizes = asyncio.run(_gets(url, run["outputs"]["final"]["png"], n))
    assert len(sizes) == n and len(set(sizes)) == 1
    return _status(pid, "VmHWM") - base, sizes[0]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_fifty_concurrent_output_gets_cost_at_most_twice_one(tmp_path):
    rng = np.random.default_rng(0)
    for name in ("a.png", "b.png"):
        Image.fromarray(rng.integers(0, 256, (1024, 1024, 4), dtype=np.uint8), "RGBA").save(tmp_path / name)
    (tmp_path / "g.yaml").write_text(GRAPH)
    env = {"MALLOC_MMAP_THRESHOLD_": str(128 << 10), "MALLOC_ARENA_MAX": "2"}
    with start_server(str(tmp_path / "g.yaml"), "--no-token", env=env) as (url, _, proc):
        one, size = measure(url, proc.pid, 1, "a.png")
        fifty, _ = measure(url, proc.pid, 50, "b.png")
    print(f"peak RSS growth: one GET {one / 2**20:.1f} MiB, 50 concurrent {fifty / 2**20:.1f} MiB "
          f"(ratio {fifty / one:.2f}); PNG {size / 2**20:.1f} MiB")
    assert size > 3 << 20                    # noise: 50 copies of the file would be > 150 MiB
    assert one > 8 << 20                     # one GET does measurable work (the encode)
    assert fifty <= 2 * one
