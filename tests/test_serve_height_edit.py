"""The hand edit of a cutout's pixel height in the page (pixgraph.PixelHeightEdit's
handles, ``pixgraph_serve.scene``): the frame from the cutout's pixels to the photo,
the tilt handle's inverse, the own-photo templates with the edit at its defaults
(identical to the graph without it), and the params saved and loaded back.
In-process ``ServeState``; the page itself is in test_page_height_edit.py."""
import os
import shutil

import numpy as np
import pytest
import yaml

from pixgraph_nodes.ops import height_edit as he
from pixgraph_nodes.ops.placement import place_cutout
from pixgraph_serve import app as serve_app
from pixgraph_serve import files, scene
from pixgraph_serve.state import ServeState
from serve_helpers import GRAPHS


# -- the geometry -----------------------------------------------------------------------------

@pytest.mark.parametrize("flip", [False, True])
@pytest.mark.parametrize("scale", [0.5, 1.0, 2.5])
def test_placed_frame_puts_a_cutout_pixel_where_place_cutout_puts_it(scale, flip):
    """A single bright pixel's placed centroid lands where the frame maps its centre."""
    h, w = 60, 40
    alpha = np.zeros((h, w), np.float32)
    alpha[10:55, 8:30] = 1.0
    img = np.zeros((h, w, 4), np.float32)
    img[..., 3] = alpha
    r, c = 20, 12
    img[r - 1:r + 2, c - 1:c + 2, 0] = 1.0           # a 3x3 marker around pixel (r, c)
    foot = (150.3, 170.7)
    out, _, _ = place_cutout(img, alpha, None, (240, 300), foot, scale, flip)
    red = out[..., 0]
    ys, xs = np.mgrid[0:240, 0:300] + 0.5
    got = (float((red * xs).sum() / red.sum()), float((red * ys).sum() / red.sum()))
    sx, tx, sy, ty = he.placed_frame(alpha, foot, scale, flip)
    want = (sx * (c + 0.5) + tx, sy * (r + 0.5) + ty)
    assert got == pytest.approx(want, abs=0.05 + 0.05 * scale)
    # and the mask's foot lands on `foot`
    ax, ay = 19.0, 55.0                               # columns 8..29 -> centre 19, bottom edge row 55
    assert (sx * ax + tx, sy * ay + ty) == pytest.approx(foot)


@pytest.mark.parametrize("tilt", [-30.0, -5.0, 0.0, 12.0, 40.0])
@pytest.mark.parametrize("lift", [0.0, 6.0])
def test_tilt_for_height_inverts_the_top_height(tilt, lift):
    H, W = 80, 50
    mask = np.zeros((H, W), bool)
    mask[15:70, 10:40] = True
    v = np.mgrid[0:H, 0:W][0] + 0.5
    height = np.where(mask, 70.0 - v, 0.0)
    edited = he.edit_pixel_height(height, mask, [(25.5, 69.5)], tilt_deg=tilt, elevation_deg=25.0, lift=lift)
    u, vv, h, h0 = he.top_point(mask, edited, tilt, 25.0, lift)
    assert (u, vv) == (25.5, 15.5)
    assert h0 == pytest.approx(69.5 - 15.5, abs=1e-3)   # the contact row (height 0.5) is the new 0
    assert h == pytest.approx(he.tilt_gain(tilt, 25.0) * h0 + lift, abs=1e-3)
    assert he.tilt_for_height(h0, h, lift, 25.0) == pytest.approx(tilt, abs=1e-3)
    # far taller than the gain allows: clamped where the object is MAX_GAIN times taller, a valid tilt
    steep = he.tilt_for_height(h0, 50 * h0 + lift, lift, 25.0)
    assert he.tilt_gain(steep, 25.0) == pytest.approx(he.MAX_GAIN)


def test_defaults_pass_the_height_through_unchanged():
    rng = np.random.default_rng(0)
    h = rng.random((30, 20)).astype(np.float32) * 9 - 1        # negatives and values outside the mask too
    m = rng.random((30, 20)) > 0.5
    out = he.edit_pixel_height(h, m)
    assert out.dtype == np.float32 and np.array_equal(out, h)
    assert not np.array_equal(he.edit_pixel_height(h, m, lift=0.5), h)


# -- the own-photo templates -------------------------------------------------------------------

