"""Bind, serve, and stop promptly: ``serve(state, host, port, on_ready)``.

SIGTERM and SIGINT (Ctrl-C) stop the server at once, even mid-render: when a run
is going, it is cancelled and the process ends right there (``os._exit(0)``):
waiting for a node to notice the cancellation, or for asyncio to wait for the
node's thread, took up to a second or more. Without a run, uvicorn closes its
sockets, and the process ends without the interpreter's teardown (half a second
with torch and OpenCL loaded); ``STOP_GRACE`` seconds after the signal it ends in
any case. Graph saves, uploads and written outputs go to a temporary name
and are renamed, so a stop leaves at most a temporary file, never half a file
under the real name. The upload folder the server made (the photos opened in the
page) is removed on every way out.
"""
from __future__ import annotations

import os
import secrets
import socket
import sys
import threading

from .app import create_app
from .state import ServeState

#: seconds between a stop signal and the hard exit when a node does not stop by itself
STOP_GRACE = 0.5


def new_token() -> str:
    """A per-launch token: 32 random bytes, URL-safe."""
    return secrets.token_urlsafe(32)


def serve(state: ServeState, host: str = "127.0.0.1", port: int = 8765, on_ready=None,
          token: str | None = None) -> None:
    """Bind ``host:port`` (port 0 picks a free one), call ``on_ready(url)`` with the URL
    to open (carrying ``?token=`` unless ``token`` is None), serve until SIGTERM/SIGINT."""
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
    app = create_app(state, token=token, port=bound, names=(host,))

    class Server(uvicorn.Server):
        def handle_exit(self, sig, frame):  # runs in the main thread, on the signal
            self.should_exit = self.force_exit = True
            if state.cancel_all():
                _exit_now(state)     # a run is going: nothing to wait for (saves and uploads are renamed into place)
            threading.Thread(target=_exit_after, args=(STOP_GRACE, state), daemon=True).start()

        async def shutdown(self, sockets=None):
            await super().shutdown(sockets)
            if self.force_exit and state.running():
                # a node still busy: asyncio.run would wait for its thread before returning
                _exit_now(state)

    config = uvicorn.Config(app, log_level="warning", access_log=False, lifespan="off",
                            limit_concurrency=64, timeout_keep_alive=30)
    server = Server(config)
    if on_ready is not None:
        on_ready(f"http://{shown}:{bound}/" + (f"?token={token}" if token else ""))
    try:
        server.run(sockets=[sock])
    finally:
        state.remove_uploads()
    if server.force_exit:       # stopped by a signal: skip the interpreter's teardown (0.5 s with torch loaded)
        _exit_now(state)


def _exit_after(seconds: float, state: ServeState) -> None:
    threading.Event().wait(seconds)
    _exit_now(state)


def _exit_now(state: ServeState | None = None) -> None:
    if state is not None:
        state.remove_uploads()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(0)
