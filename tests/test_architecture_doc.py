"""docs/architecture.md's picture is tools/architecture_picture.py's output, and the
modules the page names exist."""
import os
import re
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_picture_is_regenerated_whole(tmp_path):
    out = tmp_path / "a.svg"
    subprocess.run([sys.executable, os.path.join(ROOT, "tools", "architecture_picture.py"), str(out)],
                   check=True, capture_output=True)
    assert out.read_text() == open(os.path.join(ROOT, "docs", "img", "architecture.svg")).read()


def test_the_modules_named_exist():
    text = open(os.path.join(ROOT, "docs", "architecture.md")).read()
    assert "![data flow](img/architecture.svg)" in text
    paths = set(re.findall(r"`((?:pixgraph|nodes)/[a-z_/]+\.py)`", text))
    assert len(paths) >= 10
    for p in paths:
        assert os.path.isfile(os.path.join(ROOT, p)), p
