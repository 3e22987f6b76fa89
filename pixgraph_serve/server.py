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
#: seconds a connection may take to send a request's headers, from its opening or the
#: first byte of its next request; then it is closed (a client that sends half a
#: request and waits, a "slow-loris", held a connection for ever)
HEADER_SECONDS = 10.0
#: requests in progress at once; more are answered 503 at once. Connections are not
#: counted: idle or half-sent ones cost no more than a socket (uvicorn's
#: ``limit_concurrency`` counted them, so 64 half-sent requests locked the page out)
MAX_IN_FLIGHT = 64


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

    config = uvicorn.Config(InFlight(app, MAX_IN_FLIGHT), log_level="warning", access_log=False, lifespan="off",
                            http=_header_deadline_protocol(), timeout_keep_alive=30)
    server = Server(config)
    if on_ready is not None:
        on_ready(f"http://{shown}:{bound}/" + (f"?token={token}" if token else ""))
    try:
        server.run(sockets=[sock])
    finally:
        state.remove_uploads()
    if server.force_exit:       # stopped by a signal: skip the interpreter's teardown (0.5 s with torch loaded)
        _exit_now(state)


class InFlight:
    """ASGI wrapper: at most ``limit`` HTTP requests in progress; one more is answered
    503 at once."""

    def __init__(self, app, limit: int):
        self.app, self.limit, self.running = app, limit, 0

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        if self.running >= self.limit:
            body = b'{"error": "the server is busy: too many requests at once"}'
            await send({"type": "http.response.start", "status": 503,
                        "headers": [(b"content-type", b"application/json"),
                                    (b"content-length", str(len(body)).encode())]})
            return await send({"type": "http.response.body", "body": body})
        self.running += 1
        try:
            await self.app(scope, receive, send)
        finally:
            self.running -= 1


def _header_deadline_protocol():
    """uvicorn's h11 protocol, closing a connection whose request headers have not
    arrived ``HEADER_SECONDS`` after it opened, or after the first byte of its next
    request. (uvicorn has no such limit: its keep-alive timer, which still closes a
    connection idle after a response, stops at the first byte received, and a
    connection that never sends anything was never timed.)"""
    from uvicorn.protocols.http.h11_impl import H11Protocol

    class HeaderDeadline(H11Protocol):
        _deadline = None

        def _waiting(self) -> bool:
            return self.cycle is None or self.cycle.response_complete   # no request in progress

        def connection_made(self, transport):
            super().connection_made(transport)
            self._arm()

        def data_received(self, data):
            if self._deadline is None and self._waiting():
                self._arm()        # the first byte of a next request on a kept-alive connection
            super().data_received(data)

        def on_response_complete(self):
            self._disarm()         # idle from here: uvicorn's keep-alive timer
            super().on_response_complete()

        def connection_lost(self, exc):
            self._disarm()
            super().connection_lost(exc)

        def _arm(self):
            self._disarm()
            self._deadline = self.loop.call_later(HEADER_SECONDS, self._late)

        def _disarm(self):
            if self._deadline is not None:
                self._deadline.cancel()
                self._deadline = None

        def _late(self):
            self._deadline = None
            if self._waiting() and not self.transport.is_closing():
                self.transport.close()

    return HeaderDeadline


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
