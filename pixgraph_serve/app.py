"""The HTTP API and the page, as a Starlette application over one ``ServeState``.

Every error is JSON ``{"error": "...", "node": ..., "field": ...}`` with the status
``errors.STATUS`` gives (400 bad input, 403 a path outside the allowed folders or a
request ``guard.py`` refuses, 404, 409 a render superseded by a newer one or an undo
or redo with nothing to take back, 413 over
a limit, 415 a body that is not JSON, 422 a node that failed, 503 a run over the
time limit or a server shutting down); anything else is a 500 with a one-line
message, never a traceback.

Runs and edits go through one lock, on a worker thread. Renders from the page carry
a client id and a sequence number: a render that a newer one of the same client has
superseded is dropped (409 ``stale``) when it would start, and cancelled (through its
``CancelToken``) when it is running, so drags never queue work. ``POST /api/run``
answers a run id; ``GET /api/outputs/NAME.png?run=ID`` is that run's image, encoded
once however many clients ask (``runs.py``) and streamed in chunks.

Undo: every edit (``apply_edits``, a posted graph, ``/api/open``) is an undo step of
``ServeState``'s history, or part of the step of its ``action``; ``POST /api/undo`` and
``POST /api/redo`` move through it and answer the graph and the scene.
"""
from __future__ import annotations

import asyncio
import html
import json
import logging
import re
import time
from importlib import resources

import anyio
from starlette.applications import Starlette
from starlette.exceptions import HTTPException
from starlette.requests import Request
from starlette.responses import FileResponse, HTMLResponse, JSONResponse, PlainTextResponse, StreamingResponse
from starlette.routing import Route

from pixgraph.events import Cancelled, CancelToken
from . import files, scene
from .encode import encode_exr, encode_jpeg, encode_png
from .errors import STATUS, RunTimeout, ServeError, serve_error
from .guard import Guard, media_type
from .history import History
from .runs import Encoded, Renders, Runs
from .state import ServeState, check_depth

log = logging.getLogger("pixgraph.serve")
STATIC = resources.files("pixgraph_serve") / "static"
STATIC_NAME = re.compile(r"^[a-z][a-z0-9_]{0,40}\.(js|css)$")
UPLOAD_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.\-]{0,100}\.(png|jpg|jpeg|tif|tiff|exr)$", re.I)
YAML_TYPES = ("application/yaml", "application/x-yaml", "text/yaml", "text/x-yaml", "application/json")
#: streamed responses are sent in pieces of this size, each when the client has taken the last [bytes]
CHUNK = 256 << 10
NO_STORE = {"Cache-Control": "no-store"}


# -- helpers (each request's state is request.app.state) -----------------------------------

def _serve(request: Request) -> ServeState:
    return request.app.state.serve


async def locked(request: Request, fn, *args):
    """``fn(*args)`` on a worker thread, holding the run lock."""
    async with request.app.state.lock:
        return await anyio.to_thread.run_sync(lambda: fn(*args))


async def read_body(request: Request, limit: int | None = None) -> bytes:
    """The body, at most ``limit`` bytes (default ``Limits.max_body_bytes``): 413 over it."""
    hint = "(pixgraph serve --max-body BYTES raises it)" if limit is None else "(a JSON body's limit)"
    limit = _serve(request).limits.max_body_bytes if limit is None else limit
    declared = request.headers.get("content-length")
    if declared is not None and declared.isascii() and declared.isdigit() and int(declared) > limit:
        raise ServeError(413, f"request body of {declared} bytes is over the limit of {limit} {hint}")
    chunks, size = [], 0
    async for chunk in request.stream():
        size += len(chunk)
        if size > limit:
            raise ServeError(413, f"request body is over the limit of {limit} bytes {hint}")
        chunks.append(chunk)
    return b"".join(chunks)


async def json_body(request: Request) -> dict:
    """The request's JSON object ({} for an empty body); 415 unless sent as application/json."""
    if media_type(request.headers.get("content-type", "")) != "application/json":
        raise ServeError(415, "the request body must be JSON sent as Content-Type: application/json")
    raw = await read_body(request, min(_serve(request).limits.max_json_bytes, _serve(request).limits.max_body_bytes))
    if not raw.strip():
        return {}
    # parsed and checked on a worker thread: a large body (a million values take
    # seconds) must not stop the event loop, which answers every other client
    return await anyio.to_thread.run_sync(parse_json, raw)


