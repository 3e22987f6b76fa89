"""Self-verifying caches: a swapped, bit-flipped, truncated or forged disk entry
(NaN pixels, another size) is discarded and recomputed (never served), a killed
writer's temporaries are swept, two processes writing at once keep the byte bound,
and a source file edited during a run never leaves a wrong result in the cache.
Whose folder: a folder without pixgraph's marker is refused and left untouched, and
pixgraph deletes only files it wrote. A full disk, a read-only folder or a folder in
an entry's place means "not cached", never a failed run."""
import contextlib
import hashlib
import json
import logging
import os
import shutil
import struct
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from engine_testnodes import make_registry
from pixgraph import events as E
from pixgraph.cache import MARKER, MISS, CacheError, CacheFolderError, DiskCache, pack_entry
from pixgraph.cli import main
from pixgraph.hashing import sha256_text
from pixgraph.session import Session

TESTS = os.path.dirname(__file__)


def _graph(s, value):
    b = s.builder()
    b.add("t.Source", "src", value=value, size=8)
    b.add("t.Scale", "sc", factor=2.0)
    b.connect("src.out", "sc.x")
    b.output("o", "sc.out")
    return b.build()


def _two_entries(tmp_path):
    """A disk cache holding the results of two graphs that differ in one param."""
    s = Session(registry=make_registry(), disk_cache=tmp_path / "disk")
    ga, gb = _graph(s, 1.0), _graph(s, 3.0)
    s.run(ga), s.run(gb)
    ka, kb = s.plan(ga).keys["sc"], s.plan(gb).keys["sc"]
    return s.disk, ga, gb, ka, kb


def _fresh_run(tmp_path, graph):
    calls, events = [], []
    s = Session(registry=make_registry(calls), disk_cache=tmp_path / "disk")
    out = s.run(graph, on_event=events.append)["o"]
    logs = [e.message for e in events if isinstance(e, E.NodeLog)]
    return out, calls, logs, s


def test_swapped_entry_is_discarded_and_recomputed(tmp_path):
    disk, ga, gb, ka, kb = _two_entries(tmp_path)
    with open(disk.path(ka), "rb") as f:
        a_bytes = f.read()
    with open(disk.path(kb), "wb") as f:  # b's file now holds a's (valid) entry
        f.write(a_bytes)
    out, calls, logs, s = _fresh_run(tmp_path, gb)
    np.testing.assert_array_equal(out, 6.0)  # 3 * 2, not a's 2.0
    assert calls == ["sc"]  # src still came from the disk cache
    assert any("discarded" in m and "another key" in m for m in logs)
    # the recomputed entry is good again, and a's entry was untouched
    assert _fresh_run(tmp_path, gb)[1] == [] and _fresh_run(tmp_path, ga)[1] == []


def test_forged_entry_with_the_right_key_but_wrong_outputs_is_discarded(tmp_path):
    disk, ga, gb, ka, kb = _two_entries(tmp_path)
    with open(disk.path(kb), "wb") as f:  # checksum and key are right: only its content is wrong
        f.write(pack_entry(kb, {"alpha": np.zeros(3, np.float32)}))
    out, calls, logs, _ = _fresh_run(tmp_path, gb)
    np.testing.assert_array_equal(out, 6.0)
    assert calls == ["sc"] and any("holds outputs ['alpha']" in m for m in logs)


