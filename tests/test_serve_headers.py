"""A security header sent twice: each check reads one value, so a request carrying
``Sec-Fetch-Site`` (or ``Origin``, ``Host``, ``Content-Type``, ``Cookie``, the token
header) more than once is refused, naming the header (docs/server.md, "Safety").
Before, the last value counted: ``Sec-Fetch-Site: cross-site`` followed by
``same-origin`` passed."""
import httpx
import pytest

from pixgraph_serve.guard import Guard
from serve_helpers import copy_scene, start_server

TOKEN = "t0ken"


def _scope(headers, method="GET", path="/api/graph"):
    return {"type": "http", "method": method, "path": path, "query_string": b"",
            "headers": [(k.lower().encode(), v.encode()) for k, v in headers]}


@pytest.mark.parametrize("name, first, second", [
    ("Sec-Fetch-Site", "cross-site", "same-origin"),
    ("Sec-Fetch-Site", "same-origin", "same-origin"),
    ("Origin", "http://evil.example", "http://127.0.0.1:8765"),
    ("Host", "evil.example:8765", "127.0.0.1:8765"),
    ("X-Pixgraph-Token", "wrong", TOKEN),
    ("Content-Type", "text/plain", "application/json"),
    ("Cookie", "a=1", f"pixgraph_token_8765={TOKEN}"),
])
def test_a_security_header_twice_is_refused(name, first, second):
    guard = Guard(None, port=8765, token=TOKEN)
    base = [("Host", "127.0.0.1:8765"), ("X-Pixgraph-Token", TOKEN), ("Content-Type", "application/json")]
    once = [h for h in base if h[0] != name] + [(name, second)]
    assert guard.why_refused(_scope(once, "POST")) is None            # the last value alone passes
    twice = [h for h in base if h[0] != name] + [(name, first), (name, second)]
    status, msg = guard.why_refused(_scope(twice, "POST"))
    assert status == 400 and repr(name.lower()) in msg and "more than once" in msg


def test_other_headers_twice_pass():
    guard = Guard(None, port=8765, token=TOKEN)
    headers = [("Host", "127.0.0.1:8765"), ("X-Pixgraph-Token", TOKEN), ("Accept", "a"), ("Accept", "b")]
    assert guard.why_refused(_scope(headers)) is None


def test_a_real_server_refuses_a_repeated_sec_fetch_site(tmp_path):
    graph = copy_scene(str(tmp_path / "scene"))
    with start_server(graph) as (url, token, _):
        ok = [("X-Pixgraph-Token", token)]
        with httpx.Client(base_url=url, timeout=60) as c:
            assert c.get("/api/graph", headers=ok).status_code == 200
            for name, values in (("Sec-Fetch-Site", ("cross-site", "same-origin")),
                                 ("Origin", ("http://evil.example", url)),
                                 ("X-Pixgraph-Token", ("wrong", token))):
                headers = ok + [(name, v) for v in values] if name != "X-Pixgraph-Token" else \
                    [(name, v) for v in values]
                r = c.get("/api/graph", headers=headers)
                assert r.status_code == 400 and name.lower() in r.json()["error"], (name, r.text)
            assert c.get("/api/status", headers=ok).json()["refused"] == 3
