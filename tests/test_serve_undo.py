"""Undo and redo of the served graph's edits (``ServeState``'s history, ``POST /api/undo``
and ``POST /api/redo``): one step per user action (a drag's many previews carry one
``action``), redo after undo, a new edit dropping the redo steps, the history bounded,
a render a node refuses leaving no step, opening a photo undone, saved files untouched,
and the same guard as every POST (token, Origin, JSON). In-process: the app behind its
guard, driven by Starlette's test client; the page itself is in test_page_undo.py."""
import gc
import itertools
import os
import shutil
import tracemalloc

import pytest
from starlette.testclient import TestClient

from pixgraph_serve import app as serve_app
from pixgraph_serve.state import Limits, ServeState
from serve_helpers import GRAPHS, copy_scene

TOKEN = "secret-token"


def _state(tmp_path, **limits) -> ServeState:
    state = ServeState(copy_scene(str(tmp_path)), limits=Limits(**limits) if limits else None)
    state.set_type("shadow", "pixgraph.HardShadow")      # quick finals
    return state


def _client(state, token=None):
    return TestClient(serve_app.create_app(state, token=token))


def values(c) -> dict:
    return {n["id"]: n["values"] for n in c.get("/api/graph").json()["nodes"]}


def history(c) -> dict:
    return c.get("/api/graph").json()["history"]


def test_undo_restores_a_param_and_redo_puts_it_back(tmp_path):
    state = _state(tmp_path)
    with _client(state) as c:
        assert history(c) == {"undo": 0, "redo": 0, "limit": 100}
        assert values(c)["light"]["azimuth"] == -25
        assert c.post("/api/params", json={"params": {"light.azimuth": 40}}).status_code == 200
        assert c.post("/api/params", json={"params": {"shadow.thickness": 9}}).status_code == 200
        assert history(c) == {"undo": 2, "redo": 0, "limit": 100}
        r = c.post("/api/undo", json={})
        assert r.status_code == 200, r.text
        body = r.json()
        assert body["undo"] is True and body["history"] == {"undo": 1, "redo": 1, "limit": 100}
        # the answer is the restored graph and its handles: the page redraws from it
        got = {n["id"]: n["values"] for n in body["graph"]["nodes"]}
        assert got["shadow"]["thickness"] == 6 and got["light"]["azimuth"] == 40
        assert body["scene"]["light"]["azimuth"] == 40 and body["scene_error"] is None
        assert "thickness: 6" in body["yaml"]
        empty = c.post("/api/undo", content=b"", headers={"Content-Type": "application/json"})
        assert empty.status_code == 200                           # an empty JSON body is {} too
        assert values(c)["light"]["azimuth"] == -25
        r = c.post("/api/redo", json={"scene": False})        # what the page asks: the scene after a preview
        assert r.status_code == 200 and r.json()["redo"] is True and r.json()["scene"] is None
        assert values(c)["light"]["azimuth"] == 40 and values(c)["shadow"]["thickness"] == 6
        assert c.post("/api/redo", json={"scene": "no"}).status_code == 400
        assert c.post("/api/redo", json={}).status_code == 200
        assert values(c)["shadow"]["thickness"] == 9
        assert history(c) == {"undo": 2, "redo": 0, "limit": 100}


def test_nothing_to_undo_or_redo_is_409_and_changes_nothing(tmp_path):
    state = _state(tmp_path)
    with _client(state) as c:
        before = c.get("/api/graph.yaml").text
        for which in ("undo", "redo"):
            r = c.post(f"/api/{which}", json={})
            assert r.status_code == 409, r.text
            assert r.json()["error"].startswith(f"nothing to {which}") and r.json()["field"] == which
        assert c.get("/api/graph.yaml").text == before
        # an edit that changes nothing (the value it has) is no step either
        c.post("/api/params", json={"params": {"light.azimuth": -25}})
        assert history(c)["undo"] == 0


