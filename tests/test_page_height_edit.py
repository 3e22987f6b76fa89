"""The hand edit of the cutout's pixel height in the page (pixgraph.PixelHeightEdit's
handles), in headless Chromium: the own-photo template (which has the edit) on the
repo's own photo and cutout; the handles are drawn where the scene maps them, a
contact point dragged changes the param and the shadow's pixels while dragging
(previews) and after, the tilt handle gives the tilt of ops.height_edit's inverse,
points are added and removed, the body's ring sets the foot depth, "lying down"
toggles and the top's square then sets the thickness, and the page's save writes the
params that load back."""
import os

import httpx
import numpy as np
import pytest

from pixgraph_nodes.ops import height_edit as he
from pixgraph_serve import files
from serve_helpers import chromium_browser, running_server
from test_page_photo import _png, centre, check_handles_visible, drag, graph_params, keep, last_seq, open_page, \
    screen, shown, wait_final
from test_serve_height_edit import _assets


@pytest.fixture(scope="module")
def browser():
    with chromium_browser() as b:
        yield b


def edit_graph(dest) -> str:
    paths = _assets(os.path.join(dest, "assets"))
    rel = {k: os.path.relpath(v, dest) for k, v in paths.items()}
    text = files.fill(files.template_text("own_photo"), rel, {"W": 640, "H": 480, "w": 159, "h": 285})
    # the hard shadow: quick finals; its outline shows every change of the height
    import yaml
    doc = yaml.safe_load(text)
    doc["nodes"]["shadow"]["type"] = "pixgraph.HardShadow"
    doc["nodes"]["shadow"]["params"].pop("samples")
    text = yaml.safe_dump(doc, sort_keys=False)
    path = os.path.join(dest, "edit.yaml")
    with open(path, "w") as f:
        f.write(text)
    return path


def to_canvas(e, x, y):
    sx, tx, sy, ty = e["frame"]
    return sx * x + tx, sy * y + ty


def to_cutout(e, u, v):
    sx, tx, sy, ty = e["frame"]
    return (u - tx) / sx, (v - ty) / sy


