"""Runs inside the server, in-process (the Starlette app over ASGI, no socket) with a
render the test controls: a ``t.Gate`` node that says when it has started and holds
until it is cancelled or released. No sleeps: the test waits on the gate's events."""
import asyncio
import threading

import httpx
import numpy as np
import pytest

from pixgraph_nodes import types as T
from pixgraph.node import node, param, port
from pixgraph.registry import Registry
from pixgraph_serve.app import create_app
from pixgraph_serve.state import Limits, ServeState

PORT = 8123
URL = f"http://127.0.0.1:{PORT}"
GRAPH = """pixgraph: 1
nodes:
  gate: {type: t.Gate, params: {hold: false, value: 0.5}}
outputs: {final: gate.image}
"""


class Gate:
    started = threading.Event()
    release = threading.Event()
    computed = 0


@node("t.Gate", version=1)
class GateNode:
    """A 64 x 48 grey image; with ``hold`` it sets ``Gate.started`` and waits for
    ``Gate.release`` or the run's cancellation."""

    class Params:
        hold: bool = param(False, doc="wait for the test's release")
        value: float = param(0.5, min=0.0, max=1.0, doc="grey level")

    class Outputs:
        image: T.Image = port(doc="grey image")

    impl_version = "1"

    def compute(self, ctx, inputs, params):
        Gate.computed += 1
        if params.hold:
            Gate.started.set()
            while not Gate.release.wait(0.005):
                ctx.check_cancelled()
        return {"image": np.full((48, 64, 3), params.value, np.float32)}


@pytest.fixture
def state(tmp_path):
    (tmp_path / "g.yaml").write_text(GRAPH)
    reg = Registry()
    reg.add(GateNode, source="test")
    Gate.started.clear()
    Gate.release.clear()
    return ServeState(str(tmp_path / "g.yaml"), registry=reg, limits=Limits(run_timeout=30))


def run(coro):
    return asyncio.run(coro)


async def _started():
    assert await asyncio.get_running_loop().run_in_executor(None, Gate.started.wait, 60)


def client(state):
    return httpx.AsyncClient(transport=httpx.ASGITransport(app=create_app(state, port=PORT)), base_url=URL,
                             timeout=60)


def test_a_running_render_is_cancelled_by_a_newer_one_of_its_client(state):
    async def main():
        async with client(state) as c:
            slow = asyncio.create_task(c.post("/api/render", json={"client": "p", "seq": 1, "params": {"gate.hold": True}}))
            await _started()
            assert (await c.get("/api/status")).json()["running"] == 1
            newer = await c.post("/api/render", json={"client": "p", "seq": 2, "params": {"gate.hold": False,
                                                                                          "gate.value": 0.25}})
            return await slow, newer, (await c.get("/api/status")).json()

    slow, newer, status = run(main())
    assert slow.status_code == 409 and "stale" in slow.json()["error"]
    assert newer.status_code == 200 and newer.headers["x-pixgraph-seq"] == "2"
    assert status["running"] == 0


def test_a_run_over_the_time_limit_is_stopped(state):
    state.limits = Limits(run_timeout=0.2)

    async def main():
        async with client(state) as c:
            return await c.post("/api/run", json={"params": {"gate.hold": True}})

    r = run(main())
    assert r.status_code == 503 and "limit of 0.2 s" in r.json()["error"]
    assert Gate.started.is_set() and not Gate.release.is_set()      # it was holding, and was cancelled


def test_shutdown_cancels_the_running_render_and_refuses_new_ones(state):
    async def main():
        async with client(state) as c:
            slow = asyncio.create_task(c.post("/api/run", json={"params": {"gate.hold": True}}))
            await _started()
            assert state.cancel_all() == 1
            r = await slow
            later = await c.post("/api/run", json={"params": {"gate.value": 0.75}})
            return r, later

    r, later = run(main())
    assert r.status_code == 503 and "shutting down" in r.json()["error"]
    assert later.status_code == 503


