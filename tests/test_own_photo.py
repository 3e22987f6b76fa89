"""docs/own-photo.md: every command runs and prints what the page says; the example
makes a soft shadow that climbs the wall from a plain RGBA cutout and a photo."""
import pathlib
import re
import shlex
import shutil

import numpy as np
import pytest

from pixgraph import cli
from pixgraph.session import Session

ROOT = pathlib.Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "own-photo.md"


def _commands():
    """(command line, expected output lines) for every `$ pixgraph ...` line of the page."""
    out = []
    for block in re.findall(r"```\n(.*?)```", PAGE.read_text(), re.S):
        lines = [ln.strip() for ln in block.strip().splitlines()]
        for i, ln in enumerate(lines):
            if ln.startswith("$ pixgraph "):
                expect = []
                for nxt in lines[i + 1:]:
                    if nxt.startswith("$ "):
                        break
                    expect.append(nxt)
                out.append((ln[2:], expect))
    return out


COMMANDS = _commands()


def test_page_has_its_commands():
    assert len(COMMANDS) == 9


@pytest.mark.parametrize("index", range(len(COMMANDS)))
def test_page_command_prints_what_the_page_says(index, tmp_path, monkeypatch, capsys):
    line, expect = COMMANDS[index]
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("PIXGRAPH_DISK_CACHE", str(tmp_path / "cache"))
    # a copy, not a symlink: the path policy resolves symlinks, and errors would name
    # the files by their real (absolute) paths instead of as the page shows them
    shutil.copytree(ROOT / "graphs", tmp_path / "graphs")
    argv = shlex.split(line.replace("$PWD", str(tmp_path)))[1:]
    rc = cli.main(argv)
    captured = capsys.readouterr()
    got = [ln for ln in (captured.out + captured.err).strip().splitlines() if not ln.startswith("ran ")]
    assert got == expect
    assert rc == (2 if any("node '" in e and not e.startswith("warning: ") for e in expect) else 0)


def test_shadow_climbs_the_wall(device):
    out = Session(device=device, disk_cache=None).run(
        ROOT / "graphs" / "own_photo.yaml",
        outputs=["final", "shadow.darkness", "bg_h.height", "place.alpha", "photo.image"])
    img, dark, bg_h, alpha, photo = (out[k] for k in ("final", "shadow.darkness", "bg_h.height", "place.alpha",
                                                     "photo.image"))
    assert img.shape == (480, 640, 3) and alpha.shape == (480, 640)
    free = alpha == 0
    assert ((dark > 0.5) & (bg_h > 2.0) & free).sum() > 2000       # on the wall
    assert ((dark > 0.5) & (bg_h == 0.0) & free).sum() > 1000      # and on the floor
    assert ((dark > 0.05) & (dark < 0.95) & free).sum() > 2000     # soft
    assert np.all(img[free] <= photo[free] + 1e-6)
    # the cutout was placed at 0.8 of its 285 rows
    rows = np.nonzero((alpha > 0.5).any(axis=1))[0]
    assert abs((rows[-1] - rows[0] + 1) - 0.8 * 273) <= 3