def _assets(dest):
    os.makedirs(dest, exist_ok=True)
    for name in ("own_photo.jpg", "own_cutout.png"):
        shutil.copy(os.path.join(GRAPHS, "assets", name), os.path.join(dest, name))
    return {"photo": os.path.join(dest, "own_photo.jpg"), "cutout": os.path.join(dest, "own_cutout.png")}


def _mask_file(dest, cutout):
    from PIL import Image

    a = np.asarray(Image.open(cutout))[..., 3]
    rgb = np.asarray(Image.open(cutout))[..., :3]
    Image.fromarray(rgb).save(os.path.join(dest, "cut_rgb.png"))
    Image.fromarray(a).save(os.path.join(dest, "cut_mask.png"))
    return os.path.join(dest, "cut_rgb.png"), os.path.join(dest, "cut_mask.png")


def _without_edit(text: str) -> str:
    """The filled template as it was before the edit node: place reads fg_h directly."""
    doc = yaml.safe_load(text)
    assert doc["nodes"]["edit"]["type"] == "pixgraph.PixelHeightEdit"
    assert doc["nodes"]["place"]["inputs"]["height"] == "edit.height"
    del doc["nodes"]["edit"]
    doc["nodes"]["place"]["inputs"]["height"] = "fg_h.height"
    return yaml.safe_dump(doc, sort_keys=False)


@pytest.mark.parametrize("template", ["own_photo", "own_photo_mask"])
def test_template_with_the_edit_at_its_defaults_renders_as_without_it(tmp_path, template):
    paths = _assets(str(tmp_path))
    if template == "own_photo_mask":
        paths["cutout"], paths["mask"] = _mask_file(str(tmp_path), paths["cutout"])
    text = files.fill(files.template_text(template), paths, {"W": 640, "H": 480, "w": 159, "h": 285})
    (tmp_path / "g.yaml").write_text(text)
    state = ServeState(str(tmp_path / "g.yaml"))
    # the hard shadow keeps this quick; the edit sits upstream of every shadow method alike
    state.set_type("shadow", "pixgraph.HardShadow")
    with_edit = state.run(["final", "place.height"])
    state.load_text(_without_edit(text))
    state.set_type("shadow", "pixgraph.HardShadow")
    without = state.run(["final", "place.height"])
    assert (with_edit["place.height"] > 1).sum() > 1000          # a real height map went through
    assert np.array_equal(with_edit["place.height"], without["place.height"])
    assert np.array_equal(with_edit["final"], without["final"])


# -- the scene and edits ----------------------------------------------------------------------

@pytest.fixture(scope="module")
def photo_state(tmp_path_factory):
    d = tmp_path_factory.mktemp("edit")
    paths = _assets(str(d))
    text = files.fill(files.template_text("own_photo"), paths, {"W": 640, "H": 480, "w": 159, "h": 285})
    (d / "g.yaml").write_text(text)
    state = ServeState(str(d / "g.yaml"))
    state.set_type("shadow", "pixgraph.HardShadow")
    return state


def test_scene_describes_the_edit_in_the_cutouts_pixels(photo_state):
    s = scene.describe(photo_state)
    e = s["height_edit"]
    assert s["roles"]["height_edit"] == "edit" and e["place"] == "place"
    assert e["size"] == [159, 285]
    assert e["values"] == {"points": [], "mode": "shift", "tilt": 0.0, "elevation": 20.0, "lying": False,
                           "lift": 0.0, "depth": 0.0, "thickness": 0.0}
    assert e["params"]["depth"] == "foot_depth" and e["params"]["thickness"] == "thickness"
    sx, tx, sy, ty = e["frame"]
    foot = s["place"]["foot"]
    assert sx == sy == pytest.approx(s["place"]["scale"])
    # the cutout's foot (shown as the hollow contact handle) maps onto the placement's foot
    assert (sx * e["foot"][0] + tx, sy * e["foot"][1] + ty) == pytest.approx(foot)
    # the top: its height is the pixel height there, from the edit's output
    u, v, h, h0 = e["top"]
    out = photo_state.run(["edit.height"])["edit.height"]
    assert h == pytest.approx(float(out[int(v), int(u)])) and h == pytest.approx(h0) and h > 100
    # the placed box's top matches the frame's top row
    assert sy * (v - 0.5) + ty == pytest.approx(s["place"]["bbox"][1], abs=1.5 * sy + 1)
    # the body's ring: the covered pixel nearest the coverage's centroid, its edited height
    bu, bv, bh, bh0 = e["body"]
    cov = photo_state.run(["cutout.alpha"])["cutout.alpha"]
    cov = (cov[..., 0] if cov.ndim == 3 else cov) > 0.5
    ys, xs = np.nonzero(cov)
    d2 = (ys - ys.mean()) ** 2 + (xs - xs.mean()) ** 2
    assert cov[int(bv), int(bu)] and (int(bv) - ys.mean()) ** 2 + (int(bu) - xs.mean()) ** 2 == pytest.approx(d2.min())
    assert bh == pytest.approx(float(out[int(bv), int(bu)])) and bh == pytest.approx(bh0) and bh > 10