def test_drag_the_cutouts_contact_and_tilt_in_the_page(browser, tmp_path):
    graph = edit_graph(str(tmp_path))
    with running_server(graph) as (url, _):
        page, errors = open_page(browser, url)
        k = page.evaluate("window.pixgraphView.state.k")
        scene = httpx.get(url + "/api/scene", timeout=60).json()
        e = scene["height_edit"]
        assert page.locator("#height-tools").is_visible()
        check_handles_visible(page)
        # the height's source (the template's CutoutHeight) has its params open beside the
        # handles: its method is one choice away; the edit's coverage source (cutout) is not
        assert e["sources"] == ["fg_h"]
        assert page.locator('[data-param="fg_h.method"]').is_visible()
        assert not page.locator('[data-param="cutout.path"]').is_visible()
        # the hollow contact handle sits just under the cutout's foot (2.6 handle radii: clear
        # of the cutout's foot square), the tilt handle on its top
        for sel, (u, v), below in (("#contact-new", scene["place"]["foot"], 2.6 * 7),
                                   ("#tilt-handle", to_canvas(e, e["top"][0], e["top"][1]), 0)):
            b = page.locator(sel).bounding_box()
            assert 12 <= b["width"] <= 20, (sel, b)
            x, y = centre(page, sel)
            sx, sy = screen(page, u, v)
            assert abs(x - sx) < 1.5 and abs(y - sy - below) < 1.5, sel
        photo = _png(httpx.get(url + "/api/outputs/photo.image.png", timeout=60).content)
        alpha = _png(httpx.get(url + "/api/outputs/place.alpha.png", timeout=60).content)[:, :, 0]

        def shadow(img):
            return ((photo - img).mean(axis=2) > 0.05) & (alpha < 0.02)

        before = shadow(shown(page))
        assert before.sum() > 300
        keep(page, "height_edit_before.png")

        # one contact point, dragged 70 image px up into the figure: the object sinks by its
        # height there; the preview while dragging already shows a different shadow
        fu, fv = scene["place"]["foot"]
        row = alpha[int(fv - 70)]
        cols = np.nonzero(row > 0.9)[0]
        col = cols[np.argmin(np.abs(cols + 0.5 - fu))]      # on the figure (a leg), nearest the foot
        target = (col + 0.5, fv - 70)
        seq = last_seq(page)
        page.mouse.move(*centre(page, "#contact-new"))
        page.mouse.down()
        page.mouse.move(*screen(page, *target), steps=6)
        page.wait_for_function(f"window.pixgraphShown.some(s => s.mode === 'preview' && s.seq > {seq})",
                               timeout=120000)
        # the pointer still down: the queue done, the last preview is of the last position
        page.wait_for_function("(q => !q.inflight && !q.pending)(window.pixgraphQueue())", timeout=120000)
        preview_img = shown(page)
        assert page.evaluate("window.pixgraphShown.at(-1).mode") == "preview"
        page.mouse.up()
        wait_final(page, seq)
        pts = graph_params(url)["edit"]["contact_points"]
        assert pts == pytest.approx(list(to_cutout(e, *target)), abs=1.0 / k + 0.2)
        after = shadow(shown(page))
        assert np.logical_xor(before, after).sum() > 100, "the shadow did not change"
        assert after.sum() < before.sum()         # sunk by the height 70 px up: a shorter shadow
        # the preview came at half size: compared with the plate and coverage at half size
        photo2 = _png(httpx.get(url + "/api/outputs/photo.image.png?scale=2", timeout=60).content)
        alpha2 = _png(httpx.get(url + "/api/outputs/place.alpha.png?scale=2", timeout=60).content)[:, :, 0]
        assert preview_img.shape == photo2.shape
        small = ((photo2 - preview_img).mean(axis=2) > 0.05) & (alpha2 < 0.02)
        assert small.sum() > 50
        assert abs(4 * int(small.sum()) - int(before.sum())) > 0.5 * abs(int(after.sum()) - int(before.sum()))
        keep(page, "height_edit_contact.png")

        # "+ contact" then a click: a second point; "- contact" removes it
        seq = last_seq(page)
        page.click("#add-contact")
        page.mouse.click(*screen(page, fu + 20, fv - 5))
        wait_final(page, seq)
        pts2 = graph_params(url)["edit"]["contact_points"]
        assert len(pts2) == 4 and pts2[:2] == pts
        assert pts2[2:] == pytest.approx(list(to_cutout(e, fu + 20, fv - 5)), abs=1.0 / k + 0.2)
        assert page.locator("#contact-1").is_visible()
        # a drag from the foot's hollow handle adds a third; "- contact" takes it away again
        drag(page, centre(page, "#contact-new"), screen(page, fu - 15, fv - 3))
        pts3 = graph_params(url)["edit"]["contact_points"]
        assert len(pts3) == 6 and pts3[:4] == pts2
        assert pts3[4:] == pytest.approx(list(to_cutout(e, fu - 15, fv - 3)), abs=1.0 / k + 0.2)
        seq = last_seq(page)
        page.click("#remove-contact")
        wait_final(page, seq)
        seq = last_seq(page)
        page.click("#remove-contact")
        wait_final(page, seq)
        assert graph_params(url)["edit"]["contact_points"] == pts

        # the tilt handle: pushed 40 px down, the top's height is 40 / k image px smaller
        e2 = httpx.get(url + "/api/scene", timeout=60).json()["height_edit"]
        tu, tv, h, h0 = e2["top"]
        x, y = centre(page, "#tilt-handle")
        drag(page, (x, y), (x, y + 40))
        want_h = h - 40 / k / e2["frame"][2]
        tilt = graph_params(url)["edit"]["tilt"]
        assert tilt == pytest.approx(he.tilt_for_height(h0, want_h, 0.0, 20.0), abs=0.6)
        assert tilt > 5
        e3 = httpx.get(url + "/api/scene", timeout=60).json()["height_edit"]
        assert e3["top"][2] == pytest.approx(want_h, rel=0.02)

        # the body's ring (foot depth): pulled 12 px up, the body point is 12 / k image px taller
        b = e3["body"]
        assert b is not None and page.locator("#depth-handle").is_visible()
        x, y = centre(page, "#depth-handle")
        assert (x, y) == pytest.approx(screen(page, *to_canvas(e3, b[0], b[1])), abs=1.5)
        g = he.tilt_gain(tilt, 20.0)
        drag(page, (x, y), (x, y - 12))
        want_b = b[2] + 12 / k / e3["frame"][2]
        depth = graph_params(url)["edit"]["foot_depth"]
        assert depth == pytest.approx(he.depth_for_height(b[3], want_b, g, 0.0), abs=0.6 / g)
        assert 3 < depth < b[3] / 2                               # within the ring's range: not clipped
        e4 = httpx.get(url + "/api/scene", timeout=60).json()["height_edit"]
        assert e4["body"][:2] == b[:2] and e4["body"][2] == pytest.approx(want_b, abs=0.6)
        keep(page, "height_edit_depth.png")

        # lying down: a toggle; the ring goes, the top's square sets the thickness: pulled 20 px
        # up, the top is 20 / k image px taller (thickness = height / the tilt's gain)
        seq = last_seq(page)
        page.check("#lying")
        wait_final(page, seq)
        assert graph_params(url)["edit"]["lying"] is True
        assert page.locator("#depth-handle").count() == 0
        e5 = httpx.get(url + "/api/scene", timeout=60).json()["height_edit"]
        x, y = centre(page, "#tilt-handle")
        drag(page, (x, y), (x, y - 20))
        want_t = e5["top"][2] + 20 / k / e5["frame"][2]
        thick = graph_params(url)["edit"]["thickness"]
        assert thick == pytest.approx(he.thickness_for_height(want_t, g), abs=0.6 / g)
        assert graph_params(url)["edit"]["tilt"] == tilt          # the tilt is kept, not dragged
        e6 = httpx.get(url + "/api/scene", timeout=60).json()["height_edit"]
        assert e6["top"][2] == pytest.approx(want_t, abs=0.6)
        # pushed down past the ground: the flattest it lies, not thickness 0 (the default,
        # half the median column extent, which would make it jump up)
        x, y = centre(page, "#tilt-handle")
        drag(page, (x, y), (x, y + (e6["top"][2] * e6["frame"][2] * k + 10)))
        assert 0 < graph_params(url)["edit"]["thickness"] <= 0.01
        flat = httpx.get(url + "/api/scene", timeout=60).json()["height_edit"]
        assert flat["top"] is not None and flat["top"][2] <= 0.01 * g + 1e-4
        x, y = centre(page, "#tilt-handle")                     # and back up to the thickness above
        drag(page, (x, y), (x, y - (want_t - flat["top"][2]) * e6["frame"][2] * k))
        thick = graph_params(url)["edit"]["thickness"]
        assert thick == pytest.approx(he.thickness_for_height(want_t, g), abs=0.6 / g)
        page.fill("#save-name", "edited.yaml")
        page.click("#save")
        page.wait_for_function("document.getElementById('status').textContent.startsWith('saved')", timeout=60000)
        from pixgraph_serve.state import ServeState
        saved = ServeState(str(tmp_path / "edited.yaml"))
        vals = {n["id"]: n["values"] for n in saved.info()["nodes"]}["edit"]
        assert vals["contact_points"] == pts and vals["tilt"] == tilt and vals["lying"] is True
        assert vals["foot_depth"] == depth and vals["thickness"] == thick
        assert not errors, errors
        page.close()


