"""``pixgraph serve``'s HTTP API, with a real client (httpx) against a real server
process on 127.0.0.1, serving a copy of graphs/wall_corner_shadow.yaml (started
``--no-token``; the token, Host and Origin checks are in test_serve_security.py)."""
import io
import os

import httpx
import numpy as np
import pytest
from PIL import Image

from pixgraph import fileio
from pixgraph.registry import Registry
from pixgraph_nodes.ops.imageio import linear_to_srgb, read_image
from serve_helpers import copy_scene, running_server

MAX_PIXELS = 300_000      # 512^2 = 262,144 fits; 600^2 does not
MAX_BODY = 2_000_000
YAML = {"Content-Type": "application/yaml"}
JSON = {"Content-Type": "application/json"}


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    top = tmp_path_factory.mktemp("serve")
    graph = copy_scene(str(top / "scene"))
    os.makedirs(top / "extra")
    with running_server(graph, "--max-pixels", str(MAX_PIXELS), "--max-body", str(MAX_BODY),
                        "--allow-path", str(top / "extra")) as (url, proc):
        yield {"url": url, "graph": graph, "top": top, "text": open(graph).read(), "proc": proc}


@pytest.fixture
def api(server):
    """A client on the server, whose graph is reset to the file's text first."""
    with httpx.Client(base_url=server["url"], timeout=120) as c:
        r = c.post("/api/graph", content=server["text"], headers=YAML)
        assert r.status_code == 200, r.text
        yield c


def _error(r, status):
    assert r.status_code == status, r.text
    assert r.headers["content-type"].startswith("application/json")
    body = r.json()
    assert body["error"] and "Traceback" not in r.text
    return body


def test_graph_lists_nodes_params_and_types(api):
    info = api.get("/api/graph").json()
    ids = [n["id"] for n in info["nodes"]]
    assert ids == ["cutout", "photo", "cam", "fg_h", "bg_h", "light", "shadow", "comp"]
    light = next(n for n in info["nodes"] if n["id"] == "light")
    assert light["params"]["azimuth"] == -25 and light["values"]["target_mode"] == "mask_foot"
    assert light["inputs"] == {"camera": "cam.camera", "mask": "cutout.alpha"}
    spec = info["types"]["pixgraph.Light"]
    elevation = next(p for p in spec["params"] if p["name"] == "elevation")
    assert (elevation["min"], elevation["max"], elevation["unit"]) == (-90.0, 90.0, "deg")
    assert "pixgraph.SoftShadowSSN" in info["types"]          # the method toggle's choices
    assert info["outputs"] == {"final": "comp.image"}
    all_types = {t["type"] for t in api.get("/api/nodes").json()["types"]}
    assert {"pixgraph.Light", "pixgraph.Composite"} <= all_types


def test_run_then_param_change_reruns_only_downstream(api):
    r = api.post("/api/run", json={"outputs": ["final"]}).json()
    assert r["outputs"]["final"]["shape"] == [512, 512, 3]
    r = api.post("/api/run", json={"params": {"light.azimuth": -10}}).json()
    assert r["ran"] == ["light", "shadow", "comp"]
    assert set(r["cached"]) == {"cutout", "photo", "cam", "fg_h", "bg_h"}
    r = api.post("/api/run", json={"params": {"comp.opacity": 0.5}}).json()
    assert r["ran"] == ["comp"]
    r = api.post("/api/run", json={"params": {"light.azimuth": -25, "comp.opacity": 0.85}}).json()
    # back to the first state: all of it from the cache
    assert r["ran"] == []


def test_png_is_the_srgb_of_the_exr(api):
    run = api.post("/api/run", json={}).json()
    png = api.get(run["outputs"]["final"]["png"])
    exr = api.get(run["outputs"]["final"]["exr"])
    assert png.headers["content-type"] == "image/png" and exr.headers["content-type"] == "image/x-exr"
    shown = np.asarray(Image.open(io.BytesIO(png.content)), dtype=np.float32) / 255.0
    path = os.path.join(os.environ.get("TMPDIR", "/tmp"), f"pixgraph-serve-test-{os.getpid()}.exr")
    with open(path, "wb") as f:
        f.write(exr.content)
    try:
        linear, _ = read_image(path)
    finally:
        os.unlink(path)
    assert shown.shape == linear.shape == (512, 512, 3)
    np.testing.assert_allclose(shown, linear_to_srgb(np.clip(linear, 0, 1)), atol=0.51 / 255)
    # any node output by "node.output", e.g. the shadow's darkness as a grey PNG
    dark = np.asarray(Image.open(io.BytesIO(api.get("/api/outputs/shadow.darkness.png").content)))
    assert dark.shape == (512, 512) and dark.max() > 200 and dark.min() == 0


