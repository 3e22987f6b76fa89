"""Batch safety (issue 23): hostile manifests and sweeps are exit 2 with one line, outputs
stay inside their folder, one batch per output folder, sidecars hash the bytes written,
workers die with their parent (kill -9 and Ctrl-C), temporaries never outlive a resume."""
import hashlib
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
import tracemalloc

import pytest

import pixgraph_batch.files as F
from pixgraph.cli import main
from pixgraph.session import Session
from pixgraph_batch import BatchError, batch
from test_batch import scene  # noqa: F401 - the fixture: a 64x64 photo, five cutouts, g.yaml

LINUX = sys.platform.startswith("linux")


def _err(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert "\n" not in err, err
    return err


# -- hostile sweeps and manifests: exit 2, one line, at once ------------------------------------


def test_huge_sweep_is_refused_before_expansion(scene, tmp_path, capsys):
    tracemalloc.start()
    try:
        rc = main(["batch", str(scene / "g.yaml"), "--no-disk-cache", "--sweep", "light.azimuth=0:1000000000000:1",
                   "-o", f"final={tmp_path}/{{row}}.png"])
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert rc == 2
    err = _err(capsys)
    assert "1e+12 values" in err and "limit of 100000 rows" in err and "--max-rows" in err
    assert peak < 20 << 20  # nothing was expanded (a list of 10^12 values would be terabytes)
    assert not os.listdir(tmp_path)


@pytest.mark.parametrize("values, why", [
    ("0:10:nan", "finite"), ("0:inf:1", "finite"), ("nan:10:1", "finite"), ("0:10:0", "empty"),
    ("10:0:1", "empty"), ("a:b:c", "must be numbers"), ("0:30:1", "30 values, over the limit of 20"),
])
def test_bad_range_sweeps_are_exit_2(scene, tmp_path, capsys, values, why):
    rc = main(["batch", str(scene / "g.yaml"), "--no-disk-cache", "--max-rows", "20",
               "--sweep", f"light.azimuth={values}", "-o", f"final={tmp_path}/{{row}}.png"])
    assert rc == 2
    err = _err(capsys)
    assert err.startswith(f"--sweep light.azimuth={values}: ") and why in err


def test_crossed_sizes_are_bounded_before_crossing(scene, tmp_path, capsys):
    rc = main(["batch", str(scene / "g.yaml"), "--no-disk-cache", "--max-rows", "50",
               "--sweep", "light.azimuth=0:10:1", "--sweep", "light.elevation=10:20:1",
               "-o", f"final={tmp_path}/{{row}}.png"])
    assert rc == 2 and _err(capsys) == "10 x 10 = 100 rows, over the limit of 50 rows per batch " \
                                       "(raise it with --max-rows)"


def test_yaml_aliases_are_refused(scene, tmp_path, capsys):
    """A billion-laughs manifest (361 bytes that expand to 10^9 rows with aliases)."""
    lines = ["a: &a [{light.azimuth: 1}, {light.azimuth: 2}, {light.azimuth: 3}]"]
    for k in "bcdefghi":
        prev = chr(ord(k) - 1)
        lines.append(f"{k}: &{k} [*{prev}, *{prev}, *{prev}, *{prev}, *{prev}, *{prev}, *{prev}, *{prev}, *{prev}]")
    lines.append("rows: *i")
    man = tmp_path / "laughs.yaml"
    man.write_text("\n".join(lines) + "\n")
    t0 = time.process_time()
    rc = main(["batch", str(scene / "g.yaml"), str(man), "--no-disk-cache", "-o", f"final={tmp_path}/o/{{row}}.png"])
    assert rc == 2
    assert _err(capsys) == f"{man}:1: YAML anchors and aliases (&name, *name) are not allowed in a manifest"
    assert time.process_time() - t0 < 30  # generous: refused while parsing, not after expanding
    assert not (tmp_path / "o").exists()


def test_manifest_bounds(scene, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)  # nothing may be written, but if it were: here
    man = tmp_path / "rows.csv"
    man.write_text("light.azimuth\n" + "".join(f"{i}\n" for i in range(30)))
    assert main(["batch", str(scene / "g.yaml"), str(man), "--max-rows", "29"]) == 2
    assert _err(capsys) == f"{man}: 30 rows, over the limit of 29 rows per batch (raise it with --max-rows)"
    assert main(["batch", str(scene / "g.yaml"), str(man), "--max-manifest-bytes", "50"]) == 2
    err = _err(capsys)
    assert err.startswith(f"{man}: manifest of {man.stat().st_size} bytes is over the limit of 50 bytes") \
        and "--max-manifest-bytes" in err
    bad = tmp_path / "bad.yaml"
    bad.write_text("- {light.azimuth: [1, 2}\n")
    assert main(["batch", str(scene / "g.yaml"), str(bad)]) == 2
    assert _err(capsys).startswith(f"{bad}:1: not valid YAML")
    deep = tmp_path / "deep.yaml"
    deep.write_text("[" * 100000)
    assert main(["batch", str(scene / "g.yaml"), str(deep)]) == 2
    assert str(deep) in _err(capsys)
    assert sorted(os.listdir(tmp_path)) == ["bad.yaml", "deep.yaml", "rows.csv"]


# -- outputs stay inside the folder the user named ---------------------------------------------


def test_row_ids_cannot_leave_the_output_folder(scene, tmp_path, capsys):
    man = tmp_path / "rows.csv"
    man.write_text("id,light.azimuth\nok,10\n../../outside/pwned,20\n")
    work = tmp_path / "work"
    work.mkdir()
    rc = main(["batch", str(scene / "g.yaml"), str(man), "--no-disk-cache", "-o", f"final={work}/out/{{row}}.png"])
    assert rc == 2
    err = _err(capsys)
    assert err.startswith(f"{man}:3: output final: ") and "is outside the output folder" in err
    assert sorted(os.listdir(tmp_path)) == ["rows.csv", "work"] and os.listdir(work) == []
    # a symlink inside the output folder does not lead out either
    (work / "out").mkdir()
    os.symlink(tmp_path, work / "out" / "up")
    man.write_text("id,light.azimuth\nup/escaped,20\n")
    assert main(["batch", str(scene / "g.yaml"), str(man), "-o", f"final={work}/out/{{row}}.png"]) == 2
    assert "is outside the output folder" in _err(capsys)
    assert not (tmp_path / "escaped.png").exists()


def test_duplicate_outputs_through_a_symlinked_folder(scene, tmp_path, capsys):
    (tmp_path / "out").mkdir()
    os.symlink(tmp_path / "out", tmp_path / "alias")
    rc = main(["batch", str(scene / "g.yaml"), "--sweep", "light.azimuth=10,20", "--no-disk-cache",
               "-o", f"final={tmp_path}/out/{{row}}.png", "-o", f"shadow={tmp_path}/alias/{{row}}.png"])
    assert rc == 2
    assert _err(capsys) == f"row 0000 output final and row 0000 output shadow both write " \
                           f"{tmp_path}/out/0000.png: put {{row}} or {{stem}} in each output template"
    assert os.listdir(tmp_path / "out") == []


@pytest.mark.skipif(not LINUX, reason="descriptor-relative renames (*at calls)")
def test_a_folder_swapped_for_a_symlink_mid_write_redirects_nothing(scene, tmp_path, monkeypatch):
    """The output folder is replaced by a symlink to another folder while a row's image
    is in its temporary: the hash and the rename happen in the folder the batch opened,
    so nothing reaches the other folder."""
    out, moved, elsewhere = tmp_path / "out", tmp_path / "moved", tmp_path / "elsewhere"
    elsewhere.mkdir()
    real = Session.write_output

    def swap(self, graph, name, value, path):
        written = real(self, graph, name, value, path)
        if not moved.exists():
            os.rename(out, moved)
            os.symlink(elsewhere, out)
        return written

    monkeypatch.setattr(Session, "write_output", swap)
    res = batch(Session(), scene / "g.yaml", sweeps=[("light.azimuth", [10])], outputs={"final": str(out / "a.png")})
    assert os.listdir(elsewhere) == []
    assert res.count("done") + res.count("failed") == 1
    assert "a.png" in os.listdir(moved)  # renamed where it was being written


def test_a_folder_swapped_for_a_symlink_before_the_write_receives_nothing(scene, tmp_path, monkeypatch):
    """The output folder is replaced by a symlink to another folder after the batch
    opened it and before the row's image is written: the image's temporary goes
    nowhere (the row fails, saying so), never in the other folder. Before, the
    temporary was written by its path, through the symlink: a ``.a.tmp-PID-XXXX.png``
    was left in the other folder (and the row failed)."""
    out, moved, elsewhere = tmp_path / "out", tmp_path / "moved", tmp_path / "elsewhere"
    elsewhere.mkdir()
    real = Session.write_output

    def swap(self, graph, name, value, path):
        if not moved.exists():
            os.rename(out, moved)
            os.symlink(elsewhere, out)
        return real(self, graph, name, value, path)

    monkeypatch.setattr(Session, "write_output", swap)
    res = batch(Session(), scene / "g.yaml", sweeps=[("light.azimuth", [10])], outputs={"final": str(out / "a.png")})
    assert os.listdir(elsewhere) == []
    assert res.count("failed") == 1 and "nothing was written" in res.results[0].error


# -- one batch per output folder ----------------------------------------------------------------


def test_second_batch_on_a_folder_refuses_naming_the_other(scene, tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["batch", str(scene / "g.yaml"), "--sweep", "light.azimuth=10,20", "--no-disk-cache",
            "-o", f"final={out}/{{row}}.png"]
    with F.FolderLock([str(out)]):
        assert (out / F.LOCK_NAME).read_text().split()[0] == str(os.getpid())
        assert main(argv) == 2
        assert _err(capsys) == f"output folder {out} is in use by another batch (pid {os.getpid()} on " \
                               f"{socket.gethostname()}): wait for it to finish or write elsewhere " \
                               f"(--wait-lock waits)"
        assert main(argv + ["--wait-lock", "0.3"]) == 2
        assert os.listdir(out) == [F.LOCK_NAME]
    assert main(argv) == 0
    assert sorted(os.listdir(out)) == ["0000.png", "0000.png.json", "0001.png", "0001.png.json"]  # lock gone


AZ = {"a": [-40, -20, 0, 20], "b": [-35, -15, 5, 25]}


@pytest.fixture(scope="module")
def references(scene, tmp_path_factory):
    """sha256 of the PNG each azimuth renders to, from single in-process runs."""
    d = tmp_path_factory.mktemp("refs")
    res = batch(Session(), scene / "g.yaml", sweeps=[("light.azimuth", AZ["a"] + AZ["b"])],
                outputs={"final": str(d / "{light_azimuth}.png")})
    assert res.count("done") == 8
    return {int(p.stem): hashlib.sha256(p.read_bytes()).hexdigest() for p in d.glob("*.png")}


def _wrong_provenance(out, references) -> int:
    """Files whose sidecar says done (its hash is the file's) but names other params than the image's."""
    wrong = 0
    for p in out.glob("*.png"):
        meta = json.loads((out / (p.name + ".json")).read_text())
        digest = hashlib.sha256(p.read_bytes()).hexdigest()
        if meta["file_sha256"] == digest and references[meta["params"]["light.azimuth"]] != digest:
            wrong += 1
    return wrong


def _two_batches(scene, out, wait):
    """Two batches at once on one folder, in two threads (each with its own session and
    its own open lock file: flock locks conflict between them as between processes)."""
    results = {}

    def one(name):
        try:
            results[name] = batch(Session(), scene / "g.yaml", sweeps=[("light.azimuth", AZ[name])],
                                  outputs={"final": str(out / "{index}.png")}, wait_lock=wait)
        except BatchError as e:
            results[name] = e

    threads = [threading.Thread(target=one, args=(n,)) for n in AZ]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return results


def _concurrent_rounds(scene, tmp_path, references, rounds):
    wrong = refused = 0
    for k in range(rounds):
        out = tmp_path / f"round{k}"
        wait = None if k % 2 == 0 else 0.0  # even rounds wait for the other batch, odd ones refuse
        results = _two_batches(scene, out, wait)
        ran = [r for r in results.values() if not isinstance(r, BatchError)]
        refused += len(results) - len(ran)
        assert all(r.count("failed") == 0 for r in ran)
        assert len(ran) == 2 if wait is None else len(ran) >= 1
        for e in results.values():
            if isinstance(e, BatchError):
                assert "is in use by another batch" in str(e)
        wrong += _wrong_provenance(out, references)
        assert sorted(os.listdir(out)) == sorted(f"{i}.png{e}" for i in range(4) for e in ("", ".json"))
    assert wrong == 0
    return refused


def test_two_concurrent_batches_on_one_folder(scene, tmp_path, references):
    _concurrent_rounds(scene, tmp_path, references, rounds=4)


@pytest.mark.slow  # 100 rounds of two batches (about 2-4 minutes on 2 cores)
def test_two_concurrent_batches_100_rounds(scene, tmp_path, references):
    refused = _concurrent_rounds(scene, tmp_path, references, rounds=100)
    print(f"100 rounds: 0 wrong provenance, {refused} batches refused by the lock")


@pytest.mark.slow  # 100 rounds of two `pixgraph batch` processes (about 10 minutes on a loaded 2-core machine)
def test_two_concurrent_batch_processes_100_rounds(scene, tmp_path, references):
    """The same with two real processes per round, started together through the CLI."""
    wrong = refused = 0
    env = dict(os.environ, OMP_NUM_THREADS="1")
    for k in range(100):
        out = tmp_path / f"round{k}"
        wait = ["--wait-lock", "-1"] if k % 2 == 0 else []
        procs = [subprocess.Popen([sys.executable, "-m", "pixgraph", "batch", str(scene / "g.yaml"), "-q",
                                   "--no-disk-cache", "--sweep", "light.azimuth=" + ",".join(map(str, AZ[n])),
                                   "-o", f"final={out}/{{index}}.png", *wait], env=env,
                                  stderr=subprocess.PIPE, text=True) for n in AZ]
        codes = [(p.wait(timeout=300), p.stderr.read()) for p in procs]
        for rc, err in codes:
            assert rc == 0 or (rc == 2 and not wait and "is in use by another batch" in err), err
        refused += sum(rc == 2 for rc, _ in codes)
        wrong += _wrong_provenance(out, references)
        assert sorted(os.listdir(out)) == sorted(f"{i}.png{e}" for i in range(4) for e in ("", ".json"))
    print(f"100 rounds of two processes: {wrong} wrong provenance, {refused} batches refused by the lock")
    assert wrong == 0


def test_sidecar_hashes_the_bytes_written(scene, tmp_path, references, monkeypatch):
    """Another writer replaces an image between its rename and its sidecar: the sidecar
    still records what this batch wrote, so the file no longer matches it and a resume
    renders that row again instead of trusting the foreign bytes."""
    out = tmp_path / "out"
    import pixgraph_batch.work as W

    real = W.write_json_atomic
    foreign = (scene / "photo.png").read_bytes()

    def meddle(path, data, folder=None):
        if path.endswith("/1.png.json"):
            (out / "1.png").write_bytes(foreign)
        real(path, data, folder)

    monkeypatch.setattr(W, "write_json_atomic", meddle)
    kw = dict(sweeps=[("light.azimuth", AZ["a"])], outputs={"final": str(out / "{index}.png")})
    assert batch(Session(), scene / "g.yaml", **kw).count("done") == 4
    meta = json.loads((out / "1.png.json").read_text())
    assert meta["file_sha256"] == references[AZ["a"][1]] != hashlib.sha256(foreign).hexdigest()
    monkeypatch.setattr(W, "write_json_atomic", real)
    again = batch(Session(), scene / "g.yaml", **kw)
    assert [r.status for r in again.results] == ["skipped", "done", "skipped", "skipped"]
    assert hashlib.sha256((out / "1.png").read_bytes()).hexdigest() == references[AZ["a"][1]]
    assert _wrong_provenance(out, references) == 0


# -- temporaries -----------------------------------------------------------------------------------


def test_leftover_temporaries_of_dead_writers_are_removed(tmp_path):
    dead = 2 ** 22 + 12345  # above the default pid_max
    names = {f".r03.tmp-{dead}-0a1b2c3d.png": True,          # a batch's temporary
             f"..r03.tmp-{dead}-0a1b2c3d.tmp-{dead}.png": True,  # the image writer's, inside it
             f".r03.png.json.tmp-{dead}-99aa88bb.tmp": True,  # a sidecar's
             f".r03.tmp-{dead}.png": True,                    # `pixgraph run`'s writer
             f".r03.tmp-{os.getpid()}-0a1b2c3d.png": False,   # a live writer's: kept
             f".other.tmp-{dead}.png": False,                 # not an output of this batch
             "r03.png": False, ".r03.tmp-notes.png": False}
    for n in names:
        (tmp_path / n).write_bytes(b"x")
    removed = F.remove_temporaries([str(tmp_path / "r03.png")])
    assert sorted(os.path.basename(p) for p in removed) == sorted(n for n, gone in names.items() if gone)
    assert sorted(os.listdir(tmp_path)) == sorted(n for n, gone in names.items() if not gone)


KILL_MID_WRITE = """
import os, signal, sys
from pixgraph.session import Session
from pixgraph_batch import batch
graph, manifest, out = sys.argv[1:4]
done = []
real = Session.write_output
def write_output(self, graph, name, value, path):
    written = real(self, graph, name, value, path)
    if len(done) == 3:  # row 4's image is in its temporary file: die before the rename
        os.kill(os.getpid(), signal.SIGKILL)
    return written
Session.write_output = write_output
batch(Session(), graph, manifest, outputs={"final": out + "/{row}.png"}, on_result=done.append)
"""


def test_resume_after_kill_mid_write(scene, tmp_path):
    """kill -9 while the fourth row's image is half-way (in its temporary): the rerun
    skips the three rows done, removes the temporary and renders the rest."""
    from test_batch import _manifest

    man = _manifest(scene / f"{tmp_path.name}.csv", 8)
    out = tmp_path / "out"
    script = tmp_path / "kill.py"
    script.write_text(KILL_MID_WRITE)
    env = dict(os.environ, OMP_NUM_THREADS="1")
    r = subprocess.run([sys.executable, str(script), str(scene / "g.yaml"), str(man), str(out)], env=env,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == -signal.SIGKILL, r.stderr
    left = sorted(os.listdir(out))
    done = sorted(n[:-len(".png.json")] for n in left if n.endswith(".png.json"))
    assert len(done) == 3
    temps = [n for n in left if ".tmp-" in n]
    assert len(temps) == 1 and temps[0].startswith(".r0") and temps[0][1:4] not in done, left  # e.g. .r03.tmp-*
    assert sorted(n for n in left if ".tmp-" not in n) == sorted(
        [f"{d}.png{e}" for d in done for e in ("", ".json")] + [F.LOCK_NAME])
    mtimes = {n: os.stat(out / n).st_mtime_ns for n in left if n.endswith(".png") and ".tmp-" not in n}
    cmd = [sys.executable, "-m", "pixgraph", "batch", str(scene / "g.yaml"), str(man), "--no-disk-cache",
           "-o", f"final={out}/{{row}}.png", "--report", str(tmp_path / "r.json")]
    r = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    summary = json.loads((tmp_path / "r.json").read_text())["summary"]
    assert (summary["skipped"], summary["done"]) == (3, 5)
    assert sorted(os.listdir(out)) == sorted(f"r0{i}.png{e}" for i in range(8) for e in ("", ".json"))
    assert {n: os.stat(out / n).st_mtime_ns for n in mtimes} == mtimes  # not rewritten


# -- workers die with their parent -------------------------------------------------------------------


def _children(pid: int) -> set[int]:
    """Descendants of ``pid`` (Linux /proc)."""
    kids: dict[int, list[int]] = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as f:
                    ppid = int(f.read().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            kids.setdefault(ppid, []).append(int(d))
    out, stack = set(), [pid]
    while stack:
        for c in kids.get(stack.pop(), []):
            out.add(c)
            stack.append(c)
    return out


def _alive(pids) -> set[int]:
    alive = set()
    for p in pids:
        try:
            with open(f"/proc/{p}/stat") as f:
                if f.read().rsplit(")", 1)[1].split()[0] != "Z":
                    alive.add(p)
        except OSError:
            pass
    return alive


def _poll(cond, timeout: float, what: str):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = cond()
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


POOL_PARENT = """
import sys, threading
from pixgraph.session import Session
from pixgraph_batch import batch
graph, out = sys.argv[1:3]
def on_result(r):
    open(out + ".first", "w").close()
    threading.Event().wait()  # the parent stops here; its workers go on until it is killed
batch(Session(), graph, sweeps=["light.azimuth=-170:170:5"], outputs={"final": out + "/{row}.png"},
      executor="processes", workers=2, on_result=on_result)
"""


@pytest.mark.skipif(not LINUX, reason="reads /proc to find the workers")
def test_pool_workers_die_with_a_killed_parent(scene, tmp_path):
    script = tmp_path / "parent.py"
    script.write_text(POOL_PARENT)
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, str(script), str(scene / "g.yaml"), str(out)],
                            env=dict(os.environ, OMP_NUM_THREADS="1"), stderr=subprocess.PIPE)
    try:
        _poll(lambda: (tmp_path / "out.first").exists() or proc.poll() is not None, 180, "the first row")
        assert proc.poll() is None, proc.stderr.read().decode()[-2000:]
        workers = _children(proc.pid)
        assert len(workers) >= 2
        proc.kill()
        proc.wait()
        _poll(lambda: not _alive(workers), 10, f"workers {sorted(_alive(workers))} to exit")
    finally:
        if proc.poll() is None:
            proc.kill()


@pytest.mark.skipif(not LINUX, reason="reads /proc to find the process group")
def test_ctrl_c_to_the_process_group_leaves_no_process(scene, tmp_path):
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "pixgraph", "batch", str(scene / "g.yaml"), "--no-disk-cache",
                             "--sweep", "light.azimuth=-170:170:2", "--processes", "2",
                             "-o", f"final={out}/{{row}}.png"], env=dict(os.environ, OMP_NUM_THREADS="1"),
                            start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        _poll(lambda: (out.is_dir() and any(n.endswith(".json") for n in os.listdir(out)))
              or proc.poll() is not None, 180, "the first row")
        assert proc.poll() is None, proc.stderr.read().decode()[-2000:]
        group = _children(proc.pid) | {proc.pid}
        os.killpg(proc.pid, signal.SIGINT)
        assert proc.wait(timeout=30) == 130
        _poll(lambda: not _alive(group), 10, f"processes {sorted(_alive(group))} to exit")
        assert not [n for n in os.listdir(out) if ".tmp-" in n or n == F.LOCK_NAME]
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)



def test_doc_limit_transcript(tmp_path, monkeypatch, capsys):
    """docs/batch.md's `$ pixgraph batch ...` transcript prints what the doc shows."""
    import re
    import shlex

    doc = os.path.join(os.path.dirname(__file__), "..", "docs", "batch.md")
    blocks = [b for b in re.findall(r"```text\n(.*?)```", open(doc).read(), re.S) if b.startswith("$ pixgraph batch")]
    assert len(blocks) == 1
    cmd, expected = blocks[0].strip().splitlines()
    monkeypatch.chdir(os.path.join(os.path.dirname(__file__), ".."))
    assert main(shlex.split(cmd)[2:] + ["--no-disk-cache"]) == 2
    assert _err(capsys) == expected
