"""What keeps other web pages out of ``pixgraph serve``, against a real server process:
the probe of issue 23 replayed (Host and Origin of another site, text/plain bodies),
the per-launch token, a page on another origin in real Chromium, and stopping on
SIGTERM/SIGINT mid-render. Every refused request must change nothing on disk."""
import asyncio
import contextlib
import hashlib
import http.server
import os
import shutil
import signal
import tempfile
import textwrap
import threading
import time

import httpx
import pytest

from serve_helpers import REPO, copy_scene, start_server

EVIL_GRAPH = """pixgraph: 1
nodes:
  c: {type: pixgraph.Constant, params: {width: 8, height: 8, color: [1, 0, 0, 1]}}
  out: {type: pixgraph.SaveImage, inputs: {image: c.image}, params: {path: assets/figure.png}}
outputs: {final: c.image}
"""
CONTENT_TYPES = ["text/plain", "application/x-www-form-urlencoded", "multipart/form-data; boundary=x",
                 "application/json"]


def snapshot(folder) -> dict:
    """Every file under ``folder`` -> its SHA-256."""
    out = {}
    for root, _, files in os.walk(folder):
        for f in files:
            path = os.path.join(root, f)
            out[os.path.relpath(path, folder)] = hashlib.sha256(open(path, "rb").read()).hexdigest()
    return out


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    graph = copy_scene(str(tmp_path_factory.mktemp("guarded")))
    with start_server(graph) as (url, token, proc):
        yield {"url": url, "token": token, "graph": graph, "folder": os.path.dirname(graph), "proc": proc}


def _probe_requests(url, token):
    """The probe's requests: (method, path, headers, body) that a page on another site,
    or a rebound domain, can make; the attacker may even have guessed the token."""
    port = url.rsplit(":", 1)[1]
    bodies = {"/api/graph": EVIL_GRAPH, "/api/run": '{"params": {"light.azimuth": 90}}', "/api/save": "{}",
              "/api/params": '{"params": {"light.azimuth": 90}}', "/api/render": '{"mode": "final"}',
              "/api/undo": "{}", "/api/redo": "{}"}
    spoofs = [{"Host": "evil.example"}, {"Host": f"evil.example:{port}"}, {"Origin": "http://evil.example"},
              {"Host": f"evil.example:{port}", "Origin": f"http://evil.example:{port}"},
              {"Origin": "http://127.0.0.1:1"}, {"Origin": "null"}, {"Sec-Fetch-Site": "cross-site"},
              {"Sec-Fetch-Site": "same-site"}, {}]
    for path, body in bodies.items():
        for spoof in spoofs:
            for ctype in CONTENT_TYPES:
                for with_token in (False, True):
                    headers = {"Content-Type": ctype, **spoof}
                    if with_token:
                        headers["X-Pixgraph-Token"] = token
                    if not spoof and (with_token and ctype == "application/json"):
                        continue   # the one allowed combination: this server's own page
                    yield "POST", path, headers, body
    for spoof in spoofs[:-1]:
        yield "PUT", "/api/uploads/x.png", {"Content-Type": "image/png", "X-Pixgraph-Token": token, **spoof}, "x"
        yield "GET", "/api/outputs/final.png", {"X-Pixgraph-Token": token, **spoof}, None
    yield "GET", "/api/graph", {}, None                                     # no token
    yield "GET", "/", {}, None
    yield "GET", "/?token=wrong", {}, None
    yield "POST", "/api/run", {"Content-Type": "application/json", "Cookie": f"pixgraph_token_{port}={token}"}, "{}"