@pytest.mark.parametrize("damage", ["bit_flip", "truncate", "empty", "garbage_header"])
def test_damaged_entry_is_discarded_and_recomputed(tmp_path, damage):
    disk, ga, gb, ka, kb = _two_entries(tmp_path)
    p = disk.path(kb)
    data = bytearray(open(p, "rb").read())
    if damage == "bit_flip":
        for i in (len(data) // 2, 20, len(data) - 40):  # payload, header, last array bytes
            data[i] ^= 0x04
            open(p, "wb").write(bytes(data))
            assert DiskCache(tmp_path / "disk", 1 << 30).get(kb) is MISS
            data[i] ^= 0x04
            open(p, "wb").write(bytes(data))
        data[len(data) // 2] ^= 0x01
    elif damage == "truncate":
        data = data[: len(data) // 2]
    elif damage == "empty":
        data = b""
    else:
        data[8:16] = (10 ** 12).to_bytes(8, "little")
    open(p, "wb").write(bytes(data))
    d = DiskCache(tmp_path / "disk", 1 << 30)
    assert d.get(kb) is MISS and not os.path.exists(p) and kb in d.discarded
    open(p, "wb").write(bytes(data))
    out, calls, logs, s = _fresh_run(tmp_path, gb)
    np.testing.assert_array_equal(out, 6.0)
    assert calls == ["sc"] and any("discarded" in m for m in logs)


def test_decoding_never_imports_or_builds_what_the_entry_names(tmp_path):
    d = DiskCache(tmp_path, 1 << 30)
    key = "ab" * 32
    assert "this" not in sys.modules  # importing it prints the Zen of Python
    os.makedirs(os.path.dirname(d.path(key)), exist_ok=True)
    for name in ("this:Anything", "os:system", "subprocess:Popen", "pixgraph.cache:DiskCache"):
        # a well-formed entry, right key and checksum, naming something to build
        header = json.dumps({"key": key, "value": {"__dataclass__": name, "fields": {}}, "arrays": {}}).encode()
        raw = b"PXGCACH1" + struct.pack("<Q", len(header)) + header
        open(d.path(key), "wb").write(raw + hashlib.sha256(raw).digest())
        assert d.get(key) is MISS, name
    assert "this" not in sys.modules
    # an object array cannot even be declared
    header = json.dumps({"key": key, "value": {"__array__": "a0"},
                         "arrays": {"a0": {"dtype": "|O", "shape": [1], "offset": 0, "nbytes": 8}}}).encode()
    raw = b"PXGCACH1" + struct.pack("<Q", len(header)) + header + bytes(8)
    open(d.path(key), "wb").write(raw + hashlib.sha256(raw).digest())
    assert d.get(key) is MISS and "not numeric" in d.discarded[key]


KILL_MID_WRITE = textwrap.dedent("""
    import os, signal
    import numpy as np
    from pixgraph.cache import DiskCache

    def die(tmp, final):
        os.kill(os.getpid(), signal.SIGKILL)

    d = DiskCache({disk!r}, 1 << 30, before_commit=die)
    d.put("bb" * 32, {{"big": np.ones((512, 512, 4), np.float32)}})
""")


def test_kill_9_mid_write_leaves_only_temporaries_which_are_swept(tmp_path):
    disk = str(tmp_path / "disk")
    for _ in range(3):
        p = subprocess.run([sys.executable, "-c", KILL_MID_WRITE.format(disk=disk)], capture_output=True)
        assert p.returncode == -9
    d = DiskCache(disk, 1 << 30)  # young temporaries: maybe a live writer's, kept
    temps = d.temporaries()
    assert len(temps) == 3 and d.get("bb" * 32) is MISS and d.stats()["entries"] == 0
    for t in temps:  # ten minutes later
        os.utime(t, (os.stat(t).st_atime - 601, os.stat(t).st_mtime - 601))
    d = DiskCache(disk, 1 << 30)
    assert d.temporaries() == [] and d.stats()["bytes"] == 0


WRITER = textwrap.dedent("""
    import json, os, sys
    import numpy as np
    from pixgraph.cache import DiskCache

    d = DiskCache({disk!r}, {limit})
    worst = 0
    for i in range({n}):
        key = "%02x" % (i % 256) + "%062x" % (i * 7919 + {seed})
        d.put(key, {{"a": np.full(25_000, i, np.float32)}})  # ~100 kB
        worst = max(worst, d.stats()["bytes"])
    print(json.dumps({{"worst": worst}}))
""")


def test_two_concurrent_writers_keep_the_bound(tmp_path):
    disk, limit, n = str(tmp_path / "disk"), 1_000_000, 60
    procs = [subprocess.Popen([sys.executable, "-c", WRITER.format(disk=disk, limit=limit, n=n, seed=seed)],
                              stdout=subprocess.PIPE, text=True) for seed in (1, 2)]
    outs = [json.loads(p.communicate(timeout=300)[0]) for p in procs]
    assert all(p.returncode == 0 for p in procs)
    d = DiskCache(disk, limit)
    st = d.stats()
    entry = 100_000 + 1_000  # one entry's bytes (array + header + checksum), upper bound
    # stated tolerance: committed bytes never exceed the limit once a put returns; a
    # scan made while another process is between its commit and its eviction may
    # see at most one more entry per writer
    assert st["bytes"] <= limit and st["temporaries"] == 0
    assert max(o["worst"] for o in outs) <= limit + entry
    assert st["entries"] >= 5  # eviction kept the newest, not nothing


def test_source_file_edited_during_the_run_is_not_cached(tmp_path):
    src = tmp_path / "data.bin"
    src.write_bytes(b"x" * 10)
    calls = []
    s = Session(registry=make_registry(calls), disk_cache=tmp_path / "disk", allow_paths=[tmp_path])
    b = s.builder(base_dir=str(tmp_path))
    b.add("t.FileLen", "len", path="data.bin")
    b.add("t.Scale", "sc", factor=1.0)
    b.connect("len.out", "sc.x")
    b.output("o", "sc.out")
    g = b.build()

    def edit_when_started(ev):  # after the plan hashed the 10-byte file, before it is read
        if isinstance(ev, E.NodeStarted) and ev.node_id == "len":
            src.write_bytes(b"y" * 25)
        logs.append(ev)

    logs = []
    out = s.run(g, on_event=edit_when_started)["o"]
    assert out[0, 0] == 25.0  # this run saw the new bytes...
    msgs = [e.message for e in logs if isinstance(e, E.NodeLog)]
    assert any("file changed during the run (params.path)" in m for m in msgs)
    assert any("an input was computed from a file that changed" in m for m in msgs)
    assert s.memory.stats()["entries"] == 0 and s.disk.stats()["entries"] == 0  # ...and cached none of it
    src.write_bytes(b"x" * 10)  # revert: the old key is right again, and must give the old value
    assert s.run(g)["o"][0, 0] == 10.0
    fresh = Session(registry=make_registry(), disk_cache=tmp_path / "disk", allow_paths=[tmp_path])
    assert fresh.run(g)["o"][0, 0] == 10.0
    src.write_bytes(b"z" * 25)
    assert fresh.run(g)["o"][0, 0] == 25.0


# -- whose folder: the marker, and deleting only what pixgraph wrote ----------------------

FIXTURES = os.path.join(TESTS, "fixtures")


def _plant_foreign(root):
    """The issue's probe: files of other programs in a folder used as a cache."""
    (root / "go" / "pkg" / "mod").mkdir(parents=True)
    (root / "go" / "pkg" / "mod" / "cache.txt").write_text("go module cache")
    (root / "v1").mkdir()
    np.savez(root / "v1" / "weights.npz", w=np.arange(4))
    (root / "docs").mkdir()
    (root / "docs" / ".tmp-draft.txt").write_text("a draft")


def _snapshot(root):
    """Every path under root (symlinks not followed) with its kind, bytes and mtime."""
    out = {}
    for d, dirs, files in os.walk(root):
        for n in dirs + files:
            p = os.path.join(d, n)
            st = os.lstat(p)
            body = open(p, "rb").read() if os.path.isfile(p) and not os.path.islink(p) else os.readlink(p) \
                if os.path.islink(p) else None
            out[os.path.relpath(p, root)] = (st.st_mode, st.st_mtime_ns, body)
    return out


def test_a_folder_without_the_marker_is_refused_and_left_untouched(tmp_path, capsys):
    root = tmp_path / "shared"
    _plant_foreign(root)
    old = time.time() - 3600  # old enough for any sweep of temporaries
    for d, _, files in os.walk(root):
        for n in files:
            os.utime(os.path.join(d, n), (old, old))
    before = _snapshot(root)
    with pytest.raises(CacheFolderError, match="is not pixgraph's") as e:
        Session(registry=make_registry(), disk_cache=root)
    assert MARKER in str(e.value) and "nothing in it was changed" in str(e.value)
    good = os.path.join(FIXTURES, "good", "format1.yaml")
    for argv in (["run", good, "-q", "--disk-cache", str(root)], ["explain", good, "--disk-cache", str(root)],
                 ["cache", "clear", "--disk-cache", str(root)], ["cache", "stats", "--disk-cache", str(root)]):
        code = main(argv, registry=make_registry())
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2 and len(err) == 1 and "is not pixgraph's" in err[0] and str(root) in err[0], (argv, err)
    assert _snapshot(root) == before  # 0 files written, deleted or touched


def test_clear_and_sweep_delete_only_what_pixgraph_wrote(tmp_path, capsys):
    root, outside = tmp_path / "cache", tmp_path / "outside"
    s = Session(registry=make_registry(), disk_cache=root)
    s.run(_graph(s, 1.0)), s.run(_graph(s, 2.0))
    s.disk.save_record("last-run-" + sha256_text("g.yaml"), {"n": 1})
    assert (root / MARKER).is_file() and s.disk.stats()["entries"] == 4
    assert (root / "records" / ("last-run-" + sha256_text("g.yaml") + ".json")).is_file()
    # others' files dropped into pixgraph's own folder, some named like pixgraph's
    _plant_foreign(root)
    hh = next(p.name for p in root.iterdir() if len(p.name) == 2 and p.is_dir())
    (root / hh / "notes.txt").write_text("mine")
    (root / hh / ".tmp-draft.txt").write_text("mine")
    (root / hh / ("ab" * 32 + ".pxc")).write_text("misfiled: wrong folder for its name")
    (root / "records" / "notes.json").write_text("{}")
    outside.mkdir()
    victim = outside / ("cd" * 32 + ".pxc")
    victim.write_bytes(b"not yours")
    os.symlink(outside, root / "cd")  # an entry folder that is a symlink out of the cache
    for d, _, files in os.walk(root):
        for n in files:
            os.utime(os.path.join(d, n), (time.time() - 3600,) * 2)
    ours = {os.path.relpath(p, root) for p, _, _ in s.disk.entries()}
    assert len(ours) == 4
    import stat as st_
    before = {k: v for k, v in _snapshot(root).items() if k not in ours and not k.startswith("records/last-run")
              and not st_.S_ISDIR(v[0])}  # files and symlinks (folders' mtimes change as entries go)
    DiskCache(root, 1 << 30, tmp_max_age_s=0.0)  # opening sweeps temporaries
    assert main(["cache", "clear", "--disk-cache", str(root)], registry=make_registry()) == 0
    assert "removed 4 entries" in capsys.readouterr().out
    after = _snapshot(root)
    assert not any(k in after for k in ours) and not any(k.startswith("records/last-run") for k in after)
    # everything that is not pixgraph's is still there, byte for byte and untouched
    assert {k: v for k, v in after.items() if k in before} == before
    assert victim.read_bytes() == b"not yours" and (root / "go" / "pkg" / "mod").is_dir()
    assert (root / MARKER).is_file()


def test_a_cache_from_before_the_marker_is_adopted_when_it_holds_only_pixgraphs_files(tmp_path):
    root = tmp_path / "old"
    s = Session(registry=make_registry(), disk_cache=root)
    g = _graph(s, 1.0)
    s.run(g)
    os.remove(root / MARKER)  # as an older pixgraph left it
    calls, _ = [], None
    s2 = Session(registry=make_registry(calls), disk_cache=root)
    np.testing.assert_array_equal(s2.run(g)["o"], 2.0)
    assert calls == [] and (root / MARKER).is_file()
    # a cache of the .npz format (before .pxc): entries, a killed writer's temporary, records
    legacy = tmp_path / "legacy"
    (legacy / "ab").mkdir(parents=True)
    np.savez(legacy / "ab" / ("ab" * 32 + ".npz"), a=np.zeros(2))
    (legacy / "ab" / (".tmp-" + "ab" * 32 + "-" + "0" * 32 + ".npz")).write_bytes(b"half")
    (legacy / "records").mkdir()
    (legacy / "records" / ("last-run-" + "1" * 64 + ".json")).write_text("{}")
    d = DiskCache(legacy, 1 << 30, tmp_max_age_s=0.0)
    assert d.owned and (legacy / MARKER).is_file() and os.listdir(legacy / "ab") == []
    (root / MARKER).write_text(json.dumps({"pixgraph_cache": 99}))
    with pytest.raises(CacheFolderError, match="version 99"):
        Session(registry=make_registry(), disk_cache=root)
    (root / MARKER).unlink()
    (root / "README.txt").write_text("someone else's")
    with pytest.raises(CacheFolderError, match="README.txt"):
        Session(registry=make_registry(), disk_cache=root)
    assert (root / "README.txt").read_text() == "someone else's"


# -- entries are checked against their node's outputs before they are served --------------

def test_forged_entry_with_nan_pixels_is_discarded(tmp_path):
    disk, ga, gb, ka, kb = _two_entries(tmp_path)
    nan = np.full((8, 8), 6.0, np.float32)
    nan[3, 4] = np.nan
    with open(disk.path(kb), "wb") as f:  # right key, right checksum, right names and types
        f.write(pack_entry(kb, {"out": nan, "mean": 6.0}))
    out, calls, logs, _ = _fresh_run(tmp_path, gb)
    np.testing.assert_array_equal(out, 6.0)
    assert calls == ["sc"] and any("1 NaN or infinite" in m for m in logs)


def test_forged_entry_of_the_wrong_size_is_discarded(tmp_path):
    from pixgraph_nodes.ops.imageio import write_image

    write_image(tmp_path / "in.png", np.full((20, 30, 4), 0.5, np.float32))
    s = Session(disk_cache=tmp_path / "disk")
    b = s.builder(base_dir=str(tmp_path))
    b.add("pixgraph.LoadImage", "load", path="in.png")
    b.output("img", "load.image")
    g = b.build()
    key = s.plan(g).keys["load"]
    os.makedirs(os.path.dirname(s.disk.path(key)), exist_ok=True)
    with open(s.disk.path(key), "wb") as f:  # a well-formed 10x10 LoadImage result under the right key
        f.write(pack_entry(key, {"image": np.zeros((10, 10, 4), np.float32), "alpha": np.zeros((10, 10), np.float32)}))
    events = []
    out = s.run(g, on_event=events.append)["img"]
    assert out.shape == (20, 30, 4) and abs(float(out[..., 3].mean()) - 0.5) < 0.01
    assert any(isinstance(e, E.NodeLog) and "is 10x10, but its inputs make it 30x20" in e.message for e in events)
    # and the forged entry is gone: a new process's session reads the file again
    # (LoadImage stays off the disk cache: disk_cache = False)
    fresh = Session(disk_cache=tmp_path / "disk")
    assert key not in fresh.disk
    assert fresh.run(g)["img"].shape == (20, 30, 4) and fresh.last_run.ran == ("load",)


# -- a write that fails means "not cached", never a failed run ----------------------------

@contextlib.contextmanager
def _tmpfs(path, size="1m"):
    path.mkdir()
    p = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)], capture_output=True)
    if p.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({p.stderr.decode().strip()[:80]})")
    try:
        yield path
    finally:
        subprocess.run(["umount", "-l", str(path)], check=False)