def parse_json(raw: bytes) -> dict:
    try:
        data = json.loads(raw)
    except (ValueError, UnicodeDecodeError) as e:
        raise ServeError(400, f"request body is not valid JSON: {e}") from None
    except RecursionError:
        raise ServeError(400, "request body is nested too deeply") from None
    if not isinstance(data, dict):
        raise ServeError(400, "request body must be a JSON object")
    check_depth(data)
    return data


def apply_edits(state: ServeState, data: dict) -> None:
    """A request's node type switches, light handle drags and params, all or nothing;
    one undo step, or part of the step of its ``action`` (the page's id of one user
    action: a drag's previews and its final carry the same) of its ``client``."""
    def apply():
        types = data.get("types") or {}
        if not isinstance(types, dict):
            raise ServeError(400, "types must be an object of node id: type id", field="types")
        for nid, tid in types.items():
            state.set_type(str(nid), str(tid))
        if "light_tip" in data or "light_elevation" in data:
            state.set_params(scene.light_edits(state, data.get("light_tip"), data.get("light_elevation")))
        if data.get("params"):
            # the light's azimuth/elevation last: in the tip placement they move the tip
            params, angles, touched = scene.light_angle_edits(state, data["params"])
            state.set_params(params)
            if angles or touched:
                state.set_params(scene.angle_edits(state, angles, touched))

    state.edit(apply, step=True, action=data.get("action"), client=data.get("client"))


def edited_run(state: ServeState, work):
    """``work()`` (a request's edits, then a run of the edited graph), all or nothing: when
    the run fails (a node refuses the edited params, the time limit) the graph goes back to
    what it was, so a drag the graph cannot take (a cutout off the photo) does not leave
    every later render, ``/api/scene`` and a reload of the page failing on it. A run
    cancelled by a newer render of the page keeps its edits (the newer one carries only
    its own)."""
    return state.edit(work, keep_on=(Cancelled,))


def outputs_of(data: dict) -> list[str] | None:
    outs = data.get("outputs")
    if outs is None:
        return None
    if isinstance(outs, str):
        outs = [outs]
    if not isinstance(outs, list) or not all(isinstance(o, str) for o in outs):
        raise ServeError(400, "outputs must be a list of output names", field="outputs")
    return outs


def streamed(data: bytes, media: str, headers: dict | None = None) -> StreamingResponse:
    """``data`` sent in ``CHUNK`` pieces: a slow client holds one piece, not a copy of all."""
    async def pieces():
        view = memoryview(data)
        for i in range(0, len(view), CHUNK):
            yield bytes(view[i:i + CHUNK])

    return StreamingResponse(pieces(), media_type=media,
                             headers={"Content-Length": str(len(data)), **NO_STORE, **(headers or {})})


def run_counted(state: ServeState, work):
    """``work()``'s result and how many graph runs it made."""
    before = state.runs
    out = work()
    return out, state.runs - before


# -- routes ------------------------------------------------------------------------------

async def index(request: Request):
    page = (STATIC / "index.html").read_text(encoding="utf-8")
    token = request.app.state.token
    if token is not None:
        page = page.replace("<head>", f'<head>\n<meta name="pixgraph-token" content="{html.escape(token)}">', 1)
    response = HTMLResponse(page, headers=NO_STORE)
    if token is not None:
        response.set_cookie(request.app.state.guard.cookie, token, httponly=True, samesite="strict", path="/")
    return response


async def static(request: Request):
    name = request.path_params["name"]
    if not STATIC_NAME.match(name) or not (STATIC / name).is_file():
        raise ServeError(404, f"no static file {name!r}")
    media = "text/javascript" if name.endswith(".js") else "text/css"
    return FileResponse(str(STATIC / name), media_type=media, headers=NO_STORE)


async def graph_info(request: Request):
    return JSONResponse(_serve(request).info())


async def graph_yaml(request: Request):
    return PlainTextResponse(_serve(request).yaml(), media_type="application/yaml")


async def post_graph(request: Request):
    if media_type(request.headers.get("content-type", "")) not in YAML_TYPES:
        raise ServeError(415, "a posted graph is sent as Content-Type: application/yaml")
    raw = await read_body(request)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise ServeError(400, "graph text must be UTF-8") from None
    state = _serve(request)
    await locked(request, lambda: state.edit(lambda: state.load_text(text), step=True))
    return JSONResponse(state.info())


