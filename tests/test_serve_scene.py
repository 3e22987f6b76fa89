"""The UI's light handle: the shadow tip the server reports is where the hard shadow
of the object's top ends (no HTTP: ``ServeState`` in-process)."""
import numpy as np
import pytest

from pixgraph_serve import scene
from pixgraph_serve.state import ServeState
from serve_helpers import copy_scene


@pytest.fixture(scope="module")
def state(tmp_path_factory):
    return ServeState(copy_scene(str(tmp_path_factory.mktemp("scene"))))


@pytest.mark.parametrize("kind,azimuth", [("directional", 120.0), ("point", 240.0)])
def test_reported_tip_is_the_end_of_the_hard_shadow(state, kind, azimuth):
    state.set_type("shadow", "pixgraph.HardShadow")
    state.set_params({"light.kind": kind, "light.placement": "controls", "light.azimuth": azimuth,
                      "light.elevation": 70.0, "light.distance": 6.0})
    light = scene.describe(state)["light"]
    (u, v), top = light["tip_uv"], light["top_uvh"]
    dark = state.run(["shadow.darkness"])[0]["shadow.darkness"]
    d = np.array([u - top[0], v - top[1] - top[2]])          # from the top's foot toward the tip
    d /= np.linalg.norm(d)

    def shadowed(t):
        x, y = np.array([u, v]) + t * d
        return dark[int(y) - 1:int(y) + 2, int(x) - 1:int(x) + 2].max() > 0.5

    assert shadowed(-4) and not shadowed(6), (u, v)


def test_elevation_edit_keeps_the_tip_direction(state):
    state.set_params({"light.kind": "disk", "light.azimuth": 200.0, "light.elevation": 40.0})
    state.set_params(scene.light_edits(state, tip_uv=[140, 470]))
    before = scene.describe(state)["light"]
    state.set_params(scene.light_edits(state, elevation=35.0))
    after = scene.describe(state)["light"]
    assert after["elevation_deg"] == pytest.approx(35.0, abs=1e-6)
    assert after["azimuth_deg"] == pytest.approx(before["azimuth_deg"], abs=1e-6)
    foot = np.array([before["top_uvh"][0], before["top_uvh"][1] + before["top_uvh"][2]])
    # a lower light: a longer shadow, the tip farther from the top's foot
    assert np.linalg.norm(np.subtract(after["tip_uv"], foot)) > np.linalg.norm(np.subtract(before["tip_uv"], foot)) + 20
