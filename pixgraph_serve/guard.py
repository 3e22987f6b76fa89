"""What keeps other web pages out: every request passes ``Guard`` before a route.

A page the user visits in the same browser can send requests to 127.0.0.1, and a
page on a domain that the attacker points at 127.0.0.1 (DNS rebinding) can even
read the answers. The guard refuses, before any route runs:

1. a ``Host`` header that is not this server: the port must be the bound port and
   the name an IP address, ``localhost`` or the name given to ``--host`` (a rebound
   domain is none of these): 403;
2. an ``Origin`` header other than this server's own origin (``http://`` + Host),
   ``null`` included: 403;
3. a ``Sec-Fetch-Site`` header other than ``same-origin`` or ``none`` (a request a
   browser made for another site, including another port of this machine): 403;
4. unless started with ``--no-token``: a request without the per-launch token. The
   page ``/`` takes it as ``?token=`` (the URL ``pixgraph serve`` prints) and then
   carries it in the ``X-Pixgraph-Token`` header of every request (the token is
   written into the page it serves; the page takes ``?token=`` out of the address
   bar at load) and in a cookie (``HttpOnly``, ``SameSite=Strict``, named
   ``pixgraph_token_PORT``) that counts for GET requests only (the page's download
   links, and a reload of the page, whose address has no token any more); scripts
   send the header or ``?token=``: 403;
5. a POST whose ``Content-Type`` is missing or one a page may send without asking
   the server first (``text/plain``, a form): 415. JSON routes need
   ``application/json`` (``app.py``). (A PUT, like any method but GET, HEAD and
   POST, is never sent cross-site without the server's consent, which it never gives.)

Before these, a request that carries ``Host``, ``Origin``, ``Sec-Fetch-Site``,
``Content-Type``, ``Cookie`` or the token header more than once is refused (400,
naming the header): each check reads one value, and a repeated header read by its
last value let ``Sec-Fetch-Site: cross-site`` be followed by ``same-origin``.

``/static/*`` (the page's own JS and CSS, no data) needs no token. Every answer
says ``X-Frame-Options: DENY`` and ``Referrer-Policy: no-referrer``.
"""
from __future__ import annotations

import ipaddress
import json
import secrets
from urllib.parse import parse_qs

TOKEN_HEADER = "x-pixgraph-token"
COOKIE = "pixgraph_token"
#: request content types a cross-site page can send without a CORS preflight
SIMPLE_TYPES = ("", "text/plain", "application/x-www-form-urlencoded", "multipart/form-data")
SAFE_SITES = ("same-origin", "none")
#: headers the checks read one value of: a request carrying one of them twice is refused
SINGLE = ("host", "origin", "sec-fetch-site", "content-type", "cookie", TOKEN_HEADER)


def media_type(value: str) -> str:
    return value.split(";", 1)[0].strip().lower()


def cookie_values(header: str, name: str) -> list[str]:
    """The values of the cookies called ``name`` in a ``Cookie`` header. Not
    ``SimpleCookie``: it drops every cookie of a header when one is not to its taste
    (a value with a space or JSON, a name without '='; browsers send them, and every
    local web app's cookies come to every port of 127.0.0.1)."""
    out = []
    for part in header.split(";"):
        key, sep, value = part.partition("=")
        if sep and key.strip() == name:
            out.append(value.strip())
    return out


def _is_ip(name: str) -> bool:
    try:
        ipaddress.ip_address(name.strip("[]"))
        return True
    except ValueError:
        return False


