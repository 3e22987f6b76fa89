"""The page's handles, found from what nodes declare, and the light's screen geometry
(``pixgraph_nodes.ops.light_screen``); in-process ``ServeState``, no HTTP."""
import ast
import math
import os
import re

import numpy as np
import pytest

from pixgraph_nodes.ops import light_screen as LS
from pixgraph_nodes.ops import lights as L
from pixgraph_nodes.ops.lights import MIN_ELEVATION_DEG
from pixgraph_nodes.ops.camera import Camera
from pixgraph_serve import app as serve_app
from pixgraph_serve import scene
from pixgraph_serve.errors import ServeError
from pixgraph_serve.state import ServeState
from serve_helpers import REPO, copy_scene

CAM = Camera(512, 512, hfov=50.0, horizon=120.0, cam_height=1.0)


@pytest.fixture(scope="module")
def state(tmp_path_factory):
    return ServeState(copy_scene(str(tmp_path_factory.mktemp("scene"))))


# -- the geometry (no server) ---------------------------------------------------------------

def test_object_top_is_the_middle_of_the_highest_covered_row():
    mask = np.zeros((40, 30), np.float32)
    mask[12, 5:10] = 1.0            # highest row: columns 5..9, middle 7
    mask[13:30, 3:20] = 1.0
    mask[11, 25] = 0.4              # under half covered: not the object
    height = np.arange(40 * 30, dtype=np.float32).reshape(40, 30)
    assert LS.object_top(mask, height) == (7.5, 12.5, float(height[12, 7]))
    assert LS.object_top(np.zeros((4, 4)), height[:4, :4]) is None


@pytest.mark.parametrize("kind,distance", [("directional", math.inf), ("point", 3.0)])
def test_shadow_tip_inverts_from_shadow_tip(kind, distance):
    top = (260.0, 180.0, 150.0)
    for tip in [(150.0, 420.0), (400.0, 300.0), (255.0, 500.0)]:
        light = L.from_shadow_tip(CAM, tip, top, distance=distance, kind=kind)
        assert LS.shadow_tip(CAM, light, top) == pytest.approx(tip, abs=1e-6)


def test_tip_angles_and_tip_at_angles_are_inverse_and_those_of_the_light():
    """``tip_angles`` are the angles of the light ``from_shadow_tip`` makes (seen from the
    top); ``tip_at_angles`` gives back the tip, and the light it makes has those angles."""
    top = (260.0, 180.0, 150.0)
    for tip in [(150.0, 420.0), (400.0, 300.0), (255.0, 500.0), (300.0, 160.0)]:
        az, el = L.tip_angles(CAM, tip, top)
        controls = dict(L.from_shadow_tip(CAM, tip, top, distance=3.0, kind="disk", radius=0.2).controls)
        assert (az, el) == (controls["azimuth"], controls["elevation"])
        assert LS.tip_at_angles(CAM, top, az, el) == pytest.approx(tip, abs=1e-6)
    for az, el in [(-30.0, 35.0), (120.0, 60.0), (180.0, 20.0), (0.0, 80.0)]:
        tip = LS.tip_at_angles(CAM, top, az, el)
        assert L.tip_angles(CAM, tip, top) == pytest.approx((az, el), abs=1e-6)
    # azimuth 0 is the camera's side: the shadow falls back, up the image from the foot
    assert LS.tip_at_angles(CAM, top, 0.0, 45.0)[1] < top[1] + top[2]
    with pytest.raises(ValueError, match="0.5, 90"):
        LS.tip_at_angles(CAM, top, 0.0, 0.2)
    with pytest.raises(ValueError, match="ground in view"):
        LS.tip_at_angles(CAM, top, 180.0, 5.0)        # a low light behind: the tip behind the camera
    with pytest.raises(ValueError, match="height"):
        LS.tip_at_angles(CAM, (260.0, 180.0, 0.0), 0.0, 45.0)