def _big_graph(s, value):
    b = s.builder()
    b.add("t.Source", "src", value=value, size=600)  # 600 x 600 float32: 1.44 MB, more than the 1 MiB disk
    b.output("o", "src.out")
    return b.build()


def _stored(events):
    return [e.stored for e in events if isinstance(e, E.NodeFinished)]


def test_a_full_disk_means_not_cached(tmp_path, caplog):
    with _tmpfs(tmp_path / "small") as mnt:
        s = Session(registry=make_registry(), disk_cache=mnt / "cache")
        caplog.set_level(logging.WARNING, logger="pixgraph.cache")
        for value in (1.0, 2.0, 3.0):
            events = []
            out = s.run(_big_graph(s, value), on_event=events.append)["o"]
            assert out.shape == (600, 600) and float(out[0, 0]) == value
            assert "not on disk: the disk is full" in _stored(events)[0]
        full = [r for r in caplog.records if "disk is full" in r.getMessage()]
        assert len(full) == 1  # a warning once, not once per result
        assert s.disk.temporaries() == [] and s.disk.stats()["entries"] == 0
        assert shutil.disk_usage(mnt).used < 64 << 10  # the half-written temporaries are gone
        small = _graph(s, 5.0)  # what fits is still cached
        s.run(small)
        assert s.disk.stats()["entries"] == 2