class Guard:
    """ASGI middleware: ``Guard(app, port=..., names=..., token=...)``.

    port: the bound port (a Host must carry it); None for an app this package does not
    bind (in-process, e.g. Starlette's test client): then the Host is not checked.
    names: host names accepted besides IP addresses and ``localhost``. token: the
    per-launch token, or None (``--no-token``).
    """

    def __init__(self, app, *, port: int | None = None, names=(), token: str | None = None):
        self.app = app
        self.port = port
        self.names = {"localhost", *(n.lower() for n in names if n and not _is_ip(n))}
        self.token = token
        #: the page's cookie, named by the port: cookies ignore ports, so another
        #: server on this machine would overwrite one shared name (a reload of the
        #: first server's page was refused)
        self.cookie = COOKIE if port is None else f"{COOKIE}_{port}"
        self.refused = 0

    def host_ok(self, host: str) -> bool:
        if host.startswith("["):                  # [IPv6]:port
            name, _, rest = host[1:].partition("]")
            if not rest.startswith(":"):
                return False
            port = rest[1:]
        else:
            name, sep, port = host.rpartition(":")
            if not sep or ":" in name:
                return False
        # ASCII digits ('²' is a digit to isdigit, not to int()), at most 5: int() of
        # over 4300 digits raises (a 500 from the guard, before the token is asked for)
        if not (port.isascii() and port.isdigit()) or len(port) > 5 or int(port) != self.port:
            return False
        name = name.lower()
        return name in self.names or _is_ip(name)

    def why_refused(self, scope) -> tuple[int, str] | None:
        headers = {}
        for k, v in scope["headers"]:
            name = k.decode("latin-1").lower()
            if name in headers and name in SINGLE:
                return 400, f"refused: the header {name!r} is sent more than once (the checks read one value)"
            headers[name] = v.decode("latin-1")
        host = headers.get("host", "")
        if self.port is not None and not self.host_ok(host):
            return 403, f"refused: Host {host!r} is not this server (DNS rebinding?)"
        origin = headers.get("origin")
        if origin is not None and origin.lower() != f"http://{host}".lower():
            return 403, f"refused: a request from another origin ({origin})"
        site = headers.get("sec-fetch-site")
        if site is not None and site.lower() not in SAFE_SITES:
            return 403, f"refused: a request a browser made for another site (Sec-Fetch-Site: {site})"
        path, method = scope["path"], scope["method"]
        if self.token is not None and not path.startswith("/static/"):
            if not self._has_token(headers, scope, allow_cookie=method in ("GET", "HEAD")):
                return 403, ("refused: no valid token; open the URL that pixgraph serve printed "
                             "(it ends in ?token=...), or send the X-Pixgraph-Token header")
        if method == "POST":    # the only method with a body a page can send unasked (PUT needs a preflight)
            if media_type(headers.get("content-type", "")) in SIMPLE_TYPES:
                return 415, ("refused: a request body needs its content type (application/json; "
                             "a graph may be application/yaml), not text/plain or a form")
        return None

    def _has_token(self, headers, scope, allow_cookie: bool) -> bool:
        given = headers.get(TOKEN_HEADER)
        if given is None:
            given = (parse_qs(scope.get("query_string", b"").decode("latin-1")).get("token") or [None])[0]
        if given is None and allow_cookie and "cookie" in headers:
            return any(secrets.compare_digest(v.encode(), self.token.encode())
                       for v in cookie_values(headers["cookie"], self.cookie))
        return given is not None and secrets.compare_digest(given.encode(), self.token.encode())

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        refused = self.why_refused(scope)

        async def send_with_headers(message):
            if message["type"] == "http.response.start":
                message = dict(message)
                message["headers"] = [*message.get("headers", []), (b"x-frame-options", b"DENY"),
                                      (b"content-security-policy", b"frame-ancestors 'none'"),
                                      (b"referrer-policy", b"no-referrer"), (b"x-content-type-options", b"nosniff")]
            await send(message)

        if refused is None:
            return await self.app(scope, receive, send_with_headers)
        self.refused += 1
        status, msg = refused
        body = json.dumps({"error": msg}).encode()
        await send_with_headers({"type": "http.response.start", "status": status,
                                 "headers": [(b"content-type", b"application/json"),
                                             (b"content-length", str(len(body)).encode())]})
        await send({"type": "http.response.body", "body": body})