def test_the_learned_and_auto_heights_are_one_choice_in_the_page(browser, tmp_path):
    # the page opens CutoutHeight's params beside the handles; the own-photo templates
    # connect the cutout's colour, so learned and auto run (they read it) instead of
    # showing "connect input 'image'"
    graph = edit_graph(str(tmp_path))
    with running_server(graph) as (url, _):
        page, errors = open_page(browser, url)
        photo = _png(httpx.get(url + "/api/outputs/photo.image.png", timeout=60).content)
        alpha = _png(httpx.get(url + "/api/outputs/place.alpha.png", timeout=60).content)[:, :, 0]

        def shadow(img):
            return ((photo - img).mean(axis=2) > 0.05) & (alpha < 0.02)

        before = shadow(shown(page))
        # the view (the stage's box and the image's place on it) before any line was said
        view = page.evaluate("[document.getElementById('stage').getBoundingClientRect().toJSON(),"
                             " window.pixgraphView.state.k, window.pixgraphView.state.ox, window.pixgraphView.state.oy]")
        heights = {}
        # the last two come from the cache: what the node said when it ran with those params
        for method in ("learned", "auto", "contact_line", "learned"):
            seq = last_seq(page)
            page.locator('[data-param="fg_h.method"]').select_option(method)
            # a final, or the error box (the graph could not run)
            page.wait_for_function(f"!document.getElementById('error').hidden || "
                                   f"window.pixgraphShown.at(-1).seq > {seq}", timeout=180000)
            assert page.locator("#error").is_hidden(), page.inner_text("#error")
            wait_final(page, seq)
            assert graph_params(url)["fg_h"]["method"] == method
            heights.setdefault(method, shadow(shown(page)))
            # the line comes and goes without resizing the stage or moving the image on it
            # (it was under the stage: a switch to or from the contact line refit the image)
            assert page.evaluate("[document.getElementById('stage').getBoundingClientRect().toJSON(),"
                                 " window.pixgraphView.state.k, window.pixgraphView.state.ox,"
                                 " window.pixgraphView.state.oy]") == view, method
            # what the node said (its confidence, auto's choice) over the image's bottom edge; the
            # contact line says nothing
            logs = page.inner_text("#logs") if page.locator("#logs").is_visible() else ""
            said = [x for x in logs.splitlines() if x.startswith("fg_h: ")]
            if method == "contact_line":
                assert said == [], logs
            else:
                assert len(said) == 1 and said[0].startswith(f"fg_h: {method}: ") and "confidence 0." in said[0], logs
                # the line lies over the stage's bottom edge, under the handles (a press there
                # reaches the handle layer): on the stage, not below it
                stage, box = page.locator("#stage").bounding_box(), page.locator("#logs").bounding_box()
                assert stage["y"] < box["y"] and box["y"] + box["height"] <= stage["y"] + stage["height"], (box, stage)
                assert page.evaluate("(() => { const b = document.getElementById('logs').getBoundingClientRect();"
                                     " return document.elementFromPoint(b.x + 5, b.y + b.height / 2).closest('#handles') !== null; })()")
        assert np.logical_xor(heights["learned"], before).sum() > 100, "the learned height changed nothing"
        assert np.array_equal(heights["contact_line"], before)
        assert not errors, errors
        page.close()