FSIZE_RUN = textwrap.dedent("""
    import resource, signal, sys
    sys.path.insert(0, {tests!r})
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)          # a write past the limit fails with EFBIG
    resource.setrlimit(resource.RLIMIT_FSIZE, (200_000, 200_000))
    from engine_testnodes import make_registry
    from pixgraph.session import Session
    s = Session(registry=make_registry(), disk_cache={disk!r})
    b = s.builder()
    b.add("t.Source", "src", value=7.0, size=600)
    b.output("o", "src.out")
    print(float(s.run(b.build())["o"].sum()), s.disk.stats()["entries"], s.disk.last_skip)
""")


def test_a_write_the_kernel_refuses_means_not_cached(tmp_path):
    """Without root (no tmpfs): a file-size limit makes the kernel refuse the write."""
    p = subprocess.run([sys.executable, "-c", FSIZE_RUN.format(tests=TESTS, disk=str(tmp_path / "c"))],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    total, entries, why = p.stdout.split(" ", 2)
    assert float(total) == 7.0 * 600 * 600 and entries == "0" and "disk is full" in why
    assert "disk is full" in p.stderr and p.stderr.count("disk is full") == 1


def test_a_read_only_folder_means_not_cached(tmp_path, caplog):
    caplog.set_level(logging.WARNING, logger="pixgraph.cache")
    with contextlib.ExitStack() as stack:
        if os.geteuid() == 0:  # root writes through permission bits: make the file system read-only
            mnt = stack.enter_context(_tmpfs(tmp_path / "ro", size="4m"))
        else:
            mnt = tmp_path / "ro"
            mnt.mkdir()
        cache = mnt / "cache"
        s = Session(registry=make_registry(), disk_cache=cache)
        g1 = _graph(s, 1.0)
        s.run(g1)
        if os.geteuid() == 0:
            subprocess.run(["mount", "-o", "remount,ro", str(mnt)], check=True)
        else:
            for d, dirs, _ in os.walk(cache):
                for x in [d] + [os.path.join(d, y) for y in dirs]:
                    os.chmod(x, 0o555)
            stack.callback(lambda: [os.chmod(os.path.join(d, y), 0o755) for d, dirs, _ in os.walk(cache)
                                    for y in dirs] and os.chmod(cache, 0o755))
        calls = []
        s2 = Session(registry=make_registry(calls), disk_cache=cache)
        np.testing.assert_array_equal(s2.run(g1)["o"], 2.0)  # reading still works
        assert calls == []
        for value in (3.0, 4.0):
            events = []
            np.testing.assert_array_equal(s2.run(_graph(s2, value), on_event=events.append)["o"], 2 * value)
            assert all("not on disk: the folder is read-only" in x for x in _stored(events))
        assert len([r for r in caplog.records if "read-only" in r.getMessage()]) == 1


def test_a_directory_in_an_entrys_place_means_not_cached(tmp_path, capsys):
    root = tmp_path / "disk"
    s = Session(registry=make_registry(), disk_cache=root)
    g = _graph(s, 1.0)
    keys = s.plan(g).keys
    for key in keys.values():  # someone's folder exactly where each entry goes
        os.makedirs(s.disk.path(key))
        (tmp_path / "disk" / key[:2] / (key + ".pxc") / "keep.txt").write_text("keep")
    for _ in range(2):
        events = []
        np.testing.assert_array_equal(s.run(g, on_event=events.append)["o"], 2.0)
        assert all("not on disk: something that is not a cache entry" in x for x in _stored(events))
        assert not any(isinstance(e, E.NodeLog) and "discarded" in e.message for e in events)
        s.memory.clear()
    for key in keys.values():
        assert (tmp_path / "disk" / key[:2] / (key + ".pxc") / "keep.txt").read_text() == "keep"
    # the command line: exit 0 and the result
    y = tmp_path / "g.yaml"
    y.write_text("pixgraph: 1\nnodes:\n  src: {type: t.Source, params: {value: 1.0, size: 8}}\n"
                 "  sc: {type: t.Scale, params: {factor: 2.0}, inputs: {x: src.out}}\noutputs: {o: sc.out}\n")
    assert main(["run", str(y), "-q", "--disk-cache", str(root)], registry=make_registry()) == 0
    warned = [line for line in capsys.readouterr().err.splitlines() if "pixgraph" in line or "disk" in line]
    assert len(warned) <= 1  # one warning for the run, not one per entry


def test_a_result_too_large_for_memory_is_not_cached(tmp_path, monkeypatch):
    import pixgraph.cache as C

    def no_memory(key, value):
        raise MemoryError()

    monkeypatch.setattr(C, "entry_parts", no_memory)
    s = Session(registry=make_registry(), disk_cache=tmp_path / "disk")
    events = []
    np.testing.assert_array_equal(s.run(_graph(s, 1.0), on_event=events.append)["o"], 2.0)
    assert all("too large for memory" in x for x in _stored(events))


def test_without_descriptor_calls_the_store_still_works(tmp_path, monkeypatch):
    """Platforms without ``*at`` calls (Windows) use paths, each step checked."""
    import pixgraph.paths as P

    monkeypatch.setattr(P, "AT_CALLS", False)
    disk, ga, gb, ka, kb = _two_entries(tmp_path)
    assert disk.get(ka)["out"][0, 0] == 2.0
    (tmp_path / "disk" / "zz").mkdir()
    (tmp_path / "disk" / "zz" / "keep.txt").write_text("x")
    os.symlink(tmp_path, tmp_path / "disk" / "ee")
    assert DiskCache(tmp_path / "disk", 1 << 30, tmp_max_age_s=0).clear() == 4
    assert (tmp_path / "disk" / "zz" / "keep.txt").read_text() == "x" and os.path.islink(tmp_path / "disk" / "ee")
    from pixgraph_nodes.ops.imageio import write_image
    p = P.WritePath(str(tmp_path / "w" / "a.png"), str(tmp_path / "w" / "a.png"))
    write_image(p, np.zeros((2, 2, 4), np.float32))
    assert sorted(os.listdir(tmp_path / "w")) == ["a.png"]


def test_a_first_run_is_quiet_and_uses_descriptors_on_linux(tmp_path, caplog):
    import pixgraph.paths as P

    if sys.platform.startswith("linux"):
        assert P.AT_CALLS  # the descriptor-relative code is the one these tests exercise here
    caplog.set_level(logging.WARNING, logger="pixgraph.cache")
    s = Session(registry=make_registry(), disk_cache=tmp_path / "disk")
    events = []
    s.run(_graph(s, 1.0), on_event=events.append)
    assert not [e for e in events if isinstance(e, E.NodeLog)] and not caplog.records
    assert s.disk.stats()["entries"] == 2 and "memory+disk" in _stored(events)[0]


def test_a_negative_cache_limit_is_bad_input(capsys):
    good = os.path.join(FIXTURES, "good", "format1.yaml")
    assert main(["run", good, "-q", "--no-disk-cache", "--cache-bytes", "-1"], registry=make_registry()) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--cache-bytes" in err[0] and "got -1" in err[0]
    with pytest.raises(CacheError, match="PIXGRAPH_DISK_CACHE_BYTES"):
        DiskCache("/nonexistent-never-made", -5)


BIG_RUN = textwrap.dedent("""
    import resource, sys
    from pixgraph.cli import main
    import pixgraph_nodes.constant  # noqa: F401 - imported before the limit
    side = 3000                      # a 3000 x 3000 RGBA float32 result: 144 MB
    vm = next(int(l.split()[1]) * 1024 for l in open("/proc/self/status") if l.startswith("VmSize"))
    resource.setrlimit(resource.RLIMIT_AS, (vm + side * side * 16 + (150 << 20),) * 2)
    g = {root!r} + "/g.yaml"
    open(g, "w").write("pixgraph: 1\\nnodes:\\n  c: {{type: pixgraph.Constant, params: {{width: 3000, height: 3000}}}}\\n"
                       "outputs: {{img: c.image}}\\n")
    sys.exit(main(["run", g, "-q", "--disk-cache", {root!r} + "/cache"]))
""")


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/status")
def test_a_large_result_is_cached_without_a_copy_of_it_in_memory(tmp_path):
    """The issue's 20000^2 Constant with a disk cache, scaled down: with room for the
    result plus 150 MB, the run succeeds and the entry is streamed to disk (packing it
    in memory needed two more copies and ended in an empty MemoryError, exit 1)."""
    p = subprocess.run([sys.executable, "-c", BIG_RUN.format(root=str(tmp_path))], capture_output=True, text=True,
                       timeout=300)
    assert p.returncode == 0, p.stderr
    d = DiskCache(tmp_path / "cache", 1 << 40)
    assert d.stats()["entries"] == 1 and d.stats()["bytes"] > 3000 * 3000 * 16