def test_preview_is_a_cheap_soft_shadow_at_half_resolution(api):
    r = api.post("/api/run", json={"mode": "preview"}).json()
    assert "shadow" in r["ran"] or "shadow" in r["cached"]
    prev = np.asarray(Image.open(io.BytesIO(api.get("/api/outputs/shadow.darkness.png?mode=preview").content)))
    assert ((prev > 10) & (prev < 245)).sum() > 200          # PreviewShadow: a penumbra, at half size
    soft = np.asarray(Image.open(io.BytesIO(api.get("/api/outputs/shadow.darkness.png").content)))
    assert ((soft > 10) & (soft < 245)).sum() > 1000          # the final one has a penumbra
    png = api.post("/api/render", json={"mode": "preview"})
    assert Image.open(io.BytesIO(png.content)).size == (256, 256)
    assert Image.open(io.BytesIO(api.post("/api/render", json={"mode": "preview", "scale": 4}).content)).size \
        == (128, 128)
    assert png.headers["x-pixgraph-mode"] == "preview"


def test_method_toggle_switches_the_shadow_node_type(api):
    r = api.post("/api/params", json={"types": {"shadow": "pixgraph.SoftShadowSSN"}})
    assert r.status_code == 200
    assert "type: pixgraph.SoftShadowSSN" in r.json()["yaml"]
    r = api.post("/api/run", json={}).json()
    assert r["ran"] == ["shadow", "comp"]
    r = api.post("/api/params", json={"types": {"shadow": "pixgraph.SoftShadow"}}).json()
    assert "samples: 48" in r["yaml"]                         # its params come back with it


def test_a_type_switch_carries_a_param_only_in_the_same_unit(tmp_path):
    """SoftShadow's thickness is in image px, HardShadow's too, SoftShadowSSN's in its
    window's px: switching carries it to HardShadow, not to SoftShadowSSN (whose default
    applies), and switching back brings the node's own value back."""
    from pixgraph_serve.state import ServeState

    state = ServeState(copy_scene(str(tmp_path)))
    state.set_params({"shadow.thickness": 7})

    def switch(type_id):
        node = state.set_type("shadow", type_id).nodes["shadow"]
        assert node.type == type_id
        return dict(node.params)
    assert switch("pixgraph.HardShadow")["thickness"] == 7
    switch("pixgraph.SoftShadow")
    assert "thickness" not in switch("pixgraph.SoftShadowSSN")
    assert switch("pixgraph.SoftShadow")["thickness"] == 7


def test_light_tip_drag_moves_the_light(api):
    scene = api.get("/api/scene").json()
    assert scene["roles"] == {"camera": "cam", "light": "light", "background": "bg_h", "shadow": "shadow"}
    top = scene["light"]["top_uvh"]
    r = api.post("/api/params", json={"light_tip": [150, 420]})
    assert r.status_code == 200
    scene = api.get("/api/scene").json()
    assert scene["light"]["placement"] == "shadow_tip"
    assert scene["light"]["tip_uv"] == pytest.approx([150, 420], abs=0.5)   # the tip follows the pointer
    assert scene["light"]["top_uvh"] == top
    # the elevation slider slides the tip along its ground direction, to that elevation
    api.post("/api/params", json={"light_elevation": 20}).raise_for_status()
    assert api.get("/api/scene").json()["light"]["elevation_deg"] == pytest.approx(20, abs=0.01)


def test_save_writes_canonical_yaml(api, server):
    api.post("/api/params", json={"params": {"light.azimuth": 12.5}}).raise_for_status()
    r = api.post("/api/save", json={"path": "edited.yaml"}).json()
    path = os.path.join(os.path.dirname(server["graph"]), "edited.yaml")
    assert r["path"] == path
    reg = Registry.discover()
    g = fileio.load(path, reg)
    assert g.nodes["light"].params["azimuth"] == 12.5
    assert open(path).read() == fileio.dumps(g) == r["yaml"]
    assert g.nodes["cutout"].params["path"] == "assets/figure.png"   # still relative to the graph


