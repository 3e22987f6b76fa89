"""The light's elevation in the page, in headless Chromium: in ``shadow_tip`` placement
(the light moved by its shadow tip) the param panel's ``light.elevation``, the
toolbar's elevation slider and the light the render uses show one value: the light's
elevation seen from the object's top (``Light.tip_angles``). Before, the panel kept the
``elevation`` param the placement ignores (35) while the slider showed the light's
(56.5)."""
import httpx
import pytest
import yaml

from pixgraph_nodes.ops.lights import MIN_ELEVATION_DEG

from serve_helpers import chromium_browser, running_server
from test_page_height_edit import edit_graph
from test_page_photo import centre, drag, graph_params, last_seq, open_page, screen, wait_final


@pytest.fixture(scope="module")
def browser():
    with chromium_browser() as b:
        yield b


def shown_angles(page) -> dict:
    """What the page shows: the panel's two fields, the slider and its readout."""
    return page.evaluate("""() => ({
        panel_elevation: Number(document.querySelector('[data-param="light.elevation"]').value),
        panel_azimuth: Number(document.querySelector('[data-param="light.azimuth"]').value),
        slider: Number(document.getElementById('elevation').value),
        readout: document.getElementById('elevation-value').textContent})""")


def check_one_value(page, url) -> dict:
    """The panel, the slider and its readout agree with the elevation of the light the
    last render used (the Light node's output, ``GET /api/scene``)."""
    light = httpx.get(url + "/api/scene", timeout=60).json()["light"]
    got = shown_angles(page)
    eff = light["elevation_deg"]
    assert got["panel_elevation"] == pytest.approx(eff, abs=0.006), (got, eff)
    assert got["slider"] == pytest.approx(eff, abs=0.006), (got, eff)
    assert got["readout"] == f"{eff:.1f}", (got, eff)
    assert got["panel_azimuth"] == pytest.approx(light["azimuth_deg"], abs=0.006), (got, light)
    return light


def test_panel_and_slider_show_the_elevation_the_light_has(browser, tmp_path):
    graph = edit_graph(str(tmp_path))
    with running_server(graph) as (url, _):
        page, errors = open_page(browser, url)
        light = check_one_value(page, url)                 # controls placement: the param itself
        assert light["placement"] == "controls" and light["elevation_deg"] == 35
        # drag the shadow tip close to the foot: a high light, far from the 35 degrees
        fu, fv = httpx.get(url + "/api/scene", timeout=60).json()["place"]["foot"]
        drag(page, centre(page, "#light-handle"), screen(page, fu - 60, fv + 10))
        light = check_one_value(page, url)
        assert light["placement"] == "shadow_tip" and abs(light["elevation_deg"] - 35) > 5, light
        # the saved graph says the same (the params follow the tip)
        params = graph_params(url)["light"]
        assert params["elevation"] == pytest.approx(light["elevation_deg"], abs=0.006)
        assert params["azimuth"] == pytest.approx(light["azimuth_deg"], abs=0.006)
        # an elevation typed in the panel moves the light (its tip), as the slider does
        tip = light["tip_uv"]
        seq = last_seq(page)
        page.fill('[data-param="light.elevation"]', "30")
        page.press('[data-param="light.elevation"]', "Enter")
        wait_final(page, seq)
        light = check_one_value(page, url)
        assert light["elevation_deg"] == pytest.approx(30, abs=1e-6) and light["placement"] == "shadow_tip"
        assert abs(light["tip_uv"][1] - tip[1]) > 5            # a lower light: the tip moved away
        # the slider too (focused, as a press on it does: the panel's field is left)
        seq = last_seq(page)
        page.evaluate("""() => { const el = document.getElementById('elevation');
            el.focus(); el.value = 50; el.dispatchEvent(new Event('change')); }""")
        wait_final(page, seq)
        light = check_one_value(page, url)
        assert light["elevation_deg"] == pytest.approx(50, abs=1e-6)
        assert not errors, errors
        page.close()


def test_a_graph_saved_with_stale_angles_shows_the_lights_own(browser, tmp_path):
    """A graph whose light is in shadow_tip placement with azimuth/elevation params that
    placement does not use (a graph saved before, or written by hand): the page shows the
    light's own angles, not the params."""
    graph = edit_graph(str(tmp_path))
    with open(graph) as f:
        doc = yaml.safe_load(f)
    doc["nodes"]["light"]["params"].update({"placement": "shadow_tip", "tip_uv": [250.0, 440.0],
                                            "top_uvh": [320.0, 146.5, 262.0], "elevation": 35, "azimuth": -30})
    with open(graph, "w") as f:
        yaml.safe_dump(doc, f, sort_keys=False)
    with running_server(graph) as (url, _):
        page, errors = open_page(browser, url)
        light = check_one_value(page, url)
        assert abs(light["elevation_deg"] - 35) > 5, light
        assert not errors, errors
        page.close()


