"""Disk cache: pickle-free round trips, restarts, atomic writes under SIGKILL, eviction."""
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from engine_testnodes import Pose, make_registry
from pixgraph.cache import MISS, DiskCache, Unstorable
from pixgraph.session import Session

TESTS = os.path.dirname(__file__)


def test_round_trip_of_supported_values(tmp_path):
    from pixgraph_nodes.ops.camera import Camera
    from pixgraph_nodes.ops.lights import disk_light

    d = DiskCache(tmp_path, 1 << 30)
    value = {"img": np.arange(12, dtype=np.float32).reshape(3, 4), "n": 3, "x": 0.5, "s": "hi", "none": None,
             "nan": float("nan"), "list": [1, (2.0, "b")], "flag": True, "np_scalar": np.float32(1.5),
             "cam": Camera(640, 480, hfov=50.0, horizon=100.0), "pose": Pose(1.0, 2.0, np.ones(3, np.float32)),
             "buffers": {"a": np.zeros((2, 2), np.float32)}, "light": disk_light((1.0, 2.0, 3.0), 0.5)}
    d.put("ab" * 32, value)
    back = d.get("ab" * 32)
    np.testing.assert_array_equal(back["img"], value["img"])
    assert back["n"] == 3 and back["x"] == 0.5 and back["s"] == "hi" and back["none"] is None
    assert np.isnan(back["nan"]) and back["list"] == [1, (2.0, "b")] and back["flag"] is True
    assert back["np_scalar"] == np.float32(1.5) and back["np_scalar"].dtype == np.float32
    assert back["cam"] == value["cam"] and back["cam"].focal == value["cam"].focal
    assert back["pose"].azimuth == 1.0 and np.array_equal(back["pose"].weights, np.ones(3))
    assert back["light"] == value["light"] and back["light"].radius == 0.5
    assert d.get("cd" * 32) is MISS


def test_unstorable_values_are_refused():
    d_arrays = {}
    from pixgraph.cache import encode
    with pytest.raises(Unstorable):
        encode({"f": lambda x: x}, d_arrays)
    with pytest.raises(Unstorable):
        encode(np.array([object()]), d_arrays)
    with pytest.raises(Unstorable):
        encode({1: 2}, d_arrays)


def test_unstorable_output_stays_memory_only_and_plan_says_so(tmp_path):
    s = Session(registry=make_registry(), disk_cache=tmp_path)
    b = s.builder()
    b.add("t.Opaque", "op")
    b.output("fn", "op.fn")
    g = b.build()
    events = []
    s.run(g, on_event=events.append)
    finished = [e for e in events if type(e).__name__ == "NodeFinished"]
    assert "memory only: value of type function" in finished[0].stored
    assert s.disk.stats()["entries"] == 0
    s.memory.clear()
    step = s.plan(g).steps[0]
    assert step.status == "run" and "memory only" in step.reason


def test_corrupt_entry_is_a_miss_and_removed(tmp_path):
    d = DiskCache(tmp_path, 1 << 30)
    key = "ef" * 32
    d.put(key, {"a": np.ones(3, np.float32)})
    with open(d.path(key), "r+b") as f:
        f.write(b"garbage!")
    assert d.get(key) is MISS and not os.path.exists(d.path(key))


def test_eviction_removes_least_recently_used_first(tmp_path):
    d = DiskCache(tmp_path, 1 << 30)
    keys = [f"{i:02d}" * 32 for i in range(4)]
    for i, k in enumerate(keys):
        d.put(k, {"a": np.zeros(1000, np.float32)})
        os.utime(d.path(k), (1000 + i, 1000 + i))  # distinct ages, oldest first
    one = d.stats()["bytes"] // 4
    assert d.get(keys[0]) is not MISS  # a read makes it the most recently used
    d.limit_bytes = int(2.5 * one)
    assert d.evict() == 2
    assert [k in d for k in keys] == [True, False, False, True]
    st = d.stats()
    assert st["entries"] == 2 and st["bytes"] <= d.limit_bytes
    # a put beyond the limit evicts on its own
    d.put("ff" * 32, {"a": np.zeros(1000, np.float32)})
    assert d.stats()["entries"] == 2 and ("ff" * 32) in d


RUN_GRAPH = textwrap.dedent("""
    import json, sys
    sys.path.insert(0, {tests!r})
    from engine_testnodes import make_registry
    from pixgraph.session import Session
    calls = []
    s = Session(registry=make_registry(calls), disk_cache={disk!r})
    b = s.builder()
    b.add("t.Source", "src", value=4.0, size=8)
    b.add("t.Scale", "sc", factor=2.0)
    b.connect("src.out", "sc.x")
    b.output("o", "sc.out")
    g = b.build()
    plan = s.plan(g)
    out = s.run(g)
    print(json.dumps({{"calls": calls, "status": [st.status for st in plan.steps], "value": float(out["o"][0, 0])}}))
""")


def _py(code: str, **env) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env={**os.environ, **env})


def test_disk_cache_survives_a_new_process(tmp_path):
    import json

    code = RUN_GRAPH.format(tests=TESTS, disk=str(tmp_path / "disk"))
    first = _py(code)
    assert first.returncode == 0, first.stderr
    assert json.loads(first.stdout) == {"calls": ["src", "sc"], "status": ["run", "run"], "value": 8.0}
    second = _py(code)
    assert second.returncode == 0, second.stderr
    assert json.loads(second.stdout) == {"calls": [], "status": ["disk"], "value": 8.0}


KILL_MID_WRITE = textwrap.dedent("""
    import os, signal, sys
    import numpy as np
    from pixgraph.cache import DiskCache

    def die(tmp, final):
        # the temporary file is complete and fsynced, but not yet renamed
        assert os.path.getsize(tmp) > 4_000_000
        os.kill(os.getpid(), signal.SIGKILL)

    d = DiskCache({disk!r}, 1 << 30)
    d.put("aa" * 32, {{"ok": np.ones(10, np.float32)}})
    d.before_commit = die
    d.put("bb" * 32, {{"big": np.ones((1024, 1024, 2), np.float32)}})
    print("not reached")
""")


def test_process_killed_while_writing_leaves_no_entry(tmp_path):
    disk = str(tmp_path / "disk")
    p = _py(KILL_MID_WRITE.format(disk=disk))
    assert p.returncode == -9 and "not reached" not in p.stdout
    leftovers = [f for _, _, files in os.walk(disk) for f in files]
    assert any(f.startswith(".tmp-") for f in leftovers)  # the half entry is only a temp file
    d = DiskCache(disk, 1 << 30)
    assert d.get("bb" * 32) is MISS and ("bb" * 32) not in d
    np.testing.assert_array_equal(d.get("aa" * 32)["ok"], np.ones(10, np.float32))
    assert d.stats()["entries"] == 1
    # temp files are swept once they are old enough that no live writer owns them
    d._sweep_temporaries(older_than_s=0.0)
    assert not any(f.startswith(".tmp-") for _, _, files in os.walk(disk) for f in files)