def test_tip_at_elevation_gives_that_elevation_on_the_same_ground_direction():
    top, tip = (260.0, 180.0, 150.0), (150.0, 420.0)
    P, _ = CAM.back_project(*top)
    T0, _ = CAM.back_project(*tip, 0.0)
    for el in (30.0, 45.0, 60.0):
        new = LS.tip_at_elevation(CAM, tip, top, el)
        light = L.from_shadow_tip(CAM, new, top)
        assert dict(light.controls)["elevation"] == pytest.approx(el, abs=1e-6)
        T, _ = CAM.back_project(*new, 0.0)
        a, b = T0 - [P[0], 0, P[2]], T - [P[0], 0, P[2]]     # same direction from the top's foot
        assert abs(a[0] * b[2] - a[2] * b[0]) < 1e-9 * np.linalg.norm(a) * np.linalg.norm(b) + 1e-12
        assert a[0] * b[0] + a[2] * b[2] > 0
    with pytest.raises(ValueError, match="0.5, 90"):
        LS.tip_at_elevation(CAM, tip, top, 90.0)


# -- the server reads declarations, never type ids -----------------------------------------

def test_no_node_type_ids_or_plugin_imports_in_pixgraph_serve():
    folder = os.path.join(REPO, "pixgraph_serve")
    for name in sorted(os.listdir(folder)):
        if not name.endswith(".py"):
            continue
        text = open(os.path.join(folder, name)).read()
        assert not re.search(r"pixgraph\.[A-Z]\w+", text), name
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                mods = [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]
                assert not any(m.startswith("pixgraph_nodes") for m in mods), (name, mods)
        if name == "app.py":     # the routes use the state's public API only
            assert not re.search(r"\b(state|session|engine)\._\w", text) and ".engine" not in text


def test_roles_preview_and_alternatives_come_from_declarations(state):
    assert scene.roles(state) == {"camera": "cam", "light": "light", "background": "bg_h", "shadow": "shadow"}
    assert state.alternatives("pixgraph.SoftShadow") == ["pixgraph.HardShadow", "pixgraph.Shadow",
                                                        "pixgraph.SoftShadow", "pixgraph.SoftShadowSSN"]
    assert state.alternatives("pixgraph.Light") == ["pixgraph.Light"]
    assert state.alternatives("pixgraph.Composite") == []
    prev = state.preview_graph()
    assert prev.nodes["shadow"].type == "pixgraph.PreviewShadow"        # SoftShadow.preview
    assert prev.nodes["shadow"].params == {"thickness": 6}              # only the params it declares
    assert {n: i.type for n, i in prev.nodes.items() if n != "shadow"} == \
        {n: i.type for n, i in state.graph.nodes.items() if n != "shadow"}


@pytest.mark.parametrize("kind,azimuth", [("directional", 120.0), ("point", 240.0)])
def test_reported_tip_is_the_end_of_the_hard_shadow(state, kind, azimuth):
    state.set_type("shadow", "pixgraph.HardShadow")
    state.set_params({"light.kind": kind, "light.placement": "controls", "light.azimuth": azimuth,
                      "light.elevation": 70.0, "light.distance": 6.0})
    light = scene.describe(state)["light"]
    (u, v), top = light["tip_uv"], light["top_uvh"]
    dark = state.run(["shadow.darkness"])["shadow.darkness"]
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


