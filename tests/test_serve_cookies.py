"""The page's cookie among other cookies of 127.0.0.1: cookies ignore ports, so every
local web app's cookies come with each request, and since 1385590 a reload of the
page (its address has no token any more) is let in by the cookie alone. Python's
``SimpleCookie`` dropped every cookie of a header when one was not to its taste (a
value with a space or JSON, a name without '=', both of which browsers send), and the
reload was 403. docs/server.md, "Safety"."""
import pytest

from pixgraph_serve.guard import Guard

TOKEN = "t0ken-_AZ09"
OURS = f"pixgraph_token_8765={TOKEN}"


def _get(cookie: str, method: str = "GET"):
    guard = Guard(None, port=8765, token=TOKEN)
    return guard.why_refused({"type": "http", "method": method, "path": "/", "query_string": b"",
                              "headers": [(b"host", b"127.0.0.1:8765"), (b"cookie", cookie.encode("latin-1"))]})


@pytest.mark.parametrize("others", ["a=b c", 'prefs={"theme":"dark"}', "flag", "Expires=1", "x=\u00e9",
                                    "pixgraph_token_8766=other"])
def test_our_cookie_counts_beside_any_other(others):
    assert _get(f"{others}; {OURS}") is None
    assert _get(f"{OURS}; {others}") is None
    assert _get(f" {OURS} ") is None


@pytest.mark.parametrize("cookie", ["", "a=b c", f"pixgraph_token_8766={TOKEN}", f"pixgraph_token_8765={TOKEN}x",
                                    f"pixgraph_token_8765 = x{TOKEN}", f"xpixgraph_token_8765={TOKEN}",
                                    f"pixgraph_token={TOKEN}"])
def test_no_valid_cookie_is_403(cookie):
    status, msg = _get(cookie)
    assert status == 403 and "no valid token" in msg


def test_the_cookie_never_counts_for_a_post():
    status, _ = _get(OURS, "POST")
    assert status == 403
