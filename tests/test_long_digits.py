"""Numbers of ASCII digits too long for ``int()`` (Python refuses more than 4300 digits
with a ValueError) or for the C call they go to (``os.kill`` of a pid past a C long:
OverflowError), where a request or a planted file name carries them: refused or left
alone, never a 500 or a stopped batch. The ASCII-only checks (``'²'``:
tests/test_serve_json_bombs.py) let these through."""
import os

import httpx
import pytest

import pixgraph_batch.files as F
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


@pytest.mark.parametrize("pid", ["9" * 30, "9" * 11, str(2 ** 31)])
def test_a_planted_temporary_with_a_pid_past_any_process_is_left_alone(tmp_path, pid):
    """``.r03.tmp-999...-0a1b2c3d.png`` (a pid of 2^31 or more: none is, and os.kill
    raised OverflowError) planted in the output folder stopped every batch on it."""
    planted = tmp_path / f".r03.tmp-{pid}-0a1b2c3d.png"
    planted.write_bytes(b"x")
    assert F.remove_temporaries([str(tmp_path / "r03.png")]) == []
    assert planted.exists()
    dead = tmp_path / f".r03.tmp-{2 ** 22 + 12345}-0a1b2c3d.png"      # a pid no process has: removed
    dead.write_bytes(b"x")
    assert F.remove_temporaries([str(tmp_path / "r03.png")]) == [str(dead)]
    assert os.listdir(tmp_path) == [planted.name]
