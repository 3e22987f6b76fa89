"""What the page draws while a handle is held (headless Chromium, the own-photo template
with the hand edit on the repo's photo): the guides and the handles that hang on the
dragged thing move with the pointer, before the drag's final comes. Seen on a 20 MP
photo, where the final takes seconds: the contact points' line stayed where the points
were, the light's dotted line kept pointing at the old tip, and a drag of the cutout's
box or scale handle left the foot square, the scale handle and the orange height
handles (contact points, the new-contact ring, the top's square, the body's ring and
their guides) behind on the old place, away from the cutout the preview showed."""
import json
import time

import httpx
import pytest

from serve_helpers import chromium_browser, running_server
from test_page_height_edit import edit_graph, to_canvas
from test_page_photo import centre, last_seq, open_page, screen, wait_final


@pytest.fixture(scope="module")
def browser():
    with chromium_browser() as b:
        yield b


def held(page, start, end, steps=6):
    """Press at ``start``, move to ``end`` and keep the button down."""
    page.mouse.move(*start)
    page.mouse.down()
    page.mouse.move(*end, steps=steps)


def let_go(page, seq):
    page.mouse.up()
    wait_final(page, seq)


def points(page, selector):
    """The screen points of a polyline, in page coordinates (its transform applied)."""
    return page.evaluate(f"""(() => {{
        const el = document.querySelector('{selector}'), box = el.ownerSVGElement.getBoundingClientRect();
        const m = el.getCTM();
        return [...el.points].map((p) => [box.x + m.a * p.x + m.c * p.y + m.e, box.y + m.b * p.x + m.d * p.y + m.f]);
    }})()""")


def line_end(page, selector):
    """The (x2, y2) end of a line, in page coordinates."""
    return page.evaluate(f"""(() => {{
        const el = document.querySelector('{selector}'), box = el.ownerSVGElement.getBoundingClientRect();
        const m = el.getCTM(), x = el.x2.baseVal.value, y = el.y2.baseVal.value;
        return [box.x + m.a * x + m.c * y + m.e, box.y + m.b * x + m.d * y + m.f];
    }})()""")


def test_the_guides_follow_a_held_handle(browser, tmp_path):
    graph = edit_graph(str(tmp_path))
    with running_server(graph) as (url, _):
        page, errors = open_page(browser, url)
        fu, fv = httpx.get(url + "/api/scene", timeout=60).json()["place"]["foot"]
        # two contact points, then the first held 30 px to the left: the line through them
        # starts where the pointer is, not where the point was
        for du in (-15, 15):
            seq = last_seq(page)
            held(page, centre(page, "#contact-new"), screen(page, fu + du, fv - 4))
            let_go(page, seq)
        x, y = centre(page, "#contact-0")
        seq = last_seq(page)
        held(page, (x, y), (x - 30, y - 10))
        assert centre(page, "#contact-0") == pytest.approx((x - 30, y - 10), abs=1.0)
        line = points(page, "polyline.guide.contact")
        assert line[0] == pytest.approx([x - 30, y - 10], abs=1.0), line    # sorted by u: the leftmost
        let_go(page, seq)
        # the light's tip held: its dotted line from the top ends under the pointer
        x, y = centre(page, "#light-handle")
        seq = last_seq(page)
        held(page, (x, y), (x - 40, y + 25))
        assert line_end(page, "line.guide.light") == pytest.approx([x - 40, y + 25], abs=1.0)
        let_go(page, seq)
        assert not errors, errors
        page.close()


HUNG = ("#foot-handle", "#scale-handle", "#contact-new", "#contact-0", "#tilt-handle", "#depth-handle")


