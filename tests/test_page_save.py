"""The page's save, in headless Chromium (Debian's ``chromium`` driven by Playwright):
the name box shows a long name's end (the file name), and a graph saved from the page
and opened again lists its nodes in the order its file had."""
import shutil

import pytest
import yaml

from serve_helpers import chromium_browser, running_server
from test_page_photo import last_seq, open_page, own_photo_copy, wait_final


@pytest.fixture(scope="module")
def browser():
    with chromium_browser() as b:
        yield b


def name_end_shown(page) -> dict:
    """The save box's text scroll: whether the name is longer than the box and its end in view."""
    return page.evaluate("""(() => { const b = document.getElementById('save-name');
        return {long: b.scrollWidth > b.clientWidth + 1, end: b.scrollLeft + b.clientWidth >= b.scrollWidth - 1,
                value: b.value}; })()""")


def test_a_long_save_name_shows_its_end(browser, tmp_path):
    """The box is 16 characters wide (the toolbar's two rows are laid out for that): a
    longer name showed its start, the folder or a long photo name, and its end (the file
    name, ``.yaml``) was cut off. Outside typing, the box now shows the name's end."""
    long = "compositing_shot_0042_the_kitchen_table_v3.yaml"
    graph = own_photo_copy(str(tmp_path / "served"))
    shutil.move(graph, tmp_path / "served" / long)
    with running_server(str(tmp_path / "served" / long)) as (url, _):
        page, errors = open_page(browser, url)
        shown = name_end_shown(page)                 # the server's proposal: the served file's name
        assert shown == {"long": True, "end": True, "value": long}, shown
        page.click("#save-name")                     # typed in, then left: the end again
        page.keyboard.press("Home")
        page.click("#zoom-fit")
        page.wait_for_function("(() => { const b = document.getElementById('save-name');"
                               " return b.scrollLeft + b.clientWidth >= b.scrollWidth - 1; })()", timeout=5000)
        page.fill("#save-name", "shots/0042/" + long)
        page.click("#zoom-fit")
        page.wait_for_function("(() => { const b = document.getElementById('save-name');"
                               " return b.scrollLeft + b.clientWidth >= b.scrollWidth - 1; })()", timeout=5000)
        assert name_end_shown(page)["long"]
        assert not errors, errors
        page.close()


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