def test_concurrent_gets_of_one_run_encode_once_and_get_the_same_bytes(state):
    async def main():
        async with client(state) as c:
            a = (await c.post("/api/run", json={"params": {"gate.value": 0.25}})).json()
            b = (await c.post("/api/run", json={"params": {"gate.value": 0.75}})).json()
            before = (await c.get("/api/status")).json()["encoded"]
            got = await asyncio.gather(*[c.get(r["outputs"]["final"][fmt]) for r in (a, b)
                                         for fmt in ("png", "exr") for _ in range(10)])
            return got, (await c.get("/api/status")).json()["encoded"] - before

    got, encodes = run(main())
    assert all(r.status_code == 200 for r in got)
    assert encodes == 4                                    # 2 runs x 2 formats, for 40 requests
    groups = [got[i:i + 10] for i in range(0, 40, 10)]
    for g in groups:
        assert len({r.content for r in g}) == 1
    assert len({g[0].content for g in groups}) == 4
    from PIL import Image
    import io
    png_a = np.asarray(Image.open(io.BytesIO(groups[0][0].content)))
    png_b = np.asarray(Image.open(io.BytesIO(groups[2][0].content)))
    assert png_a.shape == (48, 64, 3) and png_a[0, 0, 0] == 137 and png_b[0, 0, 0] == 225   # sRGB of 0.25, 0.75


def test_in_process_app_without_a_port_skips_only_the_host_check(state):
    async def main():
        transport = httpx.ASGITransport(app=create_app(state))
        async with httpx.AsyncClient(transport=transport, base_url="http://testserver") as c:
            ok = await c.post("/api/params", json={"params": {"gate.value": 0.3}})
            foreign = await c.post("/api/params", json={}, headers={"Origin": "http://evil.example"})
            plain = await c.post("/api/params", content=b"{}", headers={"Content-Type": "text/plain"})
        async with client(state) as c:                      # with the port: the Host must name it
            wrong = await c.get("/api/graph", headers={"Host": "testserver"})
            other_port = await c.get("/api/graph", headers={"Host": f"127.0.0.1:{PORT + 1}"})
            right = await c.get("/api/graph", headers={"Host": f"localhost:{PORT}"})
        return ok, foreign, plain, wrong, other_port, right

    ok, foreign, plain, wrong, other_port, right = run(main())
    assert ok.status_code == 200 and foreign.status_code == 403 and plain.status_code == 415
    assert wrong.status_code == 403 and other_port.status_code == 403 and right.status_code == 200


def test_deadlines_cancel_only_runs_past_theirs():
    from pixgraph.events import CancelToken
    from pixgraph_serve.state import Deadlines

    d = Deadlines()
    first, removed, last, never = CancelToken(), CancelToken(), CancelToken(), CancelToken()
    e_first = d.add(first, 0.05)
    d.add(never, 3600)
    d.add(removed, 0.5)   # removed at once; a stall of well under 0.5 s cannot cancel it first
    d.remove(removed)
    e_last = d.add(last, 0.6)
    assert e_last.wait(30) and e_first.is_set()
    assert first.cancelled and last.cancelled and not removed.cancelled and not never.cancelled


def test_renders_remember_a_bounded_number_of_clients():
    from pixgraph.events import CancelToken
    from pixgraph_serve.runs import Renders
    r = Renders(max_clients=8)
    r.claim("busy", 1)
    r.tokens["busy"] = CancelToken()            # a client whose render is running
    for i in range(1000):                        # a script inventing a client id per request
        assert r.claim(f"c{i}", 1)
    assert len(r.latest) <= 9, len(r.latest)
    assert "busy" in r.latest and r.current("busy", 1)   # never forgotten while it renders
    assert not r.claim("c999", 1)                # the newest clients are remembered: a stale seq is refused
    assert r.claim("c0", 1)                      # a forgotten one starts again