def test_the_cutouts_handles_follow_its_box_and_its_scale(browser, tmp_path):
    graph = edit_graph(str(tmp_path))
    with running_server(graph) as (url, _):
        page, errors = open_page(browser, url)
        k = page.evaluate("window.pixgraphView.state.k")
        fu, fv = httpx.get(url + "/api/scene", timeout=60).json()["place"]["foot"]
        seq = last_seq(page)
        held(page, centre(page, "#contact-new"), screen(page, fu - 10, fv - 4))
        let_go(page, seq)
        before = {sel: centre(page, sel) for sel in HUNG}
        tilt_guide = line_end(page, "line.guide.tilt")
        # the box held 40 px right, 20 up: everything on the cutout 40 px right, 20 up
        bx, by = centre(page, "#cutout-box")
        seq = last_seq(page)
        held(page, (bx, by - 30), (bx + 40, by - 50))
        for sel, (x, y) in before.items():
            assert centre(page, sel) == pytest.approx((x + 40, y - 20), abs=1.0), sel
        assert line_end(page, "line.guide.tilt") == pytest.approx([tilt_guide[0] + 40, tilt_guide[1] - 20], abs=1.0)
        let_go(page, seq)
        place = httpx.get(url + "/api/scene", timeout=60).json()["place"]
        assert place["foot"] == pytest.approx([fu + 40 / k, fv - 20 / k], abs=1 / k + 0.2)
        # the scale handle held up: the handles on the cutout move about the foot by the
        # scale's factor, each keeping its size on the screen
        e = httpx.get(url + "/api/scene", timeout=60).json()["height_edit"]
        before = {sel: centre(page, sel) for sel in HUNG}
        size = page.locator("#tilt-handle").bounding_box()["width"]
        fx, fy = before["#foot-handle"]
        sx, sy = before["#scale-handle"]
        seq = last_seq(page)
        held(page, (sx, sy), (sx, sy - 40))
        f = (fy - (sy - 40)) / (fy - sy)
        for sel, (x, y) in before.items():
            if sel != "#scale-handle":
                assert centre(page, sel) == pytest.approx((fx + (x - fx) * f, fy + (y - fy) * f), abs=1.5), sel
        assert page.locator("#tilt-handle").bounding_box()["width"] == pytest.approx(size, abs=0.1)
        tu, tv = to_canvas(e, *e["top"][:2])
        tx, ty = screen(page, tu, tv)
        assert centre(page, "#tilt-handle") == pytest.approx((fx + (tx - fx) * f, fy + (ty - fy) * f), abs=1.5)
        let_go(page, seq)
        # after the final the handles are drawn from the new scene: where they were held
        e2 = httpx.get(url + "/api/scene", timeout=60).json()["height_edit"]
        assert centre(page, "#tilt-handle") == pytest.approx(screen(page, *to_canvas(e2, *e2["top"][:2])), abs=1.0)
        assert centre(page, "#tilt-handle") == pytest.approx((fx + (tx - fx) * f, fy + (ty - fy) * f), abs=2.5)
        assert not errors, errors
        page.close()


class HeldFinals:
    """Holds every final the page asks (``POST /api/render`` with ``mode: final``) until
    ``release()``: a final is "on its way" for as long as a test needs, however fast
    this machine renders it (previews pass at once)."""

    def __init__(self, page):
        self.page, self.held = page, []
        page.route("**/api/render", self._route)

    def _route(self, route):
        if json.loads(route.request.post_data or "{}").get("mode") == "final":
            self.held.append(route)
        else:
            route.continue_()

    def wait_asked(self):
        """Wait (up to 60 s) until the page has asked a final: the action's previews are
        sent and its release handled."""
        deadline = time.monotonic() + 60
        while not self.held:
            assert time.monotonic() < deadline, "the page asked no final"
            self.page.wait_for_timeout(20)

    def release(self):
        """Let the held finals go on (waiting, up to 60 s, for the one the page asked)."""
        self.wait_asked()
        for route in self.held:
            route.continue_()
        self.held.clear()


def test_saved_stays_shown_when_an_earlier_final_comes_after_the_save(browser, tmp_path):
    """On a 20 MP photo a final takes seconds: "save" pressed meanwhile showed "saved
    PATH", and the final, asked before the save, replaced that line as soon as it came
    (often before it could be read). Renders asked before the save now leave it; the next
    edit's replace it."""
    with running_server(edit_graph(str(tmp_path))) as (url, _):
        page, errors = open_page(browser, url)
        finals = HeldFinals(page)
        seq = last_seq(page)
        page.click("#flip")                        # its final is asked now and held
        page.fill("#save-name", "mine.yaml")
        page.click("#save")
        page.wait_for_function("document.getElementById('status').textContent.startsWith('saved')", timeout=60000)
        finals.release()                           # the final asked before the save comes after it
        wait_final(page, seq)
        assert page.inner_text("#status").startswith("saved "), page.inner_text("#status")
        assert (tmp_path / "mine.yaml").exists()
        seq = last_seq(page)
        page.click("#flip")                        # a new edit: its render's line again
        finals.release()
        wait_final(page, seq)
        assert page.inner_text("#status").startswith("final "), page.inner_text("#status")
        assert not errors, errors
        page.close()


def status_while_final(page):
    """The status line once it says a final is on its way."""
    return page.wait_for_function("""() => {
        const line = document.getElementById('status').textContent;
        return line.startsWith('rendering the final') && line; }""", timeout=60000).json_value()


