"""Numbers of ASCII digits too long for ``int()`` (Python refuses more than 4300 digits
with a ValueError) where a request carries them: refused, never a 500. The ASCII-only
checks (``'²'``: tests/test_serve_json_bombs.py) let these through."""
import httpx
import pytest

from pixgraph_serve.guard import Guard
from serve_helpers import copy_scene, running_server

LONG = "0" * 4300 + "8765"          # 8765 to the eye of a lax parser, 4304 digits to int()


def test_a_host_port_of_4304_digits_is_not_this_server():
    guard = Guard(None, port=8765, token=None)
    assert not guard.host_ok("127.0.0.1:" + LONG)
    assert not guard.host_ok("[::1]:" + LONG)
    status, msg = guard.why_refused({"type": "http", "method": "GET", "path": "/", "query_string": b"",
                                     "headers": [(b"host", ("127.0.0.1:" + LONG).encode())]})
    assert status == 403 and "not this server" in msg
    assert guard.host_ok("127.0.0.1:8765") and guard.host_ok("[::1]:8765")


@pytest.mark.parametrize("scale", ["9" * 4301, "0" * 4300 + "2"])
def test_a_scale_of_many_digits_is_400_not_500(tmp_path, scale):
    with running_server(copy_scene(str(tmp_path / "scene"))) as (url, _):
        r = httpx.get(url + "/api/outputs/final.png", params={"scale": scale}, timeout=120)
    assert r.status_code == 400 and r.json()["field"] == "scale", r.text[:300]