def slider(page) -> dict:
    return page.evaluate("""() => { const el = document.getElementById('elevation');
        return {min: Number(el.min), max: Number(el.max), value: Number(el.value)}; }""")


def drag_slider_to_its_end(page, right=True):
    """A press on the elevation slider and a drag past its end, as a user does."""
    box = page.locator("#elevation").bounding_box()
    seq = last_seq(page)
    y = box["y"] + box["height"] / 2
    page.mouse.move(box["x"] + box["width"] / 2, y)
    page.mouse.down()
    page.mouse.move(box["x"] + box["width"] + 40 if right else box["x"] - 40, y, steps=6)
    page.mouse.up()
    wait_final(page, seq)


def type_param(page, key, value):
    seq = last_seq(page)
    page.fill(f'[data-param="{key}"]', str(value))
    page.press(f'[data-param="{key}"]', "Enter")
    wait_final(page, seq)


def test_the_elevation_slider_reaches_the_params_declared_ends(browser, tmp_path):
    """The slider's range is the elevation param's declared max down to the lowest
    elevation that has an effect (1 deg: below, the light is raised to it): typed at
    either end the slider shows it, dragged to its end the param is the max. In the shadow_tip placement the range is what the tip can give. Before,
    the slider was fixed to 1..89: a typed 90 showed as 89, -90 as 1, and its end set 89."""
    graph = edit_graph(str(tmp_path))
    with running_server(graph) as (url, _):
        spec = next(p for t in httpx.get(url + "/api/nodes", timeout=60).json()["types"]
                    if t["type"] == "pixgraph.Light" for p in t["params"] if p["name"] == "elevation")
        assert (spec["min"], spec["max"]) == (-90.0, 90.0)
        # below 1 deg a light placed by its angles is raised to 1 (with a warning): the
        # slider starts there
        lo, hi = MIN_ELEVATION_DEG, spec["max"]
        page, errors = open_page(browser, url)
        assert graph_params(url)["light"]["placement"] == "controls"
        assert (slider(page)["min"], slider(page)["max"]) == (lo, hi) == (1.0, 90.0)
        for value in (hi, lo, 37.4):
            type_param(page, "light.elevation", value)
            assert graph_params(url)["light"]["elevation"] == value
            assert slider(page)["value"] == value, (value, slider(page))
            assert page.inner_text("#elevation-value") == f"{value:.1f}"
        drag_slider_to_its_end(page)
        assert graph_params(url)["light"]["elevation"] == hi and slider(page)["value"] == hi
        assert page.locator("#error").is_hidden()
        # the shadow_tip placement: the tip gives [0.5, 90) (straight above has no ground
        # direction left): the slider's ends are 0.5 and 89.99, its end a light the tip gives
        type_param(page, "light.elevation", 40)
        fu, fv = httpx.get(url + "/api/scene", timeout=60).json()["place"]["foot"]
        drag(page, centre(page, "#light-handle"), screen(page, fu - 60, fv - 30))
        assert graph_params(url)["light"]["placement"] == "shadow_tip"
        assert (slider(page)["min"], slider(page)["max"]) == (0.5, 89.99)
        drag_slider_to_its_end(page)
        light = check_one_value(page, url)
        assert light["elevation_deg"] == pytest.approx(89.99, abs=1e-6) and light["elevation"] == 89.99
        assert page.locator("#error").is_hidden()
        assert not errors, errors
        page.close()


def test_an_azimuth_typed_as_350_stays_350_in_the_page(browser, tmp_path):
    """In the shadow_tip placement an azimuth typed as 350 stays 350 in the panel and the
    graph (the tip's geometry says -10: the same light; before, the page wrote -10 back),
    and a drag of the tip then keeps it on that side of 0/360; the panel's field shows
    the dragged light's azimuth (before, the field typed in kept the focus through the
    drag, and with it the typed value)."""
    graph = edit_graph(str(tmp_path))
    with running_server(graph) as (url, _):
        page, errors = open_page(browser, url)
        fu, fv = httpx.get(url + "/api/scene", timeout=60).json()["place"]["foot"]
        drag(page, centre(page, "#light-handle"), screen(page, fu - 60, fv - 30))
        assert graph_params(url)["light"]["placement"] == "shadow_tip"
        type_param(page, "light.elevation", 40)
        type_param(page, "light.azimuth", 350)
        light = check_one_value(page, url)
        assert light["azimuth_deg"] == pytest.approx(350, abs=1e-6) and graph_params(url)["light"]["azimuth"] == 350
        tip = light["tip_uv"]
        drag(page, screen(page, *tip), screen(page, tip[0] + 15, tip[1]))
        light = check_one_value(page, url)
        assert 300 < light["azimuth_deg"] < 360 and light["azimuth_deg"] != pytest.approx(350, abs=0.5), light
        assert not errors, errors
        page.close()