def test_a_drag_of_many_previews_and_its_final_is_one_step(tmp_path):
    state = _state(tmp_path)
    with _client(state) as c:
        c.post("/api/params", json={"params": {"shadow.thickness": 8}})      # a step before the drag
        orig = values(c)["light"]
        tips = [[200 + 10 * i, 420 - 3 * i] for i in range(6)]
        for i, tip in enumerate(tips):
            r = c.post("/api/render", json={"light_tip": tip, "mode": "preview", "work": 0.25, "format": "jpeg",
                                            "client": "page", "seq": i + 1, "action": "page:7"})
            assert r.status_code == 200, r.text
        r = c.post("/api/render", json={"light_tip": tips[-1], "mode": "final", "client": "page", "seq": 10,
                                        "action": "page:7"})
        assert r.status_code == 200, r.text
        moved = values(c)["light"]
        assert moved != orig and c.get("/api/scene").json()["light"]["tip_uv"] == pytest.approx(tips[-1], abs=0.5)
        assert history(c)["undo"] == 2                          # the param, and the whole drag
        body = c.post("/api/undo", json={}).json()
        assert values(c)["light"] == orig and body["scene"]["light"]["azimuth_deg"] == pytest.approx(-25)
        assert values(c)["shadow"]["thickness"] == 8           # the step before the drag stays
        c.post("/api/redo", json={})
        assert values(c)["light"] == moved
        # the same previews without an action: each its own step (what the action groups)
        for tip in tips:
            c.post("/api/params", json={"light_tip": [tip[0] + 1, tip[1]]})
        assert history(c)["undo"] == 2 + len(tips)
        # a new action after an undo starts its own step, even with the old action's id
        c.post("/api/undo", json={})
        c.post("/api/params", json={"params": {"light.radius": 0.4}, "action": "page:7"})
        c.post("/api/params", json={"params": {"light.radius": 0.5}, "action": "page:7"})
        assert history(c)["undo"] == 2 + len(tips)
        c.post("/api/undo", json={})
        assert values(c)["light"]["radius"] == 0.25


def test_a_new_edit_after_undo_drops_the_redo_steps(tmp_path):
    state = _state(tmp_path)
    with _client(state) as c:
        for az in (10, 20, 30):
            c.post("/api/params", json={"params": {"light.azimuth": az}})
        c.post("/api/undo", json={})
        c.post("/api/undo", json={})
        assert history(c) == {"undo": 1, "redo": 2, "limit": 100}
        c.post("/api/params", json={"params": {"light.azimuth": 55}})
        assert history(c) == {"undo": 2, "redo": 0, "limit": 100}
        assert c.post("/api/redo", json={}).status_code == 409
        assert values(c)["light"]["azimuth"] == 55
        c.post("/api/undo", json={})
        assert values(c)["light"]["azimuth"] == 10


def test_the_history_is_bounded_and_holds_no_pixels(tmp_path):
    state = _state(tmp_path, undo_steps=5)
    with _client(state) as c:
        assert c.post("/api/render", json={"mode": "final"}).status_code == 200   # values in the cache
        for az in range(1, 9):
            c.post("/api/params", json={"params": {"light.azimuth": az}})
        assert history(c) == {"undo": 5, "redo": 0, "limit": 5}
        for _ in range(5):
            assert c.post("/api/undo", json={}).status_code == 200
        assert values(c)["light"]["azimuth"] == 3                # the oldest kept: after the 3rd edit
        assert c.post("/api/undo", json={}).status_code == 409
        for _ in range(5):
            assert c.post("/api/redo", json={}).status_code == 200
        assert values(c)["light"]["azimuth"] == 8
    # a step is a reference to an immutable graph (params): 100 steps of a graph whose run
    # holds megabytes of pixels in the cache cost a few hundred kilobytes, not images. Two
    # windows of 100 steps each: steps that held pixels would grow both by hundreds of MiB,
    # while a one-off growth of an interpreter table (a dict resize, ~2 MiB, seen when other
    # test modules ran first) lands in at most one of them
    state = _state(tmp_path / "big", undo_steps=200)
    state.run(["final"])
    gc.collect()
    tracemalloc.start()
    try:
        grown = []
        for window in range(2):
            base = tracemalloc.get_traced_memory()[0]
            for az in range(100):
                state.edit(lambda: state.set_params({"light.azimuth": az - 50 + 0.5 * window}), step=True)
            gc.collect()
            grown.append(tracemalloc.get_traced_memory()[0] - base)
    finally:
        tracemalloc.stop()
    assert state.history()["undo"] == 200
    assert min(grown) < 2 << 20, grown       # a 512x512 RGBA float image alone is 4 MiB


