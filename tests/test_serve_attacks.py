"""Attacks on ``pixgraph serve`` beyond the probe of test_serve_security.py, against a
real server process (``--no-token``: the token is tested there): symlinks planted in
the graph's folder where a save or a save with files writes, uploads racing on one
name, and images that dodge ``--max-pixels`` by their file name. Each must leave
every file outside the allowed folders as it was."""
import io
import os

import httpx
import numpy as np
import pytest
from PIL import Image

from pixgraph import fileio
from pixgraph.registry import Registry
from serve_helpers import copy_scene, running_server

MAX_PIXELS = 300_000      # 512^2 = 262,144 fits; 600^2 does not
JSON = {"Content-Type": "application/json"}
YAML = {"Content-Type": "application/yaml"}


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    top = tmp_path_factory.mktemp("attacks")
    graph = copy_scene(str(top / "scene"))
    os.makedirs(top / "outside")
    with running_server(graph, "--max-pixels", str(MAX_PIXELS)) as (url, proc):
        yield {"url": url, "graph": graph, "folder": os.path.dirname(graph), "top": top,
               "outside": top / "outside", "text": open(graph).read(), "proc": proc}


@pytest.fixture
def api(server):
    with httpx.Client(base_url=server["url"], timeout=120) as c:
        r = c.post("/api/graph", content=server["text"], headers=YAML)
        assert r.status_code == 200, r.text
        yield c


def _png(w, h, fmt="PNG"):
    buf = io.BytesIO()
    Image.new("RGBA" if fmt == "PNG" else "RGB", (w, h), (200, 100, 50)).save(buf, format=fmt)
    return buf.getvalue()


def _victim(outside, name):
    path = outside / name
    path.write_text("the user's own file\n")
    return path


def test_a_save_never_writes_through_a_symlink_planted_at_its_temporary(api, server):
    """Someone who can write in the graph's folder plants symlinks, pointing outside,
    at every name a save's temporary file had (``.NAME.tmp-PID``, the engine's
    ``NAME.tmp-PID`` after it, both for the served file and another name): the save
    must write the graph file itself and nothing outside. Before: the YAML went into
    the victim file outside and the graph file became a symlink to it."""
    folder, pid = server["folder"], server["proc"].pid
    victims, links = [], []
    for target in (os.path.basename(server["graph"]), "other.yaml"):
        for name in (f".{target}.tmp-{pid}", f".{target}.tmp-{pid}.tmp-{pid}", f"{target}.tmp-{pid}"):
            victim = _victim(server["outside"], f"victim-{len(victims)}.txt")
            os.symlink(victim, os.path.join(folder, name))
            victims.append(victim)
            links.append(os.path.join(folder, name))
    try:
        for path in (None, "other.yaml"):
            r = api.post("/api/save", json={} if path is None else {"path": path})
            assert r.status_code == 200, r.text
            saved = r.json()["path"]
            assert not os.path.islink(saved) and os.path.isfile(saved)
            assert open(saved).read() == r.json()["yaml"]
        for v in victims:
            assert v.read_text() == "the user's own file\n", v
    finally:
        for link in links:
            if os.path.lexists(link):
                os.unlink(link)
        with open(server["graph"], "w") as f:
            f.write(server["text"])


def test_fileio_dump_never_writes_through_a_planted_symlink(tmp_path):
    """The engine's own ``fileio.dump`` (the server's save): a symlink at the name its
    temporary used to have is neither written through nor renamed into place."""
    reg = Registry.discover()
    graph = fileio.load(copy_scene(str(tmp_path / "scene")), reg)
    victim = _victim(tmp_path, "victim.txt")
    target = tmp_path / "scene" / "copy.yaml"
    os.symlink(victim, f"{target}.tmp-{os.getpid()}")
    fileio.dump(graph, target, reg)
    assert victim.read_text() == "the user's own file\n"
    assert not target.is_symlink() and fileio.load(target, reg).nodes.keys() == graph.nodes.keys()
    assert [n for n in os.listdir(target.parent) if ".tmp-" in n] == [f"copy.yaml.tmp-{os.getpid()}"]