def test_the_status_line_says_a_final_is_on_its_way(browser, tmp_path):
    """On a 20 MP photo the final takes seconds after a drag: the status line went on
    showing the last preview's line, as if that were all. While a final is on its way it
    now starts with "rendering the final..." (the line shown before it still there); the
    final's own line replaces it."""
    with running_server(edit_graph(str(tmp_path))) as (url, _):
        page, errors = open_page(browser, url)
        finals = HeldFinals(page)
        # the light held and moved until a preview came, then let go: its final is asked
        x, y = centre(page, "#light-handle")
        seq = last_seq(page)
        held(page, (x, y), (x - 40, y + 25))
        page.wait_for_function(f"window.pixgraphShown.some((s) => s.mode === 'preview' && s.seq > {seq})",
                               timeout=60000)
        page.mouse.up()
        # what the line says while that final is held
        said = status_while_final(page)
        assert said.startswith("rendering the final\u2026 (shown: preview "), said
        finals.release()
        wait_final(page, seq)
        assert page.inner_text("#status").startswith("final "), page.inner_text("#status")
        # an edit with no previews (a toggle): the same while its final runs
        seq = last_seq(page)
        page.click("#flip")
        said = status_while_final(page)
        assert said.startswith("rendering the final\u2026 (shown: final "), said
        finals.release()
        wait_final(page, seq)
        assert page.inner_text("#status").startswith("final "), page.inner_text("#status")
        assert not errors, errors
        page.close()


def test_the_cutouts_handles_follow_a_shift_wheel_scale(browser, tmp_path):
    """Shift + wheel over the cutout scales it: the previews showed it growing while its
    box, foot, scale and height handles stayed at the old size until the final came
    (seconds on a 20 MP photo). They now follow the wheel as they follow the scale
    handle's drag (the finals held here, so "before the final" holds on any machine)."""
    from test_page_photo import graph_params
    with running_server(edit_graph(str(tmp_path))) as (url, _):
        page, errors = open_page(browser, url)
        s0 = graph_params(url)["place"]["scale"]
        before = {sel: centre(page, sel) for sel in ("#foot-handle", "#scale-handle", "#tilt-handle")}
        finals = HeldFinals(page)
        bx, by = centre(page, "#cutout-box")
        page.mouse.move(bx, by)
        page.keyboard.down("Shift")
        for _ in range(3):
            page.mouse.wheel(0, -100)
        page.keyboard.up("Shift")
        finals.wait_asked()              # the wheel's final asked (and held): the previews are done
        f = graph_params(url)["place"]["scale"] / s0
        assert f > 1.2, f
        fx, fy = before["#foot-handle"]
        for sel, (x, y) in before.items():
            assert centre(page, sel) == pytest.approx((fx + (x - fx) * f, fy + (y - fy) * f), abs=1.5), sel
        finals.release()
        assert not errors, errors
        page.close()


def test_the_cutouts_handles_mirror_at_once_on_flip(browser, tmp_path):
    """"flip cutout" mirrors the cutout about its foot: the preview (on a photo over 4 MP)
    and the final showed it flipped while its scale handle, contact points and top stayed
    where the unflipped cutout had them until the final's scene came (seconds on 20 MP),
    then jumped. They are mirrored at the click, where the final puts them."""
    with running_server(edit_graph(str(tmp_path))) as (url, _):
        page, errors = open_page(browser, url)
        fu, fv = httpx.get(url + "/api/scene", timeout=60).json()["place"]["foot"]
        seq = last_seq(page)
        held(page, centre(page, "#contact-new"), screen(page, fu - 20, fv - 4))
        let_go(page, seq)
        sels = ("#foot-handle", "#scale-handle", "#contact-0", "#tilt-handle")
        before = {sel: centre(page, sel) for sel in sels}
        finals = HeldFinals(page)
        seq = last_seq(page)
        page.click("#flip")
        finals.wait_asked()              # the flip's final asked (and held): its click handled
        during = {sel: centre(page, sel) for sel in sels}
        finals.release()
        wait_final(page, seq)
        after = {sel: centre(page, sel) for sel in sels}
        assert abs(after["#contact-0"][0] - before["#contact-0"][0]) > 10      # the flip moves them
        for sel in sels:
            assert during[sel] == pytest.approx(after[sel], abs=1.5), (sel, before[sel], during[sel], after[sel])
        assert not errors, errors
        page.close()