def test_errors_unknown_node_and_bad_values(api):
    e = _error(api.post("/api/params", json={"params": {"nope.sigma": 1}}), 400)
    assert e["node"] == "nope"
    e = _error(api.post("/api/params", json={"params": {"light.elevation": 500}}), 400)
    assert e["node"] == "light" and e["field"] == "params.elevation" and "maximum 90" in e["error"]
    e = _error(api.post("/api/params", json={"params": {"light.kind": "laser"}}), 400)
    assert "laser" in e["error"]
    _error(api.post("/api/params", json={"types": {"shadow": "pixgraph.Nope"}}), 400)
    _error(api.post("/api/params", json={"light_tip": [1, "x"]}), 400)
    _error(api.post("/api/run", json={"outputs": ["nothing"]}), 400)
    _error(api.post("/api/run", json={"mode": "fast"}), 400)
    _error(api.get("/api/outputs/light.light.png"), 400)       # not an image
    _error(api.post("/api/params", content=b"{not json", headers=JSON), 400)
    _error(api.post("/api/params", content=b"[1, 2]", headers=JSON), 400)
    _error(api.post("/api/params", content=b"[" * 100_000, headers=JSON), 400)      # not a RecursionError 500
    _error(api.post("/api/params", json={"params": {"light.tip_uv": [[[[[[[[0]]]]]]]] * 1}}), 400)
    deep = {"params": {"light.tip_uv": 0}}
    for _ in range(40):
        deep = {"params": {"light.tip_uv": [deep]}}
    _error(api.post("/api/params", json=deep), 400)
    _error(api.post("/api/graph", content=b"[" * 100_000, headers=YAML), 400)
    _error(api.post("/api/graph", content=b"pixgraph: 1\nnodes: {a: {type: x.Y}}\n", headers=YAML), 400)
    _error(api.post("/api/graph", content=b"!!python/object/apply:os.system ['touch /tmp/x']\n", headers=YAML), 400)
    # a body without its JSON content type (what a page can send cross-site unasked) is refused
    _error(api.post("/api/params", content=b'{"params": {"light.azimuth": 3}}'), 415)
    _error(api.post("/api/params", content=b'{"params": {"light.azimuth": 3}}',
                    headers={"Content-Type": "text/plain"}), 415)
    _error(api.post("/api/graph", content=server_text(api).encode(), headers={"Content-Type": "text/plain"}), 415)
    _error(api.get("/api/no-such-thing"), 404)
    _error(api.delete("/api/graph"), 405)
    # the graph is unchanged by the rejected edits
    assert api.get("/api/graph").json()["nodes"][5]["params"]["elevation"] == 32


def test_paths_outside_the_roots_are_refused(api, server):
    top = server["top"]
    (top / "outside.png").write_bytes(open(os.path.join(os.path.dirname(server["graph"]), "assets",
                                                        "figure.png"), "rb").read())
    link = os.path.join(os.path.dirname(server["graph"]), "assets", "link.png")
    if not os.path.lexists(link):
        os.symlink(top / "outside.png", link)
    for path in ("/etc/hostname", "../outside.png", str(top / "outside.png"), "assets/link.png",
                 "/etc/no-such-file.png", "../../no-such-file.png"):   # refused alike: no probing outside
        e = _error(api.post("/api/params", json={"params": {"cutout.path": path}}), 403)
        assert e["node"] == "cutout" and e["field"] == "params.path", path
    for path in ("/etc/hostname", "/etc/no-such-file.png"):
        e = _error(api.post("/api/graph", content=server["text"].replace("assets/figure.png", path), headers=YAML), 403)
        assert e["node"] == "cutout"
    assert "not found" in _error(api.post("/api/params", json={"params": {"cutout.path": "assets/nope.png"}}),
                                 400)["error"]
    _error(api.post("/api/save", json={"path": "../escaped.yaml"}), 403)
    assert not (top / "escaped.yaml").exists()
    _error(api.post("/api/save", json={"path": "edited.txt"}), 400)
    # an explicitly allowed root is readable
    (top / "extra" / "figure.png").write_bytes((top / "outside.png").read_bytes())
    assert api.post("/api/params", json={"params": {"cutout.path": str(top / "extra" / "figure.png")}}).status_code == 200