def test_the_probe_is_refused_and_nothing_changes(server):
    url, token, folder = server["url"], server["token"], server["folder"]
    before = snapshot(folder)
    ok = {"X-Pixgraph-Token": token}
    with httpx.Client(base_url=url, timeout=120) as c:
        # an edit to undo, and one undone to redo: an undo or redo let through would change the graph
        for az in (30, 35):
            c.post("/api/params", json={"params": {"light.azimuth": az}}, headers=ok).raise_for_status()
        c.post("/api/undo", json={}, headers=ok).raise_for_status()
        yaml_before = c.get("/api/graph.yaml", headers=ok).text
        history0 = c.get("/api/graph", headers=ok).json()["history"]
        assert history0["undo"] >= 1 and history0["redo"] == 1
        status0 = c.get("/api/status", headers=ok).json()
        answers = []
        for method, path, headers, body in _probe_requests(url, token):
            r = c.request(method, path, headers=headers, content=body)
            answers.append((r.status_code, method, path, headers))
        accepted = [a for a in answers if a[0] < 400]
        assert len(answers) == 517 and accepted == []
        assert {a[0] for a in answers} <= {403, 415}
        status = c.get("/api/status", headers=ok).json()
        assert status["refused"] - status0["refused"] == len(answers)          # each reached the guard
        assert status["runs"] == status0["runs"]                               # nothing ran
        assert c.get("/api/graph.yaml", headers=ok).text == yaml_before
        assert c.get("/api/graph", headers=ok).json()["history"] == history0
        # the controls: the same requests from the page itself are accepted
        r = c.post("/api/params", json={"params": {"light.azimuth": 91}}, headers=ok)
        assert r.status_code == 200, r.text
        assert c.get("/api/graph.yaml", headers=ok).text != yaml_before
        c.post("/api/params", json={"params": {"light.azimuth": -25}}, headers=ok).raise_for_status()
    assert snapshot(folder) == before


def test_the_token(server):
    url, token = server["url"], server["token"]
    assert len(token) >= 40
    with httpx.Client(base_url=url, timeout=60) as c:
        page = c.get(f"/?token={token}")
        assert page.status_code == 200 and f'<meta name="pixgraph-token" content="{token}">' in page.text
        cookie = page.headers["set-cookie"]
        assert f"pixgraph_token_{url.rsplit(':', 1)[1]}={token}" in cookie and "HttpOnly" in cookie and "SameSite=strict" in cookie
        assert page.headers["x-frame-options"] == "DENY" and page.headers["referrer-policy"] == "no-referrer"
        assert c.get("/static/app.js").status_code == 200                     # the page's code: no token
        # the cookie counts for GETs (download links), never for a POST
        assert c.get("/api/graph").status_code == 200
        assert c.post("/api/params", json={}).status_code == 403
        assert c.post("/api/params", json={}, headers={"X-Pixgraph-Token": token}).status_code == 200
        assert c.post(f"/api/params?token={token}", json={}).status_code == 200
    assert httpx.get(url + "/api/graph", timeout=60).status_code == 403       # a fresh client, no cookie
    assert httpx.get(url.replace("127.0.0.1", "localhost") + "/api/graph", headers={"X-Pixgraph-Token": token},
                     timeout=60).status_code == 200


def test_without_token_scripts_pass_and_pages_do_not(tmp_path):
    graph = copy_scene(str(tmp_path / "scene"))
    before = snapshot(tmp_path / "scene")
    with start_server(graph, "--no-token") as (url, token, _):
        assert token is None
        with httpx.Client(base_url=url, timeout=120) as c:
            assert c.post("/api/params", json={"params": {"light.azimuth": 10}}).status_code == 200
            refused = [c.post("/api/save", content="{}", headers=h).status_code
                       for h in ({"Content-Type": "text/plain"}, {"Host": "evil.example"},
                                 {"Origin": "http://evil.example", "Content-Type": "application/json"},
                                 {"Sec-Fetch-Site": "cross-site", "Content-Type": "application/json"})]
            assert refused == [415, 403, 403, 403]
    assert snapshot(tmp_path / "scene") == before


# -- a page on another origin, in real Chromium -------------------------------------------------