def test_in_the_tip_placement_the_angle_params_are_the_lights(state):
    """A tip drag writes the light's own angles (seen from the top) into its azimuth and
    elevation params; an edit of those params (the panel's fields) moves the tip to give
    them, as the slider does; in the controls placement they are plain params."""
    def light():
        return scene.describe(state)["light"]

    state.set_params({"light.kind": "disk", "light.placement": "controls", "light.elevation": 35.0,
                      "light.azimuth": -25.0})
    serve_app.apply_edits(state, {"params": {"light.elevation": 40}})
    assert light()["elevation_deg"] == 40 and light()["placement"] == "controls"
    serve_app.apply_edits(state, {"light_tip": [230, 400]})
    got = light()
    assert got["placement"] == "shadow_tip" and abs(got["elevation_deg"] - 40) > 5
    assert got["elevation"] == round(got["elevation_deg"], 2) and got["azimuth"] == round(got["azimuth_deg"], 2)
    assert got["angles"] == {"light.azimuth": got["azimuth"], "light.elevation": got["elevation"]}
    # the panel's elevation: the tip slides along its direction; its azimuth: the tip turns
    serve_app.apply_edits(state, {"params": {"light.elevation": 30}})
    got2 = light()
    assert got2["elevation_deg"] == pytest.approx(30, abs=1e-6) and got2["elevation"] == 30
    assert got2["azimuth_deg"] == pytest.approx(got["azimuth_deg"], abs=1e-6)
    assert got2["tip_uv"] != pytest.approx(got["tip_uv"], abs=1)
    serve_app.apply_edits(state, {"params": {"light": {"azimuth": 100, "radius": 0.5}}})    # the nested form
    got3 = light()
    assert (got3["azimuth_deg"], got3["elevation_deg"]) == pytest.approx((100, 30), abs=1e-6)
    assert got3["radius"] == 0.5 and got3["azimuth"] == 100
    assert LS.shadow_tip(scene.anchors(state, scene.roles(state)).camera,
                         L.from_shadow_tip(scene.anchors(state, scene.roles(state)).camera, got3["tip_uv"],
                                           got3["top_uvh"]), got3["top_uvh"]) == pytest.approx(got3["tip_uv"])
    # an elevation the tip cannot give, or out of the param's range: refused, naming the field
    before = state.yaml()
    for bad, msg in ((0.2, "0.5, 90"), (95, "maximum")):
        with pytest.raises(ServeError, match=msg) as e:
            serve_app.apply_edits(state, {"params": {"light.elevation": bad}})
        assert e.value.where["field"] == "params.elevation" and e.value.where["node"] == "light"
    assert state.yaml() == before
    # back to controls: the params it reads are the light's last angles
    serve_app.apply_edits(state, {"params": {"light.placement": "controls"}})
    assert (light()["azimuth_deg"], light()["elevation_deg"]) == (100, 30)
    # the tip typed in the panel: the angles follow it too
    serve_app.apply_edits(state, {"params": {"light.placement": "shadow_tip", "light.tip_uv": [300, 470]}})
    got4 = light()
    assert abs(got4["elevation_deg"] - 30) > 1 and got4["elevation"] == round(got4["elevation_deg"], 2)
    assert got4["azimuth"] == round(got4["azimuth_deg"], 2)


def test_a_refused_angle_edit_in_the_tip_placement_names_the_angle_at_fault(tmp_path):
    """Azimuth and elevation typed together: the 400 names the one the tip cannot give
    (an elevation of 90, straight above: params.elevation; an azimuth that turns a low
    light's tip behind the camera: params.azimuth), and a light straight above the top
    (the tip at its foot) says its azimuth turns nothing; the message names the param,
    not a request field the panel never sent."""
    st = ServeState(copy_scene(str(tmp_path)))
    serve_app.apply_edits(st, {"light_tip": [230, 400]})
    before = st.yaml()
    for params, field in (({"light.azimuth": 30, "light.elevation": 90}, "params.elevation"),
                          ({"light.azimuth": 180, "light.elevation": 5}, "params.azimuth"),
                          ({"light": {"elevation": 90, "azimuth": 10}}, "params.elevation")):
        with pytest.raises(ServeError) as e:
            serve_app.apply_edits(st, {"params": params})
        assert e.value.where == {"node": "light", "field": field}, (params, e.value.where, e.value.message)
        assert "light_" not in e.value.message and field.split(".")[1] in e.value.message
        assert st.yaml() == before
    # both typed place the light by the top alone: a tip the horizon has passed does not matter
    cam = scene.roles(st)["camera"]
    horizon = st.graph.nodes[cam].params["horizon"]
    serve_app.apply_edits(st, {"params": {f"{cam}.horizon": 420}})      # above the foot, below the tip
    serve_app.apply_edits(st, {"params": {"light.azimuth": 30, "light.elevation": 40}})
    assert (scene.describe(st)["light"]["azimuth_deg"], scene.describe(st)["light"]["elevation_deg"]) == \
        pytest.approx((30, 40), abs=1e-6)
    serve_app.apply_edits(st, {"params": {f"{cam}.horizon": horizon}})
    # the elevation alone is fine there: the fault was the pair
    serve_app.apply_edits(st, {"params": {"light.elevation": 5}})
    assert scene.describe(st)["light"]["elevation_deg"] == pytest.approx(5, abs=1e-6)
    top = scene.describe(st)["light"]["top_uvh"]
    serve_app.apply_edits(st, {"light_tip": [top[0], top[1] + top[2]]})      # straight above
    assert scene.describe(st)["light"]["elevation_deg"] == 90
    with pytest.raises(ServeError, match="straight above") as e:
        serve_app.apply_edits(st, {"params": {"light.azimuth": 45}})
    assert e.value.where == {"node": "light", "field": "params.azimuth"}


