"""The per-launch token in a real browser (Debian's ``chromium`` driven by Playwright):
the page takes it out of the address bar at load (browser history, screenshots, a
Referer), still renders and saves, a reload still works (the ``HttpOnly``,
``SameSite=Strict`` cookie the first page set, named by the server's port: another
server on this machine does not overwrite it), and a page of another site still
gets 403. docs/server.md, "Safety"."""
import os

import pytest

from serve_helpers import chromium_browser, start_server
from test_page_photo import VIEWPORT, last_seq, own_photo_copy, wait_final
from test_serve_security import _serve_page


@pytest.fixture(scope="module")
def browser():
    with chromium_browser() as b:
        yield b


def ready(page):
    page.wait_for_selector("body[data-ready='1']", state="attached", timeout=180000)
    wait_final(page, 0)


def save_as(page, name):
    page.fill("#save-name", name)
    page.click("#save")
    page.wait_for_function("document.getElementById('status').textContent.startsWith('saved')", timeout=60000)


def test_the_token_leaves_the_address_bar_and_a_reload_still_works(browser, tmp_path):
    first = own_photo_copy(str(tmp_path / "a"))
    other = own_photo_copy(str(tmp_path / "b"))
    with start_server(first) as (url, token, _), start_server(other) as (url_b, token_b, _):
        assert token and token_b and token != token_b
        ctx = browser.new_context(viewport=VIEWPORT)
        page = ctx.new_page()
        errors = []
        page.on("pageerror", lambda e: errors.append(str(e)))
        answer = page.goto(f"{url}/?token={token}")
        assert answer.status == 200 and answer.headers["referrer-policy"] == "no-referrer"
        ready(page)
        assert page.url == url + "/", page.url                   # no token in the address bar
        assert token not in page.evaluate("location.href")
        seq = last_seq(page)
        page.click("#flip")                                      # an edit and a save, with the token
        wait_final(page, seq)
        save_as(page, "first.yaml")
        assert os.path.isfile(tmp_path / "a" / "first.yaml")

        # another server of this machine opened in the same browser: its cookie is its own
        page_b = ctx.new_page()
        assert page_b.goto(f"{url_b}/?token={token_b}").status == 200
        ready(page_b)
        assert page_b.url == url_b + "/"

        answer = page.reload()                                   # the address has no token now
        assert answer.status == 200, answer.text()[:300]
        ready(page)
        assert page.url == url + "/"
        save_as(page, "again.yaml")
        assert os.path.isfile(tmp_path / "a" / "again.yaml")
        assert not errors, errors

        # a page of another site (another port of 127.0.0.1) linking to the server: 403
        link, stop = _serve_page(f'<html><body><a id="go" href="{url}/">open</a></body></html>')
        try:
            evil = ctx.new_page()
            evil.goto(link)
            with evil.expect_navigation() as nav:
                evil.click("#go")
            assert nav.value.status == 403
            assert "refused" in evil.content()
        finally:
            stop()
        ctx.close()
