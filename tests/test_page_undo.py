"""Undo and redo in the page, in headless Chromium: a drag of the pixel height's tilt handle
(many previews) is one step; Ctrl+Z brings back the param, the image the page draws (its
pixels) and the handle's place, Ctrl+Shift+Z the drag again; Ctrl+Z in a text field is
the field's own; the toolbar's buttons are disabled with nothing to undo or redo and
undo a toggle; a shadow method switch undone brings back the old type's param panel; two tabs
dragging at once make one step. The own-photo graph with the hand edit (test_page_height_edit.py's)."""
import time

import httpx
import numpy as np
import pytest

from serve_helpers import chromium_browser, running_server
from test_page_height_edit import edit_graph
from test_page_photo import centre, drag, graph_params, keep, last_seq, open_in_page, open_page, own_photo_copy, \
    photo_files, shown, wait_final


@pytest.fixture(scope="module")
def browser():
    with chromium_browser() as b:
        yield b


def history(url) -> dict:
    return httpx.get(url + "/api/graph", timeout=60).json()["history"]


def test_ctrl_z_takes_a_whole_drag_back_and_ctrl_shift_z_redoes_it(browser, tmp_path):
    graph = edit_graph(str(tmp_path))
    with running_server(graph) as (url, _):
        page, errors = open_page(browser, url)
        assert page.locator("#undo").is_disabled() and page.locator("#redo").is_disabled()
        tilt0 = graph_params(url)["edit"]["tilt"]
        before = shown(page)
        handle0 = centre(page, "#tilt-handle")
        # the tilt handle pushed 40 px down in 8 steps, held until a preview was drawn
        drag(page, handle0, (handle0[0], handle0[1] + 40), steps=8, hold_for_preview=True)
        previews = page.evaluate("window.pixgraphShown.filter(s => s.mode === 'preview').length")
        assert previews >= 1
        tilt1 = graph_params(url)["edit"]["tilt"]
        assert tilt1 > tilt0 + 5
        after = shown(page)
        assert after.shape == before.shape and np.abs(after - before).mean(axis=2).max() > 0.1   # the shadow moved
        assert history(url) == {"undo": 1, "redo": 0, "limit": 100}                 # one step, not one per preview
        assert page.locator("#undo").is_enabled() and page.locator("#redo").is_disabled()
        keep(page, "undo_dragged.png")

        seq = last_seq(page)
        page.locator("#stage").click(position={"x": 5, "y": 5})   # the page has the focus, no field
        page.keyboard.press("Control+z")
        wait_final(page, seq)
        assert graph_params(url)["edit"]["tilt"] == tilt0
        undone = shown(page)
        assert undone.shape == before.shape
        assert np.abs(undone - before).max() < 1.5 / 255          # the same image as before the drag
        assert centre(page, "#tilt-handle") == pytest.approx(handle0, abs=0.5)
        assert float(page.locator('[data-param="edit.tilt"]').input_value()) == tilt0
        assert page.locator("#undo").is_disabled() and page.locator("#redo").is_enabled()
        keep(page, "undo_undone.png")

        seq = last_seq(page)
        page.keyboard.press("Control+Shift+z")
        wait_final(page, seq)
        assert graph_params(url)["edit"]["tilt"] == tilt1
        assert np.abs(shown(page) - after).max() < 1.5 / 255
        assert history(url) == {"undo": 1, "redo": 0, "limit": 100}

        # Ctrl+Z while typing in a param's field is the field's own: the graph keeps the drag
        field = page.locator('[data-param="light.radius"]')
        field.click()
        field.press("End")
        field.type("5")
        field.press("Control+z")
        page.evaluate("window.pixgraphHistory()")    # every undo the keys asked for has been answered
        assert history(url) == {"undo": 1, "redo": 0, "limit": 100}
        assert graph_params(url)["edit"]["tilt"] == tilt1
        field.press("Escape")

        # a toggle is one step too; the toolbar's undo button takes it back (Ctrl+Y redoes)
        seq = last_seq(page)
        page.check("#lying")
        wait_final(page, seq)
        assert graph_params(url)["edit"]["lying"] is True and history(url)["undo"] == 2
        seq = last_seq(page)
        page.click("#undo")
        wait_final(page, seq)
        assert graph_params(url)["edit"]["lying"] is False and not page.locator("#lying").is_checked()
        assert np.abs(shown(page) - after).max() < 1.5 / 255
        seq = last_seq(page)
        page.locator("#stage").click(position={"x": 5, "y": 5})
        page.keyboard.press("Control+y")
        wait_final(page, seq)
        assert graph_params(url)["edit"]["lying"] is True and page.locator("#lying").is_checked()

        # the shadow method switched: the panel shows the new type's params; undone, the old type's
        assert page.locator('[data-param="shadow.samples"]').count() == 0
        seq = last_seq(page)
        page.check('input[name=method][value="pixgraph.SoftShadow"]')
        wait_final(page, seq)
        assert page.locator('[data-param="shadow.samples"]').count() == 1
        seq = last_seq(page)
        page.keyboard.press("Control+z")
        wait_final(page, seq)
        assert page.locator('input[name=method][value="pixgraph.HardShadow"]').is_checked()
        assert page.locator('[data-param="shadow.samples"]').count() == 0
        assert graph_params(url)["edit"]["lying"] is True
        assert not errors, errors
        page.close()


