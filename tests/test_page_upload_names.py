"""The page's upload names, in headless Chromium (Debian's ``chromium`` via
Playwright): a photo and a cutout named in another script open (the server takes
letters, digits and '._-': "写真.png" became "png", refused with 400, and two such
names of one extension became one file, the cutout overwriting the photo). Names
that lose characters are "NAME-HASH", HASH of the whole name; plain names are kept
(spaces become '_', as before)."""
import os
import re

import httpx
import pytest
from PIL import Image

from serve_helpers import GRAPHS, chromium_browser, running_server
from test_page_photo import last_seq, open_page, own_photo_copy, wait_final

SERVER_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.\-]{0,100}\.(png|jpg|jpeg|tif|tiff|exr)$", re.I)   # app.UPLOAD_NAME


@pytest.fixture(scope="module")
def browser():
    with chromium_browser() as b:
        yield b


def test_upload_names_the_server_takes(browser, tmp_path):
    from pixgraph_serve.app import UPLOAD_NAME

    assert UPLOAD_NAME.pattern == SERVER_NAME.pattern
    with running_server(own_photo_copy(str(tmp_path / "served"))) as (url, _):
        page, errors = open_page(browser, url)
        names = ["写真.png", "切り抜き.png", "фото.JPG", "my photo.jpeg", "IMG_0001.jpg", "a.b.png",
                 "x" * 150 + ".tif", "no_extension", ".hidden.png", "été.exr", "e\u0301te\u0301.exr"]
        got = page.evaluate("async (names) => { const m = await import('/static/app.js');"
                            " return names.map((n) => m.uploadName(n)); }", names)
        page.close()
    assert all(SERVER_NAME.match(g) for g in got), got
    assert got[4] == "IMG_0001.jpg" and got[5] == "a.b.png"             # plain names kept
    assert got[0] != got[1] and got[0].endswith(".png") and got[2].endswith(".jpg")
    assert got[3] == "my_photo.jpeg" and got[9] != got[10]              # NFC and NFD: two files
    assert len(set(got)) == len(got)


def test_a_photo_and_cutout_named_in_another_script_open(browser, tmp_path):
    mine = tmp_path / "mine"
    mine.mkdir()
    photo, cutout = mine / "写真.png", mine / "切り抜き.png"
    Image.open(os.path.join(GRAPHS, "assets", "own_photo.jpg")).convert("RGB").save(photo)
    Image.open(os.path.join(GRAPHS, "assets", "own_cutout.png")).save(cutout)
    with running_server(own_photo_copy(str(tmp_path / "served"))) as (url, _):
        page, errors = open_page(browser, url)
        page.click("#open")
        page.set_input_files("#open-photo", str(photo))
        page.set_input_files("#open-cutout", str(cutout))
        seq = last_seq(page)
        page.click("#open-go")
        page.wait_for_selector("body[data-ready='2']", state="attached", timeout=180000)
        wait_final(page, seq)
        assert not errors, errors
        assert page.locator("#error").is_hidden()
        page.close()
        nodes = {n["id"]: n["values"] for n in httpx.get(url + "/api/graph", timeout=60).json()["nodes"]}
        paths = nodes["photo"]["path"], nodes["cutout"]["path"]
        assert paths[0] != paths[1], paths
        with Image.open(paths[0]) as a, Image.open(paths[1]) as b:       # (the upload folder goes with the server)
            assert a.mode == "RGB" and b.mode == "RGBA"          # each its own file