def test_a_camera_edit_in_the_tip_placement_keeps_the_angle_params_the_lights(tmp_path):
    """Moving the horizon (or the field of view) turns the light the tip makes, seen from
    the top, without a light edit: the params must follow (a saved graph carries the
    light's angles, and switched to controls the light keeps its direction)."""
    st = ServeState(copy_scene(str(tmp_path)))
    serve_app.apply_edits(st, {"light_tip": [230, 400]})
    before = scene.describe(st)["light"]["angles"]
    cam = scene.roles(st)["camera"]
    for edit in ({f"{cam}.horizon": st.graph.nodes[cam].params["horizon"] - 60}, {cam: {"hfov": 65.0}}):
        serve_app.apply_edits(st, {"params": edit})
        got = scene.describe(st)["light"]
        assert got["angles"] != before and got["placement"] == "shadow_tip"
        assert (got["azimuth"], got["elevation"]) == (got["angles"]["light.azimuth"],
                                                        got["angles"]["light.elevation"])
        before = got["angles"]
    az, el = scene.describe(st)["light"]["azimuth_deg"], scene.describe(st)["light"]["elevation_deg"]
    serve_app.apply_edits(st, {"params": {"light.placement": "controls"}})
    assert (scene.describe(st)["light"]["azimuth_deg"], scene.describe(st)["light"]["elevation_deg"]) == \
        pytest.approx((az, el), abs=0.006)


def test_an_azimuth_written_back_keeps_the_params_convention(tmp_path):
    """In the tip placement the geometry gives azimuths in (-180, 180]; the param written
    back (a typed angle, a tip drag, a camera edit) keeps the param's convention inside
    its declared range: a typed 350 stays 350 (not -10), a drag across 0/360 reads 359.5,
    past the declared max (360) the turn that fits, and jumps never walk it round."""
    st = ServeState(copy_scene(str(tmp_path)))

    def light():
        return scene.describe(st)["light"]

    def tip_at(az, el=40.0):
        a = scene.anchors(st, scene.roles(st))
        return list(LS.tip_at_angles(a.camera, a.top, az, el))

    serve_app.apply_edits(st, {"light_tip": [230, 400]})
    serve_app.apply_edits(st, {"params": {"light.azimuth": 350, "light.elevation": 40}})
    got = light()
    assert got["azimuth"] == 350 and got["azimuth_deg"] == pytest.approx(350, abs=1e-6)
    assert got["angles"]["light.azimuth"] == 350
    # a tip drag to the light's azimuth -0.5 (= 359.5): from 350 that is 359.5
    serve_app.apply_edits(st, {"light_tip": tip_at(-0.5)})
    got = light()
    assert got["azimuth"] == pytest.approx(359.5, abs=0.006) and got["azimuth_deg"] == pytest.approx(359.5, abs=1e-6)
    assert got["angles"]["light.azimuth"] == got["azimuth"]
    # a camera edit turns the light a little: the param stays on its side of 0/360
    cam = scene.roles(st)["camera"]
    serve_app.apply_edits(st, {"params": {f"{cam}.horizon": st.graph.nodes[cam].params["horizon"] - 20}})
    got = light()
    assert 340 < got["azimuth"] <= 360 and got["azimuth"] == got["angles"]["light.azimuth"], got["angles"]
    # past the param's max (360): 370 does not fit, 10 does
    serve_app.apply_edits(st, {"light_tip": tip_at(10)})
    assert light()["azimuth"] == pytest.approx(10, abs=0.006)
    # typed on the negative side, the negative turn stays
    serve_app.apply_edits(st, {"params": {"light.azimuth": -350}})
    assert light()["azimuth"] == -350 and light()["azimuth_deg"] == pytest.approx(-350, abs=1e-6)
    serve_app.apply_edits(st, {"light_tip": tip_at(5)})
    assert light()["azimuth"] == pytest.approx(-355, abs=0.006)
    # from the example's -30, jumps of the tip stay in [-180, 180): the number does not
    # walk round (nearest-turn unwrapping read a jump to 170 as -190, and kept counting)
    serve_app.apply_edits(st, {"params": {"light.azimuth": -30}})
    for az in (170.0, -170.0, 100.0, -100.0, 175.0):
        serve_app.apply_edits(st, {"light_tip": tip_at(az)})
        assert light()["azimuth"] == pytest.approx(az, abs=0.006), az