@pytest.mark.slow
def test_undo_a_drag_on_a_20mp_photo(browser, tmp_path):
    """A 5120x3840 photo opened in the page, the height's tilt handle dragged: Ctrl+Z shows a
    screen-sized preview of the restored graph, then its final, the same pixels as before the
    drag; the undo of the opening goes back to the served graph. Prints the times (this
    machine's, under its load: no assert on them)."""
    files = photo_files(str(tmp_path / "mine"), 5120, 3840, mask=True)
    graph = own_photo_copy(str(tmp_path / "served"))
    with running_server(graph) as (url, _):
        page, errors = open_page(browser, url)
        open_in_page(page, files, timeout=300000)
        assert history(url)["undo"] == 1                      # the opening
        before, tilt0 = shown(page), graph_params(url)["edit"]["tilt"]
        handle0 = centre(page, "#tilt-handle")
        drag(page, handle0, (handle0[0], handle0[1] + 30), steps=8, hold_for_preview=True)
        tilt1 = graph_params(url)["edit"]["tilt"]
        assert tilt1 > tilt0 and history(url)["undo"] == 2
        assert np.abs(shown(page) - before).mean(axis=2).max() > 0.1
        seq = last_seq(page)
        page.locator("#stage").click(position={"x": 5, "y": 5})
        t0 = time.perf_counter()
        page.keyboard.press("Control+z")
        page.wait_for_function(f"window.pixgraphShown.some(s => s.mode === 'preview' && s.seq > {seq})",
                               timeout=300000)
        t_preview = time.perf_counter() - t0
        wait_final(page, seq, timeout=300000)
        t_final = time.perf_counter() - t0
        assert graph_params(url)["edit"]["tilt"] == tilt0
        assert np.abs(shown(page) - before).max() < 1.5 / 255
        assert centre(page, "#tilt-handle") == pytest.approx(handle0, abs=0.5)
        shown_list = page.evaluate(f"window.pixgraphShown.filter(s => s.seq > {seq})")
        print(f"20 MP undo: preview drawn {1000 * t_preview:.0f} ms, final drawn {1000 * t_final:.0f} ms; "
              + "; ".join(f"{s['mode']} {s['width']}x{s['height']} {s['ms']} ms" for s in shown_list))
        # and the opening undone: the served graph (640x480) again
        seq = last_seq(page)
        page.keyboard.press("Control+z")
        wait_final(page, seq, timeout=300000)
        assert page.evaluate("[window.pixgraphView.state.W, window.pixgraphView.state.H]") == [640, 480]
        assert shown(page).shape == (480, 640, 3) and "edit" not in graph_params(url)
        assert not errors, errors
        page.close()


def test_two_tabs_dragging_at_once_make_one_step(browser, tmp_path):
    """Two tabs on one server: tab A drags the tilt handle, and while its pointer is down
    (previews sent) tab B changes a param (its final done); then A drags on and lets go.
    Their edits interleave in the server's history; before, A's drag became several steps
    and an undo went to a graph with half of A's drag in it. Now the two overlapping
    actions are one step: Ctrl+Z in A goes back to the graph before both."""
    graph = edit_graph(str(tmp_path))
    with running_server(graph) as (url, _):
        a, errors_a = open_page(browser, url)
        b, errors_b = open_page(browser, url)
        before = graph_params(url)
        start = centre(a, "#tilt-handle")
        seq = last_seq(a)
        a.mouse.move(*start)
        a.mouse.down()
        a.mouse.move(start[0], start[1] + 20, steps=4)
        a.wait_for_function(f"window.pixgraphShown.some(s => s.mode === 'preview' && s.seq > {seq})", timeout=180000)
        a.wait_for_function("(q => !q.inflight && !q.pending)(window.pixgraphQueue())", timeout=180000)
        half = graph_params(url)["edit"]["tilt"]
        assert half != before["edit"]["tilt"]                       # A's first half is in the graph
        seq_b = last_seq(b)
        b.fill('[data-param="light.radius"]', "0.55")
        b.press('[data-param="light.radius"]', "Enter")
        wait_final(b, seq_b)
        assert graph_params(url)["light"]["radius"] == 0.55
        a.mouse.move(start[0], start[1] + 40, steps=4)               # A's drag goes on, then ends
        a.mouse.up()
        wait_final(a, seq)
        both = graph_params(url)
        assert both["edit"]["tilt"] != half and both["light"]["radius"] == 0.55
        assert history(url)["undo"] == 1, history(url)
        seq = last_seq(a)
        a.locator("#stage").click(position={"x": 5, "y": 5})
        a.keyboard.press("Control+z")
        wait_final(a, seq)
        assert graph_params(url) == before                          # no half drag left
        assert not errors_a and not errors_b, (errors_a, errors_b)
        a.close()
        b.close()