def test_save_with_files_never_copies_through_a_planted_symlink(api, server):
    """A save with the uploaded photo copied beside the graph: symlinks planted at the
    copy's names (one dangling, one to an outside file with the same bytes) are
    skipped, never written through or reused; the copy is a new regular file. Before:
    the upload was copied into the dangling link's target outside."""
    folder, outside = server["folder"], server["outside"]
    data = _png(40, 30)
    path = api.put("/api/uploads/mine.png", content=data).json()["path"]
    (outside / "same.png").write_bytes(data)
    links = {"mine.png": outside / "created.png", "mine_2.png": outside / "same.png"}
    for name, target in links.items():
        os.symlink(target, os.path.join(folder, name))
    before = sorted(os.listdir(outside))
    try:
        assert api.post("/api/params", json={"params": {"cutout.path": path}}).status_code == 200
        r = api.post("/api/save_files", json={"path": "mine.yaml"})
        assert r.status_code == 200, r.text
        assert r.json()["copied"] == ["mine_3.png"]
        copy = os.path.join(folder, "mine_3.png")
        assert not os.path.islink(copy) and open(copy, "rb").read() == data
        assert sorted(os.listdir(outside)) == before and not (outside / "created.png").exists()
    finally:
        for name in (*links, "mine_3.png", "mine.yaml"):
            if os.path.lexists(os.path.join(folder, name)):
                os.unlink(os.path.join(folder, name))


def test_two_uploads_of_one_name_do_not_share_a_temporary(tmp_path, monkeypatch):
    """Two uploads of the same name at once (the page's client and another): each is
    checked and stored as the bytes it sent. Before, both wrote ``NAME.part``: the
    second's over-limit image overwrote the first's bytes, its 413 removed the shared
    temporary, and the first then failed on a file that no longer existed (a 400 here;
    a 500 when the removal fell between the first's check and its rename)."""
    from pixgraph_serve.errors import ServeError
    from pixgraph_serve.state import Limits, ServeState

    graph = copy_scene(str(tmp_path / "scene"))
    os.makedirs(tmp_path / "up")
    state = ServeState(graph, upload_dir=str(tmp_path / "up"), limits=Limits(max_pixels=MAX_PIXELS))
    small, big = _png(64, 48), _png(600, 600)
    import OpenImageIO as oiio

    real = oiio.ImageInput.open
    second = []

    def racing(path, *args):
        if not second:      # while the first upload's header is being read, a second one arrives
            second.append(True)
            with pytest.raises(ServeError) as e:
                state.store_upload("a.png", big)
            assert e.value.status == 413
        return real(path, *args)

    monkeypatch.setattr(oiio.ImageInput, "open", racing)
    path, n = state.store_upload("a.png", small)
    assert second and n == 64 * 48 and open(path, "rb").read() == small
    assert os.listdir(tmp_path / "up") == ["a.png"]


def test_an_upload_refused_by_its_header_names_the_upload(api):
    """A PNG whose header claims 20000 x 20000 pixels from 100 bytes: a 400 naming the
    uploaded name and the reader's reason, not a temporary file in the upload folder
    (before: 'could not find a format reader for ".../h.png.part"')."""
    import struct
    import zlib

    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d))

    data = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 20000, 20000, 8, 6, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(b"\0" * 100)) + chunk(b"IEND", b""))
    r = api.put("/api/uploads/h.png", content=data)
    assert r.status_code in (400, 413), r.text
    err = r.json()["error"]
    assert "h.png" in err and ".part" not in err and ".tmp" not in err and "pixgraph-uploads" not in err, err


@pytest.mark.parametrize("name", ["big.bmp", "big.tga", "big.gif", "big", "big.data"])
def test_max_pixels_holds_whatever_the_file_is_named(api, server, name):
    """``--max-pixels`` is checked from the header of every file a graph reads, not
    only of names ending in .png/.jpg/.tif/.exr/.hdr: a 600 x 600 BMP, TGA or GIF,
    or a PNG named without an image extension, was read (the engine's own limit is
    64 Mi pixels). The same file at 500 x 500 is accepted."""
    fmt = {"big.bmp": "BMP", "big.tga": "TGA", "big.gif": "GIF"}.get(name, "PNG")
    path = os.path.join(server["folder"], "assets", name)
    for size, status in ((600, 413), (500, 200)):
        with open(path, "wb") as f:
            f.write(_png(size, size, fmt))
        r = api.post("/api/params", json={"params": {"cutout.path": f"assets/{name}"}})
        assert r.status_code == status, (size, r.text)
        if status == 413:
            assert "360000 pixels" in r.json()["error"] and "--max-pixels" in r.json()["error"]
            r = api.post("/api/graph", content=server["text"].replace("assets/figure.png", f"assets/{name}"),
                         headers=YAML)
            assert r.status_code == 413, r.text


def test_max_pixels_holds_for_a_pixel_height_array(api, server):
    """A ``.npy`` pixel-height map is checked from its header the same way."""
    path = os.path.join(server["folder"], "assets", "h.npy")
    np.save(path, np.zeros((600, 600), np.float32))
    text = server["text"].replace("outputs:", "  hh: {type: pixgraph.LoadPixelHeight, params: {path: assets/h.npy}}"
                                  "\noutputs:", 1)
    r = api.post("/api/graph", content=text, headers=YAML)
    assert r.status_code == 413 and "--max-pixels" in r.json()["error"], r.text
    np.save(path, np.zeros((500, 500), np.float32))
    assert api.post("/api/graph", content=text, headers=YAML).status_code == 200