def test_no_body_point_in_the_scene_while_lying(photo_state):
    # lying ignores the foot depth, so the body point's "height before it" would be wrong
    # (the page hides the ring; /api/scene says None)
    serve_app.apply_edits(photo_state, {"params": {"edit.lying": True, "edit.foot_depth": 10.0}})
    try:
        e = scene.describe(photo_state)["height_edit"]
        assert e["values"]["lying"] is True and e["body"] is None and e["top"] is not None
    finally:
        serve_app.apply_edits(photo_state, {"params": {"edit.lying": False, "edit.foot_depth": 0.0}})
    assert scene.describe(photo_state)["height_edit"]["body"] is not None


def test_contact_points_move_the_shadow_and_save_and_load_back(photo_state):
    before = photo_state.run(["shadow.darkness"])["shadow.darkness"]
    e = scene.describe(photo_state)["height_edit"]
    fx, fy = e["foot"]
    # a contact point 60 px above the foot: the object sinks by the height there
    edits = {"params": {"edit.contact_points": [fx, fy - 60.0], "edit.tilt": 15.0}}
    serve_app.apply_edits(photo_state, edits)
    after = photo_state.run(["shadow.darkness"])["shadow.darkness"]
    assert np.abs(after - before).sum() > 50
    got = photo_state.run(["edit.height", "fg_h.height", "cutout.alpha"])
    want = he.edit_pixel_height(got["fg_h.height"], got["cutout.alpha"] > 0.5, [(fx, fy - 60.0)], tilt_deg=15.0)
    assert np.array_equal(got["edit.height"], want)
    assert want.max() < 0.95 * got["fg_h.height"].max()       # sunk and leaning back: lower
    saved = photo_state.save("saved_edit.yaml")
    again = ServeState(saved)
    vals = {n["id"]: n["values"] for n in again.info()["nodes"]}["edit"]
    assert vals["contact_points"] == [fx, fy - 60.0] and vals["tilt"] == 15.0
    assert np.array_equal(again.run(["shadow.darkness"])["shadow.darkness"], after)


# -- previews: their own cache, JPEG ------------------------------------------------------------

def test_scaled_previews_keep_their_upstream_when_a_final_evicts_everything(photo_state):
    """A full-size final cannot push a preview's upstream out: the previews' session has its
    own memory cache (here the full-size one holds nothing at all)."""
    state = photo_state
    state.session.memory.limit_bytes = 0
    state.session.memory.clear()
    serve_app.apply_edits(state, {"params": {"light.azimuth": -20}})
    first = state.run(["final"], "preview", scale=0.5)
    assert "photo" in first.ran and first["final"].shape[:2] == (240, 320)
    state.run(["final"], "final")                                  # a final at full size in between
    serve_app.apply_edits(state, {"params": {"light.azimuth": -25}})
    again = state.run(["final"], "preview", scale=0.5)
    assert set(again.ran) == {"light", "shadow", "comp"}, again.ran
    assert state.session_for(0.5) is not state.session and state.session_for(1.0) is state.session


def test_render_answers_a_jpeg_preview(photo_state):
    import io

    from PIL import Image
    from starlette.testclient import TestClient

    with TestClient(serve_app.create_app(photo_state)) as c:
        r = c.post("/api/render", json={"mode": "preview", "scale": 1, "work": 0.5, "format": "jpeg",
                                        "params": {"light.azimuth": -28}})
        assert r.status_code == 200 and r.headers["content-type"] == "image/jpeg"
        img = Image.open(io.BytesIO(r.content))
        assert img.format == "JPEG" and img.size == (320, 240)
        png = c.post("/api/render", json={"mode": "preview", "scale": 1, "work": 0.5})
        ref = np.asarray(Image.open(io.BytesIO(png.content)).convert("RGB"), np.float32)
        assert np.abs(np.asarray(img, np.float32) - ref).mean() < 3.0      # the same picture, lossy
        bad = c.post("/api/render", json={"mode": "preview", "format": "gif"})
        assert bad.status_code == 400 and "format" in bad.json()["error"]