def test_the_elevation_sliders_range_is_the_params_and_in_the_tip_placement_the_tips(tmp_path):
    """``/api/scene``'s ``light.elevation_range``: the elevation param's declared min/max
    in the controls placement, from the light's ``elevation_min`` handle up; in the tip placement the part of it the tip geometry gives
    ([0.5, 90): 89.99 at most, the 0.01 deg the angles are written to), and each end is
    an elevation the tip takes."""
    st = ServeState(copy_scene(str(tmp_path)))
    spec = st.registry.get(st.graph.nodes["light"].type).param("elevation")
    serve_app.apply_edits(st, {"params": {"light.placement": "controls"}})
    # from the lowest elevation that does something (a light below it is raised to it)
    assert (spec.min, spec.max) == (-90.0, 90.0)
    assert scene.describe(st)["light"]["elevation_range"] == [MIN_ELEVATION_DEG, spec.max] == [1.0, 90.0]
    serve_app.apply_edits(st, {"light_tip": [230, 400]})
    lo, hi = scene.describe(st)["light"]["elevation_range"]
    assert (lo, hi) == (LS.TIP_ELEVATION_RANGE[0], 89.99)
    serve_app.apply_edits(st, {"light_elevation": hi})
    assert scene.describe(st)["light"]["elevation_deg"] == pytest.approx(hi, abs=1e-6)
    with pytest.raises(ServeError, match="0.5, 90"):
        serve_app.apply_edits(st, {"light_elevation": hi + 0.01})
    with pytest.raises(ServeError, match="0.5, 90"):
        serve_app.apply_edits(st, {"light_elevation": lo - 0.01})
    # a tip dragged within 0.005 deg of straight above is written as the slider's end, not
    # as 90.0, which the tip geometry refuses (before: 90.0, and the slider read past its end)
    a = scene.anchors(st, scene.roles(st))
    serve_app.apply_edits(st, {"light_tip": list(LS.tip_at_angles(a.camera, a.top, 30.0, 89.996))})
    assert st.graph.nodes["light"].params["elevation"] == hi == 89.99
    serve_app.apply_edits(st, {"params": {"light.azimuth": 40}})          # and it still edits
    assert scene.describe(st)["light"]["azimuth"] == 40


def test_in_the_controls_placement_the_panel_is_told_the_params_as_they_are(tmp_path):
    """In the controls placement the light's angles are its params: what the page is told
    to show for them (``angles``) must be those params, not rounded to 0.01 deg (a typed
    20.004 shown as 20.0 is a value the graph does not have)."""
    st = ServeState(copy_scene(str(tmp_path)))
    serve_app.apply_edits(st, {"params": {"light.placement": "controls", "light.azimuth": 20.004,
                                          "light.elevation": 33.337}})
    got = scene.describe(st)["light"]
    for key, value in got["angles"].items():
        assert value == {"light.azimuth": 20.004, "light.elevation": 33.337}[key], got["angles"]


def _drag(state, tip, mode="preview"):
    """What POST /api/render does for a drag step; returns the number of graph runs."""
    def work():
        serve_app.apply_edits(state, {"light_tip": tip})
        graph = state.graph_for(mode)
        extra = scene.piggyback(state, graph, ["final"])
        res = state.run(["final", *extra], mode)
        scene.note(state, graph, extra, res)
        return res
    return serve_app.run_counted(state, work)[1]