async def nodes(request: Request):
    from pixgraph.reference import as_dict

    return JSONResponse({"types": [as_dict(s) for s in _serve(request).registry.specs()]})


async def scene_info(request: Request):
    return JSONResponse(await locked(request, scene.describe, _serve(request)))


async def post_params(request: Request):
    data = await json_body(request)
    state = _serve(request)
    await locked(request, apply_edits, state, data)
    return JSONResponse({"ok": True, "yaml": state.yaml()})


async def post_run(request: Request):
    data = await json_body(request)
    outs = outputs_of(data)
    mode = data.get("mode", "final")
    state = _serve(request)

    def work():
        apply_edits(state, data)
        graph = state.graph
        return graph, state.run(outs, mode)

    # a run a node refuses takes its edits back with it (edited_run)
    (graph, res), _ = await locked(request, run_counted, state, lambda: edited_run(state, work))
    # off the event loop: a new graph's bytes are estimated (graph_bytes, linear in its size)
    run = await anyio.to_thread.run_sync(request.app.state.runs.add, graph, mode, res.outputs)
    described = {}
    for name, v in res.outputs.items():
        described[name] = {"shape": list(getattr(v, "shape", ())),
                           "dtype": str(getattr(v, "dtype", type(v).__name__)),
                           "png": f"/api/outputs/{name}.png?run={run.id}",
                           "exr": f"/api/outputs/{name}.exr?run={run.id}"}
    return JSONResponse({"run": run.id, "ran": list(res.ran), "cached": list(res.cached),
                         "seconds": {k: round(t, 6) for k, t in res.timings.items()}, "outputs": described})


async def get_output(request: Request):
    """One output of a run (``?run=ID``), or of the current graph without it (the
    page's download link); encoded once per run, output, format and scale."""
    name, _, fmt = request.path_params["name"].rpartition(".")
    if fmt not in ("png", "exr") or not name:
        raise ServeError(404, "outputs are fetched as NAME.png or NAME.exr")
    scale = request.query_params.get("scale", "1")
    if not (scale.isascii() and scale.isdigit()) or not 1 <= int(scale) <= 16:     # '²' isdigit, int() refuses it
        raise ServeError(400, f"scale must be an integer 1..16, got {scale!r}", field="scale")
    app, state = request.app.state, _serve(request)
    run_id = request.query_params.get("run")

    def work():
        if run_id is not None:
            run = app.runs.get(run_id)
        else:
            mode = request.query_params.get("mode", "final")
            state.graph_for(mode)  # checks the mode
            cur = app.current.get(mode)
            if cur is None or cur.graph is not state.graph:
                cur = app.current[mode] = app.runs.add(state.graph, mode, ())
            run = cur
        key = (run.id, name, fmt, int(scale))
        data = app.encoded.get(key)
        if data is None:
            value = state.run([name], run.mode, graph=run.graph)[name]
            data = (encode_png(value, name, int(scale)) if fmt == "png"
                    else encode_exr(state.session, state.graph_for(run.mode, run.graph), value, name))
            del value
            app.encoded.put(key, data)
        return data

    data = await locked(request, work)
    return streamed(data, "image/png" if fmt == "png" else "image/x-exr")