def test_a_refused_render_leaves_no_step(tmp_path):
    state = _state(tmp_path)
    with _client(state) as c:
        c.post("/api/params", json={"params": {"light.azimuth": 12}})
        r = c.post("/api/render", json={"params": {"light.elevation": 500}, "action": "x"})
        assert r.status_code == 400
        r = c.post("/api/run", json={"params": {"bg_h.corner": [1e9, 1e9], "light.azimuth": 70}})
        assert r.status_code >= 400
        assert history(c)["undo"] == 1 and values(c)["light"]["azimuth"] == 12
        bad = c.post("/api/params", json={"params": {"light.azimuth": 1}, "action": ["not", "a", "string"]})
        assert bad.status_code == 400 and bad.json()["field"] == "action"
        assert history(c)["undo"] == 1 and values(c)["light"]["azimuth"] == 12
        c.post("/api/undo", json={})
        assert values(c)["light"]["azimuth"] == -25


def test_a_type_switch_and_its_params_come_back(tmp_path):
    state = _state(tmp_path)
    with _client(state) as c:
        c.post("/api/params", json={"types": {"shadow": "pixgraph.SoftShadow"}})
        c.post("/api/params", json={"params": {"shadow.samples": 12}})
        c.post("/api/params", json={"types": {"shadow": "pixgraph.HardShadow"}})
        assert c.get("/api/scene").json()["shadow"]["type"] == "pixgraph.HardShadow"
        body = c.post("/api/undo", json={}).json()
        assert body["scene"]["shadow"]["type"] == "pixgraph.SoftShadow"
        assert values(c)["shadow"]["samples"] == 12
        c.post("/api/undo", json={})
        assert values(c)["shadow"]["samples"] == 48
        c.post("/api/undo", json={})
        assert c.get("/api/scene").json()["shadow"]["type"] == "pixgraph.HardShadow"
        # switched again: the soft shadow's own samples come back from the stash as before
        c.post("/api/params", json={"types": {"shadow": "pixgraph.SoftShadow"}})
        assert values(c)["shadow"]["samples"] == 48


def test_opening_a_photo_is_one_step_and_saving_is_none(tmp_path):
    state = _state(tmp_path)
    for name in ("own_photo.jpg", "own_cutout.png"):
        shutil.copy(os.path.join(GRAPHS, "assets", name), tmp_path / "assets" / name)
    with _client(state) as c:
        c.post("/api/params", json={"params": {"light.azimuth": 5}})
        before = values(c)
        r = c.post("/api/open", json={"photo": "assets/own_photo.jpg", "cutout": "assets/own_cutout.png"})
        assert r.status_code == 200, r.text
        opened = values(c)
        assert "place" in opened and "place" not in before
        assert history(c)["undo"] == 2
        body = c.post("/api/undo", json={}).json()
        assert values(c) == before and body["scene"]["camera"]["width"] == 512
        c.post("/api/redo", json={})
        assert values(c) == opened
        # a save writes the current graph and is no step; undo leaves the file as saved
        r = c.post("/api/save", json={"path": "saved.yaml"})
        assert r.status_code == 200
        saved = (tmp_path / "saved.yaml").read_bytes()
        assert history(c)["undo"] == 2
        c.post("/api/undo", json={})
        assert values(c) == before
        assert (tmp_path / "saved.yaml").read_bytes() == saved
        # a posted graph is a step too
        c.post("/api/graph", content=(tmp_path / "saved.yaml").read_text(),
               headers={"Content-Type": "application/yaml"})
        assert values(c) == opened and history(c)["undo"] == 2
        c.post("/api/undo", json={})
        assert values(c) == before