def test_half_sent_requests_do_not_lock_the_page_out(server):
    """Any local program, without the token, opens 80 connections and sends half a
    request on some, nothing on others (a slow-loris): the page's next request is
    still answered, and the server closes those connections when their headers have
    not come in ``HEADER_SECONDS`` (also on a connection kept alive after a whole
    request). Before: every request got ``503 Service Unavailable`` for as
    long as the 64 connections of uvicorn's ``limit_concurrency`` stayed open (65 s
    and more: there was no time limit on a request's headers)."""
    import socket
    import time

    from pixgraph_serve import server as serve_module

    header_seconds = getattr(serve_module, "HEADER_SECONDS", 10.0)
    host, port = server["url"].rsplit("/", 1)[1].rsplit(":", 1)
    socks = []
    try:
        request = f"GET /api/status HTTP/1.1\r\nHost: {host}:{port}\r\n"
        for i in range(80):
            s = socket.create_connection((host, int(port)), timeout=5)
            if i == 0:       # a whole request answered first, then half of the next one
                s.sendall((request + "\r\n").encode())
                seen = b""
                while not seen.endswith(b"}"):
                    seen += s.recv(4096)
            if i % 2 == 0:   # half a request; the odd ones send nothing at all
                s.sendall(request.encode())
            socks.append(s)
        r = httpx.get(server["url"] + "/api/status", timeout=30)
        assert r.status_code == 200, r.text
        deadline = time.monotonic() + header_seconds + 30
        for s in socks:
            s.settimeout(max(0.1, deadline - time.monotonic()))
            assert s.recv(100) == b""          # closed by the server, nothing answered
    finally:
        for s in socks:
            s.close()
    assert httpx.get(server["url"] + "/api/status", timeout=30).status_code == 200


def test_max_pixels_holds_for_a_file_swapped_after_its_check(api, server):
    """The header is checked when a graph names a file; someone who can write in the
    graph's folder then swaps a larger image in (keeping its mtime, so the checked
    size stays cached). The pixel limit still holds when the node reads it:
    ``pixgraph serve`` gives the engine its ``--max-pixels`` (``PIXGRAPH_MAX_PIXELS``),
    checked from the header the node itself opens. Before, the run read the 600 x 600
    image under ``--max-pixels 300000`` (the engine's own limit is 64 Mi pixels)."""
    path = os.path.join(server["folder"], "assets", "swap.png")
    with open(path, "wb") as f:
        f.write(_png(500, 500))
    text = server["text"].replace("assets/figure.png", "assets/swap.png").replace(
        "outputs: {final: comp.image}", "outputs: {final: comp.image, cut: cutout.image}")
    assert api.post("/api/graph", content=text, headers=YAML).status_code == 200
    st = os.stat(path)
    with open(path, "wb") as f:
        f.write(_png(600, 600))
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))
    r = api.post("/api/run", json={"outputs": ["cut"]})
    assert r.status_code in (400, 413), r.text
    assert "300000" in r.json()["error"] and r.json()["node"] == "cutout", r.text


def test_a_posted_graph_over_the_value_limit_is_refused_by_the_fast_scan(tmp_path, monkeypatch):
    """A posted graph of 20,000 nodes (1.9 MB, 220,000 values) is over the graph
    format's limit of values (``fileio.MAX_YAML_NODES``): it is refused by the
    linear libyaml scan that already refuses anchors and deep nesting, before any
    loader builds it. Before, the pure-Python loader built it first and refused it
    only then (30 s of the server's time on 2 loaded cores, holding the lock that
    the page's renders wait for)."""
    from pixgraph import fileio as engine_fileio
    from pixgraph_serve.errors import ServeError
    from pixgraph_serve.state import ServeState

    state = ServeState(copy_scene(str(tmp_path / "scene")), upload_dir=str(tmp_path / "up"))
    nodes = "".join(f"  c{i}: {{type: pixgraph.Constant, params: {{width: 8, height: 8, color: [0.1, 0.2, 0.3, 1]}}}}\n"
                    for i in range(20_000))
    text = open(state.graph_path).read().replace("outputs:", nodes + "outputs:", 1)

    def never(*args, **kwargs):
        raise AssertionError("the graph was built before it was refused")

    monkeypatch.setattr(engine_fileio, "loads", never)
    import yaml
    monkeypatch.setattr(yaml, "load", never)
    with pytest.raises(ServeError) as e:
        state.load_text(text)
    assert e.value.status == 400 and f"more than {engine_fileio.MAX_YAML_NODES} values" in e.value.message