async def render(request: Request):
    """Edit and render one output as PNG (or ``format: "jpeg"``, the page's previews while
    a handle moves) in one request: what the page sends while dragging."""
    t0 = time.perf_counter()
    data = await json_body(request)
    mode = data.get("mode", "final")
    name = data.get("output", "final")
    if not isinstance(name, str):
        raise ServeError(400, "output must be an output name", field="output")
    state = _serve(request)
    scale = data.get("scale", state.limits.preview_scale if mode == "preview" else 1)
    if isinstance(scale, bool) or not isinstance(scale, int) or not 1 <= scale <= 16:
        raise ServeError(400, f"scale must be an integer 1..16, got {scale!r}", field="scale")
    # a preview may run the whole graph at a working resolution (params in px scaled with it)
    working = data.get("work", 1.0) if mode == "preview" else 1.0
    if isinstance(working, bool) or not isinstance(working, (int, float)) or not 0.01 <= working <= 1:
        raise ServeError(400, f"work must be a working resolution in [0.01, 1], got {working!r}", field="work")
    fmt = data.get("format", "png")
    if fmt not in ("png", "jpeg"):
        raise ServeError(400, f"format must be 'png' or 'jpeg', got {fmt!r}", field="format")
    encode = encode_png if fmt == "png" else encode_jpeg
    client, seq = data.get("client"), data.get("seq")
    tracked = client is not None
    renders: Renders = request.app.state.renders
    if tracked:
        _check_client(client, seq)
        if not renders.claim(client, seq):
            return _stale(renders, seq)
    async with request.app.state.lock:
        if tracked and not renders.current(client, seq):
            return _stale(renders, seq)  # superseded while it waited: never run it
        token = CancelToken()
        if tracked:
            renders.tokens[client] = token

        def work():
            apply_edits(state, data)
            graph = state.graph_for(mode)
            anchor_refs = scene.piggyback(state, graph, [name])
            extra = anchor_refs if working == 1 else []   # anchors are full-size px
            tips = scene.tip_refs(state, graph, [name], anchor_refs)   # the light's handle, at any working resolution
            try:
                res = state.run(list(dict.fromkeys([name, *extra, *tips])), mode, cancel=token, scale=float(working))
            except ServeError as e:
                if working == 1:
                    raise
                # a node's sizes and pixel values are the working resolution's: say so
                raise ServeError(e.status, f"in a preview at working resolution {float(working):.3g} (its sizes and "
                                           f"pixel values are scaled by it): {e.message}", **e.where) from None
            scene.note(state, graph, extra, res)
            if mode == "final":
                state.final_said = res.said
            return res, encode(res[name], name, scale), scene.shown_tip(state, graph, tips, res, float(working))

        try:
            (res, png, tip), runs = await anyio.to_thread.run_sync(run_counted, state, lambda: edited_run(state, work))
        except Cancelled:
            if tracked and not renders.current(client, seq):
                return _stale(renders, seq)
            raise
        finally:
            if tracked and renders.tokens.get(client) is token:
                del renders.tokens[client]
    return streamed(png, f"image/{fmt}", {
        "X-Pixgraph-Seq": str(seq if tracked else ""), "X-Pixgraph-Mode": mode,
        "X-Pixgraph-Ran": ",".join(res.ran), "X-Pixgraph-Cached": ",".join(res.cached),
        "X-Pixgraph-Runs": str(runs), "X-Pixgraph-Seconds": f"{time.perf_counter() - t0:.4f}",
        # the light's handle as this render puts it: tip u, v, top u, v [full-size px]
        **({"X-Pixgraph-Tip": ",".join(map(str, tip))} if tip else {})})


def _check_client(client, seq) -> None:
    """A page's ``client`` (a string of at most ``history.MAX_ACTION`` characters, as its
    edits' ``action``: checked before the server keeps it) and its render's ``seq``."""
    History.check_action(None, client)
    if isinstance(seq, bool) or not isinstance(seq, int):
        raise ServeError(400, f"seq must be an integer, got {seq!r}", field="seq")


async def undo(request: Request):
    """Back to the graph before the newest step (``ServeState.undo``); 409 with nothing to undo."""
    return await _history_move(request, "undo")


async def redo(request: Request):
    """Forward to the graph the newest undo left; 409 with nothing to redo."""
    return await _history_move(request, "redo")


async def _history_move(request: Request, which: str):
    """Undo or redo, answered with the restored graph (``GET /api/graph``'s), its handles
    (``GET /api/scene``'s; when the scene cannot be described, ``scene`` is null and
    ``scene_error`` says why) and its YAML, so a client redraws without asking again.
    Files on disk are never touched: a saved graph stays as saved. ``client`` and ``seq``
    (optional, as in ``/api/render``) supersede that page's renders; ``"scene": false``
    leaves the scene out (``scene`` null)."""
    data = await json_body(request)      # a JSON POST like every other edit (415 otherwise); {} or empty
    state = _serve(request)
    with_scene = data.get("scene", True)
    if not isinstance(with_scene, bool):
        raise ServeError(400, "scene must be true or false", field="scene")
    client, seq = data.get("client"), data.get("seq")
    if client is not None:
        # the page's client and a new seq: its render still running (of the state being left)
        # is cancelled rather than waited for, as a newer render would cancel it
        _check_client(client, seq)
        if state.history()[which]:    # nothing to move: leave its render alone (the answer is a 409)
            request.app.state.renders.claim(client, seq)

    def work():
        getattr(state, which)()
        described, error = None, None
        try:
            # the scene may run nodes at full size (a 20 MP photo: seconds): the page asks
            # without it, shows a preview first and asks for the scene after
            described = scene.describe(state) if with_scene else None
        except (ServeError, RunTimeout) as e:
            error = serve_error(e).to_json()
        return {which: True, "history": state.history(), "graph": state.info(), "scene": described,
                "scene_error": error, "yaml": state.yaml()}

    return JSONResponse(await locked(request, work))