def test_a_render_a_node_refuses_leaves_the_graph_as_it_was(tmp_path):
    """The cutout dragged off the photo: PlaceCutout refuses it (400, naming the node), and the
    served graph keeps the foot it had, so /api/scene (what the page loads its handles and panel
    from) still answers and the next render of another edit works. Before, the refused foot
    stayed in the graph: every later render and /api/scene failed with the same error, and a
    reload of the page showed nothing but that error (no image, no panel to fix it in)."""
    from starlette.testclient import TestClient

    paths = _assets(str(tmp_path))
    text = files.fill(files.template_text("own_photo"), paths, {"W": 640, "H": 480, "w": 159, "h": 285})
    (tmp_path / "g.yaml").write_text(text)
    state = ServeState(str(tmp_path / "g.yaml"))
    state.set_type("shadow", "pixgraph.HardShadow")
    foot = state.info()["nodes"][[n["id"] for n in state.info()["nodes"]].index("place")]["values"]["foot"]
    with TestClient(serve_app.create_app(state)) as c:
        for path, body in (("/api/render", {"params": {"place.foot": [5000, 345]}}),
                           ("/api/run", {"params": {"place.foot": [5000, 345]}, "outputs": ["final"]}),
                           ("/api/render", {"params": {"place.foot": [5000, 345]}, "mode": "preview",
                                            "work": 0.5, "client": "a", "seq": 1})):
            r = c.post(path, json=body)
            assert r.status_code == 400 and r.json()["node"] == "place", (path, r.text)
            assert "placed cutout lies outside the" in r.json()["error"]
            # the preview's numbers are at its working resolution (a 320x240 canvas, the foot
            # at half): the error says so, or they read as wrong numbers of the user's photo
            if body.get("work"):
                assert "320x240" in r.json()["error"] and "working resolution 0.5" in r.json()["error"]
            values = {n["id"]: n["values"] for n in c.get("/api/graph").json()["nodes"]}
            assert values["place"]["foot"] == foot, path
            assert c.get("/api/scene").status_code == 200, path
        ok = c.post("/api/render", json={"params": {"light.azimuth": -20}})
        assert ok.status_code == 200 and ok.headers["content-type"] == "image/png"


def test_a_contact_point_on_the_cutouts_bottom_edge_works_in_previews(photo_state):
    """The page clamps a contact point to the cutout's pixel edges [0, w] x [0, h]; a drag
    to the foot's bottom edge gives v = h, which the final takes. At a preview's working
    resolution the cutout is round(h x scale) rows, here less than h x scale, and the edge
    point was refused ("outside the 80x142 cutout", the working size) on every preview
    of the drag. It now lies on the scaled cutout's edge: the same edit as the point
    moved onto that edge by hand."""
    state = photo_state
    h = state.run(["cutout.alpha"])["cutout.alpha"].shape[0]
    assert h == 285 and int(h * 0.5) != h * 0.5               # 142 rows at half size, not 142.5
    edge, inside = [58.5, float(h)], [58.5, 2.0 * int(h * 0.5)]   # 285 -> 142.5; 284 -> 142.0
    serve_app.apply_edits(state, {"params": {"edit.contact_points": edge}})
    at_edge = state.run(["edit.height"], "preview", scale=0.5)["edit.height"]
    full = state.run(["edit.height"], "final")["edit.height"]
    serve_app.apply_edits(state, {"params": {"edit.contact_points": inside}})
    moved = state.run(["edit.height"], "preview", scale=0.5)["edit.height"]
    assert np.array_equal(at_edge, moved)
    assert full.shape == (285, 159) and at_edge.shape == (142, 80)
    # further out than that is still a mistake, named by node and param
    serve_app.apply_edits(state, {"params": {"edit.contact_points": [58.5, h + 3.0]}})
    with pytest.raises(Exception, match=r"edit.*contact_points.*outside"):
        state.run(["edit.height"], "final")
    serve_app.apply_edits(state, {"params": {"edit.contact_points": []}})