def test_undo_is_guarded_like_every_post(tmp_path):
    state = _state(tmp_path)
    with _client(state, token=TOKEN) as c:
        ok = {"X-Pixgraph-Token": TOKEN}
        assert c.post("/api/params", json={"params": {"light.azimuth": 33}}, headers=ok).status_code == 200
        for which in ("undo", "redo"):
            r = c.post(f"/api/{which}", json={})                                  # no token
            assert r.status_code == 403 and "token" in r.json()["error"]
            r = c.post(f"/api/{which}", json={}, headers={**ok, "Origin": "http://evil.example"})
            assert r.status_code == 403 and "origin" in r.json()["error"]
            r = c.post(f"/api/{which}", json={}, headers={**ok, "Sec-Fetch-Site": "cross-site"})
            assert r.status_code == 403
            r = c.post(f"/api/{which}", content=b"{}", headers={**ok, "Content-Type": "text/plain"})
            assert r.status_code == 415
            r = c.post(f"/api/{which}", headers=ok)                                # no content type at all
            assert r.status_code == 415
            r = c.post(f"/api/{which}", json=[1], headers=ok)
            assert r.status_code == 400
            assert c.get(f"/api/{which}", headers=ok).status_code == 405
        assert state.history()["undo"] == 1 and state.graph.nodes["light"].params["azimuth"] == 33
        r = c.post("/api/undo", json={}, headers={**ok, "Origin": "http://testserver"})   # the page's own
        assert r.status_code == 200
        assert state.graph.nodes["light"].params["azimuth"] == -25


def test_an_undo_from_the_page_supersedes_its_older_renders(tmp_path):
    """The page sends its client id and a new seq with an undo: a render of that page still
    running (a final of the state being left) is cancelled and an older one never starts,
    as a newer render would do; with nothing to undo its renders are left alone."""
    state = _state(tmp_path)
    with _client(state) as c:
        final = {"mode": "final", "scale": 4, "client": "page"}
        assert c.post("/api/undo", json={"client": "page", "seq": 3}).status_code == 409
        assert c.post("/api/render", json={**final, "seq": 3}).status_code == 200      # not claimed by the 409
        c.post("/api/params", json={"params": {"light.azimuth": 15}})
        assert c.post("/api/undo", json={"client": "page", "seq": 5}).status_code == 200
        stale = c.post("/api/render", json={**final, "seq": 4})
        assert stale.status_code == 409 and stale.json()["error"].startswith("stale")
        assert c.post("/api/render", json={**final, "seq": 6}).status_code == 200
        bad = c.post("/api/redo", json={"client": "page", "seq": "7"})
        assert bad.status_code == 400 and bad.json()["field"] == "seq"
        assert values(c)["light"]["azimuth"] == -25