def _png(w, h):
    buf = io.BytesIO()
    Image.new("RGB", (w, h), (200, 100, 50)).save(buf, format="PNG")
    return buf.getvalue()


def test_image_and_request_size_limits(api):
    png = {"Content-Type": "image/png"}
    r = api.put("/api/uploads/small.png", content=_png(64, 48), headers=png)
    assert r.status_code == 200 and r.json()["pixels"] == 64 * 48
    # a file the browser knows no type for (an .exr) comes without one: fine for a PUT
    assert api.put("/api/uploads/untyped.png", content=_png(8, 8)).status_code == 200
    e = _error(api.put("/api/uploads/big.png", content=_png(600, 600), headers=png), 413)
    assert "360000 pixels" in e["error"] and "--max-pixels" in e["error"]   # names the option
    _error(api.put("/api/uploads/../x.png", content=_png(8, 8), headers=png), 404)
    _error(api.put("/api/uploads/evil.sh", content=b"echo", headers=png), 400)
    _error(api.put("/api/uploads/junk.png", content=b"not a png", headers=png), 400)
    e = _error(api.put("/api/uploads/huge.png", content=b"\0" * (MAX_BODY + 1), headers=png), 413)
    assert "--max-body" in e["error"]
    e = _error(api.post("/api/params", json={"params": {"cam.width": 2048}}), 413)
    assert e["node"] == "cam" and "--max-pixels" in e["error"]


def test_default_limits_take_a_50_megapixel_photo(tmp_path):
    """Issue 22: the server's defaults accept the photos people bring (a real 50 MP
    JPEG, 8660 x 5774, uploaded through the upload check), and refuse one over them
    with a message naming the option that raises the limit."""
    from pixgraph_serve.errors import ServeError
    from pixgraph_serve.state import Limits, ServeState

    graph = copy_scene(str(tmp_path / "scene"))
    os.makedirs(tmp_path / "up")
    state = ServeState(graph, upload_dir=str(tmp_path / "up"))
    buf = io.BytesIO()
    Image.new("RGB", (8660, 5774), (120, 100, 90)).save(buf, "JPEG", quality=90)
    raw = buf.getvalue()
    assert len(raw) <= Limits().max_body_bytes
    path, n = state.store_upload("photo50.jpg", raw)
    assert n == 8660 * 5774 and os.path.isfile(path)
    buf = io.BytesIO()
    Image.new("L", (9000, 8000)).save(buf, "PNG")     # 72 MP: over 8192^2
    with pytest.raises(ServeError) as e:
        state.store_upload("photo72.png", buf.getvalue())
    assert e.value.status == 413 and "--max-pixels" in str(e.value)


def test_stale_renders_are_dropped(api):
    assert api.post("/api/render", json={"client": "t", "seq": 5, "mode": "preview"}).status_code == 200
    _error(api.post("/api/render", json={"client": "t", "seq": 3, "mode": "preview"}), 409)
    _error(api.post("/api/render", json={"client": "t", "seq": 5, "mode": "preview"}), 409)
    # (a running render cancelled by a newer one: test_serve_runs.py, with a render it controls)


def test_outputs_are_fetched_by_run_id_whatever_others_edit(api, server):
    a = api.post("/api/run", json={"params": {"light.azimuth": -10}}).json()
    with httpx.Client(base_url=server["url"], timeout=120) as other:     # another client edits and runs
        b = other.post("/api/run", json={"params": {"light.azimuth": 40}}).json()
    assert a["run"] != b["run"]
    png_a, png_b = (_decoded(api.get(r["outputs"]["final"]["png"]).content) for r in (a, b))
    assert np.abs(png_a - png_b).max() > 50                     # the shadow moved between the two
    again = api.post("/api/run", json={"params": {"light.azimuth": -10}}).json()
    np.testing.assert_array_equal(_decoded(api.get(again["outputs"]["final"]["png"]).content), png_a)
    # without a run id: the current graph (the page's download link)
    np.testing.assert_array_equal(_decoded(api.get("/api/outputs/final.png").content), png_a)
    _error(api.get("/api/outputs/final.png?run=nope"), 404)


