"""The page's save, in headless Chromium (Debian's ``chromium`` driven by Playwright):
a graph saved from the page and opened again lists its nodes in the order its file had."""

import pytest
import yaml

from serve_helpers import chromium_browser, running_server
from test_page_photo import last_seq, open_page, own_photo_copy, wait_final


@pytest.fixture(scope="module")
def browser():
    with chromium_browser() as b:
        yield b


def panel_order(page) -> list[str]:
    return page.evaluate("[...document.querySelectorAll('#nodes details.node')].map((d) => d.dataset.node)")


def test_a_saved_graph_opened_again_keeps_its_nodes_order(browser, tmp_path):
    """The panel lists the nodes in the graph's order; the save wrote them sorted by id
    (the canonical dump's order then), so the graph opened again listed them
    alphabetically (bg_h, cam, comp, cutout, ...) instead of as its file had them."""
    graph = own_photo_copy(str(tmp_path / "served"))
    with open(graph) as f:
        written = list(yaml.safe_load(f)["nodes"])
    assert written != sorted(written)                # the case: not alphabetical
    with running_server(graph) as (url, _):
        page, errors = open_page(browser, url)
        assert panel_order(page) == written
        seq = last_seq(page)
        page.click("#flip")                          # an edit, then the page's save
        wait_final(page, seq)
        page.fill("#save-name", "mine.yaml")
        page.click("#save")
        page.wait_for_function("document.getElementById('status').textContent.startsWith('saved')", timeout=60000)
        assert not errors, errors
        page.close()
    saved = tmp_path / "served" / "mine.yaml"
    doc = yaml.safe_load(saved.read_text())
    assert doc["nodes"]["place"]["params"]["flip"] is True
    assert list(doc["nodes"]) == written
    with running_server(str(saved)) as (url, _):
        page, errors = open_page(browser, url)
        assert panel_order(page) == written
        assert not errors, errors
        page.close()
