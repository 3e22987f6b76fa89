"""The HTTP API and the page, as a Starlette application over one ``ServeState``.

Every error is JSON ``{"error": "...", "node": ..., "field": ...}`` with a 4xx
status (413 for bodies or images over the limits, 403 for paths outside the
allowed folders, 409 for a render superseded by a newer one); an unexpected
failure is a 500 with a one-line JSON message, never a traceback.

Runs go through one lock, on a worker thread. Renders from the page carry a
client id and a sequence number: a render that a newer one of the same client
has superseded is dropped (409 ``stale``) when it would start, and cancelled
(through its ``CancelToken``) when it is running, so drags never queue work.
"""
from __future__ import annotations

import asyncio
import json
import logging
import os
import re
import time
from importlib import resources

import anyio
from starlette.applications import Starlette
from starlette.exceptions import HTTPException
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, PlainTextResponse, Response
from starlette.routing import Route

from pixgraph.events import Cancelled, CancelToken
from . import files, scene
from .state import ServeError, ServeState, encode_exr, encode_png

log = logging.getLogger("pixgraph.serve")
STATIC = resources.files("pixgraph_serve") / "static"
STATIC_NAME = re.compile(r"^[a-z][a-z0-9_]{0,40}\.(js|css)$")
UPLOAD_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.\-]{0,100}\.(png|jpg|jpeg|tif|tiff|exr)$", re.I)


class _Renders:
    """Per-client newest sequence number and the token of its running render."""

    def __init__(self):
        self.latest: dict[str, int] = {}
        self.tokens: dict[str, CancelToken] = {}
        self.dropped = 0

    def claim(self, client: str, seq: int) -> bool:
        """Record ``seq`` as the client's newest; False when a newer one came first."""
        if seq <= self.latest.get(client, -1):
            return False
        self.latest[client] = seq
        token = self.tokens.get(client)
        if token is not None:
            token.cancel()  # its result would be stale: stop it
        return True

    def current(self, client: str, seq: int) -> bool:
        return self.latest.get(client) == seq