def _decoded(data: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(data)), dtype=np.int16)


def server_text(api) -> str:
    return api.get("/api/graph.yaml").text


def test_nodes_json_is_what_the_page_is_built_from(capsys):
    import json

    from pixgraph.cli import main

    assert main(["nodes", "pixgraph.Light", "--json"]) == 0
    light = json.loads(capsys.readouterr().out)
    kind = next(p for p in light["params"] if p["name"] == "kind")
    assert kind["choices"] == ["point", "disk", "directional"] and kind["default"] == "disk"
    assert [p["name"] for p in light["inputs"]] == ["camera", "mask"] and light["inputs"][1]["optional"]
    assert main(["nodes", "--json"]) == 0
    assert "pixgraph.SoftShadowSSN" in {t["type"] for t in json.loads(capsys.readouterr().out)}


BAD_EDITS = [
    {"params": {"light.azimuth": 10 ** 400}}, {"params": {"light.azimuth": "north"}},
    {"params": {"light.tip_uv": [1]}}, {"params": {"light": 5}}, {"params": {"": 1}},
    {"params": {"light.": 1}}, {"params": {"light.nope": 1}}, {"params": "light.azimuth=3"},
    {"params": {"cam.width": 10 ** 30}}, {"params": {"cam.width": 0.5}}, {"params": {"fg_h.method": None}},
    {"types": "x"}, {"types": {"light": "pixgraph.HardShadow"}}, {"types": {"ghost": "pixgraph.HardShadow"}},
    {"light_elevation": "high"}, {"light_elevation": 95}, {"light_tip": [float("nan"), 3]},
    {"light_tip": "here"},
    # all or nothing: the valid type switch before the bad param is not applied either
    {"types": {"shadow": "pixgraph.HardShadow"}, "params": {"light.elevation": 500}},
    {"light_tip": [150, 420], "params": {"light.kind": "laser"}},
]
BAD_RUNS = [{"outputs": 5}, {"outputs": ["comp.nope"]}, {"mode": 5}]   # bad for /api/run only


@pytest.mark.parametrize("data", BAD_EDITS + BAD_RUNS, ids=range(len(BAD_EDITS + BAD_RUNS)))
def test_every_bad_edit_is_a_4xx_json_error(api, server, data):
    import json

    raw = json.dumps(data).encode()     # NaN as the JSON extension Python writes
    for path in ("/api/params", "/api/run") if data in BAD_EDITS else ("/api/run",):
        r = api.post(path, content=raw, headers=JSON)
        assert 400 <= r.status_code < 500 and r.json()["error"], (path, r.status_code, r.text)
    assert api.get("/api/graph.yaml").text == fileio.dumps(fileio.loads(server["text"], Registry.discover(),
                                                                  base_dir=os.path.dirname(server["graph"])))


def test_bad_render_requests_and_posted_graphs(api):
    for data in ({"client": 5, "seq": 1}, {"client": "c", "seq": "1"}, {"output": ["final"]},
                 {"output": "light.light"}, {"mode": "draft"}, {"scale": 0}, {"scale": True}, {"scale": 1.5}):
        _error(api.post("/api/render", json=data), 400)
    laughs = "pixgraph: 1\na: &a [1, 1, 1, 1, 1, 1, 1, 1, 1]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a]\n"
    assert "anchors" in _error(api.post("/api/graph", content=laughs.encode(), headers=YAML), 400)["error"]
    _error(api.post("/api/graph", content=b"\xff\xfe", headers=YAML), 400)
    _error(api.post("/api/save", json={"path": 5}), 400)
    _error(api.post("/api/save", json={"path": "no/such/folder/x.yaml"}), 400)
    _error(api.get("/api/outputs/final.gif"), 404)
    _error(api.get("/api/outputs/final.png?scale=0"), 400)
    _error(api.get("/static/../state.py"), 404)


def test_a_param_override_without_a_param_name_is_refused_naming_it(api):
    # {"light": 5}: neither "node.param" nor {node: {param: value}}; the answer named no field
    for key, value in (("light", 5), ("light", [1]), ("light.", 3), (".elevation", 3)):
        err = _error(api.post("/api/params", json={"params": {key: value}}), 400)
        assert err.get("field") == f"params.{key}", err
        assert "must be 'node.param'" in err["error"], err