ATTACK_PAGE = """<!doctype html><html><body>
<iframe name="f1"></iframe><iframe name="f2"></iframe><iframe name="f3"></iframe>
<form id="g" method="POST" action="TARGET/api/graph" enctype="text/plain" target="f1">
  <input name="pixgraph: 1&#10;nodes: {}&#10;x" value="1"></form>
<form id="s" method="POST" action="TARGET/api/save" enctype="text/plain" target="f2">
  <input name='{"path": "pwned.yaml", "x": "' value='"}'></form>
<form id="r" method="POST" action="TARGET/api/run" target="f3"><input name="outputs" value="final"></form>
<script>
const T = "TARGET";
window.results = [];
async function attempt(name, f) {
  try { const r = await f(); results.push(name + ":" + r.type + ":" + r.status); }
  catch (e) { results.push(name + ":blocked"); }
}
async function go() {
  const evil = `EVIL`;
  await attempt("graph text/plain", () => fetch(T + "/api/graph", {method: "POST", mode: "no-cors", body: evil}));
  await attempt("run text/plain", () => fetch(T + "/api/run", {method: "POST", mode: "no-cors", body: "{}"}));
  await attempt("save text/plain", () => fetch(T + "/api/save", {method: "POST", mode: "no-cors", body: "{}"}));
  await attempt("params json", () => fetch(T + "/api/params", {method: "POST",
    headers: {"Content-Type": "application/json"}, body: '{"params": {"light.azimuth": 90}}'}));
  await attempt("save json", () => fetch(T + "/api/save", {method: "POST",
    headers: {"Content-Type": "application/json"}, body: '{"path": "pwned.yaml"}'}));
  await attempt("render credentials", () => fetch(T + "/api/render", {method: "POST", mode: "no-cors",
    credentials: "include", body: '{"mode": "final"}'}));
  await attempt("output get", () => fetch(T + "/api/outputs/final.png", {mode: "no-cors", credentials: "include"}));
  const loaded = ["f1", "f2", "f3"].map((n) => new Promise((ok) => document.querySelector(`iframe[name=${n}]`).onload = ok));
  for (const id of ["g", "s", "r"]) document.getElementById(id).submit();
  await Promise.all(loaded);
  const img = new Image();
  await new Promise((ok) => { img.onload = img.onerror = ok; img.src = T + "/api/outputs/final.png?x=1"; });
  window.done = true;
}
go();
</script></body></html>"""


def _serve_page(html: str):
    """A plain HTTP server on another port of 127.0.0.1 serving ``html``; returns (url, stop)."""
    body = html.encode()

    class Handler(http.server.BaseHTTPRequestHandler):
        def do_GET(self):
            self.send_response(200)
            self.send_header("Content-Type", "text/html")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args):
            pass

    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    return f"http://127.0.0.1:{httpd.server_address[1]}/", httpd.shutdown


def test_a_page_on_another_origin_changes_nothing_in_chromium(server):
    chromium = shutil.which("chromium") or "/usr/bin/chromium"
    if not os.path.exists(chromium):
        if os.environ.get("CI"):
            pytest.fail("Debian's chromium is missing: './setup.sh test' installs it")
        pytest.skip("Debian's chromium is not installed")
    from playwright.sync_api import sync_playwright

    url, token, folder = server["url"], server["token"], server["folder"]
    ok = {"X-Pixgraph-Token": token}
    before = snapshot(folder)
    yaml_before = httpx.get(url + "/api/graph.yaml", headers=ok, timeout=60).text
    status0 = httpx.get(url + "/api/status", headers=ok, timeout=60).json()
    page_url, stop = _serve_page(ATTACK_PAGE.replace("TARGET", url).replace("EVIL", EVIL_GRAPH))
    port = url.rsplit(":", 1)[1]
    try:
        with sync_playwright() as p:
            b = p.chromium.launch(executable_path=chromium, args=[
                "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-background-networking",
                "--host-resolver-rules=MAP evil.example 127.0.0.1"])
            try:
                ctx = b.new_context()
                # the user opened the real page first: the browser holds its cookie
                own = ctx.new_page()
                own.goto(f"{url}/?token={token}")
                own.wait_for_function("document.body.dataset.ready === '1'", timeout=120_000)
                assert own.evaluate("window.pixgraphShown.length") >= 1     # it rendered, with the token
                status1 = httpx.get(url + "/api/status", headers=ok, timeout=60).json()
                attacker = ctx.new_page()
                attacker.goto(page_url)
                attacker.wait_for_function("window.done === true", timeout=120_000)
                results = attacker.evaluate("window.results")
                # DNS rebinding: a domain of the attacker's that resolves to 127.0.0.1, even with the token
                rebound = ctx.new_page()
                answer = rebound.goto(f"http://evil.example:{port}/?token={token}")
                assert answer.status == 403
                answer = rebound.goto(f"http://evil.example:{port}/api/graph?token={token}")
                assert answer.status == 403
            finally:
                b.close()
    finally:
        stop()
    status = httpx.get(url + "/api/status", headers=ok, timeout=60).json()
    print("attacker page saw:", results, "refused:", status["refused"] - status1["refused"])
    assert len(results) == 7
    # what the attacker could read: nothing (opaque or blocked), and the server refused all that came
    assert all(r.endswith(":opaque:0") or r.endswith(":blocked") for r in results), results
    assert status["refused"] - status1["refused"] >= 12       # 7 fetches (or preflights), 3 forms, 1 image, 2 rebound
    assert status["runs"] == status1["runs"] and status1["runs"] > status0["runs"]
    assert httpx.get(url + "/api/graph.yaml", headers=ok, timeout=60).text == yaml_before
    assert snapshot(folder) == before