def test_the_cutouts_foot_handle_is_not_hidden_by_the_new_contact_handle(browser, tmp_path):
    """Both start at the cutout's foot: the hollow "new contact" ring was drawn over the
    cutout's green foot square and covered all of it, so a drag of the square (to move the
    cutout) added a contact point instead (the figure sank). Each is reachable now: the
    square moves the foot, the ring (just under it) adds a point."""
    graph = edit_graph(str(tmp_path))
    with running_server(graph) as (url, _):
        page, errors = open_page(browser, url)
        k = page.evaluate("window.pixgraphView.state.k")
        foot = httpx.get(url + "/api/scene", timeout=60).json()["place"]["foot"]
        x, y = centre(page, "#foot-handle")
        assert (x, y) == pytest.approx(screen(page, *foot), abs=1.5)
        for dx in (-3, 0, 3):
            for dy in (-3, 0, 3):
                assert page.evaluate(f"document.elementFromPoint({x + dx}, {y + dy}).id") == "foot-handle", (dx, dy)
        gx, gy = centre(page, "#contact-new")
        assert page.evaluate(f"document.elementFromPoint({gx}, {gy}).id") == "contact-new"
        drag(page, (x, y), (x + 20, y - 10))
        params = graph_params(url)
        assert params["edit"]["contact_points"] == []
        assert params["place"]["foot"] == pytest.approx([foot[0] + 20 / k, foot[1] - 10 / k], abs=1 / k + 0.2)
        # the ring still adds a contact point where it is let go
        e = httpx.get(url + "/api/scene", timeout=60).json()["height_edit"]
        fu, fv = graph_params(url)["place"]["foot"]
        drag(page, centre(page, "#contact-new"), screen(page, fu - 10, fv - 5))
        assert graph_params(url)["edit"]["contact_points"] == pytest.approx(
            list(to_cutout(e, fu - 10, fv - 5)), abs=1.0 / k + 0.2)
        assert not errors, errors
        page.close()


