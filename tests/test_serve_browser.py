"""The page of ``pixgraph serve`` in headless Chromium (Debian's ``chromium``, driven
by Playwright): drag the light's handle and check, on the pixels the page shows,
that the shadow moved; type a bad value and check the page shows the error.

``PIXGRAPH_UPDATE_DOCS=1`` also writes the screenshot docs/server.md shows.
"""
import base64
import io
import os

import httpx
import numpy as np
import pytest
from PIL import Image

from serve_helpers import REPO, chromium_browser, copy_scene, running_server



@pytest.fixture(scope="module")
def browser():
    with chromium_browser() as b:
        yield b


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    graph = copy_scene(str(tmp_path_factory.mktemp("browser")))
    with running_server(graph) as (url, _):
        yield url


def _png(data: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"), dtype=np.float32) / 255.0


def _shown(page) -> np.ndarray:
    """The pixels of the image the page displays, at the resolution it came in, (H, W, 3) in [0, 1]."""
    url = page.evaluate("window.pixgraphView.imageDataURL()")
    return _png(base64.b64decode(url.split(",", 1)[1]))


def _screen(page, u, v):
    """Page coordinates of image pixel (u, v) through the page's view transform."""
    box = page.locator("#stage").bounding_box()
    x, y = page.evaluate(f"window.pixgraphView.toScreen({u}, {v})")
    return box["x"] + x, box["y"] + y


def _shadow(shown, photo, alpha):
    """Pixels darker than the background photo, outside the cutout."""
    darker = (photo - shown).mean(axis=2)
    return (darker > 0.05) & (alpha < 0.02)


def _wait_final(page, after_seq):
    page.wait_for_function(
        f"() => {{ const s = window.pixgraphShown; const l = s[s.length - 1];"
        f" return l && l.mode === 'final' && l.seq > {after_seq}"
        f" && document.body.dataset.synced == l.seq; }}", timeout=60000)   # and its handles redrawn


def test_drag_light_moves_the_shadow_and_bad_value_shows_error(browser, server):
    with httpx.Client(base_url=server, timeout=60) as api:
        photo = _png(api.get("/api/outputs/photo.image.png").content)
        alpha = _png(api.get("/api/outputs/cutout.alpha.png").content)[:, :, 0]
    page = browser.new_page(viewport={"width": 1180, "height": 660})
    errors, requests = [], []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.on("request", lambda r: requests.append(r.url))
    page.goto(server + "/")
    page.wait_for_selector("body[data-ready='1']", timeout=60000)
    _wait_final(page, 0)
    before = _shadow(_shown(page), photo, alpha)
    assert before.sum() > 2000, "no shadow on the first image"
    seq0 = page.evaluate("window.pixgraphShown.at(-1).seq")

    box = page.locator("#light-handle").bounding_box()
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    tx, ty = _screen(page, 120, 500)     # the floor, in front of the figure, left
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(tx, ty, steps=12)
    # hold still until a preview is drawn (a pointer-up right away would supersede it)
    page.wait_for_function(f"window.pixgraphShown.some(s => s.mode === 'preview' && s.seq > {seq0})", timeout=60000)
    page.mouse.up()
    _wait_final(page, seq0)
    after = _shadow(_shown(page), photo, alpha)
    shown = page.evaluate("window.pixgraphShown")
    modes = [s["mode"] for s in shown if s["seq"] > seq0]
    assert "preview" in modes and modes[-1] == "final", modes   # previews while dragging, then the final
    assert [s["seq"] for s in shown] == sorted(s["seq"] for s in shown)  # never an older image over a newer

    ys, xs = np.nonzero(before)
    ys2, xs2 = np.nonzero(after)
    assert after.sum() > 2000
    # the shadow swung from the wall (up, right of the figure) to the floor, left and down
    assert xs2.mean() < xs.mean() - 60, (xs.mean(), xs2.mean())
    assert ys2.mean() > ys.mean() + 60, (ys.mean(), ys2.mean())
    # the shadow of the figure's top lies where the handle was dropped
    scene = httpx.get(server + "/api/scene").json()
    u, v = scene["light"]["tip_uv"]
    assert abs(u - 120) < 2 and abs(v - 500) < 2
    assert after[int(v) - 12:int(v) + 12, int(u) - 12:int(u) + 12].mean() > 0.3

    if os.environ.get("PIXGRAPH_UPDATE_DOCS"):
        page.screenshot(path=os.path.join(REPO, "docs", "img", "serve.png"))

    field = page.locator('[data-param="light.elevation"]')
    field.fill("500")
    field.press("Enter")
    page.wait_for_selector("#error:not([hidden])", timeout=30000)
    text = page.inner_text("#error")
    assert "elevation" in text and "maximum 90" in text, text
    assert "bad" in field.get_attribute("class")
    assert not errors, errors
    # everything the page used came from the server itself
    assert requests and all(u.startswith(server + "/") or u.startswith("data:") for u in requests), requests
    page.close()


def _drag(page, selector, dx, dy):
    box = page.locator(selector).bounding_box()
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x + dx, y + dy, steps=5)
    page.mouse.up()


