"""The light's elevation in the page, in headless Chromium: in ``shadow_tip`` placement
(the light moved by its shadow tip) the param panel's ``light.elevation``, the
toolbar's elevation slider and the light the render uses show one value: the light's
elevation seen from the object's top (``Light.tip_angles``). Before, the panel kept the
``elevation`` param the placement ignores (35) while the slider showed the light's
(56.5)."""
import httpx
import pytest
import yaml

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