async def save(request: Request):
    data = await json_body(request)
    path = data.get("path")
    if path is not None and not isinstance(path, str):
        raise ServeError(400, "path must be a string", field="path")
    state = _serve(request)
    target = await locked(request, state.save, path)
    return JSONResponse({"path": target, "yaml": state.yaml()})


async def upload(request: Request):
    """Store an uploaded image in the upload folder (an allowed root); returns its path."""
    fname = request.path_params["name"]
    if not UPLOAD_NAME.match(fname):
        raise ServeError(400, f"upload name {fname!r}: letters, digits, '._-' and an image extension",
                         field="name")
    raw = await read_body(request)
    path, n = await anyio.to_thread.run_sync(_serve(request).store_upload, fname, raw)
    return JSONResponse({"path": path, "pixels": n})


async def status(request: Request):
    """What the server is doing: runs in progress, graph runs so far, requests the guard
    refused, output files encoded (a client can wait on these instead of sleeping)."""
    app = request.app.state
    return JSONResponse({"running": app.serve.running(), "runs": app.serve.runs,
                         "refused": app.guard.refused, "encoded": app.encoded.encodes})


def _stale(renders: Renders, seq) -> JSONResponse:
    renders.dropped += 1
    return JSONResponse({"error": "stale: a newer render of this client superseded it", "seq": seq},
                        status_code=409)


ROUTES = [
    Route("/", index),
    Route("/static/{name}", static),
    Route("/api/graph", graph_info, methods=["GET"]),
    Route("/api/graph", post_graph, methods=["POST"]),
    Route("/api/graph.yaml", graph_yaml),
    Route("/api/nodes", nodes),
    Route("/api/scene", scene_info),
    Route("/api/status", status),
    Route("/api/params", post_params, methods=["POST"]),
    Route("/api/run", post_run, methods=["POST"]),
    Route("/api/outputs/{name}", get_output),
    Route("/api/render", render, methods=["POST"]),
    Route("/api/save", save, methods=["POST"]),
    Route("/api/undo", undo, methods=["POST"]),
    Route("/api/redo", redo, methods=["POST"]),
    Route("/api/uploads/{name}", upload, methods=["PUT"]),
    *files.routes(locked, json_body),
]


# -- errors: one table (errors.STATUS) -----------------------------------------------------

async def on_error(request: Request, exc: Exception):
    if isinstance(exc, HTTPException):
        return JSONResponse({"error": exc.detail or "error"}, status_code=exc.status_code)
    err = serve_error(exc)
    if err.status == 500 and not isinstance(exc, ServeError):
        log.error("internal error on %s %s: %s: %s", request.method, request.url.path, type(exc).__name__, exc)
    return JSONResponse(err.to_json(), status_code=err.status)


def create_app(state: ServeState, *, token: str | None = None, port: int | None = None,
               names=()) -> Guard:
    """The application behind ``Guard``. token: the per-launch token (None: no token);
    port, names: the bound port and host name a request's Host must name (``serve``
    always gives them; without ``port``, for an in-process app, the Host is not checked)."""
    # every class of the table answers through the same handler; Exception (a 500) too,
    # after which Starlette re-raises it for the server's log
    handlers = {cls: on_error for cls, _ in STATUS}
    handlers.update({HTTPException: on_error, ServeError: on_error, Exception: on_error})
    app = Starlette(routes=ROUTES, exception_handlers=handlers)
    app.state.serve = state
    app.state.lock = asyncio.Lock()
    app.state.renders = Renders()
    app.state.runs = Runs()
    app.state.encoded = Encoded()
    app.state.current = {}
    app.state.token = token
    app.state.guard = Guard(app, port=port, names=names, token=token)
    return app.state.guard