def test_wall_and_horizon_handles_and_method_toggle(browser, server):
    page = browser.new_page(viewport={"width": 1180, "height": 660})
    page.goto(server + "/")
    page.wait_for_selector("body[data-ready='1']", timeout=60000)
    seq = page.evaluate("window.pixgraphShown.at(-1).seq")
    _drag(page, "#corner-handle", 20, -10)
    _wait_final(page, seq)
    _drag(page, "#right-wall-handle", 0, 30)
    _wait_final(page, seq + 1)
    _drag(page, "#horizon-handle", 0, 25)
    _wait_final(page, seq + 2)
    nodes = {n["id"]: n for n in httpx.get(server + "/api/graph").json()["nodes"]}
    cu, cv = nodes["bg_h"]["params"]["corner"]
    assert abs(cu - 320) <= 1.5 and abs(cv - 290) <= 1.5
    # the right handle sits on the wall-floor line at u = 0.97 W: moved down 30 px (the
    # 512² image is shown 1:1), the line through the corner and it is 30 / (0.97 W - 320) steeper
    assert page.evaluate("window.pixgraphView.state.k") == 1
    assert nodes["bg_h"]["params"]["right_slope"] == pytest.approx(0.45 + 30 / (0.97 * 512 - 320), abs=0.01)
    assert nodes["cam"]["params"]["horizon"] == pytest.approx(145, abs=1.5)
    seq = page.evaluate("window.pixgraphShown.at(-1).seq")
    page.locator("input[name=method][value='pixgraph.SoftShadowSSN']").check()
    _wait_final(page, seq)
    assert httpx.get(server + "/api/scene").json()["shadow"]["type"] == "pixgraph.SoftShadowSSN"
    page.close()


def test_upload_a_background_from_the_page(browser, server, tmp_path):
    flat = tmp_path / "my photo.png"
    Image.new("RGB", (512, 512), (200, 60, 40)).save(flat)
    page = browser.new_page(viewport={"width": 1180, "height": 660})
    page.goto(server + "/")
    page.wait_for_selector("body[data-ready='1']", timeout=60000)
    seq = page.evaluate("window.pixgraphShown.at(-1).seq")
    page.locator('[data-param="photo.path"] + input[type=file]').set_input_files(str(flat))
    _wait_final(page, seq)
    shown = _shown(page)
    assert np.abs(shown[4, 4] * 255 - [200, 60, 40]).max() <= 1.0     # the uploaded photo, shown
    nodes = {n["id"]: n for n in httpx.get(server + "/api/graph").json()["nodes"]}
    assert nodes["photo"]["params"]["path"].endswith("my_photo.png")
    page.close()