def test_the_new_contact_ring_is_grabbable_when_the_foot_is_on_the_photos_bottom_edge(browser, tmp_path):
    """A cutout standing on the photo's bottom edge (a figure cut off by the frame) in a
    fitted view whose height is the limit: the "new contact" ring, drawn under the foot,
    fell below the stage and only its top few pixels could be grabbed. It now slides round
    the foot to its side: whole on the stage, as far from the foot as under it (clear of
    the foot square), and a drag from its centre adds a contact point."""
    import yaml
    graph = edit_graph(str(tmp_path))
    with open(graph) as f:
        doc = yaml.safe_load(f)
    doc["nodes"]["place"]["params"]["foot"] = [320, 480]           # the photo is 640 x 480
    with open(graph, "w") as f:
        yaml.safe_dump(doc, f, sort_keys=False)
    with running_server(graph) as (url, _):
        page = browser.new_page(viewport={"width": 1280, "height": 560})
        errors = []
        page.on("pageerror", lambda err: errors.append(str(err)))
        page.goto(url + "/")
        page.wait_for_selector("body[data-ready='1']", state="attached", timeout=180000)
        wait_final(page, 0)
        stage = page.locator("#stage").bounding_box()
        k = page.evaluate("window.pixgraphView.state.k")
        assert k < 1                                                # fitted by its height
        fu, fv = httpx.get(url + "/api/scene", timeout=60).json()["place"]["foot"]
        assert fv == 480
        _, bottom = screen(page, fu, 480)
        assert bottom < stage["y"] + stage["height"]                 # the photo's bottom edge is shown
        ring = page.locator("#contact-new").bounding_box()
        assert stage["y"] <= ring["y"] and ring["y"] + ring["height"] <= stage["y"] + stage["height"], (ring, stage)
        assert stage["x"] <= ring["x"] and ring["x"] + ring["width"] <= stage["x"] + stage["width"], (ring, stage)
        keep(page, "height_edit_ring_on_the_bottom_edge.png")
        gx, gy = centre(page, "#contact-new")
        assert page.evaluate(f"document.elementFromPoint({gx}, {gy}).id") == "contact-new"
        x, y = centre(page, "#foot-handle")
        assert np.hypot(gx - x, gy - y) == pytest.approx(2.6 * 7, abs=1.0)     # as far from the foot as ever
        assert page.evaluate(f"document.elementFromPoint({x}, {y}).id") == "foot-handle"
        # grabbed where it is drawn, let go on the figure: one contact point there
        e = httpx.get(url + "/api/scene", timeout=60).json()["height_edit"]
        drag(page, (gx, gy), screen(page, fu - 10, fv - 40))
        assert graph_params(url)["edit"]["contact_points"] == pytest.approx(
            list(to_cutout(e, fu - 10, fv - 40)), abs=1.0 / k + 0.2)
        assert graph_params(url)["place"]["foot"] == [320, 480]      # the cutout did not move
        assert not errors, errors
        page.close()


def test_the_lights_handle_is_grabbable_on_a_flat_lying_object(browser, tmp_path):
    """Lying at thickness ~0 the top's shadow falls on the top itself: the light's tip was
    drawn under the top's square, only its rim to grab. The light's handle now goes aside
    (on the shadow's side, a dotted line on to it) and both handles are whole; its drag
    moves the tip by the pointer's move."""
    import yaml
    graph = edit_graph(str(tmp_path))
    with open(graph) as f:
        doc = yaml.safe_load(f)
    doc["nodes"]["edit"].setdefault("params", {}).update({"lying": True, "thickness": 0.01})
    with open(graph, "w") as f:
        yaml.safe_dump(doc, f, sort_keys=False)
    with running_server(graph) as (url, _):
        page, errors = open_page(browser, url)
        k = page.evaluate("window.pixgraphView.state.k")
        light = httpx.get(url + "/api/scene", timeout=60).json()["light"]
        e = httpx.get(url + "/api/scene", timeout=60).json()["height_edit"]
        tip = screen(page, *light["tip_uv"])
        assert screen(page, *to_canvas(e, *e["top"][:2])) == pytest.approx(tip, abs=2.0)   # the case
        # a press on either handle's centre grabs that handle
        for sel in ("#light-handle", "#tilt-handle"):
            x, y = centre(page, sel)
            hit = page.evaluate(f"document.elementFromPoint({x}, {y}).id")
            assert hit == sel[1:], (sel, hit)
        x, y = centre(page, "#light-handle")
        assert 2.4 * 7 < np.hypot(x - tip[0], y - tip[1]) < 2.8 * 7           # aside, LIGHT_ASIDE
        # its drag moves the tip by the pointer's move (not to the pointer)
        drag(page, (x, y), (x - 60, y + 30))
        new = graph_params(url)["light"]["tip_uv"]
        assert new == pytest.approx([light["tip_uv"][0] - 60 / k, light["tip_uv"][1] + 30 / k], abs=1 / k + 0.2)
        assert not errors, errors
        page.close()