def create_app(state: ServeState) -> Starlette:
    lock = asyncio.Lock()
    renders = _Renders()

    async def locked(fn, *args, **kw):
        async with lock:
            return await anyio.to_thread.run_sync(lambda: fn(*args, **kw))

    async def body(request: Request) -> bytes:
        limit = state.limits.max_body_bytes
        declared = request.headers.get("content-length")
        if declared is not None and declared.isdigit() and int(declared) > limit:
            raise ServeError(413, f"request body of {declared} bytes is over the limit of {limit}")
        chunks, size = [], 0
        async for chunk in request.stream():
            size += len(chunk)
            if size > limit:
                raise ServeError(413, f"request body is over the limit of {limit} bytes")
            chunks.append(chunk)
        return b"".join(chunks)

    async def json_body(request: Request) -> dict:
        raw = await body(request)
        if not raw.strip():
            return {}
        try:
            data = json.loads(raw)
        except (ValueError, UnicodeDecodeError) as e:
            raise ServeError(400, f"request body is not valid JSON: {e}") from None
        if not isinstance(data, dict):
            raise ServeError(400, "request body must be a JSON object")
        return data

    def edit(data: dict) -> None:
        """Apply a request's node type switches, light handle drags and params."""
        types = data.get("types") or {}
        if not isinstance(types, dict):
            raise ServeError(400, "types must be an object of node id: type id", field="types")
        for nid, tid in types.items():
            state.set_type(str(nid), str(tid))
        if "light_tip" in data or "light_elevation" in data:
            edits = scene.light_edits(state, data.get("light_tip"), data.get("light_elevation"))
            state.set_params(edits)
        if data.get("params"):
            state.set_params(data["params"])

    def outputs_of(data: dict) -> list[str] | None:
        outs = data.get("outputs")
        if outs is None:
            return None
        if isinstance(outs, str):
            outs = [outs]
        if not isinstance(outs, list) or not all(isinstance(o, str) for o in outs):
            raise ServeError(400, "outputs must be a list of output names", field="outputs")
        return outs

    # -- routes -----------------------------------------------------------------

    async def index(request):
        return FileResponse(str(STATIC / "index.html"), headers={"Cache-Control": "no-store"})

    async def static(request):
        name = request.path_params["name"]
        if not STATIC_NAME.match(name) or not (STATIC / name).is_file():
            raise ServeError(404, f"no static file {name!r}")
        media = "text/javascript" if name.endswith(".js") else "text/css"
        return FileResponse(str(STATIC / name), media_type=media, headers={"Cache-Control": "no-store"})

    async def graph_info(request):
        return JSONResponse(state.info())

    async def graph_yaml(request):
        return PlainTextResponse(state.yaml(), media_type="application/yaml")

    async def post_graph(request):
        raw = await body(request)
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError:
            raise ServeError(400, "graph text must be UTF-8") from None
        await locked(state.load_text, text)
        return JSONResponse(state.info())

    async def nodes(request):
        from pixgraph.reference import as_dict

        return JSONResponse({"types": [as_dict(s) for s in state.registry.specs()]})

    async def scene_info(request):
        return JSONResponse(await locked(scene.describe, state))

    async def post_params(request):
        data = await json_body(request)
        await locked(edit, data)
        return JSONResponse({"ok": True, "yaml": state.yaml()})

    async def post_run(request):
        data = await json_body(request)
        outs = outputs_of(data)
        mode = data.get("mode", "final")
        async with lock:
            values, res = await anyio.to_thread.run_sync(lambda: (edit(data), state.run(outs, mode))[1])
        described = {}
        for name, v in values.items():
            shape = list(getattr(v, "shape", ()))
            described[name] = {"shape": shape, "dtype": str(getattr(v, "dtype", type(v).__name__)),
                               "png": f"/api/outputs/{name}.png?mode={mode}",
                               "exr": f"/api/outputs/{name}.exr?mode={mode}"}
        return JSONResponse({"ran": list(res.ran), "cached": list(res.cached),
                             "seconds": {k: round(t, 6) for k, t in res.timings.items()},
                             "outputs": described})

    async def get_output(request):
        name, _, fmt = request.path_params["name"].rpartition(".")
        if fmt not in ("png", "exr") or not name:
            raise ServeError(404, "outputs are fetched as NAME.png or NAME.exr")
        mode = request.query_params.get("mode", "final")
        scale = request.query_params.get("scale", "1")
        if not scale.isdigit() or not 1 <= int(scale) <= 16:
            raise ServeError(400, f"scale must be an integer 1..16, got {scale!r}", field="scale")
        values, _ = await locked(state.run, [name], mode)
        if fmt == "png":
            data = await anyio.to_thread.run_sync(lambda: encode_png(values[name], name, int(scale)))
            return Response(data, media_type="image/png")
        data = await anyio.to_thread.run_sync(lambda: encode_exr(values[name], name))
        return Response(data, media_type="image/x-exr")

    async def render(request):
        """Edit and render one output as PNG in one request: what the page sends while dragging."""
        t0 = time.perf_counter()
        data = await json_body(request)
        mode = data.get("mode", "final")
        name = data.get("output", "final")
        if not isinstance(name, str):
            raise ServeError(400, "output must be an output name", field="output")
        scale = data.get("scale", state.limits.preview_scale if mode == "preview" else 1)
        if isinstance(scale, bool) or not isinstance(scale, int) or not 1 <= scale <= 16:
            raise ServeError(400, f"scale must be an integer 1..16, got {scale!r}", field="scale")
        client, seq = data.get("client"), data.get("seq")
        tracked = client is not None
        if tracked:
            if not isinstance(client, str) or isinstance(seq, bool) or not isinstance(seq, int):
                raise ServeError(400, "client must be a string and seq an integer", field="seq")
            if not renders.claim(client, seq):
                return _stale(renders, seq)
        async with lock:
            if tracked and not renders.current(client, seq):
                return _stale(renders, seq)  # superseded while it waited: never run it
            token = CancelToken()
            if tracked:
                renders.tokens[client] = token

            def work():
                edit(data)
                return state.run([name], mode, cancel=token)

            try:
                values, res = await anyio.to_thread.run_sync(work)
            except Cancelled:
                return _stale(renders, seq)
            finally:
                if tracked and renders.tokens.get(client) is token:
                    del renders.tokens[client]
        png = await anyio.to_thread.run_sync(lambda: encode_png(values[name], name, scale))
        return Response(png, media_type="image/png", headers={
            "X-Pixgraph-Seq": str(seq if tracked else ""), "X-Pixgraph-Mode": mode,
            "X-Pixgraph-Ran": ",".join(res.ran), "X-Pixgraph-Cached": ",".join(res.cached),
            "X-Pixgraph-Seconds": f"{time.perf_counter() - t0:.4f}", "Cache-Control": "no-store"})

    async def save(request):
        data = await json_body(request)
        path = data.get("path")
        if path is not None and not isinstance(path, str):
            raise ServeError(400, "path must be a string", field="path")
        target = await locked(state.save, path)
        return JSONResponse({"path": target, "yaml": state.yaml()})

    async def upload(request):
        """Store an uploaded image in the upload folder (an allowed root); returns its path."""
        fname = request.path_params["name"]
        if not UPLOAD_NAME.match(fname):
            raise ServeError(400, f"upload name {fname!r}: letters, digits, '._-' and an image extension",
                             field="name")
        raw = await body(request)
        path = os.path.join(state.upload_dir, fname)
        tmp = path + ".part"
        with open(tmp, "wb") as f:
            f.write(raw)
        try:
            n = state._image_pixels(tmp)
            if n > state.limits.max_pixels:
                raise ServeError(413, f"uploaded image of {n} pixels is over the server's limit of "
                                      f"{state.limits.max_pixels}")
        except ServeError:
            os.unlink(tmp)
            raise
        os.replace(tmp, path)
        return JSONResponse({"path": path, "pixels": n})

    routes = [
        Route("/", index),
        Route("/static/{name}", static),
        Route("/api/graph", graph_info, methods=["GET"]),
        Route("/api/graph", post_graph, methods=["POST"]),
        Route("/api/graph.yaml", graph_yaml),
        Route("/api/nodes", nodes),
        Route("/api/scene", scene_info),
        Route("/api/params", post_params, methods=["POST"]),
        Route("/api/run", post_run, methods=["POST"]),
        Route("/api/outputs/{name}", get_output),
        Route("/api/render", render, methods=["POST"]),
        Route("/api/save", save, methods=["POST"]),
        Route("/api/uploads/{name}", upload, methods=["PUT"]),
        *files.routes(state, locked, json_body),
    ]

    async def serve_error(request, exc: ServeError):
        return JSONResponse(exc.to_json(), status_code=exc.status)

    async def http_error(request, exc: HTTPException):
        return JSONResponse({"error": exc.detail or "error"}, status_code=exc.status_code)

    async def internal_error(request, exc: Exception):
        log.error("internal error on %s %s: %s: %s", request.method, request.url.path, type(exc).__name__, exc)
        msg = f"internal error: {type(exc).__name__}: {exc}".splitlines()[0]
        return JSONResponse({"error": msg}, status_code=500)

    return Starlette(routes=routes, exception_handlers={
        ServeError: serve_error, HTTPException: http_error, Exception: internal_error})


def _stale(renders: _Renders, seq) -> JSONResponse:
    renders.dropped += 1
    return JSONResponse({"error": "stale: a newer render of this client superseded it", "seq": seq},
                        status_code=409)


def serve(state: ServeState, host: str = "127.0.0.1", port: int = 8765, on_ready=None) -> None:
    """Bind ``host:port`` (port 0 picks a free one), call ``on_ready(url)``, serve until Ctrl-C."""
    import socket

    import uvicorn

    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    # proto IPPROTO_TCP, not 0: asyncio sets TCP_NODELAY only on sockets that say they
    # are TCP, and without it every keep-alive response waits ~40 ms (Nagle + delayed ACK)
    sock = socket.socket(family, socket.SOCK_STREAM, socket.IPPROTO_TCP)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    sock.bind((host, port))
    sock.listen(64)
    bound = sock.getsockname()[1]
    shown = f"[{host}]" if family == socket.AF_INET6 else host
    config = uvicorn.Config(create_app(state), log_level="warning", access_log=False, lifespan="off",
                            limit_concurrency=64, timeout_keep_alive=30)
    server = uvicorn.Server(config)
    if on_ready is not None:
        on_ready(f"http://{shown}:{bound}/")
    server.run(sockets=[sock])