def test_two_clients_interleaved_drags_make_no_extra_steps(tmp_path):
    """Two pages (two tabs) drag at once: their previews and finals interleave. Each drag
    stays whole (no undo step boundary inside it): actions that overlap in time are one
    step, so undo goes back to the graph before both and redo forward to after both; an
    action of one client after the other's ended is a step of its own, and the same
    action id from two clients names two actions (the grouping is by client and action)."""
    state = _state(tmp_path)
    with _client(state) as c:
        c.post("/api/params", json={"params": {"shadow.thickness": 8}})      # a step before
        orig = values(c)

        seqs = itertools.count(1)      # each tab's renders in order (one counter serves both)

        def send(client, edits, mode):
            r = c.post("/api/render", json={**edits, "mode": mode, "work": 0.25, "format": "jpeg",
                                            "client": client, "seq": next(seqs), "action": f"{client}:1"})
            assert r.status_code == 200, r.text

        def a(tip, mode="preview"):
            send("tabA", {"light_tip": tip}, mode)

        def b(thickness, mode="preview"):
            send("tabB", {"params": {"shadow.thickness": thickness}}, mode)

        a([210, 415])              # A's drag starts
        b(9)                       # B's starts while A's goes on
        a([230, 410])
        b(10)
        a([250, 405])
        b(11, "final")             # B's ends
        a([270, 400], "final")     # A's ends
        both = values(c)
        assert both["shadow"]["thickness"] == 11 and both["light"] != orig["light"]
        assert history(c)["undo"] == 2, history(c)         # the param before, and the two drags as one
        c.post("/api/undo", json={})
        assert values(c) == orig                            # before both: no half of A's drag left
        c.post("/api/redo", json={})
        assert values(c) == both                            # after both
        # one after the other: each its own step, the same id from another client too
        for client, az in (("tabA", 40), ("tabB", 50)):
            r = c.post("/api/params", json={"params": {"light.azimuth": az}, "client": client, "action": "same"})
            assert r.status_code == 200, r.text
        assert history(c)["undo"] == 4
        c.post("/api/undo", json={})
        assert values(c)["light"]["azimuth"] == 40
        bad = c.post("/api/params", json={"params": {"light.azimuth": 1}, "client": 7, "action": "x"})
        assert bad.status_code == 400 and bad.json()["field"] == "client"


def test_many_action_ids_joined_into_one_step_keep_the_history_bounded(tmp_path):
    """An attacker (or a buggy page) keeps one drag going while another client sends a new
    action id with every edit: each of those joins the drag's step, and the ids it keeps
    to tell the actions apart must stay bounded (``history.MAX_STEP_ACTIONS`` per step),
    while the drag that goes on stays one step that undo takes back whole."""
    from pixgraph_serve import history as H
    MAX_STEP_ACTIONS = getattr(H, "MAX_STEP_ACTIONS", 32)
    state = _state(tmp_path)
    orig = dict(state.graph.nodes["light"].params)

    def edit(client, action, params):
        state.edit(lambda: state.set_params(params), step=True, action=action, client=client)

    n = 4 * MAX_STEP_ACTIONS + 10
    for i in range(n):
        edit("tabA", "drag", {"light.azimuth": float(i % 300)})               # the drag goes on
        edit("tabB", f"x{i}" * 50, {"shadow.thickness": 1.0 + (i % 20)})    # a new action each time
    edit("tabA", "drag", {"light.azimuth": 301.0})                            # and its last edit
    kept = sum(len(keys) for keys in state.steps.actions)
    assert state.history()["undo"] == 1
    assert kept <= MAX_STEP_ACTIONS, kept                  # not n + 1
    state.undo()
    assert dict(state.graph.nodes["light"].params) == orig


def test_a_bad_client_is_refused_naming_client_before_it_is_kept(tmp_path):
    """``client`` groups a page's edits into its actions (and supersedes its renders): a
    client that is not a string of at most 200 characters is a 400 naming ``client`` in
    /api/render, /api/undo and /api/params alike, and is never kept in the server's
    per-client table (one huge id per request would grow it)."""
    state = _state(tmp_path)
    with _client(state) as c:
        renders = c.app.app.state.renders
        for bad in (7, ["a"], "x" * 201):
            for path, body in (("/api/render", {"mode": "preview", "work": 0.25, "format": "jpeg"}),
                               ("/api/undo", {}), ("/api/params", {"params": {"shadow.thickness": 3}})):
                r = c.post(path, json={**body, "client": bad, "seq": 1})
                assert r.status_code == 400 and r.json()["field"] == "client", (path, bad, r.text)
        assert not any(len(k) > 200 for k in renders.latest), [len(k) for k in renders.latest]
        r = c.post("/api/render", json={"mode": "preview", "work": 0.25, "format": "jpeg", "client": "ok", "seq": "1"})
        assert r.status_code == 400 and r.json()["field"] == "seq"