# -- stopping -------------------------------------------------------------------------------------

# A node that holds a render busy until the test lets it go: stopping "mid-render" is then
# certain, not a race with a render a fast machine finishes between two polls.
HOLD_PLUGIN = {
    "holdpack/__init__.py": '''
        import os
        import time

        from pixgraph_nodes import types as T
        from pixgraph.node import node, param, port

        @node("test.Hold", version=1)
        class Hold:
            """Its input; with ``hold``, once the file ``gate`` exists (``started`` is written
            when the wait begins)."""
            class Inputs:
                image: T.Image = port()
            class Params:
                hold: bool = param(False, doc="wait for the gate")
                started: str = param("", doc="file written when the wait begins")
                gate: str = param("", doc="file whose existence ends the wait")
            class Outputs:
                image: T.Image = port()
            def compute(self, ctx, inputs, params):
                if params.hold:
                    open(params.started, "w").close()
                    deadline = time.monotonic() + 600
                    while not os.path.exists(params.gate):
                        if time.monotonic() > deadline:
                            raise RuntimeError("the test never opened the gate")
                        time.sleep(0.005)
                return {"image": inputs.image}
    ''',
    "holdpack-0.1.dist-info/METADATA": "Metadata-Version: 2.1\nName: holdpack\nVersion: 0.1\n",
    "holdpack-0.1.dist-info/entry_points.txt": "[pixgraph.nodes]\nhold = holdpack\n",
}
HOLD_GRAPH = """pixgraph: 1
nodes:
  c: {type: pixgraph.Constant, params: {width: 8, height: 8}}
  hold: {type: test.Hold, inputs: {image: c.image}}
outputs: {final: hold.image}
"""


@contextlib.contextmanager
def held_server(tmp_path):
    """A server (``test.Hold`` on its path) of a graph whose render a test holds busy:
    yields (url, process, the render's params that hold it, the file its start writes).
    The gate opens on the way out, so a server still running would finish that render."""
    plugins = tmp_path / "plugins"
    for rel, text in HOLD_PLUGIN.items():
        (plugins / rel).parent.mkdir(parents=True, exist_ok=True)
        (plugins / rel).write_text(textwrap.dedent(text).lstrip())
    graph = tmp_path / "held.yaml"
    graph.write_text(HOLD_GRAPH)
    started, gate = tmp_path / "started", tmp_path / "gate"
    env = {"PYTHONPATH": os.pathsep.join([str(plugins), *filter(None, [os.environ.get("PYTHONPATH")])])}
    try:
        with start_server(str(graph), "--no-token", env=env) as (url, _, proc):
            yield url, proc, {"hold.hold": True, "hold.started": str(started), "hold.gate": str(gate)}, started
    finally:
        gate.touch()


