"""A disk cache entry another user wrote is never read: its key and checksum are
computable by anyone (the graph, the params, the code's hash, the input files'
sha256), so a plausible forged entry (right key, right outputs, wrong pixels) planted
in a shared or world-writable cache folder was served as the node's result.
docs/security.md, "Caches"."""
import os

import numpy as np

from engine_testnodes import make_registry
from pixgraph.cache import pack_entry
from pixgraph.session import Session
from test_security_cache import _fresh_run, _two_entries


def test_an_entry_another_user_wrote_is_not_read(tmp_path, monkeypatch):
    disk, ga, gb, ka, kb = _two_entries(tmp_path)
    good = disk.get(kb)
    forged = {name: np.full_like(v, 42.0) if isinstance(v, np.ndarray) else type(v)(42) for name, v in good.items()}
    with open(disk.path(kb), "wb") as f:       # right key, checksum and outputs: only the pixels are wrong
        f.write(pack_entry(kb, forged))
    me = os.geteuid()
    monkeypatch.setattr(os, "geteuid", lambda: me + 1)      # the files are now another user's
    out, calls, logs, _ = _fresh_run(tmp_path, gb)
    np.testing.assert_array_equal(out, 6.0)                   # 3 * 2: recomputed, not 42
    assert calls == ["src", "sc"] and any("written by another user" in m for m in logs), (calls, logs)
    assert os.path.exists(disk.path(kb))                       # not ours to delete
    monkeypatch.setattr(os, "geteuid", lambda: me)
    out, calls, _, _ = _fresh_run(tmp_path, ga)
    assert calls == [] and np.all(out == 2.0)                  # our own entries are read as before


def test_records_another_user_wrote_are_not_read(tmp_path, monkeypatch):
    s = Session(registry=make_registry(), disk_cache=tmp_path / "disk")
    name = "last-run-" + "0" * 64
    s.disk.save_record(name, {"keys": {"a": "b"}})
    assert s.disk.load_record(name) == {"keys": {"a": "b"}}
    me = os.geteuid()
    monkeypatch.setattr(os, "geteuid", lambda: me + 1)
    assert s.disk.load_record(name) is None


def test_a_plan_does_not_count_on_entries_another_user_wrote(tmp_path, monkeypatch):
    """``pixgraph explain`` / ``Session.plan`` said 'disk' for an entry a run will not
    read, and left the nodes upstream of it out of the plan."""
    disk, ga, gb, ka, kb = _two_entries(tmp_path)
    s = Session(registry=make_registry(), disk_cache=tmp_path / "disk")
    assert [(st.node_id, st.status) for st in s.plan(gb).steps] == [("sc", "disk")]
    me = os.geteuid()
    monkeypatch.setattr(os, "geteuid", lambda: me + 1)
    assert kb not in s.disk
    assert sorted((st.node_id, st.status) for st in s.plan(gb).steps) == [("sc", "run"), ("src", "run")]
