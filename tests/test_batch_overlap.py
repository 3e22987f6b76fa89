"""A batch writes a row's files on a writer thread while the next row computes
(pixgraph_batch.work.run_group): same files and sidecars as writing in line, one
write in flight at most, results reported in order, a failed write fails its row
only, an interrupt leaves no temporary; and on the own-photo graph (load, place,
heights) the rows of a light sweep compute the upstream once."""
import json
import os
import threading

import numpy as np
import pytest

import pixgraph_batch.work as W
from pixgraph.session import Session
from pixgraph_batch import batch
from test_batch import scene  # noqa: F401 - the fixture: a 64x64 photo, five cutouts, g.yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
AZ = [-60, -30, 0, 30, 60]


def _sweep(scene, out, **kw):
    return batch(Session(), scene / "g.yaml", sweeps=[("light.azimuth", AZ)],
                 outputs={"final": str(out / "{index}.png"), "shadow": str(out / "{index}_s.exr")}, **kw)


def test_overlapped_writes_give_the_files_of_inline_writes(scene, tmp_path):
    a = _sweep(scene, tmp_path / "a")
    b = _sweep(scene, tmp_path / "b", overlap=False)
    assert [r.status for r in a.results] == [r.status for r in b.results] == ["done"] * 5
    for i in range(5):
        for name in (f"{i}.png", f"{i}_s.exr"):
            assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name
            ma, mb = (json.loads((tmp_path / d / f"{name}.json").read_text()) for d in "ab")
            assert ma["file_sha256"] == mb["file_sha256"] and ma["content_key"] != mb["content_key"]
            assert ma["ran"] == mb["ran"] and ma["seconds"] > 0
    # resume: every row of the overlapped batch is done
    again = _sweep(scene, tmp_path / "a")
    assert [r.status for r in again.results] == ["skipped"] * 5
    assert not [n for n in os.listdir(tmp_path / "a") if ".tmp" in n]


def test_cli_no_overlap_writes_the_same_files(scene, tmp_path, capsys):
    from pixgraph.cli import main

    for d, extra in (("a", []), ("b", ["--no-overlap"])):
        rc = main(["batch", str(scene / "g.yaml"), "--no-disk-cache", "--sweep", "light.azimuth=-40,0,40",
                   "-o", f"final={tmp_path / d}/{{index}}.png", *extra])
        assert rc == 0, capsys.readouterr()
    for i in range(3):
        assert (tmp_path / "a" / f"{i}.png").read_bytes() == (tmp_path / "b" / f"{i}.png").read_bytes()


def test_a_row_is_written_while_the_next_computes_one_write_at_a_time(scene, tmp_path, monkeypatch):
    """Row k's write waits (without a timeout that matters) until row k+1's compute has
    started: only a writer thread can see that; never two writes at once; results in order."""
    started = {}  # row index -> Event set when its compute starts
    lock = threading.Lock()
    state = {"writing": 0, "most": 0, "threads": set()}
    real_compute, real_write = W.compute_item, W._write_output

    def compute(session, graph, item, *a, **kw):
        started.setdefault(item.index, threading.Event()).set()
        return real_compute(session, graph, item, *a, **kw)

    def write(session, graph, name, value, path, folder):
        idx = int(os.path.basename(path).split(".")[0].split("_")[0])
        with lock:
            state["writing"] += 1
            state["most"] = max(state["most"], state["writing"])
            state["threads"].add(threading.get_ident())
        try:
            if idx + 1 < len(AZ) and name == "final":
                nxt = started.setdefault(idx + 1, threading.Event())
                assert nxt.wait(60), f"row {idx + 1} did not start while row {idx} was being written"
            return real_write(session, graph, name, value, path, folder)
        finally:
            with lock:
                state["writing"] -= 1

    monkeypatch.setattr(W, "compute_item", compute)
    monkeypatch.setattr(W, "_write_output", write)
    order = []
    res = _sweep(scene, tmp_path / "o", on_result=lambda r: order.append(r.index))
    assert [r.status for r in res.results] == ["done"] * 5, res.table()
    assert order == list(range(5))
    assert state["most"] == 1
    assert threading.get_ident() not in state["threads"]  # written on the writer thread


def test_a_failed_write_fails_its_row_only(scene, tmp_path):
    out = tmp_path / "f"
    (out / "2.png").mkdir(parents=True)  # a folder where row 2's image goes: its rename fails
    res = _sweep(scene, out)
    assert [r.status for r in res.results] == ["done", "done", "failed", "done", "done"]
    assert "2.png" in res.results[2].error
    assert not (out / "2.png.json").exists() and (out / "3.png.json").exists()
    assert not [n for n in os.listdir(out) if ".tmp" in n]


def test_an_interrupt_waits_for_the_write_in_flight_and_leaves_no_temporary(scene, tmp_path, monkeypatch):
    real_run = Session.run_plan
    calls = []

    def run_plan(self, plan, *a, **kw):
        calls.append(1)
        if len(calls) == 3:  # row 2 computes while row 1 is written
            raise KeyboardInterrupt
        return real_run(self, plan, *a, **kw)

    monkeypatch.setattr(Session, "run_plan", run_plan)
    done = []
    with pytest.raises(KeyboardInterrupt):
        _sweep(scene, tmp_path / "k", on_result=done.append)
    names = os.listdir(tmp_path / "k")
    assert not [n for n in names if ".tmp" in n], names
    assert [r.index for r in done] == [0]  # row 1's write was in flight: finished, not reported
    for i in (0, 1):  # both complete: image and sidecar agree
        meta = json.loads((tmp_path / "k" / f"{i}.png.json").read_text())
        from pixgraph_batch.files import file_sha256
        assert meta["file_sha256"] == file_sha256(str(tmp_path / "k" / f"{i}.png"))
    monkeypatch.setattr(Session, "run_plan", real_run)
    again = _sweep(scene, tmp_path / "k")
    assert [r.status for r in again.results] == ["skipped", "skipped", "done", "done", "done"]