def test_a_drag_runs_the_graph_once(state):
    state.set_type("shadow", "pixgraph.SoftShadow")
    state.set_params({"cutout.path": "assets/figure.png"})
    state.anchors = None
    assert _drag(state, [150, 420]) == 2          # the first one finds the object's top with a run of its own
    runs = [_drag(state, [150 + 7 * i, 420 - 3 * i]) for i in range(1, 6)]
    assert runs == [1] * 5                        # then one run per drag step
    assert list(state.graph.nodes["light"].params["tip_uv"]) == [185.0, 405.0]
    # an edit upstream of the object's top or the camera costs one more run, once
    state.set_params({"cam.horizon": 121})
    assert _drag(state, [160, 430]) == 2
    assert _drag(state, [161, 431]) == 1
    state.set_params({"cam.horizon": 120})


def test_a_refused_edit_changes_nothing(state):
    before = state.yaml()
    with pytest.raises(ServeError) as e:
        serve_app.apply_edits(state, {"types": {"shadow": "pixgraph.HardShadow"},
                                      "params": {"light.elevation": 500}})
    assert e.value.status == 400 and e.value.where["field"] == "params.elevation"
    assert state.yaml() == before and state.graph.nodes["shadow"].type == "pixgraph.SoftShadow"
    with pytest.raises(ServeError):
        serve_app.apply_edits(state, {"light_tip": [150, 420], "params": {"light.kind": "laser"}})
    assert state.yaml() == before


def test_own_photo_graph_camera_size_from_its_image_and_the_placed_cutout(tmp_path):
    import shutil

    from serve_helpers import GRAPHS

    os.makedirs(tmp_path / "assets")
    for name in ("own_cutout.png", "own_photo.jpg"):
        shutil.copy(os.path.join(GRAPHS, "assets", name), tmp_path / "assets" / name)
    shutil.copy(os.path.join(GRAPHS, "own_photo.yaml"), tmp_path / "own_photo.yaml")
    st = ServeState(str(tmp_path / "own_photo.yaml"))
    r = scene.roles(st)
    assert r == {"camera": "cam", "light": "light", "background": "bg_h", "shadow": "shadow", "place": "place"}
    d = scene.describe(st)
    photo = st.run(["photo.image"])["photo.image"]
    assert [d["camera"]["width"], d["camera"]["height"]] == [photo.shape[1], photo.shape[0]]
    alpha = st.run(["place.alpha"])["place.alpha"]
    rows, cols = np.nonzero(alpha > 0.5)
    assert d["place"]["bbox"] == [cols.min(), rows.min(), cols.max() + 1, rows.max() + 1]
    assert d["place"]["foot"] == [270, 345] and d["place"]["scale"] == 0.8
    u0, _, u1, v1 = d["place"]["bbox"]
    assert u0 < 270 < u1 and abs(v1 - 345) < 3            # the foot is on the box's bottom edge


def test_a_cutout_changed_on_disk_moves_the_top_from_the_next_render(tmp_path):
    from PIL import Image

    st = ServeState(copy_scene(str(tmp_path / "scene")))
    path = tmp_path / "scene" / "assets" / "figure.png"
    _drag(st, [150, 420])
    top = st.anchors.top
    assert _drag(st, [151, 421]) == 1 and st.anchors.top == top
    img = Image.open(path)
    lowered = Image.new(img.mode, img.size)
    lowered.paste(img.crop((0, 0, img.width, img.height - 20)), (0, 20))    # the figure 20 px lower
    lowered.save(path)
    os.utime(path, ns=(os.stat(path).st_atime_ns, os.stat(path).st_mtime_ns + 10**9))
    assert _drag(st, [152, 422]) == 1                  # this step still uses the old top; its run sees the file
    assert st.anchors.top[1] == top[1] + 20 and st.anchors.top[0] == top[0]
    assert list(st.graph.nodes["light"].params["top_uvh"]) == list(top)
    _drag(st, [153, 423])
    assert list(st.graph.nodes["light"].params["top_uvh"]) == list(st.anchors.top)
