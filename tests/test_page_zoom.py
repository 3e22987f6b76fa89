"""A zoom on a photo over 4 MP (headless Chromium, a generated 4.3 MP photo opened in
the page): the page asks again for an image fine enough for the closer view. That
final is in the cache (only its encode runs), but the page asked first the sharper,
screen-sized preview it asks after an edit on a large photo: a new working resolution,
so the whole graph ran again for it (2.3 s on a 12 MP photo on 2 busy cores) before
the cached final could come. A zoom, which edits nothing, now asks the final alone."""
import json

import pytest

from serve_helpers import chromium_browser, running_server
from test_page_photo import last_seq, open_in_page, open_page, own_photo_copy, photo_files, wait_final


@pytest.fixture(scope="module")
def browser():
    with chromium_browser() as b:
        yield b


def test_a_zoom_on_a_large_photo_asks_no_preview(browser, tmp_path):
    files = photo_files(str(tmp_path / "mine"), 2400, 1800, mask=True)     # 4.3 MP: over RELEASE_PIXELS
    with running_server(own_photo_copy(str(tmp_path / "served"))) as (url, _):
        page, errors = open_page(browser, url)
        open_in_page(page, files, timeout=300000)
        asked = []
        page.on("request", lambda r: asked.append(json.loads(r.post_data or "{}").get("mode"))
                if r.url.endswith("/api/render") else None)
        seq = last_seq(page)
        page.click("#zoom-1")
        wait_final(page, seq, timeout=300000)
        shown = page.evaluate("window.pixgraphShown.at(-1)")
        assert (shown["mode"], shown["scale"]) == ("final", 1), shown
        assert asked == ["final"], asked
        assert not errors, errors
        page.close()