@pytest.mark.parametrize("cache_bytes", [None, 1 << 20])
def test_own_photo_sweep_computes_the_upstream_once(tmp_path, cache_bytes):
    """graphs/own_photo.yaml (photo 640x480, cutout placed, wall junction): six light
    azimuths in one batch compute the photo and cutout loads, the camera, both heights
    and the placement once (the first row) and only light -> shadow -> composite in
    every other row, also when the memory cache (1 MiB) cannot hold one 640x480
    intermediate: the group's pins keep them. Pixels equal single runs."""
    out = tmp_path / "out"
    az = [-60, -36, -12, 12, 36, 60]
    s = Session(cache_bytes=cache_bytes) if cache_bytes else Session()
    graph = os.path.join(ROOT, "graphs", "own_photo.yaml")
    res = batch(s, graph, sweeps=[("light.azimuth", az)], params={"shadow.samples": 8},
                outputs={"final": str(out / "{index}.png")})
    assert res.count("done") == 6 and res.groups == 1, res.table()
    ran = [json.loads((out / f"{i}.png.json").read_text())["ran"] for i in range(6)]
    upstream = ["cutout", "photo", "cam", "fg_h", "place", "bg_h"]
    counts = {n: sum(n in r for r in ran) for n in upstream}
    assert counts == {n: 1 for n in upstream}, counts
    assert set(ran[0]) >= set(upstream)
    assert all(set(r) == {"light", "shadow", "comp"} for r in ran[1:]), ran
    for i in (0, 5):
        single = Session().run(graph, outputs=["final"], params={"light.azimuth": az[i], "shadow.samples": 8})
        path = tmp_path / f"single{i}.png"
        from pixgraph_nodes.ops.imageio import write_image
        write_image(path, single["final"])
        assert path.read_bytes() == (out / f"{i}.png").read_bytes()
    assert np.isfinite(s.memory.limit_bytes)


# -- per-row work: checks of the same frozen upstream arrays are not repeated ---------------------


def test_checks_skip_frozen_arrays_that_passed_and_only_those():
    from pixgraph.node import InputError
    from pixgraph_nodes import _checks as C

    a = np.ones((64, 48), np.float32)
    C.finite(a=a)
    assert not C._passed("finite", a)  # writable: anyone may change it, checked every time
    a.flags.writeable = False
    C.finite(a=a)
    assert C._passed("finite", a)
    a.flags.writeable = True  # thawed by its owner and changed: checked again, the NaN found
    a[3, 5] = np.nan
    with pytest.raises(InputError, match="u=5, v=3"):
        C.finite(a=a)
    # a read-only view of a writable array is not frozen
    base = np.zeros((8, 8), np.float32)
    view = base[:4]
    view.flags.writeable = False
    C.finite(v=view)
    assert not C._passed("finite", view)
    base[0, 0] = np.inf
    with pytest.raises(InputError, match="'v'"):
        C.finite(v=view)
    # pixel heights: remembered only when valid everywhere, so any later ``where`` holds
    h = np.full((16, 16), 3.0, np.float32)
    h[0, 0] = -1.0  # outside the cutout: fine under this where, not remembered
    h.flags.writeable = False
    where = np.zeros((16, 16), bool)
    where[4:, 4:] = True
    C.pixel_heights(where, fg_height=h)
    assert not C._passed("pixel_heights", h)
    # ``where`` as a function: made only when a map is not valid everywhere
    made = []
    C.pixel_heights(lambda: made.append(1) or where, fg_height=h)
    assert made == [1]
    C.pixel_heights(lambda: made.append(2) or where, fg_height=np.ones((16, 16), np.float32))
    assert made == [1]
    with pytest.raises(InputError, match="u=0, v=0"):
        C.pixel_heights(lambda: ~where, fg_height=h)
    with pytest.raises(InputError, match="negative"):
        C.pixel_heights(fg_height=h)
    g = np.full((16, 16), 2.0, np.float32)
    g.flags.writeable = False
    C.pixel_heights(bg_height=g)
    assert C._passed("pixel_heights", g)
    key = ("pixel_heights", id(g))
    del g  # forgotten with the array: a new array at the same address is checked
    assert key not in C._PASSED


def test_finite_outputs_finds_nan_and_either_infinity():
    """_checks.finite_outputs (found by min / max first): NaN, +inf or -inf anywhere
    is a RuntimeError that counts them; finite and empty arrays pass."""
    from pixgraph_nodes import _checks as C
    C.finite_outputs(a=np.zeros((4, 4, 4), np.float32), e=np.zeros((0, 3), np.float32))
    for bad in (np.nan, np.inf, -np.inf):
        a = np.ones((4, 4, 4), np.float32)
        a[2, 1, 3] = a[0, 0, 0] = bad
        with pytest.raises(RuntimeError, match="'a' holds 2 non-finite"):
            C.finite_outputs(ok=np.ones(3, np.float32), a=a)