async def stop_while_held(url, proc, hold, started, sig=signal.SIGTERM) -> tuple[int, float]:
    """Start a render the gate holds, wait (polls, up to 120 s) until its node is waiting,
    send ``sig``; the exit code and the seconds to exit. Asserts the stop came while the
    render was busy: the render never answered, and the server exited while its node was
    still waiting at the gate (which opens only after the server is gone)."""
    async with httpx.AsyncClient(base_url=url, timeout=600) as c:
        long = asyncio.create_task(c.post("/api/render", json={"params": hold}))
        for _ in range(12000):
            if started.exists() or long.done():
                break
            await asyncio.sleep(0.01)
        assert started.exists() and not long.done(), "the held render did not start"
        assert (await c.get("/api/status")).json()["running"] >= 1
        t0 = time.monotonic()
        proc.send_signal(sig)
        code = await asyncio.get_running_loop().run_in_executor(None, proc.wait, 30)
        seconds = time.monotonic() - t0
        with pytest.raises(httpx.TransportError):      # the server went away mid-render
            await long
    return code, seconds


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_stops_the_server_mid_render(tmp_path, sig):
    """A stop signal while a node runs (held by its gate, so the render is certainly
    busy) ends the server at once, exit code 0, without waiting for the node."""
    with held_server(tmp_path) as (url, proc, hold, started):
        code, seconds = asyncio.run(stop_while_held(url, proc, hold, started, sig))
    assert code == 0
    print(f"{signal.Signals(sig).name}: exited in {seconds:.3f} s")


def test_a_signal_stops_an_idle_server(tmp_path):
    with start_server(copy_scene(str(tmp_path / "scene")), "--no-token") as (url, _, proc):
        httpx.post(url + "/api/run", json={}, timeout=120).raise_for_status()
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=5) == 0


@pytest.mark.parametrize("busy", [False, True])
def test_a_stopped_server_leaves_no_uploaded_photo_behind(tmp_path, busy):
    """The photos and cutouts opened in the page go to an upload folder the server made;
    it is removed when the server stops (idle, or mid-render: a render held busy by a
    node the test lets go only after the stop), so the user's photos do not stay in the
    temporary folder (a graph saved from the page reads copies beside it). Before, every
    stop left the folder and its files behind."""
    with held_server(tmp_path) as (url, proc, hold, started):
        with open(os.path.join(REPO, "graphs", "assets", "figure.png"), "rb") as f:
            r = httpx.put(url + "/api/uploads/mine.png", content=f.read(), timeout=60)
        r.raise_for_status()
        folder = os.path.dirname(r.json()["path"])
        assert os.path.isfile(os.path.join(folder, "mine.png"))
        if busy:
            assert asyncio.run(stop_while_held(url, proc, hold, started))[0] == 0
        else:
            assert httpx.get(url + "/api/status", timeout=60).json()["running"] == 0
            proc.send_signal(signal.SIGTERM)
            assert proc.wait(timeout=30) == 0
            assert not started.exists()
    assert not os.path.exists(folder)


def test_bad_serve_options_exit_2_with_one_line(tmp_path, capsys, monkeypatch):
    graph = copy_scene(str(tmp_path / "scene"))
    import socket

    busy = socket.socket()
    busy.bind(("127.0.0.1", 0))
    busy.listen(1)
    cases = [["--run-timeout", "-1"], ["--run-timeout", "nan"], ["--run-timeout", "inf"], ["--max-pixels", "0"],
             ["--max-body", "-5"], ["--allow-path", str(tmp_path / "nope")], ["--device", "no-such-device:9"],
             ["--port", str(busy.getsockname()[1])], ["--host", "no-such-host.invalid"]]
    from pixgraph.cli import main

    temp = tmp_path / "temp"          # where the server would make its upload folder
    temp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(temp))
    for extra in cases + [None]:
        args = [graph, *extra] if extra is not None else [str(tmp_path / "missing.yaml")]
        code = main(["serve", "--port", "0", *args])           # in-process: each fails before serving
        err = capsys.readouterr().err
        assert code == 2, (extra, err)
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, (extra, err)
    # none of them left an upload folder behind
    assert os.listdir(temp) == []
    busy.close()
