"""The server side of opening your own files in the page (pixgraph_serve/files.py),
in process through Starlette's test client: the own-photo template filled in with
uploaded files, the path rules on them, save with the files beside the graph, and
the page's module files served (and nothing else)."""
import io
import os
import shutil

import numpy as np
import pytest
import yaml
from PIL import Image
from starlette.testclient import TestClient

from pixgraph.session import Session
from pixgraph_serve import files
from pixgraph_serve.app import create_app
from pixgraph_serve.state import ServeError, ServeState
from serve_helpers import GRAPHS


@pytest.fixture
def served(tmp_path):
    os.makedirs(tmp_path / "served" / "assets")
    for name in ("own_photo.jpg", "own_cutout.png"):
        shutil.copy(os.path.join(GRAPHS, "assets", name), tmp_path / "served" / "assets" / name)
    shutil.copy(os.path.join(GRAPHS, "own_photo.yaml"), tmp_path / "served" / "own_photo.yaml")
    state = ServeState(str(tmp_path / "served" / "own_photo.yaml"), upload_dir=str(tmp_path / "uploads"))
    os.makedirs(state.upload_dir, exist_ok=True)
    with TestClient(create_app(state)) as client:
        yield state, client


def mine(tmp_path, w=320, h=240):
    """A photo, an RGB cutout and its mask (small, made here)."""
    d = tmp_path / "mine"
    d.mkdir(exist_ok=True)
    photo = np.zeros((h, w, 3), np.uint8)
    photo[: h // 2] = (200, 190, 180)
    photo[h // 2:] = (120, 90, 60)
    Image.fromarray(photo).save(d / "my photo.jpg")
    cut = np.full((60, 30, 3), (200, 60, 40), np.uint8)
    Image.fromarray(cut).save(d / "fig.png")
    mask = np.zeros((60, 30), np.uint8)
    mask[5:58, 8:22] = 255
    Image.fromarray(mask).save(d / "fig_mask.png")
    return {"photo": d / "my photo.jpg", "cutout": d / "fig.png", "mask": d / "fig_mask.png"}


def upload(client, path, name=None):
    r = client.put(f"/api/uploads/{name or os.path.basename(path).replace(' ', '_')}", content=open(path, "rb").read())
    assert r.status_code == 200, r.text
    return r.json()["path"]


def test_template_numbers_and_files():
    text = files.template_text("own_photo_mask")
    out = yaml.safe_load(files.fill(text, {"photo": "/p.jpg", "cutout": "/c.png", "mask": "/m.png"},
                                    {"W": 1000, "H": 800, "w": 100, "h": 200}))
    n = out["nodes"]
    assert n["photo"]["params"]["path"] == "/p.jpg" and n["mask"]["params"]["path"] == "/m.png"
    assert n["place"]["params"]["foot"] == [500.0, 680.0]
    assert n["place"]["params"]["scale"] == pytest.approx(800 * 0.45 / 200)
    assert n["cam"]["params"]["horizon"] == 240.0
    assert n["bg_h"]["params"]["junction_points"] == [0, 440.0, 1000.0, 440.0]
    with pytest.raises(ServeError, match="needs a mask file"):
        files.fill(text, {"photo": "/p.jpg", "cutout": "/c.png"}, {"W": 1, "H": 1, "w": 1, "h": 1})
    with pytest.raises(ServeError, match="not a number expression"):
        files.fill("nodes: {a: {params: {x: '=__import__(1)'}}}", {}, {"W": 1})


def test_open_photo_cutout_and_mask(served, tmp_path):
    state, client = served
    f = mine(tmp_path)
    paths = {role: upload(client, p) for role, p in f.items()}
    r = client.post("/api/open", json=paths)
    assert r.status_code == 200, r.text
    assert r.json()["template"] == "own_photo_mask" and r.json()["notes"] == []
    scene = client.get("/api/scene").json()
    # the camera takes the photo's size; the cutout stands where the template put it
    assert (scene["camera"]["width"], scene["camera"]["height"]) == (320, 240)
    assert scene["place"]["foot"] == [160.0, 204.0]
    u0, v0, u1, v1 = scene["place"]["bbox"]
    # the mask's 53 rows at scale 240 * 0.45 / 60 = 1.8: about 95 rows above the foot
    assert v1 == pytest.approx(204, abs=1.5) and v1 - v0 == pytest.approx(53 * 1.8, abs=3)
    final = client.post("/api/render", json={"mode": "final"})
    assert final.status_code == 200 and final.headers["content-type"] == "image/png"
    # the page asks for images at the screen's size: box-filtered by `scale`
    small = client.post("/api/render", json={"mode": "final", "scale": 3})
    assert Image.open(io.BytesIO(small.content)).size == (320 // 3, 240 // 3)
    # a preview at working resolution 1/4: the whole graph runs at 80x60
    quarter = client.post("/api/render", json={"mode": "preview", "scale": 1, "work": 0.25})
    assert quarter.status_code == 200, quarter.text
    assert Image.open(io.BytesIO(quarter.content)).size == (80, 60)
    for bad in (0, 1.5, True, "0.5"):
        r = client.post("/api/render", json={"mode": "preview", "work": bad})
        assert r.status_code == 400 and r.json()["field"] == "work", bad
    for bad in (0, 17, 2.5, True, "2"):
        r = client.post("/api/render", json={"mode": "final", "scale": bad})
        assert r.status_code == 400 and r.json()["field"] == "scale", bad
    # a horizon dragged below the foot: the check's warning, for the page to show
    client.post("/api/params", json={"params": {"cam.horizon": 230}}).raise_for_status()
    found = client.get("/api/notes").json()["notes"]
    assert len(found) == 1 and "foot (row 204) is at or above the camera's horizon (row 230)" in found[0]
    # an RGBA cutout alone takes the template without a mask
    rgba = tmp_path / "mine" / "fig_rgba.png"
    Image.open(f["cutout"]).convert("RGBA").save(rgba)
    r = client.post("/api/open", json={"photo": paths["photo"], "cutout": upload(client, rgba)})
    assert r.json()["template"] == "own_photo" and "mask" not in client.get("/api/scene").json()["roles"].values()


def test_open_refuses_missing_and_outside_files(served, tmp_path):
    state, client = served
    f = mine(tmp_path)
    photo = upload(client, f["photo"])
    r = client.post("/api/open", json={"photo": photo})
    assert r.status_code == 400 and r.json()["field"] == "cutout"
    r = client.post("/api/open", json={"photo": photo, "cutout": str(f["cutout"])})   # not uploaded: outside
    assert r.status_code == 403 and r.json()["field"] == "cutout"
    r = client.post("/api/open", json={"photo": photo, "cutout": "../mine/fig.png"})
    assert r.status_code == 403
    # an RGB cutout without its mask is refused by the graph's own check, naming the node
    r = client.post("/api/open", json={"photo": photo, "cutout": upload(client, f["cutout"])})
    assert r.status_code == 400 and "no alpha channel" in r.json()["error"]
    assert r.json()["node"] in ("fg_h", "place")   # the first node that uses the cutout's alpha
    # and the graph served before is kept
    assert client.get("/api/scene").json()["camera"]["width"] == 640


def test_save_keeps_the_files_beside_the_graph(served, tmp_path):
    state, client = served
    f = mine(tmp_path)
    client.post("/api/open", json={role: upload(client, p) for role, p in f.items()}).raise_for_status()
    # a file of the same name and other bytes is already there: kept, the copy is renamed
    os.makedirs(tmp_path / "served" / "scenes")
    Image.new("RGB", (4, 4)).save(tmp_path / "served" / "scenes" / "fig.png")
    r = client.post("/api/save_files", json={"path": "scenes/mine.yaml"})
    assert r.status_code == 200, r.text
    assert sorted(r.json()["copied"]) == ["fig_2.png", "fig_mask.png", "my_photo.jpg"]
    saved = tmp_path / "served" / "scenes" / "mine.yaml"
    doc = yaml.safe_load(saved.read_text())
    assert doc["nodes"]["photo"]["params"]["path"] == "my_photo.jpg"
    assert doc["nodes"]["cutout"]["params"]["path"] == "fig_2.png"
    # the saved folder runs without the server
    out = Session(disk_cache=None).run(str(saved), outputs=["place.alpha"])
    assert (np.asarray(out["place.alpha"]) > 0.5).sum() > 1000
    # the served graph now reads the copies, not the upload folder
    nodes = {n["id"]: n for n in client.get("/api/graph").json()["nodes"]}
    assert nodes["photo"]["params"]["path"] == os.path.join("scenes", "my_photo.jpg")
    # saving again copies nothing: the graph reads the copies
    assert client.post("/api/save_files", json={"path": "scenes/mine.yaml"}).json()["copied"] == []
    assert len(os.listdir(tmp_path / "served" / "scenes")) == 5
    r = client.post("/api/save_files", json={"path": "../elsewhere.yaml"})
    assert r.status_code == 403


def test_page_modules_are_served_and_nothing_else(served):
    state, client = served
    page = client.get("/").text
    assert '<script type="module" src="/static/main.js">' in page
    for name in ("main.js", "app.js", "render.js", "view.js", "handles.js", "horizon.js", "panel.js", "files.js",
                 "style.css"):
        r = client.get(f"/static/{name}")
        assert r.status_code == 200 and r.headers["content-type"].startswith(
            "text/javascript" if name.endswith(".js") else "text/css"), name
        if name.endswith(".js"):
            assert len(r.text.splitlines()) <= 600
            assert "http://" not in r.text.replace("http://www.w3.org/2000/svg", "")
    for bad in ("index.html", "state.py", "..%2Fstate.py", "nope.js", "App.js"):
        assert client.get(f"/static/{bad}").status_code == 404, bad


def test_the_proposed_save_name_is_never_the_served_graphs(served, tmp_path):
    # the example's own photo (assets/own_photo.jpg) opened beside the served own_photo.yaml:
    # the proposal was "own_photo.yaml", i.e. "save" wrote over the graph the server was
    # started with (found by the review); the page now shows the server's proposal, so a
    # reload proposes the same name ("(1) beach.jpg", uploaded by the page as "1__beach.jpg":
    # the page proposed "_1__beach.yaml", after a reload the server "1__beach.yaml")
    state, client = served
    f = mine(tmp_path)
    cut = {"cutout": upload(client, f["cutout"]), "mask": upload(client, f["mask"])}
    r = client.post("/api/open", json={"photo": "assets/own_photo.jpg", **cut})
    assert r.status_code == 200, r.text
    assert r.json()["save_as"] == "own_photo_1.yaml"
    assert client.get("/api/graph").json()["save_as"] == "own_photo_1.yaml"
    r = client.post("/api/open", json={"photo": upload(client, f["photo"], "1__beach.jpg"), **cut})
    assert r.json()["save_as"] == "1__beach.yaml" == client.get("/api/graph").json()["save_as"]
    assert files.save_name_for("/x/OWN_PHOTO.png", "/srv/own_photo.yaml") == "OWN_PHOTO_1.yaml"
    assert files.save_name_for("/x/été.jpg", "/srv/g.yaml") == "_t_.yaml"
